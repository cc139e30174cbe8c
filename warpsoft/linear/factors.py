"""The warped preconditioner world by world with sparse factors (``preconditioner="factors"``).

:class:`~warpsoft.linear.blocks.WorldBlocks` keeps a dense inverse per world: ``N_w^2`` numbers,
read whole at every CG iteration, and inverted on the host by LAPACK (1.6 s for a Diamond on the
2-core VM). That is what a batch of a few meshes can afford (worlds of one mesh share it), not one
of many different meshes, and even with a few it steps slower: 1024 Diamonds of 4 meshes (4 blocks
either way) on one H200 took 87.23 ms a step with dense inverses and 44.12 ms with these factors,
which are therefore the default for several worlds on CUDA. Here each world (or group of
proportional worlds, as there) keeps the sparse Cholesky factor of its rest system instead,
CHOLMOD's: 0.1-0.4 M numbers for the Diamond's 3048-5157 free DOFs, against 9-27 M. Its two
triangular solves run on the device as levels of independent rows
(:mod:`warpsoft.linear.supernodal`): one launch per level, every world's rows of that level in it. A
level's launch has a floor that converged worlds do not lower (and the last CG iterations run only
the slowest designs), so the factors take METIS's nested dissection, whose elimination trees are
shallow: 11-16 levels each way for a sample of 128 of 1024 different Diamonds, against 30-53 with
CHOLMOD's own ordering (AMD), for 1 % more entries (H200, those 1024: P^-1 9.18 -> 7.20 ms, a step's
graphs 154.9 -> 129.6 ms). In the levels of short rows (a thread a row) the entries lie in slices of
32 rows, interleaved, so that a warp reads side by side (P^-1 7.22 -> 6.70 ms for 3 % more entries,
in padding). The default layout is now panels
(:meth:`~warpsoft.linear.supernodal.Supernodal.panels`): a task is up to :data:`PANEL_ROWS` rows of
a supernode that read the same columns, listed once and read once for them, a few lanes a panel
sharing its columns (1024 Diamonds on the H200: P^-1 4.90 -> 3.45 ms, a step 70.9 -> 60.5 ms;
docs/performance.md); ``layout="rows"`` keeps a task a row. A panel's task holds its world and the
world's first row, and when every world runs its lanes skip the test of their world (with the
operand rows read whole, P^-1 3.39 -> 3.21 ms, a step 60.5-60.9 -> 58.5 ms).

So ``P^-1 = Q blockdiag(s_w^-1 P_b^T L_b^-T L_b^-1 P_b) Q^T``: the same preconditioner as the
dense inverse (the rest system's exact inverse, turned by the node rotations), at a fraction of
the bytes, in more launches: for one robot the dense inverse stays the better (launch-bound),
for many the factors (bandwidth-bound).
"""

from __future__ import annotations

import math
import mmap
import multiprocessing
import os
from collections import deque
from collections.abc import Mapping
from concurrent.futures import ProcessPoolExecutor
from dataclasses import fields, replace
from functools import partial
from typing import NamedTuple

import numpy as np
import warp as wp
from threadpoolctl import threadpool_limits

from warpsoft.kernels.linear import factors as kernels

from ..errors import SceneError
from ..launch import launch
from ..processes import bind_to_parent, in_threads, release_freed, usable_cores
from .assembly import ORDERINGS, CholmodFactor, element_pattern
from .blocks import WorldGroups
from .operator import SystemOperator
from .own_refresh import OwnRefreshes
from .pattern import Pattern, Sparsity
from .refactor import lock_pages, lower_system, unlock_pages
from .supernodal import Panels, Program, Supernodal, sliced

LANES = 32  # threads a row in the levels of long rows, on CUDA
LANES_FROM = 128.0  # the mean entries a row from which a level takes them (docs/performance.md)
WIDTH = 32  # rows a slice of the other levels' entries, on CUDA (a warp's threads read side by side)
ORDERING = "nested_dissection"  # of the factors: levels, not fill, set the device's time (docs/performance.md)
# the running worlds' shares (of all worlds) below which a level launches their tasks alone, a tier
# each: the last CG iterations run a few slow designs, and a launch of every world's tasks cost
# them about 1.2 ms a P^-1 for 12 worlds of 1024 (docs/performance.md)
TAIL = (1 / 64, 1 / 16, 1 / 4)
# the threads a row of the sliced levels (short rows) takes in the tail's launches, at each tier:
# there a row's thread would walk its entries alone, a load after another, while threads are spare
# (H200, 1024 Diamonds: a P^-1 with 11 worlds running 0.96 -> 0.45 ms, docs/performance.md)
TAIL_LANES = (32, 16, 4)
# and when every world's tasks launch, on CUDA: two lanes a row keep a slice's loads side by side
# and halve the longest row's walk (P^-1 5.38 -> 5.14 ms; four lanes 5.28)
SHORT_LANES = 2
# an entry's column takes 16 bits when every factor has at most this many places (the Diamond's
# 3048-5157): 6 bytes an entry instead of 8 (H200, 1024 Diamonds: P^-1 5.14 -> 4.91 ms)
NARROW_PLACES = 2 ** 16
# how a level's work is cut: "rows" (a task a row, each row listing its columns) or "panels" (a task
# up to PANEL_ROWS rows of a supernode that read the same columns, listed once and read once for them)
LAYOUT = "panels"
PANEL_ROWS = 4
# the columns a panel's lane takes, on CUDA (its lanes: a power of 2 up to 32), at full load and in
# the tail (where threads are spare)
PANEL_SPREAD = (8.0, 1.0)
# in the tail, on CUDA, a level whose panels read at least WIDE_FROM columns on average takes a block of
# WIDE_LANES threads a panel (kernels.wide_panel_kernel): there a level lasts as long as its longest
# panel's walk, and the forward solve's last levels read up to 2,208 columns a panel
WIDE_FROM, WIDE_LANES = 256.0, 128
# a first factorization's state its forked workers inherit (a fork keeps a module's globals; nothing
# pickled): by its token, (the shared memory of its slots, a slot's bytes, the meshes' MeshPatterns)
_INHERITED: dict[int, tuple] = {}
WORKERS = None  # processes that factorize the blocks (None: one a core this process may run on; where processes fork)
POOL_FROM = 32  # blocks from which they do
# the blocks sent ahead to them, per worker, each in a slot of shared memory (the size of the largest
# world's element blocks): the rest wait, their results taken in order as they come
AHEAD = 4
# a world's own refresh (panels): its block is factorized anew at its state, between steps, when its CG
# needed more than WORLD_RATIO times the iterations of its first solve after its block's last
# factorization, and more than WORLD_FLOOR (None: never), by worker processes beside the steps and
# installed WORLD_LAG step boundaries later (a step's boundary: its first solve, beside which the host
# does this work) (warpsoft/linear/refactor.py); at most WORLD_BATCH blocks
# sent at one boundary (None: every one due), the slowest worlds' first (a fixed number, so that a
# trajectory never depends on the machine's cores). On by default: on the H200, 1024 Diamonds over
# the scene's 100 steps, the steps took 59.4 ms on average with it (a floor of 10, a ratio of 1.5,
# a lag of 2, batches of 16) and 960 ms without, where three refactorizations of the whole model
# stalled a step for 29-31 s each (docs/performance.md). It forks a worker a core, with their shared
# memory page-locked on CUDA (6 GB for those 1024 worlds). A lag of 2: the workers were waited for
# 0.03 s in 10 steps, 0.16 s with a lag of 1
WORLD_RATIO, WORLD_FLOOR, WORLD_LAG, WORLD_BATCH = 1.5, 10, 2, 16


def factor_programs(sparsity: Sparsity, values: np.ndarray, ordering: str, panel_rows: int = 0,
                    kept: tuple[np.dtype, np.dtype] | None = None
                    ) -> tuple[np.ndarray, tuple[Program, Program] | tuple[Panels, Panels]]:
    """One block: CHOLMOD's factor of the system ``values`` (its lower triangle's, on
    ``sparsity``) in ``ordering``, read out as the forward and backward level programs (a task a
    row), or with ``panel_rows`` as panels of that many rows, their values and columns in the
    dtypes ``kept`` (as the device keeps them: a worker sends back half the bytes); and the
    factor's ``order`` (the DOF at each of its places). A function of its arguments alone, so that
    worker processes can run it; raises ArithmeticError when the system is not positive definite."""
    L, order = CholmodFactor(sparsity, ordering=ordering).lower(values)
    analysis = Supernodal(L)
    if not panel_rows:
        return order, analysis.programs(L)
    panels = analysis.panels(L, panel_rows)
    if kept is not None:
        panels = tuple(replace(p, val=p.val.astype(kept[0], copy=False), col=p.col.astype(kept[1], copy=False))
                       for p in panels)
    return order, panels


class _Placed(NamedTuple):
    """An array a worker wrote into the shared memory: its first byte there, numpy type and shape."""

    offset: int
    dtype: str
    shape: tuple


def _arrays(result: tuple) -> list[np.ndarray]:
    """:func:`factor_programs`'s ``(order, programs)``'s arrays: the order, then each program's."""
    order, programs = result
    return [order] + [getattr(p, f.name) for p in programs for f in fields(p)
                      if isinstance(getattr(p, f.name), np.ndarray)]


def _rebuilt(result: tuple, take) -> tuple:
    """``result`` with each array ``a`` (:func:`_arrays`) replaced by ``take(a, its field)`` (the
    order's field: None)."""
    order, programs = result
    return take(order, None), tuple(replace(p, **{f.name: take(getattr(p, f.name), f.name) for f in fields(p)
                                                  if isinstance(getattr(p, f.name), (np.ndarray, _Placed))})
                                    for p in programs)


def _aligned(nbytes: int) -> int:
    """``nbytes`` rounded up to a multiple of 8."""
    return -(-nbytes // 8) * 8


def _placed_bytes(result: tuple) -> int:
    """The bytes ``result``'s arrays take in a slot, each from an 8-byte boundary."""
    return sum(_aligned(a.nbytes) for a in _arrays(result))


def _factor_in_slot(token: int, slot: int, key, count: int, masses: np.ndarray | None, stiffness_scale: float,
                    ordering: str, panel_rows: int, kept: tuple) -> tuple:
    """In a forked worker: :func:`factor_programs` of the system whose ``count`` element-block
    numbers (float64, unscaled) the parent put in ``slot`` of the shared memory it left in
    :data:`_INHERITED` under ``token`` (with the meshes' :class:`MeshPatterns`, ``key`` this one's), times
    ``stiffness_scale``, with ``masses`` (scaled, or None) on its diagonal. Its arrays go back in
    the same slot (:class:`_Placed`), or pickled where they do not fit."""
    arena, size, patterns = _INHERITED[token]
    pattern = patterns[key]
    entries = np.frombuffer(arena, np.float64, count, slot * size)
    result = factor_programs(pattern.sparsity(), lower_system(pattern, stiffness_scale * entries, masses),
                             ordering, panel_rows, kept)
    if _placed_bytes(result) > size:
        return result
    at = slot * size

    def put(a: np.ndarray, _) -> _Placed:
        nonlocal at
        np.frombuffer(arena, a.dtype, a.size, at)[:] = a.reshape(-1)
        placed, at = _Placed(at, a.dtype.str, a.shape), at + _aligned(a.nbytes)
        return placed

    return _rebuilt(result, put)


def _taken(arena: mmap.mmap, future, device) -> tuple:
    """A worker's result (:func:`_factor_in_slot`), its arrays copied out of its slot: panels'
    values and columns straight to ``device`` (where they go: the host never holds them), the rest
    to the host."""
    result = future.result()

    def take(a, field):
        if not isinstance(a, _Placed):
            return a
        view = np.frombuffer(arena, np.dtype(a.dtype), math.prod(a.shape), a.offset).reshape(a.shape)
        if field in ("val", "col") and isinstance(result[1][0], Panels):
            return wp.array(view, dtype=wp.dtype_from_numpy(view.dtype), device=device)
        return view.copy()

    return _rebuilt(result, take)


def _as(array, dtype):
    """A numpy ``array`` in ``dtype`` (no copy where it is); a Warp array (already the device's) as it is."""
    return array if isinstance(array, wp.array) else array.astype(dtype, copy=False)


def _stacked(parts: list, dtype, device, into: wp.array | None = None) -> wp.array:
    """``parts`` (numpy arrays, or Warp arrays of ``dtype`` on ``device``) one after another in one
    array of ``dtype`` on ``device`` (``into``, or a new one), copied part by part: the host never
    holds them joined (joined, with their tasks, they are the factors' whole device memory)."""
    out = wp.empty(sum(len(p) for p in parts), dtype=dtype, device=device) if into is None else into
    at, kind = 0, wp.dtype_to_numpy(dtype)
    for part in parts:
        if len(part):
            if not isinstance(part, wp.array):
                part = wp.array(np.ascontiguousarray(part, dtype=kind), dtype=dtype, device="cpu", copy=False)
            wp.copy(out, part, dest_offset=at, count=len(part))
        at += len(part)
    return out


def _by_level(levels: np.ndarray, per_world: np.ndarray, kind: list, device) -> tuple:
    """Every world's tasks (their ``levels``, world after world; ``per_world`` ``(depth, worlds)``
    each level's tasks of each world) in launch order: ``order`` (by level, then world, then its
    own order), per level with tasks ``(first, count, kind[level], most of a world)``, and each
    world's ``(offset, count)`` there on ``device`` (the tail's launches: ``kernels._task_at``)."""
    order = np.argsort(levels, kind="stable")
    count = np.bincount(levels, minlength=per_world.shape[0])
    firsts = np.concatenate([[0], np.cumsum(count)[:-1]])
    spans = np.stack([np.cumsum(per_world, axis=1) - per_world, per_world], axis=-1)[count > 0]
    listed = [(int(f), int(c), k, int(most)) for f, c, k, most in zip(firsts, count, kind, per_world.max(axis=1),
                                                                       strict=True) if c]
    return order, listed, wp.array(spans.astype(np.int32), dtype=wp.vec2i, device=device)


class MeshPatterns(Mapping):
    """Mesh -> the :class:`~warpsoft.linear.pattern.Pattern` of its system's lower triangle over its
    free DOFs, each made at its first look, in the process that looks (a forked worker makes its
    blocks' own) and kept there. ``meshes``: mesh -> ``(local, nodes, free)``: its elements' node
    ids ``(elements, k)``, its nodes, its free DOFs ``3 i + a``."""

    def __init__(self, meshes: dict):
        self._meshes, self._made = meshes, {}

    def __getitem__(self, key) -> Pattern:
        made = self._made.get(key)
        if made is None:
            local, nodes, dofs = self._meshes[key]
            free = np.zeros(3 * nodes, dtype=bool)
            free[dofs] = True
            made = self._made[key] = element_pattern([local], free)
        return made

    def __iter__(self):
        return iter(self._meshes)

    def __len__(self) -> int:
        return len(self._meshes)


class WorldFactors(OwnRefreshes, WorldGroups):
    """Args:
        operator: the system (rotations, scales, model).
        columns: right-hand sides ``k`` of the solves it serves.
        precision: "float32" or "float64", of the factors' entries, the solves and the frame ``q_rot``
            (the CG runs in float64; with float32, ``apply`` may write a vec3f ``z``: ``single_output``).
        refresh_ratio, refresh_floor: when to refactorize every block, as
            :class:`~warpsoft.linear.warped.WarpedFactor`'s.
        share, share_tolerance: which worlds share a factor, as
            :class:`~warpsoft.linear.blocks.WorldBlocks`'.
        ordering: the factors' ordering, :class:`~warpsoft.linear.assembly.CholmodFactor`'s
            (default :data:`ORDERING`: a level's launch has a floor however few worlds still
            run, so a shallow tree pays).
        layout: "rows" or "panels", how a level's work is cut (default :data:`LAYOUT`).

    Attributes: ``blocks`` (distinct factors), ``block_of`` ``(worlds,)``, ``levels`` (the forward
    and backward solves' launches), ``entries`` (the programs' numbers, all blocks), ``refreshes``,
    ``memory_bytes``, ``lanes`` and ``lanes_from`` (the threads a row of the levels whose rows
    average that many entries; H200, 1024 different Diamonds: P^-1 26.6 -> 9.8 ms with 32 from 128),
    ``width`` (the slices' rows in the other levels), ``unroll`` (the entries a level's thread loads
    at a time), ``whole_rows`` (the levels read an operand row from its address: the CPU's faster
    way, and the panels' on CUDA, where a task a row indexes its numbers), ``workers`` (the
    processes that factorize the blocks, :data:`WORKERS`; the GPU machine's 16 for 256 different
    Diamonds: 49.2 -> 15.2 s), ``tiers`` (the counts of running worlds at or below which the levels
    launch those worlds' tasks alone, from :data:`TAIL` on CUDA: :meth:`tail`), ``short_lanes`` and
    ``tail_lanes`` (the threads a row of the sliced levels takes with every world's tasks,
    :data:`SHORT_LANES`, and at each tier, :data:`TAIL_LANES`), ``index_dtype`` (the entries'
    columns: ``uint16`` when every factor has at most :data:`NARROW_PLACES` places, else ``int32``);
    with ``layout="panels"``: ``panel_rows`` (:data:`PANEL_ROWS`), ``panel_spread``
    (:data:`PANEL_SPREAD`) and ``panel_unroll`` (the columns a lane loads at a time), ``wide_from``
    and ``wide_lanes`` (in the tail, the levels whose panels read that many columns on average take a
    block of that many threads a panel: :data:`WIDE_FROM`, :data:`WIDE_LANES` on CUDA; None: never),
    ``unchecked_full`` (when every world runs, the panels' tasks do not test their world),
    ``world_ratio`` and ``world_floor`` (when a world's block is refactorized alone:
    :meth:`observe_worlds`; from :data:`WORLD_RATIO`, :data:`WORLD_FLOOR`; a floor None: never),
    ``world_lag`` (the step boundaries between a block found due and its new factor installed,
    :data:`WORLD_LAG`), ``world_batch`` (the most blocks sent at one boundary, the slowest worlds'
    first, :data:`WORLD_BATCH`; None: all due), ``world_refreshes`` (the blocks refactorized alone
    and installed, in all), ``refactorizer`` (their :class:`~warpsoft.linear.refactor.Refactorizer`, made at the first).
    """

    capturable = True

    def __init__(self, operator: SystemOperator, columns: int, precision: str = "float32",
                 refresh_ratio: float = 2.0, refresh_floor: int = 40, share: bool = True,
                 share_tolerance: float = 1e-10, ordering: str | None = None, layout: str | None = None):
        if precision not in ("float64", "float32"):
            raise ValueError(f"WorldFactors: precision must be 'float64' or 'float32', got {precision!r}")
        self.ordering = ORDERING if ordering is None else ordering
        if self.ordering not in ORDERINGS:
            raise ValueError(f"WorldFactors: ordering must be one of {ORDERINGS}, got {ordering!r}")
        self.layout = LAYOUT if layout is None else layout
        if self.layout not in ("rows", "panels"):
            raise ValueError(f"WorldFactors: layout must be 'rows' or 'panels', got {layout!r}")
        self.dtype = wp.float64 if precision == "float64" else wp.float32
        # (the rotations in the factors' precision: a float32 factor's P^-1 loses nothing by them)
        super().__init__(operator, columns, refresh_ratio, refresh_floor, share, share_tolerance,
                         wp.mat33f if self.dtype == wp.float32 else wp.mat33d)
        m, d = operator.model, operator.model.device
        # a float32 P^-1 may hand z over in float32 (the block CG's directions in single precision)
        self.single_output = self.dtype == wp.float32
        # a panel's lane loads PANEL_UNROLL columns at a time on CUDA (H200: 3.97 -> 3.45 ms from 2 to 4),
        # one on the CPU (4 Diamonds on the VM: P^-1 3.95 -> 2.98 and 3.69 -> 3.60 ms from 4 to 1)
        self.panel_rows, self.panel_spread = PANEL_ROWS, PANEL_SPREAD
        self.panel_unroll = kernels.PANEL_UNROLL if d.is_cuda else 1
        self.wide_from, self.wide_lanes = (WIDE_FROM if d.is_cuda else None), WIDE_LANES
        # the entries' types: their values in `dtype`, their columns uint16 or int32 (set with the
        # patterns below: :data:`NARROW_PLACES`)
        self.value_dtype, self.index_dtype = self.dtype, None
        rows = 3 * m.num_nodes
        # the solves' operands, flat (3 nodes, k), each world's rows in its factor's order
        # (``place``): input, forward, backward
        self.u, self.y, self.x = (wp.zeros((rows, self.columns), dtype=self.dtype, device=d) for _ in range(3))
        # the levels read an operand row from its address on the CPU and in panels, indexed on CUDA
        # in rows (the faster on each: ``_row_load`` in kernels/linear/factors.py)
        self.whole_rows = self.layout == "panels" or not d.is_cuda
        self.world_row = wp.array((3 * m.world_node_start[:-1]).astype(np.int32), dtype=wp.int32, device=d)
        first = {}  # mesh -> its first world
        for w, key in enumerate(self.mesh_of):
            first.setdefault(key, w)
        # mesh -> the lower triangle of its system over its free DOFs, made where first looked at: the
        # first factorization's workers make their blocks' (docs/performance.md)
        self.patterns = MeshPatterns({key: (local, nodes, self.local_free[first[key]])
                                      for key, (local, nodes) in self.meshes.items()})
        # an entry's column is a place of its factor, which has a place per free DOF
        places = max((len(self.local_free[w]) for w in first.values()), default=0)
        self.index_dtype = wp.uint16 if places <= NARROW_PLACES else wp.int32
        self.orders = []  # per block, the factor's ordering (the DOF at each place), made at the first refresh
        self.workers = WORKERS
        self.solves = None  # per direction: (tasks, col, val, [(first, count, long rows) per level])
        # levels whose rows average at least lanes_from entries take `lanes` threads a row
        # (level_kernel_lanes: they add by warp shuffles); the others a thread a row. None: never
        # (the CPU, where a row has one thread)
        self.lanes, self.lanes_from = (LANES, LANES_FROM) if d.is_cuda else (1, None)
        # the other levels' rows, a thread each, in slices of `width` (1: each row's entries one
        # after another, as the CPU's one thread reads them)
        self.width = WIDTH if d.is_cuda else 1
        self.unroll = kernels.UNROLL  # entries a thread of the levels loads at a time
        self.place = None  # (3 nodes,) each DOF's row among the operands, made at the first refresh
        self.inv_scale = None
        # the tail: the running worlds (a count, then the list); on CUDA (the CPU's one thread
        # passes a converged world's tasks at little cost: there it would add three launches)
        self.running = wp.zeros(1, dtype=wp.int32, device=d)
        self.running_list = wp.zeros(m.num_worlds, dtype=wp.int32, device=d)
        # the threads a short row takes when every world's tasks launch, and in the tail (a number
        # per tier, the last for any more; the CPU's one thread has one lane)
        self.short_lanes = SHORT_LANES if d.is_cuda else 1
        self.tail_lanes = list(TAIL_LANES) if d.is_cuda else [1]
        # when every world runs (the branch the tail's count picks), the panels' kernels skip the
        # test of a task's world: its lanes wait for one load fewer before the operands
        self.unchecked_full = True
        self.world_ratio, self.world_floor, self.world_lag = WORLD_RATIO, WORLD_FLOOR, WORLD_LAG
        self.world_batch = WORLD_BATCH
        self.world_refreshes, self.refactorizer = 0, None
        self.progress = None  # called with (blocks factorized, blocks) as a whole refresh goes (a sweep's bar)
        self._world_first = np.zeros(m.num_worlds, dtype=np.int64)  # its first solve's iterations (0: none yet)
        # per block: its world's CG count where due for its own refresh (else 0); whether it serves one world alone
        self._due = self._own = None
        self._value_start = None  # per direction: each block's first value (panels), and the end
        self._frames = None  # (nodes,) mat33d: each world being refactorized alone, its nodes' rotations factorized
        self.tail(sorted({math.ceil(f * m.num_worlds) for f in TAIL}) if d.is_cuda else [])

    def tail(self, tiers: list[int]) -> None:
        """The counts of running worlds at or below which the levels launch the running worlds'
        tasks alone, sized for that many (ascending; those not below the worlds' count are left
        out; [] for every world's tasks always). Before a step is captured."""
        worlds = self.op.model.num_worlds
        self.tiers = [int(t) for t in tiers if 0 < t < worlds]
        if self.tiers != sorted(set(self.tiers)):
            raise ValueError(f"WorldFactors: the tail's tiers must ascend, got {tiers}")
        d = self.op.model.device
        self.tiers_d = wp.array(self.tiers or [0], dtype=wp.int32, device=d)
        # one of tiers + 2 runs: a tier, every world's tasks tested, or untested when all run
        self.branch = wp.zeros(len(self.tiers) + 2, dtype=wp.int32, device=d)

    @property
    def levels(self) -> tuple[int, int]:
        """Launches of the forward and backward solves (0 before the first factorization)."""
        return (0, 0) if self.solves is None else tuple(len(s[3]) for s in self.solves)

    @property
    def entries(self) -> int:
        """Numbers of the forward and backward programs of every block."""
        return 0 if self.solves is None else sum(s[2].shape[0] for s in self.solves)

    @property
    def memory_bytes(self) -> int:
        """Device memory of the programs (entries and tasks) and the operands."""
        if self.solves is None:
            return 0
        return sum(a.capacity for s in self.solves for a in s[:3]) + 3 * self.u.capacity

    def _system(self, blocks: wp.array, w: int) -> np.ndarray:
        """World ``w``'s lower triangle (its pattern's values) at the element blocks ``blocks``."""
        values = self._values(blocks, w)
        count = 144 * len(self.meshes[self.mesh_of[w]][0])  # 16 blocks of 9 numbers per element
        masses = values[count:] if len(values) > count else None
        return lower_system(self.patterns[self.mesh_of[w]], values[:count], masses)

    def refresh(self) -> None:
        """Factorize each block at the current rotations (its first world's state) with CHOLMOD,
        turn the factors into level programs, and take the rotations as the new frame. From
        :data:`POOL_FROM` blocks, ``workers`` processes do it side by side."""
        m, d = self.op.model, self.op.model.device
        blocks = wp.zeros(16 * m.num_elements, dtype=wp.mat33d, device=d)  # made here, freed after
        self.op.elastic.blocks(self.op.rot, blocks)
        first = self.block_of is None
        if first:
            self._group(blocks)
        rows = self.panel_rows if self.layout == "panels" else 0
        kept = (np.dtype(np.float64 if self.dtype == wp.float64 else np.float32),
                np.dtype(wp.dtype_to_numpy(self.index_dtype)))
        workers = min(self.workers or usable_cores(), len(self.first_world))
        # one BLAS thread for the blocks' small dense products: the workers, forked inside, keep
        # the limit (16 processes of 16 OpenBLAS threads each would oversubscribe 16 cores)
        with threadpool_limits(1):
            if workers > 1 and len(self.first_world) >= POOL_FROM and "fork" in multiprocessing.get_all_start_methods():
                self._take(m, first, self._in_workers(blocks, workers, rows, kept))
            else:
                if first:  # (the patterns side by side in threads: numpy's sorts and gathers run outside the GIL)
                    in_threads(self.patterns.__getitem__, list(dict.fromkeys(self.mesh_of[w]
                                                                             for w in self.first_world)))
                self._take(m, first, ((w, partial(factor_programs, self.patterns[self.mesh_of[w]].sparsity(),
                                                  self._system(blocks, w), self.ordering, rows, kept))
                                      for w in self.first_world))
        self.take_frame()
        self._world_first[:] = 0  # every world's count starts anew
        if self._due is not None:
            self._due[:] = 0
        if self.refactorizer is not None:  # blocks being refactorized alone: made at an older state
            self.refactorizer.cancel()
        elif first and self.world_floor is not None and self.layout == "panels":
            # the workers forked now, while the model is built: they analyse their blocks before
            # the steps need them (forking 16 from the H200's full host took 3.1 s); the memory the
            # factorization freed given back first (its pages not inherited)
            release_freed()
            self._start_own()
            self.refactorizer = self._refactorizer()

    def _in_workers(self, blocks: wp.array, workers: int, rows: int, kept: tuple):
        """Each block's ``(world, call)`` in order (:meth:`_take`), factorized by ``workers`` forked
        processes. A block's element blocks go to its worker, and its programs come back, through a
        slot of memory they share, :data:`AHEAD` slots a worker: nothing big crosses a pipe, and the
        systems are summed in the workers (docs/performance.md). A block's slot is filled once the
        block :data:`AHEAD` times the workers before it is taken. The workers run CHOLMOD, METIS
        and numpy on their slots, never Warp or CUDA (forked on Linux: a spawned one would first run
        the user's script again, up to here, wherever it lacks the ``if __name__ == "__main__"``
        guard)."""
        m, op = self.op.model, self.op
        starts = m.world_elem_start
        count = {int(w): 144 * int(starts[w + 1] - starts[w]) for w in self.first_world}  # float64 numbers
        slots, size = AHEAD * workers, 8 * max(count.values())
        arena = mmap.mmap(-1, slots * size)
        token = id(arena)
        _INHERITED[token] = (arena, size, self.patterns)
        sync, locked = m.device.is_cuda, []
        try:
            with ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("fork"),
                                     initializer=bind_to_parent, initargs=(os.getpid(),)) as pool:
                if sync:  # the slots page-locked once the workers forked (CUDA keeps such pages out of
                    # forked children): the copies to and from the device then run at the bus's speed
                    pool.submit(int).result()
                    locked = lock_pages(m.device, [arena])
                waiting = deque()
                for b, w in enumerate(self.first_world):
                    w, slot = int(w), b % slots
                    into = np.frombuffer(arena, np.float64, count[w], slot * size).reshape(-1, 3, 3)
                    wp.copy(wp.array(into, dtype=wp.mat33d, device="cpu", copy=False), blocks,
                            src_offset=16 * int(starts[w]), count=count[w] // 9)
                    if sync:
                        wp.synchronize_stream(m.device.stream)
                    del into
                    masses = op.mass_scale * m.mass_np[m.world_nodes(w)] if op.mass_scale != 0.0 else None
                    waiting.append((w, pool.submit(_factor_in_slot, token, slot, self.mesh_of[w], count[w], masses,
                                                   op.stiffness_scale, self.ordering, rows, kept)))
                    if len(waiting) >= slots:
                        w0, future = waiting.popleft()
                        yield w0, partial(_taken, arena, future, m.device)
                while waiting:
                    w0, future = waiting.popleft()
                    yield w0, partial(_taken, arena, future, m.device)
        finally:
            _INHERITED.pop(token, None)
            if locked:  # (the device done with the slots first)
                wp.synchronize_device(m.device)
                unlock_pages(m.device, locked, [arena])

    def _take(self, m, first: bool, results) -> None:
        """Lay out the blocks' programs, ``results`` (an iterable of ``(world, call)``) in block
        order, each call returning :func:`factor_programs`'s; a system not positive definite names
        its world. Panels are kept as the device will hold them (their values in the factors'
        precision, their columns in ``index_dtype``) as they come. ``m``: the model."""
        npd = np.float64 if self.dtype == wp.float64 else np.float32
        index = wp.dtype_to_numpy(self.index_dtype)
        programs = []
        for b, (w, result) in enumerate(results):
            order, program = self._factorized(m, b, w, result, first)
            if first:
                self.orders.append(order)
            if self.layout == "panels":  # (held till the lay-out; made in these dtypes, so no copy)
                program = tuple(replace(p, val=_as(p.val, npd), col=_as(p.col, index)) for p in program)
            programs.append(program)
            if self.progress is not None:
                self.progress(b + 1, len(self.first_world))
        self._lay_out(programs)

    def _factorized(self, m, b: int, w: int, call, first: bool = False) -> tuple:
        """``call()`` (a factorization of block ``b``, whose world is ``w``, returning ``(order,
        ...)``), a system not positive definite named by its world; after the first, its ordering
        checked against the block's."""
        try:
            result = call()
        except ArithmeticError as e:
            raise SceneError(f"WorldFactors: world {w} (scene '{m.scenes[w].name}'): its system is not "
                             f"positive definite ({e}); is the body held?") from e
        if not first and not np.array_equal(result[0], self.orders[b]):
            raise RuntimeError(f"WorldFactors: block {b}'s ordering changed between factorizations")
        return result

    def _lay_out(self, programs: list) -> None:
        """The programs of every block on the device: each block's entries once (their columns as
        places of its factor), sliced for ``width`` threads (:func:`~warpsoft.linear.supernodal.sliced`)
        but in the levels of long rows; each world's tasks (rows at its places: ``place``), sorted by
        level. At a later refresh only the entries' values change, in place (a captured graph
        holds them)."""
        m, d = self.op.model, self.op.model.device
        npd = np.float64 if self.dtype == wp.float64 else np.float32
        if self.place is None:
            # each model DOF's row among the operands: world w's factor place p at 3 n_w + p (the
            # rows its ordering keeps together lie together), -1 for a fixed DOF
            place = np.full(3 * m.num_nodes, -1, dtype=np.int32)
            for w in range(m.num_worlds):
                b, start = int(self.block_of[w]), 3 * int(m.world_node_start[w])
                dof = self.local_free[w][self.orders[b]]  # the world's DOF at each place
                place[start + dof] = start + np.arange(len(dof))
            self.place = wp.array(place, dtype=wp.int32, device=d)
        if self.layout == "panels":
            self._lay_out_panels(programs)
            return
        worlds = np.bincount(self.block_of, minlength=len(programs))
        solves = []
        for direction in range(2):
            progs = [p[direction] for p in programs]
            # a level's rows, and their entries, over every world: long rows take several threads each
            depth = max(p.levels for p in progs)
            counts, length = np.zeros(depth), np.zeros(depth)
            for p, n in zip(progs, worlds, strict=True):
                counts[:p.levels] += n * np.bincount(p.level, minlength=p.levels)
                length[:p.levels] += n * np.bincount(p.level, weights=p.start[:, 2] - p.start[:, 0], minlength=p.levels)
            long = (length >= self.lanes_from * counts) if self.lanes_from is not None else np.zeros(depth, dtype=bool)
            layouts = [sliced(p, self.width, long) for p in progs]
            offset = np.concatenate([[0], np.cumsum([s.size for s in layouts])])
            val = np.zeros(offset[-1], dtype=npd)
            for p, s, o in zip(progs, layouts, offset[:-1], strict=True):
                val[o + s.place] = p.val
            if self.solves is not None:
                self.solves[direction][2].assign(val)
                continue
            col = np.zeros(offset[-1], dtype=wp.dtype_to_numpy(self.index_dtype))
            for p, s, o in zip(progs, layouts, offset[:-1], strict=True):
                col[o + s.place] = p.col
            tasks, levels = [], []
            per_world = np.zeros((depth, m.num_worlds), dtype=np.int64)  # each level's tasks of each world
            for w in range(m.num_worlds):
                b = int(self.block_of[w])
                s = layouts[b]
                row = np.where(s.row >= 0, 3 * int(m.world_node_start[w]) + s.row, -1)
                tasks.append(np.column_stack([row, s.start + offset[b]]))
                levels.append(s.level)
                per_world[:, w] = np.bincount(s.level, minlength=depth)
            tasks, levels = np.concatenate(tasks), np.concatenate(levels)
            if tasks.max() >= 2 ** 31:
                raise ValueError(f"WorldFactors: {tasks.max()} entries pass the 2^31 a Warp index holds; "
                                 "step fewer designs at a time")
            order, level_list, spans = _by_level(levels, per_world, [bool(lg) for lg in long], d)
            solves.append((wp.array(tasks[order].astype(np.int32), dtype=wp.vec4i, device=d),
                           wp.array(col, dtype=self.index_dtype, device=d),
                           wp.array(val, dtype=self.value_dtype, device=d), level_list, spans))
        if self.solves is None:
            self.solves = solves
            self.inv_scale = wp.array((1.0 / self.scale_np).astype(npd), dtype=self.dtype, device=d)

    def _lay_out_panels(self, programs: list) -> None:
        """:meth:`_lay_out` for panels: each block's values and columns once, each world's panels
        (their first rows at its places), sorted by level; per level, its panels' mean columns."""
        m, d = self.op.model, self.op.model.device
        npd = np.float64 if self.dtype == wp.float64 else np.float32
        solves, starts = [], []
        for direction in range(2):
            progs = [p[direction] for p in programs]
            values = np.concatenate([[0], np.cumsum([len(p.val) for p in progs])])
            starts.append(values)
            if self.solves is not None:  # (in place: the captured graphs read it)
                _stacked([p.val for p in progs], self.value_dtype, d, self.solves[direction][2])
                continue
            if values[-1] >= 2 ** 31:
                raise ValueError(f"WorldFactors: {values[-1]} values pass the 2^31 a Warp index holds; "
                                 "step fewer designs at a time")
            val = _stacked([p.val for p in progs], self.value_dtype, d)
            cols = np.concatenate([[0], np.cumsum([len(p.col) for p in progs])])
            col = _stacked([p.col for p in progs], self.index_dtype, d)
            depth = max(p.levels for p in progs)
            tasks, levels = [], []
            per_world = np.zeros((depth, m.num_worlds), dtype=np.int64)  # each level's panels of each world
            for w in range(m.num_worlds):
                b = int(self.block_of[w])
                p = progs[b]
                base = 3 * int(m.world_node_start[w])
                tasks.append(np.column_stack([base + p.row, p.height, p.val_start + values[b], p.col_start + cols[b],
                                              p.reads, np.full(len(p.row), w), np.full(len(p.row), base)]))
                levels.append(p.level)
                per_world[:, w] = np.bincount(p.level, minlength=depth)
            tasks, levels = np.concatenate(tasks), np.concatenate(levels)
            count = np.maximum(np.bincount(levels, minlength=depth), 1)
            reads = np.bincount(levels, weights=tasks[:, 4] + tasks[:, 5], minlength=depth) / count
            order, level_list, spans = _by_level(levels, per_world, [float(r) for r in reads], d)
            solves.append((wp.array(tasks[order].astype(np.int32), dtype=kernels.panel_task, device=d), col, val,
                           level_list, spans))
        self._value_start = starts
        if self.solves is None:
            self.solves = solves
            self.inv_scale = wp.array((1.0 / self.scale_np).astype(npd), dtype=self.dtype, device=d)
            # the kernels' rows a panel: the programs' tallest (panel_rows may change after)
            self.panel_height = max(int(p[k].height.max(initial=1)) for p in programs for k in range(2))

    def apply(self, r: wp.array, z: wp.array) -> None:
        """``z = Q blockdiag(s_w^-1 A_b^-1) Q^T r`` for ``(k, n)`` arrays, ``k <= columns``: ``r`` vec3d,
        ``z`` vec3d (or vec3f, with ``single_output``); fixed DOFs 0."""
        m, d = self.op.model, self.op.model.device
        k = r.shape[0]
        if z.dtype != wp.vec3d and not self.single_output:
            raise ValueError(f"WorldFactors: a float64 P^-1 writes vec3d, got a {z.dtype.__name__} z")
        launch(kernels.rotate_in_scaled(self.dtype, k, self.q_rot.dtype), m.num_nodes,
               inputs=[r, self.q_rot, m.mask, m.node_world, self.place, self.inv_scale, self._done], outputs=[self.u],
               device=d)
        lanes = max([self.lanes, *(self._short_lanes(t) for t in [0, *self.tiers])])
        if lanes > 1 and not d.is_cuda:
            raise ValueError(f"WorldFactors: {lanes} lanes a row add by warp shuffles, which only CUDA has; "
                             "give the CPU one lane a row")
        if self.tiers:  # the tail: the running worlds' tasks alone, when few run
            self.running.zero_()
            launch(kernels.running_worlds(k), m.num_worlds, inputs=[self._done], outputs=[self.running,
                                                                                          self.running_list], device=d)
            launch(kernels.pick_tail, 1, inputs=[self.running, self.tiers_d, m.num_worlds], outputs=[self.branch],
                   device=d)
            for j, tier in enumerate(self.tiers):
                wp.capture_if(self.branch[j:j + 1], self._levels, k=k, tier=tier)
            n = len(self.tiers)
            wp.capture_if(self.branch[n:n + 1], self._levels, k=k, tier=0)
            wp.capture_if(self.branch[n + 1:], self._levels, k=k, tier=0, check=not self.unchecked_full)
        else:
            self._levels(k, 0)
        launch(kernels.rotate_out(self.dtype, k, z.dtype, self.q_rot.dtype), m.num_nodes,
               inputs=[self.x, self.q_rot, m.mask, m.node_world, self.place, self._done], outputs=[z], device=d)

    def _short_lanes(self, tier: int) -> int:
        """Threads a short row (the sliced levels') takes at ``tier`` (0: every world's tasks)."""
        if tier == 0:
            return self.short_lanes
        lanes = self.tail_lanes
        return lanes[min(self.tiers.index(tier), len(lanes) - 1)] if len(lanes) else 1

    def _levels(self, k: int, tier: int, check: bool = True) -> None:
        """The two triangular solves, level by level: every world's tasks (``tier`` 0), or those of
        the running worlds, at most ``tier`` of them (a level's launch: ``tier`` times its most
        tasks of a world). A long row takes ``lanes`` threads, a short one ``_short_lanes(tier)``.
        ``check`` False (when every world runs): the panels' tasks do not test their world."""
        m, d = self.op.model, self.op.model.device
        compact = tier > 0
        if self.layout == "panels":
            self._panel_levels(k, tier, check)
            return
        short = self._short_lanes(tier)
        entry = (self.index_dtype, self.value_dtype)
        if short == 1:
            level = kernels.level_kernel(k, self.dtype, self.width, self.unroll, self.whole_rows, compact, entry)
        else:
            level = kernels.level_kernel_lanes(k, self.dtype, short, self.unroll, self.whole_rows, compact, self.width,
                                               entry)
        lanes = None if self.lanes_from is None else kernels.level_kernel_lanes(
            k, self.dtype, self.lanes, self.unroll, self.whole_rows, compact, entry=entry)
        for (tasks, col, val, levels, spans), inp, out in zip(self.solves, (self.u, self.y), (self.y, self.x),
                                                              strict=True):
            for j, (first, count, long, most) in enumerate(levels):
                tail = [self.running, self.running_list, spans[j], most if compact else count]
                inputs = [tasks, first, col, val, m.node_world, self.world_row, self._done, inp]
                threads = tier * most if compact else count
                per = self.lanes if long else short  # threads a task
                if per > 1:  # whole warps: each thread reaches the shuffles
                    threads = -(-threads * per // 32) * 32
                launch(lanes if long else level, threads, inputs=inputs, outputs=[out, *tail], device=d)

    def panel_lanes(self, reads: float, tier: int) -> int:
        """Threads a panel takes in a level whose panels read ``reads`` columns on average, at
        ``tier`` (0: every world's tasks): about ``panel_spread`` columns a lane, a power of 2 up
        to 32, on CUDA; one on the CPU."""
        if not self.op.model.device.is_cuda:
            return 1
        spread = self.panel_spread[0 if tier == 0 else 1]
        return int(min(32, 2 ** max(0, math.ceil(math.log2(max(reads / spread, 1.0))))))

    def _panel_levels(self, k: int, tier: int, check: bool) -> None:
        """:meth:`_levels` for panels: a launch a level, ``panel_lanes`` threads a panel (in the tail, a
        block of ``wide_lanes`` threads a panel in the levels of wide panels)."""
        d = self.op.model.device
        compact = tier > 0
        entry = (self.index_dtype, self.value_dtype)
        for (tasks, col, val, levels, spans), inp, out in zip(self.solves, (self.u, self.y), (self.y, self.x),
                                                              strict=True):
            for j, (first, count, reads, most) in enumerate(levels):
                if compact and self.wide_from is not None and reads >= self.wide_from:
                    kernel = kernels.wide_panel_kernel(k, self.dtype, self.panel_height, self.panel_unroll,
                                                       self.whole_rows, entry)
                    wp.launch_tiled(kernel, dim=(tier * most,), inputs=[tasks, first, col, val, inp],
                                    outputs=[out, self.running, self.running_list, spans[j], most],
                                    block_dim=self.wide_lanes, device=d)
                    continue
                lanes = self.panel_lanes(reads, tier)
                kernel = kernels.panel_kernel(k, self.dtype, self.panel_height, lanes, self.panel_unroll,
                                              self.whole_rows, compact, entry, check)
                threads = (tier * most if compact else count) * lanes
                if lanes > 1:  # whole warps: each thread reaches the shuffles
                    threads = -(-threads // 32) * 32
                launch(kernel, threads, inputs=[tasks, first, col, val, self._done, inp],
                       outputs=[out, self.running, self.running_list, spans[j], most if compact else count],
                       device=d)
