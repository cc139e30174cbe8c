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
    points: wp.array(dtype=wp.vec3d),
    point_nodes: wp.array(dtype=wp.vec4i),
    point_weights: wp.array(dtype=wp.vec4d),
    start: wp.array(dtype=wp.int32),
    count: wp.array(dtype=wp.int32),
    pull: wp.array(dtype=wp.vec3d),
    rest_length: wp.array(dtype=wp.float64),
    row: wp.array(dtype=wp.int32),
    entry_offset: int,
    delta: wp.array(dtype=wp.float64),
    h_row: wp.array(dtype=wp.int32),
    h_node: wp.array(dtype=wp.int32),
    h_coef: wp.array(dtype=wp.vec3d),
):
    """One thread per cable. ``d delta / d p_j`` is the unit direction from ``p_j`` to the
    previous point plus the one to the next point; a tension pulls each point along them."""
    cab = wp.tid()
    s = start[cab]
    n = count[cab]
    r = row[cab]
    prev = pull[cab]
    length = wp.float64(0.0)
    for j in range(n):
        p = points[s + j]
        length += wp.length(p - prev)
        g = unit_or_zero(prev - p)
        if j + 1 < n:
            g = g + unit_or_zero(points[s + j + 1] - p)
        write_point_entries(h_row, h_node, h_coef, entry_offset + 4 * (s + j), r, point_nodes[s + j],
                            point_weights[s + j], g)
        prev = p
    delta[r] = rest_length[cab] - length
