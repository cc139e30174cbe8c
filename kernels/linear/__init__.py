"""Kernels of warpsoft.linear."""
