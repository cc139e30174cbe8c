"""The warped preconditioner world by world (``preconditioner="blocks"``): a dense inverse per
world on the device, for models of many worlds (batches of designs).

The worlds of a model are separate bodies, so ``A`` is block diagonal. :class:`WarpedFactor`'s
dense mode inverts the whole of it, ``N^2`` numbers for ``N`` free DOFs over all worlds: four
Diamonds already pass its 12000-DOF limit, and a batch then fell back to host solves (30 times
slower than the designs one at a time on an H200, docs/performance.md). Here each world keeps
only its own block, ``sum_w N_w^2`` numbers, and the product of every world runs in one launch
(``kernels/linear/blocks.py``).

Worlds whose system at the factorized state is the same up to a factor (the same mesh, supports
and Poisson ratio, quasi-static, only Young's modulus differing: a sweep over a modulus) share
one block, each with its own scale: ``(s A)^-1 = A^-1 / s``. Sharing is decided at the first
factorization, by comparing the assembled values. A later refresh (when the iterations grow, as
in :class:`WarpedFactor`) refactorizes each block at its first world's state and keeps the
sharing: for the other worlds of a block that is an approximate inverse, which a preconditioner
may be.

Each block is inverted on the host by LAPACK (a dense Cholesky ``potrf`` and ``potri``): 1.6 s
for the Diamond's 4227 free DOFs on the 2-core VM. A sweep of many different meshes pays this
once per mesh, at its first step.
"""

from __future__ import annotations

import hashlib

import numpy as np
import scipy.linalg as sla
import warp as wp

from warpsoft.kernels.linear import blocks as kernels
from warpsoft.kernels.linear import warped as rotations
from warpsoft.kernels.linear.cg import NUM_SCALARS

from ..elastic import block_pairs
from ..errors import SceneError
from ..launch import launch
from .operator import SystemOperator
from .warped import WarpedFrames

UNROLL, WIDTH = 2, 2  # loads in flight per thread, numbers per load (the whole-model product's best: warped.STREAM)
THREADS = 1 << 20  # segments are added until the product has about this many threads (enough loads in flight)
GROUPS = (1, 2, 4, 8)  # worlds of one block a thread of the product may serve
SUMS = 48  # a thread's sums at most (G worlds x W numbers x k columns): past this they spill from registers
TILE = (64, 64, 64)  # the tiled product's rows and columns of a tile of the result, and rows of a slice
TILE_THREADS = 128  # threads of a tile
TILED_FROM = 8  # worlds of one block from which its product is tiled (below, streamed)


class WorldGroups(WarpedFrames):
    """What the preconditioners kept world by world share: each world's mesh (its elements' local
    node ids and supports, as a key) and free DOFs, which worlds share one factorization (the same
    mesh and supports, systems proportional at the first factorization: :meth:`_group`), and the
    CG scalars of the solver served, by which a world whose columns all converged skips its work.

    Attributes: ``local_free`` (per world, its free DOFs ``3 i + a`` in its own numbering),
    ``mesh_of`` (per world, its mesh key), ``meshes`` (key -> (local elements, nodes)), and after
    the first factorization ``block_of`` ``(worlds,)``, ``scale_np`` ``(worlds,)`` (world ``w``'s system
    is ``scale_np[w]`` times its block's) and ``first_world`` (each block's world).
    """

    def __init__(self, operator: SystemOperator, columns: int, refresh_ratio: float, refresh_floor: int,
                 share: bool, share_tolerance: float, frame_kind=wp.mat33d):
        super().__init__(operator, refresh_ratio, refresh_floor, frame_kind)
        m = operator.model
        if operator.elastic.kinds != ["corotational"]:
            quad = next(b for b in m.bodies if b.element != "corotational")
            raise SceneError(f"{type(self).__name__}: body '{quad.name}' of world {quad.world} has {quad.element} "
                             "elements; the per-world preconditioners take linear tetrahedra only so far: use "
                             "preconditioner='host' or 'dense', or solver='direct'")
        self.columns = int(columns)
        self.share, self.share_tolerance = bool(share), float(share_tolerance)
        starts, estarts = m.world_node_start.astype(np.int64), m.world_elem_start
        self.local_free, self.mesh_of, self.meshes = [], [], {}
        for w in range(m.num_worlds):
            n0, n1 = int(starts[w]), int(starts[w + 1])
            local = np.ascontiguousarray(m.tets_np[estarts[w]:estarts[w + 1]] - n0)
            mask = np.ascontiguousarray(m.mask_np[n0:n1])
            self.local_free.append(np.flatnonzero(mask.ravel() > 0))
            key = (n1 - n0, hashlib.sha1(local.tobytes() + mask.tobytes()).hexdigest())
            self.meshes.setdefault(key, (local, n1 - n0))
            self.mesh_of.append(key)
        self.block_of = self.scale_np = self.first_world = None  # decided at the first factorization
        # the CG scalars of the solver served (:meth:`watch`); until then none reads as converged
        self._done = wp.zeros((self.columns, m.num_worlds, NUM_SCALARS), dtype=wp.float64, device=m.device)

    def watch(self, scal: wp.array) -> None:
        """The CG scalars ``(columns, worlds, slots)`` of the solver it serves: a world whose columns
        are all done skips its work."""
        self._done = scal

    @property
    def blocks(self) -> int:
        """Number of distinct factorizations."""
        return 0 if self.block_of is None else int(self.block_of.max()) + 1

    def _values(self, blocks: wp.array, w: int) -> np.ndarray:
        """World ``w``'s system as numbers that fix it: its element blocks (scaled) and, when the
        system has mass, its nodes' masses (scaled)."""
        m, op = self.op.model, self.op
        e0, e1 = int(m.world_elem_start[w]), int(m.world_elem_start[w + 1])
        values = op.stiffness_scale * blocks[16 * e0:16 * e1].numpy().ravel()
        if op.mass_scale != 0.0:
            values = np.concatenate([values, op.mass_scale * m.mass_np[m.world_nodes(w)]])
        return values

    def _group(self, blocks: wp.array) -> None:
        """Which worlds share a block: the same mesh and supports, proportional values. A world
        takes the block of the first earlier world of its mesh it is proportional to; the blocks
        are numbered by their first worlds. Done mesh by mesh, holding the values of one mesh's
        blocks at a time (a Diamond's are 3.3-6.9 MB: 4096 of them held at once, about 19 GB)."""
        m = self.op.model
        leader, scale = np.arange(m.num_worlds), np.ones(m.num_worlds)  # each world's block's first world
        by_mesh: dict[tuple, list[int]] = {}
        for w in range(m.num_worlds):
            by_mesh.setdefault(self.mesh_of[w], []).append(w)
        for worlds in by_mesh.values() if self.share else []:
            if len(worlds) < 2:  # (its world leads its own block: its values unread)
                continue
            reps: list[tuple[int, np.ndarray]] = []  # this mesh's blocks: (first world, its values)
            for w in worlds:
                values = self._values(blocks, w)
                for first, ref in reps:
                    s = float(values @ ref) / max(float(ref @ ref), np.finfo(float).tiny)
                    if s > 0 and np.abs(values - s * ref).max() <= self.share_tolerance * np.abs(values).max():
                        leader[w], scale[w] = first, s
                        break
                else:
                    reps.append((w, values))
        self.first_world = np.flatnonzero(leader == np.arange(m.num_worlds))
        number = np.zeros(m.num_worlds, dtype=np.int64)
        number[self.first_world] = np.arange(len(self.first_world))
        self.block_of, self.scale_np = number[leader], scale


class WorldBlocks(WorldGroups):
    """``P^-1 = Q blockdiag(s_w A_b(w)^-1) Q^T``: :class:`WarpedFactor`'s preconditioner with one
    dense inverse per world (or per group of proportional worlds) on the device.

    Args:
        operator: the system (rotations, scales, model).
        columns: right-hand sides ``k`` of the solves it serves.
        precision: "float32" or "float64", of the dense inverses (the CG runs in float64).
        refresh_ratio, refresh_floor: when to refactorize, as :class:`WarpedFactor`'s.
        share: let proportional worlds share a block (False: one block per world).
        share_tolerance: world ``w`` shares block ``b`` when ``max|A_w - s A_b| <= tol max|A_w|`` for
            some ``s > 0`` (the element blocks and lumped masses compared; the same mesh and supports).
        tiled_from: a block shared by at least this many worlds is applied as one tiled matrix
            product over all their columns (``kernels/linear/blocks.py``); a block of fewer is
            streamed. None: ``TILED_FROM``.

    Attributes: ``blocks`` (distinct inverses), ``block_of`` ``(worlds,)``, ``scale`` ``(worlds,)``,
    ``refreshes``, ``memory_bytes``.
    """

    capturable = True

    def __init__(self, operator: SystemOperator, columns: int, precision: str = "float32",
                 refresh_ratio: float = 2.0, refresh_floor: int = 40, share: bool = True,
                 share_tolerance: float = 1e-10, tiled_from: int | None = None):
        if precision not in ("float64", "float32"):
            raise ValueError(f"WorldBlocks: precision must be 'float64' or 'float32', got {precision!r}")
        m = operator.model
        d = m.device
        super().__init__(operator, columns, refresh_ratio, refresh_floor, share, share_tolerance)
        tiled_from = TILED_FROM if tiled_from is None else tiled_from
        if int(tiled_from) < 1:
            raise ValueError(f"WorldBlocks: tiled_from must be at least 1, got {tiled_from!r}")
        self.tiled_from = int(tiled_from)
        self.dtype = wp.float64 if precision == "float64" else wp.float32
        n = m.num_nodes
        # the flat layout: world w's 3 n_w DOFs padded to a multiple of S * UNROLL rows (and of
        # WIDTH, and of the tiles' rows)
        starts = m.world_node_start.astype(np.int64)
        dofs = 3 * np.diff(starts)
        segments = 1
        while segments < 64 and segments * int(dofs.sum()) // WIDTH < THREADS:
            segments *= 2
        self.segments = segments
        quantum = int(np.lcm.reduce([segments * UNROLL, WIDTH, TILE[0], TILE[2]]))
        self.size_np = (-(-dofs // quantum) * quantum).astype(np.int64)  # (worlds,) rows of each world
        first = np.concatenate([[0], np.cumsum(self.size_np)])
        self.rows = int(first[-1])
        if self.rows >= 2 ** 31:
            raise SceneError(f"WorldBlocks: {self.rows} rows over {m.num_worlds} worlds pass the 2^31 a Warp "
                             "array holds; step fewer worlds at a time")
        node_row = first[m.node_world_np] + 3 * (np.arange(n) - starts[m.node_world_np])
        self.node_row = wp.array(node_row.astype(np.int32), dtype=wp.int32, device=d)
        self.node_world = m.node_world
        self.first_row = wp.array(first[:-1].astype(np.int32), dtype=wp.int32, device=d)
        self.size = wp.array(self.size_np.astype(np.int32), dtype=wp.int32, device=d)
        self.u = wp.zeros((self.rows, self.columns), dtype=self.dtype, device=d)
        self.partials = wp.zeros((segments, self.columns, self.rows), dtype=self.dtype, device=d)
        # worlds of one mesh share the map from element block entries to their dense matrix's entries
        self._entries = {key: _dense_entries(local, nodes) for key, (local, nodes) in self.meshes.items()}
        self.inverse = self._wide = self.scale = self.block_row = None

    @property
    def memory_bytes(self) -> int:
        """Device memory of the dense inverses (0 before the first factorization)."""
        return 0 if self.inverse is None else self.inverse.capacity

    def _dense(self, values: np.ndarray, w: int) -> np.ndarray:
        """World ``w``'s block of ``A`` over its free DOFs, dense ``(f_w, f_w)``, from :meth:`_values`."""
        n = 3 * (int(self.op.model.world_node_start[w + 1]) - int(self.op.model.world_node_start[w]))
        entries = self._entries[self.mesh_of[w]]
        dense = np.bincount(entries, weights=values[:len(entries)], minlength=n * n).reshape(n, n)
        if len(values) > len(entries):  # lumped masses on the diagonal
            dense[np.diag_indices(n)] += np.repeat(values[len(entries):], 3)
        lf = self.local_free[w]
        return dense[np.ix_(lf, lf)]

    def _allocate(self) -> None:
        m, d = self.op.model, self.op.model.device
        sizes = self.size_np[self.first_world]  # (blocks,)
        block_first = np.concatenate([[0], np.cumsum(sizes)])
        width = int(sizes.max())
        need = int(block_first[-1]) * width * (8 if self.dtype == wp.float64 else 4)
        free_bytes = getattr(d, "free_memory", None) if d.is_cuda else None
        if free_bytes is not None and need > 0.9 * free_bytes:
            raise SceneError(f"WorldBlocks: the dense inverses of {len(sizes)} distinct worlds (of {m.num_worlds}) "
                             f"need {need / 1e9:.1f} GB, {d} has {free_bytes / 1e9:.1f} GB free: step fewer designs "
                             "at a time, or use preconditioner='host'")
        self.block_first = block_first
        self.inverse = wp.zeros((int(block_first[-1]), width), dtype=self.dtype, device=d)
        self._wide = wp.array(ptr=self.inverse.ptr, dtype=rotations.wide_type(WIDTH, self.dtype),
                              shape=(int(block_first[-1]), width // WIDTH), device=d)
        npd = np.float64 if self.dtype == wp.float64 else np.float32
        self.block_row = wp.array(block_first[self.block_of].astype(np.int32), dtype=wp.int32, device=d)
        self.scale = wp.array((1.0 / self.scale_np).astype(npd), dtype=self.dtype, device=d)
        lists = [np.flatnonzero(self.block_of == b) for b in range(len(sizes))]  # each block's worlds
        tiled = [b for b, ws in enumerate(lists) if len(ws) >= self.tiled_from]
        self._tile(tiled, lists)
        # the other blocks' worlds dealt into chunks of at most G of one block, for each G the product may take
        lists = [ws for b, ws in enumerate(lists) if b not in tiled]
        most = max((len(ws) for ws in lists), default=0)
        self.chunks = {}
        for g in (g for g in GROUPS if lists and (g == 1 or g // 2 < most)):
            table = [np.pad(ws[i:i + g], (0, g - len(ws[i:i + g])), constant_values=-1)
                     for ws in lists for i in range(0, len(ws), g)]
            table = np.array(table, dtype=np.int32).reshape(-1, g)
            threads = self.size_np[table[:, 0]] // WIDTH  # each chunk's threads per segment
            first = np.concatenate([[0], np.cumsum(threads)])
            self.chunks[g] = (wp.array(np.repeat(np.arange(len(table), dtype=np.int32), threads), dtype=wp.int32,
                                       device=d),
                              wp.array(first[:-1].astype(np.int32), dtype=wp.int32, device=d),
                              wp.array(table, dtype=wp.int32, device=d), int(first[-1]))

    def _tile(self, tiled: list[int], lists: list[np.ndarray]) -> None:
        """The layout of the tiled product for the blocks ``tiled`` (``lists[b]``: block ``b``'s
        worlds): block ``b``'s ``n`` worlds own a region of ``k n`` columns of ``G``, padded to whole
        tiles (the columns still running are packed at its front at each application); its rows,
        ``size`` of them, are cut into tiles of ``TM`` rows."""
        m, (tm, tn, _) = self.op.model, TILE
        d = m.device
        flag = np.zeros(m.num_worlds, dtype=np.int32)
        tiles, region_size, region_col, world_list, list_region = [], [], [], [], []
        width = 0
        for g, b in enumerate(tiled):
            ws, size = lists[b], int(self.size_np[lists[b][0]])
            flag[ws] = 1
            region_size.append(size)
            region_col.append(width)
            world_list.extend(ws.tolist())
            list_region.extend([g] * len(ws))
            span = -(-self.columns * len(ws) // tn) * tn
            tiles += [(int(self.block_first[b]) + r, r, width + c, g) for r in range(0, size, tm)
                      for c in range(0, span, tn)]
            width += span
        rows = max(region_size, default=1)

        def ints(values):
            return wp.array(np.array(values if len(values) else [0], dtype=np.int32), dtype=wp.int32, device=d)

        self.tiled, self.tiled_col = ints(flag), wp.zeros((self.columns, m.num_worlds), dtype=wp.int32, device=d)
        self.tiles = wp.array(np.array(tiles, dtype=np.int32), dtype=wp.vec4i, device=d) if tiles else None
        self.world_list, self.list_region = ints(world_list), ints(list_region)
        self.region_size, self.region_col = ints(region_size), ints(region_col)
        self.count = wp.zeros(max(len(tiled), 1), dtype=wp.int32, device=d)  # each region's columns in use
        self.g = wp.zeros((rows, max(width, 1)), dtype=self.dtype, device=d)
        self.g_out = wp.zeros_like(self.g)
        self.tiled_worlds = len(world_list)

    def refresh(self) -> None:
        """Factorize each block at the current rotations (its first world's state) and take them
        as the new frame."""
        m = self.op.model
        blocks = wp.zeros(16 * m.num_elements, dtype=wp.mat33d, device=m.device)  # made here, freed after
        self.op.elastic.blocks(self.op.rot, blocks)
        if self.block_of is None:
            self._group(blocks)
            self._allocate()
        npd = np.float64 if self.dtype == wp.float64 else np.float32
        for b, w in enumerate(self.first_world):
            lf = self.local_free[w]
            dense = np.zeros((self.block_first[b + 1] - self.block_first[b], self.inverse.shape[1]), dtype=npd)
            dense[np.ix_(lf, lf)] = self._inverse(self._dense(self._values(blocks, w), w), w)
            self.inverse[int(self.block_first[b]):int(self.block_first[b + 1])].assign(dense)  # in place
        self.take_frame()

    def _inverse(self, dense: np.ndarray, w: int) -> np.ndarray:
        """``dense^-1`` by LAPACK's Cholesky; a clear error naming the world when it is not positive definite."""
        factor, info = sla.lapack.dpotrf(dense, lower=1, overwrite_a=1)
        if info == 0:
            inv, info = sla.lapack.dpotri(factor, lower=1, overwrite_c=1)
        if info != 0:
            name = self.op.model.scenes[w].name
            raise SceneError(f"WorldBlocks: world {w} (scene '{name}'): its system is not positive definite "
                             f"(LAPACK info {info}); is the body held?")
        return np.tril(inv) + np.tril(inv, -1).T

    def apply(self, r: wp.array, z: wp.array) -> None:
        """``z = Q blockdiag(s_w A_b^-1) Q^T r`` for ``(k, n)`` vec3d arrays, ``k <= columns``; fixed DOFs 0."""
        m, d = self.op.model, self.op.model.device
        k = r.shape[0]
        group = max((g for g in self.chunks if g == 1 or g * WIDTH * k <= SUMS), default=1)
        rotate_in, product, rotate_out = kernels.block_kernels(k, self.dtype, self.segments, UNROLL, WIDTH, group)
        layout = [self.node_row, self.node_world, self.first_row, self.tiled, self.tiled_col]
        if self.tiles is not None:  # the tiled blocks' columns still running, packed at their regions' front
            self.count.zero_()
            launch(kernels.pack_tiled_columns, (k, self.tiled_worlds),
                   inputs=[self.world_list, self.list_region, self.region_col, self._done],
                   outputs=[self.count, self.tiled_col], device=d)
        launch(rotate_in, r.shape, inputs=[r, self.q_rot, m.mask, *layout, self._done], outputs=[self.u, self.g],
               device=d)
        if self.chunks:  # the streamed blocks
            row_chunk, chunk_first, chunk_worlds, threads = self.chunks[group]
            launch(product, (self.segments, threads),
                   inputs=[self._wide, self.u, row_chunk, chunk_first, chunk_worlds, self.first_row, self.block_row,
                           self.size, self._done], outputs=[self.partials], device=d)
        if self.tiles is not None:  # the tiled blocks
            wp.launch_tiled(kernels.tiled_kernel(self.dtype, *TILE), dim=(self.tiles.shape[0],),
                            inputs=[self.inverse, self.g, self.tiles, self.region_size, self.region_col, self.count],
                            outputs=[self.g_out], block_dim=TILE_THREADS, device=d)
        launch(rotate_out, r.shape, inputs=[self.partials, self.g_out, self.q_rot, m.mask, *layout, self.scale,
                                            self._done], outputs=[z], device=d)


def _dense_entries(tets: np.ndarray, nodes: int) -> np.ndarray:
    """For the element blocks of a mesh (``(16 m,)`` 3x3 blocks, block ``4 a + b`` of element ``e``
    coupling its nodes ``a`` and ``b``), the flat index ``3 n`` by ``3 n`` of each number in the
    dense matrix: ``(144 m,)``, in the blocks' order."""
    pairs = block_pairs(tets)  # (16 m, 2) the nodes each block couples, in the blocks' order
    rows = 3 * pairs[:, 0, None, None] + np.arange(3)[:, None]  # (16 m, 3, 1): entry (i, j)'s row
    cols = 3 * pairs[:, 1, None, None] + np.arange(3)[None, :]  # (16 m, 1, 3): its column
    return (rows * (3 * nodes) + cols).ravel()
