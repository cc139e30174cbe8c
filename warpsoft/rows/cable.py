"""Cable rows: ``delta = L0 - L``, the shortening (m) of the path pull point -> p_1 -> ... -> p_N
through points carried by the body; ``lambda`` is the tension (N, >= 0); ``H`` per path point
is the unit direction to the previous point plus the one to the next (four entries per point,
through its tetrahedron's weights). A cable fastened over an anchor (``anchor_radius > 0``) ends
at the mean motion of the material within that radius of its last point
(:func:`warpsoft.mapping.ball_weights`): its pull is spread over those nodes, as a knot or a
washer spreads it, and converges under refinement where a point's does not."""

from __future__ import annotations

import numpy as np
import warp as wp

from warpsoft.kernels.rows import cable as kernels

from ..errors import SceneError
from ..launch import launch
from ..mapping import ball_weights, barycentric, locate
from ..processes import in_threads
from ..scene.obstacles import pose_of
from .kind import RowKind


class CableRows(RowKind):
    name, actuator, columns, scene_attr = "cable", True, True, "cables"

    @staticmethod
    def points(item) -> np.ndarray:
        return item.points

    def __init__(self, model, placed, entry_offset):
        super().__init__(model, placed, entry_offset)
        by_body = {}  # (body, world) -> its cables, checked in turn (they share its elements' boxes)
        for p in placed:
            by_body.setdefault((p.item.body.name, p.world), []).append(p)

        def check(cables: list) -> None:
            boxes = {}
            for p in cables:
                check_pull_point(model, p, boxes)

        in_threads(check, list(by_body.values()))
        d = model.device
        counts = np.array([p.num_points for p in placed], dtype=np.int32)
        self.point_offset = placed[0].first_point
        # anchors: node ids and weights of each anchored cable, one block after the points' entries
        a_start, a_count, a_nodes, a_weights, a_offset = [], [], [], [], []
        for p in placed:
            cable = p.item
            a_start.append(sum(len(ids) for ids in a_nodes))
            if cable.anchor_radius > 0.0:
                lo, hi = self.point_elements(model, p.world, cable)
                ids, w = ball_weights(model.rest_np, model.tets_np[lo:hi], cable.points[-1], cable.anchor_radius,
                                      f"cable '{cable.name}': anchor")
                a_nodes.append(ids)
                a_weights.append(w)
                a_offset.append(cable.points[-1] - w @ model.rest_np[ids])  # (the ball's part in the body)
            else:
                a_offset.append(np.zeros(3))
            a_count.append(len(a_nodes[-1]) if cable.anchor_radius > 0.0 else 0)
        anchors = int(sum(a_count))
        self.num_entries = 4 * int(counts.sum()) + anchors
        self.anchor_entry = entry_offset + 4 * int(counts.sum())
        self.anchor_start = wp.array(np.array(a_start, dtype=np.int32), dtype=wp.int32, device=d)
        self.anchor_count = wp.array(np.array(a_count, dtype=np.int32), dtype=wp.int32, device=d)
        self.anchor_node = wp.array(np.concatenate(a_nodes) if anchors else np.zeros(1, np.int32), dtype=wp.int32,
                                    device=d)
        self.anchor_weight = wp.array(np.concatenate(a_weights) if anchors else np.zeros(1), dtype=wp.float64,
                                      device=d)
        self.anchor_offset = wp.array(np.array(a_offset), dtype=wp.vec3d, device=d)
        self.start = wp.array(np.array([p.first_point for p in placed], dtype=np.int32), dtype=wp.int32, device=d)
        self.count = wp.array(counts, dtype=wp.int32, device=d)
        self.pull_host = np.array([p.item.pull_point for p in placed])  # where each is now (m)
        self.pull = wp.array(self.pull_host, dtype=wp.vec3d, device=d)
        self.moving = [k for k, p in enumerate(placed) if p.item.pull_motion is not None]
        self._posed_at = None  # the time the pull points were last placed at (s)
        self.rest_length = wp.array(np.array([p.item.rest_length for p in placed]), dtype=wp.float64, device=d)
        self.row = wp.array(np.array([p.first_row for p in placed], dtype=np.int32), dtype=wp.int32, device=d)

    def set_time(self, t: float) -> None:
        """The pull points that ride a frame, where it is at ``t`` (s): one upload, once per time."""
        if not self.moving or self._posed_at == t:
            return
        for k in self.moving:
            cable = self.placed[k].item
            rotation, translation = pose_of(cable.pull_motion, t, f"cable '{cable.name}': pull_motion")
            self.pull_host[k] = rotation @ cable.pull_point + translation
        self.pull.assign(self.pull_host)
        self._posed_at = t

    def evaluate(self, table, q) -> None:
        # the entries of cable point j sit at entry_offset + 4 (j - point_offset): the cables'
        # points are contiguous in the table
        launch(kernels.cable_rows, len(self.placed),
               inputs=[q, table.points, table.point_nodes, table.point_weights, self.start, self.count, self.pull,
                       self.rest_length, self.row, self.entry_offset - 4 * self.point_offset, self.anchor_start,
                       self.anchor_count, self.anchor_node, self.anchor_weight, self.anchor_offset,
                       self.anchor_entry],
               outputs=[table.delta, table.h_row, table.h_node, table.h_coef], device=self.model.device)

    def paths(self, points: np.ndarray, world: int) -> dict[str, np.ndarray]:
        """Each cable's polyline (m, pull point first) in ``world`` from the mapped points ``(p, 3)``."""
        return {p.item.name: np.vstack([self.pull_host[k], points[p.first_point:p.first_point + p.num_points]])
                for k, p in enumerate(self.placed) if p.world == world}


def check_pull_point(model, placed, boxes: dict | None = None) -> None:
    """A cable is pulled from a point fixed in space. One inside a moving part of its body would
    be passed by the body, and one on the first path point where that point moves leaves the
    pull without a direction: either turns or reverses the command, so both are errors. (A pull
    point on the body's fixed face is fine: only fixed nodes carry it.) ``boxes``: the bodies'
    element boxes found so far, ``(body, world) -> (lower, upper)`` ``(m, 3)`` each (m), kept for
    the body's next cable."""
    cable, info = placed.item, model.body_info(placed.item.body.name, placed.world)
    nodes = model.rest_np
    tets = model.tets_np[info.elem_start:info.elem_start + info.elem_count]
    body = nodes[info.node_start:info.node_start + info.node_count]
    lo, hi = body.min(axis=0), body.max(axis=0)  # the body's box (m)
    size = float((hi - lo).max())

    def moves(ids: np.ndarray, weights: np.ndarray) -> bool:  # the point's nodes (weight != 0) not all fixed
        return bool(np.any(model.mask_np[ids[np.abs(weights) > 1e-9]] != 0.0))

    # only a point in the body's box can be in one of its elements, and only in one whose box holds
    # it (1,024 Diamonds' 4,096 cables on the VM, in cProfile: 8.3 s when each was solved against
    # every element of its body, 1.8 s so)
    p, pad = cable.pull_point, 1e-6 * max(size, 1e-3)
    near = np.zeros(0, dtype=np.int64)
    if np.all((lo - pad <= p) & (p <= hi + pad)):
        boxes = {} if boxes is None else boxes
        if (info.name, info.world) not in boxes:
            x = nodes[tets]  # (m, 4, 3) m
            boxes[info.name, info.world] = x.min(axis=1), x.max(axis=1)
        low, high = boxes[info.name, info.world]
        near = np.flatnonzero(np.all((low <= p + pad) & (p - pad <= high), axis=1))
    lam = barycentric(nodes, tets[near], p)
    if any(moves(tets[e], w) for e, w in zip(near, lam, strict=True) if w.min() >= -1e-9):
        raise SceneError(f"cable '{cable.name}': its pull point {cable.pull_point.tolist()} m lies inside body "
                         f"'{info.name}' where the body moves; a cable is pulled from a fixed point: put it "
                         "outside the body (behind its base) or in its fixed region")
    first = cable.points[0]
    if np.linalg.norm(first - cable.pull_point) <= 1e-9 * max(size, 1e-3):
        ids, w = locate(nodes, tets, first[None], [f"cable '{cable.name}' point 0"])
        if moves(ids[0], w[0]):
            raise SceneError(f"cable '{cable.name}': its pull point is its first path point "
                             f"{first.tolist()} m, which moves with the body: the pull has no direction; "
                             "put the pull point behind the first point, e.g. outside the body")
