"""Each world's rows after a step, as the report records them (``StepStats.worlds``), from the
step's one read.

What can be computed for all worlds at once is: the effectors' errors, each world's gap to the
linear prediction, the actuators' misses and the warnings they raise; the loop over the worlds
only fills their dictionaries, by names laid out once per model (:class:`Layout`). When every
world ran its own NumPy calls, 256 Diamonds took 5.0-6.5 ms here (CPU VM), now 1.7-2.7 ms; on the
H200 the host's share of a 1024-design step fell from 44-48 ms to 25-35 ms (docs/performance.md).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from warpsoft.kernels.resolve import gauss_seidel as gs_kernels

from . import watch
from .stats import StepStats

if TYPE_CHECKING:
    from .simulator import Simulator


class Layout:
    """Where each world's named rows are, found once per model: its actuators' names and rows,
    its effectors (point, table index and controlled axes), the displacement-driven actuator rows
    of direct-model worlds (whose misses are watched) with their floors (m, m^3)."""

    def __init__(self, sim: Simulator):
        rows, scenes = sim.rows, sim.model.scenes
        g, k = sim.gauss_seidel.host if rows.num_actuators else None, gs_kernels
        worlds = sim.model.num_worlds
        self.actuators = [(rows.actuator_rows(w).start, [a.name for a in rows.actuators[w]]) for w in range(worlds)]
        self.effectors = [[(p.item.name, p.first_point) for _, p in rows._world_effectors(w)] if rows.kind("effector")
                          else [] for w in range(worlds)]
        targeted = [(w, k_, p) for w in range(worlds) if rows.kind("effector")
                    for k_, p in rows._world_effectors(w) if p.item.target is not None]
        self.targeted = [[] for _ in range(worlds)]  # per world: (name, place in the arrays below)
        for j, (w, _, p) in enumerate(targeted):
            self.targeted[w].append((p.item.name, j))
        self.target_index = np.array([k_ for _, k_, _ in targeted], dtype=np.int64)
        self.target_point = np.array([p.first_point for _, _, p in targeted], dtype=np.int64)
        self.target_axes = np.zeros((len(targeted), 3))
        for j, (_, _, p) in enumerate(targeted):
            self.target_axes[j, p.item.axis_ids] = 1.0
        # the direct-model worlds' actuator rows (their delta is kept for the next step's aims), and
        # among them the displacement-driven ones, whose misses are watched
        self.direct_rows, self.watched = [], [[] for _ in range(worlds)]
        floors = []
        for w in range(worlds):
            if scenes[w].inverse:
                continue
            start = rows.world_row_start[w]
            for i, act in enumerate(rows.actuators[w]):
                self.direct_rows.append(start + i)
                if not g[k.FORCE_MODE, start + i]:
                    self.watched[w].append((act.name, start + i, len(floors)))
                    floors.append(1e-4 * (sim.size if act.kind == "cable" else sim.size ** 3))
        self.direct_rows = np.array(self.direct_rows, dtype=np.int64)
        self.watched_rows = np.array([r for per in self.watched for _, r, _ in per], dtype=np.int64)
        self.floors = np.array(floors)
        self.world_of_row = np.searchsorted(rows.world_row_start, np.arange(rows.num_rows), side="right") - 1
        self.forces = rows.world_actuators + rows.world_bilateral + rows.world_contacts > 0
        self.gaps = np.zeros(worlds)  # each world's gap to its last linear prediction (keep_gaps)
        # per world, as Python values (the loop of record_rows reads them 1024 times a step):
        # what it records (direct: its Gauss-Seidel's outcome; inverse: its actuators' reach)
        inverse = [bool(scenes[w].inverse) for w in range(worlds)]
        self.world_flags = list(zip((rows.world_bilateral > 0).tolist(), (rows.world_contacts > 0).tolist(),
                                    self.forces.tolist(), inverse, strict=True))


def layout(sim: Simulator) -> Layout:
    """The model's :class:`Layout`, made at the first step."""
    if sim.report_layout is None:
        sim.report_layout = Layout(sim)
    return sim.report_layout


def record_rows(sim: Simulator, stats: StepStats, host: dict[str, np.ndarray]) -> None:
    """Each world's rows at the new state (evaluated on the device by the step), by name, and the
    Gauss-Seidel statistics, from the step's read (``host``)."""
    rows, lay = sim.rows, layout(sim)
    targets = rows.set_time(stats.time)  # the step's targets, already on the device
    delta, points = host["delta"], host["points"][: rows.num_points]
    lam = host["lam"] if rows.num_columns else np.zeros(rows.num_rows)
    errors = []
    if len(lay.target_index):  # every targeted effector's distance to its target on its controlled axes (m)
        off = (points[lay.target_point] - targets[lay.target_index]) * lay.target_axes
        errors = np.sqrt(np.einsum("ij,ij->i", off, off)).tolist()
    gaps = unpredicted(sim, stats, host, lay)
    missed = actuator_misses(sim, stats, delta, lay) if len(lay.direct_rows) else []
    delta_l, lam_l = delta.tolist(), lam.tolist()
    result = host["resolve"].tolist() if rows.num_columns else None
    # (a world's empty dictionaries stay the ones WorldStats made; 256 Diamonds: 0.98 -> 0.75 ms, CPU VM)
    for w, (ws, (start, names), (bilateral, contacts, forces, inverse)) in enumerate(
            zip(stats.worlds, lay.actuators, lay.world_flags, strict=True)):
        if names:
            end = start + len(names)
            ws.actuator_delta = dict(zip(names, delta_l[start:end], strict=True))
            ws.actuator_lambda = dict(zip(names, lam_l[start:end], strict=True))
        if lay.effectors[w]:
            ws.effectors = {name: points[i] for name, i in lay.effectors[w]}
        if lay.targeted[w]:
            ws.targets = {name: targets[lay.target_index[j]] for name, j in lay.targeted[w]}
            ws.effector_error = {name: errors[j] for name, j in lay.targeted[w]}
        if lay.watched[w]:
            ws.actuator_residual = {name: missed[j] for name, _, j in lay.watched[w]}
        if bilateral:
            ws.attachments = rows.kind("attachment").forces(lam, w)
        if contacts:
            watch.contacts(sim, stats, w, host)
        if forces:
            ws.linearization_error = gaps[w]
        if names and inverse:
            watch.out_of_reach(sim, stats, w, delta[start:start + len(names)], lam[start:start + len(names)])
        if forces and not inverse:
            ws.resolve_iterations, ws.resolve_residual = int(result[w][0]), result[w][1]
            if not result[w][2]:
                stats.warnings.append(f"step {stats.index}{sim.world_label(w)}: Gauss-Seidel stopped after "
                                      f"{ws.resolve_iterations} sweeps, last change {ws.resolve_residual:.3e}")


def keep_gaps(sim: Simulator, host: dict[str, np.ndarray], moved: np.ndarray) -> None:
    """After a Newton iteration, from its read ``host``: how far each world's rows ended from the
    iteration's linear prediction ``delta_free + W lambda`` (``W``'s columns are the world's own
    force rows, the first ``force_rows[w]``), the largest per world (its units: m, m^3), kept for
    the worlds that ``moved`` in it. A world held while others iterate keeps the gap of its own
    last iteration: the later iterations' predictions do not apply to it (it does not move)."""
    rows, lay = sim.rows, layout(sim)
    if not (rows.num_rows and rows.num_columns):
        return
    gaps = np.zeros(sim.model.num_worlds)
    W = host["W"][:, :int(host["force_rows"].max(initial=0))]  # (the columns in use: the most force rows of a world)
    j = np.arange(W.shape[1])
    # each world's multipliers in its columns' order (0 past its force rows), repeated for its rows
    starts = rows.world_row_start
    lam = np.where(j[None, :] < host["force_rows"][:, None],
                   host["lam"][np.minimum(starts[:-1, None] + j[None, :], rows.num_rows - 1)], 0.0)
    lam = np.repeat(lam, np.diff(starts), axis=0)
    predicted = host["delta_free"] + np.einsum("ij,ij->i", W, lam)
    np.maximum.at(gaps, lay.world_of_row, np.abs(host["delta"] - predicted))
    lay.gaps[moved] = gaps[moved]


def unpredicted(sim: Simulator, stats: StepStats, host: dict[str, np.ndarray], lay: Layout) -> list[float]:
    """Each world's gap to its last linear prediction (:func:`keep_gaps`), and the warning of
    :func:`warpsoft.watch.unpredicted_message` for the worlds where it exceeds ``UNPREDICTED``
    times the step's largest node motion."""
    gaps, worlds = lay.gaps, sim.model.num_worlds
    motion = np.sqrt(host["health_step"])
    far = lay.forces & (gaps > watch.UNPREDICTED * motion) & (gaps > 1e-9 * sim.size)
    for w in range(worlds):
        key = ("unpredicted", w)
        if (far[w] or sim.episodes.get(key)) and watch.begins(sim, key, bool(far[w])):
            stats.warnings.append(watch.unpredicted_message(sim, stats, w, float(gaps[w]), float(motion[w])))
    return gaps.tolist()


def actuator_misses(sim: Simulator, stats: StepStats, delta: np.ndarray, lay: Layout) -> list[float]:
    """Direct model: how far each displacement-driven actuator (the watched rows of ``lay``) is
    from what it was asked for this step, in its units (cable m, cavity m^3); a warning, once per
    episode, for a world where one misses by more than ``MISSED_COMMAND`` of its command and
    more than its floor. The direct worlds' actuator rows are kept for the next step's aims."""
    aims = watch.actuator_aims(sim)
    r = lay.watched_rows
    misses = np.abs(delta[r] - aims[r])
    missing = misses > watch.MISSED_COMMAND * np.abs(aims[r]) + lay.floors
    sim.row_delta_prev[lay.direct_rows] = delta[lay.direct_rows]
    misses_l = misses.tolist()
    worlds = np.zeros(sim.model.num_worlds, dtype=bool)
    worlds[lay.world_of_row[r[missing]]] = True
    for w in range(sim.model.num_worlds):
        key = ("missed", w)
        if (worlds[w] or sim.episodes.get(key)) and watch.begins(sim, key, bool(worlds[w])):
            which = [f"{name} ({float(delta[row]):.4g} for {float(aims[row]):.4g})"
                     for name, row, j in lay.watched[w] if missing[j]]
            stats.warnings.append(watch.missed_message(sim, stats, w, which))
    return misses_l
