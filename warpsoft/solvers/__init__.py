"""Linear solvers of the step: matrix-free PCG (any device) and assembled sparse direct (CPU)."""

from .cg import BlockJacobi, BlockJacobiCG, CGResult, SystemOperator
from .direct import SparseDirect

__all__ = ["BlockJacobi", "BlockJacobiCG", "CGResult", "SystemOperator", "SparseDirect"]
