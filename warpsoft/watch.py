"""What a step watches for after it ran, from the step's one read: non-finite or absurd motion
(errors, the state kept), and, as warnings said once per episode, elements turned inside out,
actuators that miss their command, and inverse targets out of reach."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from warpsoft.kernels.resolve import gauss_seidel as gs_kernels

from .errors import SimulationError
from .stats import StepStats

if TYPE_CHECKING:
    from .simulator import Simulator


def beginning(sim: Simulator, what: str, active: np.ndarray) -> np.ndarray:
    """The worlds where a warning episode ``what`` begins now: ``active`` ``(worlds,)`` (bool) is
    whether it is in force in each world, and it begins where it was not in force at the last
    step. Records ``active`` for the next step."""
    was = episodes(sim, what)
    if not (active.any() or was.any()):  # (the common case: no episode in force, nor one beginning)
        return EMPTY
    begin = np.flatnonzero(active & ~was)
    was[:] = active
    return begin


EMPTY = np.zeros(0, dtype=np.int64)


def begins(sim: Simulator, what: str, w: int, active: bool) -> bool:
    """:func:`beginning` for world ``w`` alone."""
    was = episodes(sim, what)
    began = bool(active) and not was[w]
    was[w] = bool(active)
    return began


def episodes(sim: Simulator, what: str) -> np.ndarray:
    """Whether a warning episode ``what`` is in force, per world ``(worlds,)`` (bool; changed in place)."""
    flags = sim.episodes.get(what)
    if flags is None:
        flags = sim.episodes[what] = np.zeros(sim.model.num_worlds, dtype=bool)
    return flags


ABSURD_STEP = 10.0  # a node moving this many times the model's size in one step: rejected like a NaN


def health(sim: Simulator, stats: StepStats, host: dict[str, np.ndarray], warn: bool = True) -> None:
    """No NaN leaves a step: a non-finite node is an error, and so is a node that moved more
    than ``ABSURD_STEP`` times the model's size in one step (finite but absurd: a load of 1e300 N
    put positions at 1e298 m and "-inf" in the report); more than the model's size is a warning
    (when ``warn``: the step's last read, not each of its Newton iterations). Each world is
    judged on its own nodes; the error names the worlds that failed (``SimulationError.worlds``)."""
    bad, largest = host["health_flag"], np.sqrt(host["health_step"])  # (worlds,)
    failed = [int(w) for w in np.flatnonzero(bad)]
    far = largest > ABSURD_STEP * sim.size
    absurd = [int(w) for w in np.flatnonzero((bad == 0) & far)] if far.any() else []
    if warn:
        for w in np.flatnonzero(largest > sim.size):
            stats.warnings.append(f"step {stats.index}{sim.world_label(int(w))}: a node moved {largest[w]:.3g} m in "
                                  f"one step, more than the model's size {sim.size:.3g} m: the simulation is likely "
                                  "unstable")
    if failed or absurd:
        sim.forget_warm_starts()
        worlds = sorted(failed + absurd)
    if failed:  # (any absurd world is named with them: the step failed for all of them)
        raise SimulationError(
            f"step {stats.index} (t = {stats.time:g} s){sim.world_label(worlds)}: {int(bad.sum())} node(s) got "
            f"non-finite positions (CG {stats.cg_iterations} iterations, residual {stats.cg_residual:.3e}); "
            "the state before the step is kept", worlds=worlds)
    if absurd:
        raise SimulationError(
            f"step {stats.index} (t = {stats.time:g} s){sim.world_label(worlds)}: a node moved "
            f"{largest[absurd].max():.3g} m in one step, more than {ABSURD_STEP:g} times the model's size "
            f"({sim.size:.3g} m): loads or inputs out of all proportion (or a diverging solve); the state before "
            "the step is kept", worlds=worlds)


def inverted_elements(sim: Simulator, stats: StepStats, host: dict[str, np.ndarray]) -> None:
    """Each world's count of elements turned inside out (``det F <= 0``) after the step; a
    warning when some appear (a very soft body under load, a step too large)."""
    counts = stats.worlds.record.columns["inverted_elements"] = host["inverted"]  # (a copy, the step's read)
    for w in beginning(sim, "inverted", counts > 0):
        stats.warnings.append(f"step {stats.index}{sim.world_label(int(w))}: {counts[w]} element(s) turned "
                              "inside out (det F <= 0): the material is too soft for the loads, or the step too "
                              "large; the step goes on (the element models turn inverted elements back), but the "
                              "result is not physical there")


def contacts(sim: Simulator, stats: StepStats, w: int, host: dict[str, np.ndarray]) -> None:
    """A world's contacts after the step: how many carry a force, the total normal force and the
    total friction force (N, the sums of each contact's), the deepest penetration (m, the most
    negative gap); an overflow of its contact slots is a warning, once per episode (the slots
    went to the first nodes in node order, not the nearest)."""
    rows, ws = sim.rows, stats.worlds[w]
    rps = rows.rows_per_contact(w)
    block = host["lam"][rows.contact_rows(w)]
    used = rows.contacts_in_use(w, host["force_rows"][w])
    lam = block[:used * rps].reshape(used, rps)
    gaps = host["delta"][rows.contact_rows(w)][:used * rps:rps]
    ws.contacts = int(np.count_nonzero(lam[:, 0] > 0.0))
    ws.contact_force = float(lam[:, 0].sum())
    ws.friction_force = float(np.linalg.norm(lam[:, 1:], axis=1).sum()) if rps > 1 else 0.0
    ws.penetration = float(max(0.0, -gaps.min())) if used else 0.0
    found, capacity = int(host["contacts_found"][w]), int(rows.world_contacts[w]) // rps
    if begins(sim, "overflow", w, found > capacity):
        stats.warnings.append(f"step {stats.index}{sim.world_label(w)}: {found} points came within contact distance "
                              f"of an obstacle, a rigid body or their own surface, more than the scene's {capacity} "
                              f"contact rows: the first {capacity} (in node order) were kept, the others may go "
                              "through; raise it with scene.set_contacts(capacity)")


UNPREDICTED = 0.2  # rows ending this far (relative to the step's largest node motion) from the linear prediction


def unpredicted_message(sim: Simulator, stats: StepStats, w: int, gap: float, motion: float) -> str:
    """The warning of a world whose rows ended ``gap`` (m, m^3) from the step's linear prediction
    ``delta_free + W lambda``, more than ``UNPREDICTED`` times the step's largest node motion
    ``motion`` (m): the step solves the linearized problem, and near a buckling point, or with a
    step too large, the body no longer moves as predicted (the gaps are measured for all worlds
    at once in :mod:`warpsoft.record`)."""
    return (f"step {stats.index}{sim.world_label(w)}: the rows ended {gap:.3g} away from the step's linear "
            f"prediction, for nodes that moved up to {motion:.3g} m: the linearization no longer predicts the "
            "motion (near a buckling point, or a step too large); smaller steps (dt, max_step) follow it better")


MISSED_COMMAND = 0.05  # relative miss of a displacement command, past which a direct-model actuator warns


def actuator_aims(sim: Simulator) -> np.ndarray:
    """What each row's actuator was asked for this step, ``(rows,)``: its input within its bounds
    and within its step limit from where it was (for all worlds at once; read by
    :mod:`warpsoft.record`)."""
    g, k, prev = sim.gauss_seidel.host, gs_kernels, sim.row_delta_prev
    aim = np.clip(sim.values, g[k.DMIN], g[k.DMAX])
    return np.clip(aim, prev - g[k.MAX_STEP], prev + g[k.MAX_STEP])


def missed_message(sim: Simulator, stats: StepStats, w: int, which: list[str]) -> str:
    """The warning of a direct-model world whose displacement-driven actuators ``which`` (each
    "name (reached for asked)") miss what they were asked for this step (:func:`actuator_aims`) by
    more than ``MISSED_COMMAND`` of the command and a floor tied to the model's size (the misses
    are measured for all worlds at once in :mod:`warpsoft.record`)."""
    return (f"step {stats.index}{sim.world_label(w)}: actuator(s) missing their command: {', '.join(which)}: the "
            "body cannot follow (too soft, a large step, or bounds); see each step's actuator_residual")


OUT_OF_REACH = 1e-3  # effector error, in model sizes, past which an inverse world says what holds it back


def out_of_reach(sim: Simulator, stats: StepStats, w: int, delta: np.ndarray, lam: np.ndarray) -> None:
    """An inverse world whose target is out of reach says so, once per episode: which effector
    misses by how much, and which actuators sit on a bound (displacement or force) when it begins.
    Out of reach: the error is not small and no longer shrinks (while it shrinks, the world is
    on its way, held only by the change allowed per step), and some actuator is on a bound."""
    rows, ws = sim.rows, stats.worlds[w]
    worst = max(ws.effector_error.items(), key=lambda kv: kv[1], default=(None, 0.0))
    last_error = sim.last_effector_error.get(w, np.inf)
    held = ()
    if worst[1] > OUT_OF_REACH * sim.size and worst[1] >= (1.0 - 1e-3) * last_error:
        g, k, start = sim.gauss_seidel.host, gs_kernels, rows.world_row_start[w]
        found = []
        for i, act in enumerate(rows.actuators[w]):
            r = start + i
            for value, bound, side, what in ((delta[i], g[k.DMAX, r], 1, "largest displacement"),
                                             (delta[i], g[k.DMIN, r], -1, "smallest displacement"),
                                             (lam[i], g[k.HI, r], 1, "largest force"),
                                             (lam[i], g[k.LO, r], -1, "smallest force")):
                # on it (the geometry may take a displacement a little past the QP's linear bound)
                if np.isfinite(bound) and side * (value - bound) >= -(1e-2 if "displacement" in what else 1e-9) * \
                        max(abs(bound), 1e-12):
                    found.append(f"{act.name} (at its {what}, {bound:g})")
                    break
        held = tuple(found)
    if begins(sim, "out of reach", w, bool(held)):  # said once (the bounds may take turns after)
        stats.warnings.append(f"step {stats.index}{sim.world_label(w)}: inverse model: the target is out of reach: "
                              f"effector '{worst[0]}' misses it by {worst[1]:.3g} m; held back by {', '.join(held)}")
    sim.last_effector_error[w] = worst[1]
