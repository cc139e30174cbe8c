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
from functools import partial
from typing import TYPE_CHECKING

import numpy as np
import warp as wp

from warpsoft.kernels.elastic import geometry
from warpsoft.kernels.linear import cg as linalg
from warpsoft.kernels.rows import common as row_kernels

from . import record, watch
from .errors import SimulationError
from .inputs import host_inputs
from .launch import launch
from .newton import zero_moving
from .resolve.host import resolve_on_host
from .state import Control
from .stats import ConvergenceWarning, StepStats, WorldRecord, Worlds

if TYPE_CHECKING:
    from .simulator import Simulator


def step(sim: Simulator, controls: list[Control | None]) -> StepStats:
    """Advance every world by one step; the state is swapped in only when the step succeeded.

    The step is a Newton iteration (``newton.py``) that most steps leave after its first
    linearization. On CUDA, when the solver allows it, each iteration's device part is replayed
    as a CUDA graph: one, or two around the host QP when some world uses the inverse model.
    Elsewhere the same stages run one by one, each timed. Either way the host reads an
    iteration in one transfer (and one more before the QP): see ``readback.py``.
    """
    m, rows = sim.model, sim.rows
    stats = StepStats(sim.step_index + 1, sim.time + m.dt, worlds=Worlds(WorldRecord(m.num_worlds)))
    start = time.perf_counter()
    actuated = rows is not None and rows.num_columns > 0  # rows that carry a force: actuators, contacts
    inverse = actuated and bool(sim.inverse_worlds)
    host_qp = inverse and sim.device_inverse is None
    host_resolve = host_qp or sim.host_gauss_seidel  # the step splits into two graphs around it
    host_inputs(sim, stats.time, controls)  # user schedules, evaluated once; uploads only when they change
    # host work that no launch waits for, done while the next graph runs (run's ``beside``): first
    # the worlds whose preconditioner went stale, made anew (the step's boundary is its first
    # graph), then each iteration's records
    later = [("refresh_worlds", sim.solver.refresh_worlds)] if getattr(sim.solver, "worlds_due", False) else []
    newton = sim.newton
    factorizations = reuse_factor(sim)
    newton.begin_step()
    first = True
    while True:
        host = iterate(sim, stats, actuated, host_resolve, first, later)
        while newton.judge(host):  # line search: a world that overshot retries a shorter step
            host = run(sim, stats, "line_search", [("correct", lambda: newton.advance(correction(sim, actuated, False),
                                                                                      actuated, retry=True)),
                                                   ("linearize", lambda: relinearize(sim, actuated))],
                       capturable(sim), beside=later)
            watch.health(sim, stats, host, warn=False)
        if rows is not None:  # (the worlds that moved in this iteration)
            later.append((None, partial(record.keep_gaps, sim, host, ~newton.done)))
        if not newton.go_on():
            break
        if first:  # the next solves start their corrections from 0: keep the step's motion to warm-start the next step
            wp.copy(newton.warm, sim.dx_free[0])
        first = False
    run_beside(stats, later)  # (the last iteration's: nothing runs beside them)
    if not first:
        wp.copy(sim.dx_free[0], newton.warm)
    record_newton(sim, stats)
    if factorizations is not None:
        stats.factorizations = sim.solver.factorizations - factorizations
        sim.reuse.learn(newton)
        sim.solver.keep[:] = False  # (a solve between steps takes the linearization made last)
    watch.health(sim, stats, host)
    watch.inverted_elements(sim, stats, host)
    if rows is not None:
        record.record_rows(sim, stats, host)  # the rows at the new state: what the report records
    if sim.rigid is not None:
        for k, (w, name) in enumerate(sim.rigid.names):
            stats.worlds[w].rigid_bodies[name] = (host["rigid_p"][k].copy(), host["rigid_r"][k].copy())
    if sim.device_inverse is not None:
        record_device_qp(sim, stats, host)

    sim.state, sim.next = sim.next, sim.state
    sim.time, sim.step_index = stats.time, stats.index
    stats.total = time.perf_counter() - start
    return stats


def iterate(sim: Simulator, stats: StepStats, actuated: bool, host_resolve: bool,
            first: bool, later: list) -> dict[str, np.ndarray]:
    """One Newton iteration (the first also starts the step), read back in one transfer.
    ``later``: host work run beside its first graph (:func:`run`), to which it adds its own."""
    captured = capturable(sim)
    if not first and sim.factor_reuse:  # the step iterates: on the tangent of where it is (the worlds
        sim.solver.keep[:] = sim.newton.done  # done are held: their factors serve no solve of this step)
    solve = [("linearize", lambda: begin(sim, actuated))] if first else []
    solve.append(("free_solve", lambda: free_solve(sim, actuated, first, captured)))
    if actuated:
        solve += [("compliance", lambda: compliance(sim)), ("resolve", lambda: resolve_on_device(sim))]
    finish = [("correct", lambda: sim.newton.advance(correction(sim, actuated), actuated,
                                                     scaled_forces=made_forces(sim, actuated))),
              ("linearize", lambda: relinearize(sim, actuated))]
    if host_resolve:  # two graphs around the host's QP or Gauss-Seidel
        before = run(sim, stats, "device_before_qp" if first else "newton_before_qp", solve, captured, sim.before_qp,
                     later)
        with stage(sim, stats, "resolve"):
            resolve_on_host(sim, stats, before)
        host = run(sim, stats, "device_after_qp", finish, captured)
    else:  # the whole iteration as one graph
        host = run(sim, stats, "device_step" if first else "newton_step", solve + finish, captured, beside=later)
    res = sim.solver.result(host) if captured else sim.solve_result
    if captured:  # the preconditioner learns the iterations (solve() does it itself); each world's
        sim.solver.finish(res, worlds=False)  # (for a later step's boundary) beside the next graph
        later.append((None, partial(sim.solver.finish_worlds, res)))
    finish_solve(sim, stats, res)
    watch.health(sim, stats, host, warn=False)
    return host


def capturable(sim: Simulator) -> bool:
    """Whether this iteration's device work can be replayed as graphs (CUDA, and a solver that
    needs no host work now)."""
    return sim.capture and getattr(sim.solver, "capturable", False)


def run(sim: Simulator, stats: StepStats, name: str, parts: list, captured: bool,
        readback=None, beside: list | None = None) -> dict[str, np.ndarray]:
    """Run ``parts`` (stage name, work), then gather ``readback`` (the step's by default) and read
    it: as one replayed graph timed as ``name`` if ``captured``, else stage by stage. ``beside``:
    ``[(stage name or None, work)]``, host work run (and taken off the list) once the graph is
    launched, while the device runs it (after the stages, elsewhere), before the read; what it
    queues on the device follows the graph. A named one is timed as its stage, which overlaps the
    graph's."""
    readback = readback or sim.after_step
    if captured:
        replay(sim, stats, name, lambda: ([work() for _, work in parts], readback.gather()), beside)
    else:
        for what, work in parts:
            with stage(sim, stats, what):
                work()
        readback.gather()
        run_beside(stats, beside)
    return readback.read()


def run_beside(stats: StepStats, beside: list | None) -> None:
    """Run the host work ``beside`` (:func:`run`) in its order, emptying it; a named one timed."""
    while beside:
        name, work = beside.pop(0)
        t0 = time.perf_counter()
        work()
        if name is not None:
            stats.stages[name] = stats.stages.get(name, 0.0) + time.perf_counter() - t0


def replay(sim: Simulator, stats: StepStats, name: str, work, beside=None) -> None:
    """Run ``work`` as a CUDA graph: captured once per pair of state buffers (they swap each step)
    and replayed; timed as the stage ``name``. (On the CPU device, where nothing is captured,
    ``work`` simply runs: the same flow, for tests.) ``beside``: host work run once the graph is
    launched (:func:`run`)."""
    key = (name, sim.state.q.ptr)
    with stage(sim, stats, name):
        if not sim.model.device.is_cuda:
            work()
        else:
            if key not in sim.graphs:
                with wp.ScopedCapture(device=sim.model.device) as capture:
                    work()
                sim.graphs[key] = capture.graph
            wp.capture_launch(sim.graphs[key])
        run_beside(stats, beside)  # (inside the graph's stage: with timing, its sync waits for the graph after it)


def reuse_factor(sim: Simulator) -> int | None:
    """Which worlds may keep the direct solver's factorization of an earlier linearization in this
    step (``factor_reuse``, decided by :class:`~warpsoft.reuse.FactorReuse`). Returns the solver's
    factorization count (None: a solver without one)."""
    solver = sim.solver
    if not hasattr(solver, "factorizations"):
        return None
    solver.keep[:] = sim.reuse.decide(sim.newton, sim.step_index == 0)
    return solver.factorizations


# ---- stages ------------------------------------------------------------------------------
def linearize(sim: Simulator, q: wp.array) -> None:
    """Element rotations and internal forces at ``q``; the solver's per-linearization update. The
    worlds that Newton leaves where they are (``sim.operator.moving``: a later iteration's done
    worlds, a line search's worlds not retrying) keep theirs: the same numbers, not made again."""
    moving = sim.operator.moving
    zero_moving(sim.f_int, sim.model, moving)
    sim.elastic.linearize(q, sim.rot, sim.f_int, moving)
    sim.operator.linearized()  # (the assembled blocks, where A is applied from them)
    sim.solver.prepare()
    sim.newton.linearized_at(q)


def begin(sim: Simulator, actuated: bool) -> None:
    """The step's start: the linearization at ``q`` (made by the last step unless the state was
    changed since, or the preconditioner is due for a refresh), the rows there and, with
    actuators, their columns ``H_a^T``; the first right-hand side ``b = P(f_int + f_ext)``
    (quasi-static) or ``P(h (f_int + f_ext) + M v)``."""
    q = sim.state.q

    def again() -> None:  # the state changed since the last step linearized it
        if sim.factor_reuse:  # (by a jump the last factorization knows nothing of)
            sim.solver.keep[:] = False
            sim.reuse.forget()
            sim.newton.limit[:] = sim.newton.tolerance
        linearize(sim, q)
        if actuated:
            sim.rows.evaluate(q, sim.state)
            columns(sim)

    if getattr(sim.solver, "stale", False):  # its preconditioner is due for a refresh: before this solve
        again()  # (such a step is not captured: the refresh is host work)
    else:
        sim.newton.linearize_if_moved(q, again)
    if actuated:  # effectors alone need no column: they are measured after
        contacts = sim.rows.kind("contact") is not None
        if contacts:  # which nodes take the contact rows of this step (they stay for its iterations)
            sim.rows.detect(q, sim.gauss_seidel.lam, sim.gauss_seidel.friction, sim.state)
        # Rows are linearized where A is. Evaluated at the free configuration instead, H
        # lets a follower load (a pressure) gain energy step after step (the pneunet
        # oscillated ever wider), and delta(q_free) misses the imposed displacement by a
        # second-order term (17 % on a bent cable beam); the linear prediction meets it
        # exactly once the step has converged. (Effector rows measure x - target: their
        # targets moved with the time, so the rows are evaluated again.)
        sim.rows.evaluate(q, sim.state)
        if contacts:
            columns(sim)  # the columns of this step's contacts
        wp.copy(sim.newton.delta_start, sim.rows.delta)  # the actuators' per-step limits count from here
    sim.newton.start()
    if actuated and sim.driven is not None:  # the rows after the frames' move: it is part of the step
        sim.rows.shift(sim.newton.dx)
    if sim.rigid is not None:
        sim.rigid.start(sim.state)  # the rigid bodies' free motion


def free_solve(sim: Simulator, actuated: bool, first: bool, captured: bool) -> None:
    """The batched solve ``A [e, X] = [r, H_a^T]`` at the current linearization: the free motion
    (the step's first, or a Newton correction, started from 0) and the actuators' compliance
    columns, warm-started from the last solves (extrapolated: ``warm_start``)."""
    if not sim.warm_start:
        sim.sol.zero_()
    elif not first:
        sim.dx_free.zero_()
    elif sim.guess is not None:  # from the last steps' solutions, extrapolated
        sim.guess.predict(sim.sol, sim.newton.moved)
    if not first:
        sim.newton.hold_done_worlds()
    sim.newton.accept(actuated)
    if sim.rigid is not None:
        sim.rigid.accept()
    if captured:
        sim.solver.run(sim.rhs, sim.sol)  # read with the iteration
    elif from_factor(sim):  # the free motion alone: W comes from the factor, the correction by one more solve
        sim.solve_result = sim.solver.solve(sim.b, sim.dx_free)
    else:
        sim.solve_result = sim.solver.solve(sim.rhs, sim.sol)  # (pcg: the loop is one graph on CUDA)


def columns(sim: Simulator) -> None:
    """The force rows' columns ``H^T`` (the batched solve's right-hand sides), unless ``W`` comes
    from the factor, where nothing reads them (the correction and Newton's residual take
    ``H^T lambda`` from the rows' entries): 0.37 ms a step on the Grasper's CPU path."""
    if not from_factor(sim):
        sim.rows.actuator_columns(sim.columns)


FACTOR_COLUMNS = 16  # force rows in use from which W comes from the factor rather than solved columns


def from_factor(sim: Simulator) -> bool:
    """Whether this iteration takes ``W`` from the solver's factorization (the CPU's sparse
    Cholesky), never solving the force rows' columns ``X``: when at least
    :data:`FACTOR_COLUMNS` force rows are in use (contacts). It cost 1.5 ms for the Finger's
    few rows and 2.7 ms for the Grasper's 108, against 0.07 ms a solved column (2-core VM):
    a few rows go faster as columns. (The rows in use are set by the detection, before the
    solve: one answer for the whole iteration.)"""
    if not getattr(sim.solver, "factor_compliance", False) or sim.rows is None or not sim.rows.num_columns:
        return False
    return int(sim.rows.world_force_rows.numpy().sum()) >= FACTOR_COLUMNS  # (a view on the CPU device)


def lazy(sim: Simulator) -> bool:
    """Whether this iteration resolves the lazy contact set (:mod:`warpsoft.resolve.contact_set`):
    the CPU path, ``W`` from the factor, direct-model worlds with contacts swept on the device."""
    return sim.contact_set is not None and not sim.host_gauss_seidel and from_factor(sim)


def compliance(sim: Simulator) -> None:
    """``delta_free = delta(q_k) + H e`` and ``W = s H X`` (device); with the lazy contact set,
    only the rigid bodies' share of ``W`` (the resolve forms the soft share of its set)."""
    sim.rows.predict(sim.dx_free)
    if lazy(sim):
        sim.rows.W.zero_()
    elif from_factor(sim):
        sim.solver.compliance(sim.rows, sim.constraint_scale)
    else:
        sim.rows.compliance(sim.X, sim.constraint_scale)
    if sim.rigid is not None:  # the rigid bodies' share: their free motion and M^-1 J^T
        sim.rigid.predict()
        sim.rigid.compliance(sim.constraint_scale)


def correction(sim: Simulator, actuated: bool, make: bool = True) -> wp.array:
    """The iteration's correction ``e = e_free + s X lambda`` (made here from the resolve's
    multipliers unless ``make`` is False: the line search reuses it), or ``e_free``; without
    columns (``from_factor``), ``s A^-1 H^T lambda`` is one more solve."""
    if not actuated:
        return sim.dx_free[0]
    if make and lazy(sim):  # the contact set's resolve made it, checking the contacts left out
        return sim.dx
    if make and from_factor(sim):
        correct_by_one_solve(sim)
    elif make:
        sim.rows.correct(sim.dx_free[0], sim.X, sim.gauss_seidel.lam, sim.constraint_scale, sim.dx)
        if sim.rigid is not None:
            sim.rigid.correct(sim.gauss_seidel.lam, sim.constraint_scale)
    return sim.dx


def made_forces(sim: Simulator, actuated: bool) -> wp.array | None:
    """``s H_f^T lambda`` where this iteration's correction made it (its one solve, from the
    factor), for Newton's slope to reuse; else None."""
    return sim.row_force[0] if actuated and from_factor(sim) else None


def correct_by_one_solve(sim: Simulator) -> None:
    """``e = e_free + A^-1 (s H^T lambda)``: one solve instead of the columns (``row_motion``
    keeps the second term), and the rigid bodies' correction."""
    sim.rows.force_rows_forces(sim.gauss_seidel.lam, sim.constraint_scale, sim.row_force[0])
    sim.solver.solve(sim.row_force, sim.row_motion)
    launch(row_kernels.add_motion, sim.model.num_nodes, inputs=[sim.dx_free[0], sim.row_motion[0]],
           outputs=[sim.dx], device=sim.model.device)
    if sim.rigid is not None:
        sim.rigid.correct(sim.gauss_seidel.lam, sim.constraint_scale)


def relinearize(sim: Simulator, actuated: bool) -> None:
    """At the new positions: the linearization (the next iteration's or step's), the rows (what
    the report records) and their columns, the nonlinear residual, the health check's kernels."""
    m, q = sim.model, sim.next.q
    linearize(sim, q)
    if sim.rows is not None:
        sim.rows.evaluate(q, sim.next)
    if actuated:
        columns(sim)
    sim.newton.residual(correction(sim, actuated, make=False))
    sim.health_flag.zero_()
    sim.health_step.zero_()
    launch(linalg.step_health, m.num_nodes, inputs=[q, sim.newton.dx[0], m.node_world],
           outputs=[sim.health_flag, sim.health_step], device=m.device)
    if sim.rigid is not None:
        sim.rigid.linearize(sim.next, sim.health_flag)
    sim.inverted.zero_()
    launch(geometry.count_inverted, m.num_elements, inputs=[q, m.tets, m.dm_inv, m.elem_world],
           outputs=[sim.inverted], device=m.device)


def finish_solve(sim: Simulator, stats: StepStats, res) -> None:
    """Record a batched solve (read once, after it ran; a step's Newton iterations add up); a
    non-finite one is an error, a non-converged one a warning."""
    na = sim.rhs.shape[0] - 1
    what = "free solve" if na == 0 else f"free solve and {na} compliance column{'s' if na > 1 else ''}"
    if not math.isfinite(res.residual):
        raise SimulationError(f"step {stats.index} (t = {stats.time:g} s): the {what} met non-finite values "
                              "(NaN or inf in the state, loads or rows); the state before the step is kept")
    stats.cg_iterations += res.iterations
    stats.cg_residual = max(stats.cg_residual, res.residual)
    stats.compliance_iterations += res.iterations if na else 0
    stats.converged = stats.converged and res.converged
    per_world = getattr(res, "world_iterations", None)  # when the solver counts them per world
    stats.worlds.record.add("cg_iterations", per_world if per_world is not None
                            else [res.iterations] * len(stats.worlds))
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


def resolve_on_device(sim: Simulator) -> None:
    """Direct-model worlds: projected Gauss-Seidel on the device, every world at once; then the
    inverse-model worlds' QP when it runs on the device (each leaves the other's multipliers
    alone). The actuators' per-step limits count from the rows at the step's start."""
    rows, start = sim.rows, sim.newton.delta_start
    if lazy(sim):  # (no inverse world then)
        sim.contact_set.resolve(lambda: correct_by_one_solve(sim))
        return
    if any(not s.inverse for s in sim.model.scenes) and not sim.host_gauss_seidel:
        if sim.contact_set is not None:  # the CPU device: the lazy set on W's arrays in place
            gs = sim.gauss_seidel
            sim.contact_set.resolve_columns({"W": rows.W.numpy(), "delta_free": rows.delta_free.numpy(),
                                             "delta": start.numpy(), "lam": gs.lam.numpy(),
                                             "force_rows": rows.world_force_rows.numpy(),
                                             "friction": gs.friction.numpy()})
        else:
            sim.gauss_seidel.solve(rows.W, rows.delta_free, start)
    if sim.device_inverse is not None:
        sim.device_inverse.solve(rows.W, rows.delta_free, start, sim.gauss_seidel.inputs, sim.gauss_seidel.lam)


def record_newton(sim: Simulator, stats: StepStats) -> None:
    """Each world's Newton iterations and final relative residual; a warning, once per episode,
    for a world that ended above the tolerance."""
    newton, columns = sim.newton, stats.worlds.record.columns
    columns["newton_iterations"], columns["newton_residual"] = newton.iterations.copy(), newton.error.copy()
    for w in watch.beginning(sim, "newton", columns["newton_residual"] > newton.tolerance):
        stats.warnings.append(
            f"step {stats.index}{sim.world_label(int(w))}: the implicit step did not converge: nonlinear residual "
            f"{newton.error[w]:.3g} > newton_tolerance {newton.tolerance:g} after {newton.iterations[w]} "
            "Newton iteration(s); the motion is not resolved within the step: a smaller dt, or more "
            "newton_iterations")
    stats.newton_iterations = int(newton.iterations.max())
    stats.newton_residual = float(newton.error.max())
    stats.line_searches = newton.trials


def record_device_qp(sim: Simulator, stats: StepStats, host: dict[str, np.ndarray]) -> None:
    """Each inverse world's QP outcome, from the step's read; a failure is a warning (the world
    kept its previous actuation)."""
    for w in sim.device_inverse.worlds:
        status, warning = sim.device_inverse.outcome(host["qp"], w)
        ws = stats.worlds[w]
        ws.qp_status, ws.qp_seconds, ws.resolve_iterations = status, 0.0, sim.device_inverse.iterations(host["qp"], w)
        if warning:
            stats.warnings.append(f"step {stats.index}{sim.world_label(w)}: inverse model: {warning}")


@contextmanager
def stage(sim: Simulator, stats: StepStats, name: str):
    """Time a stage (s); on CUDA with ``timing``, synchronize the step's stream around it so the
    time is its own (not the device: the copies to the refactorizing workers run on a stream of
    their own, beside the step)."""
    sync = sim.timing and sim.model.device.is_cuda
    if sync:
        wp.synchronize_stream(wp.get_stream(sim.model.device))
    t0 = time.perf_counter()
    yield
    if sync:
        wp.synchronize_stream(wp.get_stream(sim.model.device))
    stats.stages[name] = stats.stages.get(name, 0.0) + time.perf_counter() - t0
