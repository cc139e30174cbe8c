"""A body's contact with itself (``warpsoft/rows/contact.py``, records of kind ``SELF``).

A surface node ``p`` meets a surface triangle ``(a, b, c)`` of its own body that it is not a
corner of. The gap is measured from the triangle's nearest point ``y = wa xa + wb xb + wc xc``
along the face's outward normal ``n``: ``delta = n . (x_p - y)``, with ``H`` entries ``n`` on
``p`` and ``-w_i n`` on the triangle's nodes. The forces are equal and opposite: a self-contact
neither adds nor removes momentum. A body's surface BVH (single precision, ``wp.Mesh``) is
refitted to the nodes before each detection.
"""

import warp as wp

from .. import OPTIONS
from .closest import triangle_nearest

wp.set_module_options(OPTIONS)

CORNER = wp.constant(0.01)  # a nearest point with a weight above 1 - CORNER is at that corner (node to node)


@wp.kernel
def surface_points(q: wp.array(dtype=wp.vec3d), node: wp.array(dtype=wp.int32), points: wp.array(dtype=wp.vec3)):
    """``points[i] = q[node[i]]`` in single precision: the self-contact BVHs' vertices (m)."""
    i = wp.tid()
    x = q[node[i]]
    points[i] = wp.vec3(wp.float32(x[0]), wp.float32(x[1]), wp.float32(x[2]))


@wp.kernel
def surface_normals(q: wp.array(dtype=wp.vec3d), tri_nodes: wp.array(dtype=wp.vec3i),
                    normal: wp.array(dtype=wp.vec3d)):
    """``normal[i]`` (zeroed before) sums the area-weighted outward normals (m^2) of the surface
    triangles at node ``i``: which way the surface faces there."""
    t = wp.tid()
    tri = tri_nodes[t]
    a = q[tri[0]]
    n = wp.cross(q[tri[1]] - a, q[tri[2]] - a)
    for k in range(3):
        wp.atomic_add(normal, tri[k], n)


@wp.func
def triangle_point(q: wp.array(dtype=wp.vec3d), tri: wp.vec3i, w: wp.vec3d) -> wp.vec3d:
    """The point of triangle ``tri`` (node ids into ``q``) with barycentric weights ``w`` (m)."""
    return w[0] * q[tri[0]] + w[1] * q[tri[1]] + w[2] * q[tri[2]]


@wp.func
def search_box(x: wp.vec3d, reach: wp.float64, h: wp.float64, speed: wp.float64):
    """The box (single precision, the BVH's) searched around a point ``x`` (m) moving at
    ``speed`` (m/s): within ``reach + 2 h speed`` of it, widened by 1 % and 0.1 um for the
    rounding to single precision."""
    pad = wp.float32(reach + wp.float64(2.0) * h * speed) * wp.float32(1.01) + wp.float32(1e-7)
    xf = wp.vec3(wp.float32(x[0]), wp.float32(x[1]), wp.float32(x[2]))
    return xf - wp.vec3(pad, pad, pad), xf + wp.vec3(pad, pad, pad)


@wp.func
def self_gap(x: wp.vec3d, a: wp.vec3d, b: wp.vec3d, c: wp.vec3d):
    """Signed gap (m) of point ``x`` to triangle ``abc`` (outward: counter-clockwise seen from
    outside) along its outward face normal ``n``, from the triangle's nearest point (negative
    behind it: inside the body), the normal, the nearest point's barycentric weights, and the
    distance to that point (m). The face's normal even beside the face: two surfaces meeting
    node to node would otherwise take the direction of an offset that is rounding noise."""
    w, inside = triangle_nearest(x, a, b, c)
    n = wp.normalize(wp.cross(b - a, c - a))
    d = x - (w[0] * a + w[1] * b + w[2] * c)
    return wp.dot(d, n), n, w, wp.length(d)


@wp.func
def may_touch(q: wp.array(dtype=wp.vec3d), v: wp.array(dtype=wp.vec3d), tri: wp.vec3i, x: wp.vec3d,
              facing: wp.vec3d, speed: wp.float64, reach: wp.float64, h: wp.float64):
    """Whether a point ``x`` (m) moving at ``speed`` (m/s), its surface facing ``facing``, may
    touch triangle ``tri`` (node ids into ``q``, velocities ``v``) this step: they face each
    other, its signed gap is above ``-reach`` (deeper behind it is across the body) and below
    ``reach`` plus what both can close in the step ``h`` (s), and it lies over the face or
    within ``reach`` of it along the face (beyond a convex edge, below the plane's extension,
    is outside the body); and the weights of the triangle's nearest point and the distance to
    it (m)."""
    xa = q[tri[0]]
    if wp.dot(facing, wp.cross(q[tri[1]] - xa, q[tri[2]] - xa)) >= wp.float64(0.0):  # not facing
        return False, wp.vec3d(), wp.float64(1e300)
    gap, n, w, dist = self_gap(x, xa, q[tri[1]], q[tri[2]])
    closing = h * (speed + wp.max(wp.length(v[tri[0]]), wp.max(wp.length(v[tri[1]]), wp.length(v[tri[2]]))))
    beside = wp.sqrt(wp.max(dist * dist - gap * gap, wp.float64(0.0)))  # along the face, past its edge
    return gap > -reach and dist < reach + closing and beside < reach, w, dist


@wp.func
def self_nearest(mesh: wp.uint64, tri0: int, tri_nodes: wp.array(dtype=wp.vec3i), q: wp.array(dtype=wp.vec3d),
                 v: wp.array(dtype=wp.vec3d), normal: wp.array(dtype=wp.vec3d), rest: wp.array(dtype=wp.vec3d),
                 node: int, reach: wp.float64, apart: wp.float64, h: wp.float64):
    """The surface triangle (index into ``tri_nodes``; -1 for none) nearest to surface node ``node`` among
    its body's others that it may touch this step, and the distance to it (m).

    Others: not a triangle it is a corner of, nor one within ``apart`` (m) of it in the rest shape
    ``rest`` (a neighbour: the faces at a corner, a thin wall's two sides). Facing: the surface at
    the node (``normal``, from :func:`surface_normals`) and the triangle face each other (a node on
    a face's rim is not in contact with the face beside it in the same plane, but with the one it
    presses on). May touch: its signed gap is above ``-reach`` (a node deeper behind a triangle is
    across the body, not in contact) and below ``reach`` plus what the node and the triangle can
    close in the step (``h`` (s) times their speeds ``v``, m/s), so that fast surfaces are caught
    before they pass through each other; and the node lies over the face, or within ``reach`` of it
    along the face (beyond a convex edge, below the plane's extension, is outside the body).

    Node to node (the triangle's nearest point is at its corner ``k``, within :data:`CORNER`), the
    pair is kept by the lower node id alone: ``k``'s own row would be nearly the same row, and two
    such rows make the contact problem degenerate. The BVH is searched within ``reach + 2 h
    |v_node|`` of the node: a fast triangle is caught by its own nodes' searches."""
    x = q[node]
    speed = wp.length(v[node])
    lower, upper = search_box(x, reach, h, speed)
    query = wp.mesh_query_aabb(mesh, lower, upper)
    face = wp.int32(0)
    best = wp.int32(-1)
    best_dist = wp.float64(1e300)
    while wp.mesh_query_aabb_next(query, face):
        t = tri0 + face
        tri = tri_nodes[t]
        if tri[0] == node or tri[1] == node or tri[2] == node:
            continue
        near, w, dist = may_touch(q, v, tri, x, normal[node], speed, reach, h)
        if not near or dist >= best_dist:
            continue
        near_one = wp.float64(1.0 - CORNER)
        corner = wp.where(w[0] > near_one, tri[0], wp.where(w[1] > near_one, tri[1], wp.where(w[2] > near_one, tri[2],
                                                                                              -1)))
        if corner >= 0 and corner < node:  # node to node: that node's own row (to ours) measures the same gap
            continue
        rest_gap, rest_n, rest_w, rest_dist = self_gap(rest[node], rest[tri[0]], rest[tri[1]], rest[tri[2]])
        if rest_dist < apart:  # neighbours in the rest shape
            continue
        best = t
        best_dist = dist
    return best, best_dist
