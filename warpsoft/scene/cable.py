"""Cable actuator: a cable from a fixed pull point through points carried by the body.

``delta = L0 - L`` is the cable's shortening (m) from its rest length, ``lambda`` its
tension (N, >= 0: a slack cable pulls nothing).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from ..errors import SceneError
from .actuator import Actuator


@dataclass
class Cable(Actuator):
    """A cable (scene side). ``points``: ``(k, 3)`` path points (m) inside ``body``, from the
    one nearest the pull point to the attachment; ``pull_point``: fixed point (m) where the
    cable is pulled from (often outside the body, behind its base), carried by ``pull_motion``
    when given (a pose per time, as a moving fixed region's)."""

    body: object = None
    points: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    pull_point: np.ndarray = field(default_factory=lambda: np.zeros(3))
    pull_motion: Callable[[float], object] | None = None  # the pull point's frame (None: fixed in space)
    anchor_radius: float = 0.0  # m: the last point pulls the material within it (0: that point alone)
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
        try:
            radius = float(self.anchor_radius)
        except (TypeError, ValueError):
            radius = math.nan
        if not (math.isfinite(radius) and radius >= 0.0):
            raise SceneError(f"cable '{self.name}': anchor_radius must be a finite length >= 0 m, "
                             f"got {self.anchor_radius!r}")
        self.anchor_radius = radius
        self.points, self.pull_point = pts, pull

    @property
    def rest_length(self) -> float:
        path = np.vstack([self.pull_point, self.points])
        return float(np.sum(np.linalg.norm(np.diff(path, axis=0), axis=1)))
