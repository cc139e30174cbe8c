"""A step's inputs from the user's Python: the kinematic frames' poses, time-dependent loads,
effector targets and actuator inputs (a Control's value, else the actuator's own: a number, a
:class:`~warpsoft.scene.actuator.Ramp` or a schedule of time), evaluated once a step on the host
and copied to the device in one go each (:func:`host_inputs`)."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from .errors import SceneError
from .scene.actuator import Ramp
from .state import Control

if TYPE_CHECKING:
    from .simulator import Simulator


def host_inputs(sim: Simulator, t: float, controls: list[Control | None]) -> None:
    """What the user's Python decides for this step, computed once and copied in one go each:
    the kinematic frames' poses, time-dependent loads, effector targets, actuator inputs (only
    when they changed)."""
    m, rows = sim.model, sim.rows
    if sim.driven is not None:
        sim.driven.set_time(t)  # where the kinematic frames carry their nodes
    if m.time_dependent_loads:
        sim.f_ext.assign(m.external_forces(t) + (m.f_const_np if m.f_const is not None else 0.0))
    if rows is not None:
        rows.set_time(t)  # effector rows measure x - target
        if rows.num_actuators:
            sim.values = actuator_values(sim, t, controls)
            sim.gauss_seidel.set_values(sim.values)


def actuator_values(sim: Simulator, t: float, controls: list[Control | None]) -> np.ndarray:
    """The input of every actuator row at time ``t`` (``(rows,)``): a Control's value, else the
    actuator's own (a number, or a schedule called once here: :func:`own_inputs`)."""
    rows, values = sim.rows, own_inputs(sim, t)
    if controls.count(None) == len(controls):  # (a batch's usual step: no world's inputs overridden, no loop
        return values  # over the worlds: 1024 coarse Diamonds on the VM, host_inputs 84 -> 38-39 us)
    starts = rows.world_row_start.tolist()
    for w, control in enumerate(controls):
        given = control.inputs if control is not None else None
        if not given:
            continue
        acts, start = rows.actuators[w], starts[w]
        unknown = set(given) - {a.name for a in acts}
        if unknown:
            raise SceneError(f"control{sim.world_label(w)}: no actuator named {', '.join(sorted(unknown))}")
        for k, a in enumerate(acts):
            if a.name in given:
                v = float(given[a.name])
                if not math.isfinite(v):
                    raise SceneError(f"control{sim.world_label(w)}: input of {a.kind} '{a.name}' must be finite, "
                                     f"got {v}")
                values[start + k] = v
    return values


RAMPS_AT_ONCE = 32  # ramps from which one NumPy expression evaluates them (a few are faster called)


def own_inputs(sim: Simulator, t: float) -> np.ndarray:
    """Every actuator row's own input at ``t`` (``(rows,)``): the numbers laid out once, at the
    first call, the :class:`~warpsoft.scene.actuator.Ramp` inputs evaluated all at once, and the
    other schedules called in one loop; a schedule that raises or gives no finite number is then
    named by :meth:`~warpsoft.scene.actuator.Actuator.input_at`, as each input was read before
    (1024 Diamonds, 4096 cable schedules on the CPU VM: 2.8-5.7 -> 1.0-2.1 ms a step as one loop;
    as ramps, docs/performance.md)."""
    if sim.own_inputs is None:
        rows, base, place, schedules, ramps = sim.rows, np.zeros(sim.rows.num_rows), [], [], []
        for acts, start in zip(rows.actuators, rows.world_row_start.tolist(), strict=False):
            for k, a in enumerate(acts):
                if isinstance(a.value, Ramp):
                    ramps.append((start + k, a.value))
                elif callable(a.value):
                    place.append(start + k)
                    schedules.append(a)
                else:
                    base[start + k] = a.value
        ramp_rows = np.array([r for r, _ in ramps], dtype=np.int64)
        ramp_table = np.array([ramp.row() for _, ramp in ramps], dtype=np.float64).reshape(-1, 4)
        sim.own_inputs = (base, np.array(place, dtype=np.int64), [a.value for a in schedules], schedules,
                          ramp_rows, ramp_table, [ramp for _, ramp in ramps])
    base, place, calls, schedules, ramp_rows, ramp_table, ramp_calls = sim.own_inputs
    values = base.copy()
    if len(ramp_rows) > RAMPS_AT_ONCE:
        values[ramp_rows] = Ramp.at(ramp_table, t)  # (finite: their numbers were checked when made)
    elif len(ramp_rows):
        values[ramp_rows] = [ramp(t) for ramp in ramp_calls]  # (the same numbers)
    if not calls:
        return values
    try:
        values[place] = [float(f(t)) for f in calls]
        if np.isfinite(values[place]).all():
            return values
    except Exception:  # (input_at below says what and whose)
        pass
    values[place] = [a.input_at(t) for a in schedules]  # the slow way, which names the actuator at fault
    return values
