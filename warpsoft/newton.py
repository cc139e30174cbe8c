"""Newton iterations of the implicit step, with a line search, each world judged on its own.

One linearization per step is what most steps need: the step then costs what it always did,
plus one residual check. Where it is not enough (a time step large against the body's motion:
the finger at ``dt = 0.5 s`` flipped between two shapes every step), the step iterates:

- iteration ``k`` linearizes everything at ``q_k = q0 + dx_k`` (element rotations and forces,
  rows, preconditioner) and solves for the correction ``e`` from the out-of-balance ``r(dx_k)``
  (``kernels/newton.py``), the rows resolved anew at ``q_k`` (Gauss-Seidel or QP; the actuators'
  per-step limits still count from the step's start): ``A e = r + s H^T lambda``;
- ``dx_{k+1} = dx_k + alpha e`` and ``lambda = lambda_k + alpha (lambda_new - lambda_k)``;
- the residual is measured along the correction: ``eta = R(q_{k+1}) . e / (e . A e)``. The step
  minimizes an energy (inertia, elastic, loads, rows: corotational elasticity is hyperelastic),
  whose slope along ``e`` is ``-R . e``: ``eta`` is 1 before the step, 0 at the minimum along
  ``e``, negative past it. A force norm would not do: second-order stretching of a bending
  beam leaves forces as large as the load itself for a motion error a millionth of the step;
- ``eta`` is scale-free (it measures the tangent's error along ``e``, and stays the same while a
  slowly converging iteration shrinks ``e``): the error left is ``|eta|`` times the size of ``e``
  relative to the step's first correction (in the energy norm ``sqrt(e . A e)``; at least that
  of a strain of ``FLOOR_STRAIN`` throughout the body, so that a step that hardly moves is not
  iterated for nothing). In a world free to move as a whole (no fixed node), the first
  correction's rigid part (the rigid motion that fits it best, by its mass moments) is left out
  of that measure, down to ``RIGID_SHARE`` of it: a body spinning or flying is judged against how
  it deforms more than against how far it travels (one linearization of a free cube turning at
  20 rad/s left it stretched a hundred times too far, its error 1 % of its rigid motion). A
  world is done when a full step leaves an error ``<= tolerance`` (``<= factor_reuse`` where
  it solved on an earlier linearization's factorization: ``limit``); its later iterations
  leave it in place (``alpha = 0``), its solve column 0;
- line search: a world that overshot (``eta < -1/2``: its energy rises again before the full
  step) retries with ``alpha`` where the slope, interpolated linearly, vanishes;
- inverse-model worlds solve their QP again at each iteration's linearization (the step ends
  where the mechanics and the QP agree); a QP whose active set switches between iterations may
  keep a step from converging: it then warns.

The linearization made at the end of a step is the next step's (a device check makes it again
if the state was changed from outside), so a step that converges at once adds only node passes
(the state check, the slope before and after, the update and multipliers along ``alpha``) and,
with stiffness damping, one stiffness product: measured 40-80 us on an H200 (3-6 % of a step)
and 5-7 % on the CPU device (docs/performance.md).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import warp as wp

from warpsoft.kernels import newton as kernels
from warpsoft.kernels import worlds as world_kernels
from warpsoft.kernels.linear import cg as cg_kernels
from warpsoft.kernels.linear.pcg import launch_nodes

from .errors import SceneError
from .launch import launch

if TYPE_CHECKING:
    from .simulator import Simulator

OVERSHOOT = 0.5  # eta below -OVERSHOOT: the step went past the minimum along it; the line search shortens it
FLOOR_STRAIN = 1e-5  # corrections are judged against at least the energy of this strain throughout the body
# a free world's first correction counts its deformation, but at least this share of its whole energy: a
# converged implicit Euler step takes angular momentum from a spinning body ((w h)^2 a step), one
# linearization keeps it; this share keeps it where one linearization's error is small against the motion
RIGID_SHARE = 1e-2


def zero_moving(a: wp.array, model, moving: wp.array | None) -> None:
    """``a`` (``(nodes,)``) zeroed for the worlds that move (``moving``, ``kernels/worlds.py``):
    an accumulator the linearization sums into anew; None: all of it (a memset)."""
    if moving is None:
        a.zero_()
        return
    launch(world_kernels.zero_moving, model.num_nodes, inputs=[model.node_world, moving], outputs=[a],
           device=model.device)


class Newton:
    """The step's Newton state: buffers on the device, each world's judgement on the host.

    Args:
        sim: the simulator (its model, rows, multipliers and linearization buffers).
        iterations: most linearizations per step (1: v1's single linearization, never iterate).
        tolerance: the error a world's full step must leave (see the module doc).
        backtracks: most line-search retries per iteration (0: no line search).
    """

    def __init__(self, sim: Simulator, iterations: int = 10, tolerance: float = 0.1, backtracks: int = 4):
        if int(iterations) < 1:
            raise SceneError(f"Simulator: newton_iterations must be >= 1, got {iterations!r}")
        if not (0.0 < float(tolerance) < 1.0):
            raise SceneError(f"Simulator: newton_tolerance must lie in (0, 1), got {tolerance!r}")
        if int(backtracks) < 0:
            raise SceneError(f"Simulator: line_search must be >= 0 retries, got {backtracks!r}")
        m, d = sim.model, sim.model.device
        self.sim, self.max_iterations = sim, int(iterations)
        self.tolerance = float(tolerance)
        self.backtracks = int(backtracks) if self.max_iterations > 1 else 0  # one linearization: its full step
        n, worlds = m.num_nodes, m.num_worlds
        h, k = m.dt, sim.end_share
        # r(dx) = c_v M v0 + c_f f(q0 + dx) + c_0 f(q0) - ...: implicit Euler (k = 1) takes the
        # forces at the step's end, the trapezoid (k = 1/2) the mean of both ends
        self.c_v, self.c_f = (0.0, 1.0) if m.static else (h, (k * h) ** 2)
        self.c_0 = 0.0 if m.static else (k - k * k) * h * h  # (s^2) before the step start's forces
        self.c_d = sim.stiffness_scale - self.c_f  # Rayleigh stiffness damping k h b (0 quasi-static)
        # v = dx / (k h) - (1/k - 1) v0: implicit Euler dx / h, the trapezoid 2 dx / h - v0
        self.inv_kh, self.keep_v = (0.0, 0.0) if m.static else (1.0 / (k * h), 1.0 / k - 1.0)
        # c_0 (f_int + f_ext) at the step's start (kg m): the trapezoid's only
        self.f_start = wp.zeros(n if self.c_0 else 0, dtype=wp.vec3d, device=d)
        self.dx_base = wp.zeros(n, dtype=wp.vec3d, device=d)  # dx_k (m)
        self.dx = wp.zeros((1, n), dtype=wp.vec3d, device=d)  # dx_k + alpha e: the step so far (m)
        self.kdx = wp.zeros((1, n), dtype=wp.vec3d, device=d)  # c_d K dx
        self.warm = wp.zeros(n, dtype=wp.vec3d, device=d)  # the first solve's motion, kept while the step iterates
        # where the last linearization was made (m); none yet (NaN differs from every position)
        self.q_lin = wp.array(np.full((n, 3), np.nan), dtype=wp.vec3d, device=d)
        self.moved = wp.zeros(1, dtype=wp.int32, device=d)  # set when the step must linearize first
        self.sums = wp.zeros((1, worlds, kernels.NUM_SUMS), dtype=wp.float64, device=d)  # R . e after the step
        self.slope0 = wp.zeros((1, worlds, kernels.NUM_SUMS), dtype=wp.float64, device=d)  # e . A e before it
        # the least e . A e a world's corrections are measured against (J times c_f: the strain
        # energy of FLOOR_STRAIN throughout its body): a step that hardly moves is not iterated for
        # errors far below that
        young = (m.mu.numpy() * (3 * m.lam.numpy() + 2 * m.mu.numpy()) / (m.lam.numpy() + m.mu.numpy()))
        energy = np.bincount(m.elem_world_np, young * m.volume.numpy(), minlength=worlds)
        self.floor = self.c_f * energy * FLOOR_STRAIN ** 2
        # the worlds free to move as a whole: no node held on any axis (``rigid_moments``)
        free = np.ones(worlds, dtype=bool)
        np.logical_and.at(free, m.node_world_np, np.all(m.mask_np != 0.0, axis=1))
        self.free_host = free & (not m.static)
        self.free = wp.array(self.free_host.astype(np.int32), dtype=wp.int32, device=d)
        self.moments = wp.zeros((worlds, kernels.NUM_MOMENTS) if self.free_host.any() else (0, 0), dtype=wp.float64,
                                device=d)
        self.world_mass = np.bincount(m.node_world_np, m.mass_np, minlength=worlds) if self.free_host.any() else None
        self.alpha_host = np.ones(worlds)
        self.alpha = wp.array(self.alpha_host, dtype=wp.float64, device=d)
        # the worlds this pass moves (1) and those it leaves where the last linearization was made
        # (0): a later iteration's done worlds, a line search's worlds not retrying. Their
        # linearization is kept rather than made again (``kernels/worlds.py``)
        self.moving_host = np.ones(worlds, dtype=np.int32)
        self.moving = wp.array(self.moving_host, dtype=wp.int32, device=d)
        # the same as CG scalars (``(1, worlds, slots)``, DONE set for the worlds that stay): the
        # stiffness product of the damping skips them as a solve skips its converged worlds
        self.still = wp.zeros((1, worlds, cg_kernels.NUM_SCALARS) if self.c_d != 0.0 and worlds > 1 else (0, 0, 0),
                              dtype=wp.float64, device=d)
        # what the linearization reads (its operator's): one world moves whenever one is made, so
        # it takes the plain path (no flag, memsets)
        self.moving_flag = self.moving if worlds > 1 else None
        self.mass = m.mass if m.mass is not None else wp.zeros(n, dtype=wp.float64, device=d)
        rows = sim.rows
        self.actuated = rows is not None and rows.num_columns > 0  # rows that carry a force
        if self.actuated:
            self.lam_base = wp.zeros(rows.num_rows, dtype=wp.float64, device=d)
            self.lam_full = wp.zeros(rows.num_rows, dtype=wp.float64, device=d)
            self.row_world = wp.array(np.repeat(np.arange(worlds), np.diff(rows.world_row_start)), dtype=wp.int32,
                                      device=d)
            self.delta_start = wp.zeros(rows.num_rows, dtype=wp.float64, device=d)  # rows at the step's start
        self.row_forces = wp.zeros(n, dtype=wp.vec3d, device=d)  # H_f^T lambda (N): 0 without force rows
        # the error each world's full step must leave to be done: the tolerance, or less in a step
        # that solves on an earlier linearization's factorization (set by the step: factor_reuse)
        self.limit = np.full(worlds, self.tolerance)
        self._reset_host()

    # ---- device work (captured in the step's graphs) --------------------------------------
    def linearize_if_moved(self, q: wp.array, linearize) -> None:
        """Run ``linearize`` (at ``q``) unless the last linearization was made at ``q`` already."""
        m = self.sim.model
        self.moved.zero_()
        launch(kernels.moved, m.num_nodes, inputs=[q, self.q_lin], outputs=[self.moved], device=m.device)
        wp.capture_if(self.moved, on_true=linearize)

    def linearized_at(self, q: wp.array) -> None:
        """Remember that the element rotations, forces and preconditioner are those of ``q``."""
        wp.copy(self.q_lin, q)

    def start(self) -> None:
        """The step so far is nothing (``dx = 0``) but the kinematic frames' prescribed move; the
        first solve's right-hand side ``r(0)`` (less the move's pull on the free nodes)."""
        sim, m = self.sim, self.sim.model
        self.dx.zero_()
        launch(kernels.start, m.num_nodes, inputs=[sim.state.v, self.mass, sim.f_int, sim.f_ext, m.mask, self.c_v,
                                                    self.c_f, self.c_0], outputs=[sim.rhs, self.f_start],
               device=m.device)
        if sim.driven is not None:  # the kinematic frames' nodes: their move is known
            sim.driven.prescribe(sim.state.q, self.dx, sim.rhs, sim.operator, m.mask)

    def hold_done_worlds(self) -> None:
        """Worlds done iterating get no correction (their first solve column is 0)."""
        m = self.sim.model
        launch(kernels.hold_done_worlds, m.num_nodes, inputs=[self.alpha, m.node_world],
               outputs=[self.sim.rhs, self.sim.sol], device=m.device)

    def accept(self, actuated: bool) -> None:
        """An iteration begins from the step so far and its multipliers."""
        wp.copy(self.dx_base, self.dx[0])
        if actuated:
            wp.copy(self.lam_base, self.sim.gauss_seidel.lam)

    def advance(self, e: wp.array, actuated: bool, retry: bool = False, scaled_forces: wp.array | None = None) -> None:
        """``dx = dx_k + alpha e``, the positions and velocities it gives (``next``), and the
        multipliers along the same fraction (the resolve's kept in ``lam_full``); ``retry``: the
        same correction along new fractions (the line search). ``scaled_forces``: ``s H_f^T lambda``
        (``(n,)`` vec3d) when the correction already made it (its one solve's right-hand side)."""
        sim, m = self.sim, self.sim.model
        if not retry:  # e . A e = (r + s H^T lambda) . e, at this iteration's linearization
            self.slope0.zero_()
            forces, s = self.row_forces, sim.constraint_scale
            if actuated and scaled_forces is not None:
                forces, s = scaled_forces, 1.0
            elif actuated:
                sim.rows.force_rows_forces(sim.gauss_seidel.lam, 1.0, self.row_forces)
            launch_nodes(kernels.slope, 1, m.num_nodes, [sim.rhs, m.mask, forces, s, e, m.node_world, self.slope0],
                         m.device)
            if sim.driven is not None and self.accepted == 0:  # the step's first correction: with the frames' move
                launch(kernels.prescribed_slope, m.num_nodes, inputs=[e, self.dx_base, sim.driven.a_dx,
                                                                      m.node_world, self.slope0], device=m.device)
            if self.moments.shape[0] and self.accepted == 0:  # its rigid part, in the free worlds
                self.moments.zero_()
                launch(kernels.rigid_moments, m.num_nodes, inputs=[sim.state.q, self.mass, e, m.node_world, self.free],
                       outputs=[self.moments], device=m.device)
        if actuated and not retry:
            wp.copy(self.lam_full, sim.gauss_seidel.lam)
        if actuated:
            launch(kernels.blend_multipliers, sim.rows.num_rows,
                   inputs=[self.lam_base, self.lam_full, self.alpha, self.row_world],
                   outputs=[sim.gauss_seidel.lam], device=m.device)
        launch(kernels.update, m.num_nodes,
               inputs=[sim.state.q, sim.state.v, self.dx_base, e, self.alpha, m.node_world, self.inv_kh, self.keep_v],
               outputs=[self.dx[0], sim.next.q, sim.next.v], device=m.device)
        if sim.rigid is not None:  # the rigid bodies along the same fraction
            sim.rigid.advance(sim.state, sim.next, self.alpha)

    def residual(self, e: wp.array) -> None:
        """The out-of-balance ``r(dx)`` (the next solve's right-hand side, ``rhs[0]``) and ``R . e``
        (``sums``), at the current linearization (forces, rows' columns)."""
        sim, m = self.sim, self.sim.model
        if self.c_d != 0.0:  # (unchanged for the worlds that stay: their dx and rotations are)
            zero_moving(self.kdx[0], m, self.moving_flag)
            sim.elastic.apply(self.dx, self.kdx, sim.rot, self.c_d, self.still if self.moving_flag else None)
        self.sums.zero_()
        if self.actuated:
            sim.rows.force_rows_forces(sim.gauss_seidel.lam, 1.0, self.row_forces)
        launch_nodes(kernels.residual, 1, m.num_nodes,
                     [sim.state.v, self.mass, sim.f_int, sim.f_ext, self.f_start, self.kdx[0], self.dx[0], m.mask,
                      self.c_v, self.c_f, sim.mass_scale, self.row_forces, sim.constraint_scale, e, m.node_world,
                      sim.rhs, self.sums], m.device)

    # ---- host judgement -------------------------------------------------------------------
    def _reset_host(self) -> None:
        worlds = self.sim.model.num_worlds
        self.done = np.zeros(worlds, dtype=bool)
        self.eta = np.zeros(worlds)  # R . e / e . A e after each world's last accepted step
        self.error = np.zeros(worlds)  # |eta| |e|_A / |e_0|_A: what is left, relative to the step's first correction
        self.energy0 = np.zeros(worlds)  # e . A e of each world's first correction (at least the floor)
        self.trials_left = np.full(worlds, self.backtracks)
        self.retried = np.zeros(worlds, dtype=bool)  # the worlds that took a shortened step in this step
        self.iterations = np.zeros(worlds, dtype=int)
        self.trials, self.accepted = 0, 0

    def begin_step(self) -> None:
        """Before a step: every world takes full steps again."""
        if self.accepted != 1 or self.trials:  # (after a step of one full iteration, all is as it should be)
            self._reset_host()
            self._set_alpha(np.ones_like(self.alpha_host))
            self._set_moving(np.ones_like(self.moving_host))
        else:
            self.done[:] = False
            self.iterations[:] = 0
            self.accepted = 0

    def _set_alpha(self, alpha: np.ndarray) -> None:
        if not np.array_equal(alpha, self.alpha_host):  # uploads only when it changes
            self.alpha_host = alpha.copy()
            self.alpha.assign(self.alpha_host)

    def _set_moving(self, moving: np.ndarray) -> None:
        moving = moving.astype(np.int32)
        if not np.array_equal(moving, self.moving_host):  # uploads only when it changes
            self.moving_host = moving
            self.moving.assign(moving)
            if self.still.shape[0]:
                still = np.zeros(self.still.shape)
                still[0, :, cg_kernels.DONE] = moving == 0
                self.still.assign(still)

    def judge(self, host: dict[str, np.ndarray]) -> bool:
        """After an iteration or a line-search trial was read: True when some world overshot and
        must retry along a shorter ``alpha`` (set for it)."""
        g, g0 = host["newton"][0, :, kernels.SLOPE], host["newton_slope"][0, :, kernels.SLOPE]
        with np.errstate(divide="ignore", invalid="ignore"):
            eta = np.where(g0 > 0.0, g / g0, 0.0)
        if self.accepted == 0:  # (a free world: its deformation, or RIGID_SHARE of its whole motion)
            energy0 = np.maximum(np.maximum(g0 - self.rigid_energy(host), RIGID_SHARE * g0), self.floor)
        else:
            energy0 = self.energy0
        # the next correction along e is about eta e: relative to the step's first (or to the
        # floor, for a step that hardly moves), it is what is left
        error = np.abs(eta) * np.sqrt(np.maximum(g0, 0.0) / energy0)
        over = (eta < -OVERSHOOT) & (error > self.tolerance) & (self.trials_left > 0) & ~self.done
        if over.any():
            alpha = self.alpha_host.copy()
            # the slope, linear between g0 at 0 and g at alpha, vanishes at alpha / (1 - eta)
            alpha[over] = np.maximum(alpha[over] / (1.0 - eta[over]), 0.1 * alpha[over])
            self.trials_left[over] -= 1
            self.retried[over] = True
            self.trials += 1
            self._set_alpha(alpha)
            self._set_moving(over)  # the others are where they were: their linearization stays
            return True
        moving = ~self.done
        self.energy0, self.accepted = energy0, self.accepted + 1
        self.eta[moving], self.error[moving] = eta[moving], error[moving]
        self.iterations[moving] += 1
        return False

    def rigid_energy(self, host: dict[str, np.ndarray]) -> np.ndarray:
        """Per world, ``e_r . A e_r`` of the rigid motion ``e_r`` that fits the first correction
        best in the mass norm (``(worlds,)``, 0 for a world held anywhere): its translation
        ``P / M`` and rotation ``I^-1 L`` from the mass moments (``A`` acts on a rigid motion
        by its mass term alone)."""
        out = np.zeros(len(self.free_host))
        if "newton_moments" not in host:
            return out
        free = np.flatnonzero(self.free_host)
        mom, mass = host["newton_moments"][free], self.world_mass[free]
        c, p = mom[:, 0:3] / mass[:, None], mom[:, 9:12]
        xx, yy, zz, xy, xz, yz = mom[:, 3:9].T
        s = np.stack([np.stack([xx, xy, xz], -1), np.stack([xy, yy, yz], -1), np.stack([xz, yz, zz], -1)], 1)
        s -= mass[:, None, None] * c[:, :, None] * c[:, None, :]  # second moments about the centre
        inertia = np.trace(s, axis1=1, axis2=2)[:, None, None] * np.eye(3) - s
        moment = mom[:, 12:15] - np.cross(c, p)
        spin = np.einsum("wi,wij,wj->w", moment, np.linalg.pinv(inertia), moment)
        out[free] = self.sim.mass_scale * (np.einsum("wi,wi->w", p, p) / mass + spin)
        return out

    def go_on(self) -> bool:
        """After an iteration was accepted: whether another is due (some world's full step left an
        error above the tolerance, or its step was shortened, and the cap is not reached); if so,
        the done worlds stay where they are."""
        self.done |= (self.alpha_host == 1.0) & (self.error <= self.limit)
        if self.accepted >= self.max_iterations or self.done.all():
            # between steps every world is linearized whole (a state set from outside, a new
            # preconditioner's first factorization)
            self._set_moving(np.ones_like(self.moving_host))
            return False
        self.trials_left[:] = self.backtracks
        self._set_alpha(np.where(self.done, 0.0, 1.0))
        self._set_moving(~self.done)  # the done worlds are held: their linearization stays
        return True
