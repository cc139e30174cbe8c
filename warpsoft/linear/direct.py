"""Assembled sparse direct solve of ``A = mass_scale M + stiffness_scale K`` on the host.

The CPU path (Warp's CPU device runs one thread, so a factorization beats any iteration)
and the accuracy reference of the iterative solvers. Fixed DOFs are removed from the system.
"""

from __future__ import annotations

import numpy as np
import warp as wp

from .assembly import FACTORIZATIONS, Assembly, solve_dofs
from .operator import SystemOperator
from .pcg import SolveResult


class SparseDirect:
    """Factorize at each linearization (the pattern analysed once), solve all columns at once.

    Args:
        operator: the system; its rotations and scales are read at each :meth:`prepare`.
        factorization: "cholmod" (default) or "superlu" (v1's, for comparison).
    """

    capturable = False

    def __init__(self, operator: SystemOperator, factorization: str = "cholmod"):
        if factorization not in FACTORIZATIONS:
            raise ValueError(f"SparseDirect: factorization must be one of {sorted(FACTORIZATIONS)}, "
                             f"got {factorization!r}")
        self.op = operator
        self.assembly = Assembly(operator)
        self.factor = FACTORIZATIONS[factorization](self.assembly)

    def prepare(self) -> None:
        """Assemble and factorize ``A`` at the operator's current rotations and scales."""
        self.factor.factorize(self.assembly.values())

    def solve(self, b: wp.array, x: wp.array) -> SolveResult:
        """``x[c] = A^-1 b[c]`` for ``(k, n)`` vec3d arrays. Zero columns (contact slots that
        no contact took this step) are not solved: they stay 0."""
        flat = b.numpy().reshape(b.shape[0], -1)  # on the CPU device, views: no copy
        used = np.flatnonzero(flat.any(axis=1))
        on_host = x.device.is_cpu
        out = x.numpy().reshape(flat.shape) if on_host else np.empty_like(flat)
        out.fill(0.0)
        if len(used):
            free = self.assembly.free
            out[np.ix_(used, free)] = self.factor.solve(np.ascontiguousarray(flat[np.ix_(used, free)].T)).T
        if not on_host:
            x.assign(out.reshape(x.shape[0], -1, 3))
        return SolveResult(0, 0.0, True)

    def solve_array(self, b: np.ndarray) -> np.ndarray:
        """Solve for right-hand sides ``(k, n, 3)`` (host arrays); fixed DOFs get 0."""
        return solve_dofs(self.factor, b.reshape(b.shape[0], -1)).reshape(b.shape)
