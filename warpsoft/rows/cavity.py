"""Pneumatic cavity rows: ``delta = V - V0`` (m^3), the growth of the volume enclosed by the
cavity's closed, oriented surface; ``lambda`` its pressure (Pa); ``H = dV/dq`` per node, the
sum over its triangles of area x normal / 3 (one thread per triangle)."""

from __future__ import annotations

import numpy as np
import warp as wp

from warpsoft.kernels.rows import cavity as kernels

from ..launch import launch
from ..scene.cavity import enclosed_volume
from .kind import RowKind


class CavityRows(RowKind):
    name, actuator, columns, scene_attr = "cavity", True, True, "cavities"

    def __init__(self, model, placed, entry_offset):
        super().__init__(model, placed, entry_offset)
        d = model.device
        tris, tri_row, origins, self.rest_volume = [], [], [], []
        for p in placed:
            cav = p.item
            local = cav.surface()
            origin = cav.origin(local)
            tris.append(local + model.body_info(cav.body.name, p.world).node_start)
            tri_row.append(np.full(len(local), p.first_row, dtype=np.int32))
            origins.append(np.repeat(origin[None, :], len(local), axis=0))
            self.rest_volume.append(enclosed_volume(cav.body.mesh.nodes, local, origin))
        self.triangles = np.concatenate(tris).astype(np.int32)
        self.num_entries = 3 * len(self.triangles)
        self.tris = wp.array(self.triangles, dtype=wp.vec3i, device=d)
        self.tri_row = wp.array(np.concatenate(tri_row), dtype=wp.int32, device=d)
        self.tri_origin = wp.array(np.concatenate(origins), dtype=wp.vec3d, device=d)

    def rest_delta(self) -> dict[int, float]:
        return {p.first_row: -v for p, v in zip(self.placed, self.rest_volume, strict=True)}

    def evaluate(self, table, q) -> None:
        """Accumulate ``V`` into ``delta``, which holds ``-V0`` on these rows."""
        launch(kernels.cavity_rows, len(self.triangles),
               inputs=[q, self.tris, self.tri_row, self.tri_origin, self.entry_offset],
               outputs=[table.delta, table.h_row, table.h_node, table.h_coef], device=self.model.device)
