"""The worlds' own refreshes of :class:`~warpsoft.linear.factors.WorldFactors`: a block that
serves one world alone is factorized anew, by worker processes beside the steps
(:mod:`~warpsoft.linear.refactor`), when that world's CG grew since its last factorization, and
installed a fixed number of step boundaries later.

:class:`OwnRefreshes` is the part of ``WorldFactors`` that decides, sends and installs them.
It reads the factors' operator and blocks (``op``, ``layout``, ``dtype``, ``panel_rows``,
``workers``, ``block_of``, ``first_world``, ``blocks``, ``orders``, ``patterns``, ``mesh_of``,
``solves``, ``_value_start``, ``_factorized``), their frames (``node_rot``, ``take_frame``) and
the settings ``world_ratio``, ``world_floor``, ``world_lag`` and ``world_batch`` (their defaults
and measurements: ``WORLD_*`` in factors.py), and keeps ``refactorizer``, ``world_refreshes``,
``_world_first``, ``_due``, ``_own`` and ``_frames`` (set by ``WorldFactors.__init__``).
"""

from __future__ import annotations

import multiprocessing

import numpy as np
import warp as wp

from ..processes import usable_cores
from .refactor import Block, Refactorizer


class OwnRefreshes:
    """Mixin of :class:`~warpsoft.linear.factors.WorldFactors`: its worlds' own refreshes (module doc)."""

    @property
    def refreshes_alone(self) -> bool:
        """Whether a block that serves one world alone is refreshed alone (the worlds' own
        refreshes are on: ``world_floor`` set, panels); then only the worlds that share a block
        count toward a refresh of the whole model (:meth:`observe`)."""
        return self.world_floor is not None and self.layout == "panels"

    def observe(self, iterations: int) -> None:
        """Told a solve's iterations (its slowest world's). With :attr:`refreshes_alone`, passed
        over: a world alone in its block is refreshed alone (:meth:`observe_worlds`), and the
        worlds that share one mark the whole model stale there. Else as
        :meth:`~warpsoft.linear.warped.WarpedFrames.observe`. (Where the slowest world's count
        refactorized every block, 1024 different Diamonds in the inverse model, on the H200, had a
        step of 30.2 s, all 1024 blocks factorized on the host, at step 46 of 50:
        docs/performance.md.)"""
        if not self.refreshes_alone:
            super().observe(iterations)

    def observe_worlds(self, iterations: np.ndarray) -> None:
        """Told each world's iterations of a solve, ``(worlds,)``: a world whose CG grew past
        ``world_ratio`` times its first solve's after its block's last factorization, and past
        ``world_floor``, marks its block due for :meth:`refresh_worlds`, with that count (panels
        only; a block that serves one world alone: a shared one is made at its first world's
        state, and its other worlds would then step otherwise than alone). A world installed while
        this solve ran (:meth:`refresh_worlds` with ``solving``) solved on its old factor: its count
        is passed over, and its next solve's starts the new factor's. The worlds that share a
        block count toward the whole model's refresh, their slowest as a solve's count in
        :meth:`~warpsoft.linear.warped.WarpedFrames.observe`."""
        if not self.refreshes_alone or self.block_of is None:
            return
        its = np.asarray(iterations, dtype=np.int64)
        if self._due is None:
            self._start_own()
        shared = ~self._own[self.block_of]
        if shared.any():
            super().observe(int(its[shared].max()))
        first = self._world_first
        new, passed = first == 0, first < 0
        first[new] = np.maximum(its[new], 1)
        first[passed] = 0
        grown = ~new & ~passed & (its > np.maximum(self.world_ratio * first, self.world_floor))
        np.maximum.at(self._due, self.block_of[grown], its[grown])
        self._due[~self._own] = 0

    def _start_own(self) -> None:
        """The blocks that serve one world alone (they may be refreshed alone), none due yet."""
        self._due = np.zeros(self.blocks, dtype=np.int64)
        self._own = np.bincount(self.block_of, minlength=self.blocks) == 1

    @property
    def worlds_due(self) -> bool:
        """Whether the next step boundary has work (:meth:`refresh_worlds`): a block due for its own
        refresh, or one being refactorized."""
        pending = self.refactorizer is not None and bool(self.refactorizer.pending)
        return pending or (self._due is not None and bool(self._due.any()))

    def refresh_worlds(self, solving: bool = False) -> int:
        """At a step boundary (the step runs it beside its first solve): send the blocks due (:meth:`observe_worlds`;
        at most ``world_batch``, those of the worlds whose CG took the most) to be factorized anew
        at its world's last linearization (:mod:`~warpsoft.linear.refactor`), and install those sent
        ``world_lag`` boundaries ago: their values written in place (the captured graphs read the
        same arrays), their worlds' frame the node rotations they were factorized at. Host work
        here: a due world's element blocks made and their copy into its worker's shared memory
        queued (beside the graphs, on CUDA), a job's values copied from it to the device; the
        system's sum, CHOLMOD and the panels run in the worker. ``solving``: a solve on the current
        factors is in flight (the step runs this beside its first graph): what this queues follows
        it on the device, and its iterations, observed next, are the installed worlds' old factors'
        (:meth:`observe_worlds` passes them over). Returns the blocks installed."""
        m, d = self.op.model, self.op.model.device
        if self.refactorizer is None and self._due is not None:
            self.refactorizer = self._refactorizer()
        refactor = self.refactorizer
        if refactor is None:
            return 0
        refactor.lag = self.world_lag
        refactor.next_boundary()
        # the slowest worlds' blocks first, at most world_batch of them (the others, still grown at
        # the next solve, come up again); a block being made is not sent again: its count still
        # grows on the old factor
        due = [] if self._due is None else [int(b) for b in np.flatnonzero(self._due) if int(b) not in refactor.pending]
        due = sorted(sorted(due, key=lambda b: -int(self._due[b]))[:self.world_batch or len(due)])
        if due:  # their worlds' element blocks, one world after another, and their nodes' rotations now
            worlds = [int(self.first_world[b]) for b in due]
            ranges = [(int(m.world_elem_start[w]), int(m.world_elem_start[w + 1])) for w in worlds]
            blocks = wp.empty(sum(16 * (e1 - e0) for e0, e1 in ranges), dtype=wp.mat33d, device=d)
            self.op.elastic.blocks(self.op.rot, blocks, ranges)
            spans = [(int(m.world_node_start[w]), int(m.world_node_start[w + 1])) for w in worlds]
            if self._frames is None:
                self._frames = wp.empty_like(self.node_rot)
            for lo, hi in spans:  # (a world being made is not sent again: its nodes' stay until installed)
                wp.copy(self._frames, self.node_rot, dest_offset=lo, src_offset=lo, count=hi - lo)
            refactor.submit(due, worlds, blocks, self.op.stiffness_scale, self.op.mass_scale, spans, self._frames)
        if self._due is not None:
            self._due[:] = 0
        jobs, copies = refactor.due(), []
        for job in jobs:
            b = job.block
            # (_factorized names the world of an error; the worker has checked the ordering itself)
            _, *values = self._factorized(m, b, job.world, lambda j=job: (self.orders[j.block], *refactor.values(j)))
            for (_, _, val, _, _), start, v in zip(self.solves, self._value_start, values, strict=True):
                copies.append((val, int(start[b]), v))  # (from the shared memory)
            self._world_first[job.world] = -1 if solving else 0
        refactor.install(copies)
        if jobs:
            self.take_frame([job.span for job in jobs], [job.frame for job in jobs])
        self.world_refreshes += len(jobs)
        return len(jobs)

    def _refactorizer(self) -> Refactorizer:
        """The workers of the worlds' own refreshes (:data:`WORKERS`, or a core each), their shared
        memory laid out for the blocks that serve one world alone."""
        m = self.op.model
        workers = min(self.workers or usable_cores(), int(self._own.sum()))
        if "fork" not in multiprocessing.get_all_start_methods():  # (this process does the work)
            workers = 1
        own = [int(b) for b in np.flatnonzero(self._own)]
        worlds = {b: int(self.first_world[b]) for b in own}
        elements = {b: 144 * int(m.world_elem_start[w + 1] - m.world_elem_start[w]) for b, w in worlds.items()}
        values = {b: tuple(int(s[b + 1] - s[b]) for s in self._value_start) for b in own}
        itemsize = 8 if self.dtype == wp.float64 else 4
        places, slots, arenas = Refactorizer.layout(elements, values, workers, itemsize)
        has_mass = getattr(m, "mass_np", None) is not None
        blocks = {b: Block(self.patterns, self.mesh_of[w], self.orders[b],
                           m.mass_np[m.world_nodes(w)].copy() if has_mass else None, elements[b], places[b])
                  for b, w in worlds.items()}
        npd = np.float64 if itemsize == 8 else np.float32
        return Refactorizer(blocks, slots, arenas, self.world_lag, self.panel_rows, npd, m.device)
