"""Preconditioned conjugate gradient for ``k`` right-hand sides at once, the loop on the device.

Every quantity of an iteration stays on the device: the CG scalars per column live in
``scal`` and the stopping test is a one-thread kernel that clears a device flag, which
``wp.capture_while`` loops on. On CUDA the whole solve (start, loop, stop) is captured once
as a graph with a conditional node and replayed; the host reads the iteration count and the
residuals once, after the solve. On the CPU device the same code runs the loop directly.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import warp as wp

from warpsoft.kernels.linear import cg as linalg

from .operator import SystemOperator


@dataclass
class SolveResult:
    """Outcome of one solve: iterations (shared by the columns; 0 for a direct solve), the
    largest relative residual ``|r| / |b|`` over the columns (NaN when a value was not
    finite), and whether every column reached the tolerance. ``world_iterations`` and
    ``world_residuals`` (``(worlds,)``, when the solver knows them) are the same per world: the
    iterations its columns needed and its largest relative residual."""

    iterations: int
    residual: float
    converged: bool
    world_iterations: np.ndarray | None = None
    world_residuals: np.ndarray | None = None


class PCG:
    """``A x[c] = b[c]`` for ``columns`` right-hand sides by preconditioned CG.

    Args:
        operator: the system; its model gives sizes, device and the fixed-DOF mask.
        preconditioner: any object with ``apply(r, z)`` on ``(k, n)`` vec3d arrays, and a
            ``capturable`` attribute (False when it needs the host, as a host factorization
            on a CUDA device does: the loop then runs without a graph).
        columns: ``k``.
        tolerance: relative residual ``|r| / |b|`` every column must reach.
        max_iterations: cap; reaching it is reported, not hidden.
        graph: on CUDA, capture the whole solve once per pair of buffers and replay it.
    """

    def __init__(self, operator: SystemOperator, preconditioner, columns: int, tolerance: float = 1e-6,
                 max_iterations: int = 2000, graph: bool = True):
        m = operator.model
        self.op, self.precond = operator, preconditioner
        self.tolerance, self.max_iterations = float(tolerance), int(max_iterations)
        self.graph = bool(graph) and m.device.is_cuda and getattr(preconditioner, "capturable", False)
        shape = (int(columns), m.num_nodes)
        self.r, self.z, self.p, self.ap = (wp.zeros(shape, dtype=wp.vec3d, device=m.device) for _ in range(4))
        self.scal = wp.zeros((shape[0], m.num_worlds, linalg.NUM_SCALARS), dtype=wp.float64, device=m.device)
        self.info = wp.zeros(2, dtype=wp.int32, device=m.device)
        self.active = wp.zeros(1, dtype=wp.int32, device=m.device)
        self._graphs = {}

    def prepare(self) -> None:
        """Per linearization: update the preconditioner."""
        self.precond.prepare()

    @property
    def capturable(self) -> bool:
        """Whether :meth:`prepare` and :meth:`run` of this step can be captured in a larger graph:
        the preconditioner works on the device and needs no host refactorization this step."""
        return getattr(self.precond, "capturable", False) and not getattr(self.precond, "stale", False)

    def run(self, b: wp.array, x: wp.array) -> None:
        """The device part of :meth:`solve`, to be captured inside a step's graph; after the
        graph ran, read :meth:`result` and pass it to :meth:`finish`."""
        self._run(b, x)

    def finish(self, res: SolveResult) -> None:
        """After a solve: tell the preconditioner how many iterations it took (it refreshes its
        factorization when they grow)."""
        self.precond.observe(res.iterations)

    def solve(self, b: wp.array, x: wp.array) -> SolveResult:
        """Solve in place; ``x`` (``(k, n)`` vec3d) holds the warm start on entry."""
        if self.graph:
            key = (b.ptr, x.ptr)
            if key not in self._graphs:
                with wp.ScopedCapture(device=self.op.model.device) as capture:
                    self._run(b, x)
                self._graphs[key] = capture.graph
            wp.capture_launch(self._graphs[key])
        else:
            self._run(b, x)
        res = self.result()
        self.finish(res)
        return res

    def result(self) -> SolveResult:
        """Iterations and residual of the last solve (one read of a few numbers)."""
        info, s = self.info.numpy(), self.scal.numpy()
        its = int(info[linalg.ITERATIONS])
        b2, r2 = s[:, :, linalg.B2], s[:, :, linalg.R2_LAST]  # (columns, worlds)
        if info[linalg.NONFINITE] or not (np.all(np.isfinite(b2)) and np.all(np.isfinite(r2))):
            return SolveResult(its, math.nan, False)
        rel = np.divide(np.sqrt(np.maximum(r2, 0.0)), np.sqrt(b2), out=np.zeros_like(b2), where=b2 > 0).max(axis=0)
        done = s[:, :, linalg.DONE] > 0
        world_its = np.where(done, s[:, :, linalg.ITS], its).max(axis=0).astype(int)
        residual = float(rel.max())
        return SolveResult(its, residual, residual <= self.tolerance, world_its, rel)

    def _run(self, b: wp.array, x: wp.array) -> None:
        m, d, shape = self.op.model, self.op.model.device, self.r.shape
        wp.launch(linalg.project, shape, inputs=[m.mask], outputs=[x], device=d)
        self.op.apply(x, self.ap)
        self.scal.zero_()
        self.info.zero_()
        wp.launch(linalg.pcg_residual, shape, inputs=[b, self.ap, m.mask, self.r, m.node_world], outputs=[self.scal],
                  device=d)
        self.precond.apply(self.r, self.z)
        wp.launch(linalg.pcg_begin, shape, inputs=[self.r, self.z, x, self.p, m.node_world], outputs=[self.scal],
                  device=d)
        self._check(0)
        wp.capture_while(self.active, self._iteration, x=x)

    def _iteration(self, x: wp.array) -> None:
        """One iteration: ``A p``, ``alpha``, ``x``, ``r``, ``z = P^-1 r``, ``beta``, ``p``, stop test."""
        m, d, shape = self.op.model, self.op.model.device, self.r.shape
        self.op.apply(self.p, self.ap)
        wp.launch(linalg.cg_curvature, shape, inputs=[self.p, self.ap, m.mask, m.node_world], outputs=[self.scal],
                  device=d)
        wp.launch(linalg.pcg_update, shape, inputs=[x, self.r, self.p, self.ap, m.node_world], outputs=[self.scal],
                  device=d)
        self.precond.apply(self.r, self.z)
        wp.launch(linalg.pcg_rz, shape, inputs=[self.r, self.z, m.node_world], outputs=[self.scal], device=d)
        wp.launch(linalg.cg_scalars, self.scal.shape[:2], inputs=[self.scal], device=d)
        wp.launch(linalg.cg_direction, shape, inputs=[self.z, self.p, m.node_world, self.scal], device=d)
        self._check(1)

    def _check(self, done: int) -> None:
        wp.launch(linalg.pcg_check, 1, inputs=[self.scal, self.tolerance, self.max_iterations, done],
                  outputs=[self.info, self.active], device=self.op.model.device)
