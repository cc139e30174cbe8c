"""All constraint rows of a model, laid out as actuator rows first (cables, then cavities),
then effector rows; ``H`` as sparse entries shared by every row type."""

from __future__ import annotations

import numpy as np
import warp as wp

from warpsoft.kernels import mapping, rows

from ..mapping import locate
from .cable import CableRows
from .cavity import CavityRows
from .effector import EffectorRows


class ConstraintSet:
    """Device arrays and kernels of a model's constraint rows.

    Attributes:
        actuators: the scene's actuators in row order (rows ``0 .. na-1``).
        effectors: the scene's effectors (rows ``na ..``, one per controlled axis).
        delta: ``(rows,)`` current row values; ``W``: ``(rows, na)`` compliance of the last
            :meth:`compliance` call (device).
    """

    def __init__(self, model, cables, cavities, effectors):
        d = model.device
        self.model = model
        self.actuators = list(cables) + list(cavities)
        self.effectors = list(effectors)
        self.num_actuators = len(self.actuators)
        # mapped points: every cable's path points (each inside its own body), then the effectors
        nodes, weights = [], []
        for c in cables:
            info = model.body_info(c.body.name)
            tets = model.tets_np[info.elem_start:info.elem_start + info.elem_count]
            names = [f"cable '{c.name}' point {k}" for k in range(len(c.points))]
            ids, w = locate(model.rest_np, tets, c.points, names)
            nodes.append(ids)
            weights.append(w)
        if effectors:
            ids, w = locate(model.rest_np, model.tets_np, np.array([e.point for e in effectors]),
                            [f"effector '{e.name}'" for e in effectors])
            nodes.append(ids)
            weights.append(w)
        self.num_points = sum(len(n) for n in nodes)
        row = entry = 0
        self.cables = self.cavities = self.effector_rows = None
        if cables:
            self.cables = CableRows(list(cables), list(range(len(cables))), 0, d)
            row += len(cables)
        if cavities:
            offsets = [model.body_info(c.body.name).node_start for c in cavities]
            self.cavities = CavityRows(list(cavities), list(range(row, row + len(cavities))), offsets, d)
            row += len(cavities)
        if effectors:
            n_cable_points = sum(len(c.points) for c in cables)
            self.effector_rows = EffectorRows(list(effectors), row, n_cable_points, d)
            row += len(self.effector_rows.rows)
        self.num_rows = row
        for block in (self.cables, self.cavities, self.effector_rows):
            if block is not None:
                block.entry_offset = entry
                entry += block.num_entries
        self.num_entries = entry

        self.point_nodes = wp.array(np.concatenate(nodes), dtype=wp.vec4i, device=d) if nodes else None
        self.point_weights = wp.array(np.concatenate(weights), dtype=wp.vec4d, device=d) if nodes else None
        self.points = wp.zeros(max(self.num_points, 1), dtype=wp.vec3d, device=d)
        base = np.zeros(self.num_rows)
        if self.cavities is not None:
            base[self.cavities.rows] = -np.array(self.cavities.rest_volume)
        self.delta_base = wp.array(base, dtype=wp.float64, device=d)
        self.delta = wp.zeros(self.num_rows, dtype=wp.float64, device=d)
        self.h_row = wp.zeros(self.num_entries, dtype=wp.int32, device=d)
        self.h_node = wp.zeros(self.num_entries, dtype=wp.int32, device=d)
        self.h_coef = wp.zeros(self.num_entries, dtype=wp.vec3d, device=d)
        col = np.full(self.num_rows, -1, dtype=np.int32)
        col[: self.num_actuators] = np.arange(self.num_actuators)
        self.column_of_row = wp.array(col, dtype=wp.int32, device=d)
        self.W = wp.zeros((self.num_rows, max(self.num_actuators, 1)), dtype=wp.float64, device=d)
        self._change = wp.zeros((self.num_rows, 1), dtype=wp.float64, device=d)

    @property
    def effector_row_slice(self) -> slice:
        return slice(self.num_actuators, self.num_rows)

    def set_time(self, t: float) -> np.ndarray | None:
        """Update time-dependent effector targets; returns the targets ``(e, 3)`` (m) or None."""
        return self.effector_rows.set_time(t) if self.effector_rows is not None else None

    def evaluate(self, q: wp.array) -> None:
        """``delta`` and ``H`` of every row at positions ``q``."""
        d = self.model.device
        if self.num_points:
            wp.launch(mapping.interpolate_points, self.num_points, inputs=[q, self.point_nodes, self.point_weights],
                      outputs=[self.points], device=d)
        wp.copy(self.delta, self.delta_base)
        out = [self.delta, self.h_row, self.h_node, self.h_coef]
        if self.cables is not None:
            self.cables.evaluate(self.points, self.point_nodes, self.point_weights, self.cables.entry_offset, *out)
        if self.cavities is not None:
            self.cavities.evaluate(q, self.cavities.entry_offset, *out)
        if self.effector_rows is not None:
            self.effector_rows.evaluate(self.points, self.point_nodes, self.point_weights,
                                        self.effector_rows.entry_offset, *out)

    def actuator_columns(self, columns: wp.array) -> None:
        """``columns[c] = H_c^T`` for each actuator row ``c`` (``(na, n)`` vec3d)."""
        columns.zero_()
        wp.launch(rows.rows_to_columns, self.num_entries,
                  inputs=[self.h_row, self.h_node, self.h_coef, self.column_of_row], outputs=[columns],
                  device=self.model.device)

    def compliance(self, x: wp.array, scale: float) -> np.ndarray:
        """``W = scale * H X`` for all rows against the actuator columns ``X``; ``(rows, na)``."""
        self.W.zero_()
        wp.launch(rows.rows_times_columns, (self.num_entries, self.num_actuators),
                  inputs=[self.h_row, self.h_node, self.h_coef, x, scale], outputs=[self.W], device=self.model.device)
        return self.W.numpy().copy()

    def linear_change(self, dx: wp.array) -> np.ndarray:
        """``H dx`` for one displacement ``dx`` (``(1, n)`` vec3d): the rows' first-order change."""
        self._change.zero_()
        wp.launch(rows.rows_times_columns, (self.num_entries, 1),
                  inputs=[self.h_row, self.h_node, self.h_coef, dx, 1.0], outputs=[self._change],
                  device=self.model.device)
        return self._change.numpy()[:, 0].copy()

    def forces(self, lam: np.ndarray) -> np.ndarray:
        """Nodal forces ``H^T lambda`` (N), ``(n, 3)``, for multipliers of all rows."""
        m = self.model
        f = wp.zeros(m.num_nodes, dtype=wp.vec3d, device=m.device)
        wp.launch(rows.rows_transpose_times, self.num_entries,
                  inputs=[self.h_row, self.h_node, self.h_coef, wp.array(lam, dtype=wp.float64, device=m.device)],
                  outputs=[f], device=m.device)
        return f.numpy()

    def point_positions(self) -> np.ndarray:
        """Mapped cable and effector points (m) of the last :meth:`evaluate`, ``(p, 3)``."""
        return self.points.numpy()[: self.num_points].copy()

    def effector_positions(self) -> dict[str, np.ndarray]:
        n_cable = self.num_points - len(self.effectors)
        pts = self.point_positions()
        return {e.name: pts[n_cable + k] for k, e in enumerate(self.effectors)}
