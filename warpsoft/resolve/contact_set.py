"""The contacts that bear, found lazily (wherever the Gauss-Seidel runs on the host's CPU): the
sweeps run on them alone and, where ``W`` comes from the factor, ``W`` is formed between them alone.

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

Where ``W`` was formed between every row in use from solved columns (CUDA, whose sweeps run on
the host between two graphs, and iterative solvers on the CPU device), only the sweeps shrink:
step 1 sweeps ``S``, step 3 checks a left-out contact by its row of ``W``, exactly, and no
correction is made between rounds (:meth:`ContactSet.resolve_columns`). The Grasper's sweeps,
108 rows, took 2.2 ms a step on the CPU device; on its 21, 0.7 ms.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np
import warp as wp

from warpsoft.kernels.resolve import gauss_seidel as gs_kernels
from warpsoft.kernels.rows import common as row_kernels

from ..launch import launch

if TYPE_CHECKING:
    from ..simulator import Simulator

MAX_ROUNDS = 6  # rounds of the set before the last one takes every contact in use
PENETRATION = 1e-8  # a left-out contact's gap below -PENETRATION x (the largest |delta_free|) joins the set


class ContactSet:
    """The lazy contact set of a simulator whose direct-model worlds have contacts swept on the
    host's CPU. ``rounds`` and ``size`` (the rows in the set) of the last resolve, for the bench
    and the tests."""

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
        # the set's rows packed world by world for the sweeps, on Warp's CPU device (filled in place:
        # the same arrays at every launch)
        f64 = lambda *shape: wp.zeros(shape, dtype=wp.float64, device="cpu")  # noqa: E731
        self.packed = {"W": f64(max(n, 1), max(rows.W.shape[1], 1)), "delta_free": f64(max(n, 1)),
                       "start": f64(max(n, 1)), "inputs": f64(gs_kernels.NUM_INPUTS, max(n, 1)),
                       "friction": f64(max(n, 1)), "lam": f64(max(n, 1))}
        self.packed_start = wp.zeros(rows.num_worlds + 1, dtype=wp.int32, device="cpu")
        self.packed_rows = wp.zeros(rows.num_worlds, dtype=wp.int32, device="cpu")
        self.rounds, self.size = 0, 0

    def resolve(self, correct: Callable[[], None]) -> None:
        """Steps 1-3 above until no contact left out would go through; ``correct()`` makes the
        correction from ``lam`` (``sim.dx``, ``sim.row_motion = A^-1 (s H^T lambda)`` and the
        rigid bodies'): after the last round it is the iteration's. ``lam`` holds the multipliers
        (0 off ``S``), the Gauss-Seidel's ``result`` its sweeps (summed over the rounds)."""
        sim, rows = self.sim, self.rows
        gs = sim.gauss_seidel
        W, delta_free, lam = rows.W.numpy(), rows.delta_free.numpy(), gs.lam.numpy()  # views: the CPU device
        start, friction = sim.newton.delta_start.numpy(), gs.friction.numpy()
        force_rows = rows.world_force_rows.numpy()
        rigid_share = W.copy()  # what the rigid bodies put in W (the compliance stage left only that)

        def one_round(member: np.ndarray, out: np.ndarray, in_use: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            sim.solver.compliance(rows, sim.constraint_scale, only=member | ~(in_use | self.contact))
            W[:] += rigid_share
            sweeps = self._sweep(member, W, delta_free, start, friction, lam)
            correct()
            self._predict()
            predicted = self.predicted.numpy()
            predicted[out] += (rigid_share[out] * self._by_column(lam, force_rows)[self.world_of[out]]).sum(axis=1)
            return sweeps, predicted

        sweeps, out, predicted = self._rounds(force_rows, delta_free, lam, one_round)
        delta_free[out] = predicted[out]  # no W row: the prediction is delta_free alone
        W[out] = 0.0
        gs.result.numpy()[:, gs_kernels.ITERATIONS] = sweeps

    def resolve_columns(self, host: dict[str, np.ndarray]) -> None:
        """The same rounds where ``W`` was formed between every row in use (from solved columns:
        the Gauss-Seidel on the host between two CUDA graphs, or on the CPU device with an
        iterative solver), from the arrays of one read ``host`` (``W``, ``delta_free``, ``delta``
        at the step's start, ``lam``, ``force_rows``, ``friction``; ``host["lam"]`` is updated in
        place). Only the sweeps shrink; a left-out contact is checked by its row of ``W``:
        ``delta_free + W lambda``, exact (no correction is made in between)."""
        gs = self.sim.gauss_seidel
        W, delta_free, lam, force_rows = host["W"], host["delta_free"], host["lam"], host["force_rows"]

        def one_round(member: np.ndarray, out: np.ndarray, in_use: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            sweeps = self._sweep(member, W, delta_free, host["delta"], host["friction"], lam)
            predicted = delta_free.copy()
            predicted[out] += (W[out] * self._by_column(lam, force_rows)[self.world_of[out]]).sum(axis=1)
            return sweeps, predicted

        sweeps, _, _ = self._rounds(force_rows, delta_free, lam, one_round)
        result = gs.host_arrays()["result"]
        result.numpy()[:, gs_kernels.ITERATIONS] = sweeps
        if result.ptr != gs.result.ptr:
            gs.result.assign(result)

    def _rounds(self, force_rows: np.ndarray, delta_free: np.ndarray, lam: np.ndarray, one_round: Callable) -> tuple:
        """The rounds, from the first set to the one that lets no contact through (or the last,
        with every contact): ``one_round(member, out, in_use)`` sweeps the set ``member`` (and
        what goes with it) and returns the worlds' sweeps and every row's predicted delta, read
        at the contacts left out ``out``. Returns the sweeps summed, the last ``out`` and the
        last prediction."""
        in_use, contacts, member = self._begin(force_rows, lam)
        scale = float(np.abs(delta_free[in_use]).max(initial=0.0))
        sweeps = np.zeros(self.rows.num_worlds)
        self.rounds = 0
        while True:
            self.rounds += 1
            if self.rounds >= MAX_ROUNDS:
                member = in_use.copy()
            lam[contacts & ~member] = 0.0
            out = contacts & ~member
            done, predicted = one_round(member, out, in_use)
            sweeps += done
            through = out & self.is_normal & (predicted < -PENETRATION * scale)
            if self.rounds >= MAX_ROUNDS or not through.any():
                break
            member |= through[self.normal_of] & in_use
        self.size = int(member.sum())
        return sweeps, out, predicted

    def _begin(self, force_rows: np.ndarray, lam: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The force rows in use (from each world's count ``force_rows``), the contact rows among
        them and the first set: the actuators and attachments, and the contacts whose normal
        multiplier in ``lam`` (the warm start) is positive."""
        rows = self.rows
        in_use = np.zeros(rows.num_rows, dtype=bool)
        for w in range(rows.num_worlds):
            in_use[rows.world_row_start[w]:rows.world_row_start[w] + int(force_rows[w])] = True
        contacts = in_use & self.contact
        bearing = contacts & self.is_normal & (lam > 0.0)
        return in_use, contacts, (in_use & ~self.contact) | (contacts & bearing[self.normal_of])

    def _by_column(self, lam: np.ndarray, force_rows: np.ndarray) -> np.ndarray:
        """``lam`` laid out as ``W``'s columns, one line per world ``(worlds, columns)``: a world's
        force rows in use (``force_rows`` of them) are its first columns."""
        rows = self.rows
        out = np.zeros((rows.num_worlds, rows.W.shape[1]))
        for w in range(rows.num_worlds):
            k, r = int(force_rows[w]), int(rows.world_row_start[w])
            out[w, :k] = lam[r:r + k]
        return out

    def _sweep(self, member: np.ndarray, W: np.ndarray, delta_free: np.ndarray, start: np.ndarray,
               friction: np.ndarray, lam: np.ndarray) -> np.ndarray:
        """The Gauss-Seidel kernel on Warp's CPU device on the rows of ``member``, packed world by
        world (a world's actuators, attachments, then its contacts in the set: the layout the
        kernel expects); ``lam`` is updated in place. Returns each world's sweeps."""
        rows, gs = self.rows, self.sim.gauss_seidel
        idx = np.flatnonzero(member)
        world = self.world_of[idx]
        counts = np.bincount(world, minlength=rows.num_worlds).astype(np.int32)
        packed_start = np.concatenate([[0], np.cumsum(counts)]).astype(np.int32)
        local = idx - rows.world_row_start[world]  # each member's column in W
        pos = np.arange(len(idx)) - packed_start[world]  # its column among its world's members
        p = {name: a.numpy() for name, a in self.packed.items()}  # views
        same = world[:, None] == world[None, :]
        ii, jj = np.nonzero(same)
        p["W"][ii, pos[jj]] = W[idx[ii], local[jj]]
        k = len(idx)
        p["delta_free"][:k], p["start"][:k], p["friction"][:k], p["lam"][:k] = (delta_free[idx], start[idx],
                                                                               friction[idx], lam[idx])
        p["inputs"][:, :k] = gs.host[:, idx]
        self.packed_start.numpy()[:] = packed_start
        self.packed_rows.numpy()[:] = counts
        c, a = gs.host_arrays(), self.packed
        gs._launch(a["W"], a["delta_free"], a["start"], a["inputs"], self.packed_start, self.packed_rows, c["direct"],
                   a["friction"], a["lam"], c["result"], c["counts"], c["factor"], c["work"])
        lam[idx] = p["lam"][:k]
        return c["result"].numpy()[:, gs_kernels.ITERATIONS].copy()

    def _predict(self) -> None:
        """Every row's delta after the correction, to first order, into ``predicted``:
        ``delta_free + H A^-1 (s H^T lambda)`` (the rigid share is added by the caller, for the
        rows it needs)."""
        sim, rows = self.sim, self.rows
        wp.copy(self.predicted, rows.delta_free)
        launch(row_kernels.rows_times_vector, rows.num_entries,
               inputs=[rows.h_row, rows.h_node, rows.h_coef, sim.row_motion, 0], outputs=[self.predicted],
               device=rows.device)
