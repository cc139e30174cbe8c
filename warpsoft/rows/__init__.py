"""Constraint rows: every row of every world in one table.

A row has a measure ``delta(q)``, a direction ``H = d delta / dq`` stored as sparse entries
``(h_row, h_node, h_coef)`` and a multiplier ``lambda``. Rows are laid out world by world; in a
world the force rows come first: the actuator rows (in :data:`ROW_KINDS` order: cables, then
cavities), then the bilateral rows (attachments: always in use), then its block of contact rows
(a fixed capacity, of which the first ``world_force_rows - world_actuators - world_bilateral``
are in use after a detection); then the effector rows.
Force row ``j`` of a world owns compliance column ``j`` (the column count is the largest force
block of a world): a column spans every world's nodes and holds, on world ``w``'s nodes, the
response to world ``w``'s ``j``-th force row. So ``W = H X`` needs no world bookkeeping: a row's
entries touch only its world's nodes.
"""

from __future__ import annotations

import numpy as np
import warp as wp

from warpsoft.kernels.rows import common as kernels
from warpsoft.kernels.rows import mapping

from ..launch import launch
from ..mapping import locate
from ..processes import in_threads
from .attachment import AttachmentRows
from .cable import CableRows
from .cavity import CavityRows
from .contact import ContactRows
from .effector import EffectorRows
from .kind import Placed, RowKind

ROW_KINDS: tuple[type[RowKind], ...] = (CableRows, CavityRows, AttachmentRows, ContactRows, EffectorRows)
"""Row kinds in table order (actuators, then bilateral kinds, then other kinds with columns,
then the rest, within a world); a new kind is one line here."""


class Rows:
    """Device arrays of all constraint rows of a model.

    Attributes (device unless said): ``delta`` ``(rows,)`` row values (m, m^3); ``h_row``,
    ``h_node``, ``h_coef`` ``(entries,)`` the entries of ``H``; ``points`` ``(points,)`` mapped
    points (m); ``j_row``, ``j_body``, ``j_lin``, ``j_ang`` ``(rigid entries,)`` the entries of
    ``H`` on rigid bodies (translation m/m, rotation m/rad; body -1: inert); ``W``
    ``(rows, columns)`` compliance of each row against its world's actuator
    columns (m/N, m^3/Pa). Host: ``world_row_start`` ``(worlds + 1,)``, ``world_actuators``
    ``(worlds,)``, ``world_bilateral`` ``(worlds,)`` (attachment rows), ``world_contacts``
    ``(worlds,)`` (contact capacity), ``num_columns`` (largest
    force block of a world), ``kinds`` (one object per row kind present), ``actuators[w]`` and
    ``effectors[w]`` (the scene items, in row order). Device: ``world_force_rows`` ``(worlds,)``,
    the force rows in use (actuators and the contacts of the last detection).
    """

    def __init__(self, model):
        d = self.device = model.device
        self.model = model
        self.num_worlds = model.num_worlds
        order = ([k for k in ROW_KINDS if k.actuator] + [k for k in ROW_KINDS if k.bilateral]
                 + [k for k in ROW_KINDS if k.columns and not (k.actuator or k.bilateral)]
                 + [k for k in ROW_KINDS if not k.columns])
        placed: dict[type[RowKind], list[Placed]] = {k: [] for k in order}
        row, starts, counts, bilateral, contacts = 0, [0], [], [], []
        self.actuators, self.effectors = [], []
        for w, scene in enumerate(model.scenes):
            na = nb = nc = 0
            for kind in order:
                for item in kind.items(scene):
                    n = kind.row_count(item)
                    placed[kind].append(Placed(w, item, row, n))
                    row += n
                    na += n if kind.actuator else 0
                    nb += n if kind.bilateral else 0
                    nc += n if kind.columns and not (kind.actuator or kind.bilateral) else 0
            counts.append(na)
            bilateral.append(nb)
            contacts.append(nc)
            starts.append(row)
            self.actuators.append([p.item for k in order if k.actuator for p in placed[k] if p.world == w])
            self.effectors.append([p.item for p in placed[EffectorRows] if p.world == w])
        self.num_rows = row
        self._effectors_by_world = None  # (index in the effector table, placed) per world, made when first read
        self.world_row_start = np.array(starts, dtype=np.int32)
        self.world_actuators = np.array(counts, dtype=np.int32)
        self.world_bilateral = np.array(bilateral, dtype=np.int32)
        self.world_contacts = np.array(contacts, dtype=np.int32)
        held = self.world_actuators + self.world_bilateral  # the force rows always in use
        self.num_columns = int((held + self.world_contacts).max(initial=0))
        self.world_row_start_d = wp.array(self.world_row_start, dtype=wp.int32, device=d)
        self.world_actuators_d = wp.array(self.world_actuators, dtype=wp.int32, device=d)
        self.world_held_d = wp.array(held, dtype=wp.int32, device=d)
        self.world_force_rows = wp.array(held, dtype=wp.int32, device=d)  # no contact yet
        self.force_columns = wp.array([held.max(initial=0)], dtype=wp.int32, device=d)  # columns in use

        # mapped points, kind by kind (a kind's points are contiguous), each located in its elements
        spans, point = {}, 0  # (lo, hi) elements -> [(first point, points, names)] to locate in them
        for kind in order:
            for p in placed[kind]:
                pts = kind.points(p.item)
                if not len(pts):
                    continue
                names = ([f"effector '{p.item.name}'"] if kind is EffectorRows
                         else [f"{kind.name} '{p.item.name}' point {k}" for k in range(len(pts))])
                spans.setdefault(kind.point_elements(model, p.world, p.item), []).append((point, pts, names))
                p.first_point, p.num_points = point, len(pts)
                point += len(pts)
        self.num_points = point
        nodes, weights = np.zeros((point, 4), dtype=np.int32), np.zeros((point, 4))
        # a body's points at once: one search tree of its elements (1,024 Diamonds on the VM, in
        # cProfile: 7.7 -> 2.9 s, a tree per cable and effector before)
        def body_points(span) -> tuple[np.ndarray, tuple[np.ndarray, np.ndarray]]:
            (lo, hi), items = span
            at = np.concatenate([np.arange(first, first + len(pts)) for first, pts, _ in items])
            return at, locate(model.rest_np, model.tets_np[lo:hi], np.concatenate([pts for _, pts, _ in items]),
                              [name for _, _, names in items for name in names])

        for at, (ids, w) in in_threads(body_points, list(spans.items())):
            nodes[at], weights[at] = ids, w
        self.point_nodes = wp.array(nodes, dtype=wp.vec4i, device=d) if point else None
        self.point_weights = wp.array(weights, dtype=wp.vec4d, device=d) if point else None
        self.points = wp.zeros(max(point, 1), dtype=wp.vec3d, device=d)

        self.kinds, entry, base = [], 0, np.zeros(self.num_rows)
        for kind in order:
            if placed[kind]:
                block = kind(model, placed[kind], entry)
                entry += block.num_entries
                for r, v in block.rest_delta().items():
                    base[r] = v
                self.kinds.append(block)
        self.num_entries = entry
        # entries on rigid bodies (contacts that touch one): (row, body, j_lin, j_ang), each kind's
        # block from its rigid_offset; only in models with rigid bodies
        self.num_rigid_entries = 0
        for block in self.kinds:
            block.rigid_offset = self.num_rigid_entries
            self.num_rigid_entries += getattr(block, "num_rigid_entries", 0)
        n_rigid = max(self.num_rigid_entries, 1)
        self.j_row = wp.zeros(n_rigid, dtype=wp.int32, device=d)
        self.j_body = wp.full(n_rigid, -1, dtype=wp.int32, device=d)
        self.j_lin = wp.zeros(n_rigid, dtype=wp.vec3d, device=d)
        self.j_ang = wp.zeros(n_rigid, dtype=wp.vec3d, device=d)
        self.bodies = None  # the State whose rigid poses the rows are evaluated at (None: no rigid body)
        self.delta_base = wp.array(base, dtype=wp.float64, device=d)
        self.delta = wp.zeros(self.num_rows, dtype=wp.float64, device=d)
        self.h_row = wp.zeros(entry, dtype=wp.int32, device=d)
        self.h_node = wp.zeros(entry, dtype=wp.int32, device=d)
        self.h_coef = wp.zeros(entry, dtype=wp.vec3d, device=d)
        col = np.full(self.num_rows, -1, dtype=np.int32)
        for w in range(self.num_worlds):
            nf = counts[w] + bilateral[w] + contacts[w]
            col[starts[w]:starts[w] + nf] = np.arange(nf)
        self.column_of_row = wp.array(col, dtype=wp.int32, device=d)
        self.W = wp.zeros((self.num_rows, max(self.num_columns, 1)), dtype=wp.float64, device=d)
        self.delta_free = wp.zeros(max(self.num_rows, 1), dtype=wp.float64, device=d)

    # ---- what a world holds ---------------------------------------------------------------
    def kind(self, name: str) -> RowKind | None:
        """The block of row kind ``name`` ("cable", "cavity", "effector"), or None."""
        return next((k for k in self.kinds if k.name == name), None)

    def actuator_rows(self, world: int) -> slice:
        s = int(self.world_row_start[world])
        return slice(s, s + int(self.world_actuators[world]))

    def bilateral_rows(self, world: int) -> slice:
        """The world's attachment rows (after its actuators)."""
        s = self.actuator_rows(world).stop
        return slice(s, s + int(self.world_bilateral[world]))

    def contact_rows(self, world: int) -> slice:
        """The world's block of contact rows (its capacity; the first ones are in use)."""
        s = self.bilateral_rows(world).stop
        return slice(s, s + int(self.world_contacts[world]))

    def contacts_in_use(self, world: int, force_rows: int) -> int:
        """The world's contacts of the last detection, from its force rows in use."""
        held = int(self.world_actuators[world] + self.world_bilateral[world])
        return (int(force_rows) - held) // self.rows_per_contact(world)

    def rows_per_contact(self, world: int) -> int:
        """Rows per contact slot of the world: 3 with friction (normal, two tangents), else 1."""
        contact = self.kind("contact")
        return int(contact.rows_per_slot_np[world]) if contact is not None else 1

    def effector_rows(self, world: int) -> slice:
        return slice(self.contact_rows(world).stop, int(self.world_row_start[world + 1]))

    @property
    def num_actuators(self) -> int:
        """Actuator rows of all worlds."""
        return int(self.world_actuators.sum())

    def detect(self, q: wp.array, lam: wp.array, friction: wp.array, bodies=None) -> None:
        """Contacts at ``q`` (and the rigid poses of the State ``bodies``): which nodes and rigid
        points take the contact rows of this step, their multipliers' warm starts and their
        tangent rows' friction coefficients."""
        contact = self.kind("contact")
        if contact is not None:
            self.bodies = bodies
            contact.detect(self, q, lam, friction)
            launch(kernels.most_force_rows, 1, inputs=[self.world_force_rows], outputs=[self.force_columns],
                   device=self.device)

    @property
    def effector_row_slice(self) -> slice:
        """The effector rows of a one-world model."""
        return self.effector_rows(0)

    # ---- evaluation -------------------------------------------------------------------------
    def set_time(self, t: float) -> np.ndarray | None:
        """Upload the effector targets, the moving obstacles' poses and moving pull points at
        time ``t`` (the step's end); returns the targets ``(effectors, 3)`` (m), in table order,
        or None without effectors."""
        contact, cable = self.kind("contact"), self.kind("cable")
        if contact is not None:
            contact.set_time(t, self.model.dt)
        if cable is not None:
            cable.set_time(t)  # pull points that ride a frame
        eff = self.kind("effector")
        return eff.set_time(t) if eff is not None else None

    def evaluate(self, q: wp.array, bodies=None) -> None:
        """``delta`` and ``H`` of every row at positions ``q`` (and the rigid poses of the State
        ``bodies``, in a model with rigid bodies): one launch per kind, all worlds."""
        self.bodies = bodies
        if self.num_points:
            launch(mapping.interpolate_points, self.num_points, inputs=[q, self.point_nodes, self.point_weights],
                   outputs=[self.points], device=self.device)
        wp.copy(self.delta, self.delta_base)
        for block in self.kinds:
            block.evaluate(self, q)

    def actuator_columns(self, columns: wp.array) -> None:
        """``columns[j] = H_j^T`` for each world's ``j``-th force row (``(columns, n)`` vec3d)."""
        columns.zero_()
        launch(kernels.rows_to_columns, self.num_entries,
               inputs=[self.h_row, self.h_node, self.h_coef, self.column_of_row], outputs=[columns],
               device=self.device)

    def compliance(self, x: wp.array, scale: float) -> None:
        """``W = scale H X`` (device) against the actuator columns ``X``; ``(rows, columns)``, row
        ``r`` against its own world's columns. Only the columns of force rows in use are formed
        (a cavity's thousands of entries against every contact slot's column cost 20 ms on the
        pneunet): on the CPU device the launch is that wide (the count is read in place); a CUDA
        graph launches every column and the threads past the count return."""
        self.W.zero_()
        columns = self.num_columns
        if not self.device.is_cuda:
            columns = int(self.force_columns.numpy()[0])
        launch(kernels.rows_times_columns, (self.num_entries, columns),
               inputs=[self.h_row, self.h_node, self.h_coef, x, scale, self.force_columns], outputs=[self.W],
               device=self.device)

    def predict(self, dx: wp.array) -> wp.array:
        """``delta_free = delta + H dx`` (device, ``(rows,)``) for one displacement ``dx`` (``(1, n)``
        vec3d): the rows after the free motion, to first order (linearized where ``A`` is)."""
        wp.copy(self.delta_free, self.delta, count=self.num_rows)
        launch(kernels.rows_times_vector, self.num_entries, inputs=[self.h_row, self.h_node, self.h_coef, dx, 0],
               outputs=[self.delta_free], device=self.device)
        return self.delta_free

    def shift(self, dx: wp.array) -> None:
        """``delta += H dx`` (device) for a known motion ``dx`` (``(1, n)`` vec3d, m): the rows
        after it, to first order (a kinematic frame's move, taken as part of the step)."""
        launch(kernels.rows_times_vector, self.num_entries, inputs=[self.h_row, self.h_node, self.h_coef, dx, 0],
               outputs=[self.delta], device=self.device)

    def correct(self, dx_free: wp.array, x: wp.array, lam: wp.array, scale: float, dx: wp.array) -> None:
        """``dx = dx_free + scale X lambda`` (m): ``dx_free`` ``(n,)``, the columns ``x``
        ``(columns, n)``, ``lam`` per row (the force rows in use)."""
        m = self.model
        launch(kernels.correct_with_columns, m.num_nodes,
               inputs=[dx_free, x, lam, m.node_world, self.world_row_start_d, self.world_force_rows, scale],
               outputs=[dx], device=self.device)

    def force_rows_forces(self, lam: wp.array, scale: float, force: wp.array) -> None:
        """``force = scale H_f^T lam`` (device, ``(n,)`` vec3d, N x scale) over each world's force
        rows in use: the right-hand side of the correction's one solve (the CPU path)."""
        force.zero_()
        launch(kernels.force_rows_transpose_times, self.num_entries,
               inputs=[self.h_row, self.h_node, self.h_coef, lam, scale, self.column_of_row, self.model.node_world,
                       self.world_force_rows], outputs=[force], device=self.device)

    def forces(self, lam: np.ndarray) -> np.ndarray:
        """Nodal forces ``H^T lambda`` (N), ``(n, 3)``, for multipliers of all rows."""
        f = wp.zeros(self.model.num_nodes, dtype=wp.vec3d, device=self.device)
        launch(kernels.rows_transpose_times, self.num_entries,
               inputs=[self.h_row, self.h_node, self.h_coef, wp.array(lam, dtype=wp.float64, device=self.device)],
               outputs=[f], device=self.device)
        return f.numpy()

    # ---- geometry for reports and USD -------------------------------------------------------
    def point_positions(self) -> np.ndarray:
        """Mapped cable and effector points (m) of the last :meth:`evaluate`, ``(p, 3)``."""
        return self.points.numpy()[: self.num_points].copy()

    def effector_positions(self, world: int = 0, points: np.ndarray | None = None) -> dict[str, np.ndarray]:
        """Effector points (m) of ``world`` at the last :meth:`evaluate`, by name (from ``points``,
        a :meth:`point_positions` already read, when given: one read serves every world)."""
        if self.kind("effector") is None:
            return {}
        pts = self.point_positions() if points is None else points
        return {p.item.name: pts[p.first_point] for _, p in self._world_effectors(world)}

    def targets(self, all_targets: np.ndarray | None, world: int = 0) -> dict[str, np.ndarray]:
        """The targets (m) of ``world``'s targeted effectors, by name, from :meth:`set_time`'s result."""
        if self.kind("effector") is None or all_targets is None:
            return {}
        return {p.item.name: all_targets[k] for k, p in self._world_effectors(world) if p.item.target is not None}

    def _world_effectors(self, world: int) -> list[tuple[int, Placed]]:
        """``world``'s effectors with their index in the effector table (found once for all worlds:
        a report of many worlds reads them for each world every step)."""
        if self._effectors_by_world is None:
            self._effectors_by_world = [[] for _ in range(self.model.num_worlds)]
            for k, p in enumerate(self.kind("effector").placed):
                self._effectors_by_world[p.world].append((k, p))
        return self._effectors_by_world[world]

    def cable_paths(self, world: int = 0) -> dict[str, np.ndarray]:
        """Cable polylines (m, pull point first) of ``world`` at the last :meth:`evaluate`."""
        cab = self.kind("cable")
        return cab.paths(self.point_positions(), world) if cab is not None else {}


__all__ = ["ROW_KINDS", "Placed", "RowKind", "Rows"]
