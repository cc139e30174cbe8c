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
from warpsoft.kernels.elastic import geometry
from warpsoft.kernels.linear import cg as linalg
from warpsoft.kernels.resolve import gauss_seidel as gs_kernels

from . import watch
from .errors import SceneError, SimulationError
from .resolve import RowInputs, solve_inverse
from .state import Control
from .stats import ConvergenceWarning, StepStats, WorldStats

if TYPE_CHECKING:
    from .simulator import Simulator


def step(sim: Simulator, controls: list[Control | None]) -> StepStats:
    """Advance every world by one step; the state is swapped in only when the step succeeded.

    On CUDA, when the solver allows it, the device part is replayed as CUDA graphs: one for the
    whole step, or two around the host QP when some world uses the inverse model. Elsewhere the
    same stages run one by one, each timed. Either way the host reads the step in one transfer
    (and one more before the QP): see ``readback.py``.
    """
    m, rows = sim.model, sim.rows
    stats = StepStats(sim.step_index + 1, sim.time + m.dt, worlds=[WorldStats() for _ in range(m.num_worlds)])
    start = time.perf_counter()
    actuated = rows is not None and rows.num_actuators > 0
    inverse = actuated and any(s.inverse and rows.world_actuators[w] for w, s in enumerate(m.scenes))
    host_qp = inverse and sim.device_inverse is None
    host_inputs(sim, stats.time, controls)  # user schedules, evaluated once; uploads only when they change

    if sim.capture and getattr(sim.solver, "capturable", False):
        if host_qp:  # two graphs around the host QP
            replay(sim, stats, "device_before_qp", lambda: (before_resolve(sim, actuated), sim.before_qp.gather()))
            with stage(sim, stats, "resolve"):
                resolve_inverse(sim, stats, sim.before_qp.read())
            replay(sim, stats, "device_after_qp", lambda: (after_resolve(sim, actuated), sim.after_step.gather()))
        else:  # the whole step as one graph
            replay(sim, stats, "device_step", lambda: (before_resolve(sim, actuated), after_resolve(sim, actuated),
                                                       sim.after_step.gather()))
        host = sim.after_step.read()
        res = sim.solver.result(host)
        sim.solver.finish(res)  # the preconditioner learns the iterations (solve() does it itself)
        finish_solve(sim, stats, res)
    else:
        with stage(sim, stats, "linearize"):  # rotations, internal forces, preconditioner
            linearize(sim)
        with stage(sim, stats, "free_solve"):  # A [dx_free, X] = [b, H_a^T]
            free_solve_inputs(sim, actuated)
            finish_solve(sim, stats, sim.solver.solve(sim.rhs, sim.sol))  # (pcg: the loop is one graph on CUDA)
        if actuated:
            with stage(sim, stats, "compliance"):  # delta_free = delta(q) + H dx_free; W = s H X
                compliance(sim)
            with stage(sim, stats, "resolve"):  # lambda of every world: direct model or inverse model
                resolve_direct(sim)
                if sim.device_inverse is not None:
                    resolve_inverse_on_device(sim)
                elif inverse:
                    sim.before_qp.gather()
                    resolve_inverse(sim, stats, sim.before_qp.read())
        with stage(sim, stats, "correct"):  # dx = dx_free + s X lambda; q += dx, v = dx / h
            after_resolve(sim, actuated)
            sim.after_step.gather()
            host = sim.after_step.read()
    watch.health(sim, stats, host)
    watch.inverted_elements(sim, stats, host)
    if rows is not None:
        record_rows(sim, stats, host)  # the rows at the new state: what the report records
    if sim.device_inverse is not None:
        record_device_qp(sim, stats, host)

    sim.state, sim.next = sim.next, sim.state
    sim.time, sim.step_index = stats.time, stats.index
    stats.total = time.perf_counter() - start
    return stats


def before_resolve(sim: Simulator, actuated: bool) -> None:
    """Device work up to the multipliers: linearize, the batched solve, the compliance, the
    direct model's Gauss-Seidel and the inverse model's QP when it runs on the device."""
    linearize(sim)
    free_solve_inputs(sim, actuated)
    sim.solver.run(sim.rhs, sim.sol)
    if actuated:
        compliance(sim)
        resolve_direct(sim)
        if sim.device_inverse is not None:
            resolve_inverse_on_device(sim)


def after_resolve(sim: Simulator, actuated: bool) -> None:
    """Device work after the multipliers: ``dx = dx_free + s X lambda``, ``q += dx``, ``v = dx / h``,
    the health check's kernel and the rows at the new state."""
    m, rows = sim.model, sim.rows
    dx = sim.dx_free[0]
    if actuated:
        rows.correct(dx, sim.X, sim.gauss_seidel.lam, sim.constraint_scale, sim.dx)
        dx = sim.dx
    wp.launch(integrate.advance, m.num_nodes, inputs=[sim.state.q, dx, 0.0 if m.static else 1.0 / m.dt],
              outputs=[sim.next.q, sim.next.v], device=m.device)
    sim.health_flag.zero_()
    sim.health_step.zero_()
    wp.launch(linalg.step_health, m.num_nodes, inputs=[sim.next.q, dx], outputs=[sim.health_flag, sim.health_step],
              device=m.device)
    sim.inverted.zero_()
    wp.launch(geometry.count_inverted, m.num_elements, inputs=[sim.next.q, m.tets, m.dm_inv, m.elem_world],
              outputs=[sim.inverted], device=m.device)
    if rows is not None:
        rows.evaluate(sim.next.q)


def replay(sim: Simulator, stats: StepStats, name: str, work) -> None:
    """Run ``work`` as a CUDA graph: captured once per pair of state buffers (they swap each step)
    and replayed; timed as the stage ``name``. (On the CPU device, where nothing is captured,
    ``work`` simply runs: the same flow, for tests.)"""
    key = (name, sim.state.q.ptr)
    with stage(sim, stats, name):
        if not sim.model.device.is_cuda:
            work()
            return
        if key not in sim.graphs:
            with wp.ScopedCapture(device=sim.model.device) as capture:
                work()
            sim.graphs[key] = capture.graph
        wp.capture_launch(sim.graphs[key])


# ---- stages ------------------------------------------------------------------------------
def linearize(sim: Simulator) -> None:
    """Element rotations and internal forces at ``q``; the solver's per-linearization update."""
    sim.f_int.zero_()
    sim.elastic.linearize(sim.state.q, sim.rot, sim.f_int)
    sim.solver.prepare()


def free_solve_inputs(sim: Simulator, actuated: bool) -> None:
    """The batched solve's right-hand sides: ``b = f_int + f_ext`` (quasi-static) or
    ``h (f_int + f_ext) + M v`` (dynamic), fixed DOFs 0; with actuators, their columns ``H_a^T``."""
    m = sim.model
    if not sim.warm_start:
        sim.sol.zero_()
    if m.static:
        wp.launch(integrate.rhs_static, m.num_nodes, inputs=[sim.f_int, sim.f_ext, m.mask], outputs=[sim.b[0]],
                  device=m.device)
    else:
        wp.launch(integrate.rhs_dynamic, m.num_nodes, inputs=[sim.state.v, m.mass, sim.f_int, sim.f_ext, m.dt, m.mask],
                  outputs=[sim.b[0]], device=m.device)
    if actuated:  # effectors alone need no column: they are measured after
        # Rows are linearized where A is, at q. Evaluated at the free configuration
        # instead, H lets a follower load (a pressure) gain energy step after step (the
        # pneunet oscillated ever wider), and delta(q_free) misses the imposed
        # displacement by a second-order term (17 % on a bent cable beam); the linear
        # prediction meets it exactly once the step has converged.
        sim.rows.evaluate(sim.state.q)
        sim.rows.actuator_columns(sim.columns)


def compliance(sim: Simulator) -> None:
    """``delta_free = delta(q) + H dx_free`` and ``W = s H X`` (device)."""
    sim.rows.predict(sim.dx_free)
    sim.rows.compliance(sim.X, sim.constraint_scale)


def finish_solve(sim: Simulator, stats: StepStats, res) -> None:
    """Record the batched solve (read once, after it ran); a non-finite one is an error, a
    non-converged one a warning."""
    na = sim.rhs.shape[0] - 1
    what = "free solve" if na == 0 else f"free solve and {na} compliance column{'s' if na > 1 else ''}"
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
               f"{res.residual:.3e} > tolerance {sim.solver.tolerance:.1e}; {convergence_advice(sim)}")
        stats.warnings.append(msg)
        warnings.warn(msg, ConvergenceWarning, stacklevel=4)


def convergence_advice(sim: Simulator) -> str:
    """What a CG that stopped short means here, and what to do about it."""
    nu = sim.model.poisson_np
    why = (f"the material is nearly incompressible (Poisson ratio up to {nu.max():.3g}), which makes the system "
           "ill-conditioned (and the elements lock: too stiff at coarse meshes)" if nu.max() >= 0.45
           else "the system is ill-conditioned (stiff, or with a large stiffness contrast)")
    if sim.solver_name == "jacobi":
        todo = "use solver='pcg' (tens of iterations) or 'direct' (exact)"
    else:
        todo = "use solver='direct' (exact), or raise max_iterations or the tolerance"
    return f"{why}; {todo}"


def host_inputs(sim: Simulator, t: float, controls: list[Control | None]) -> None:
    """What the user's Python decides for this step, computed once and copied in one go each:
    time-dependent loads, effector targets, actuator inputs (only when they changed)."""
    m, rows = sim.model, sim.rows
    if m.time_dependent_loads:
        sim.f_ext.assign(m.external_forces(t) + (m.f_const_np if m.f_const is not None else 0.0))
    if rows is not None:
        rows.set_time(t)  # effector rows measure x - target
        if rows.num_actuators:
            sim.values = actuator_values(sim, t, controls)
            sim.gauss_seidel.set_values(sim.values)


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


def resolve_direct(sim: Simulator) -> None:
    """Direct-model worlds: projected Gauss-Seidel on the device, every world at once (inverse
    worlds are overwritten by their QP)."""
    rows = sim.rows
    if any(not s.inverse for s in sim.model.scenes):
        sim.gauss_seidel.solve(rows.W, rows.delta_free, rows.delta)


def resolve_inverse(sim: Simulator, stats: StepStats, host: dict[str, np.ndarray]) -> None:
    """Inverse-model worlds: a QP each on the host, from ``W``, ``delta_free``, ``delta`` and
    ``lambda`` read in one transfer (``host``); the multipliers go back in one copy."""
    rows, gs, scenes = sim.rows, sim.gauss_seidel, sim.model.scenes
    W, dfree, delta, lam = host["W"], host["delta_free"], host["delta"], host["lam"]
    for w, scene in enumerate(scenes):
        if not (scene.inverse and rows.world_actuators[w]):
            continue
        a, e = rows.actuator_rows(w), rows.effector_rows(w)
        na = a.stop - a.start
        res = solve_inverse(W[a, :na], W[e, :na], dfree[a], dfree[e], row_inputs(gs.host, sim.values, delta, a),
                            sim.effector_weights[w], lam[a], scene.inverse_epsilon)
        lam[a] = res.lam
        stats.worlds[w].qp_status, stats.worlds[w].qp_seconds = res.status, res.seconds
        if res.warning:
            stats.warnings.append(f"step {stats.index}{sim.world_label(w)}: inverse model: {res.warning}")
    gs.lam.assign(lam)


def resolve_inverse_on_device(sim: Simulator) -> None:
    """Inverse-model worlds: the QP of each on the device (after the Gauss-Seidel of the direct
    worlds, whose multipliers it leaves alone)."""
    rows, gs = sim.rows, sim.gauss_seidel
    sim.device_inverse.solve(rows.W, rows.delta_free, rows.delta, gs.inputs, gs.lam)


def record_device_qp(sim: Simulator, stats: StepStats, host: dict[str, np.ndarray]) -> None:
    """Each inverse world's QP outcome, from the step's read; a failure is a warning (the world
    kept its previous actuation)."""
    for w in sim.device_inverse.worlds:
        status, warning = sim.device_inverse.outcome(host["qp"], w)
        ws = stats.worlds[w]
        ws.qp_status, ws.qp_seconds, ws.resolve_iterations = status, 0.0, sim.device_inverse.iterations(host["qp"], w)
        if warning:
            stats.warnings.append(f"step {stats.index}{sim.world_label(w)}: inverse model: {warning}")


def row_inputs(host: np.ndarray, values: np.ndarray, delta: np.ndarray, a: slice) -> RowInputs:
    """The inputs of actuator rows ``a`` for the host solvers, displacement bounds narrowed to the
    change allowed this step (as the device Gauss-Seidel does)."""
    k = gs_kernels
    lo_step, hi_step = delta[a] - host[k.MAX_STEP, a], delta[a] + host[k.MAX_STEP, a]
    return RowInputs(force_mode=host[k.FORCE_MODE, a] != 0, value=values[a], lo=host[k.LO, a], hi=host[k.HI, a],
                     dmin=np.clip(host[k.DMIN, a], lo_step, hi_step), dmax=np.clip(host[k.DMAX, a], lo_step, hi_step))


def record_rows(sim: Simulator, stats: StepStats, host: dict[str, np.ndarray]) -> None:
    """Each world's rows at the new state (evaluated on the device by the step), by name, and the
    Gauss-Seidel statistics, from the step's read (``host``)."""
    rows = sim.rows
    targets = rows.set_time(stats.time)  # the step's targets, already on the device
    delta, points = host["delta"], host["points"][: rows.num_points]
    lam = host["lam"] if rows.num_actuators else np.zeros(rows.num_rows)
    result = host["resolve"] if rows.num_actuators else None
    for w, ws in enumerate(stats.worlds):
        a, acts = rows.actuator_rows(w), rows.actuators[w]
        ws.actuator_delta = {x.name: float(v) for x, v in zip(acts, delta[a], strict=True)}
        ws.actuator_lambda = {x.name: float(v) for x, v in zip(acts, lam[a], strict=True)}
        ws.effectors = rows.effector_positions(w, points)
        ws.targets = rows.targets(targets, w)
        ws.effector_error = {e.name: float(np.linalg.norm((ws.effectors[e.name] - ws.targets[e.name])[e.axis_ids]))
                             for e in rows.effectors[w] if e.target is not None}
        if acts:
            watch.linearization(sim, stats, w, host)
        if acts and sim.model.scenes[w].inverse:
            watch.out_of_reach(sim, stats, w, delta[a], lam[a])
        elif acts:
            watch.actuator_residuals(sim, stats, w, delta[a])
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
