"""Rigid obstacles the soft bodies touch (analytic solids, fixed in the world).

An obstacle is a solid given by its signed distance ``phi(x)`` (m, negative inside) and outward
normal; a soft body's surface nodes closer than a contact distance become contact rows
(Signorini: ``phi >= 0``, normal force ``>= 0``, one of them zero). Declared with
:meth:`warpsoft.Scene.add_obstacle`; nothing is detected in a scene that declares none.

Every obstacle packs into the same record for the kernels (``kernels/rows/contact.py``): a kind,
two points ``a`` and ``b`` (m), a radius (m) and a rotation (world from local). An obstacle
may move by a schedule (``motion``: a rigid pose per time); it is then packed again each step.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from ..errors import SceneError

FLOOR, BALL, BOX, CAPSULE, CYLINDER, MESH = range(6)  # kinds, as the kernels know them


def _vec3(value, what: str) -> np.ndarray:
    try:
        a = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise SceneError(f"{what} must be 3 numbers, got {value!r}") from None
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise SceneError(f"{what} must be 3 finite numbers, got {value!r}")
    return a


def _tuple(a: np.ndarray) -> tuple:
    return tuple(float(x) for x in a)


def _positive(value, what: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)) \
            or not math.isfinite(value) or value <= 0:
        raise SceneError(f"{what} must be a finite number > 0 m, got {value!r}")
    return float(value)


@dataclass(frozen=True)
class Obstacle:
    """Base: what every obstacle packs for the kernels (``kind``, ``a``, ``b``, ``radius``,
    ``rotation``) and its signed distance on the host (for checks and tests)."""

    def pack(self) -> tuple[int, np.ndarray, np.ndarray, float, np.ndarray]:
        raise NotImplementedError

    def distance(self, points: np.ndarray) -> np.ndarray:
        """Signed distance (m) of ``(n, 3)`` points: negative inside."""
        raise NotImplementedError

    def moved(self, rotation: np.ndarray, translation: np.ndarray) -> Obstacle:
        """The same solid carried by the rigid motion ``x -> rotation x + translation``."""
        raise NotImplementedError


@dataclass(frozen=True)
class Floor(Obstacle):
    """The half-space below the plane through ``point`` with upward ``normal`` (the floor's top)."""

    point: tuple = (0.0, 0.0, 0.0)
    normal: tuple = (0.0, 0.0, 1.0)
    _n: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self):
        p, n = _vec3(self.point, "Floor.point"), _vec3(self.normal, "Floor.normal")
        if np.linalg.norm(n) == 0:
            raise SceneError("Floor.normal must be non-zero")
        object.__setattr__(self, "_n", n / np.linalg.norm(n))
        object.__setattr__(self, "point", _tuple(p))

    def pack(self):
        return FLOOR, np.asarray(self.point), self._n, 0.0, np.eye(3)

    def distance(self, points):
        return (np.asarray(points) - np.asarray(self.point)) @ self._n

    def moved(self, rotation, translation):
        return Floor(rotation @ np.asarray(self.point) + translation, rotation @ self._n)


@dataclass(frozen=True)
class Ball(Obstacle):
    """A rigid ball of ``radius`` (m) at ``center`` (m)."""

    center: tuple
    radius: float

    def __post_init__(self):
        object.__setattr__(self, "center", _tuple(_vec3(self.center, "Ball.center")))
        object.__setattr__(self, "radius", _positive(self.radius, "Ball.radius"))

    def pack(self):
        return BALL, np.asarray(self.center), np.zeros(3), self.radius, np.eye(3)

    def distance(self, points):
        return np.linalg.norm(np.asarray(points) - np.asarray(self.center), axis=1) - self.radius

    def moved(self, rotation, translation):
        return Ball(rotation @ np.asarray(self.center) + translation, self.radius)


@dataclass(frozen=True)
class Box(Obstacle):
    """A rigid box of edge lengths ``size`` (m) centred at ``center`` (m), turned by ``rotation``
    (a 3x3 rotation matrix, world from box axes; axis-aligned by default)."""

    center: tuple
    size: tuple
    rotation: tuple | None = None

    def __post_init__(self):
        object.__setattr__(self, "center", _tuple(_vec3(self.center, "Box.center")))
        size = _vec3(self.size, "Box.size")
        if np.any(size <= 0):
            raise SceneError(f"Box.size must be > 0 on every axis, got {size.tolist()}")
        object.__setattr__(self, "size", _tuple(size))
        r = np.eye(3) if self.rotation is None else np.asarray(self.rotation, dtype=float)
        if r.shape != (3, 3) or not np.allclose(r.T @ r, np.eye(3), atol=1e-9) or np.linalg.det(r) < 0:
            raise SceneError(f"Box.rotation must be a 3x3 rotation matrix, got {self.rotation!r}")
        object.__setattr__(self, "rotation", tuple(_tuple(row) for row in r))

    def pack(self):
        return BOX, np.asarray(self.center), 0.5 * np.asarray(self.size), 0.0, np.asarray(self.rotation)

    def distance(self, points):
        local = (np.asarray(points) - np.asarray(self.center)) @ np.asarray(self.rotation)
        q = np.abs(local) - 0.5 * np.asarray(self.size)
        outside = np.linalg.norm(np.maximum(q, 0.0), axis=1)
        return outside + np.minimum(q.max(axis=1), 0.0)

    def moved(self, rotation, translation):
        return Box(rotation @ np.asarray(self.center) + translation, self.size, rotation @ np.asarray(self.rotation))


@dataclass(frozen=True)
class _Axial(Obstacle):
    """A solid around the segment from ``a`` to ``b`` (m) with a ``radius`` (m): what a capsule
    and a cylinder share (checks, packing, motion)."""

    a: tuple
    b: tuple
    radius: float
    kind = -1  # the kernels' kind, set by each solid

    def __post_init__(self):
        name = type(self).__name__
        object.__setattr__(self, "a", _tuple(_vec3(self.a, f"{name}.a")))
        object.__setattr__(self, "b", _tuple(_vec3(self.b, f"{name}.b")))
        object.__setattr__(self, "radius", _positive(self.radius, f"{name}.radius"))
        if np.allclose(self.a, self.b):
            raise SceneError(f"{name}: a and b must differ" + (" (use a Ball for a point)" if self.kind == CAPSULE
                                                                else ""))

    def pack(self):
        return self.kind, np.asarray(self.a), np.asarray(self.b), self.radius, np.eye(3)

    def moved(self, rotation, translation):
        return type(self)(rotation @ np.asarray(self.a) + translation, rotation @ np.asarray(self.b) + translation,
                          self.radius)


@dataclass(frozen=True)
class Capsule(_Axial):
    """The points within ``radius`` (m) of the segment from ``a`` to ``b`` (m)."""

    kind = CAPSULE

    def distance(self, points):
        a, b = np.asarray(self.a), np.asarray(self.b)
        ab = b - a
        t = np.clip((np.asarray(points) - a) @ ab / (ab @ ab), 0.0, 1.0)
        return np.linalg.norm(np.asarray(points) - (a + t[:, None] * ab), axis=1) - self.radius


@dataclass(frozen=True)
class Cylinder(_Axial):
    """A rigid cylinder of ``radius`` (m) whose axis runs from ``a`` to ``b`` (m), flat ends."""

    kind = CYLINDER

    def distance(self, points):
        a, b = np.asarray(self.a), np.asarray(self.b)
        axis = b - a
        length = np.linalg.norm(axis)
        u = axis / length
        rel = np.asarray(points) - 0.5 * (a + b)
        along = rel @ u
        radial = np.linalg.norm(rel - along[:, None] * u, axis=1)
        q = np.stack([radial - self.radius, np.abs(along) - 0.5 * length], axis=1)
        return np.linalg.norm(np.maximum(q, 0.0), axis=1) + np.minimum(q.max(axis=1), 0.0)


@dataclass(frozen=True, eq=False)
class Mesh(Obstacle):
    """A rigid surface of triangles: ``vertices`` ``(k, 3)`` (m) and ``triangles`` ``(m, 3)``
    (vertex ids), oriented with their normals (right-hand rule) pointing out of the solid. A
    closed surface bounds a solid (negative distance inside); an open one (a terrain) is a
    surface whose back is inside. On the device the nearest triangle comes from a BVH
    (``wp.Mesh``) and the distance to it is computed again in double precision.
    :meth:`load` reads a surface file (STL, OBJ, ...)."""

    vertices: np.ndarray
    triangles: np.ndarray
    rotation: np.ndarray | None = None  # the pose that carries it (set by moved(); identity as declared)
    translation: np.ndarray | None = None

    def __post_init__(self):
        try:
            v = np.array(self.vertices, dtype=float)
            t = np.array(self.triangles, dtype=np.int64)
        except (TypeError, ValueError):
            raise SceneError("Mesh: vertices must be (k, 3) numbers and triangles (m, 3) vertex ids") from None
        if v.ndim != 2 or v.shape[1] != 3 or not np.all(np.isfinite(v)):
            raise SceneError(f"Mesh: vertices must be (k, 3) finite numbers (m), got shape {v.shape}")
        if t.ndim != 2 or t.shape[1] != 3 or len(t) == 0:
            raise SceneError(f"Mesh: needs at least one triangle, (m, 3) vertex ids; got shape {t.shape}")
        if t.min() < 0 or t.max() >= len(v):
            raise SceneError(f"Mesh: triangle vertex ids must be in [0, {len(v)}), got {t.min()}..{t.max()}")
        areas = 0.5 * np.linalg.norm(np.cross(v[t[:, 1]] - v[t[:, 0]], v[t[:, 2]] - v[t[:, 0]]), axis=1)
        if np.any(areas <= 1e-12 * max(np.ptp(v, axis=0).max(), 1e-300) ** 2):
            raise SceneError(f"Mesh: {int(np.sum(areas <= 0))} or more triangles have no area (repeated vertices?)")
        r = np.eye(3) if self.rotation is None else np.asarray(self.rotation, dtype=float)
        p = np.zeros(3) if self.translation is None else _vec3(self.translation, "Mesh.translation")
        for name, value in (("vertices", v), ("triangles", t), ("rotation", r), ("translation", p)):
            value.setflags(write=False)
            object.__setattr__(self, name, value)
        edges = np.sort(t[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
        _, counts = np.unique(edges, axis=0, return_counts=True)
        object.__setattr__(self, "_closed", bool(np.all(counts == 2)))
        if self._closed:  # the solid is on the normals' back: its volume from them must be positive
            a, b, c = v[t[:, 0]], v[t[:, 1]], v[t[:, 2]]
            volume = float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0)
            if volume <= 0.0:
                raise SceneError(f"Mesh: a closed surface must enclose a positive volume with its normals "
                                 f"pointing out of the solid (right-hand rule), got {volume:.3g} m^3: its "
                                 "triangles are inward (reverse each triangle's vertex order)")

    @classmethod
    def load(cls, path, scale: float = 1.0) -> Mesh:
        """The triangles of a surface file (meshio: STL, OBJ, PLY, ...), coordinates times
        ``scale`` (e.g. 1e-3 for a file in millimetres)."""
        import meshio

        try:
            data = meshio.read(str(path))
        except Exception as exc:
            raise SceneError(f"Mesh.load: cannot read {str(path)!r}: {exc}") from None
        tris = [c.data for c in data.cells if c.type == "triangle"]
        if not tris:
            raise SceneError(f"Mesh.load: {str(path)!r} has no triangles")
        return cls(float(scale) * np.asarray(data.points, dtype=float)[:, :3], np.concatenate(tris))

    def closed(self) -> bool:
        """Whether every edge is shared by exactly two triangles (a surface that bounds a solid)."""
        return self._closed

    def pack(self):
        return MESH, self.translation.copy(), np.zeros(3), 0.0, self.rotation.copy()

    def moved(self, rotation, translation):
        """The same triangles under a new pose, without checking them again (a moving obstacle
        is moved every step)."""
        copy = object.__new__(Mesh)
        for name in ("vertices", "triangles", "_closed"):
            object.__setattr__(copy, name, getattr(self, name))
        object.__setattr__(copy, "rotation", rotation @ self.rotation)
        object.__setattr__(copy, "translation", rotation @ self.translation + translation)
        return copy

    def distance(self, points):
        """Signed distance (brute force over the triangles, for checks): the sign from the
        winding number for a closed surface, from the nearest triangle's side for an open one."""
        x = (np.asarray(points, dtype=float) - self.translation) @ self.rotation  # into the declared frame
        tri = self.vertices[self.triangles]
        closest = closest_on_triangles(x, tri)  # (n, m, 3)
        d2 = np.sum((x[:, None, :] - closest) ** 2, axis=2)
        nearest = np.argmin(d2, axis=1)
        dist = np.sqrt(d2[np.arange(len(x)), nearest])
        if self.closed():
            return np.where(winding_numbers(x, tri) > 0.5, -dist, dist)
        normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])[nearest]
        side = np.einsum("ij,ij->i", x - closest[np.arange(len(x)), nearest], normal)
        return np.where(side < 0, -dist, dist)


def closest_on_triangles(x: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """The point of each triangle ``tri`` ``(m, 3, 3)`` nearest to each point ``x`` ``(n, 3)``:
    ``(n, m, 3)`` (the regions of the triangle's plane: inside, then each edge, then each vertex)."""
    a, b, c = (tri[None, :, k, :] for k in range(3))
    p = x[:, None, :]
    n = np.cross(b - a, c - a)
    inside = p - np.einsum("nmk,nmk->nm", p - a, n)[..., None] * n / np.einsum("nmk,nmk->nm", n, n)[..., None]
    within = np.ones(inside.shape[:2], dtype=bool)
    for u, v in ((a, b), (b, c), (c, a)):  # the plane's projection counts when it is left of every edge
        within &= np.einsum("nmk,nmk->nm", np.cross(v - u, inside - u), n) >= 0
    candidates = [np.where(within[..., None], inside, np.inf)]
    for u, v in ((a, b), (b, c), (c, a)):
        e = v - u
        t = np.clip(np.einsum("nmk,nmk->nm", p - u, e) / np.einsum("nmk,nmk->nm", e, e), 0.0, 1.0)
        candidates.append(u + t[..., None] * e)
    d = np.stack([np.sum((p - q) ** 2, axis=2) for q in candidates])
    d = np.where(np.isnan(d), np.inf, d)
    pick = np.argmin(d, axis=0)
    stacked = np.stack([np.broadcast_to(q, inside.shape) for q in candidates])
    return np.take_along_axis(stacked, pick[None, ..., None], axis=0)[0]


def winding_numbers(x: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """Generalized winding number of closed triangles ``(m, 3, 3)`` at points ``(n, 3)``: 1
    inside, 0 outside (van Oosterom and Strackee's solid angle)."""
    r = tri[None, :, :, :] - x[:, None, None, :]
    lengths = np.linalg.norm(r, axis=3)
    a, b, c = r[:, :, 0], r[:, :, 1], r[:, :, 2]
    la, lb, lc = lengths[:, :, 0], lengths[:, :, 1], lengths[:, :, 2]
    num = np.einsum("nmk,nmk->nm", a, np.cross(b, c))
    den = la * lb * lc + np.einsum("nmk,nmk->nm", a, b) * lc + np.einsum("nmk,nmk->nm", b, c) * la \
        + np.einsum("nmk,nmk->nm", c, a) * lb
    return np.sum(2.0 * np.arctan2(num, den), axis=1) / (4.0 * np.pi)


@dataclass
class ObstacleEntry:
    """An obstacle of a scene (use :meth:`Scene.add_obstacle`): its name, solid, Coulomb friction
    coefficient with the bodies, the distance (m) within which a surface node becomes a contact
    (None: a quarter of the body's mean surface edge, set when the model is built), and its
    motion (None: it stays where declared)."""

    name: str
    shape: Obstacle
    mu: float = 0.0
    contact_distance: float | None = None
    motion: Callable[[float], object] | None = None

    def pose(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """``(rotation 3x3, translation (3,) m)`` that carries the declared solid to where it is
        at time ``t`` (s): the identity for a fixed obstacle."""
        if self.motion is None:
            return np.eye(3), np.zeros(3)
        return pose_of(self.motion, t, f"obstacle '{self.name}': motion")

    def at(self, t: float) -> Obstacle:
        """The solid where it is at time ``t`` (s)."""
        return self.shape if self.motion is None else self.shape.moved(*self.pose(t))


@dataclass
class SelfContact:
    """A body that touches itself (use :meth:`Scene.add_self_contact`): its surface nodes meet its
    own surface triangles, with Coulomb friction ``mu``, within ``contact_distance`` (m; None: a
    quarter of its mean surface edge). A node and a triangle closer than twice that distance in
    the rest shape are neighbours, never a contact (a corner's faces, a thin wall's two sides)."""

    name: str
    body: object
    mu: float = 0.0
    contact_distance: float | None = None


def pose_of(motion: Callable[[float], object], t: float, what: str) -> tuple[np.ndarray, np.ndarray]:
    """``motion(t)`` read as a rigid pose: a translation (3 numbers, m) or a pair
    ``(rotation 3x3, translation)``; anything else, or a failure of the user's code, is a
    SceneError that names ``what`` and the time."""
    try:
        value = motion(t)
    except Exception as exc:  # the user's schedule: say whose and when
        raise SceneError(f"{what} failed at t = {t:g} s: {type(exc).__name__}: {exc}") from exc
    if isinstance(value, tuple) and len(value) == 2:
        rotation, translation = np.asarray(value[0], dtype=float), value[1]
        if rotation.shape != (3, 3) or not np.all(np.isfinite(rotation)) or \
                not np.allclose(rotation.T @ rotation, np.eye(3), atol=1e-9) or np.linalg.det(rotation) < 0:
            raise SceneError(f"{what} at t = {t:g} s: the rotation must be a 3x3 rotation matrix, got {value[0]!r}")
    else:
        rotation, translation = np.eye(3), value
    return rotation, _vec3(translation, f"{what} at t = {t:g} s: the translation")


__all__ = ["Ball", "Box", "Capsule", "Cylinder", "Floor", "Mesh", "Obstacle", "ObstacleEntry"]
