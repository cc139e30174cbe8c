"""Right-hand sides of the linearized step and the state update (implicit Euler)."""

import warp as wp


@wp.kernel
def rhs_dynamic(
    v: wp.array(dtype=wp.vec3d),
    mass: wp.array(dtype=wp.float64),
    f_int: wp.array(dtype=wp.vec3d),
    f_ext: wp.array(dtype=wp.vec3d),
    h: wp.float64,
    mask: wp.array(dtype=wp.vec3d),
    b: wp.array(dtype=wp.vec3d),
):
    """``b = P(h M v + h^2 (f_int + f_ext))`` in kg m (``A`` is in kg, ``dx`` in m)."""
    i = wp.tid()
    b[i] = wp.cw_mul(mask[i], (h * mass[i]) * v[i] + (h * h) * (f_int[i] + f_ext[i]))


@wp.kernel
def rhs_static(f_int: wp.array(dtype=wp.vec3d), f_ext: wp.array(dtype=wp.vec3d), mask: wp.array(dtype=wp.vec3d),
               b: wp.array(dtype=wp.vec3d)):
    """``b = P(f_int + f_ext)`` (N): the out-of-balance force of the quasi-static step."""
    i = wp.tid()
    b[i] = wp.cw_mul(mask[i], f_int[i] + f_ext[i])


@wp.kernel
def advance(q: wp.array(dtype=wp.vec3d), dx: wp.array(dtype=wp.vec3d), inv_h: wp.float64,
            q_out: wp.array(dtype=wp.vec3d), v_out: wp.array(dtype=wp.vec3d)):
    """``q_out = q + dx``, ``v_out = dx / h`` (``inv_h = 0`` in a quasi-static step)."""
    i = wp.tid()
    q_out[i] = q[i] + dx[i]
    v_out[i] = inv_h * dx[i]


@wp.kernel
def kinetic_energy(v: wp.array(dtype=wp.vec3d), mass: wp.array(dtype=wp.float64),
                   energy: wp.array(dtype=wp.float64)):
    """``energy[0] += 1/2 m v.v`` (J)."""
    i = wp.tid()
    wp.atomic_add(energy, 0, wp.float64(0.5) * mass[i] * wp.dot(v[i], v[i]))
