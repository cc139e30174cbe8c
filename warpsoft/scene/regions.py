"""Geometric selections of nodes (fixed regions, loaded faces, cavity walls).

A region is called with an ``(n, 3)`` array of positions (m) and returns a boolean mask.
Regions combine with ``|`` (union), ``&`` (intersection) and ``~`` (complement).

Region names say where the nodes are (``InBox``, ``OnPlane``, ``InHalfSpace``, ``InSphere``), so
that they cannot be taken for the solids that are meshed (``ws.shapes.Box``, ``ws.Cylinder``,
``ws.Cone``, ``ws.Ball``). The first names (``Box``, ``Plane``, ``HalfSpace``, ``Sphere``) still
work, with a ``DeprecationWarning`` that gives the new one.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from ..errors import SceneError


def _vec3(value, what: str) -> np.ndarray:
    a = np.asarray(value, dtype=float)
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise SceneError(f"{what} must be 3 finite numbers, got {value!r}")
    return a


class Region:
    """Base class: ``region(points) -> bool mask``."""

    def __call__(self, points: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def __or__(self, other: Region) -> Region:
        return _Combined(self, other, np.logical_or, "|")

    def __and__(self, other: Region) -> Region:
        return _Combined(self, other, np.logical_and, "&")

    def __invert__(self) -> Region:
        return _Not(self)


@dataclass(frozen=True, repr=False)
class _Combined(Region):
    a: Region
    b: Region
    op: object
    sym: str

    def __call__(self, points):
        return self.op(self.a(points), self.b(points))

    def __repr__(self):
        return f"({self.a!r} {self.sym} {self.b!r})"


@dataclass(frozen=True, repr=False)
class _Not(Region):
    a: Region

    def __call__(self, points):
        return ~self.a(points)

    def __repr__(self):
        return f"~{self.a!r}"


class InBox(Region):
    """Points in the axis-aligned box ``lo <= x <= hi`` (m), widened by ``tol`` on every side."""

    def __init__(self, lo, hi, tol: float = 1e-9):
        self.lo, self.hi = _vec3(lo, "InBox.lo"), _vec3(hi, "InBox.hi")
        if np.any(self.hi < self.lo):
            raise SceneError(f"InBox: hi {self.hi.tolist()} must be >= lo {self.lo.tolist()} on every axis")
        self.tol = float(tol)

    def __call__(self, points):
        p = np.asarray(points)
        return np.all((p >= self.lo - self.tol) & (p <= self.hi + self.tol), axis=1)

    def __repr__(self):
        return f"InBox(lo={self.lo.tolist()}, hi={self.hi.tolist()})"


class _Oriented(Region):
    """A plane through ``point`` with unit ``normal`` and a tolerance ``tol`` (m)."""

    def __init__(self, point, normal, tol: float = 1e-6):
        kind = type(self).__name__
        self.point = _vec3(point, f"{kind}.point")
        n = _vec3(normal, f"{kind}.normal")
        if np.linalg.norm(n) == 0:
            raise SceneError(f"{kind}.normal must be non-zero")
        self.normal, self.tol = n / np.linalg.norm(n), float(tol)

    def distance(self, points) -> np.ndarray:
        """Signed distance (m) along the normal."""
        return (np.asarray(points) - self.point) @ self.normal

    def __repr__(self):
        return f"{type(self).__name__}(point={self.point.tolist()}, normal={self.normal.tolist()})"


class OnPlane(_Oriented):
    """Points within ``tol`` (m) of the plane through ``point`` with normal ``normal``."""

    def __call__(self, points):
        return np.abs(self.distance(points)) <= self.tol


class InHalfSpace(_Oriented):
    """Points on the side of the plane that ``normal`` points away from:
    ``(x - point) . normal <= tol`` (m)."""

    def __call__(self, points):
        return self.distance(points) <= self.tol


class InSphere(Region):
    """Points within ``radius`` (m, plus ``tol``) of ``center``."""

    def __init__(self, center, radius: float, tol: float = 1e-9):
        self.center, self.radius, self.tol = _vec3(center, "InSphere.center"), float(radius), float(tol)
        if not self.radius > 0:
            raise SceneError(f"InSphere.radius must be > 0 m, got {radius!r}")

    def __call__(self, points):
        return np.linalg.norm(np.asarray(points) - self.center, axis=1) <= self.radius + self.tol

    def __repr__(self):
        return f"InSphere(center={self.center.tolist()}, radius={self.radius})"


def _deprecated(new: type[Region], old: str) -> type[Region]:
    """``old``, the region's first name: the same region, with a warning that names the new one."""

    def __init__(self, *args, **kwargs):
        warnings.warn(f"ws.{old} is now ws.{new.__name__} (regions say where nodes are: InBox, OnPlane, "
                      f"InHalfSpace, InSphere; solids to mesh are ws.shapes.Box, ws.Cylinder, ws.Cone, ws.Ball)",
                      DeprecationWarning, stacklevel=2)
        new.__init__(self, *args, **kwargs)

    return type(old, (new,), {"__init__": __init__, "__doc__": f"Deprecated name of :class:`{new.__name__}`."})


Box = _deprecated(InBox, "Box")
Plane = _deprecated(OnPlane, "Plane")
HalfSpace = _deprecated(InHalfSpace, "HalfSpace")
Sphere = _deprecated(InSphere, "Sphere")


def as_region(value, what: str) -> Region:
    """``value`` if it is a region, else a clear error: regions select nodes by geometry, shapes
    (``ws.shapes``) are solids to mesh."""
    if isinstance(value, Region):
        return value
    from . import shapes

    hint = ""
    if isinstance(value, shapes.Shape):
        qualified = "ws.shapes.Box" if isinstance(value, shapes.Box) else f"ws.{type(value).__name__}"
        hint = (f": {qualified} is a solid shape for meshing (ws.mesh_shape), not a region; "
                "regions are ws.InBox, ws.OnPlane, ws.InHalfSpace and ws.InSphere, combined with |, & and ~")
    raise SceneError(f"{what} must be a region (ws.InBox, ws.OnPlane, ws.InHalfSpace, ws.InSphere, ...), got "
                     f"{type(value).__name__}{hint}")

