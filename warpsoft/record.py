"""Each world's rows after a step, as the report records them (``StepStats.worlds``), from the
step's one read.

Everything is computed for all worlds at once: the effectors' errors, each world's gap to the
linear prediction, the actuators' misses and the warnings they raise (in a loop over the worlds
that warn). A world's dictionaries, by the names laid out once per model (:class:`Layout`), are
made only when read (:class:`~warpsoft.stats.WorldRecord`). When every world ran its own NumPy
calls, 256 Diamonds took 5.0-6.5 ms here (CPU VM); a loop over the worlds that filled their
dictionaries, 1.7-2.7 ms (1024 Diamonds: about 6 ms); none, the figures of docs/performance.md.
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
        # what each world records: direct, its Gauss-Seidel's outcome; inverse, its actuators' reach
        # (as lists where a step loops over them: a few worlds then cost no NumPy call)
        inverse = np.array([bool(scenes[w].inverse) for w in range(worlds)], dtype=bool)
        self.solved = self.forces & ~inverse  # the worlds whose Gauss-Seidel ran
        self.some_solved, self.all_solved, self.all_forces = self.solved.any(), self.solved.all(), self.forces.all()
        self.bilateral = rows.world_bilateral > 0
        self.contact = np.flatnonzero(rows.world_contacts > 0).tolist()
        self.reach = [w for w in range(worlds) if inverse[w] and self.actuators[w][1]]


def layout(sim: Simulator) -> Layout:
    """The model's :class:`Layout`, made at the first step."""
    if sim.report_layout is None:
        sim.report_layout = Layout(sim)
    return sim.report_layout


def record_rows(sim: Simulator, stats: StepStats, host: dict[str, np.ndarray]) -> None:
    """Each world's rows at the new state (evaluated on the device by the step), by name, and the
    Gauss-Seidel statistics, from the step's read (``host``): computed for all worlds at once, and
    each world's dictionaries made only when read (:class:`~warpsoft.stats.WorldRecord`)."""
    rows, lay, record = sim.rows, layout(sim), stats.worlds.record
    targets = rows.set_time(stats.time)  # the step's targets, already on the device
    delta, points = host["delta"], host["points"][: rows.num_points]
    lam = host["lam"] if rows.num_columns else np.zeros(rows.num_rows)
    errors = np.zeros(0)
    if len(lay.target_index):  # every targeted effector's distance to its target on its controlled axes (m)
        off = (points[lay.target_point] - targets[lay.target_index]) * lay.target_axes
        errors = np.sqrt(np.einsum("ij,ij->i", off, off))
    gaps = unpredicted(sim, stats, host, lay)
    missed = actuator_misses(sim, stats, delta, lay) if len(lay.direct_rows) else np.zeros(0)

    def by_name(values: np.ndarray):  # world w's actuator rows of ``values``, by the actuators' names
        def make(w: int) -> dict[str, float]:
            start, names = lay.actuators[w]
            return dict(zip(names, values[start:start + len(names)].tolist(), strict=True))
        return make

    record.makers |= {
        "actuator_delta": by_name(delta), "actuator_lambda": by_name(lam),
        "effectors": lambda w: {name: points[i] for name, i in lay.effectors[w]},
        "targets": lambda w: {name: targets[lay.target_index[j]] for name, j in lay.targeted[w]},
        "effector_error": lambda w: {name: float(errors[j]) for name, j in lay.targeted[w]},
        "actuator_residual": lambda w: {name: float(missed[j]) for name, _, j in lay.watched[w]},
        "attachments": lambda w: rows.kind("attachment").forces(lam, w) if lay.bilateral[w] else {}}
    record.columns["linearization_error"] = gaps if lay.all_forces else np.where(lay.forces, gaps, 0.0)
    for w in lay.contact:
        watch.contacts(sim, stats, w, host)
    for w in lay.reach:
        start, names = lay.actuators[w]
        watch.out_of_reach(sim, stats, w, delta[start:start + len(names)], lam[start:start + len(names)])
    if rows.num_columns and lay.some_solved:  # the direct worlds' Gauss-Seidel: sweeps, last change, converged
        result = host["resolve"]
        sweeps, change = result[:, 0].astype(np.int64), result[:, 1]
        if not lay.all_solved:
            sweeps, change = np.where(lay.solved, sweeps, 0), np.where(lay.solved, change, 0.0)
        record.columns["resolve_iterations"], record.columns["resolve_residual"] = sweeps, change
        for w in np.flatnonzero(lay.solved & (result[:, 2] == 0)):
            stats.warnings.append(f"step {stats.index}{sim.world_label(int(w))}: Gauss-Seidel stopped after "
                                  f"{int(result[w, 0])} sweeps, last change {result[w, 1]:.3e}")


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


def unpredicted(sim: Simulator, stats: StepStats, host: dict[str, np.ndarray], lay: Layout) -> np.ndarray:
    """Each world's gap to its last linear prediction (:func:`keep_gaps`), ``(worlds,)``, and the
    warning of :func:`warpsoft.watch.unpredicted_message` for the worlds where it exceeds
    ``UNPREDICTED`` times the step's largest node motion."""
    gaps = lay.gaps.copy()
    motion = np.sqrt(host["health_step"])
    far = lay.forces & (gaps > watch.UNPREDICTED * motion) & (gaps > 1e-9 * sim.size)
    for w in watch.beginning(sim, "unpredicted", far):
        stats.warnings.append(watch.unpredicted_message(sim, stats, int(w), float(gaps[w]), float(motion[w])))
    return gaps


def actuator_misses(sim: Simulator, stats: StepStats, delta: np.ndarray, lay: Layout) -> np.ndarray:
    """Direct model: how far each displacement-driven actuator (the watched rows of ``lay``) is
    from what it was asked for this step, in its units (cable m, cavity m^3); a warning, once per
    episode, for a world where one misses by more than ``MISSED_COMMAND`` of its command and
    more than its floor. The direct worlds' actuator rows are kept for the next step's aims."""
    aims = watch.actuator_aims(sim)
    r = lay.watched_rows
    misses = np.abs(delta[r] - aims[r])
    missing = misses > watch.MISSED_COMMAND * np.abs(aims[r]) + lay.floors
    sim.row_delta_prev[lay.direct_rows] = delta[lay.direct_rows]
    worlds = np.zeros(sim.model.num_worlds, dtype=bool)
    worlds[lay.world_of_row[r[missing]]] = True
    for w in watch.beginning(sim, "missed", worlds):
        which = [f"{name} ({float(delta[row]):.4g} for {float(aims[row]):.4g})"
                 for name, row, j in lay.watched[w] if missing[j]]
        stats.warnings.append(watch.missed_message(sim, stats, int(w), which))
    return misses
