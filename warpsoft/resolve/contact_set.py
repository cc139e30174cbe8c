"""The contacts that bear, found lazily: ``W`` only between them (the CPU path, ``W`` from the factor).

A detection keeps every point within contact distance, and few of them bear: on the Grasper's
lift, 6 of 35 contacts (a flat face on a rigid one bears on the patch's corners). Each kept
contact costs three columns of ``Z = L^-1 P H^T`` and three rows of every sweep, yet one that
carries no force changes nothing, as long as its gap stays open. So the direct model resolves a
set ``S``: the actuator and attachment rows and the contacts that bore at the warm start. Then

1. ``W`` between the rows of ``S`` (a forward solve over their columns) plus the rigid bodies'
   share, and the sweeps on ``S`` alone (the same kernel, on ``S`` packed world by world);
2. the correction ``e = e_free + A^-1 (s H^T lambda)`` (one solve) and the rigid bodies';
3. every contact left out is checked against it: its normal delta to first order,
   ``delta_free + H (e - e_free) + J (d - d_free)``. Those it would let through (a gap below
   ``-PENETRATION`` times the largest free delta) join ``S`` and the round repeats from 1,
   warm-started.

At the end every contact outside ``S`` has no force and an open gap: Signorini's conditions
hold for it, so the multipliers solve the whole problem (friction too: a contact without normal
force has none). After :data:`MAX_ROUNDS` rounds the last one takes every contact. A row left
out keeps no ``W`` row; its ``delta_free`` holds its delta after the correction, so that
``delta_free + W lambda`` stays each row's linear prediction (what the report checks).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np
import warp as wp

from warpsoft.kernels.resolve import gauss_seidel as gs_kernels
from warpsoft.kernels.rows import common as row_kernels

if TYPE_CHECKING:
    from ..simulator import Simulator

MAX_ROUNDS = 6  # rounds of the set before the last one takes every contact in use
PENETRATION = 1e-8  # a left-out contact's gap below -PENETRATION x (the largest |delta_free|) joins the set


class ContactSet:
    """The lazy contact set of a CPU simulator whose direct-model worlds have contacts and whose
    ``W`` comes from the factor (``SparseDirect``). ``rounds`` and ``size`` (the rows in the
    set) of the last resolve, for the bench and the tests."""

    def __init__(self, sim: Simulator):
        rows = sim.rows
        self.sim, self.rows, cpu = sim, rows, rows.device
        n = rows.num_rows
        self.contact = np.zeros(n, dtype=bool)  # rows of the contact blocks
        self.normal_of = np.arange(n)  # each contact row's normal row (itself elsewhere)
        for w in range(rows.num_worlds):
            block, rps = rows.contact_rows(w), rows.rows_per_contact(w)
            self.contact[block] = True
            self.normal_of[block] = block.start + (np.arange(block.stop - block.start) // rps) * rps
        self.is_normal = self.normal_of == np.arange(n)  # (every row that is not a contact's tangent)
        self.world_of = np.searchsorted(rows.world_row_start, np.arange(n), side="right") - 1
        self.predicted = wp.zeros(n, dtype=wp.float64, device=cpu)  # every row's delta after a correction
        self.packed_start = wp.zeros(rows.num_worlds + 1, dtype=wp.int32, device=cpu)
        self.packed_rows = wp.zeros(rows.num_worlds, dtype=wp.int32, device=cpu)
        self.rounds, self.size = 0, 0

    def resolve(self, correct: Callable[[], None]) -> None:
        """Steps 1-3 above until no contact left out would go through; ``correct()`` makes the
        correction from ``lam`` (``sim.dx``, ``sim.row_motion = A^-1 (s H^T lambda)`` and the
        rigid bodies'): after the last round it is the iteration's. ``lam`` holds the multipliers
        (0 off ``S``), the Gauss-Seidel's ``result`` its sweeps (summed over the rounds)."""
        sim, rows = self.sim, self.rows
        gs = sim.gauss_seidel
        W, delta_free, lam = rows.W.numpy(), rows.delta_free.numpy(), gs.lam.numpy()  # views: the CPU device
        force_rows = rows.world_force_rows.numpy()
        start = rows.world_row_start
        in_use = np.zeros(rows.num_rows, dtype=bool)  # force rows in use
        for w in range(rows.num_worlds):
            in_use[start[w]:start[w] + int(force_rows[w])] = True
        contacts = in_use & self.contact
        rigid_share = W.copy()  # what the rigid bodies put in W (the compliance stage left only that)
        held = in_use & ~self.contact  # actuators and attachments: always in the set
        bearing = contacts & self.is_normal & (lam > 0.0)  # the contacts that bore at the warm start
        member = held | (contacts & bearing[self.normal_of])
        scale = float(np.abs(delta_free[in_use]).max(initial=0.0))
        sweeps = np.zeros(rows.num_worlds)
        self.rounds = 0
        while True:
            self.rounds += 1
            last = self.rounds >= MAX_ROUNDS
            if last:
                member = in_use.copy()
            lam[contacts & ~member] = 0.0
            sim.solver.compliance(rows, sim.constraint_scale, only=member | ~(in_use | self.contact))
            W += rigid_share
            self._sweep(member, W, delta_free, lam)
            sweeps += gs.result.numpy()[:, gs_kernels.ITERATIONS]
            correct()
            self._predict()
            predicted = self.predicted.numpy()
            out = contacts & ~member
            by_column = np.zeros((rows.num_worlds, W.shape[1]))  # lam of each world's force rows, by column
            for w in range(rows.num_worlds):
                by_column[w, :int(force_rows[w])] = lam[start[w]:start[w] + int(force_rows[w])]
            predicted[out] += (rigid_share[out] * by_column[self.world_of[out]]).sum(axis=1)
            through = out & self.is_normal & (predicted < -PENETRATION * scale)
            if last or not through.any():
                break
            member |= through[self.normal_of] & in_use
        delta_free[out] = predicted[out]  # no W row: the prediction is delta_free alone
        W[out] = 0.0
        gs.result.numpy()[:, gs_kernels.ITERATIONS] = sweeps
        self.size = int(member.sum())

    def _sweep(self, member: np.ndarray, W: np.ndarray, delta_free: np.ndarray, lam: np.ndarray) -> None:
        """The Gauss-Seidel kernel on the rows of ``member``, packed world by world (a world's
        actuators, attachments, then its contacts in the set: the layout the kernel expects)."""
        sim, rows, gs = self.sim, self.rows, self.sim.gauss_seidel
        idx = np.flatnonzero(member)
        world = self.world_of[idx]
        counts = np.bincount(world, minlength=rows.num_worlds).astype(np.int32)
        packed_start = np.concatenate([[0], np.cumsum(counts)]).astype(np.int32)
        local = idx - rows.world_row_start[world]  # each member's column in W
        pos = np.arange(len(idx)) - packed_start[world]  # its column among its world's members
        width = max(int(counts.max(initial=0)), 1)
        packed = np.zeros((max(len(idx), 1), width))
        same = world[:, None] == world[None, :]
        ii, jj = np.nonzero(same)
        packed[ii, pos[jj]] = W[idx[ii], local[jj]]
        cpu = rows.device
        f64 = lambda a: wp.array(np.ascontiguousarray(a, dtype=np.float64), dtype=wp.float64, device=cpu)  # noqa: E731
        self.packed_start.assign(packed_start)
        self.packed_rows.assign(counts)
        lam_packed = f64(lam[idx] if len(idx) else np.zeros(1))
        start = sim.newton.delta_start.numpy()
        gs._launch(f64(packed), f64(delta_free[idx]), f64(start[idx]), f64(gs.host[:, idx]), self.packed_start,
                   self.packed_rows, gs.direct, f64(gs.friction.numpy()[idx]), lam_packed, gs.result, gs.counts,
                   gs.factor, gs.work)
        lam[idx] = lam_packed.numpy()[: len(idx)]

    def _predict(self) -> None:
        """Every row's delta after the correction, to first order, into ``predicted``:
        ``delta_free + H A^-1 (s H^T lambda)`` (the rigid share is added by the caller, for the
        rows it needs)."""
        sim, rows = self.sim, self.rows
        wp.copy(self.predicted, rows.delta_free)
        wp.launch(row_kernels.rows_times_vector, rows.num_entries,
                  inputs=[rows.h_row, rows.h_node, rows.h_coef, sim.row_motion, 0], outputs=[self.predicted],
                  device=rows.device)
