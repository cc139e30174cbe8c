"""Kernels of warpsoft.resolve."""
