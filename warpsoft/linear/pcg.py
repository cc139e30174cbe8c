"""Preconditioned conjugate gradient for ``k`` right-hand sides at once, the loop on the device.

Every quantity of an iteration stays on the device: the CG scalars per column and world live
in ``scal``, and the kernel that rolls them over also sets the device flag that
``wp.capture_while`` loops on while some column has not converged. On CUDA the whole solve
(start, loop, stop) is captured once as a graph with a conditional node and replayed; the host
reads the iteration count and the residuals once, after the solve. On the CPU device the same
code runs the loop directly.

Only the right-hand sides in use are solved when the caller says how many are (:meth:`PCG.bound`,
a count on the device: the contact slots a detection filled). On CUDA the solve is captured
once per size in :data:`SIZES` up to ``k`` (each a conditional branch, the smallest that holds
the count runs); on the CPU device the count is read and the solve takes exactly that many.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import warp as wp

from warpsoft.kernels.linear import block_pcg as blockk
from warpsoft.kernels.linear import cg as slots
from warpsoft.kernels.linear import pcg as kernels

from ..launch import launch
from .operator import SystemOperator

SIZES = (8, 32, 64, 128)  # right-hand sides a bounded CUDA solve is captured for (then every k)


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
        block: a world's right-hand sides share one search space (block CG, breakdown-free:
            ``kernels/linear/block_pcg.py``) when there are at most ``MAX_COLUMNS`` of them and
            all are solved (not bounded); each column then stops with its world, when all of
            the world's columns reached the tolerance. False: each column its own CG.
        directions: the block CG's storage of its directions ``P`` and ``Z = P^-1 R``: "float64",
            "float32" (half their bytes; ``X``, ``R`` and ``A P`` stay float64, so ``R`` stays the
            residual of ``X``: ``kernels/linear/block_pcg.py``) or "auto": float32 where the
            preconditioner works in float32 anyway and can write it (``single_output``) and the
            operator takes it (its assembled blocks), else float64. Without the block CG: float64.

    Attributes: ``bp``, ``bz``: the block CG's ``P`` and ``Z``, ``(k, n)`` vec3d or vec3f (with vec3d,
    the column CG's ``p`` and ``z`` themselves).
    """

    def __init__(self, operator: SystemOperator, preconditioner, columns: int, tolerance: float = 1e-6,
                 max_iterations: int = 2000, graph: bool = True, block: bool = True, directions: str = "auto"):
        m = operator.model
        self.op, self.precond = operator, preconditioner
        self.tolerance, self.max_iterations = float(tolerance), int(max_iterations)
        self.graph = bool(graph) and m.device.is_cuda and getattr(preconditioner, "capturable", False)
        shape = (int(columns), m.num_nodes)
        self.r, self.z, self.p, self.ap = (wp.zeros(shape, dtype=wp.vec3d, device=m.device) for _ in range(4))
        self.scal = wp.zeros((shape[0], m.num_worlds, slots.NUM_SCALARS), dtype=wp.float64, device=m.device)
        self.info = wp.zeros(2, dtype=wp.int32, device=m.device)
        if hasattr(preconditioner, "watch"):  # a preconditioner that skips the worlds that converged
            preconditioner.watch(self.scal)
        self.active = wp.zeros(1, dtype=wp.int32, device=m.device)
        self._graphs = {}
        self.count, self.offset = None, 0  # right-hand sides in use: offset + count[0] (None: all)
        self.held = None  # worlds not solved (hold)
        self.sizes = [s for s in SIZES if s < shape[0]] + [shape[0]]
        # made here, never inside a capture: an array made there is filled by a copy the graph
        # replays from host memory freed since (a graph captured at the first step picked wrong
        # sizes at the 20th)
        self.sizes_d = wp.array(self.sizes, dtype=wp.int32, device=m.device)
        self.branch = wp.zeros(len(self.sizes), dtype=wp.int32, device=m.device)
        self.branches = m.device.is_cuda  # a bounded solve by size branches; else the count is read
        self.block = bool(block) and 1 < shape[0] <= blockk.MAX_COLUMNS
        if self.block:
            k, worlds = shape[0], m.num_worlds
            self.gram = wp.zeros((worlds, blockk.NUM_GRAMS, k, k), dtype=wp.float64, device=m.device)
            self.coef = wp.zeros((worlds, 2, k, k), dtype=wp.float64, device=m.device)
            self.wdone = wp.zeros(worlds, dtype=wp.int32, device=m.device)
            self.world_start = wp.array(m.world_node_start, dtype=wp.int32, device=m.device)  # (worlds + 1,)
        self.directions = self._directions(directions, operator, preconditioner)
        self.bp, self.bz = self.p, self.z
        if self.directions == "float32":
            self.bp, self.bz = (wp.zeros(shape, dtype=wp.vec3f, device=m.device) for _ in range(2))

    def _directions(self, directions: str, operator: SystemOperator, preconditioner) -> str:
        """The block CG's storage of ``P`` and ``Z`` for ``directions`` ("auto", "float64", "float32")."""
        if directions not in ("auto", *blockk.DIRECTIONS):
            raise ValueError(f"PCG: directions must be 'auto', 'float64' or 'float32', got {directions!r}")
        if not self.block:  # (no block directions to store: the column CG's are float64)
            return "float64"
        can = getattr(preconditioner, "single_output", False) and getattr(operator, "blocks", None) is not None
        if directions == "float32" and not can:
            raise ValueError("PCG: directions='float32' needs a float32 preconditioner that writes it "
                             "(preconditioner='factors', precision='float32') and the assembled operator")
        return "float32" if can and directions != "float64" else "float64"

    def bound(self, count: wp.array, offset: int = 0) -> None:
        """Solve only the right-hand sides ``c < offset + count[0]`` (``count`` an int32 device array
        of one element, updated on the device between solves); the others keep their values and
        their CG scalars read as converged. ``offset``: the right-hand sides always in use."""
        self.count, self.offset = count, int(offset)

    def hold(self, flags: wp.array | None) -> None:
        """Worlds not to solve: those with ``flags[w] = 0`` (``(worlds,)`` float64 on the device,
        read at each solve's start; None: none). Their columns keep what ``x`` held and read as
        converged: a world that Newton holds in place needs no new compliance."""
        self.held = flags

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

    def finish(self, res: SolveResult, worlds: bool = True) -> None:
        """After a solve: tell the preconditioner how many iterations it took (it goes stale when
        they grow), and with ``worlds``, :meth:`finish_worlds`."""
        self.precond.observe(res.iterations)
        if worlds:
            self.finish_worlds(res)

    def finish_worlds(self, res: SolveResult) -> None:
        """After a solve: tell the preconditioner each world's iterations, where it keeps a
        factorization per world (it refreshes them at a later step boundary when they grow)."""
        if res.world_iterations is not None and hasattr(self.precond, "observe_worlds"):
            self.precond.observe_worlds(res.world_iterations)

    @property
    def worlds_due(self) -> bool:
        """Whether the step boundary has work for the worlds' own refreshes (:meth:`refresh_worlds`):
        some are due, or being made."""
        return bool(getattr(self.precond, "worlds_due", False))

    def refresh_worlds(self) -> None:
        """Host work beside the step's first solve (its graph launched): the due worlds' own
        refreshes sent to be made, those made installed (queued after that solve: the later ones
        read the new factors in place)."""
        self.precond.refresh_worlds(solving=True)

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
        d = self.op.model.device
        k = min(b.shape[0], self.r.shape[0])
        self.scal.zero_()  # right-hand sides left out read as converged (b = 0)
        self.info.zero_()
        if self.block and self.count is None and k == self.r.shape[0]:  # a world's columns as one block
            self._block_columns(b, x)
        elif self.count is None or k == 1 or (self.branches and len(self.sizes) == 1):  # all of them
            self._columns(b, x, k)
        elif not self.branches:  # (the CPU device: the count is host memory)
            self._columns(b, x, min(k, self.offset + int(self.count.numpy()[0])))
        else:  # one branch runs: the smallest size that holds the count (clamped to k)
            launch(kernels.pick_size, 1, inputs=[self.count, self.offset, self.sizes_d, k], outputs=[self.branch],
                   device=d)
            for j, size in enumerate(self.sizes):
                wp.capture_if(self.branch[j:j + 1], self._columns, b=b, x=x, k=min(size, k))

    def _columns(self, b: wp.array, x: wp.array, k: int) -> None:
        """The solve of the first ``k`` right-hand sides."""
        m, d = self.op.model, self.op.model.device
        n = m.num_nodes
        b, x = b[:k], x[:k]
        r, z, p, ap, scal = self.r[:k], self.z[:k], self.p[:k], self.ap[:k], self.scal[:k]
        launch(slots.project, (k, n), inputs=[m.mask], outputs=[x], device=d)
        self.op.apply(x, ap)
        self.active.zero_()
        kernels.launch_nodes(kernels.pcg_residual, k, n, [b, ap, m.mask, r, m.node_world, scal], d)
        self.precond.apply(r, z)
        kernels.launch_nodes(kernels.pcg_begin, k, n, [r, z, x, p, m.node_world, scal], d)
        self._scalars(scal, 0)
        wp.capture_while(self.active, self._iteration, x=x)

    def _iteration(self, x: wp.array) -> None:
        """One iteration: ``A p``, ``alpha``, ``x``, ``r``, ``z = P^-1 r``, ``beta``, ``p``, stop test
        (over the right-hand sides of ``x``)."""
        m, d = self.op.model, self.op.model.device
        k, n = x.shape
        r, z, p, ap, scal = self.r[:k], self.z[:k], self.p[:k], self.ap[:k], self.scal[:k]
        self.op.apply(p, ap, scal)  # a converged column of a world is skipped, here and below
        kernels.launch_nodes(kernels.pcg_curvature, k, n, [p, ap, m.mask, m.node_world, scal], d)
        kernels.launch_nodes(kernels.pcg_update, k, n, [x, r, p, ap, m.node_world, scal], d)
        self.precond.apply(r, z)
        kernels.launch_nodes(kernels.pcg_rz, k, n, [r, z, m.node_world, scal], d)
        launch(kernels.pcg_direction, (k, n), inputs=[z, p, m.node_world, scal], outputs=[self.active], device=d)
        self._scalars(scal, 1)

    def _block_columns(self, b: wp.array, x: wp.array) -> None:
        """The block solve of all right-hand sides (see ``kernels/linear/block_pcg.py``)."""
        m, d = self.op.model, self.op.model.device
        k, n = x.shape
        launch(slots.project, (k, n), inputs=[m.mask], outputs=[x], device=d)
        self.op.apply(x, self.ap)
        self.active.zero_()
        self.gram.zero_()
        kernels.launch_nodes(kernels.pcg_residual, k, n, [b, self.ap, m.mask, self.r, m.node_world, self.scal], d)
        self._block_scalars(0)  # (the worlds held, the columns left out)
        self.precond.apply(self.r, self.bz)
        launch(blockk.block_begin_kernel(self.bz.dtype), (k, n), inputs=[self.r, self.bz, x, self.bp, m.node_world,
                                                                          self.scal], device=d)
        wp.capture_while(self.active, self._block_iteration, x=x)

    def _block_iteration(self, x: wp.array) -> None:
        """One block iteration: ``A P``, ``P^T A P`` and ``P^T R``, ``alpha``, ``X`` and ``R``, ``Z = M^-1 R``
        and ``(A P)^T Z``, ``beta`` and the stop test, ``P``."""
        m, d = self.op.model, self.op.model.device
        k, n = x.shape
        p, z = self.bp, self.bz
        self.op.apply(p, self.ap, self.scal)  # the worlds done are skipped, here and below
        self._gram(p, self.ap, self.r)  # P^T A P and P^T R, one pass over P
        launch(blockk.small_kernels(k, d.is_cuda)[0], m.num_worlds, inputs=[self.gram, self.wdone, blockk.DEPENDENT],
               outputs=[self.coef, self.active], device=d)
        blockk.launch_worlds(blockk.block_update_kernel(k, p.dtype), m.num_worlds,
                             [x, self.r, p, self.ap, m.mask, self.world_start, self.scal, self.wdone, self.coef], d)
        self.precond.apply(self.r, z)
        self._gram(self.ap, None, z)  # (A P)^T Z
        self._block_scalars(1)
        launch(blockk.block_direction_kernel(k, p.dtype), n, inputs=[z, p, m.node_world, self.scal, self.wdone,
                                                                     self.coef], device=d)

    def _gram(self, u: wp.array, v: wp.array | None, w: wp.array) -> None:
        """``G_PAP += u^T v`` (with ``v``: ``P^T A P``, symmetric) and ``G_PR += u^T w`` (``P^T R``), or
        without ``v``, ``G_QZ += u^T w`` (``(A P)^T Z``)."""
        m = self.op.model
        kernel = blockk.gram_kernel(u.shape[0], u.dtype, None if v is None else v.dtype, w.dtype)
        slot = blockk.G_PR if v is not None else blockk.G_QZ
        blockk.launch_worlds(kernel, m.num_worlds, [u, self.ap if v is None else v, w, m.mask, self.world_start,
                                                    self.scal, self.wdone, blockk.G_PAP, slot, self.gram], m.device)

    def _block_scalars(self, advance: int) -> None:
        launch(blockk.small_kernels(self.r.shape[0], self.op.model.device.is_cuda)[1], self.op.model.num_worlds,
               inputs=[self.scal, self.gram, self.tolerance, self.max_iterations, advance, self.held, blockk.DEPENDENT],
               outputs=[self.wdone, self.coef, self.info, self.active],
               device=self.op.model.device)

    def _scalars(self, scal: wp.array, advance: int) -> None:
        launch(kernels.pcg_scalars, scal.shape[:2],
               inputs=[scal, self.tolerance, self.max_iterations, advance, self.held],
               outputs=[self.info, self.active], device=self.op.model.device)
