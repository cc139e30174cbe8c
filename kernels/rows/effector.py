"""Effector rows: one per controlled axis of a mapped point."""

import warp as wp

from .. import OPTIONS
from .common import write_point_entries

wp.set_module_options(OPTIONS)


@wp.kernel
def effector_rows(
    points: wp.array(dtype=wp.vec3d),
    point_nodes: wp.array(dtype=wp.vec4i),
    point_weights: wp.array(dtype=wp.vec4d),
    point: wp.array(dtype=wp.int32),
    axis: wp.array(dtype=wp.int32),
    target: wp.array(dtype=wp.float64),
    row: wp.array(dtype=wp.int32),
    entry_offset: int,
    delta: wp.array(dtype=wp.float64),
    h_row: wp.array(dtype=wp.int32),
    h_node: wp.array(dtype=wp.int32),
    h_coef: wp.array(dtype=wp.vec3d),
):
    """One thread per effector axis: ``delta = x(p)[axis] - target`` (m), ``H`` = mapping weights."""
    k = wp.tid()
    p = point[k]
    ax = axis[k]
    r = row[k]
    delta[r] = points[p][ax] - target[k]
    unit = wp.vec3d()
    unit[ax] = wp.float64(1.0)
    write_point_entries(h_row, h_node, h_coef, entry_offset + 4 * k, r, point_nodes[p], point_weights[p], unit)
