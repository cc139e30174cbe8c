"""Warp kernels of warpsoft (``warpsoft.kernels``): kernels and device functions only.

Nothing here imports from ``warpsoft``; orchestration lives there.
"""
