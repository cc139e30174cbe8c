"""The warped-factorization preconditioner ``P^-1 = Q A_f^-1 Q^T`` (SOFA's WarpPreconditioner,
Courtecuisse et al.): ``A`` is factorized once (at rest) and turned with the body by per-node
rotations ``Q_i = R_i R_f,i^T`` (see ``kernels/linear/warped.py``). Corotational stiffness changes
mostly by rotation, so this preconditioner stays close to ``A^-1`` under large motion:
DESIGN section 4 measured 29 iterations on a Diamond bent by a 20 mm cable where block
Jacobi needs 577.

``A_f^-1`` is applied in one of two ways:
- ``host``: CHOLMOD triangular solves on the host (the CPU device, where device memory is
  host memory; on CUDA it would cost a round trip per iteration);
- ``dense``: ``A_f^-1`` kept as a dense ``(N, N)`` matrix on the device (a GPU reads it at
  memory bandwidth, and the loop can be captured as one graph). Built from the factorization;
  its memory is ``8 N^2`` bytes (``4 N^2`` in float32). Its product with the ``k`` columns is
  either ``stream`` (the symmetric matrix read down its columns, the inner dimension cut into
  segments) or ``tiles`` (tiled matrix product), or by ``auto`` the first for a few columns and
  the second for many; ``tools/bench_precond.py`` measures both.

The factorization is refreshed at the current state when a solve needs more than
``refresh_ratio`` times the iterations of the first solve after the last refresh (and more
than ``refresh_floor``); the count of refreshes is kept in ``refreshes``.
"""

from __future__ import annotations

import numpy as np
import warp as wp

from warpsoft.kernels.linear import warped as kernels

from ..launch import launch
from ..newton import zero_moving
from .assembly import SOLVE_ENTRIES, Assembly, CholmodFactor, solve_dofs
from .operator import SystemOperator

MODES = ("auto", "host", "dense")
PRODUCTS = ("auto", "stream", "tiles")
DENSE_LIMIT = 12000  # free DOFs above which "auto" does not keep a dense inverse (1.2 GB in float64)
# tiled product: rows per block, inner dimension per tile, threads, splits; the fastest for many columns
# (tools/bench_precond.py, H200 float32, 128 columns: Octoleg 97 us, PneuNet 1291 us; (8, 32, ...) 110 and
# 2885 us, (8, 64, ...) 2147 us on the PneuNet; (8, 128, ...), once the default, 100 us on the Octoleg)
TILES = (16, 32, 128, 1)
# streaming product: segments of the inner dimension, loads in flight per thread, numbers per load; the
# fastest measured on the Diamond and the Trunk in both precisions (tools/bench_precond.py)
STREAM = (64, 2, 2)
# "auto": right-hand sides up to which the product is streamed, above it tiled. H200, float32, us per
# application, streamed/tiled (tools/bench_precond.py, docs/bench-v2-gpu-columns/precond/): Octoleg
# (1431 DOFs) 16 columns 22.5/43.6, 32: 35.2/57.5, 128: 224/97, 290: 3559/372; PneuNet (8565
# DOFs) 32: 610/618, 128: 4436/1291 (a streaming thread holds k sums per row: past 32 they spill)
STREAM_COLUMNS = 32


class WarpedFrames:
    """What every warped preconditioner shares: the node rotations ``Q_i = R_i R_f,i^T`` between
    the factorized frame and the current one, and when to refactorize (a solve needing more than
    ``refresh_ratio`` times the iterations of the first solve after the last refresh, and more
    than ``refresh_floor``). A subclass gives :meth:`refresh`, which factorizes and then calls
    :meth:`take_frame`.

    Arrays ``(nodes,)`` mat33d: ``node_sum`` (volume-weighted element rotations), ``node_rot``
    (``R_i``), ``frame`` (``R_f,i``); ``q_rot`` (``Q_i``) of ``frame_kind`` (mat33d, or mat33f where
    the preconditioner works in float32: 36 bytes a node fewer at each rotation in and out).
    """

    def __init__(self, operator: SystemOperator, refresh_ratio: float, refresh_floor: int,
                 frame_kind=wp.mat33d):
        m = operator.model
        self.op = operator
        self.refresh_ratio, self.refresh_floor = float(refresh_ratio), int(refresh_floor)
        self.refreshes, self._baseline, self._stale = 0, None, True
        n = m.num_nodes
        self.node_sum = wp.zeros(n, dtype=wp.mat33d, device=m.device)
        self.node_rot = wp.zeros(n, dtype=wp.mat33d, device=m.device)
        self.frame = wp.array(np.tile(np.eye(3), (n, 1, 1)), dtype=wp.mat33d, device=m.device)
        self.q_rot = wp.zeros(n, dtype=frame_kind, device=m.device)

    @property
    def stale(self) -> bool:
        """True when the next :meth:`prepare` refactorizes on the host (not capturable)."""
        return self._stale

    def prepare(self) -> None:
        """Per linearization: node rotations from the element rotations; refactorize if due."""
        m, moving = self.op.model, self.op.moving  # (the nodes of the worlds that stay keep theirs)
        zero_moving(self.node_sum, m, moving)
        self.op.elastic.node_rotations(self.op.rot, self.node_sum, moving)
        launch(kernels.relative_node_rotations(self.q_rot.dtype), m.num_nodes,
               inputs=[self.node_sum, self.frame, m.node_world, moving], outputs=[self.node_rot, self.q_rot],
               device=m.device)
        if self._stale:
            self.refresh()

    def refresh(self) -> None:
        """Factorize at the current state, then :meth:`take_frame` (each preconditioner its own way)."""
        raise NotImplementedError

    def take_frame(self, spans: list[tuple[int, int]] | None = None, frames: list[wp.array] | None = None) -> None:
        """After a factorization at the current rotations: they become the frame (``Q = I``), of
        every node, or of the nodes ``lo:hi`` of each of ``spans`` (worlds refactorized alone); or,
        with ``frames`` (``(nodes,)`` mat33d each: every node's rotation at an earlier linearization,
        the one factorized), those nodes' rotations there."""
        m = self.op.model
        if spans is None:
            wp.copy(self.frame, self.node_rot)
        for k, (lo, hi) in enumerate(spans or []):
            if frames is None:
                wp.copy(self.frame, self.node_rot, dest_offset=lo, src_offset=lo, count=hi - lo)
            else:
                wp.copy(self.frame, frames[k], dest_offset=lo, src_offset=lo, count=hi - lo)
        launch(kernels.relative_node_rotations(self.q_rot.dtype), m.num_nodes,
               inputs=[self.node_sum, self.frame, m.node_world, None], outputs=[self.node_rot, self.q_rot],
               device=m.device)
        if spans is None:
            self.refreshes += 1
            self._baseline, self._stale = None, False

    def observe(self, iterations: int) -> None:
        """Told the iteration count of each solve; marks the factorization stale when it grows."""
        if self._baseline is None:
            self._baseline = max(int(iterations), 1)
        elif iterations > max(self.refresh_ratio * self._baseline, self.refresh_floor):
            self._stale = True


class WarpedFactor(WarpedFrames):
    """Args:
        operator: the system (rotations, scales, model).
        columns: number of right-hand sides ``k`` of the solves it serves.
        mode: "host", "dense", or "auto" (dense on CUDA up to ``DENSE_LIMIT`` free DOFs).
        precision: "float32" or "float64", of the dense inverse only (it preconditions a float64 CG).
        refresh_ratio, refresh_floor: when to refactorize (see the module doc).
        product: the dense product, "stream", "tiles" or "auto" (streamed for up to
            :data:`STREAM_COLUMNS` right-hand sides, tiled for more: a solve bounded to the columns
            in use takes either).
        tiles: the tiled product's (rows per block, inner dimension per tile, threads per block,
            splits of the inner dimension; 1 if left out).
        stream: the streaming product's (segments of the inner dimension, unrolled loads, numbers
            per load).
    """

    def __init__(self, operator: SystemOperator, columns: int, mode: str = "auto", precision: str = "float32",
                 refresh_ratio: float = 2.0, refresh_floor: int = 40, product: str = "auto",
                 tiles: tuple[int, ...] = TILES, stream: tuple[int, int] = STREAM):
        if mode not in MODES:
            raise ValueError(f"WarpedFactor: mode must be one of {MODES}, got {mode!r}")
        if precision not in ("float64", "float32"):
            raise ValueError(f"WarpedFactor: precision must be 'float64' or 'float32', got {precision!r}")
        if product not in PRODUCTS:
            raise ValueError(f"WarpedFactor: product must be one of {PRODUCTS}, got {product!r}")
        m = operator.model
        d = m.device
        super().__init__(operator, refresh_ratio, refresh_floor)
        self.columns = int(columns)
        self.assembly = Assembly(operator)
        self.factor = CholmodFactor(self.assembly)
        if mode == "auto":
            mode = "dense" if d.is_cuda and self.assembly.size <= DENSE_LIMIT else "host"
        self.mode, self.capturable = mode, mode == "dense"
        n = m.num_nodes
        if self.mode == "host":
            self.u = wp.zeros((self.columns, n), dtype=wp.vec3d, device=d)
            self.y = wp.zeros((self.columns, n), dtype=wp.vec3d, device=d)
        else:
            self.dtype = wp.float64 if precision == "float64" else wp.float32
            self.product, self.inverse = product, None
            self.tiles = (*(int(t) for t in tiles), 1)[:4]
            self.stream = (*(int(t) for t in stream), 1)[:3]
            segments, unroll, width = self.stream
            streamed = [k for k in range(1, self.columns + 1) if self._streams(k)]  # the k it streams
            step = 1
            if streamed:
                step = np.lcm(step, np.lcm(segments * unroll, width))
            if len(streamed) < self.columns:
                step = np.lcm(step, np.lcm(self.tiles[0], self.tiles[1] * self.tiles[3]))
            self.padded = int(-(-3 * n // step) * step)
            self.u = wp.zeros((self.padded, self.columns), dtype=self.dtype, device=d)
            self.y = self.partials = None  # the tiled product's output, the streamed one's partial sums
            if len(streamed) < self.columns:
                self.y = wp.zeros((self.padded, self.columns), dtype=self.dtype, device=d)
                self._rotate_in, self._rotate_out = kernels.flat_rotations(self.dtype)
            if streamed:
                self.segment = self.padded // segments
                self._wide = kernels.wide_type(width, self.dtype)
                self.partials = wp.zeros((segments, max(streamed), self.padded), dtype=self.dtype, device=d)

    def _streams(self, k: int) -> bool:
        """Whether ``k`` right-hand sides take the streamed product (else the tiled one)."""
        return self.product == "stream" or (self.product == "auto" and k <= STREAM_COLUMNS)

    @property
    def memory_bytes(self) -> int:
        """Device memory of the dense inverse (0 in host mode)."""
        return 0 if self.mode == "host" else self.padded ** 2 * (8 if self.dtype == wp.float64 else 4)

    def refresh(self) -> None:
        """Factorize ``A`` at the current rotations and take them as the new frame."""
        m = self.op.model
        self.factor.factorize(self.assembly.values())
        self.take_frame()
        if self.mode == "dense":
            dense = self._dense_inverse()
            if self.inverse is None:
                self.inverse = wp.array(dense, dtype=self.dtype, device=m.device)
                if self.partials is not None:  # the same memory, W numbers per element
                    w = self.stream[2]
                    self._inverse_wide = wp.array(ptr=self.inverse.ptr, dtype=self._wide,
                                                  shape=(self.padded, self.padded // w), device=m.device)
            else:  # in place: a captured solve graph holds this buffer's address
                self.inverse.assign(dense)

    def _dense_inverse(self, tile: int = 2048) -> np.ndarray:
        """``A_f^-1`` as a dense ``(padded, padded)`` array of the stored precision, 0 on fixed
        DOFs: solved in runs of columns of the identity and written in place, then made exactly
        symmetric tile by tile (it is to round-off), so that the host holds one matrix of the
        stored precision at a time, and a run (the whole identity, its solve and their sum held
        five of float64: 17.5 GB at the 10-node PneuNet's 20916 free DOFs)."""
        free = self.assembly.free
        dense = np.zeros((self.padded, self.padded), dtype=np.float64 if self.dtype == wp.float64 else np.float32)
        run = max(1, SOLVE_ENTRIES // len(free))
        for j in range(0, len(free), run):
            cols = min(run, len(free) - j)
            unit = np.zeros((len(free), cols))
            unit[j + np.arange(cols), np.arange(cols)] = 1.0
            dense[np.ix_(free, free[j:j + cols])] = self.factor.solve(unit)
        for i in range(0, self.padded, tile):
            for k in range(i, self.padded, tile):
                mean = 0.5 * (dense[i:i + tile, k:k + tile] + dense[k:k + tile, i:i + tile].T)
                dense[i:i + tile, k:k + tile] = mean
                dense[k:k + tile, i:i + tile] = mean.T
        return dense

    def apply(self, r: wp.array, z: wp.array) -> None:
        """``z = Q A_f^-1 Q^T r`` for ``(k, n)`` vec3d arrays, ``k <= columns`` (the first ``k`` of
        the solves it serves; the dense products are compiled per ``k``), fixed DOFs 0."""
        m, d = self.op.model, self.op.model.device
        shape = r.shape
        k = shape[0]
        if self.mode == "dense" and self._streams(k):
            _, rotate_in, partial_product, rotate_out = kernels.stream_kernels(k, self.dtype, *self.stream)
            launch(rotate_in, shape, inputs=[r, self.q_rot, m.mask], outputs=[self.u], device=d)
            launch(partial_product, (self.stream[0], self.padded // self.stream[2]),
                   inputs=[self._inverse_wide, self.u, self.segment], outputs=[self.partials], device=d)
            launch(rotate_out, shape, inputs=[self.partials, self.q_rot, m.mask], outputs=[z], device=d)
            return
        if self.mode == "dense":
            launch(self._rotate_in, shape, inputs=[r, self.q_rot, m.mask], outputs=[self.u], device=d)
            if self.tiles[3] > 1:
                self.y.zero_()  # the splits add into it
            product = kernels.dense_product(k, self.dtype, self.tiles[0], self.tiles[1], self.tiles[3])
            wp.launch_tiled(product, dim=[self.padded // self.tiles[0], self.tiles[3]],
                            inputs=[self.inverse, self.u], outputs=[self.y], block_dim=self.tiles[2], device=d)
            launch(self._rotate_out, shape, inputs=[self.y, self.q_rot, m.mask], outputs=[z], device=d)
            return
        u, y = self.u[:k], self.y[:k]
        launch(kernels.rotate_in, shape, inputs=[r, self.q_rot, m.mask], outputs=[u], device=d)
        y.assign(solve_dofs(self.factor, u.numpy().reshape(k, -1)).reshape(k, -1, 3))
        launch(kernels.rotate_out, shape, inputs=[y, self.q_rot, m.mask], outputs=[z], device=d)
