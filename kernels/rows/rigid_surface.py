"""A rigid body's collision points against a soft body's surface triangles
(``warpsoft/rows/contact.py``, records of kind ``SURFACE``).

The other half of a contact between a rigid and a soft body: the soft body's surface nodes meet
the rigid body's solid (records the rigid body owns), and the rigid body's points meet the soft
body's triangles here, so that a corner or an edge of the solid pressing between the soft
body's nodes is caught too. The gap is the self-contact's (``self_contact.self_gap``): along
the triangle's outward normal ``n`` from its nearest point ``y = wa xa + wb xb + wc xc``,
``delta = n . (x_p - y)``, with the entries ``(n, r x n)`` on the point's body and ``-w_i n`` on
the triangle's nodes; the forces are equal and opposite.
"""

import warp as wp

from .. import OPTIONS
from .self_contact import may_touch, search_box

wp.set_module_options(OPTIONS)


@wp.func
def rigid_nearest(mesh: wp.uint64, tri0: int, tri_nodes: wp.array(dtype=wp.vec3i), q: wp.array(dtype=wp.vec3d),
                  v: wp.array(dtype=wp.vec3d), x: wp.vec3d, outward: wp.vec3d, speed: wp.float64, reach: wp.float64,
                  h: wp.float64):
    """The surface triangle (index into ``tri_nodes``; -1 for none) of a soft body nearest to a
    rigid body's point ``x`` (m) that the point may touch this step, and the distance to it (m).

    ``outward`` is the direction from the rigid body's centre of mass to the point (the way its
    convex solid faces there): a triangle that faces the same way is behind the point, not in
    front of it. The point may touch a triangle whose signed gap is above ``-reach`` (a point
    deeper behind it is across the soft body) and below ``reach`` plus what the point and the
    triangle can close in the step (``h`` (s) times the point's ``speed`` and the nodes' ``v``,
    m/s), and that it lies over, or within ``reach`` of along the face. A point whose nearest
    point is a triangle's corner keeps its row, though that node's own row against the rigid
    solid may bear too: handing the contact over to the node's row changed the gap by up to
    the corner's share times the edge times the angle between the two normals, and each
    hand-over pushed the bodies apart by that (a cube on a dented slab gained ~5e-8 J each)."""
    lower, upper = search_box(x, reach, h, speed)
    query = wp.mesh_query_aabb(mesh, lower, upper)
    face = wp.int32(0)
    best = wp.int32(-1)
    best_dist = wp.float64(1e300)
    while wp.mesh_query_aabb_next(query, face):
        t = tri0 + face
        tri = tri_nodes[t]
        near, w, dist = may_touch(q, v, tri, x, outward, speed, reach, h)
        if not near or dist >= best_dist:
            continue
        best = t
        best_dist = dist
    return best, best_dist
