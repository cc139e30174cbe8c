"""Effector: a point of a body to place, on all axes or a subset; one row per axis."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..errors import SceneError, call_user


@dataclass
class Effector:
    """A material point (m, rest configuration) and its target: a 3-vector, a function of
    time ``t -> 3-vector``, or None (then the rest position: ``delta`` is the displacement).
    ``axes``: which of "xyz" are controlled; ``weight``: its share in the inverse model."""

    name: str
    point: np.ndarray
    target: np.ndarray | Callable | None = None
    axes: str = "xyz"
    weight: float = 1.0

    def __post_init__(self) -> None:
        p = np.asarray(self.point, dtype=float)
        if p.shape != (3,) or not np.all(np.isfinite(p)):
            raise SceneError(f"effector '{self.name}': point must be 3 finite numbers, got {self.point!r}")
        self.point = p
        if not self.axes or any(a not in "xyz" for a in self.axes) or len(set(self.axes)) != len(self.axes):
            raise SceneError(f"effector '{self.name}': axes must be a subset of 'xyz', got {self.axes!r}")
        if not (isinstance(self.weight, (int, float)) and np.isfinite(self.weight) and self.weight > 0):
            raise SceneError(f"effector '{self.name}': weight must be a finite number > 0, got {self.weight!r}")
        if self.target is not None and not callable(self.target):
            self.target = self.target_at(0.0)

    def target_at(self, t: float) -> np.ndarray:
        """The target (m) at time ``t`` (s); NaN or a wrong shape is an error naming the effector."""
        if self.target is None:
            return self.point
        v = call_user(self.target, t, f"effector '{self.name}': its target function") if callable(self.target) \
            else self.target
        try:
            v = np.asarray(v, dtype=float)
        except (TypeError, ValueError):
            v = np.array([np.nan])
        if v.shape != (3,) or not np.all(np.isfinite(v)):
            raise SceneError(f"effector '{self.name}': target at t = {t:g} s must be 3 finite numbers, got {v!r}")
        return v

    @property
    def axis_ids(self) -> list[int]:
        return ["xyz".index(a) for a in self.axes]


def waypoints(points, times) -> Callable[[float], np.ndarray]:
    """A target trajectory through ``points`` ``(k, 3)`` (m) reached at ``times`` ``(k,)`` (s),
    linear in between and held before the first and after the last."""
    pts, ts = np.asarray(points, dtype=float), np.asarray(times, dtype=float)
    if pts.ndim != 2 or pts.shape[1] != 3 or ts.shape != (len(pts),) or np.any(np.diff(ts) <= 0):
        raise SceneError(f"waypoints: need (k, 3) points and k increasing times, got {pts.shape} and {ts.shape}")
    if not (np.all(np.isfinite(pts)) and np.all(np.isfinite(ts))):
        raise SceneError("waypoints: points and times must be finite")
    return lambda t: np.array([np.interp(t, ts, pts[:, k]) for k in range(3)])
