"""Cable rows: ``delta = L0 - L`` (shortening, m) of the path pull point -> p_1 -> ... -> p_N."""

import warp as wp

from .. import OPTIONS
from .common import write_point_entries

wp.set_module_options(OPTIONS)

EPS_LENGTH = wp.constant(wp.float64(1e-12))  # m: a shorter segment has no direction (no NaN)


@wp.func
def unit_or_zero(v: wp.vec3d) -> wp.vec3d:
    n = wp.length(v)
    if n > EPS_LENGTH:
        return v / n
    return wp.vec3d()


@wp.kernel
def cable_rows(
    q: wp.array(dtype=wp.vec3d),
    points: wp.array(dtype=wp.vec3d),
    point_nodes: wp.array(dtype=wp.vec4i),
    point_weights: wp.array(dtype=wp.vec4d),
    start: wp.array(dtype=wp.int32),
    count: wp.array(dtype=wp.int32),
    pull: wp.array(dtype=wp.vec3d),
    rest_length: wp.array(dtype=wp.float64),
    row: wp.array(dtype=wp.int32),
    entry_offset: int,
    anchor_start: wp.array(dtype=wp.int32),
    anchor_count: wp.array(dtype=wp.int32),
    anchor_node: wp.array(dtype=wp.int32),
    anchor_weight: wp.array(dtype=wp.float64),
    anchor_offset: wp.array(dtype=wp.vec3d),
    anchor_entry: int,
    delta: wp.array(dtype=wp.float64),
    h_row: wp.array(dtype=wp.int32),
    h_node: wp.array(dtype=wp.int32),
    h_coef: wp.array(dtype=wp.vec3d),
):
    """One thread per cable. ``d delta / d p_j`` is the unit direction from ``p_j`` to the
    previous point plus the one to the next point; a tension pulls each point along them. A cable
    with an anchor (``anchor_count > 0``) ends at ``anchor_offset + sum_k w_k q[node_k]``, the mean
    motion of the material around its last point: that point's tetrahedron entries are zero and
    its anchor's entries ``anchor_entry + anchor_start ..`` carry the pull."""
    cab = wp.tid()
    s = start[cab]
    n = count[cab]
    r = row[cab]
    a0 = anchor_start[cab]
    na = anchor_count[cab]
    end = points[s + n - 1]  # the last point: mapped, or its anchor's mean position
    if na > 0:
        end = anchor_offset[cab]
        for k in range(na):
            end = end + anchor_weight[a0 + k] * q[anchor_node[a0 + k]]
    prev = pull[cab]
    length = wp.float64(0.0)
    for j in range(n):
        p = points[s + j]
        if j + 1 == n:
            p = end
        anchored = j + 1 == n and na > 0
        length += wp.length(p - prev)
        g = unit_or_zero(prev - p)
        if j + 2 < n:
            g = g + unit_or_zero(points[s + j + 1] - p)
        elif j + 2 == n:
            g = g + unit_or_zero(end - p)
        if anchored:
            write_point_entries(h_row, h_node, h_coef, entry_offset + 4 * (s + j), r, point_nodes[s + j],
                                point_weights[s + j], wp.vec3d())
            for k in range(na):
                e = anchor_entry + a0 + k
                h_row[e] = r
                h_node[e] = anchor_node[a0 + k]
                h_coef[e] = anchor_weight[a0 + k] * g
        else:
            write_point_entries(h_row, h_node, h_coef, entry_offset + 4 * (s + j), r, point_nodes[s + j],
                                point_weights[s + j], g)
        prev = p
    delta[r] = rest_length[cab] - length
