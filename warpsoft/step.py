"""One step of every world, top to bottom (implicit Euler with one linearization, or
quasi-static). Each stage is one call into the module that owns it; the Simulator holds the
model, the state and the work buffers, and turns failures into clear errors.

Dynamic: ``A = M + h D + h^2 K`` with ``D = a M + b K``; quasi-static: ``A = K``.
"""

from __future__ import annotations

import math
import time
import warnings
from contextlib import contextmanager
from typing import TYPE_CHECKING

import numpy as np
import warp as wp

from warpsoft.kernels import integrate
from warpsoft.kernels.linear import cg as linalg

from .errors import SceneError, SimulationError
from .resolve import RowInputs, solve_inverse
from .state import Control
from .stats import ConvergenceWarning, StepStats, WorldStats

if TYPE_CHECKING:
    from .simulator import Simulator


def step(sim: Simulator, controls: list[Control | None]) -> StepStats:
    """Advance every world by one step; the state is swapped in only when the step succeeded."""
    m, rows = sim.model, sim.rows
    stats = StepStats(sim.step_index + 1, sim.time + m.dt, worlds=[WorldStats() for _ in range(m.num_worlds)])
    start = time.perf_counter()
    actuated = rows is not None and rows.num_actuators > 0
    values = actuator_values(sim, stats.time, controls) if actuated else None  # user schedules, once

    with stage(sim, stats, "linearize"):  # rotations, internal forces, preconditioner
        sim.f_int.zero_()
        sim.elastic.linearize(sim.state.q, sim.rot, sim.f_int)
        sim.solver.prepare()

    if m.time_dependent_loads:
        with stage(sim, stats, "loads"):
            sim.f_ext.assign(m.external_forces(stats.time) + (m.f_const_np if m.f_const is not None else 0.0))

    with stage(sim, stats, "free_solve"):  # A [dx_free, X] = [b, H_a^T]
        right_hand_side(sim)
        if actuated:  # effectors alone need no column: they are measured after
            # Rows are linearized where A is, at q. Evaluated at the free configuration
            # instead, H lets a follower load (a pressure) gain energy step after step (the
            # pneunet oscillated ever wider), and delta(q_free) misses the imposed
            # displacement by a second-order term (17 % on a bent cable beam); the linear
            # prediction meets it exactly once the step has converged.
            rows.set_time(stats.time)  # effector rows measure x - target
            rows.evaluate(sim.state.q)
            rows.actuator_columns(sim.columns)
        solve(sim, stats)
    dx = sim.dx_free[0]

    if actuated:
        with stage(sim, stats, "compliance"):  # delta_free = delta(q) + H dx_free; W = s H X
            delta_free = rows.predict(sim.dx_free)
            rows.compliance(sim.X, sim.constraint_scale)
        with stage(sim, stats, "resolve"):  # lambda of every world: direct model or inverse model
            resolve(sim, stats, values, delta_free)

    with stage(sim, stats, "correct"):  # dx = dx_free + s X lambda; q += dx, v = dx / h
        if actuated:
            rows.correct(dx, sim.X, sim.gauss_seidel.lam, sim.constraint_scale, sim.dx)
            dx = sim.dx
        wp.launch(integrate.advance, m.num_nodes, inputs=[sim.state.q, dx, 0.0 if m.static else 1.0 / m.dt],
                  outputs=[sim.next.q, sim.next.v], device=m.device)
        check_health(sim, stats, dx)
        if rows is not None:  # rows at the new state: what the report records
            record_rows(sim, stats, sim.next.q)

    sim.state, sim.next = sim.next, sim.state
    sim.time, sim.step_index = stats.time, stats.index
    stats.total = time.perf_counter() - start
    return stats


# ---- stages ------------------------------------------------------------------------------
def right_hand_side(sim: Simulator) -> None:
    """``b = f_int + f_ext`` (quasi-static) or ``h (f_int + f_ext) + M v`` (dynamic), fixed DOFs 0."""
    m = sim.model
    if m.static:
        wp.launch(integrate.rhs_static, m.num_nodes, inputs=[sim.f_int, sim.f_ext, m.mask], outputs=[sim.b[0]],
                  device=m.device)
    else:
        wp.launch(integrate.rhs_dynamic, m.num_nodes, inputs=[sim.state.v, m.mass, sim.f_int, sim.f_ext, m.dt, m.mask],
                  outputs=[sim.b[0]], device=m.device)


def solve(sim: Simulator, stats: StepStats) -> None:
    """``A sol = rhs`` for every column (warm start: the last step's ``sol``)."""
    na = sim.rhs.shape[0] - 1
    what = "free solve" if na == 0 else f"free solve and {na} compliance column{'s' if na > 1 else ''}"
    if not sim.warm_start:
        sim.sol.zero_()
    res = sim.solver.solve(sim.rhs, sim.sol)
    if not math.isfinite(res.residual):
        raise SimulationError(f"step {stats.index} (t = {stats.time:g} s): the {what} met non-finite values "
                              "(NaN or inf in the state, loads or rows); the state before the step is kept")
    stats.cg_iterations, stats.cg_residual = res.iterations, res.residual
    stats.compliance_iterations = res.iterations if na else 0
    stats.converged = res.converged
    per_world = getattr(res, "world_iterations", None)  # when the solver counts them per world
    for w, ws in enumerate(stats.worlds):
        ws.cg_iterations = int(per_world[w]) if per_world is not None else res.iterations
    if not res.converged:
        msg = (f"step {stats.index}: CG ({what}) stopped after {res.iterations} iterations at relative residual "
               f"{res.residual:.3e} > tolerance {sim.solver.tolerance:.1e}")
        stats.warnings.append(msg)
        warnings.warn(msg, ConvergenceWarning, stacklevel=4)


def actuator_values(sim: Simulator, t: float, controls: list[Control | None]) -> np.ndarray:
    """The input of every actuator row at time ``t`` (``(rows,)``): a Control's value, else the
    actuator's own (a number, or a schedule called once here)."""
    rows = sim.rows
    values = np.zeros(rows.num_rows)
    for w, acts in enumerate(rows.actuators):
        given = controls[w].inputs if controls[w] is not None else {}
        unknown = set(given) - {a.name for a in acts}
        if unknown:
            raise SceneError(f"control{sim.world_label(w)}: no actuator named {', '.join(sorted(unknown))}")
        for k, a in enumerate(acts):
            v = float(given[a.name]) if a.name in given else a.input_at(t)
            if not math.isfinite(v):
                raise SceneError(f"control{sim.world_label(w)}: input of {a.kind} '{a.name}' must be finite, got {v}")
            values[rows.world_row_start[w] + k] = v
    return values


def resolve(sim: Simulator, stats: StepStats, values: np.ndarray, delta_free: wp.array) -> None:
    """Direct-model worlds: projected Gauss-Seidel on the device, all worlds at once. Inverse-model
    worlds: a QP each on the host, from one read of ``W``, ``delta_free`` and ``delta``."""
    rows, gs, scenes = sim.rows, sim.gauss_seidel, sim.model.scenes
    gs.set_values(values)
    inverse = [w for w, s in enumerate(scenes) if s.inverse and rows.world_actuators[w]]
    if len(inverse) < len(scenes):
        gs.solve(rows.W, delta_free, rows.delta)
    if not inverse:
        return
    W, dfree, delta, lam = rows.W.numpy(), delta_free.numpy(), rows.delta.numpy(), gs.lam.numpy().copy()
    for w in inverse:
        a, e, scene = rows.actuator_rows(w), rows.effector_rows(w), scenes[w]
        na = a.stop - a.start
        res = solve_inverse(W[a, :na], W[e, :na], dfree[a], dfree[e], row_inputs(gs.host, values, delta, a),
                            sim.effector_weights[w], lam[a], scene.inverse_epsilon)
        lam[a] = res.lam
        stats.worlds[w].qp_status, stats.worlds[w].qp_seconds = res.status, res.seconds
        if res.warning:
            stats.warnings.append(f"step {stats.index}{sim.world_label(w)}: inverse model: {res.warning}")
    gs.lam.assign(lam)  # the one copy back


def row_inputs(host: np.ndarray, values: np.ndarray, delta: np.ndarray, a: slice) -> RowInputs:
    """The inputs of actuator rows ``a`` for the host solvers, displacement bounds narrowed to the
    change allowed this step (as the device Gauss-Seidel does)."""
    from warpsoft.kernels.resolve import gauss_seidel as k

    step_ = host[k.MAX_STEP, a]
    lo_step, hi_step = delta[a] - step_, delta[a] + step_
    return RowInputs(force_mode=host[k.FORCE_MODE, a] != 0, value=values[a], lo=host[k.LO, a], hi=host[k.HI, a],
                     dmin=np.clip(host[k.DMIN, a], lo_step, hi_step), dmax=np.clip(host[k.DMAX, a], lo_step, hi_step))


def check_health(sim: Simulator, stats: StepStats, dx: wp.array) -> None:
    """No NaN leaves a step: a non-finite node is an error; a step larger than the model is a warning."""
    m = sim.model
    sim.health_flag.zero_()
    sim.health_step.zero_()
    wp.launch(linalg.step_health, m.num_nodes, inputs=[sim.next.q, dx], outputs=[sim.health_flag, sim.health_step],
              device=m.device)
    bad, largest = int(sim.health_flag.numpy()[0]), float(np.sqrt(sim.health_step.numpy()[0]))
    if largest > sim.size:
        stats.warnings.append(f"step {stats.index}: a node moved {largest:.3g} m in one step, more than the "
                              f"model's size {sim.size:.3g} m: the simulation is likely unstable")
    if bad:
        sim.forget_warm_starts()
        raise SimulationError(
            f"step {stats.index} (t = {stats.time:g} s): {bad} node(s) got non-finite positions "
            f"(CG {stats.cg_iterations} iterations, residual {stats.cg_residual:.3e}); "
            "the state before the step is kept"
        )


def record_rows(sim: Simulator, stats: StepStats, q: wp.array) -> None:
    """Each world's rows at the new state, by name, and the resolution's statistics (one read each)."""
    rows = sim.rows
    targets = rows.set_time(stats.time)
    rows.evaluate(q)
    delta = rows.delta.numpy()
    lam = sim.gauss_seidel.lam.numpy() if rows.num_actuators else np.zeros(rows.num_rows)
    result = sim.gauss_seidel.result.numpy() if rows.num_actuators else None
    for w, ws in enumerate(stats.worlds):
        a, acts = rows.actuator_rows(w), rows.actuators[w]
        ws.actuator_delta = {x.name: float(v) for x, v in zip(acts, delta[a], strict=True)}
        ws.actuator_lambda = {x.name: float(v) for x, v in zip(acts, lam[a], strict=True)}
        ws.effectors = rows.effector_positions(w)
        ws.targets = rows.targets(targets, w)
        ws.effector_error = {e.name: float(np.linalg.norm((ws.effectors[e.name] - ws.targets[e.name])[e.axis_ids]))
                             for e in rows.effectors[w] if e.target is not None}
        if acts and not sim.model.scenes[w].inverse:
            ws.resolve_iterations, ws.resolve_residual = int(result[w, 0]), float(result[w, 1])
            if not result[w, 2]:
                stats.warnings.append(f"step {stats.index}{sim.world_label(w)}: Gauss-Seidel stopped after "
                                      f"{ws.resolve_iterations} sweeps, last change {ws.resolve_residual:.3e}")


@contextmanager
def stage(sim: Simulator, stats: StepStats, name: str):
    """Time a stage (s); on CUDA with ``timing``, synchronize around it so the time is its own."""
    sync = sim.timing and sim.model.device.is_cuda
    if sync:
        wp.synchronize_device(sim.model.device)
    t0 = time.perf_counter()
    yield
    if sync:
        wp.synchronize_device(sim.model.device)
    stats.stages[name] = stats.stages.get(name, 0.0) + time.perf_counter() - t0
