"""Kernels of the implicit step's Newton iterations (see ``warpsoft/newton.py``).

Iteration ``k`` linearizes at ``q_k = q0 + dx_k`` and solves ``A_k e = r_k`` for the correction,
where ``r_k`` is the step's out-of-balance at ``dx_k`` without the rows' forces:

    r(dx) = P( c_v M v0 + c_f (f_int(q0 + dx) + f_ext) + c_0 (f_int(q0) + f_ext) - mass_scale M dx - c_d K dx )

with ``(c_v, c_f, c_0) = (h, k^2 h^2, (k - k^2) h^2)`` in a dynamic step (kg m), ``(0, 1, 0)``
quasi-static (N), and ``c_d = k h b`` the Rayleigh stiffness damping (0 quasi-static); ``k`` is
the share of the step's end in its forces: 1 for implicit Euler, 1/2 for the trapezoid (whose
``dx = h (v0 + v1) / 2`` and ``M (v1 - v0) = h (f0 + f1) / 2`` give the line above). At ``dx = 0`` it is the step's
usual right-hand side. The nonlinear residual adds the rows' forces, ``R = r + s H^T lambda``
(``H^T lambda`` formed from the rows' entries, ``Rows.force_rows_forces``).
"""

import warp as wp

from . import OPTIONS
from .linear.pcg import block_add, block_world, node_add

wp.set_module_options(OPTIONS)

SLOPE = wp.constant(0)  # sums[0, w, SLOPE]: R . e, e the iteration's correction
NUM_SUMS = 1


@wp.kernel
def residual(
    v0: wp.array(dtype=wp.vec3d),
    mass: wp.array(dtype=wp.float64),
    f_int: wp.array(dtype=wp.vec3d),
    f_ext: wp.array(dtype=wp.vec3d),
    f_start: wp.array(dtype=wp.vec3d),
    kdx: wp.array(dtype=wp.vec3d),
    dx: wp.array(dtype=wp.vec3d),
    mask: wp.array(dtype=wp.vec3d),
    c_v: wp.float64,
    c_f: wp.float64,
    mass_scale: wp.float64,
    row_forces: wp.array(dtype=wp.vec3d),
    s: wp.float64,
    e: wp.array(dtype=wp.vec3d),
    world: wp.array(dtype=wp.int32),
    rhs: wp.array2d(dtype=wp.vec3d),
    sums: wp.array3d(dtype=wp.float64),
):
    """``rhs[0] = r(dx)`` (the next solve's right-hand side) and, per world, ``R . e`` where
    ``row_forces = H_f^T lambda`` (N) are the rows' forces at the same positions (``sums`` zeroed
    before). ``kdx`` is ``c_d K dx`` (zero without stiffness damping); ``mass`` is zero in a
    quasi-static model; ``f_start`` is ``c_0 (f_int(q0) + f_ext)`` (kg m; empty when ``c_0 = 0``)."""
    c, blk, lane = wp.tid()
    i0, i1, w, uniform = block_world(blk, rhs.shape[1], world)
    re = wp.float64(0.0)
    i = i0 + lane
    while i < i1:
        p = mask[i]
        wi = world[i]
        b = wp.cw_mul(p, (c_v * mass[i]) * v0[i] - (mass_scale * mass[i]) * dx[i] + c_f * (f_int[i] + f_ext[i])
                      - kdx[i])
        if f_start.shape[0] > 0:
            b += wp.cw_mul(p, f_start[i])
        rhs[0, i] = b
        r = b + s * wp.cw_mul(p, row_forces[i])
        re = node_add(uniform, re, wp.dot(r, e[i]), sums, c, wi, SLOPE)
        i += wp.block_dim()
    block_add(re, lane, uniform, sums, c, w, SLOPE)


@wp.kernel
def start(v0: wp.array(dtype=wp.vec3d), mass: wp.array(dtype=wp.float64), f_int: wp.array(dtype=wp.vec3d),
          f_ext: wp.array(dtype=wp.vec3d), mask: wp.array(dtype=wp.vec3d), c_v: wp.float64, c_f: wp.float64,
          c_0: wp.float64, rhs: wp.array2d(dtype=wp.vec3d), f_start: wp.array(dtype=wp.vec3d)):
    """``rhs[0] = r(0) = P(c_v M v0 + (c_f + c_0) (f_int + f_ext))``: the step's first right-hand
    side, the forces at the step's start; ``f_start = c_0 (f_int + f_ext)`` when ``c_0 != 0``."""
    i = wp.tid()
    f = f_int[i] + f_ext[i]
    if f_start.shape[0] > 0:
        f_start[i] = c_0 * f
    rhs[0, i] = wp.cw_mul(mask[i], (c_v * mass[i]) * v0[i] + (c_f + c_0) * f)


@wp.kernel
def slope(
    rhs: wp.array2d(dtype=wp.vec3d),
    mask: wp.array(dtype=wp.vec3d),
    row_forces: wp.array(dtype=wp.vec3d),
    s: wp.float64,
    e: wp.array(dtype=wp.vec3d),
    world: wp.array(dtype=wp.int32),
    sums: wp.array3d(dtype=wp.float64),
):
    """``sums[0, w, SLOPE] = (r + s H^T lambda) . e`` at the iteration's linearization (``rhs[0]``:
    its right-hand side; ``row_forces = H_f^T lambda`` (N), ``lambda`` the resolve's): ``e . A e``,
    the energy of the correction, which ``R . e`` after the step is measured against (``sums``
    zeroed before)."""
    c, blk, lane = wp.tid()
    i0, i1, w, uniform = block_world(blk, rhs.shape[1], world)
    re = wp.float64(0.0)
    i = i0 + lane
    while i < i1:
        f = rhs[0, i] + s * row_forces[i]
        re = node_add(uniform, re, wp.dot(wp.cw_mul(mask[i], f), e[i]), sums, c, world[i], SLOPE)
        i += wp.block_dim()
    block_add(re, lane, uniform, sums, c, w, SLOPE)


@wp.kernel
def update(q0: wp.array(dtype=wp.vec3d), v0: wp.array(dtype=wp.vec3d), dx_base: wp.array(dtype=wp.vec3d),
           e: wp.array(dtype=wp.vec3d), alpha: wp.array(dtype=wp.float64), world: wp.array(dtype=wp.int32),
           inv_kh: wp.float64, keep_v: wp.float64, dx: wp.array(dtype=wp.vec3d), q: wp.array(dtype=wp.vec3d),
           v: wp.array(dtype=wp.vec3d)):
    """``dx = dx_base + alpha_w e``, ``q = q0 + dx``, ``v = dx / (k h) - keep_v v0`` (implicit
    Euler ``dx / h``, the trapezoid ``2 dx / h - v0``; ``inv_kh = 0`` quasi-static)."""
    i = wp.tid()
    d = dx_base[i] + alpha[world[i]] * e[i]
    dx[i] = d
    q[i] = q0[i] + d
    vel = inv_kh * d
    if keep_v != wp.float64(0.0):
        vel -= keep_v * v0[i]
    v[i] = vel


@wp.kernel
def blend_multipliers(base: wp.array(dtype=wp.float64), full: wp.array(dtype=wp.float64),
                      alpha: wp.array(dtype=wp.float64), row_world: wp.array(dtype=wp.int32),
                      lam: wp.array(dtype=wp.float64)):
    """``lam = base + alpha_w (full - base)``: the multipliers along the same fraction of the step."""
    r = wp.tid()
    a = alpha[row_world[r]]
    lam[r] = base[r] + a * (full[r] - base[r])


@wp.kernel
def hold_done_worlds(alpha: wp.array(dtype=wp.float64), world: wp.array(dtype=wp.int32),
                     rhs: wp.array2d(dtype=wp.vec3d), x: wp.array2d(dtype=wp.vec3d)):
    """A world done iterating (``alpha = 0``) needs no correction: its right-hand side and start
    are 0, which its CG columns take as solved at once."""
    i = wp.tid()
    if alpha[world[i]] == wp.float64(0.0):
        rhs[0, i] = wp.vec3d()
        x[0, i] = wp.vec3d()


@wp.kernel
def moved(q: wp.array(dtype=wp.vec3d), q_lin: wp.array(dtype=wp.vec3d), flag: wp.array(dtype=wp.int32)):
    """``flag[0] = 1`` when some node of ``q`` is not where the last linearization was made
    (``flag`` zeroed before): the state was changed from outside the step."""
    i = wp.tid()
    a, b = q[i], q_lin[i]
    if not (a[0] == b[0] and a[1] == b[1] and a[2] == b[2]):  # NaN differs from everything
        flag[0] = 1


@wp.kernel
def prescribed_slope(e: wp.array(dtype=wp.vec3d), d: wp.array(dtype=wp.vec3d), a_d: wp.array2d(dtype=wp.vec3d),
                     world: wp.array(dtype=wp.int32), sums: wp.array3d(dtype=wp.float64)):
    """The first iteration's energy with the kinematic frames' prescribed move ``d`` (``a_d = A d``)
    counted in: ``(d + e) . A (d + e) = e . A e + (2 e + d) . A d`` (``e`` is 0 where ``d`` is
    not). Measured against ``e`` alone, a frame's move would look like a large deformation and
    let a step go unconverged."""
    i = wp.tid()
    wp.atomic_add(sums, 0, world[i], SLOPE, wp.dot(wp.float64(2.0) * e[i] + d[i], a_d[0, i]))


NUM_MOMENTS = 15  # moments[w, :]: sum m x (3), sum m x x^T (xx, yy, zz, xy, xz, yz), sum m e (3), sum m x x e (3)


@wp.kernel
def rigid_moments(
    q: wp.array(dtype=wp.vec3d),
    mass: wp.array(dtype=wp.float64),
    e: wp.array(dtype=wp.vec3d),
    world: wp.array(dtype=wp.int32),
    free: wp.array(dtype=wp.int32),
    moments: wp.array2d(dtype=wp.float64),
):
    """The mass moments of the positions ``q`` (m) and of the correction ``e`` (m) of the nodes
    of the worlds free to move as a whole (``free[w]``), from which the host takes the rigid
    motion that fits ``e`` best (``moments`` zeroed before)."""
    i = wp.tid()
    w = world[i]
    if free[w] == 0:
        return
    m = mass[i]
    x = q[i]
    d = e[i]
    c = wp.cross(x, d)
    for k in range(3):
        wp.atomic_add(moments, w, k, m * x[k])
        wp.atomic_add(moments, w, 3 + k, m * x[k] * x[k])
        wp.atomic_add(moments, w, 9 + k, m * d[k])
        wp.atomic_add(moments, w, 12 + k, m * c[k])
    wp.atomic_add(moments, w, 6, m * x[0] * x[1])
    wp.atomic_add(moments, w, 7, m * x[0] * x[2])
    wp.atomic_add(moments, w, 8, m * x[1] * x[2])
