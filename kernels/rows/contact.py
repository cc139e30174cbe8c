"""Contact rows against rigid solids: obstacles (analytic or triangle meshes) and rigid bodies
(``warpsoft/rows/contact.py``).

A candidate is a (point, solid record) pair of one world; candidates are grouped by world. A
point is a soft body's surface node or a rigid body's collision point; a record is an obstacle's
solid or a rigid body's (its ``owner``), posed from the body's state before each use. Detection
marks the candidates within their record's contact distance, then gives each world's marked
candidates, in candidate order (deterministic), the world's contact slots up to its capacity.
A slot's row measures the gap ``delta = phi(x)`` (m, the solid's signed distance) with
``H = n`` (its outward normal) at a soft point, and on the rigid bodies involved the entries
``(n, r x n)`` for the point's body and ``(-n, -r x n)`` for the owner (``r`` from each
body's centre of mass); an unused slot's row is inert (no entry, ``delta = 0``). Against a soft
body's triangles (its own surface nodes, ``SELF``, or a rigid body's points, ``SURFACE``) the
row is measured from the triangle's nearest point and has entries on its three nodes too.
"""

import warp as wp

from .. import OPTIONS
from .closest import triangle_closest, triangle_nearest
from .rigid_surface import rigid_nearest
from .self_contact import self_gap, self_nearest, triangle_point

wp.set_module_options(OPTIONS)

FLOOR = wp.constant(0)
BALL = wp.constant(1)
BOX = wp.constant(2)
CAPSULE = wp.constant(3)
CYLINDER = wp.constant(4)
MESH = wp.constant(5)
SELF = wp.constant(6)  # a body's own surface (self_contact.py): a, b, rot unused, radius the rest-shape apart distance
SURFACE = wp.constant(7)  # a soft body's surface met by rigid points (rigid_surface.py): a, b, radius, rot unused


@wp.func
def away(d: wp.vec3d, radius: wp.float64):
    """``|d| - radius`` and the direction of ``d`` (up when ``d`` is 0): the distance to a ball
    of ``radius`` around the point ``d`` points away from, and its outward normal."""
    length = wp.length(d)
    n = wp.vec3d(wp.float64(0.0), wp.float64(0.0), wp.float64(1.0))
    if length > wp.float64(0.0):
        n = d / length
    return length - radius, n


@wp.func
def point_distance(x: wp.vec3d, c: wp.vec3d, radius: wp.float64):
    """Distance to the point ``c`` minus ``radius``, and the outward normal."""
    return away(x - c, radius)


@wp.func
def segment_distance(x: wp.vec3d, a: wp.vec3d, b: wp.vec3d, radius: wp.float64):
    """Distance to the segment ``ab`` minus ``radius``, and the outward normal."""
    ab = b - a
    t = wp.clamp(wp.dot(x - a, ab) / wp.dot(ab, ab), wp.float64(0.0), wp.float64(1.0))
    return away(x - (a + t * ab), radius)


@wp.func
def box_distance(x: wp.vec3d, center: wp.vec3d, half: wp.vec3d, rot: wp.mat33d):
    """Signed distance to the box and its outward normal (the nearest face's inside)."""
    p = wp.transpose(rot) * (x - center)
    q = wp.vec3d(wp.abs(p[0]) - half[0], wp.abs(p[1]) - half[1], wp.abs(p[2]) - half[2])
    outside = wp.vec3d(wp.max(q[0], wp.float64(0.0)), wp.max(q[1], wp.float64(0.0)), wp.max(q[2], wp.float64(0.0)))
    dist = wp.length(outside)
    n_local = wp.vec3d()
    if dist > wp.float64(0.0):
        n_local = wp.vec3d(wp.sign(p[0]) * outside[0], wp.sign(p[1]) * outside[1], wp.sign(p[2]) * outside[2]) / dist
    else:  # inside: the face nearest to the point
        k = wp.int32(0)
        if q[1] > q[k]:
            k = wp.int32(1)
        if q[2] > q[k]:
            k = wp.int32(2)
        dist = q[k]
        n_local[k] = wp.sign(p[k])
    return dist, rot * n_local


@wp.func
def cylinder_distance(x: wp.vec3d, a: wp.vec3d, b: wp.vec3d, radius: wp.float64):
    """Signed distance to the flat-ended cylinder on axis ``ab`` and its outward normal."""
    axis = b - a
    half = wp.float64(0.5) * wp.length(axis)
    u = wp.normalize(axis)
    rel = x - wp.float64(0.5) * (a + b)
    along = wp.dot(rel, u)
    radial_v = rel - along * u
    radial = wp.length(radial_v)
    e = wp.vec3d()
    if radial > wp.float64(0.0):
        e = radial_v / radial
    else:  # on the axis: any direction across it
        e = wp.normalize(wp.cross(u, wp.vec3d(wp.float64(1.0), wp.float64(0.0), wp.float64(0.0))))
        if wp.length(wp.cross(u, wp.vec3d(wp.float64(1.0), wp.float64(0.0), wp.float64(0.0)))) < wp.float64(1e-6):
            e = wp.normalize(wp.cross(u, wp.vec3d(wp.float64(0.0), wp.float64(1.0), wp.float64(0.0))))
    qr = radial - radius
    qa = wp.abs(along) - half
    s = wp.sign(along)
    if qr > wp.float64(0.0) and qa > wp.float64(0.0):  # beyond the rim
        d = wp.sqrt(qr * qr + qa * qa)
        return d, (qr * e + qa * s * u) / d
    if qr > qa:
        return qr, e
    return qa, s * u


@wp.func
def mesh_distance(x: wp.vec3d, origin: wp.vec3d, rot: wp.mat33d, mesh: wp.uint64, tri0: int,
                  tri_xyz: wp.array2d(dtype=wp.vec3d)):
    """Signed distance to a triangle mesh posed by ``(rot, origin)``, and its outward normal: the
    BVH (single precision) finds the nearest triangle; the distance to it is computed again in
    double from its vertices ``tri_xyz[tri0 + face]``. Nearest to the face's inside, the distance
    is to its plane, signed by its outward normal (exact even on the surface, where the offset's
    own direction is rounding noise); nearest to an edge or a vertex, the BVH's angle-weighted
    pseudo-normal gives the sign and the offset the normal (the face's within 1e-6 of an edge's
    length of the surface)."""
    p = wp.transpose(rot) * (x - origin)
    up = wp.vec3d(wp.float64(0.0), wp.float64(0.0), wp.float64(1.0))
    query = wp.mesh_query_point_sign_normal(mesh, wp.vec3(wp.float32(p[0]), wp.float32(p[1]), wp.float32(p[2])),
                                            wp.float32(1.0e6))
    if not query.result:
        return wp.float64(1.0e6), up
    t = tri0 + query.face
    a = tri_xyz[t, 0]
    b = tri_xyz[t, 1]
    c = tri_xyz[t, 2]
    n = wp.normalize(wp.cross(b - a, c - a))
    closest, inside_face = triangle_closest(p, a, b, c)
    if inside_face:
        return wp.dot(p - a, n), rot * n
    d = p - closest
    dist = wp.length(d)
    sign = wp.where(query.sign < wp.float32(0.0), wp.float64(-1.0), wp.float64(1.0))
    if dist > wp.float64(1e-6) * wp.length(b - a):  # nearer, the offset's direction is rounding noise:
        n = sign * d / dist  # (the face's normal then, and the sign within single precision of the surface)
    return sign * dist, rot * n


@wp.func
def obstacle_distance(kind: int, a: wp.vec3d, b: wp.vec3d, radius: wp.float64, rot: wp.mat33d, mesh: wp.uint64,
                      tri0: int, tri_xyz: wp.array2d(dtype=wp.vec3d), x: wp.vec3d):
    """Signed distance (m, negative inside) of ``x`` to an obstacle, and its outward normal."""
    if kind == MESH:  # a: its origin, rot: its rotation; its triangles from tri0 in tri_xyz
        return mesh_distance(x, a, rot, mesh, tri0, tri_xyz)
    if kind == FLOOR:  # a: a point of its top plane, b: the upward normal
        return wp.dot(x - a, b), b
    if kind == BALL:
        return point_distance(x, a, radius)
    if kind == BOX:  # a: centre, b: half sizes
        return box_distance(x, a, b, rot)
    if kind == CAPSULE:
        return segment_distance(x, a, b, radius)
    return cylinder_distance(x, a, b, radius)


@wp.struct
class Obstacles:
    """Every (obstacle, body) record of the model, one entry each: its kind, two points ``a``,
    ``b`` (m), radius (m) and rotation (world from local), as ``obstacle_distance`` reads them;
    for a mesh its BVH id and first triangle in ``tri_xyz`` (all meshes' triangles, ``(t, 3)``
    vertices in double); ``reach`` the contact distance (m). Soft-surface records (``SELF``,
    ``SURFACE``) have a BVH of their body's surface and their first triangle in ``tri_nodes``
    (the surface triangles of every soft body met so, global node ids); a ``SELF`` record has in
    ``radius`` the distance (m) within which a node and a triangle of the rest shape ``rest``
    (``(n,)`` m) are neighbours; a ``SURFACE`` record has in ``partner`` the record of the same
    rigid body's solid met by the same soft body's nodes (-1 for other kinds)."""

    kind: wp.array(dtype=wp.int32)
    a: wp.array(dtype=wp.vec3d)
    b: wp.array(dtype=wp.vec3d)
    radius: wp.array(dtype=wp.float64)
    rot: wp.array(dtype=wp.mat33d)
    mesh: wp.array(dtype=wp.uint64)
    tri0: wp.array(dtype=wp.int32)
    tri_xyz: wp.array2d(dtype=wp.vec3d)
    reach: wp.array(dtype=wp.float64)
    tri_nodes: wp.array(dtype=wp.vec3i)
    rest: wp.array(dtype=wp.vec3d)
    partner: wp.array(dtype=wp.int32)


@wp.func
def record_distance(obstacles: Obstacles, o: int, x: wp.vec3d):
    """``obstacle_distance`` of record ``o``."""
    return obstacle_distance(obstacles.kind[o], obstacles.a[o], obstacles.b[o], obstacles.radius[o], obstacles.rot[o],
                             obstacles.mesh[o], obstacles.tri0[o], obstacles.tri_xyz, x)


@wp.struct
class Points:
    """The candidates' points: a soft node (``node >= 0``) or a rigid body's collision point
    (``body >= 0``, ``local`` in the body's frame, m); ``obstacle`` the record each meets."""

    node: wp.array(dtype=wp.int32)
    body: wp.array(dtype=wp.int32)
    local: wp.array(dtype=wp.vec3d)
    obstacle: wp.array(dtype=wp.int32)


@wp.struct
class Bodies:
    """The rigid bodies' state the rows are evaluated at (``(bodies,)``; 1 inert entry without
    bodies): centres of mass ``p`` (m), orientations ``r``, velocities ``v`` (m/s), ``w`` (rad/s)."""

    p: wp.array(dtype=wp.vec3d)
    r: wp.array(dtype=wp.quatd)
    v: wp.array(dtype=wp.vec3d)
    w: wp.array(dtype=wp.vec3d)


@wp.func
def point_at(points: Points, bodies: Bodies, q: wp.array(dtype=wp.vec3d), c: int):
    """Where candidate ``c``'s point is (m)."""
    b = points.body[c]
    if b >= 0:
        return bodies.p[b] + wp.quat_rotate(bodies.r[b], points.local[c])
    return q[points.node[c]]


@wp.func
def body_speed(bodies: Bodies, b: int, x: wp.vec3d):
    """Speed (m/s) of the point ``x`` carried by rigid body ``b`` (0 for ``b < 0``)."""
    if b < 0:
        return wp.float64(0.0)
    return wp.length(bodies.v[b] + wp.cross(bodies.w[b], x - bodies.p[b]))


@wp.kernel
def pose_records(owned: wp.array(dtype=wp.int32), owner: wp.array(dtype=wp.int32), a_loc: wp.array(dtype=wp.vec3d),
                 b_loc: wp.array(dtype=wp.vec3d), rot_loc: wp.array(dtype=wp.mat33d), bodies: Bodies,
                 obstacles: Obstacles):
    """The solids of rigid bodies (records ``owned``) where their bodies are: their record in the
    body's frame carried by its pose (a capsule's or cylinder's ``b`` is a point, a box's its
    half sizes)."""
    k = wp.tid()
    o = owned[k]
    b = owner[o]
    rot = wp.quat_to_matrix(bodies.r[b])
    obstacles.a[o] = rot * a_loc[o] + bodies.p[b]
    kind = obstacles.kind[o]
    if kind == CAPSULE or kind == CYLINDER:
        obstacles.b[o] = rot * b_loc[o] + bodies.p[b]
    else:
        obstacles.b[o] = b_loc[o]
    obstacles.rot[o] = rot * rot_loc[o]


@wp.func
def flat_against(obstacles: Obstacles, solid: int, tri: wp.vec3i, q: wp.array(dtype=wp.vec3d)) -> bool:
    """Whether the soft triangle ``tri`` lies against one flat face of the rigid solid (record
    ``solid``), its three nodes within contact distance of that face and facing it: then the
    nodes' own rows against the solid keep the whole triangle out of it (the convex solid lies
    behind the face's plane, the triangle in front of it), and a rigid point's row against the
    triangle would be the sum of theirs with the weights of its nearest point (the contact
    problem then has forces that cancel, and no unique solution)."""
    reach = obstacles.reach[solid]
    phi0, n0 = record_distance(obstacles, solid, q[tri[0]])
    phi1, n1 = record_distance(obstacles, solid, q[tri[1]])
    phi2, n2 = record_distance(obstacles, solid, q[tri[2]])
    if phi0 >= reach or phi1 >= reach or phi2 >= reach:  # a node without its row
        return False
    same = wp.float64(1.0 - 1e-9)
    if wp.dot(n0, n1) < same or wp.dot(n0, n2) < same:  # not one face (an edge, a corner, a curved solid)
        return False
    xa = q[tri[0]]
    return wp.dot(n0, wp.cross(q[tri[1]] - xa, q[tri[2]] - xa)) < wp.float64(0.0)


@wp.kernel
def mark_candidates(
    q: wp.array(dtype=wp.vec3d),
    points: Points,
    obstacles: Obstacles,
    owner: wp.array(dtype=wp.int32),
    bodies: Bodies,
    h: wp.float64,
    v: wp.array(dtype=wp.vec3d),
    normal: wp.array(dtype=wp.vec3d),
    near: wp.array(dtype=wp.int32),
    cand_tri: wp.array(dtype=wp.int32),
):
    """``near[c] = 1`` when candidate ``c``'s point is within its record's contact distance; where
    a rigid body takes part, the distance grows by what the bodies can cover in the step (``h``
    times their points' speeds), so that a falling solid is caught before it passes through. A
    self-contact candidate keeps the triangle it meets in ``cand_tri[c]`` (``v`` the nodes'
    velocities, m/s, widen its reach the same way; ``normal`` says where the surface faces at
    each node)."""
    c = wp.tid()
    o = points.obstacle[c]
    if obstacles.kind[o] == SELF:
        t, dist = self_nearest(obstacles.mesh[o], obstacles.tri0[o], obstacles.tri_nodes, q, v, normal, obstacles.rest,
                               points.node[c], obstacles.reach[o], obstacles.radius[o], h)
        cand_tri[c] = t
        near[c] = wp.where(t >= 0, 1, 0)
        return
    x = point_at(points, bodies, q, c)
    if obstacles.kind[o] == SURFACE:  # a rigid body's point against a soft body's triangles
        b = points.body[c]
        t, dist = rigid_nearest(obstacles.mesh[o], obstacles.tri0[o], obstacles.tri_nodes, q, v, x, x - bodies.p[b],
                                body_speed(bodies, b, x), obstacles.reach[o], h)
        if t >= 0:
            if flat_against(obstacles, obstacles.partner[o], obstacles.tri_nodes[t], q):
                t = wp.int32(-1)
        cand_tri[c] = t
        near[c] = wp.where(t >= 0, 1, 0)
        return
    phi, n = record_distance(obstacles, o, x)
    reach = obstacles.reach[o] + h * (body_speed(bodies, points.body[c], x) + body_speed(bodies, owner[o], x))
    near[c] = wp.where(phi < reach, 1, 0)


@wp.func
def tangents(n: wp.vec3d):
    """Two unit tangents that make a right-handed frame with the unit normal ``n``."""
    e = wp.vec3d(wp.float64(1.0), wp.float64(0.0), wp.float64(0.0))
    if wp.abs(n[0]) > wp.float64(0.9):
        e = wp.vec3d(wp.float64(0.0), wp.float64(1.0), wp.float64(0.0))
    t1 = wp.normalize(wp.cross(n, e))
    return t1, wp.cross(n, t1)


@wp.kernel
def assign_slots(
    q: wp.array(dtype=wp.vec3d),
    world_cand_start: wp.array(dtype=wp.int32),
    near: wp.array(dtype=wp.int32),
    points: Points,
    bodies: Bodies,
    owner: wp.array(dtype=wp.int32),
    mu: wp.array(dtype=wp.float64),
    step_rot: wp.array(dtype=wp.mat33d),
    step_shift: wp.array(dtype=wp.vec3d),
    capacity: wp.array(dtype=wp.int32),
    slot_start: wp.array(dtype=wp.int32),
    contact_row: wp.array(dtype=wp.int32),
    rows_per_slot: wp.array(dtype=wp.int32),
    world_held: wp.array(dtype=wp.int32),
    obstacles: Obstacles,
    cand_tri: wp.array(dtype=wp.int32),
    slot_candidate: wp.array(dtype=wp.int32),
    slot_tri: wp.array(dtype=wp.int32),
    slot_weights: wp.array(dtype=wp.vec3d),
    anchor: wp.array(dtype=wp.vec3d),
    found: wp.array(dtype=wp.int32),
    force_rows: wp.array(dtype=wp.int32),
    lam: wp.array(dtype=wp.float64),
    friction: wp.array(dtype=wp.float64),
    cand_lam: wp.array2d(dtype=wp.float64),
):
    """One thread per world: its near candidates take its slots in candidate order; ``found[w]``
    counts them all (more than the capacity: an overflow), ``force_rows[w]`` is the world's
    rows always in use (actuators, attachments: ``world_held``) plus its contacts' rows (1 per
    contact, 3 with friction: normal, then two tangents, whose ``friction`` is the record's
    coefficient). A slot keeps the point's position now as the anchor its tangential slip is
    measured from: carried over the step by a moving obstacle, or kept in the owner's frame for
    a rigid body's solid; a contact with a soft body's triangle (``SELF``, ``SURFACE``) keeps
    the triangle, the weights of its point nearest to the point now, and the point's offset
    from it (its slip is measured between the two). A contact's multipliers start from what its
    candidate carried at the last step (0 for a new contact)."""
    w = wp.tid()
    cap = capacity[w]
    rps = rows_per_slot[w]
    c0, c1 = world_cand_start[w], world_cand_start[w + 1]
    for c in range(c0, c1):
        for m in range(3):
            cand_lam[c, m] = wp.float64(0.0)
    for j in range(cap):  # the last step's contacts hand their multipliers to their candidates
        c = slot_candidate[slot_start[w] + j]
        if c >= 0:
            for m in range(rps):
                cand_lam[c, m] = lam[contact_row[w] + j * rps + m]
    k = wp.int32(0)  # not int(0): ruff would fold it to a constant
    for c in range(c0, c1):
        if near[c] != 0:
            if k < cap:
                slot_candidate[slot_start[w] + k] = c
                o = points.obstacle[c]
                x = point_at(points, bodies, q, c)
                b = owner[o]
                if obstacles.kind[o] == SELF or obstacles.kind[o] == SURFACE:  # offset from the nearest point
                    t = cand_tri[c]
                    tri = obstacles.tri_nodes[t]
                    w3, inside = triangle_nearest(x, q[tri[0]], q[tri[1]], q[tri[2]])
                    slot_tri[slot_start[w] + k] = t
                    slot_weights[slot_start[w] + k] = w3
                    anchor[slot_start[w] + k] = x - triangle_point(q, tri, w3)
                elif b >= 0:  # in the owner's frame
                    anchor[slot_start[w] + k] = wp.quat_rotate_inv(bodies.r[b], x - bodies.p[b])
                else:  # the point's place now, carried as the obstacle moves over the step
                    anchor[slot_start[w] + k] = step_rot[o] * x + step_shift[o]
                for m in range(rps):
                    lam[contact_row[w] + k * rps + m] = cand_lam[c, m]
                    friction[contact_row[w] + k * rps + m] = wp.where(m > 0, mu[o], wp.float64(0.0))
            k += 1
    for j in range(k, cap):
        slot_candidate[slot_start[w] + j] = -1
        for m in range(rps):
            lam[contact_row[w] + j * rps + m] = wp.float64(0.0)
            friction[contact_row[w] + j * rps + m] = wp.float64(0.0)
    found[w] = k
    force_rows[w] = world_held[w] + wp.min(k, cap) * rps


@wp.kernel
def contact_rows(
    q: wp.array(dtype=wp.vec3d),
    slot_candidate: wp.array(dtype=wp.int32),
    slot_row: wp.array(dtype=wp.int32),
    slot_rows: wp.array(dtype=wp.int32),
    slot_entry: wp.array(dtype=wp.int32),
    slot_tri: wp.array(dtype=wp.int32),
    slot_weights: wp.array(dtype=wp.vec3d),
    anchor: wp.array(dtype=wp.vec3d),
    points: Points,
    obstacles: Obstacles,
    owner: wp.array(dtype=wp.int32),
    bodies: Bodies,
    entry_offset: int,
    entries_per_row: int,
    rigid_offset: int,
    delta: wp.array(dtype=wp.float64),
    h_row: wp.array(dtype=wp.int32),
    h_node: wp.array(dtype=wp.int32),
    h_coef: wp.array(dtype=wp.vec3d),
    j_row: wp.array(dtype=wp.int32),
    j_body: wp.array(dtype=wp.int32),
    j_lin: wp.array(dtype=wp.vec3d),
    j_ang: wp.array(dtype=wp.vec3d),
    slot_point: wp.array(dtype=wp.vec3d),
    row_dir: wp.array(dtype=wp.vec3d),
):
    """The rows of slot ``k`` at ``q`` and the bodies' poses (first row ``slot_row[k]``,
    ``slot_rows[k]`` of them, ``entries_per_row`` soft entries each from ``entry_offset +
    entries_per_row slot_entry[k]`` (1, or 4 in a model with soft-surface records: the node,
    then a triangle's three) and, with rigid bodies (``rigid_offset >= 0``), two rigid entries
    each from ``rigid_offset + 2 slot_entry[k]``): the gap along the normal, and with friction the slip
    from the anchor along two tangents. ``slot_point`` keeps the point (m) and ``row_dir`` each
    row's direction at it (what the force on the point is made of). An unused slot's rows are
    inert."""
    k = wp.tid()
    c = slot_candidate[k]
    node = wp.int32(0)
    pb = wp.int32(-1)  # the point's rigid body
    ob = wp.int32(-1)  # the solid's
    soft = wp.float64(0.0)  # 1 for a soft node: its entries carry the directions
    phi = wp.float64(0.0)
    x, slip = wp.vec3d(), wp.vec3d()
    n, t1, t2 = wp.vec3d(), wp.vec3d(), wp.vec3d()
    tri = wp.vec3i(0, 0, 0)  # a self-contact's triangle, its nearest point's weights now and at the anchor
    w_now, w_anchor = wp.vec3d(), wp.vec3d()
    # lever arms from the bodies' centres (m): the point's, and the owner's to the point (normal
    # row) and to the anchor (tangent rows)
    r_point, r_normal, r_anchor = wp.vec3d(), wp.vec3d(), wp.vec3d()
    if c >= 0:
        o = points.obstacle[c]
        x = point_at(points, bodies, q, c)
        pb = points.body[c]
        ob = owner[o]
        if pb < 0:
            node = points.node[c]
            soft = wp.float64(1.0)
        else:
            r_point = x - bodies.p[pb]
        if obstacles.kind[o] == SELF or obstacles.kind[o] == SURFACE:  # against a triangle: gap from its nearest
            # point, slip from the anchor's
            tri = obstacles.tri_nodes[slot_tri[k]]
            phi, n, w_now, dist = self_gap(x, q[tri[0]], q[tri[1]], q[tri[2]])
            w_anchor = slot_weights[k]
            slip = x - triangle_point(q, tri, w_anchor) - anchor[k]
        else:
            a = anchor[k]
            if ob >= 0:
                a = bodies.p[ob] + wp.quat_rotate(bodies.r[ob], anchor[k])
                r_normal = x - bodies.p[ob]
                r_anchor = a - bodies.p[ob]
            phi, n = record_distance(obstacles, o, x)
            slip = x - a
        t1, t2 = tangents(n)
    slot_point[k] = x
    for m in range(slot_rows[k]):
        row = slot_row[k] + m
        e = entry_offset + entries_per_row * (slot_entry[k] + m)
        d = n
        value = phi
        r_o = r_normal
        w_tri = w_now
        if m == 1:
            d = t1
            value = wp.dot(t1, slip)
            r_o = r_anchor
            w_tri = w_anchor
        elif m == 2:
            d = t2
            value = wp.dot(t2, slip)
            r_o = r_anchor
            w_tri = w_anchor
        if c < 0:
            value = wp.float64(0.0)
        h_row[e] = row
        h_node[e] = node
        h_coef[e] = soft * d
        for i in range(1, entries_per_row):  # the triangle's nodes (0 weights: an inert entry)
            h_row[e + i] = row
            h_node[e + i] = tri[i - 1]
            h_coef[e + i] = -w_tri[i - 1] * d
        delta[row] = value
        row_dir[slot_entry[k] + m] = d
        if rigid_offset >= 0:
            j = rigid_offset + 2 * (slot_entry[k] + m)
            j_row[j] = row
            j_body[j] = pb
            j_lin[j] = d
            j_ang[j] = wp.cross(r_point, d)
            j_row[j + 1] = row
            j_body[j + 1] = ob
            j_lin[j + 1] = -d
            j_ang[j + 1] = -wp.cross(r_o, d)
