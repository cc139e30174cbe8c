"""The Simulator: one linearized step of a soft-robot scene, implicit Euler or quasi-static."""

from __future__ import annotations

import time
import warnings
from contextlib import contextmanager
from dataclasses import dataclass, field

import numpy as np
import warp as wp

from warpsoft.kernels import fem, integrate, linalg, mapping

from .errors import SceneError, SimulationError
from .model import Model, State
from .scene import Scene
from .solvers import BlockJacobiCG, SparseDirect, SystemOperator


class ConvergenceWarning(UserWarning):
    """An iterative solve stopped at its iteration cap above its tolerance."""


@dataclass
class StepStats:
    """What one step did: solver statistics and the wall time (s) of each stage that ran."""

    index: int
    time: float
    cg_iterations: int = 0
    cg_residual: float = 0.0
    converged: bool = True
    stages: dict[str, float] = field(default_factory=dict)
    total: float = 0.0
    warnings: list[str] = field(default_factory=list)


class Simulator:
    """Steps a scene on a device.

    Args:
        scene: the scene (or an already built :class:`Model`).
        device: Warp device ("cpu", "cuda", "cuda:0"); Warp's default if None.
        solver: "cg" (matrix-free block-Jacobi PCG, any device) or "direct" (assembled
            sparse LU on the host, the CPU alternative and accuracy reference).
        tolerance: CG relative residual |r| / |b|.
        max_iterations: CG iteration cap (reaching it is a warning in the step stats).
        warm_start: start each free solve from the previous step's solution.
        timing: synchronize the device around stages to time them (CUDA only matters).
    """

    def __init__(self, scene: Scene | Model, device: str | None = None, solver: str = "cg",
                 tolerance: float = 1e-6, max_iterations: int = 2000, warm_start: bool = True,
                 timing: bool = True):
        if solver not in ("cg", "direct"):
            raise SceneError(f"Simulator: solver must be 'cg' or 'direct', got {solver!r}")
        if not (0.0 < float(tolerance) < 1.0):
            raise SceneError(f"Simulator: tolerance must lie in (0, 1), got {tolerance!r}")
        if int(max_iterations) < 1:
            raise SceneError(f"Simulator: max_iterations must be >= 1, got {max_iterations!r}")
        self.model = scene if isinstance(scene, Model) else Model(scene, device)
        m, d = self.model, self.model.device
        self.solver_name, self.warm_start, self.timing = solver, bool(warm_start), bool(timing)
        self.state, self._next = m.state(), m.state()
        self.time, self.step_index = 0.0, 0

        n = m.num_nodes
        self.rot = wp.zeros(m.num_elements, dtype=wp.mat33d, device=d)
        self.f_int = wp.zeros(n, dtype=wp.vec3d, device=d)
        self.f_ext = wp.zeros(n, dtype=wp.vec3d, device=d)
        if m.f_const is not None:
            wp.copy(self.f_ext, m.f_const)
        self.b = wp.zeros(n, dtype=wp.vec3d, device=d)
        self.dx = wp.zeros(n, dtype=wp.vec3d, device=d)
        self._flag = wp.zeros(1, dtype=wp.int32, device=d)

        scene_ = m.scene
        h = m.dt
        if m.static:
            self.mass_scale, self.stiffness_scale = 0.0, 1.0
        else:  # A = M + h D + h^2 K with D = a M + b K
            self.mass_scale = 1.0 + h * scene_.rayleigh_mass
            self.stiffness_scale = h * h + h * scene_.rayleigh_stiffness
        self.operator = SystemOperator(m, self.rot)
        self.operator.set_scales(self.mass_scale, self.stiffness_scale)
        if solver == "cg":
            self.cg = BlockJacobiCG(self.operator, tolerance, max_iterations)
        else:
            self.direct = SparseDirect(m)

    # ---- the step ------------------------------------------------------------------------
    def step(self) -> StepStats:
        """Advance the state by one step; on a non-finite result raise and keep the old state."""
        m, d = self.model, self.model.device
        stats = StepStats(self.step_index + 1, self.time + m.dt)
        start = time.perf_counter()

        with self._stage(stats, "linearize"):  # rotations, internal forces, preconditioner
            self.f_int.zero_()
            wp.launch(fem.corotational_forces, m.num_elements,
                      inputs=[self.state.q, m.tets, m.dm_inv, m.volume, m.mu, m.lam],
                      outputs=[self.rot, self.f_int], device=d)
            if self.solver_name == "cg":
                self.cg.update_preconditioner()
            else:
                self.direct.factorize(self.rot, self.mass_scale, self.stiffness_scale)

        if m.time_dependent_loads:
            with self._stage(stats, "loads"):
                f = m.external_forces(stats.time) + (m.f_const_np if m.f_const is not None else 0.0)
                self.f_ext.assign(f)

        with self._stage(stats, "free_solve"):  # A dx = b
            if m.static:
                wp.launch(integrate.rhs_static, m.num_nodes, inputs=[self.f_int, self.f_ext, m.mask],
                          outputs=[self.b], device=d)
            else:
                wp.launch(integrate.rhs_dynamic, m.num_nodes,
                          inputs=[self.state.v, m.mass, self.f_int, self.f_ext, m.dt, m.mask],
                          outputs=[self.b], device=d)
            if self.solver_name == "cg":
                if not self.warm_start:
                    self.dx.zero_()
                res = self.cg.solve(self.b, self.dx)
                stats.cg_iterations, stats.cg_residual, stats.converged = res.iterations, res.residual, res.converged
                if not res.converged:
                    msg = (f"step {stats.index}: CG stopped after {res.iterations} iterations at relative residual "
                           f"{res.residual:.3e} > tolerance {self.cg.tolerance:.1e}")
                    stats.warnings.append(msg)
                    warnings.warn(msg, ConvergenceWarning, stacklevel=2)
            else:
                self.dx.assign(self.direct.solve(self.b.numpy()))

        with self._stage(stats, "correct"):  # q += dx, v = dx / h
            inv_h = 0.0 if m.static else 1.0 / m.dt
            wp.launch(integrate.advance, m.num_nodes, inputs=[self.state.q, self.dx, inv_h],
                      outputs=[self._next.q, self._next.v], device=d)
            self._check_finite(stats)

        self.state, self._next = self._next, self.state
        self.time, self.step_index = stats.time, stats.index
        stats.total = time.perf_counter() - start
        return stats

    # ---- helpers -------------------------------------------------------------------------
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

    def _check_finite(self, stats: StepStats) -> None:
        self._flag.zero_()
        wp.launch(linalg.count_nonfinite, self.model.num_nodes, inputs=[self._next.q], outputs=[self._flag],
                  device=self.model.device)
        bad = int(self._flag.numpy()[0])
        if bad:
            self.dx.zero_()  # a poisoned warm start would spoil the next attempt
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
