"""Rigid bodies in the implicit step (``warpsoft/rigid.py``).

A body's unknown over a step is its displacement ``d = (d_lin, d_ang)``: the move of its centre
of mass (m) and its rotation vector (rad). Implicit Euler with the mass matrix
``M = diag(m I, I_w)`` and the scene's Rayleigh mass damping ``a``:
``(1 + h a) M d = h M (v, w) + h^2 (m g, -w x I_w w) + h^2 J^T lambda``, so with
``keep = 1 / (1 + h a)`` the free motion is ``d_free = keep (h (v, w) + h^2 (g, -I_w^-1 (w x I_w w)))``
(the gyroscopic torque taken at the step's start) and a row's force moves it by
``keep h^2 M^-1 J^T lambda``. A row's entry on a
body is ``(j_lin, j_ang)``: ``delta`` changes by ``j_lin . d_lin + j_ang . d_ang``.
"""

import warp as wp

from . import OPTIONS

wp.set_module_options(OPTIONS)


@wp.func
def world_inverse_inertia(r: wp.quatd, inertia: wp.mat33d):
    """``R I^-1 R^T``: the inverse inertia (1/(kg m^2)) in world axes of a body turned by ``r``."""
    rot = wp.quat_to_matrix(r)
    return rot * wp.inverse(inertia) * wp.transpose(rot)


@wp.kernel
def start(r: wp.array(dtype=wp.quatd), v: wp.array(dtype=wp.vec3d), w: wp.array(dtype=wp.vec3d),
          inertia: wp.array(dtype=wp.mat33d), gravity: wp.array(dtype=wp.vec3d), h: wp.float64, keep: wp.float64,
          inv_inertia_w: wp.array(dtype=wp.mat33d), target_lin: wp.array(dtype=wp.vec3d),
          target_ang: wp.array(dtype=wp.vec3d), dx_lin: wp.array(dtype=wp.vec3d), dx_ang: wp.array(dtype=wp.vec3d)):
    """The step's free motion of body ``b`` from its state (``inertia`` in its own frame,
    ``gravity`` m/s^2) and its world inverse inertia; the step so far is nothing."""
    b = wp.tid()
    rot = wp.quat_to_matrix(r[b])
    i_inv = world_inverse_inertia(r[b], inertia[b])
    inv_inertia_w[b] = i_inv
    target_lin[b] = keep * (h * v[b] + h * h * gravity[b])
    spin = rot * inertia[b] * wp.transpose(rot) * w[b]  # I_w w
    target_ang[b] = keep * (h * w[b] - h * h * (i_inv * wp.cross(w[b], spin)))
    dx_lin[b] = wp.vec3d()
    dx_ang[b] = wp.vec3d()


@wp.kernel
def accept(target_lin: wp.array(dtype=wp.vec3d), target_ang: wp.array(dtype=wp.vec3d),
           dx_lin: wp.array(dtype=wp.vec3d), dx_ang: wp.array(dtype=wp.vec3d),
           base_lin: wp.array(dtype=wp.vec3d), base_ang: wp.array(dtype=wp.vec3d),
           free_lin: wp.array(dtype=wp.vec3d), free_ang: wp.array(dtype=wp.vec3d)):
    """An iteration starts from the step so far; its free correction is what is left of the free
    motion (the rigid equations are linear in ``d``)."""
    b = wp.tid()
    base_lin[b] = dx_lin[b]
    base_ang[b] = dx_ang[b]
    free_lin[b] = target_lin[b] - dx_lin[b]
    free_ang[b] = target_ang[b] - dx_ang[b]


@wp.kernel
def columns(j_row: wp.array(dtype=wp.int32), j_body: wp.array(dtype=wp.int32), j_lin: wp.array(dtype=wp.vec3d),
            j_ang: wp.array(dtype=wp.vec3d), column_of_row: wp.array(dtype=wp.int32),
            inv_mass: wp.array(dtype=wp.float64), inv_inertia_w: wp.array(dtype=wp.mat33d), keep: wp.float64,
            y_lin: wp.array2d(dtype=wp.vec3d), y_ang: wp.array2d(dtype=wp.vec3d)):
    """``Y[j, b] = keep M_b^-1 J_b^T`` of force row ``j``: the body's motion per unit force (the
    rigid counterpart of the compliance columns ``X``)."""
    e = wp.tid()
    b = j_body[e]
    if b < 0:
        return
    col = column_of_row[j_row[e]]
    if col < 0:
        return
    wp.atomic_add(y_lin, col, b, keep * inv_mass[b] * j_lin[e])
    wp.atomic_add(y_ang, col, b, keep * (inv_inertia_w[b] * j_ang[e]))


@wp.kernel
def compliance(j_row: wp.array(dtype=wp.int32), j_body: wp.array(dtype=wp.int32), j_lin: wp.array(dtype=wp.vec3d),
               j_ang: wp.array(dtype=wp.vec3d), y_lin: wp.array2d(dtype=wp.vec3d),
               y_ang: wp.array2d(dtype=wp.vec3d), rigid_world: wp.array(dtype=wp.int32),
               world_force_rows: wp.array(dtype=wp.int32), scale: wp.float64, W: wp.array2d(dtype=wp.float64)):
    """``W[r, j] += scale J_r Y[j]``: the rigid bodies' share of the compliance, one thread per
    entry over its world's force rows in use (an inert entry, an unused contact slot's, costs a
    test: the Grasper has 576 entries and 291 columns, of which about 100 are in use)."""
    e = wp.tid()
    b = j_body[e]
    if b < 0:
        return
    r = j_row[e]
    for j in range(world_force_rows[rigid_world[b]]):
        wp.atomic_add(W, r, j, scale * (wp.dot(j_lin[e], y_lin[j, b]) + wp.dot(j_ang[e], y_ang[j, b])))


@wp.kernel
def predict(j_row: wp.array(dtype=wp.int32), j_body: wp.array(dtype=wp.int32), j_lin: wp.array(dtype=wp.vec3d),
            j_ang: wp.array(dtype=wp.vec3d), free_lin: wp.array(dtype=wp.vec3d), free_ang: wp.array(dtype=wp.vec3d),
            delta_free: wp.array(dtype=wp.float64)):
    """``delta_free += J d_free``: the rows after the bodies' free motion."""
    e = wp.tid()
    b = j_body[e]
    if b < 0:
        return
    wp.atomic_add(delta_free, j_row[e], wp.dot(j_lin[e], free_lin[b]) + wp.dot(j_ang[e], free_ang[b]))


@wp.kernel
def correct(free_lin: wp.array(dtype=wp.vec3d), free_ang: wp.array(dtype=wp.vec3d),
            y_lin: wp.array2d(dtype=wp.vec3d), y_ang: wp.array2d(dtype=wp.vec3d), lam: wp.array(dtype=wp.float64),
            body_world: wp.array(dtype=wp.int32), world_row_start: wp.array(dtype=wp.int32),
            force_rows: wp.array(dtype=wp.int32), scale: wp.float64,
            e_lin: wp.array(dtype=wp.vec3d), e_ang: wp.array(dtype=wp.vec3d)):
    """The iteration's correction ``e = d_free + scale sum_j lambda_j Y[j]`` over the force rows
    of the body's world."""
    b = wp.tid()
    w = body_world[b]
    s = world_row_start[w]
    dl = free_lin[b]
    da = free_ang[b]
    for j in range(force_rows[w]):
        dl = dl + (scale * lam[s + j]) * y_lin[j, b]
        da = da + (scale * lam[s + j]) * y_ang[j, b]
    e_lin[b] = dl
    e_ang[b] = da


@wp.func
def turned(r: wp.quatd, d: wp.vec3d):
    """The orientation ``r`` turned by the rotation vector ``d`` (rad, world axes)."""
    angle = wp.length(d)
    if angle == wp.float64(0.0):
        return r
    return wp.normalize(wp.quat_from_axis_angle(d / angle, angle) * r)


@wp.kernel
def advance(p0: wp.array(dtype=wp.vec3d), r0: wp.array(dtype=wp.quatd), base_lin: wp.array(dtype=wp.vec3d),
            base_ang: wp.array(dtype=wp.vec3d), e_lin: wp.array(dtype=wp.vec3d), e_ang: wp.array(dtype=wp.vec3d),
            alpha: wp.array(dtype=wp.float64), body_world: wp.array(dtype=wp.int32), inv_h: wp.float64,
            dx_lin: wp.array(dtype=wp.vec3d), dx_ang: wp.array(dtype=wp.vec3d), p: wp.array(dtype=wp.vec3d),
            r: wp.array(dtype=wp.quatd), v: wp.array(dtype=wp.vec3d), w: wp.array(dtype=wp.vec3d),
            pose_p: wp.array(dtype=wp.vec3d), pose_r: wp.array(dtype=wp.quatd)):
    """``d = d_base + alpha_w e``; the pose and velocities it gives (also copied to ``pose_p``,
    ``pose_r``: the buffers the host reads)."""
    b = wp.tid()
    a = alpha[body_world[b]]
    dl = base_lin[b] + a * e_lin[b]
    da = base_ang[b] + a * e_ang[b]
    dx_lin[b] = dl
    dx_ang[b] = da
    p[b] = p0[b] + dl
    r[b] = turned(r0[b], da)
    v[b] = inv_h * dl
    w[b] = inv_h * da
    pose_p[b] = p[b]
    pose_r[b] = r[b]


@wp.kernel
def health(p: wp.array(dtype=wp.vec3d), r: wp.array(dtype=wp.quatd), body_world: wp.array(dtype=wp.int32),
           flag: wp.array(dtype=wp.int32)):
    """Count the bodies whose pose is not finite into ``flag`` of their world."""
    b = wp.tid()
    x, q = p[b], r[b]
    s = x[0] + x[1] + x[2] + q[0] + q[1] + q[2] + q[3]
    if not wp.isfinite(s):
        wp.atomic_add(flag, body_world[b], 1)


@wp.kernel
def inverse_inertia(r: wp.array(dtype=wp.quatd), inertia: wp.array(dtype=wp.mat33d),
                    inv_inertia_w: wp.array(dtype=wp.mat33d)):
    """The world inverse inertia at orientation ``r`` (each linearization's)."""
    b = wp.tid()
    inv_inertia_w[b] = world_inverse_inertia(r[b], inertia[b])
