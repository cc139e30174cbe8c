"""Cable actuator: a cable from a fixed pull point through points carried by the body.

``delta = L0 - L`` is the cable's shortening (m) from its rest length, ``lambda`` its
tension (N, >= 0: a slack cable pulls nothing).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import warp as wp

from warpsoft.kernels import cable as kernels

from ..errors import SceneError
from .actuator import Actuator


@dataclass
class Cable(Actuator):
    """A cable (scene side). ``points``: ``(k, 3)`` path points (m) inside ``body``, from the
    one nearest the pull point to the attachment; ``pull_point``: fixed point (m) where the
    cable is pulled from (often outside the body, behind its base)."""

    body: object = None
    points: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    pull_point: np.ndarray = field(default_factory=lambda: np.zeros(3))
    kind = "cable"

    def __post_init__(self) -> None:
        super().__post_init__()
        pts = np.asarray(self.points, dtype=float)
        if pts.ndim != 2 or pts.shape[1] != 3 or len(pts) == 0:
            raise SceneError(f"cable '{self.name}': points must be a (k, 3) array with k >= 1, got shape {pts.shape}")
        if not np.all(np.isfinite(pts)):
            raise SceneError(f"cable '{self.name}': points must be finite, got {pts.tolist()}")
        pull = np.asarray(self.pull_point, dtype=float)
        if pull.shape != (3,) or not np.all(np.isfinite(pull)):
            raise SceneError(f"cable '{self.name}': pull_point must be 3 finite numbers, got {self.pull_point!r}")
        if self.min_force < 0:
            raise SceneError(f"cable '{self.name}': min_force must be >= 0 N (a cable cannot push), "
                             f"got {self.min_force}")
        self.points, self.pull_point = pts, pull

    @property
    def rest_length(self) -> float:
        path = np.vstack([self.pull_point, self.points])
        return float(np.sum(np.linalg.norm(np.diff(path, axis=0), axis=1)))


class CableRows:
    """Device side of all cables of a model: one row each."""

    def __init__(self, cables: list[Cable], rows: list[int], point_offset: int, device):
        self.cables = cables
        counts = [len(c.points) for c in cables]
        starts = np.concatenate([[0], np.cumsum(counts)[:-1]]).astype(np.int32) + point_offset
        self.num_entries = 4 * int(sum(counts))
        self.point_offset = point_offset
        self.start = wp.array(starts, dtype=wp.int32, device=device)
        self.count = wp.array(np.array(counts, dtype=np.int32), dtype=wp.int32, device=device)
        self.pull = wp.array(np.array([c.pull_point for c in cables]), dtype=wp.vec3d, device=device)
        self.rest_length = wp.array(np.array([c.rest_length for c in cables]), dtype=wp.float64, device=device)
        self.row = wp.array(np.array(rows, dtype=np.int32), dtype=wp.int32, device=device)
        self.rows = rows

    def evaluate(self, points, point_nodes, point_weights, entry_offset, delta, h_row, h_node, h_coef):
        # the entries of cable point j sit at entry_offset + 4 * (global point id): shift by the offset
        wp.launch(kernels.cable_rows, len(self.cables),
                  inputs=[points, point_nodes, point_weights, self.start, self.count, self.pull, self.rest_length,
                          self.row, entry_offset - 4 * self.point_offset],
                  outputs=[delta, h_row, h_node, h_coef], device=delta.device)


def cable_paths(cables: list[Cable], points: np.ndarray) -> list[np.ndarray]:
    """Each cable's polyline (pull point first) from the current mapped points ``(p, 3)``."""
    out, k = [], 0
    for c in cables:
        out.append(np.vstack([c.pull_point, points[k:k + len(c.points)]]))
        k += len(c.points)
    return out

