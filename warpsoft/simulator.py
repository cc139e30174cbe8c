"""The Simulator: one linearized step of a soft-robot scene, implicit Euler or quasi-static."""

from __future__ import annotations

import math
import time
import warnings
from contextlib import contextmanager
from dataclasses import dataclass, field

import numpy as np
import warp as wp

from warpsoft.kernels import fem, integrate, linalg, mapping, rows

from .constraints import ConstraintSet
from .constraints.cable import cable_paths
from .control import Control
from .errors import SceneError, SimulationError
from .inverse import solve_inverse
from .linear import SOLVERS, SystemOperator, choose, make_solver
from .model import Model, State
from .resolve import RowInputs, kinematic_jacobian, projected_gauss_seidel
from .scene import Scene


class ConvergenceWarning(UserWarning):
    """An iterative solve stopped at its iteration cap above its tolerance."""


@dataclass
class StepStats:
    """What one step did: solver statistics and the wall time (s) of each stage that ran.

    Stages: ``linearize`` (rotations, forces, preconditioner or factorization), ``loads`` (only
    with time-dependent loads), ``free_solve`` (the right-hand side and, with actuators, their
    compliance columns ``H^T``, solved together in one batched solve), ``compliance``
    (``delta_free`` and ``W`` from the solved columns), ``resolve`` (the multipliers),
    ``correct`` (the correction, the update, the health check). ``cg_iterations`` counts the
    iterations of that one solve (0 for a direct solve); ``compliance_iterations`` is the same
    count when actuators rode along, else 0.
    """

    index: int
    time: float
    cg_iterations: int = 0
    cg_residual: float = 0.0
    converged: bool = True
    stages: dict[str, float] = field(default_factory=dict)
    total: float = 0.0
    warnings: list[str] = field(default_factory=list)
    compliance_iterations: int = 0
    resolve_iterations: int = 0
    resolve_residual: float = 0.0
    qp_status: str = ""
    qp_seconds: float = 0.0
    effector_error: dict[str, float] = field(default_factory=dict)
    actuator_delta: dict[str, float] = field(default_factory=dict)
    actuator_lambda: dict[str, float] = field(default_factory=dict)
    effectors: dict[str, np.ndarray] = field(default_factory=dict)
    targets: dict[str, np.ndarray] = field(default_factory=dict)


class Simulator:
    """Steps a scene on a device.

    Args:
        scene: the scene (or an already built :class:`Model`).
        device: Warp device ("cpu", "cuda", "cuda:0"); Warp's default if None.
        solver: "auto" (``direct`` on the CPU device, ``pcg`` on CUDA), "pcg" (CG preconditioned
            by the warped rest factorization, the loop on the device), "direct" (assembled sparse
            Cholesky on the host, the CPU path and the accuracy reference) or "jacobi" (v1's
            block-Jacobi CG, kept for comparison). See :mod:`warpsoft.linear`.
        tolerance: CG relative residual |r| / |b|.
        max_iterations: CG iteration cap (reaching it is a warning in the step stats).
        warm_start: start each free solve from the previous step's solution.
        timing: synchronize the device around stages to time them (CUDA only matters).
        check_every: ``jacobi`` only: the residual is read back every this many iterations
            (default: 1 on the CPU, where reading is free; 16 on CUDA).
        graphs: on CUDA, replay captured graphs (``pcg``: the whole solve; ``jacobi``: runs of
            ``check_every`` iterations).
        factorization: ``direct`` only: "cholmod" (default) or "superlu" (v1's).
        preconditioner: ``pcg`` only: how the warped factorization is applied, "host" (sparse
            solves), "dense" (a dense inverse on the device) or "auto" (dense on CUDA).
        precision: ``pcg`` with a dense inverse: "float64" or "float32".
    """

    def __init__(self, scene: Scene | Model, device: str | None = None, solver: str = "auto",
                 tolerance: float = 1e-6, max_iterations: int = 2000, warm_start: bool = True,
                 timing: bool = True, check_every: int | None = None, graphs: bool = True,
                 factorization: str = "cholmod", preconditioner: str = "auto", precision: str = "float64"):
        if solver not in SOLVERS:
            raise SceneError(f"Simulator: solver must be one of {', '.join(SOLVERS)}, got {solver!r}")
        if not (0.0 < float(tolerance) < 1.0):
            raise SceneError(f"Simulator: tolerance must lie in (0, 1), got {tolerance!r}")
        if int(max_iterations) < 1:
            raise SceneError(f"Simulator: max_iterations must be >= 1, got {max_iterations!r}")
        if check_every is not None and int(check_every) < 1:
            raise SceneError(f"Simulator: check_every must be >= 1, got {check_every!r}")
        self.model = scene if isinstance(scene, Model) else Model(scene, device)
        m, d = self.model, self.model.device
        self.solver_name, self.warm_start, self.timing = choose(solver, d), bool(warm_start), bool(timing)
        self.state, self._next = m.state(), m.state()
        self.time, self.step_index = 0.0, 0

        n = m.num_nodes
        self.rot = wp.zeros(m.num_elements, dtype=wp.mat33d, device=d)
        self.f_int = wp.zeros(n, dtype=wp.vec3d, device=d)
        self.f_ext = wp.zeros(n, dtype=wp.vec3d, device=d)
        if m.f_const is not None:
            wp.copy(self.f_ext, m.f_const)
        self.dx = wp.zeros(n, dtype=wp.vec3d, device=d)
        self._flag = wp.zeros(1, dtype=wp.int32, device=d)
        self._largest_step = wp.zeros(1, dtype=wp.float64, device=d)
        self._size = float(np.linalg.norm(np.ptp(m.rest_np, axis=0)))  # model size (m) for step-size warnings

        scene_ = m.scene
        h = m.dt
        if m.static:
            self.mass_scale, self.stiffness_scale = 0.0, 1.0
        else:  # A = M + h D + h^2 K with D = a M + b K
            self.mass_scale = 1.0 + h * scene_.rayleigh_mass
            self.stiffness_scale = h * h + h * scene_.rayleigh_stiffness
        self.operator = SystemOperator(m, self.rot)
        self.operator.set_scales(self.mass_scale, self.stiffness_scale)

        # constraint rows exist only when the scene declares actuators or effectors
        self.constraints = None
        self.constraint_scale = 1.0 if m.static else h * h  # dx = dx_free + s X lambda, W = s H X
        self.last_W = None
        na = 0
        if scene_.actuators or scene_.effectors:
            self.constraints = ConstraintSet(m, scene_.cables, scene_.cavities, scene_.effectors)
            na = self.constraints.num_actuators
            self.lam = np.zeros(na)
            self._effector_weights = np.concatenate(
                [np.full(len(e.axes), e.weight) for e in scene_.effectors]) if scene_.effectors else np.zeros(0)
            self.actuator_delta = np.zeros(na)  # delta after the last step (rest: 0)

        # One batched solve per step: column 0 is the free solve A dx_free = b, columns 1..na the
        # compliance A X = H_a^T of the actuators (effectors alone need no column). Both are
        # warm-started from the last step.
        self.rhs = wp.zeros((1 + na, n), dtype=wp.vec3d, device=d)
        self.sol = wp.zeros((1 + na, n), dtype=wp.vec3d, device=d)
        self.b, self.dx_free = self.rhs[0:1], self.sol[0:1]
        if na:
            self.columns, self.X = self.rhs[1:], self.sol[1:]
        self.solver = make_solver(self.solver_name, self.operator, 1 + na, tolerance, max_iterations, graphs,
                                  check_every, factorization, preconditioner, precision)

    # ---- the step ------------------------------------------------------------------------
    def step(self, control: Control | None = None) -> StepStats:
        """Advance the state by one step; on a non-finite result raise and keep the old state.

        ``control`` overrides actuator inputs for this step (by actuator name).
        """
        try:
            return self._step(control)
        except SceneError:
            raise
        except SimulationError:
            self._forget_warm_starts()
            raise
        except (RuntimeError, ValueError, ArithmeticError, np.linalg.LinAlgError) as exc:
            self._forget_warm_starts()
            raise SimulationError(f"step {self.step_index + 1} (t = {self.time + self.model.dt:g} s) failed in a "
                                  f"solver: {type(exc).__name__}: {exc}; the state before the step is kept") from exc

    def _step(self, control: Control | None) -> StepStats:
        m, d = self.model, self.model.device
        cs = self.constraints
        stats = StepStats(self.step_index + 1, self.time + m.dt)
        start = time.perf_counter()
        inputs = self._row_inputs(stats.time, control) if cs is not None and cs.num_actuators else None

        with self._stage(stats, "linearize"):  # rotations, internal forces, preconditioner
            self.f_int.zero_()
            wp.launch(fem.corotational_forces, m.num_elements,
                      inputs=[self.state.q, m.tets, m.dm_inv, m.volume, m.mu, m.lam],
                      outputs=[self.rot, self.f_int], device=d)
            self.solver.prepare()

        if m.time_dependent_loads:
            with self._stage(stats, "loads"):
                f = m.external_forces(stats.time) + (m.f_const_np if m.f_const is not None else 0.0)
                self.f_ext.assign(f)

        with self._stage(stats, "free_solve"):  # A [dx_free, X] = [b, H_a^T]
            if m.static:
                wp.launch(integrate.rhs_static, m.num_nodes, inputs=[self.f_int, self.f_ext, m.mask],
                          outputs=[self.b[0]], device=d)
            else:
                wp.launch(integrate.rhs_dynamic, m.num_nodes,
                          inputs=[self.state.v, m.mass, self.f_int, self.f_ext, m.dt, m.mask],
                          outputs=[self.b[0]], device=d)
            if cs is not None and cs.num_actuators:  # effectors alone need no column: they are measured after
                # Rows are linearized where A is, at q. Evaluated at the free configuration
                # instead, H lets a follower load (a pressure) gain energy step after step (the
                # pneunet oscillated ever wider), and delta(q_free) misses the imposed
                # displacement by a second-order term (17 % on a bent cable beam); the linear
                # prediction meets it exactly once the step has converged.
                if m.scene.inverse:
                    cs.set_time(stats.time)  # effector rows measure x - target
                cs.evaluate(self.state.q)
                cs.actuator_columns(self.columns)
            self._solve(stats)
        dx = self.dx_free[0]

        if cs is not None and cs.num_actuators:
            with self._stage(stats, "compliance"):  # delta_free = delta(q) + H dx_free; W = s H X
                delta_free = cs.delta.numpy() + cs.linear_change(self.dx_free)
                self.last_W = cs.compliance(self.X, self.constraint_scale)
            with self._stage(stats, "resolve"):  # lambda from the direct or the inverse model
                na, eff = cs.num_actuators, cs.effector_row_slice
                if m.scene.inverse:
                    res = solve_inverse(self.last_W[:na], self.last_W[eff], delta_free[:na], delta_free[eff], inputs,
                                        self._effector_weights, self.lam, m.scene.inverse_epsilon)
                    stats.qp_status, stats.qp_seconds = res.status, res.seconds
                    if res.warning:
                        stats.warnings.append(f"step {stats.index}: inverse model: {res.warning}")
                else:
                    res = projected_gauss_seidel(self.last_W[:na], delta_free[:na], inputs, self.lam)
                    stats.resolve_iterations, stats.resolve_residual = res.iterations, res.residual
                    if not res.converged:
                        stats.warnings.append(f"step {stats.index}: Gauss-Seidel stopped after {res.iterations} "
                                              f"sweeps, last change {res.residual:.3e}")
                self.lam = res.lam

        with self._stage(stats, "correct"):  # dx = dx_free + s X lambda; q += dx, v = dx / h
            if cs is not None and cs.num_actuators:
                wp.launch(rows.correct_with_columns, m.num_nodes,
                          inputs=[dx, self.X, wp.array(self.lam, dtype=wp.float64, device=d), self.constraint_scale],
                          outputs=[self.dx], device=d)
                dx = self.dx
            inv_h = 0.0 if m.static else 1.0 / m.dt
            wp.launch(integrate.advance, m.num_nodes, inputs=[self.state.q, dx, inv_h],
                      outputs=[self._next.q, self._next.v], device=d)
            self._check_health(stats, dx)
            if cs is not None:  # rows at the new state: what the report records
                targets = cs.set_time(stats.time)
                cs.evaluate(self._next.q)
                self.actuator_delta = cs.delta.numpy()[: cs.num_actuators].copy()
                stats.actuator_delta = {a.name: float(v) for a, v in zip(cs.actuators, self.actuator_delta,
                                                                              strict=True)}
                stats.actuator_lambda = {a.name: float(v) for a, v in zip(cs.actuators, self.lam, strict=True)}
                stats.effectors = cs.effector_positions()
                if targets is not None:
                    stats.targets = {e.name: t for e, t in zip(cs.effectors, targets, strict=True)
                                     if e.target is not None}
                    stats.effector_error = {e.name: float(np.linalg.norm((stats.effectors[e.name] - t)[e.axis_ids]))
                                            for e, t in zip(cs.effectors, targets, strict=True)
                                            if e.target is not None}

        self.state, self._next = self._next, self.state
        self.time, self.step_index = stats.time, stats.index
        stats.total = time.perf_counter() - start
        return stats

    # ---- helpers -------------------------------------------------------------------------
    def _solve(self, stats: StepStats) -> None:
        """``A sol = rhs`` for every column (warm start: the last step's ``sol``)."""
        na = self.rhs.shape[0] - 1
        what = "free solve" if na == 0 else f"free solve and {na} compliance column{'s' if na > 1 else ''}"
        if not self.warm_start:
            self.sol.zero_()
        res = self.solver.solve(self.rhs, self.sol)
        if not math.isfinite(res.residual):
            raise SimulationError(f"step {stats.index} (t = {stats.time:g} s): the {what} met non-finite values "
                                  "(NaN or inf in the state, loads or rows); the state before the step is kept")
        stats.cg_iterations, stats.cg_residual = res.iterations, res.residual
        stats.compliance_iterations = res.iterations if na else 0
        stats.converged = res.converged
        if not res.converged:
            msg = (f"step {stats.index}: CG ({what}) stopped after {res.iterations} iterations at relative residual "
                   f"{res.residual:.3e} > tolerance {self.solver.tolerance:.1e}")
            stats.warnings.append(msg)
            warnings.warn(msg, ConvergenceWarning, stacklevel=3)

    def _row_inputs(self, t: float, control: Control | None) -> RowInputs:
        acts = self.constraints.actuators
        given = (control.inputs if control is not None else {})
        unknown = set(given) - {a.name for a in acts}
        if unknown:
            raise SceneError(f"control: no actuator named {', '.join(sorted(unknown))}")
        value = np.array([float(given[a.name]) if a.name in given else a.input_at(t) for a in acts])
        if not np.all(np.isfinite(value)):
            bad = acts[int(np.argmin(np.isfinite(value)))]
            raise SceneError(f"control: input of {bad.kind} '{bad.name}' must be finite, got {given.get(bad.name)}")
        step = np.array([a.max_step for a in acts])
        lo_step, hi_step = self.actuator_delta - step, self.actuator_delta + step
        return RowInputs(
            force_mode=np.array([a.mode == "force" for a in acts]),
            value=value,
            lo=np.array([a.min_force for a in acts]),
            hi=np.array([a.max_force for a in acts]),
            dmin=np.clip([a.min_displacement for a in acts], lo_step, hi_step),
            dmax=np.clip([a.max_displacement for a in acts], lo_step, hi_step),
        )

    def constraint_geometry(self) -> dict:
        """Rows at the current state: cable polylines (m, pull point first) by cable name,
        effector positions and targets (m) by effector name."""
        cs = self.constraints
        if cs is None:
            return {"cables": {}, "effectors": {}, "targets": {}}
        cs.evaluate(self.state.q)
        targets = cs.set_time(self.time)
        paths = cable_paths(cs.cables.cables, cs.point_positions()) if cs.cables is not None else []
        return {"cables": {c.name: p for c, p in zip(cs.cables.cables, paths, strict=True)} if paths else {},
                "effectors": cs.effector_positions(),
                "targets": {e.name: t for e, t in zip(cs.effectors, targets, strict=True) if e.target is not None}
                if targets is not None else {}}

    def kinematic_jacobian(self) -> np.ndarray:
        """``W_ea W_aa^-1`` of the last step: effector-axis motion (m) per unit actuator
        displacement, ``(effector rows, actuators)``."""
        cs = self.constraints
        if cs is None or not cs.num_actuators or not cs.effectors or self.last_W is None:
            raise SceneError("kinematic_jacobian: needs actuators, effectors and one step")
        return kinematic_jacobian(self.last_W[cs.effector_row_slice], self.last_W[: cs.num_actuators])

    @contextmanager
    def _stage(self, stats: StepStats, name: str):
        sync = self.timing and self.model.device.is_cuda
        if sync:
            wp.synchronize_device(self.model.device)
        t0 = time.perf_counter()
        yield
        if sync:
            wp.synchronize_device(self.model.device)
        stats.stages[name] = stats.stages.get(name, 0.0) + time.perf_counter() - t0

    def _forget_warm_starts(self) -> None:
        """A poisoned warm start would spoil the next attempt."""
        self.sol.zero_()

    def _check_health(self, stats: StepStats, dx: wp.array) -> None:
        self._flag.zero_()
        self._largest_step.zero_()
        wp.launch(linalg.step_health, self.model.num_nodes, inputs=[self._next.q, dx],
                  outputs=[self._flag, self._largest_step], device=self.model.device)
        bad = int(self._flag.numpy()[0])
        largest = float(np.sqrt(self._largest_step.numpy()[0]))
        if largest > self._size:
            stats.warnings.append(f"step {stats.index}: a node moved {largest:.3g} m in one step, more than the "
                                  f"model's size {self._size:.3g} m: the simulation is likely unstable")
        if bad:
            self._forget_warm_starts()
            raise SimulationError(
                f"step {stats.index} (t = {stats.time:g} s): {bad} node(s) got non-finite positions "
                f"(CG {stats.cg_iterations} iterations, residual {stats.cg_residual:.3e}); "
                "the state before the step is kept"
            )

    def probe_positions(self, state: State | None = None) -> dict[str, np.ndarray]:
        """Current position (m) of each probe point, by name."""
        m = self.model
        if m.probe_nodes is None:
            return {}
        out = wp.zeros(len(m.probe_names), dtype=wp.vec3d, device=m.device)
        wp.launch(mapping.interpolate_points, len(m.probe_names),
                  inputs=[(state or self.state).q, m.probe_nodes, m.probe_weights], outputs=[out], device=m.device)
        return dict(zip(m.probe_names, out.numpy(), strict=True))

    def internal_forces(self, state: State | None = None) -> np.ndarray:
        """Corotational internal forces (N), ``(n, 3)``, at ``state`` (current by default)."""
        m = self.model
        f = wp.zeros(m.num_nodes, dtype=wp.vec3d, device=m.device)
        rot = wp.zeros(m.num_elements, dtype=wp.mat33d, device=m.device)
        wp.launch(fem.corotational_forces, m.num_elements,
                  inputs=[(state or self.state).q, m.tets, m.dm_inv, m.volume, m.mu, m.lam], outputs=[rot, f],
                  device=m.device)
        return f.numpy()

    def energy(self, state: State | None = None) -> dict[str, float]:
        """Kinetic, elastic and gravitational potential energy (J) of ``state``."""
        m, s = self.model, state or self.state
        acc = wp.zeros(2, dtype=wp.float64, device=m.device)
        wp.launch(fem.elastic_energy, m.num_elements, inputs=[s.q, m.tets, m.dm_inv, m.volume, m.mu, m.lam],
                  outputs=[acc[0:1]], device=m.device)
        if m.mass is not None and not m.static:
            wp.launch(integrate.kinetic_energy, m.num_nodes, inputs=[s.v, m.mass], outputs=[acc[1:2]],
                      device=m.device)
        elastic, kinetic = (float(v) for v in acc.numpy())
        potential = 0.0
        if m.has_gravity:
            potential = -float(np.sum(m.mass_np[:, None] * s.q.numpy() * m.scene.gravity[None, :]))
        return {"kinetic": kinetic, "elastic": elastic, "gravity": potential,
                "total": kinetic + elastic + potential}
