"""Contact rows: the gap between a soft body's surface nodes and the scene's rigid obstacles
(Signorini: ``delta = phi(x) >= 0``, ``lambda >= 0`` the normal force (N), one of them zero) and,
when some obstacle of the world has friction, two tangential rows per contact: the slip
``t . (x - x_anchor)`` (m) from where the node was at the step's start, whose forces stay in
Coulomb's cone ``|lambda_t| <= mu lambda_n``. A world has a fixed block of ``capacity`` contact
slots (1 or 3 rows each); detection, at the start of a step, fills the first of them with the
nodes then within their obstacle's contact distance of where it will be at the step's end (in
node order: deterministic); a moving obstacle carries the anchors of its contacts; the rows
are evaluated at every linearization of the step for those nodes, and the rest stay inert. More
near nodes than slots is an overflow, reported. Kernels: ``kernels/rows/contact.py``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import warp as wp

from warpsoft.kernels.rows import contact as kernels

from ..scene import obstacles as ob
from .kind import RowKind


@dataclass
class ContactBlock:
    """A world's block of contact rows: its obstacles and capacity (the scene's) and the rows
    per contact (3 when some obstacle has friction: the normal and two tangents, else 1)."""

    obstacles: list
    capacity: int
    rows_per_contact: int
    name: str = "contacts"


def mean_surface_edge(mesh) -> float:
    """Mean edge length (m) of a mesh's surface triangles."""
    tris = mesh.surface()
    x = mesh.nodes[tris]
    return float(np.mean(np.linalg.norm(x - np.roll(x, 1, axis=1), axis=2)))


class ContactRows(RowKind):
    name, actuator, columns = "contact", False, True

    @classmethod
    def items(cls, scene) -> list:
        if not scene.obstacles:
            return []
        rows = 3 if any(o.mu > 0 for o in scene.obstacles) else 1
        return [ContactBlock(list(scene.obstacles), scene.contact_capacity, rows)]

    @staticmethod
    def row_count(item) -> int:
        return item.capacity * item.rows_per_contact

    def __init__(self, model, placed, entry_offset):
        super().__init__(model, placed, entry_offset)
        d = model.device
        worlds = model.num_worlds
        kind, a, b, radius, rot, reach, mu = [], [], [], [], [], [], []
        self.records = []  # the scene's obstacle entry of each (obstacle, body) record
        cand_node, cand_obstacle, cand_start = [], [], [0]
        capacity, slot_start, contact_row = np.zeros(worlds, np.int32), [0], np.zeros(worlds, np.int32)
        rows_per_slot, slot_row, slot_rows = np.ones(worlds, np.int32), [], []
        by_world = {p.world: p for p in placed}
        for w in range(worlds):
            p = by_world.get(w)
            if p is not None:
                bodies = [info for info in model.bodies if info.world == w]
                for entry in p.item.obstacles:
                    k, pa, pb, r, R = entry.at(0.0).pack()
                    for info in bodies:
                        body = next(bd for bd in model.scenes[w].bodies if bd.name == info.name)
                        dist = entry.contact_distance or 0.25 * mean_surface_edge(body.mesh)
                        self.records.append(entry)
                        kind.append(k)
                        a.append(pa)
                        b.append(pb)
                        radius.append(r)
                        rot.append(R)
                        reach.append(dist)
                        mu.append(entry.mu)
                        nodes = np.unique(info.surface)
                        cand_node.append(nodes)
                        cand_obstacle.append(np.full(len(nodes), len(kind) - 1))
                rps = p.item.rows_per_contact
                capacity[w], rows_per_slot[w] = p.item.capacity, rps
                contact_row[w] = p.first_row
                slot_row.append(p.first_row + rps * np.arange(p.item.capacity))
                slot_rows.append(np.full(p.item.capacity, rps))
            cand_start.append(sum(len(c) for c in cand_node))
            slot_start.append(slot_start[-1] + int(capacity[w]))
        self.num_slots = slot_start[-1]
        slot_rows = np.concatenate(slot_rows)
        self.num_entries = int(slot_rows.sum())
        self.num_candidates = cand_start[-1]
        i32 = lambda v: wp.array(np.asarray(v, dtype=np.int32), dtype=wp.int32, device=d)  # noqa: E731
        self.kind, self.reach = i32(kind), wp.array(np.array(reach), dtype=wp.float64, device=d)
        self.mu = wp.array(np.array(mu), dtype=wp.float64, device=d)
        self.a = wp.array(np.array(a), dtype=wp.vec3d, device=d)
        self.b = wp.array(np.array(b), dtype=wp.vec3d, device=d)
        self.radius = wp.array(np.array(radius), dtype=wp.float64, device=d)
        self.rot = wp.array(np.array(rot), dtype=wp.mat33d, device=d)
        self._meshes(d)
        # how a point fixed to each obstacle moves over the step: x -> step_rot x + step_shift
        self.step_rot = wp.array(np.tile(np.eye(3), (len(kind), 1, 1)), dtype=wp.mat33d, device=d)
        self.step_shift = wp.zeros(len(kind), dtype=wp.vec3d, device=d)
        self.moving = [i for i, e in enumerate(self.records) if e.motion is not None]
        self.obstacles = kernels.Obstacles()  # the records as the kernels take them (the same arrays)
        for name in ("kind", "a", "b", "radius", "rot", "mesh", "tri0", "tri_xyz", "reach"):
            setattr(self.obstacles, name, getattr(self, name))
        self._posed_at = None
        self.cand_node = i32(np.concatenate(cand_node))
        self.cand_obstacle = i32(np.concatenate(cand_obstacle))
        self.world_cand_start = i32(cand_start)
        self.capacity = i32(capacity)  # contact slots per world
        self.slot_start, self.contact_row = i32(slot_start), i32(contact_row)
        self.slot_row, self.slot_rows = i32(np.concatenate(slot_row)), i32(slot_rows)
        self.slot_entry = i32(np.concatenate([[0], np.cumsum(slot_rows)[:-1]]))
        self.rows_per_slot, self.rows_per_slot_np = i32(rows_per_slot), rows_per_slot
        self.near = wp.zeros(max(self.num_candidates, 1), dtype=wp.int32, device=d)
        self.cand_lam = wp.zeros((max(self.num_candidates, 1), 3), dtype=wp.float64, device=d)  # warm starts (N)
        self.anchor = wp.zeros(self.num_slots, dtype=wp.vec3d, device=d)  # where each contact's node began (m)
        self.slot_candidate = wp.full(self.num_slots, -1, dtype=wp.int32, device=d)
        self.found = wp.zeros(worlds, dtype=wp.int32, device=d)  # near nodes per world at the last detection
        # host copies, read once: what set_time rewrites for moving obstacles, and the slot layout
        self.host = {name: getattr(self, name).numpy().copy() for name in (
            "a", "b", "rot", "step_rot", "step_shift", "slot_start", "capacity", "contact_row", "slot_entry",
            "cand_node")}

    def _meshes(self, device) -> None:
        """Each mesh obstacle's BVH (``wp.Mesh``, single precision, kept alive here) and its
        triangles' vertices in double; analytic records get id 0 and no triangles."""
        self.bvh, ids, tri0, xyz, made = [], [], [], [], {}
        count = 0
        for entry in self.records:
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

    def forces(self, table, world: int, q: np.ndarray, lam: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The world's contacts in use (host): their nodes' positions ``(k, 3)`` (m) from ``q``
        and the force the obstacle puts on each ``(k, 3)`` (N: ``sum_m lambda_m H_m``, the normal
        force along the normal, friction along the tangents) from the multipliers ``lam``."""
        h = self.host
        start, cap = int(h["slot_start"][world]), int(h["capacity"][world])
        slots = self.slot_candidate.numpy()[start:start + cap]
        used = int(np.count_nonzero(slots >= 0))
        rps = int(self.rows_per_slot_np[world])
        rows = int(h["contact_row"][world]) + np.arange(used * rps)
        entries = self.entry_offset + h["slot_entry"][start:start + used, None] + np.arange(rps)
        coef = table.h_coef.numpy()[entries.ravel()].reshape(used, rps, 3)
        force = np.einsum("km,kmi->ki", lam[rows].reshape(used, rps), coef)
        return q[h["cand_node"][slots[:used]]], force

    def detect(self, table, q: wp.array, lam: wp.array, friction: wp.array) -> None:
        """The nodes within contact distance at ``q`` take their world's contact rows; the
        worlds' force-row counts (actuators + contacts) follow; a contact's multiplier starts
        from its node's at the last step."""
        d = self.model.device
        wp.launch(kernels.mark_candidates, self.num_candidates,
                  inputs=[q, self.cand_node, self.cand_obstacle, self.obstacles], outputs=[self.near], device=d)
        wp.launch(kernels.assign_slots, self.model.num_worlds,
                  inputs=[q, self.world_cand_start, self.near, self.cand_node, self.cand_obstacle, self.mu,
                          self.step_rot, self.step_shift, self.capacity, self.slot_start, self.contact_row,
                          self.rows_per_slot, table.world_actuators_d],
                  outputs=[self.slot_candidate, self.anchor, self.found, table.world_force_rows, lam, friction,
                           self.cand_lam], device=d)

    def evaluate(self, table, q) -> None:
        wp.launch(kernels.contact_rows, self.num_slots,
                  inputs=[q, self.slot_candidate, self.slot_row, self.slot_rows, self.slot_entry, self.anchor,
                          self.cand_node, self.cand_obstacle, self.obstacles, self.entry_offset],
                  outputs=[table.delta, table.h_row, table.h_node, table.h_coef], device=self.model.device)
