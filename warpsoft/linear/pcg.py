"""Preconditioned conjugate gradient for ``k`` right-hand sides at once, the loop on the device.

Every quantity of an iteration stays on the device: the CG scalars per column and world live
in ``scal``, and the kernel that rolls them over also sets the device flag that
``wp.capture_while`` loops on while some column has not converged. On CUDA the whole solve
(start, loop, stop) is captured once as a graph with a conditional node and replayed; the host
reads the iteration count and the residuals once, after the solve. On the CPU device the same
code runs the loop directly.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import warp as wp

from warpsoft.kernels.linear import cg as slots
from warpsoft.kernels.linear import pcg as kernels

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
        self.scal = wp.zeros((shape[0], m.num_worlds, slots.NUM_SCALARS), dtype=wp.float64, device=m.device)
        self.info = wp.zeros(2, dtype=wp.int32, device=m.device)
        self.active = wp.zeros(1, dtype=wp.int32, device=m.device)
        self._graphs = {}

    def prepare(self) -> None:
        """Per linearization: update the preconditioner."""
        self.precond.prepare()

    @property
    def stale(self) -> bool:
        """Whether the preconditioner is due for a refresh: the next :meth:`prepare` does it."""
        return getattr(self.precond, "stale", False)

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

    def readback_arrays(self) -> dict[str, wp.array]:
        """The device arrays :meth:`result` reads (a step gathers them with its other reads)."""
        return {"info": self.info, "scal": self.scal}

    def result(self, host: dict[str, np.ndarray] | None = None) -> SolveResult:
        """Iterations and residual of the last solve, from ``host`` (the arrays of
        :meth:`readback_arrays`, already read) or by reading them."""
        info, s = (host["info"], host["scal"]) if host is not None else (self.info.numpy(), self.scal.numpy())
        its = int(info[kernels.ITERATIONS])
        b2, r2 = s[:, :, slots.B2], s[:, :, slots.R2_LAST]  # (columns, worlds)
        if info[kernels.NONFINITE] or not (np.all(np.isfinite(b2)) and np.all(np.isfinite(r2))):
            return SolveResult(its, math.nan, False)
        rel = np.divide(np.sqrt(np.maximum(r2, 0.0)), np.sqrt(b2), out=np.zeros_like(b2), where=b2 > 0).max(axis=0)
        world_its = s[:, :, slots.ITS].max(axis=0).astype(int)
        residual = float(rel.max())
        return SolveResult(its, residual, residual <= self.tolerance, world_its, rel)

    def _run(self, b: wp.array, x: wp.array) -> None:
        m, d, shape = self.op.model, self.op.model.device, self.r.shape
        k, n = shape
        wp.launch(slots.project, shape, inputs=[m.mask], outputs=[x], device=d)
        self.op.apply(x, self.ap)
        self.scal.zero_()
        self.info.zero_()
        self.active.zero_()
        kernels.launch_nodes(kernels.pcg_residual, k, n, [b, self.ap, m.mask, self.r, m.node_world, self.scal], d)
        self.precond.apply(self.r, self.z)
        kernels.launch_nodes(kernels.pcg_begin, k, n, [self.r, self.z, x, self.p, m.node_world, self.scal], d)
        self._scalars(0)
        wp.capture_while(self.active, self._iteration, x=x)

    def _iteration(self, x: wp.array) -> None:
        """One iteration: ``A p``, ``alpha``, ``x``, ``r``, ``z = P^-1 r``, ``beta``, ``p``, stop test."""
        m, d = self.op.model, self.op.model.device
        k, n = self.r.shape
        self.op.apply(self.p, self.ap)
        kernels.launch_nodes(kernels.pcg_curvature, k, n, [self.p, self.ap, m.mask, m.node_world, self.scal], d)
        kernels.launch_nodes(kernels.pcg_update, k, n, [x, self.r, self.p, self.ap, m.node_world, self.scal], d)
        self.precond.apply(self.r, self.z)
        kernels.launch_nodes(kernels.pcg_rz, k, n, [self.r, self.z, m.node_world, self.scal], d)
        wp.launch(kernels.pcg_direction, (k, n), inputs=[self.z, self.p, m.node_world, self.scal],
                  outputs=[self.active], device=d)
        self._scalars(1)

    def _scalars(self, advance: int) -> None:
        wp.launch(kernels.pcg_scalars, self.scal.shape[:2],
                  inputs=[self.scal, self.tolerance, self.max_iterations, advance], outputs=[self.info, self.active],
                  device=self.op.model.device)
