"""Warp kernels of warpsoft (``warpsoft.kernels``): kernels and device functions only.

Nothing here imports from ``warpsoft``; orchestration lives there.
"""

# No kernel here is differentiated, so no module compiles adjoints: each module sets these
# options (``wp.set_module_options``, or ``module_options`` for a kernel of its own module).
# Without adjoints the block CG's kernels compiled 2-5 times faster on the CPU device.
OPTIONS = {"enable_backward": False}
