"""Effector rows: ``delta = x(p) - x_target`` (m) on each controlled axis of a point mapped into
the mesh; ``H`` is the mapping weights on that axis. Effectors carry no force: they are what the
inverse model steers (with no target, ``delta`` is the point's displacement)."""

from __future__ import annotations

import numpy as np
import warp as wp

from warpsoft.kernels.rows import effector as kernels

from ..launch import launch
from .kind import RowKind


class EffectorRows(RowKind):
    name, actuator, scene_attr = "effector", False, "effectors"

    @staticmethod
    def row_count(item) -> int:
        return len(item.axes)

    @staticmethod
    def points(item) -> np.ndarray:
        return item.point[None, :]

    @staticmethod
    def point_elements(model, world, item) -> tuple[int, int]:
        return int(model.world_elem_start[world]), int(model.world_elem_start[world + 1])  # any body of its world

    def __init__(self, model, placed, entry_offset):
        super().__init__(model, placed, entry_offset)
        d = model.device
        point, axis, rows = [], [], []
        for p in placed:
            for k, a in enumerate(p.item.axis_ids):
                point.append(p.first_point)
                axis.append(a)
                rows.append(p.first_row + k)
        self.num_entries = 4 * len(rows)
        self.point = wp.array(np.array(point, dtype=np.int32), dtype=wp.int32, device=d)
        self.axis = wp.array(np.array(axis, dtype=np.int32), dtype=wp.int32, device=d)
        self.row = wp.array(np.array(rows, dtype=np.int32), dtype=wp.int32, device=d)
        self.target = wp.zeros(len(rows), dtype=wp.float64, device=d)
        self.constant = not any(callable(p.item.target) for p in placed)
        self._targets, self._time = None, None

    def set_time(self, t: float) -> np.ndarray:
        """The targets (m) at time ``t``, ``(effectors, 3)`` in table order, uploaded in one copy:
        the user's functions are called once per time, and once only when none depends on time."""
        if self._targets is None or (not self.constant and t != self._time):
            self._time = t
            targets = np.array([p.item.target_at(t) for p in self.placed])
            per_row = np.concatenate([targets[k, p.item.axis_ids] for k, p in enumerate(self.placed)])
            self.target.assign(per_row)
            self._targets = targets
        return self._targets

    def evaluate(self, table, q) -> None:
        launch(kernels.effector_rows, len(self.row),
               inputs=[table.points, table.point_nodes, table.point_weights, self.point, self.axis, self.target,
                       self.row, self.entry_offset],
               outputs=[table.delta, table.h_row, table.h_node, table.h_coef], device=self.model.device)
