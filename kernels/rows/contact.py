"""Contact rows against rigid obstacles, analytic or triangle meshes (``warpsoft/rows/contact.py``).

A candidate is a (surface node, obstacle) pair of one world; candidates are grouped by world.
Detection marks the candidates within their obstacle's contact distance, then gives each world's
marked candidates, in candidate order (deterministic), the world's contact slots up to its
capacity. A slot's row measures the gap ``delta = phi(x_node)`` (m, the obstacle's signed
distance) with ``H = n`` (its outward normal) at the node; an unused slot's row is inert (no
entry, ``delta = 0``).
"""

import warp as wp

FLOOR = wp.constant(0)
BALL = wp.constant(1)
BOX = wp.constant(2)
CAPSULE = wp.constant(3)
CYLINDER = wp.constant(4)
MESH = wp.constant(5)


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
def triangle_closest(p: wp.vec3d, a: wp.vec3d, b: wp.vec3d, c: wp.vec3d):
    """The point of triangle ``abc`` nearest to ``p``, and whether it lies inside the face (not on
    an edge or a vertex): by the Voronoi region of ``p``, from the dot products of ``p``'s
    offsets with the two edges at ``a``."""
    zero = wp.float64(0.0)
    ab = b - a
    ac = c - a
    d1 = wp.dot(ab, p - a)
    d2 = wp.dot(ac, p - a)
    if d1 <= zero and d2 <= zero:
        return a, False
    d3 = wp.dot(ab, p - b)
    d4 = wp.dot(ac, p - b)
    if d3 >= zero and d4 <= d3:
        return b, False
    vc = d1 * d4 - d3 * d2
    if vc <= zero and d1 >= zero and d3 <= zero:  # edge ab
        return a + (d1 / (d1 - d3)) * ab, False
    d5 = wp.dot(ab, p - c)
    d6 = wp.dot(ac, p - c)
    if d6 >= zero and d5 <= d6:
        return c, False
    vb = d5 * d2 - d1 * d6
    if vb <= zero and d2 >= zero and d6 <= zero:  # edge ac
        return a + (d2 / (d2 - d6)) * ac, False
    va = d3 * d6 - d5 * d4
    if va <= zero and d4 - d3 >= zero and d5 - d6 >= zero:  # edge bc
        return b + ((d4 - d3) / ((d4 - d3) + (d5 - d6))) * (c - b), False
    inv = wp.float64(1.0) / (va + vb + vc)  # the face
    return a + ab * (vb * inv) + ac * (vc * inv), True


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
    vertices in double); ``reach`` the contact distance (m)."""

    kind: wp.array(dtype=wp.int32)
    a: wp.array(dtype=wp.vec3d)
    b: wp.array(dtype=wp.vec3d)
    radius: wp.array(dtype=wp.float64)
    rot: wp.array(dtype=wp.mat33d)
    mesh: wp.array(dtype=wp.uint64)
    tri0: wp.array(dtype=wp.int32)
    tri_xyz: wp.array2d(dtype=wp.vec3d)
    reach: wp.array(dtype=wp.float64)


@wp.func
def record_distance(obstacles: Obstacles, o: int, x: wp.vec3d):
    """``obstacle_distance`` of record ``o``."""
    return obstacle_distance(obstacles.kind[o], obstacles.a[o], obstacles.b[o], obstacles.radius[o], obstacles.rot[o],
                             obstacles.mesh[o], obstacles.tri0[o], obstacles.tri_xyz, x)


@wp.kernel
def mark_candidates(
    q: wp.array(dtype=wp.vec3d),
    cand_node: wp.array(dtype=wp.int32),
    cand_obstacle: wp.array(dtype=wp.int32),
    obstacles: Obstacles,
    near: wp.array(dtype=wp.int32),
):
    """``near[c] = 1`` when candidate ``c``'s node is within its obstacle's contact distance."""
    c = wp.tid()
    o = cand_obstacle[c]
    phi, n = record_distance(obstacles, o, q[cand_node[c]])
    near[c] = wp.where(phi < obstacles.reach[o], 1, 0)


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
    cand_node: wp.array(dtype=wp.int32),
    cand_obstacle: wp.array(dtype=wp.int32),
    mu: wp.array(dtype=wp.float64),
    step_rot: wp.array(dtype=wp.mat33d),
    step_shift: wp.array(dtype=wp.vec3d),
    capacity: wp.array(dtype=wp.int32),
    slot_start: wp.array(dtype=wp.int32),
    contact_row: wp.array(dtype=wp.int32),
    rows_per_slot: wp.array(dtype=wp.int32),
    world_actuators: wp.array(dtype=wp.int32),
    slot_candidate: wp.array(dtype=wp.int32),
    anchor: wp.array(dtype=wp.vec3d),
    found: wp.array(dtype=wp.int32),
    force_rows: wp.array(dtype=wp.int32),
    lam: wp.array(dtype=wp.float64),
    friction: wp.array(dtype=wp.float64),
    cand_lam: wp.array2d(dtype=wp.float64),
):
    """One thread per world: its near candidates take its slots in candidate order; ``found[w]``
    counts them all (more than the capacity: an overflow), ``force_rows[w]`` is the world's
    actuator rows plus its contacts' rows (1 per contact, 3 with friction: normal, then two
    tangents, whose ``friction`` is the obstacle's coefficient). A slot keeps its node's position
    now, moved with the obstacle over the step, as the anchor its tangential slip is measured
    from. A contact's multipliers start from what its node and obstacle carried at the last
    step (0 for a new contact)."""
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
                o = cand_obstacle[c]  # the node's place now, carried as the obstacle moves over the step
                anchor[slot_start[w] + k] = step_rot[o] * q[cand_node[c]] + step_shift[o]
                for m in range(rps):
                    lam[contact_row[w] + k * rps + m] = cand_lam[c, m]
                    friction[contact_row[w] + k * rps + m] = wp.where(m > 0, mu[cand_obstacle[c]], wp.float64(0.0))
            k += 1
    for j in range(k, cap):
        slot_candidate[slot_start[w] + j] = -1
        for m in range(rps):
            lam[contact_row[w] + j * rps + m] = wp.float64(0.0)
            friction[contact_row[w] + j * rps + m] = wp.float64(0.0)
    found[w] = k
    force_rows[w] = world_actuators[w] + wp.min(k, cap) * rps


@wp.kernel
def contact_rows(
    q: wp.array(dtype=wp.vec3d),
    slot_candidate: wp.array(dtype=wp.int32),
    slot_row: wp.array(dtype=wp.int32),
    slot_rows: wp.array(dtype=wp.int32),
    slot_entry: wp.array(dtype=wp.int32),
    anchor: wp.array(dtype=wp.vec3d),
    cand_node: wp.array(dtype=wp.int32),
    cand_obstacle: wp.array(dtype=wp.int32),
    obstacles: Obstacles,
    entry_offset: int,
    delta: wp.array(dtype=wp.float64),
    h_row: wp.array(dtype=wp.int32),
    h_node: wp.array(dtype=wp.int32),
    h_coef: wp.array(dtype=wp.vec3d),
):
    """The rows of slot ``k`` at ``q`` (first row ``slot_row[k]``, ``slot_rows[k]`` of them, one
    entry each from ``entry_offset + slot_entry[k]``): the gap with the normal at the node, and
    with friction the slip from the anchor along two tangents; an unused slot's rows are inert."""
    k = wp.tid()
    c = slot_candidate[k]
    node = wp.int32(0)
    phi = wp.float64(0.0)
    n, t1, t2 = wp.vec3d(), wp.vec3d(), wp.vec3d()
    if c >= 0:
        node = cand_node[c]
        o = cand_obstacle[c]
        phi, n = record_distance(obstacles, o, q[node])
        t1, t2 = tangents(n)
    slip = q[node] - anchor[k]
    for m in range(slot_rows[k]):
        row = slot_row[k] + m
        e = entry_offset + slot_entry[k] + m
        h_row[e] = row
        h_node[e] = node
        if c < 0:
            delta[row] = wp.float64(0.0)
            h_coef[e] = wp.vec3d()
        elif m == 0:
            delta[row] = phi
            h_coef[e] = n
        elif m == 1:
            delta[row] = wp.dot(t1, slip)
            h_coef[e] = t1
        else:
            delta[row] = wp.dot(t2, slip)
            h_coef[e] = t2
