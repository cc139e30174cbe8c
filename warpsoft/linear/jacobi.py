"""v1's batched block-Jacobi preconditioned conjugate gradient (solver ``jacobi``, kept to
compare against) on ``A = mass_scale M + stiffness_scale K``.

Matrix-free: ``K`` is applied element by element from the rotations of the last
linearization, for all right-hand sides at once. Fixed DOFs are projected out (the
unknowns stay 0 there).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import warp as wp

from warpsoft.kernels.linear import cg as linalg

from ..launch import launch
from .operator import SystemOperator


class BlockJacobi:
    """Inverse 3x3 diagonal blocks of ``A``, rebuilt at each linearization."""

    def __init__(self, operator: SystemOperator):
        m = operator.model
        self.op = operator
        self.kdiag = wp.zeros(m.num_nodes, dtype=wp.mat33d, device=m.device)
        self.inverse = wp.zeros(m.num_nodes, dtype=wp.mat33d, device=m.device)
        self._mass = m.mass if m.mass is not None else wp.zeros(m.num_nodes, dtype=wp.float64, device=m.device)

    def update(self) -> None:
        m, op = self.op.model, self.op
        self.kdiag.zero_()
        op.elastic.diagonal(op.rot, self.kdiag)
        launch(linalg.block_jacobi_inverse, m.num_nodes,
               inputs=[self.kdiag, self._mass, op.mass_scale, op.stiffness_scale, m.mask],
               outputs=[self.inverse], device=m.device)


@dataclass
class CGResult:
    """Outcome of one batched solve: iterations (shared by the columns), the largest relative
    residual ``|r| / |b|`` over the columns, and whether every column converged."""

    iterations: int
    residual: float
    converged: bool


class BlockJacobiCG:
    """PCG on ``columns`` right-hand sides at once.

    Args:
        operator: the system (its model gives sizes, device, mask, mass).
        preconditioner: block Jacobi of the same system (shared between solvers).
        columns: number of right-hand sides ``k``.
        tolerance: relative residual ``|r| / |b|`` each column must reach.
        max_iterations: cap; reaching it is reported, not hidden.
        check_every: read the residuals back to the host every this many iterations (the
            iterations in between run without a host round trip; a few extra ones past
            convergence only refine the solution).
        graphs: on CUDA, capture ``check_every`` iterations once as a graph and replay it.
    """

    def __init__(self, operator: SystemOperator, preconditioner: BlockJacobi, columns: int = 1,
                 tolerance: float = 1e-6, max_iterations: int = 2000, check_every: int = 1, graphs: bool = True):
        self.op, self.precond = operator, preconditioner
        self.tolerance, self.max_iterations, self.check_every = float(tolerance), int(max_iterations), int(check_every)
        self.graphs = bool(graphs) and operator.model.device.is_cuda
        self._captured = {}  # (b, x) pointers -> graph of check_every iterations
        m = operator.model
        shape = (int(columns), m.num_nodes)
        self.r, self.z, self.p, self.ap = (wp.zeros(shape, dtype=wp.vec3d, device=m.device) for _ in range(4))
        # v1's solver for comparison: one system, whatever the worlds (one world id for all nodes)
        self.one_world = wp.zeros(m.num_nodes, dtype=wp.int32, device=m.device)
        self.scal = wp.zeros((shape[0], 1, linalg.NUM_SCALARS), dtype=wp.float64, device=m.device)

    def _relative(self) -> float:
        """Largest relative residual over the columns; NaN if any ``b`` or ``r`` is not finite."""
        s = self.scal.numpy()
        b2, r2 = s[:, 0, linalg.B2], s[:, 0, linalg.R2_LAST]
        if not (np.all(np.isfinite(b2)) and np.all(np.isfinite(r2))):
            return math.nan
        b = np.sqrt(b2)
        rel = np.divide(np.sqrt(np.maximum(r2, 0.0)), b, out=np.zeros_like(b), where=b > 0)
        return float(rel.max())

    def prepare(self) -> None:
        """Per linearization: rebuild the block-Jacobi preconditioner."""
        self.precond.update()

    def solve(self, b: wp.array, x: wp.array) -> CGResult:
        """Solve ``A x[c] = b[c]`` in place for every column (``(k, n)`` arrays); ``x`` holds the
        warm start on entry (its fixed DOFs are zeroed)."""
        m, d, shape = self.op.model, self.op.model.device, self.r.shape
        pre = self.precond.inverse
        launch(linalg.project, shape, inputs=[m.mask], outputs=[x], device=d)
        self.op.apply(x, self.ap)
        self.scal.zero_()
        launch(linalg.cg_start, shape, inputs=[b, self.ap, m.mask, pre, self.r, self.z, self.p, self.one_world],
               outputs=[self.scal],
               device=d)
        launch(linalg.cg_clear_zero_columns, shape, inputs=[self.one_world, self.scal, x, self.p], device=d)
        rel = self._relative()
        it = 0
        while rel > self.tolerance and math.isfinite(rel) and it < self.max_iterations:
            k = min(self.check_every, self.max_iterations - it)
            if self.graphs and k == self.check_every:
                key = (b.ptr, x.ptr)
                if key not in self._captured:
                    with wp.ScopedCapture(device=d) as capture:
                        for _ in range(k):
                            self._iteration(x)
                    self._captured[key] = capture.graph
                wp.capture_launch(self._captured[key])
            else:
                for _ in range(k):
                    self._iteration(x)
            it += k
            rel = self._relative()
        return CGResult(it, rel, bool(rel <= self.tolerance))

    def _iteration(self, x: wp.array) -> None:
        """One CG iteration, all on the device: ``A p``, ``alpha``, ``x``, ``r``, ``z``, ``beta``, ``p``."""
        m, d, shape = self.op.model, self.op.model.device, self.r.shape
        self.op.apply(self.p, self.ap)
        launch(linalg.cg_curvature, shape, inputs=[self.p, self.ap, m.mask, self.one_world], outputs=[self.scal],
               device=d)
        launch(linalg.cg_update, shape,
               inputs=[x, self.r, self.z, self.p, self.ap, self.precond.inverse, self.one_world],
               outputs=[self.scal], device=d)
        launch(linalg.cg_scalars, self.scal.shape[:2], inputs=[self.scal], device=d)
        launch(linalg.cg_direction, shape, inputs=[self.z, self.p, self.one_world, self.scal], device=d)
