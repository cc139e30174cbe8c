"""Kernels of warpsoft.elastic."""
