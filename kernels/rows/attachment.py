"""Attachment rows: a soft node held at a point of a rigid body, one row per axis."""

import warp as wp

from .. import OPTIONS

wp.set_module_options(OPTIONS)


@wp.kernel
def attachment_rows(
    q: wp.array(dtype=wp.vec3d),
    node: wp.array(dtype=wp.int32),
    body: wp.array(dtype=wp.int32),
    local: wp.array(dtype=wp.vec3d),
    first_row: wp.array(dtype=wp.int32),
    body_p: wp.array(dtype=wp.vec3d),
    body_r: wp.array(dtype=wp.quatd),
    entry_offset: int,
    rigid_offset: int,
    delta: wp.array(dtype=wp.float64),
    h_row: wp.array(dtype=wp.int32),
    h_node: wp.array(dtype=wp.int32),
    h_coef: wp.array(dtype=wp.vec3d),
    j_row: wp.array(dtype=wp.int32),
    j_body: wp.array(dtype=wp.int32),
    j_lin: wp.array(dtype=wp.vec3d),
    j_ang: wp.array(dtype=wp.vec3d),
):
    """One thread per held node ``k``: rows ``first_row[k] + a`` (``a`` = x, y, z) measure
    ``delta = x_node - (p + R local)`` (m) along axis ``a``, the node's offset from its point on
    the body (``local`` in the body's frame). On the node the entry is the axis ``e_a``; on the
    body ``-e_a`` for its translation and ``-(R local) x e_a`` for its rotation vector, since a
    turn ``dtheta`` moves the point by ``dtheta x (R local)``."""
    k = wp.tid()
    b = body[k]
    arm = wp.quat_rotate(body_r[b], local[k])
    gap = q[node[k]] - (body_p[b] + arm)
    for a in range(3):
        row = first_row[k] + a
        e = entry_offset + 3 * k + a
        axis = wp.vec3d()
        axis[a] = wp.float64(1.0)
        delta[row] = gap[a]
        h_row[e] = row
        h_node[e] = node[k]
        h_coef[e] = axis
        j = rigid_offset + 3 * k + a
        j_row[j] = row
        j_body[j] = b
        j_lin[j] = -axis
        j_ang[j] = -wp.cross(arm, axis)
