"""Attachment rows: soft nodes held by a rigid body (``Scene.attach``). Each held node has three
bilateral rows, ``delta = x_node - (p + R r)`` along x, y and z (m), where ``r`` is the node's
place at ``t = 0`` in the body's frame; their multipliers are free forces (N) that keep
``delta = 0``, on the node and, opposite, on the body. Kernels: ``kernels/rows/attachment.py``."""

from __future__ import annotations

import numpy as np
import warp as wp

from warpsoft.kernels.rows import attachment as kernels

from ..launch import launch
from .kind import RowKind


class AttachmentRows(RowKind):
    name, actuator, columns, bilateral, scene_attr = "attachment", False, True, True, "attachments"

    @staticmethod
    def row_count(item) -> int:
        return 3 * len(item.nodes)

    def __init__(self, model, placed, entry_offset):
        super().__init__(model, placed, entry_offset)
        d = model.device
        rigid_index = {(w, id(rb)): k for k, (w, rb) in enumerate(model.rigid)}
        node, body, local, first = [], [], [], []
        self.ranges = []  # (world, name, first row, held nodes) of each attachment
        for p in placed:
            a = p.item
            ids = a.nodes + model.body_info(a.body.name, p.world).node_start  # (none fixed: Scene.validate)
            node.append(ids)
            body.append(np.full(len(ids), rigid_index[(p.world, id(a.rigid))]))
            local.append(model.rest_np[ids] - a.rigid.center)  # the body's frame: world axes at t = 0
            first.append(p.first_row + 3 * np.arange(len(ids)))
            self.ranges.append((p.world, a.name, p.first_row, len(ids)))
        i32 = lambda v: wp.array(np.concatenate(v).astype(np.int32), dtype=wp.int32, device=d)  # noqa: E731
        self.node, self.body, self.first_row = i32(node), i32(body), i32(first)
        self.local = wp.array(np.concatenate(local), dtype=wp.vec3d, device=d)
        self.num_nodes = len(self.node)
        self.num_entries = self.num_rigid_entries = 3 * self.num_nodes

    def forces(self, lam: np.ndarray, world: int) -> dict[str, np.ndarray]:
        """What each attachment of ``world`` exerts on its soft nodes (N, the sum; the rigid body
        takes the opposite) from the multipliers ``lam`` of all rows."""
        return {name: lam[start:start + 3 * n].reshape(n, 3).sum(axis=0)
                for w, name, start, n in self.ranges if w == world}

    def evaluate(self, table, q) -> None:
        bodies = table.bodies
        launch(kernels.attachment_rows, self.num_nodes,
               inputs=[q, self.node, self.body, self.local, self.first_row, bodies.body_p, bodies.body_r,
                       self.entry_offset, self.rigid_offset],
               outputs=[table.delta, table.h_row, table.h_node, table.h_coef, table.j_row, table.j_body,
                        table.j_lin, table.j_ang], device=self.model.device)
