"""Rigid bodies in the step: their free motion, their share of the rows' compliance, their
correction and update, next to the soft bodies' (see ``kernels/rigid.py`` for the equations).

A rigid body is six unknowns with a block-diagonal mass matrix, so its "solve" is exact and
local: the free motion from its velocities and gravity, and for each force row ``j`` the motion
per unit force ``Y[j] = M^-1 J^T`` (the counterpart of the soft bodies' compliance columns
``X``). Rows that touch it (contacts) carry entries ``(row, body, j_lin, j_ang)`` besides their
soft ones, written by their kind at each evaluation: ``W`` gains ``h^2 J Y`` and
``delta_free`` gains ``J d_free``. The step's Newton iterations carry the bodies along the same
fraction ``alpha`` as their world's nodes. Nothing here exists in a scene without rigid bodies.
"""

from __future__ import annotations

import numpy as np
import warp as wp

from warpsoft.kernels import rigid as kernels

from .launch import launch


class RigidBodies:
    """The step's rigid-body buffers (device, ``(bodies,)`` unless said): ``inv_inertia_w``
    (mat33d, 1/(kg m^2), world axes, at the current linearization); the step's free motion
    ``target_*``, the step so far ``dx_*``, an iteration's start ``base_*``, its free correction
    ``free_*`` and correction ``e_*`` (``_lin`` m, ``_ang`` rad); ``y_lin``, ``y_ang``
    ``(columns, bodies)`` the columns ``M^-1 J^T`` (m/N, rad/N); ``pose_p``, ``pose_r`` the pose
    after the last update (what the host reads)."""

    def __init__(self, model, rows):
        self.model, self.rows, d = model, rows, model.device
        n = model.num_rigid
        vec = lambda: wp.zeros(n, dtype=wp.vec3d, device=d)  # noqa: E731
        self.inv_inertia_w = wp.zeros(n, dtype=wp.mat33d, device=d)
        self.target_lin, self.target_ang, self.dx_lin, self.dx_ang = vec(), vec(), vec(), vec()
        self.base_lin, self.base_ang, self.free_lin, self.free_ang = vec(), vec(), vec(), vec()
        self.e_lin, self.e_ang = vec(), vec()
        ncol = max(rows.num_columns, 1)
        self.y_lin = wp.zeros((ncol, n), dtype=wp.vec3d, device=d)
        self.y_ang = wp.zeros((ncol, n), dtype=wp.vec3d, device=d)
        self.pose_p, self.pose_r = vec(), wp.zeros(n, dtype=wp.quatd, device=d)
        self.names = [(w, rb.name) for w, rb in model.rigid]
        # the scene's Rayleigh mass damping acts on every body it integrates, rigid ones too
        self.keep = 1.0 / (1.0 + model.dt * model.rayleigh_mass)

    def _launch(self, kernel, dim, inputs) -> None:
        launch(kernel, dim, inputs=inputs, device=self.model.device)

    # ---- the step's stages (device; capturable) ------------------------------------------
    def start(self, state) -> None:
        """The step's free motion from ``state``; the step so far is nothing."""
        m = self.model
        self._launch(kernels.start, m.num_rigid,
                     [state.body_r, state.body_v, state.body_w, m.rigid_inertia, m.rigid_gravity, m.dt, self.keep,
                      self.inv_inertia_w, self.target_lin, self.target_ang, self.dx_lin, self.dx_ang])

    def accept(self) -> None:
        """An iteration begins from the step so far."""
        self._launch(kernels.accept, self.model.num_rigid,
                     [self.target_lin, self.target_ang, self.dx_lin, self.dx_ang, self.base_lin, self.base_ang,
                      self.free_lin, self.free_ang])

    def predict(self) -> None:
        """``delta_free += J d_free`` (after the soft bodies' ``H e_free``)."""
        r = self.rows
        self._launch(kernels.predict, r.num_rigid_entries,
                     [r.j_row, r.j_body, r.j_lin, r.j_ang, self.free_lin, self.free_ang, r.delta_free])

    def compliance(self, scale: float) -> None:
        """``Y = M^-1 J^T`` of the force rows, and ``W += scale J Y``."""
        r = self.rows
        self.y_lin.zero_()
        self.y_ang.zero_()
        self._launch(kernels.columns, r.num_rigid_entries,
                     [r.j_row, r.j_body, r.j_lin, r.j_ang, r.column_of_row, self.model.rigid_inv_mass,
                      self.inv_inertia_w, self.keep, self.y_lin, self.y_ang])
        self._launch(kernels.compliance, r.num_rigid_entries,
                     [r.j_row, r.j_body, r.j_lin, r.j_ang, self.y_lin, self.y_ang, self.model.rigid_world,
                      r.world_force_rows, scale, r.W])

    def correct(self, lam: wp.array, scale: float) -> None:
        """The iteration's correction ``e = d_free + scale Y lambda``."""
        m, r = self.model, self.rows
        self._launch(kernels.correct, m.num_rigid,
                     [self.free_lin, self.free_ang, self.y_lin, self.y_ang, lam, m.rigid_world, r.world_row_start_d,
                      r.world_force_rows, scale, self.e_lin, self.e_ang])

    def no_rows(self) -> None:
        """Without force rows this iteration, the correction is the free one."""
        wp.copy(self.e_lin, self.free_lin)
        wp.copy(self.e_ang, self.free_ang)

    def advance(self, state, out, alpha: wp.array) -> None:
        """``d = d_base + alpha e``: the bodies of ``out`` moved from ``state``."""
        m = self.model
        self._launch(kernels.advance, m.num_rigid,
                     [state.body_p, state.body_r, self.base_lin, self.base_ang, self.e_lin, self.e_ang, alpha,
                      m.rigid_world, 1.0 / m.dt, self.dx_lin, self.dx_ang, out.body_p, out.body_r, out.body_v,
                      out.body_w, self.pose_p, self.pose_r])

    def linearize(self, state, flag: wp.array) -> None:
        """At ``state``: the world inverse inertia, and the non-finite poses counted into ``flag``
        (per world)."""
        m = self.model
        self._launch(kernels.inverse_inertia, m.num_rigid, [state.body_r, m.rigid_inertia, self.inv_inertia_w])
        self._launch(kernels.health, m.num_rigid, [state.body_p, state.body_r, m.rigid_world, flag])

    # ---- host ------------------------------------------------------------------------------
    def poses(self, state, world: int | None = None) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """``name -> (rotation 3x3, centre of mass (3,) m)`` of the rigid bodies of ``state`` (of
        ``world`` only if given), read from the device."""
        p, r = state.body_p.numpy(), state.body_r.numpy()
        return {name: (quat_matrix(r[k]), p[k].copy()) for k, (w, name) in enumerate(self.names)
                if world is None or w == world}


def quat_matrix(q: np.ndarray) -> np.ndarray:
    """The rotation matrix of a unit quaternion ``(x, y, z, w)`` (Warp's order)."""
    x, y, z, w = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
