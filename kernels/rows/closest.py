"""Nearest points on triangles (double precision), for mesh obstacles and self-contact."""

import warp as wp

from .. import OPTIONS

wp.set_module_options(OPTIONS)


@wp.func
def triangle_nearest(p: wp.vec3d, a: wp.vec3d, b: wp.vec3d, c: wp.vec3d):
    """The barycentric weights ``(wa, wb, wc)`` (summing to 1) of the point of triangle ``abc``
    nearest to ``p``, and whether it lies inside the face (not on an edge or a vertex): by the
    Voronoi region of ``p``, from the dot products of ``p``'s offsets with the two edges at ``a``."""
    zero = wp.float64(0.0)
    one = wp.float64(1.0)
    ab = b - a
    ac = c - a
    d1 = wp.dot(ab, p - a)
    d2 = wp.dot(ac, p - a)
    if d1 <= zero and d2 <= zero:
        return wp.vec3d(one, zero, zero), False
    d3 = wp.dot(ab, p - b)
    d4 = wp.dot(ac, p - b)
    if d3 >= zero and d4 <= d3:
        return wp.vec3d(zero, one, zero), False
    vc = d1 * d4 - d3 * d2
    if vc <= zero and d1 >= zero and d3 <= zero:  # edge ab
        t = d1 / (d1 - d3)
        return wp.vec3d(one - t, t, zero), False
    d5 = wp.dot(ab, p - c)
    d6 = wp.dot(ac, p - c)
    if d6 >= zero and d5 <= d6:
        return wp.vec3d(zero, zero, one), False
    vb = d5 * d2 - d1 * d6
    if vb <= zero and d2 >= zero and d6 <= zero:  # edge ac
        t = d2 / (d2 - d6)
        return wp.vec3d(one - t, zero, t), False
    va = d3 * d6 - d5 * d4
    if va <= zero and d4 - d3 >= zero and d5 - d6 >= zero:  # edge bc
        t = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        return wp.vec3d(zero, one - t, t), False
    inv = one / (va + vb + vc)  # the face
    return wp.vec3d(va * inv, vb * inv, vc * inv), True


@wp.func
def triangle_closest(p: wp.vec3d, a: wp.vec3d, b: wp.vec3d, c: wp.vec3d):
    """The point of triangle ``abc`` nearest to ``p`` (m), and whether it lies inside the face."""
    w, inside = triangle_nearest(p, a, b, c)
    return w[0] * a + w[1] * b + w[2] * c, inside
