"""Kernels of warpsoft.rows."""
