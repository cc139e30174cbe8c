"""A world's factor made anew beside the step (:meth:`WorldFactors.refresh_worlds
<warpsoft.linear.factors.WorldFactors.refresh_worlds>`).

A block of the factors that serves one world alone is refactorized when that world's CG grew:
one rotation per node no longer follows the elements of a bending node (1024 Diamonds: the soft,
thin designs climb from 7 to 18 iterations in 15 steps). That is host work: the world's system
summed, CHOLMOD's numeric factorization in the block's ordering, then the panels' values
(:meth:`~warpsoft.linear.supernodal.Supernodal.panel_values`), 13-15 ms for a Diamond of 3048
DOFs on the 2-core VM, and 30-55 ms more the first time (the supernodes' analysis). Done in the
step, one block after another, it cost 1.6 s a step on the H200's host for 1024 Diamonds. Here
worker processes do it while the device runs the steps:

- at the step boundary where a block is found due (the step's first graph, beside which the host
  does this work), its world's element blocks at the last linearization are copied from the
  device into memory the block's worker shares, on a stream of their own beside the step's
  graphs, followed by the job's number (its ``ready`` mark); the worker is told at once (a few
  numbers down a pipe) and starts when the mark has landed. That
  linearization's node rotations are kept on the device, to become the world's frame with the
  new factor;
- :attr:`Refactorizer.lag` boundaries later (two by default: WORLD_LAG of factors.py) the worker's
  values are copied from the shared memory to the device in place, and the frame taken, after
  waiting for the worker if it has not finished. On CUDA they cross to the device on the side
  stream, into a buffer of their own, while the step's solve in flight still reads the old ones;
  the step's stream then moves them in place, device to device (a Diamond's values are about
  4 MB, and 1024 Diamonds install about 4 a step: across the bus in the step's stream, they would
  hold its next solve for that time). The trajectory therefore never depends on how
  fast the host was; with a lag of 0 the factor is installed at the boundary that found it due.

Each block has its worker (its index modulo the workers) and its values' place in that worker's
shared memory; the element blocks come through :data:`SLOTS` slots a worker (each with its mark),
taken in turn, a job's slot waiting for the worker to answer the job before in it (its slot's element
blocks then read). All is laid out when the workers are forked (after a header: the blocks the
worker analysed ahead): they inherit each block's mesh, ordering and masses, and send back only a
status. (Slots, not a place for every block's element blocks: the page-locked memory is mostly the
values'.) A worker
analyses its blocks' supernodes while it has nothing to do (:func:`warm`, on a made-up matrix of
the pattern: the supernodes depend on the pattern alone), so that a block's first refactorization
costs what the later ones do. On CUDA the shared memory is page-locked once the workers are
forked (``cuMemHostRegister``), so that the copies run beside the graphs instead of in the
step's time: copied into pageable memory, touched for the first time, a world's 4.6 MB took about
6 ms of the step on the H200's host (docs/performance.md). Nothing big crosses a pipe and the
parent runs no thread of its own (a ``concurrent.futures`` pool pickled each job's 4.6 MB in its
threads: its refresh stage took 507 ms a step for 131 refreshes in 10 steps). Without ``fork`` (or
with one worker) the same work runs in this process at submission, with the same results.
"""

from __future__ import annotations

import ctypes
import mmap
import multiprocessing
import os
import time
import weakref
from collections import deque
from collections.abc import Hashable, Mapping
from dataclasses import dataclass

import numpy as np
import warp as wp
from threadpoolctl import threadpool_limits

from ..processes import bind_to_parent
from .assembly import CholmodFactor
from .pattern import Pattern
from .supernodal import Supernodal

_WORKER_LIMITS = []  # a worker's BLAS thread limit, held for its life
# how long a worker waits for a job's element blocks to land once told of it (s): the copy is
# already queued then, behind at most the boundary's few launches
READY_TIMEOUT = 120.0
# the most blocks' analyses (CHOLMOD's, the supernodes' and their panels' places) a worker keeps,
# the least recently used dropped past it; it analyses that many of its blocks ahead. About 6 MB a
# Diamond: 4096 Diamonds' 256 a worker on the H200's host would hold 1.5 GB in each of 16 workers.
# 64: every block of 1024 Diamonds on 16 workers (the measurements of record); past that, a block
# dropped, or never analysed ahead, costs its next refactorization the analysis (25-32 ms for a
# Diamond on the 2-core VM, against 10-13 analysed)
KEEP_ANALYSES = 64
# the element blocks' slots a worker has (fewer when it has fewer blocks): the blocks sent at a boundary
# (at most WORLD_BATCH of factors.py, 16) spread over the workers by their index, and a job's slot is
# free again once its worker answered it, within a step or two
SLOTS = 8
# pages left locked by refactorizers shut down while their device captured a graph: ``(device,
# addresses, arenas)``, unlocked at the next chance outside a capture (the arenas kept mapped till then)
_UNLOCK_LATER: list[tuple] = []


def lower_system(pattern: Pattern, entries: np.ndarray, masses: np.ndarray | None) -> np.ndarray:
    """A world's system as the lower triangle on ``pattern``: its element blocks' numbers ``entries``
    ``(144 elements,)`` summed into their slots, its nodes' ``masses`` ``(nodes,)`` (or None) on the
    diagonal, both already scaled (the stiffness and mass scales of the operator)."""
    return pattern.lower_values(entries, None if masses is None else np.repeat(masses, 3))


@dataclass
class Block:
    """What a block's worker knows of it: its world's mesh (``patterns[mesh]``, its
    :attr:`pattern`, made where first looked at), the factor's ``order`` (the DOF at each place),
    the world's nodes' ``masses`` ``(nodes,)`` kg (None without mass), its ``elements`` (the numbers
    of its element blocks, float64) and its ``values``' places in the shared memory, ``((offset,
    numbers), (offset, numbers))`` (bytes; numbers in the factors' precision) of its forward and
    backward panels' values."""

    patterns: Mapping
    mesh: Hashable
    order: np.ndarray
    masses: np.ndarray | None
    elements: int
    values: tuple[tuple[int, int], tuple[int, int]]

    @property
    def pattern(self) -> Pattern:
        """The lower triangle of the world's system over its free DOFs."""
        return self.patterns[self.mesh]


@dataclass
class Slot:
    """Where a worker finds a job's element blocks in its shared memory (bytes): ``ready`` the
    offset of the slot's mark (int64: the last job whose element blocks landed there, plus one),
    ``at`` that of its element blocks (float64), ``numbers`` the most it holds."""

    ready: int
    at: int
    numbers: int


def _factor(cache: dict, block: int, info: Block, system: np.ndarray):
    """Block ``block``'s lower factor of ``system`` (its pattern's values) in its ordering, and its
    supernodes, analysed the first time and kept in ``cache``."""
    if block not in cache:
        cache[block] = [CholmodFactor(info.pattern.sparsity(), ordering="nested_dissection",
                                      permutation=info.order), None]
    factor, supernodes = cache[block]
    L, order = factor.lower(system)
    if not np.array_equal(order, info.order):
        raise RuntimeError(f"Refactorizer: block {block}'s ordering changed between factorizations")
    if supernodes is None:
        supernodes = cache[block][1] = Supernodal(L)
    return L, supernodes


def warm(cache: dict, block: int, info: Block, panel_rows: int) -> None:
    """Analyse block ``block``'s supernodes and their panels of ``panel_rows`` rows ahead of its
    first refactorization, on a made-up system of its pattern (-1 off the diagonal, the pattern's
    entries on it: diagonally dominant, so positive definite). CHOLMOD's factor has the pattern its
    analysis gives, whatever the values, so its supernodes are the real system's. (A Diamond of
    3048 DOFs on the 2-core VM: its first refactorization 25-32 ms, the next ones 10-13 ms.)"""
    if block in cache and cache[block][1] is not None:
        return
    pattern = info.pattern
    system = np.full(pattern.nnz, -1.0)
    system[pattern.diagonal] = float(pattern.nnz)
    L, supernodes = _factor(cache, block, info, system)
    supernodes.panel_values(L, panel_rows)  # (the panels' places, found once)


def refactor(cache: dict, arena, block: int, info: Block, at: int, stiffness_scale: float, mass_scale: float,
             panel_rows: int, dtype: type) -> None:
    """Block ``block``'s factor at the element blocks in ``arena`` from byte ``at`` (unscaled, then times
    ``stiffness_scale``; ``mass_scale`` times its masses on the diagonal), in its ordering, its
    panels' values of ``panel_rows`` rows written to ``arena`` in ``dtype`` (``info``'s places).
    ``cache`` keeps the block's CHOLMOD analysis and supernodes between calls. Raises
    ArithmeticError when the system is not positive definite."""
    elements = np.frombuffer(arena, np.float64, info.elements, at)
    masses = None if info.masses is None or mass_scale == 0.0 else mass_scale * info.masses
    L, supernodes = _factor(cache, block, info, lower_system(info.pattern, stiffness_scale * elements, masses))
    for values, (offset, count) in zip(supernodes.panel_values(L, panel_rows), info.values, strict=True):
        if len(values) != count:
            raise RuntimeError(f"Refactorizer: block {block}'s panels changed between factorizations")
        np.frombuffer(arena, dtype, count, offset)[:] = values


def _landed(arena, block: int, slot: Slot, job: int) -> None:
    """Wait until job ``job``'s element blocks of ``block`` are in ``arena`` (its ``slot``'s mark reached)."""
    mark = np.frombuffer(arena, np.int64, 1, slot.ready)
    deadline = time.monotonic() + READY_TIMEOUT
    while mark[0] <= job:
        if time.monotonic() > deadline:
            raise RuntimeError(f"Refactorizer: block {block}'s element blocks for job {job} never arrived "
                               f"in {READY_TIMEOUT} s")
        time.sleep(5e-5)


def _keep(cache: dict, block: int, keep: int) -> None:
    """``block``'s analysis in ``cache`` made the most recent, and the least recent ones dropped
    past ``keep`` (a dict keeps its order of insertion)."""
    if block in cache:
        cache[block] = cache.pop(block)
    while len(cache) > keep:
        cache.pop(next(iter(cache)))


def _serve(conn, arena, blocks: dict, slots: list[Slot], panel_rows: int, dtype: type, parent: int,
           keep: int) -> None:
    """A worker: for each ``(job, block, slot, stiffness_scale, mass_scale)`` received, once its element
    blocks landed in ``slots[slot]``, :func:`refactor`, then ``(job, None or the error, seconds waiting for the blocks,
    seconds refactorizing)`` sent back; None stops it. While nothing waits, it analyses its first
    ``keep`` blocks one by one (:func:`warm`), and it keeps the analyses of the ``keep`` blocks it
    used last. It ends when its ``parent`` (pid) does (:func:`~warpsoft.processes.bind_to_parent`)."""
    bind_to_parent(parent)
    _WORKER_LIMITS.append(threadpool_limits(1))  # one BLAS thread: small products, and the workers fill the cores
    cache = {}
    cold = sorted(blocks)[:keep]
    analysed = np.frombuffer(arena, np.int64, 1, 0)  # (the arena's header: the blocks tried ahead)
    while True:
        while cold and not conn.poll():
            b = cold.pop(0)
            try:
                warm(cache, b, blocks[b], panel_rows)
            except Exception:  # (its first job analyses it, and reports what fails)
                cache.pop(b, None)
            analysed[0] += 1
        message = conn.recv()
        if message is None:
            return
        job, block, slot, stiffness_scale, mass_scale = message
        start = time.perf_counter()
        landed = start
        try:
            _landed(arena, block, slots[slot], job)
            landed = time.perf_counter()
            refactor(cache, arena, block, blocks[block], slots[slot].at, stiffness_scale, mass_scale, panel_rows,
                     dtype)
            error = None
        except Exception as e:  # (sent back, raised where the job is installed)
            error = e
        _keep(cache, block, keep)
        conn.send((job, error, landed - start, time.perf_counter() - landed))


@dataclass
class Job:
    """A block being refactorized: ``block`` and its ``world``, the boundary it is installed at
    (``at``), its number ``id``, the world's nodes ``span`` ``(lo, hi)`` and their rotations
    ``frame`` ``(nodes,)`` mat33d on the device, holding the world's nodes' rotations at the
    linearization factorized (in its span); ``held``: the device arrays its copies read, kept until
    they are done."""

    block: int
    world: int
    at: int
    id: int
    span: tuple[int, int]
    frame: wp.array
    held: tuple = ()


class Refactorizer:
    """Blocks refactorized in worker processes, installed a fixed number of step boundaries later.

    Args:
        blocks: block -> :class:`Block` (the offsets: see :meth:`layout`), of the blocks it may be
            given; block ``b`` goes to worker ``b % workers``.
        slots: each worker's element slots (:class:`Slot`, :meth:`layout`).
        arenas: each worker's shared memory, bytes (:meth:`layout`); one arena: no worker, the work
            runs in this process at submission (the caller gives one where processes cannot fork).
        lag: boundaries between a block's submission and its installation (0: the same one).
        panel_rows: the panels' rows (:meth:`~warpsoft.linear.supernodal.Supernodal.panels`).
        dtype: the values' numpy type.
        device: the model's device (CUDA: the copies to the workers on a stream of their own, into
            page-locked shared memory).
        keep: the most blocks' analyses a worker keeps, and analyses ahead (default
            :data:`KEEP_ANALYSES`).

    Attributes: ``workers`` (processes; 0: none), ``blocks``, ``slots`` (as given), ``boundary``
    (the boundaries counted), ``pending`` (block -> :class:`Job`), ``waited`` (seconds the host
    waited on workers, in all), ``submitted``, ``landing`` and ``working`` (per job a worker
    answered: seconds it waited for the element blocks to land, seconds it refactorized),
    ``page_locked`` (whether the shared memory is: the copies then run beside the step).
    """

    def __init__(self, blocks: dict[int, Block], slots: list[list[Slot]], arenas: list[int], lag: int,
                 panel_rows: int, dtype: type, device, keep: int | None = None):
        if lag < 0:
            raise ValueError(f"Refactorizer: the lag is a count of step boundaries, got {lag}")
        self.keep = KEEP_ANALYSES if keep is None else int(keep)
        if self.keep < 1:
            raise ValueError(f"Refactorizer: a worker keeps at least one block's analysis, got keep={keep!r}")
        self.lag, self.panel_rows, self.dtype = int(lag), int(panel_rows), dtype
        self.boundary, self.pending, self.waited, self.submitted = 0, {}, 0.0, 0
        self.landing, self.working = [], []  # per job answered by a worker: s waiting for its blocks, s working
        self.blocks, self.slots = blocks, slots
        self.workers = len(arenas) if len(arenas) > 1 else 0
        self._sent = [0] * len(arenas)  # per worker, the jobs sent to it (its next slot: this modulo its slots)
        self._occupant = [[None] * len(k) for k in slots]  # per worker and slot, its last job
        self._arenas = [mmap.mmap(-1, max(size, 1)) for size in arenas]  # shared with the forked workers
        self._errors: dict[int, Exception | None] = {}  # job -> its outcome, once known
        self._dropped: set[int] = set()  # jobs cancelled before their answer was read
        self._queues = [deque() for _ in arenas]  # per worker, its jobs' ids in the order sent
        self._cache: dict = {}  # this process's analyses (no workers)
        self._view: dict = {}  # block -> its values' places as CPU arrays (:meth:`_values_of`)
        self._slot_view: dict = {}  # (worker, slot) -> its element blocks and mark as CPU arrays
        self._procs = []
        context = multiprocessing.get_context("fork") if self.workers else None
        for k in range(self.workers):  # forked: they run CHOLMOD and numpy, never Warp or CUDA
            mine = {b: info for b, info in blocks.items() if b % self.workers == k}
            parent, child = context.Pipe()
            proc = context.Process(target=_serve, name=f"warpsoft-refactor-{k}", daemon=True,
                                   args=(child, self._arenas[k], mine, slots[k], self.panel_rows, dtype, os.getpid(),
                                         self.keep))
            proc.start()
            child.close()
            self._procs.append((proc, parent))
        device = wp.get_device(device)
        # (after the fork: CUDA may keep page-locked memory out of forked children)
        self._locked = lock_pages(device, self._arenas)
        self.page_locked = bool(self._locked) and len(self._locked) == len(self._arenas)
        self._side = wp.Stream(device) if device.is_cuda else None  # the copies to the workers, and back
        self._staging, self._staged = None, None  # values on their way in (CUDA), and the event they left it at
        self._finalizer = weakref.finalize(self, _shut_down, self._procs, self._locked, device, self._arenas)

    @staticmethod
    def layout(elements: dict[int, int], values: dict[int, tuple[int, int]], workers: int,
               itemsize: int, slots: int | None = None) -> tuple[dict, list[list[Slot]], list[int]]:
        """Each block's values' places in its worker's shared memory, and each worker's element
        slots: ``elements`` block -> its element blocks' numbers (float64), ``values`` block -> its
        forward and backward values (of ``itemsize`` bytes), ``slots`` a worker (default
        :data:`SLOTS`; fewer where it has fewer blocks), each the size of its largest blocks'.
        Returns block -> its values ``((offset, count), (offset, count))``, each worker's
        :class:`Slot` list, and each arena's bytes (``workers`` of them, or one with 1 or less)."""
        arenas = max(int(workers), 1)
        slots = SLOTS if slots is None else int(slots)
        if slots < 1:
            raise ValueError(f"Refactorizer: a worker needs at least one slot, got {slots}")
        mine = [[b for b in sorted(elements) if b % arenas == k] for k in range(arenas)]
        sizes, places, slot_lists = [], {}, []
        for blocks in mine:
            at, largest = 8, max((elements[b] for b in blocks), default=0)  # (the header: the blocks analysed ahead)
            listed = []
            for _ in range(min(slots, len(blocks))):
                listed.append(Slot(at, at + 8, largest))
                at += 8 + 8 * largest
            for b in blocks:
                forward, backward = values[b]
                f0 = at
                b0 = f0 + -(-itemsize * forward // 8) * 8
                places[b] = ((f0, forward), (b0, backward))
                at = b0 + -(-itemsize * backward // 8) * 8
            slot_lists.append(listed)
            sizes.append(at)
        return places, slot_lists, sizes

    def _values_of(self, block: int) -> tuple[wp.array, wp.array]:
        """Block ``block``'s forward and backward values in its arena, as CPU arrays (made once)."""
        views = self._view.get(block)
        if views is None:
            arena = self._arenas[block % max(self.workers, 1)]
            kind = wp.dtype_from_numpy(np.dtype(self.dtype))
            views = self._view[block] = tuple(
                wp.array(np.frombuffer(arena, self.dtype, n, o), dtype=kind, device="cpu", copy=False)
                for o, n in self.blocks[block].values)
        return views

    def _slot_views(self, k: int, s: int) -> tuple[wp.array, wp.array]:
        """Worker ``k``'s slot ``s`` as CPU arrays (made once): its element blocks (mat33d, all it
        holds) and its mark (int64)."""
        views = self._slot_view.get((k, s))
        if views is None:
            arena, slot = self._arenas[k], self.slots[k][s]
            views = self._slot_view[k, s] = (
                wp.array(np.frombuffer(arena, np.float64, slot.numbers, slot.at).reshape(-1, 3, 3), dtype=wp.mat33d,
                         device="cpu", copy=False),
                wp.array(np.frombuffer(arena, np.int64, 1, slot.ready), dtype=wp.int64, device="cpu", copy=False))
        return views

    def _slot_for(self, block: int, job: int) -> tuple[int, int]:
        """The worker and the slot of job ``job`` (of ``block``): the worker's next, once the job
        before in it has been answered (its element blocks read)."""
        k = block % max(self.workers, 1)
        s = self._sent[k] % len(self.slots[k])
        self._sent[k] += 1
        before = self._occupant[k][s]
        if self.workers and before is not None:
            start = time.perf_counter()
            while before in self._queues[k]:
                self._answer(k)
            self.waited += time.perf_counter() - start
        self._occupant[k][s] = job
        return k, s

    def _answer(self, k: int) -> None:
        """Read worker ``k``'s next answer (it answers in the order it was told)."""
        proc, conn = self._procs[k]
        try:
            done, error, landing, working = conn.recv()
        except EOFError:
            raise RuntimeError(f"Refactorizer: worker {k} stopped (exit code {proc.exitcode})") from None
        if self._queues[k].popleft() != done:
            raise RuntimeError(f"Refactorizer: worker {k} answered job {done} out of order")
        self.landing.append(landing)
        self.working.append(working)
        if done in self._dropped:
            self._dropped.discard(done)
        else:
            self._errors[done] = error

    def submit(self, blocks: list[int], worlds: list[int], elements: wp.array, stiffness_scale: float,
               mass_scale: float, spans: list[tuple[int, int]], frame: wp.array) -> None:
        """Refactorize each of ``blocks`` (of ``worlds``) at its world's element blocks, to install
        ``lag`` boundaries after the current one. ``elements``: mat33d on the device (kept until
        copied), the worlds' element blocks one world after another (each world's ``16 e``, in the
        order of ``blocks``); the operator's scales; ``spans``: each world's nodes ``(lo, hi)``;
        ``frame``: ``(nodes,)`` mat33d, its worlds' nodes' rotations at the linearization factorized
        (read, on the device, where installed)."""
        first = self.submitted
        marks = wp.array(np.arange(first + 1, first + 1 + len(blocks), dtype=np.int64), dtype=wp.int64,
                         device=elements.device)  # (each copied after its blocks)
        if self._side is not None:  # (after the work that made them, beside what follows)
            self._side.wait_event(wp.get_stream(elements.device).record_event())
        total = sum(self.blocks[b].elements for b in blocks) // 9
        if total != elements.size:
            raise ValueError(f"Refactorizer: {elements.size} element blocks given, the blocks' worlds have {total}")
        at = 0
        for i, (block, world, span) in enumerate(zip(blocks, worlds, spans, strict=True)):
            job, count = first + i, self.blocks[block].elements // 9
            k, s = self._slot_for(block, job)
            arena, slot = self._arenas[k], self.slots[k][s]
            shared, mark = self._slot_views(k, s)
            wp.copy(shared, elements, src_offset=at, count=count, stream=self._side)
            wp.copy(mark, marks, src_offset=i, count=1, stream=self._side)
            at += count
            self.pending[block] = Job(block, world, self.boundary + self.lag, job, span, frame, (elements, marks))
            if self.workers:
                self._procs[k][1].send((job, block, s, float(stiffness_scale), float(mass_scale)))
                self._queues[k].append(job)
                continue
            if self._side is not None:  # (here, at once: the slot is the next job's)
                wp.synchronize_stream(self._side)
            with threadpool_limits(1):
                try:
                    refactor(self._cache, arena, block, self.blocks[block], slot.at, stiffness_scale, mass_scale,
                             self.panel_rows, self.dtype)
                    _keep(self._cache, block, self.keep)
                    self._errors[job] = None
                except ArithmeticError as e:  # raised where the job is installed, as a worker's would be
                    self._errors[job] = e
        self.submitted += len(blocks)

    def settle(self, timeout: float = 600.0) -> float:
        """Wait until every worker has analysed its blocks ahead (:func:`warm`, ``keep`` at most);
        returns the seconds waited. (A benchmark's timed steps then see what a long run's do.)"""
        start = time.perf_counter()
        for k, (proc, _) in enumerate(self._procs):
            mine = min(sum(1 for b in self.blocks if b % self.workers == k), self.keep)
            analysed = np.frombuffer(self._arenas[k], np.int64, 1, 0)
            while analysed[0] < mine:
                if not proc.is_alive():
                    raise RuntimeError(f"Refactorizer: worker {k} stopped (exit code {proc.exitcode})")
                if time.perf_counter() - start > timeout:
                    raise RuntimeError(f"Refactorizer: worker {k} analysed {analysed[0]} of {mine} blocks in "
                                       f"{timeout} s")
                time.sleep(1e-3)
        return time.perf_counter() - start

    def due(self) -> list[Job]:
        """The jobs to install at the current boundary (in block order), taken off ``pending``,
        their workers waited for."""
        jobs = [self.pending.pop(b) for b in sorted(self.pending) if self.pending[b].at <= self.boundary]
        start = time.perf_counter()
        for job in jobs:
            while job.id not in self._errors:
                self._answer(job.block % max(self.workers, 1))
        self.waited += time.perf_counter() - start
        return jobs

    def values(self, job: Job) -> tuple[wp.array, wp.array]:
        """A job's forward and backward values (CPU arrays over the shared memory, until its block
        is sent again); raises its worker's error."""
        error = self._errors.pop(job.id)
        if error is not None:
            raise error
        return self._values_of(job.block)

    def install(self, copies: list[tuple[wp.array, int, wp.array]]) -> None:
        """Copy installed values to the device: ``copies`` ``(dest, offset, values)``, each CPU
        ``values`` (:meth:`values`) to ``dest[offset:]``. On CUDA through a device buffer: host to
        device on the side stream, beside the work already queued (the solve in flight still reads
        the old values), then in place on the current stream, after that work."""
        if not copies:
            return
        if self._side is None:
            for dest, offset, values in copies:
                wp.copy(dest, values, dest_offset=offset, count=values.size)
            return
        device, total = copies[0][0].device, sum(values.size for _, _, values in copies)
        main = wp.get_stream(device)
        if self._staging is None or self._staging.size < total:  # (a larger one: the last is freed after its copies)
            self._staging = wp.empty(total, dtype=copies[0][0].dtype, device=device)
        elif self._staged is not None:
            self._side.wait_event(self._staged)  # (the last installation's values out of it first)
        at = 0
        for _, _, values in copies:
            wp.copy(self._staging, values, dest_offset=at, count=values.size, stream=self._side)
            at += values.size
        main.wait_event(self._side.record_event())
        at = 0
        for dest, offset, values in copies:
            wp.copy(dest, self._staging, dest_offset=offset, src_offset=at, count=values.size, stream=main)
            at += values.size
        self._staged = main.record_event()

    def next_boundary(self) -> None:
        """Count a step boundary."""
        self.boundary += 1

    def cancel(self) -> None:
        """Forget the pending jobs (a refresh of every block made them stale); their workers'
        answers are read and dropped with the next ones."""
        if self._side is not None:  # (their copies done before their arrays go)
            wp.synchronize_stream(self._side)
        for job in self.pending.values():
            if job.id in self._errors:
                del self._errors[job.id]
            else:  # (its answer is still to come)
                self._dropped.add(job.id)
        self.pending.clear()

    def close(self) -> None:
        """Stop the workers."""
        self.cancel()
        self._finalizer()


def lock_pages(device, arenas: list) -> list[int]:
    """Page-lock each arena for ``device``'s copies (``cuMemHostRegister``: a copy from the device
    into it then runs beside other work instead of through the driver's staging); returns the
    addresses locked, none where the device is not CUDA or the driver refuses (the copies are then
    pageable: the same results, in the step's time)."""
    if not device.is_cuda:
        return []
    try:
        driver = ctypes.CDLL("libcuda.so.1")
    except OSError:
        return []
    unlock_pages(device, [], [])  # (what earlier refactorizers left locked)
    locked = []
    with wp.ScopedDevice(device):  # (its context current for the driver's call)
        for arena in arenas:
            address = np.frombuffer(arena, np.uint8).ctypes.data
            size = ctypes.c_size_t(len(arena))
            if driver.cuMemHostRegister_v2(ctypes.c_void_p(address), size, ctypes.c_uint(0)) == 0:  # (CUDA_SUCCESS)
                locked.append(address)
    return locked


def _shut_down(procs: list, locked: list[int], device, arenas: list) -> None:
    """Tell each worker to stop, and end those that do not within a second; unlock the arenas'
    pages (``arenas`` kept alive until then)."""
    for _, conn in procs:
        try:
            conn.send(None)
        except (BrokenPipeError, OSError):
            pass
    for proc, conn in procs:
        proc.join(timeout=1.0)
        if proc.is_alive():
            proc.terminate()
        conn.close()
    procs.clear()
    if locked:
        unlock_pages(device, list(locked), arenas)
        locked.clear()


def unlock_pages(device, addresses: list[int], arenas: list) -> None:
    """Unlock the pages at ``addresses`` (``cuMemHostUnregister``), and those left locked before;
    while ``device`` captures a graph, keep them all for later instead: the driver's call would end
    the capture in error (a refactorizer is often shut down by the garbage collector, at any point of
    another simulator's capture)."""
    if addresses:
        _UNLOCK_LATER.append((device, addresses, arenas))
    if getattr(device, "is_capturing", False):
        return
    due, kept = [], []
    for entry in _UNLOCK_LATER:  # (another device may be capturing)
        (kept if getattr(entry[0], "is_capturing", False) else due).append(entry)
    _UNLOCK_LATER[:] = kept
    try:
        driver = ctypes.CDLL("libcuda.so.1")
        for where, locked, _ in due:
            with wp.ScopedDevice(where):
                for address in locked:
                    driver.cuMemHostUnregister(ctypes.c_void_p(address))
    except Exception:  # (at interpreter exit the driver may be gone: the process's end frees them)
        pass
