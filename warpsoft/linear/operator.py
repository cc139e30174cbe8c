"""The step's system ``A = mass_scale M + stiffness_scale K(R)``: applied matrix-free, or from its
3x3 blocks assembled at each linearization (:class:`AssembledBlocks`)."""

from __future__ import annotations

from functools import partial

import numpy as np
import warp as wp

from warpsoft.kernels.linear import assembled as assembled_kernels
from warpsoft.kernels.linear import cg as linalg

from ..elastic import element_model
from ..launch import launch
from ..model import Model
from ..processes import in_threads, usable_cores

OPERATORS = ("auto", "matrix_free", "assembled")
# "auto" assembles the blocks on CUDA from this many elements (a batch of designs): there the
# matrix-free product's atomic additions bind it (measured on an H200, docs/performance.md)
ASSEMBLED_FROM = 1 << 16
# the assembled blocks' rows a chunk on CUDA (a warp's threads; kernels/linear/assembled.py); 1 on
# the CPU, whose one thread walks the rows one after another and would only read the padding
CHUNK_ROWS = 32


class SystemOperator:
    """``y[c] = mass_scale M x[c] + stiffness_scale K(rot) x[c]`` for the model's elements.

    ``rot`` (m mat33d) holds the element rotations of the current linearization;
    ``x`` and ``y`` are ``(k, n)`` arrays of vec3d. ``elastic`` is the element model (the
    model's corotational one by default). ``assembled``: keep ``K``'s 3x3 blocks, refreshed by
    :meth:`linearized`, and apply them (:class:`AssembledBlocks`); else every product is formed
    element by element.
    """

    def __init__(self, model: Model, rot: wp.array, elastic=None, assembled: bool = False):
        self.model, self.rot = model, rot
        self.elastic = elastic if elastic is not None else element_model(model)
        self.mass_scale = 0.0
        self.stiffness_scale = 1.0
        self.blocks = AssembledBlocks(model, self.elastic) if assembled else None
        # the worlds whose linearization is made anew at the next one (``(worlds,)`` int32 on the
        # device, ``kernels/worlds.py``; None: all): set once by the step's Newton iterations
        self.moving = None

    def set_scales(self, mass_scale: float, stiffness_scale: float) -> None:
        if mass_scale != 0.0 and self.model.mass is None:
            raise ValueError("SystemOperator: mass_scale != 0 in a model without mass")
        self.mass_scale, self.stiffness_scale = float(mass_scale), float(stiffness_scale)

    def linearized(self) -> None:
        """``rot`` was rewritten (a new linearization): the assembled blocks follow it (nothing to
        do matrix-free)."""
        if self.blocks is not None:
            self.blocks.refresh(self.rot, self.moving)

    def apply(self, x: wp.array, y: wp.array, done: wp.array | None = None) -> None:
        """``y = A x`` for ``(k, n)`` columns: ``y`` vec3d, ``x`` vec3d (or vec3f with the assembled
        blocks). ``done``: a solver's CG scalars ``(k, worlds, slots)``; the columns of the worlds
        they mark converged are skipped and keep what ``y`` held (a converged world stops costing
        work)."""
        m = self.model
        if self.blocks is not None:
            self.blocks.apply(x, y, self.mass_scale, self.stiffness_scale, done)
            return
        if x.dtype != wp.vec3d:
            raise ValueError(f"SystemOperator: the matrix-free product takes vec3d columns, got {x.dtype.__name__}; "
                             "single-precision columns need the assembled operator")
        if self.mass_scale != 0.0:
            launch(linalg.mass_product, x.shape, inputs=[x, m.mass, self.mass_scale, m.node_world, done],
                   outputs=[y], device=m.device)
        elif done is None:
            y.zero_()
        else:
            launch(linalg.zero_columns, x.shape, inputs=[m.node_world, done], outputs=[y], device=m.device)
        self.elastic.apply(x, y, self.rot, self.stiffness_scale, done)


def chunked(rows: np.ndarray, cols: np.ndarray, n: int,
            chunk_rows: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The sliced layout of the slots ``(rows, cols)`` (``(slots,)`` each, sorted by row) of ``n``
    rows, in chunks of ``chunk_rows`` rows: ``place`` ``(slots,)`` each slot's place, ``column``
    ``(places,)`` (a padding place: its lane's row, the last row past the end), ``chunk_start`` and
    ``chunk_slots`` ``(chunks,)``: a chunk's first place over ``chunk_rows`` and its rows' slots."""
    c = int(chunk_rows)
    row_start = np.searchsorted(rows, np.arange(n + 1))
    length = np.zeros(-(-n // c) * c, dtype=np.int64)
    length[:n] = np.diff(row_start)
    chunk_slots = length.reshape(-1, c).max(axis=1)
    chunk_start = np.concatenate([[0], np.cumsum(chunk_slots)[:-1]])
    nth = np.arange(len(rows)) - row_start[rows]  # a slot's rank in its row
    place = (chunk_start[rows // c] + nth) * c + rows % c
    places = int(chunk_slots.sum()) * c
    lane_row = np.repeat(np.arange(len(chunk_slots)) * c, chunk_slots * c) + np.arange(places) % c
    column = np.minimum(lane_row, n - 1)
    column[place] = cols
    return place, column.astype(np.int32), chunk_start.astype(np.int32), chunk_slots.astype(np.int32)


def _world_groups(model: Model, elastic) -> list[list[tuple[int, np.ndarray]]]:
    """The element blocks cut into groups of whole worlds, about one a core: each a list of
    ``(first block, elements)``, its elements' node ids ``(count, k)`` and the index of their first
    block among all. With several element models, one group of them all (their elements come
    model after model, not world after world)."""
    if len(elastic.groups) != 1:
        parts, b0 = [], 0
        for g in elastic.groups:
            parts.append((b0, g.group.elems_np))
            b0 += g.group.elems_np.shape[1] ** 2 * g.group.count
        return [parts]
    elems = elastic.groups[0].group.elems_np
    k2 = elems.shape[1] ** 2
    starts = model.world_elem_start.astype(np.int64)
    wanted = np.linspace(0, len(elems), usable_cores() + 1)[1:-1]  # (cut at the next world's start)
    cuts = np.unique(np.concatenate([[0], starts[np.minimum(np.searchsorted(starts, wanted), len(starts) - 1)],
                                     [len(elems)]]))
    return [[(k2 * int(a), elems[a:b])] for a, b in zip(cuts[:-1], cuts[1:], strict=True) if b > a]


def _slots_of(parts: list[tuple[int, np.ndarray]], n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One group of worlds (:func:`_world_groups`): its slots' keys ``row n + column`` in order,
    each slot's count of element blocks, and those blocks (their index among all, int32) slot by
    slot, each slot's in their own order (a stable sort). Block ``k a + c`` of an element couples its
    nodes ``a`` and ``c`` (:func:`~warpsoft.elastic.block_pairs`)."""
    keys, index = [], []
    for b0, elems in parts:
        e = np.asarray(elems, dtype=np.int64)
        keys.append((e[:, :, None] * n + e[:, None, :]).reshape(-1))
        index.append(np.arange(b0, b0 + keys[-1].size, dtype=np.int32))
    key, index = (np.concatenate(keys), np.concatenate(index)) if len(keys) > 1 else (keys[0], index[0])
    order = np.argsort(key, kind="stable")
    ordered = key[order]
    first = np.flatnonzero(np.concatenate([[True], ordered[1:] != ordered[:-1]]))
    return ordered[first], np.diff(np.append(first, len(key))), index[order]


class AssembledBlocks:
    """``K`` as 3x3 blocks (N/m) by node rows, both triangles, in chunks of ``chunk_rows`` rows
    (sliced ELLPACK: ``kernels/linear/assembled.py``; :data:`CHUNK_ROWS` on CUDA, 1 on the CPU):
    ``chunk_start`` and ``chunk_slots`` ``(chunks,)``, ``column`` and ``values`` ``(slots,)``, the
    padding included (a zero block at the row's own column). The slots are the node pairs that
    share an element; each sums the element blocks listed for it (``slot_start`` ``(slots + 1,)``,
    ``contributions`` ``(element blocks,)``: indexes into the element models' blocks,
    :meth:`Elements.blocks`; none for a padding slot). A refresh sums them into the slots.
    ``fused``: a thread per slot forms its element blocks (where the element model can: one
    corotational group); else, or with ``fused=False``, the element blocks are written first
    (``element_blocks``, ``(element blocks,)`` mat33d) and gathered. None: fused on CUDA (H200, 1024
    Diamonds: 3.33 ms against 13.42), written on the CPU (two Diamonds on one thread: 2.1 ms fused,
    0.76 written). A product reads each slot once for all its columns. Device memory: 4 bytes an
    element block (76 where they are written), 80 a slot (a Diamond: 16 element blocks an element,
    about 10.5 slots a node, 1.31 times as many with the padding of chunks of 32 rows)."""

    def __init__(self, model: Model, elastic, fused: bool | None = None, chunk_rows: int | None = None):
        self.model, self.elastic = model, elastic
        n, d = model.num_nodes, model.device
        self.chunk_rows = int(chunk_rows or (CHUNK_ROWS if d.is_cuda else 1))
        blocks = elastic.num_blocks
        if blocks >= 2 ** 31:
            raise ValueError(f"AssembledBlocks: {blocks} element blocks pass the 2^31 a Warp index holds; "
                             "step fewer designs at a time, or use operator='matrix_free'")
        # each world group's slots (node pairs) in order, their element blocks' counts, and those
        # blocks in slot order, side by side in threads (a batch's tens of millions of element blocks)
        found = in_threads(partial(_slots_of, n=n), _world_groups(model, elastic))
        slots, runs = np.concatenate([f[0] for f in found]), np.concatenate([f[1] for f in found])
        self.filled = len(slots)  # the slots that hold a block (the padding aside)
        place, column, chunk_start, chunk_slots = chunked(slots // n, slots % n, n, self.chunk_rows)
        self.num_slots = len(column)
        if self.num_slots >= 2 ** 31:
            raise ValueError(f"AssembledBlocks: {self.num_slots} slots pass the 2^31 a Warp index holds; "
                             "step fewer designs at a time, or use operator='matrix_free'")
        self.chunk_start = wp.array(chunk_start, dtype=wp.int32, device=d)
        self.chunk_slots = wp.array(chunk_slots, dtype=wp.int32, device=d)
        self.column = wp.array(column, dtype=wp.int32, device=d)
        self.place = place.astype(np.int32)  # (filled,) where each slot of the rows in order lies, host (by_rows)
        # each place's element blocks: a filled slot's, in the order of the places; none for the padding
        count = np.zeros(self.num_slots, dtype=np.int64)
        count[place] = runs
        slot_start = np.concatenate([[0], np.cumsum(count)])
        contributions = np.empty(blocks, dtype=np.int32)
        at = np.cumsum([0] + [len(f[0]) for f in found])

        def scatter(g: int) -> None:  # a group's blocks to their places' lists
            mine, order = runs[at[g]:at[g + 1]], found[g][2]
            head = slot_start[place[at[g]:at[g + 1]]] - (np.cumsum(mine) - mine)
            contributions[np.repeat(head, mine) + np.arange(len(order))] = order

        in_threads(scatter, list(range(len(found))))
        self.slot_start = wp.array(slot_start.astype(np.int32), device=d)
        self.contributions = wp.array(contributions, device=d)
        self.values = wp.zeros(self.num_slots, dtype=wp.mat33d, device=d)
        self.no_mass = wp.zeros(0, dtype=wp.float64, device=d)
        groups = elastic.groups
        can = len(groups) == 1 and hasattr(groups[0].kernels, "rotated_gradients")
        self.fused = can and (d.is_cuda if fused is None else bool(fused))
        self.element_blocks = None if self.fused else wp.zeros(blocks, dtype=wp.mat33d, device=d)
        # per element block: its index (4 bytes) and a 16th of the element's rotated gradients and
        # moduli (112 bytes) when fused, else the block itself too (72 bytes)
        self.memory_bytes = (11 if self.fused else 76) * blocks + 80 * self.num_slots + 8 * len(chunk_start)

    def by_rows(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The filled slots read back, rows in order: ``(rows, columns, values)``, ``(filled,)`` each
        (values ``(filled, 3, 3)``, N/m)."""
        c = self.chunk_rows
        chunk = np.searchsorted(self.chunk_start.numpy().astype(np.int64) * c, self.place, side="right") - 1
        return chunk * c + self.place % c, self.column.numpy()[self.place], self.values.numpy()[self.place]

    def refresh(self, rot: wp.array, moving: wp.array | None = None) -> None:
        """The blocks of ``K`` at the rotations ``rot`` (the element models' linearization); fused,
        the slots of the worlds that stay (``moving``, ``kernels/worlds.py``) keep theirs."""
        if self.fused and self.elastic.groups[0].gather_blocks(rot, self.slot_start, self.contributions, self.values,
                                                               moving):
            return
        self.elastic.blocks(rot, self.element_blocks)
        launch(assembled_kernels.gather_blocks, self.num_slots,
               inputs=[self.element_blocks, self.slot_start, self.contributions], outputs=[self.values],
               device=self.model.device)

    def apply(self, x: wp.array, y: wp.array, mass_scale: float, stiffness_scale: float,
              done: wp.array | None = None) -> None:
        """``y[c] = mass_scale M x[c] + stiffness_scale K x[c]`` for ``(k, n)`` ``x`` (vec3d or vec3f)
        and ``y`` (vec3d); the converged columns of ``done``'s worlds keep what ``y`` held."""
        m = self.model
        mass = m.mass if mass_scale != 0.0 else self.no_mass
        launch(assembled_kernels.block_product(x.shape[0], x.dtype), m.num_nodes,
               inputs=[x, self.chunk_start, self.chunk_slots, self.chunk_rows, self.column, self.values,
                       stiffness_scale, mass, mass_scale, m.node_world, done], outputs=[y], device=m.device)
