"""Barycentric mappings: points carried by tetrahedra (probes, cable and effector points)."""

import warp as wp

from .. import OPTIONS

wp.set_module_options(OPTIONS)


@wp.kernel
def interpolate_points(
    q: wp.array(dtype=wp.vec3d),
    nodes: wp.array(dtype=wp.vec4i),
    weights: wp.array(dtype=wp.vec4d),
    out: wp.array(dtype=wp.vec3d),
):
    """``out[p] = sum_k weights[p][k] q[nodes[p][k]]`` (m)."""
    p = wp.tid()
    n = nodes[p]
    w = weights[p]
    out[p] = w[0] * q[n[0]] + w[1] * q[n[1]] + w[2] * q[n[2]] + w[3] * q[n[3]]
