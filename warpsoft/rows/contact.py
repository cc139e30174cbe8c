"""Contact rows: the gap between points and rigid solids (Signorini: ``delta = phi(x) >= 0``,
``lambda >= 0`` the normal force (N), one of them zero) and, when some solid of the world has
friction, two tangential rows per contact: the slip ``t . (x - x_anchor)`` (m) from where the
point was at the step's start, whose forces stay in Coulomb's cone ``|lambda_t| <= mu
lambda_n``.

The points are the soft bodies' surface nodes and the rigid bodies' collision points; the
solids are the obstacles (fixed or moving by a schedule) and the rigid bodies' own (a body's
points meet every other body's solid, never its own), the soft bodies' surface triangles, which
the rigid bodies' points meet (``kernels/rows/rigid_surface.py``; a rigid body holding some of
a soft body's nodes skips that body), and, for a body that touches itself, its own surface
triangles (``kernels/rows/self_contact.py``). A row against a triangle has entries on four
nodes. A world has a fixed block of ``capacity`` contact slots (1 or 3 rows each); detection,
at the start of a step, fills the first of them with the points then within their solid's
contact distance of where it will be at the step's end (in candidate order: deterministic); a
moving obstacle carries the anchors of its contacts, a rigid body keeps them in its frame; the
rows are evaluated at every linearization of the step for those points, and the rest stay
inert. More near points than slots is an overflow, reported. Kernels: ``kernels/rows/contact.py``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import warp as wp

from warpsoft.kernels.rows import contact as kernels
from warpsoft.kernels.rows import self_contact as self_kernels

from ..launch import launch
from ..scene import obstacles as ob
from .kind import RowKind

RIGID_REACH = 0.02  # default contact distance for a rigid body's points: this share of its size (m/m)


@dataclass
class ContactBlock:
    """A world's block of contact rows: its obstacles, rigid bodies, self-contacts and capacity
    (the scene's) and the rows per contact (3 when some solid has friction: the normal and two
    tangents, else 1)."""

    obstacles: list
    rigid: list
    selfs: list
    capacity: int
    rows_per_contact: int
    name: str = "contacts"


class ContactRows(RowKind):
    name, actuator, columns = "contact", False, True

    @classmethod
    def items(cls, scene) -> list:
        if not scene.touches:
            return []
        rows = 3 if any(o.mu > 0 for o in scene.obstacles + scene.rigid_bodies + scene.self_contacts) else 1
        return [ContactBlock(list(scene.obstacles), list(scene.rigid_bodies), list(scene.self_contacts),
                             scene.contact_capacity, rows)]

    @staticmethod
    def row_count(item) -> int:
        return item.capacity * item.rows_per_contact

    def __init__(self, model, placed, entry_offset):
        super().__init__(model, placed, entry_offset)
        d = model.device
        worlds = model.num_worlds
        rec = {k: [] for k in ("kind", "a", "b", "radius", "rot", "reach", "mu", "owner", "a_loc", "b_loc",
                               "rot_loc", "partner")}
        self.records = []  # the scene's obstacle entry or rigid body of each (solid, points) record
        cand = {k: [] for k in ("node", "body", "local", "obstacle")}
        cand_start = [0]
        capacity, slot_start, contact_row = np.zeros(worlds, np.int32), [0], np.zeros(worlds, np.int32)
        rows_per_slot, slot_row, slot_rows = np.ones(worlds, np.int32), [], []
        by_world = {p.world: p for p in placed}
        rigid_index = {(w, id(rb)): k for k, (w, rb) in enumerate(model.rigid)}  # (a scene may serve two worlds)
        held = {}  # a rigid body's attached soft nodes (global ids): they never touch its solid
        for w, scene in enumerate(model.scenes):
            for att in scene.attachments:
                ids = att.nodes + model.body_info(att.body.name, w).node_start
                held.setdefault(rigid_index[(w, id(att.rigid))], []).extend(ids.tolist())

        surfaces = {}  # the soft-surface records' bodies (self-contact, rigid points): record -> BodyInfo
        solid_record = {}  # (rigid body, soft body's first node) -> the record of its solid met by those nodes

        def add(entry, pack, owner, reach, mu, nodes=None, body=None, partner=-1):  # a record and its candidates
            k, pa, pb, r, R = pack
            self.records.append(entry)
            for key, v in (("kind", k), ("a", pa), ("b", pb), ("radius", r), ("rot", R), ("reach", reach),
                           ("mu", mu), ("owner", owner), ("partner", partner)):
                rec[key].append(v)
            if owner >= 0:  # the record in its body's frame (its centre of mass, world axes at t = 0)
                _, la, lb, _, lR = entry.shape.moved(np.eye(3), -entry.center).pack()
            else:
                la, lb, lR = pa, pb, R
            rec["a_loc"].append(la)
            rec["b_loc"].append(lb)
            rec["rot_loc"].append(lR)
            o = len(rec["kind"]) - 1
            if nodes is not None:
                count = len(nodes)
                cand["node"].append(nodes)
                cand["body"].append(np.full(count, -1))
                cand["local"].append(np.zeros((count, 3)))
            else:
                rb = model.rigid[body][1]
                count = len(rb.points)
                cand["node"].append(np.full(count, -1))
                cand["body"].append(np.full(count, body))
                cand["local"].append(rb.points - rb.center)
            cand["obstacle"].append(np.full(count, o))

        for w in range(worlds):
            p = by_world.get(w)
            if p is not None:
                softs = []  # (BodyInfo, surface nodes, contact distance)
                for info in (b for b in model.bodies if b.world == w):
                    body = next(bd for bd in model.scenes[w].bodies if bd.name == info.name)
                    softs.append((info, np.unique(info.surface), 0.25 * body.mesh.mean_surface_edge()))
                rigids = [(rigid_index[(w, id(rb))], RIGID_REACH * rb.size) for rb in p.item.rigid]
                for entry in p.item.obstacles:  # obstacles: every soft body's nodes, every rigid body's points
                    pack = entry.at(0.0).pack()
                    for _, nodes, reach in softs:
                        add(entry, pack, -1, entry.contact_distance or reach, entry.mu, nodes=nodes)
                    for k, reach in rigids:
                        add(entry, pack, -1, entry.contact_distance or reach, entry.mu, body=k)
                for k, _ in rigids:  # a rigid body's solid: the soft nodes, the other rigid bodies' points
                    rb = model.rigid[k][1]
                    pack = rb.shape.pack()
                    for info, nodes, reach in softs:
                        free = np.setdiff1d(nodes, held.get(k, []))
                        if len(free):
                            add(rb, pack, k, rb.contact_distance or reach, rb.mu, nodes=free)
                            solid_record[(k, info.node_start)] = len(self.records) - 1
                    for j, reach in rigids:
                        if j != k:
                            add(rb, pack, k, rb.contact_distance or reach, rb.mu, body=j)
                for k, _ in rigids:  # a rigid body's points against the soft bodies' triangles it holds none of
                    rb = model.rigid[k][1]
                    pack = (kernels.SURFACE, np.zeros(3), np.zeros(3), 0.0, np.eye(3))
                    for info, nodes, reach in softs:
                        if np.isin(nodes, held.get(k, [])).any():  # attached: its points sit on the surface
                            continue
                        add(rb, pack, -1, rb.contact_distance or reach, rb.mu, body=k,
                            partner=solid_record[(k, info.node_start)])
                        surfaces[len(self.records) - 1] = info
                for sc in p.item.selfs:  # a body's surface nodes against its own triangles
                    info = model.body_info(sc.body.name, w)
                    reach = sc.contact_distance or 0.25 * sc.body.mesh.mean_surface_edge()
                    pack = (kernels.SELF, np.zeros(3), np.zeros(3), 2.0 * reach, np.eye(3))  # radius: apart
                    add(sc, pack, -1, reach, sc.mu, nodes=np.unique(info.surface))
                    surfaces[len(self.records) - 1] = info
                rps = p.item.rows_per_contact
                capacity[w], rows_per_slot[w] = p.item.capacity, rps
                contact_row[w] = p.first_row
                slot_row.append(p.first_row + rps * np.arange(p.item.capacity))
                slot_rows.append(np.full(p.item.capacity, rps))
            cand_start.append(sum(len(c) for c in cand["node"]))
            slot_start.append(slot_start[-1] + int(capacity[w]))
        self.num_slots = slot_start[-1]
        slot_rows = np.concatenate(slot_rows)
        # soft entries per row: the point, and with soft-surface records a triangle's three nodes
        self.entries_per_row = 4 if surfaces else 1
        self.self_contact = any(k == kernels.SELF for k in rec["kind"])  # (the surfaces' normals serve it alone)
        self.num_entries = self.entries_per_row * int(slot_rows.sum())
        self.num_rigid_entries = 2 * self.num_entries if model.num_rigid else 0  # the point's body, the solid's
        self.num_candidates = cand_start[-1]
        i32 = lambda v: wp.array(np.asarray(v, dtype=np.int32), dtype=wp.int32, device=d)  # noqa: E731
        f64 = lambda v, dtype: wp.array(np.array(v, dtype=float), dtype=dtype, device=d)  # noqa: E731
        self.kind, self.reach, self.mu = i32(rec["kind"]), f64(rec["reach"], wp.float64), f64(rec["mu"], wp.float64)
        self.a, self.b, self.rot = f64(rec["a"], wp.vec3d), f64(rec["b"], wp.vec3d), f64(rec["rot"], wp.mat33d)
        self.radius = f64(rec["radius"], wp.float64)
        self.owner, self.partner = i32(rec["owner"]), i32(rec["partner"])
        self.a_loc, self.b_loc = f64(rec["a_loc"], wp.vec3d), f64(rec["b_loc"], wp.vec3d)
        self.rot_loc = f64(rec["rot_loc"], wp.mat33d)
        self.owned = np.flatnonzero(np.array(rec["owner"]) >= 0)
        self.owned_d = i32(self.owned if len(self.owned) else [0])
        self._meshes(d, surfaces)
        # how a point fixed to each obstacle moves over the step: x -> step_rot x + step_shift
        n_rec = len(rec["kind"])
        self.step_rot = wp.array(np.tile(np.eye(3), (n_rec, 1, 1)), dtype=wp.mat33d, device=d)
        self.step_shift = wp.zeros(n_rec, dtype=wp.vec3d, device=d)
        self.moving = [i for i, e in enumerate(self.records) if getattr(e, "motion", None) is not None]
        self.obstacles = kernels.Obstacles()  # the records as the kernels take them (the same arrays)
        for name in ("kind", "a", "b", "radius", "rot", "mesh", "tri0", "tri_xyz", "reach", "tri_nodes", "partner"):
            setattr(self.obstacles, name, getattr(self, name))
        self.obstacles.rest = model.rest
        self._posed_at = None
        self.cand_node = i32(np.concatenate(cand["node"]))
        self.points = kernels.Points()
        self.points.node, self.points.body = self.cand_node, i32(np.concatenate(cand["body"]))
        self.points.local = f64(np.concatenate(cand["local"]), wp.vec3d)
        self.points.obstacle = self.cand_obstacle = i32(np.concatenate(cand["obstacle"]))
        # made here, never inside a capture (an array uploaded there is filled by a copy the graph
        # replays from host memory freed since): the Bodies struct of a model without rigid
        # bodies (inert arrays), the nodes' velocities when the rows are evaluated without a State
        self._no_bodies = kernels.Bodies()
        self._no_bodies.p = self._no_bodies.v = self._no_bodies.w = wp.zeros(1, dtype=wp.vec3d, device=d)
        self._no_bodies.r = wp.array([[0.0, 0.0, 0.0, 1.0]], dtype=wp.quatd, device=d)
        self._still = wp.zeros(model.num_nodes, dtype=wp.vec3d, device=d)
        self._bodies = {}  # a State's Bodies struct, by the State
        self.world_cand_start = i32(cand_start)
        self.capacity = i32(capacity)  # contact slots per world
        self.slot_start, self.contact_row = i32(slot_start), i32(contact_row)
        self.slot_row, self.slot_rows = i32(np.concatenate(slot_row)), i32(slot_rows)
        self.slot_entry = i32(np.concatenate([[0], np.cumsum(slot_rows)[:-1]]))
        self.rows_per_slot, self.rows_per_slot_np = i32(rows_per_slot), rows_per_slot
        self.near = wp.zeros(max(self.num_candidates, 1), dtype=wp.int32, device=d)
        self.cand_lam = wp.zeros((max(self.num_candidates, 1), 3), dtype=wp.float64, device=d)  # warm starts (N)
        self.anchor = wp.zeros(self.num_slots, dtype=wp.vec3d, device=d)  # where each contact's point began (m)
        self.slot_candidate = wp.full(self.num_slots, -1, dtype=wp.int32, device=d)
        self.cand_tri = wp.full(max(self.num_candidates, 1), -1, dtype=wp.int32, device=d)  # self-contact
        self.slot_tri = wp.zeros(self.num_slots, dtype=wp.int32, device=d)  # a self-contact's triangle
        self.slot_weights = wp.zeros(self.num_slots, dtype=wp.vec3d, device=d)  # and its anchor's weights
        self.slot_point = wp.zeros(self.num_slots, dtype=wp.vec3d, device=d)  # each contact's point (m)
        self.row_dir = wp.zeros(self.num_entries, dtype=wp.vec3d, device=d)  # each row's direction at it
        self.found = wp.zeros(worlds, dtype=wp.int32, device=d)  # near points per world at the last detection
        # host copies, read once: what set_time rewrites for moving obstacles, and the slot layout
        self.host = {name: getattr(self, name).numpy().copy() for name in (
            "a", "b", "rot", "step_rot", "step_shift", "slot_start", "capacity", "contact_row", "slot_entry")}

    def bodies(self, state) -> kernels.Bodies:
        """The rigid bodies of ``state`` as the kernels take them (inert arrays without bodies)."""
        if state is None or state.body_p is None:
            return self._no_bodies
        key = state.body_p.ptr
        if key not in self._bodies:
            b = kernels.Bodies()
            b.p, b.r, b.v, b.w = state.body_p, state.body_r, state.body_v, state.body_w
            self._bodies[key] = b
        return self._bodies[key]

    def velocities(self, table) -> wp.array:
        """The nodes' velocities (m/s) of the State the rows are evaluated at (0 without one)."""
        state = table.bodies
        if state is None or getattr(state, "v", None) is None:
            return self._still
        return state.v

    def _pose(self, bodies) -> None:
        """The rigid bodies' solids where their bodies are (before a detection or an evaluation)."""
        if len(self.owned):
            launch(kernels.pose_records, len(self.owned),
                   inputs=[self.owned_d, self.owner, self.a_loc, self.b_loc, self.rot_loc, bodies, self.obstacles],
                   device=self.model.device)

    def _meshes(self, device, surfaces: dict) -> None:
        """The records' triangles and BVHs (``wp.Mesh``, single precision, kept alive here):
        a mesh obstacle's, its vertices in double in ``tri_xyz``; a soft-surface record's (a
        self-contact, a rigid body's points against a soft body), its body's surface
        (``surfaces``: record -> BodyInfo; one BVH per body), its triangles' global node ids in
        ``tri_nodes``, the BVH's vertices moved to the nodes and refitted by :meth:`detect`.
        ``tri0`` is each record's first triangle in its table; analytic records get id 0."""
        self.bvh, ids, tri0, xyz, made = [], [], [], [], {}
        self.surface_bvh, tris, nodes, bodies = [], [], [], {}
        unique = {info.node_start: info for info in surfaces.values()}
        self.surface_points = wp.zeros(max(sum(i.node_count for i in unique.values()), 1), dtype=wp.vec3,
                                       device=device)
        count = start = surface_count = 0
        for o, entry in enumerate(self.records):
            if o in surfaces:  # a soft body's surface: one BVH per body, shared by its records
                info = surfaces[o]
                if info.node_start not in bodies:
                    view = self.surface_points[start:start + info.node_count]
                    view.assign(self.model.rest_np[info.node_start:info.node_start + info.node_count]
                                .astype(np.float32))
                    local = (info.surface - info.node_start).astype(np.int32)
                    self.surface_bvh.append(wp.Mesh(points=view, indices=wp.array(local.ravel(), dtype=wp.int32,
                                                                                   device=device)))
                    bodies[info.node_start] = (self.surface_bvh[-1].id, surface_count)
                    tris.append(info.surface)
                    nodes.append(np.arange(info.node_start, info.node_start + info.node_count))
                    start += info.node_count
                    surface_count += len(info.surface)
                ids.append(bodies[info.node_start][0])
                tri0.append(bodies[info.node_start][1])
                continue
            shape = entry.shape
            if not isinstance(shape, ob.Mesh):
                ids.append(0)
                tri0.append(0)
                continue
            if id(shape) not in made:  # one BVH per obstacle, shared by the bodies that touch it
                bvh = wp.Mesh(points=wp.array(shape.vertices, dtype=wp.vec3, device=device),
                              indices=wp.array(shape.triangles.ravel(), dtype=wp.int32, device=device))
                self.bvh.append(bvh)
                made[id(shape)] = (bvh.id, count)
                xyz.append(shape.vertices[shape.triangles])
                count += len(shape.triangles)
            ids.append(made[id(shape)][0])
            tri0.append(made[id(shape)][1])
        self.mesh = wp.array(np.array(ids, dtype=np.uint64), dtype=wp.uint64, device=device)
        self.tri0 = wp.array(np.array(tri0, dtype=np.int32), dtype=wp.int32, device=device)
        self.tri_xyz = wp.array(np.concatenate(xyz) if xyz else np.zeros((1, 3, 3)), dtype=wp.vec3d, device=device)
        self.tri_nodes = wp.array(np.concatenate(tris).astype(np.int32) if tris else np.zeros((1, 3), np.int32),
                                  dtype=wp.vec3i, device=device)
        self.surface_normal = wp.zeros(self.model.num_nodes if tris else 1, dtype=wp.vec3d, device=device)
        self.surface_node = wp.array(np.concatenate(nodes).astype(np.int32) if nodes else np.zeros(1, np.int32),
                                     dtype=wp.int32, device=device)

    def set_time(self, t: float, dt: float) -> None:
        """The moving obstacles where they are at the step's end ``t`` (s), and how they moved
        since ``t - dt``; uploaded in one copy per array, only for scenes with moving obstacles."""
        if not self.moving or self._posed_at == t:
            return
        h = self.host
        a, b, rot, step_rot, step_shift = h["a"], h["b"], h["rot"], h["step_rot"], h["step_shift"]
        for i in self.moving:
            entry = self.records[i]
            _, a[i], b[i], _, rot[i] = entry.at(t).pack()
            (r0, p0), (r1, p1) = entry.pose(t - dt), entry.pose(t)
            step_rot[i] = r1 @ r0.T  # x1 = r1 r0^T (x0 - p0) + p1
            step_shift[i] = p1 - step_rot[i] @ p0
        for array, host in ((self.a, a), (self.b, b), (self.rot, rot), (self.step_rot, step_rot),
                            (self.step_shift, step_shift)):
            array.assign(host)
        self._posed_at = t

    def forces(self, table, world: int, lam: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The world's contacts in use (host) at the last evaluation: their points ``(k, 3)`` (m)
        and the force the solid puts on each ``(k, 3)`` (N: ``sum_m lambda_m d_m`` over the
        contact's rows' directions, the normal force along the normal, friction along the
        tangents) from the multipliers ``lam``."""
        h = self.host
        start, cap = int(h["slot_start"][world]), int(h["capacity"][world])
        slots = self.slot_candidate.numpy()[start:start + cap]
        used = int(np.count_nonzero(slots >= 0))
        rps = int(self.rows_per_slot_np[world])
        rows = int(h["contact_row"][world]) + np.arange(used * rps)
        entries = h["slot_entry"][start:start + used, None] + np.arange(rps)
        direction = self.row_dir.numpy()[entries.ravel()].reshape(used, rps, 3)
        force = np.einsum("km,kmi->ki", lam[rows].reshape(used, rps), direction)
        return self.slot_point.numpy()[start:start + used].copy(), force

    def detect(self, table, q: wp.array, lam: wp.array, friction: wp.array) -> None:
        """The points within contact distance at ``q`` (and the rigid poses of ``table.bodies``)
        take their world's contact rows; the worlds' force-row counts (actuators + contacts)
        follow; a contact's multiplier starts from its candidate's at the last step."""
        d, bodies = self.model.device, self.bodies(table.bodies)
        self._pose(bodies)
        if self.surface_bvh:  # the soft surfaces met by points where the nodes are
            launch(self_kernels.surface_points, len(self.surface_node), inputs=[q, self.surface_node],
                   outputs=[self.surface_points], device=d)
            for bvh in self.surface_bvh:
                bvh.refit()
        if self.self_contact:  # which way the surfaces face at their nodes
            self.surface_normal.zero_()
            launch(self_kernels.surface_normals, len(self.tri_nodes), inputs=[q, self.tri_nodes],
                   outputs=[self.surface_normal], device=d)
        launch(kernels.mark_candidates, self.num_candidates,
               inputs=[q, self.points, self.obstacles, self.owner, bodies, self.model.dt, self.velocities(table),
                       self.surface_normal],
               outputs=[self.near, self.cand_tri], device=d)
        launch(kernels.assign_slots, self.model.num_worlds,
               inputs=[q, self.world_cand_start, self.near, self.points, bodies, self.owner, self.mu,
                       self.step_rot, self.step_shift, self.capacity, self.slot_start, self.contact_row,
                       self.rows_per_slot, table.world_held_d, self.obstacles, self.cand_tri],
               outputs=[self.slot_candidate, self.slot_tri, self.slot_weights, self.anchor, self.found,
                        table.world_force_rows, lam, friction, self.cand_lam], device=d)

    def evaluate(self, table, q) -> None:
        bodies = self.bodies(table.bodies)
        self._pose(bodies)
        launch(kernels.contact_rows, self.num_slots,
               inputs=[q, self.slot_candidate, self.slot_row, self.slot_rows, self.slot_entry, self.slot_tri,
                       self.slot_weights, self.anchor, self.points, self.obstacles, self.owner, bodies,
                       self.entry_offset, self.entries_per_row, self.rigid_offset if self.num_rigid_entries else -1],
               outputs=[table.delta, table.h_row, table.h_node, table.h_coef, table.j_row, table.j_body,
                        table.j_lin, table.j_ang, self.slot_point, self.row_dir], device=self.model.device)
