"""Pneumatic cavity rows: ``delta = V - V0`` (m^3) of a closed surface, ``H = dV/dq`` (m^2)."""

import warp as wp

from .. import OPTIONS

wp.set_module_options(OPTIONS)


@wp.kernel
def cavity_rows(
    q: wp.array(dtype=wp.vec3d),
    tris: wp.array(dtype=wp.vec3i),
    tri_weight: wp.array(dtype=wp.float64),
    tri_row: wp.array(dtype=wp.int32),
    tri_origin: wp.array(dtype=wp.vec3d),
    entry_offset: int,
    delta: wp.array(dtype=wp.float64),
    h_row: wp.array(dtype=wp.int32),
    h_node: wp.array(dtype=wp.int32),
    h_coef: wp.array(dtype=wp.vec3d),
):
    """One thread per node triple (of a surface oriented out of the cavity): ``V = sum w a . (b x c)``
    with positions relative to the cavity's origin (``w = 1/6`` for a linear triangle),
    accumulated into ``delta`` (which holds ``-V0`` on entry); the exact gradient per node."""
    t = wp.tid()
    tri = tris[t]
    o = tri_origin[t]
    a = q[tri[0]] - o
    b = q[tri[1]] - o
    c = q[tri[2]] - o
    r = tri_row[t]
    w = tri_weight[t]
    wp.atomic_add(delta, r, w * wp.dot(a, wp.cross(b, c)))
    e = entry_offset + 3 * t
    h_row[e] = r
    h_row[e + 1] = r
    h_row[e + 2] = r
    h_node[e] = tri[0]
    h_node[e + 1] = tri[1]
    h_node[e + 2] = tri[2]
    h_coef[e] = w * wp.cross(b, c)
    h_coef[e + 1] = w * wp.cross(c, a)
    h_coef[e + 2] = w * wp.cross(a, b)

