"""Linear solvers of the step: matrix-free PCG (any device) and assembled sparse direct (CPU)."""

from .cg import BlockJacobiCG, CGResult, SystemOperator
from .direct import SparseDirect

__all__ = ["BlockJacobiCG", "CGResult", "SystemOperator", "SparseDirect"]
