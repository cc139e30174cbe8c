"""Warp kernels of warpsoft (``warpsoft.kernels``): kernels and device functions only.

Nothing here imports from ``warpsoft``; orchestration lives there.
"""

# No kernel here is differentiated, so no module compiles adjoints (they are most of a module's
# compile time): each module sets these options (``wp.set_module_options``, or ``module_options``
# for a kernel of its own module).
OPTIONS = {"enable_backward": False}
