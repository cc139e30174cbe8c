"""Pneumatic cavity rows: ``delta = V - V0`` (m^3), the growth of the volume enclosed by the
cavity's closed, oriented surface; ``lambda`` its pressure (Pa); ``H = dV/dq`` per node, the
volume's exact gradient, summed over weighted triple products of the surface's nodes (one thread
each: a linear triangle, or one of the twenty of a 6-node face; :mod:`warpsoft.scene.surface`)."""

from __future__ import annotations

import numpy as np
import warp as wp

from warpsoft.kernels.rows import cavity as kernels

from ..launch import launch
from ..scene.surface import enclosed_volume, volume_terms
from .kind import RowKind


class CavityRows(RowKind):
    name, actuator, columns, scene_attr = "cavity", True, True, "cavities"

    def __init__(self, model, placed, entry_offset):
        super().__init__(model, placed, entry_offset)
        d = model.device
        tris, weights, tri_row, origins, self.rest_volume = [], [], [], [], []
        for p in placed:
            cav = p.item
            local = cav.surface()
            origin = cav.origin(local)
            triples, w = volume_terms(cav.body.mesh, local, f"cavity '{cav.name}'")
            tris.append(triples + model.body_info(cav.body.name, p.world).node_start)
            weights.append(w)
            tri_row.append(np.full(len(triples), p.first_row, dtype=np.int32))
            origins.append(np.repeat(origin[None, :], len(triples), axis=0))
            self.rest_volume.append(enclosed_volume(cav.body.mesh.nodes, triples, w, origin))
        self.triangles = np.concatenate(tris).astype(np.int32)  # node triples (k, 3)
        self.num_entries = 3 * len(self.triangles)
        self.tris = wp.array(self.triangles, dtype=wp.vec3i, device=d)
        self.tri_weight = wp.array(np.concatenate(weights), dtype=wp.float64, device=d)
        self.tri_row = wp.array(np.concatenate(tri_row), dtype=wp.int32, device=d)
        self.tri_origin = wp.array(np.concatenate(origins), dtype=wp.vec3d, device=d)

    def rest_delta(self) -> dict[int, float]:
        return {p.first_row: -v for p, v in zip(self.placed, self.rest_volume, strict=True)}

    def evaluate(self, table, q) -> None:
        """Accumulate ``V`` into ``delta``, which holds ``-V0`` on these rows."""
        launch(kernels.cavity_rows, len(self.triangles),
               inputs=[q, self.tris, self.tri_weight, self.tri_row, self.tri_origin, self.entry_offset],
               outputs=[table.delta, table.h_row, table.h_node, table.h_coef], device=self.model.device)
