"""Cable rows: ``delta = L0 - L``, the shortening (m) of the path pull point -> p_1 -> ... -> p_N
through points carried by the body; ``lambda`` is the tension (N, >= 0); ``H`` per path point
is the unit direction to the previous point plus the one to the next (four entries per point,
through its tetrahedron's weights)."""

from __future__ import annotations

import numpy as np
import warp as wp

from warpsoft.kernels.rows import cable as kernels

from .kind import RowKind


class CableRows(RowKind):
    name, actuator, scene_attr = "cable", True, "cables"

    @staticmethod
    def points(item) -> np.ndarray:
        return item.points

    def __init__(self, model, placed, entry_offset):
        super().__init__(model, placed, entry_offset)
        d = model.device
        counts = np.array([p.num_points for p in placed], dtype=np.int32)
        self.point_offset = placed[0].first_point
        self.num_entries = 4 * int(counts.sum())
        self.start = wp.array(np.array([p.first_point for p in placed], dtype=np.int32), dtype=wp.int32, device=d)
        self.count = wp.array(counts, dtype=wp.int32, device=d)
        self.pull = wp.array(np.array([p.item.pull_point for p in placed]), dtype=wp.vec3d, device=d)
        self.rest_length = wp.array(np.array([p.item.rest_length for p in placed]), dtype=wp.float64, device=d)
        self.row = wp.array(np.array([p.first_row for p in placed], dtype=np.int32), dtype=wp.int32, device=d)

    def evaluate(self, table, q) -> None:
        # the entries of cable point j sit at entry_offset + 4 (j - point_offset): the cables'
        # points are contiguous in the table
        wp.launch(kernels.cable_rows, len(self.placed),
                  inputs=[table.points, table.point_nodes, table.point_weights, self.start, self.count, self.pull,
                          self.rest_length, self.row, self.entry_offset - 4 * self.point_offset],
                  outputs=[table.delta, table.h_row, table.h_node, table.h_coef], device=self.model.device)

    def paths(self, points: np.ndarray, world: int) -> dict[str, np.ndarray]:
        """Each cable's polyline (m, pull point first) in ``world`` from the mapped points ``(p, 3)``."""
        return {p.item.name: np.vstack([p.item.pull_point, points[p.first_point:p.first_point + p.num_points]])
                for p in self.placed if p.world == world}
