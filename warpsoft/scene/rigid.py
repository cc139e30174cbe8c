"""Rigid bodies: 6-DOF solids with a mass and an inertia that move under gravity and contacts.

A rigid body is a solid of :mod:`warpsoft.scene.obstacles` (a ball, box, capsule, cylinder or
closed triangle mesh) declared where it is at ``t = 0``, with a mass and an inertia (from the
solid and a density, or given). Its frame is its centre of mass with the world's axes at
``t = 0``. Soft bodies' surface nodes touch its solid (contact rows against its signed distance,
with its friction coefficient); its own collision points (by default its solid's corners, or
points spread over it, or its vertices) touch the obstacles and the other rigid bodies. Declared with
:meth:`warpsoft.Scene.add_rigid`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import SceneError
from . import obstacles as ob


@dataclass
class RigidBody:
    """A rigid body of a scene: ``mass`` (kg), ``center`` its centre of mass at ``t = 0`` (m),
    ``inertia`` (3x3, kg m^2, about the centre, world axes at ``t = 0``), initial ``velocity``
    (m/s) and ``angular_velocity`` (rad/s, world), Coulomb ``mu`` with what touches it,
    ``contact_distance`` (m, None: a quarter of the toucher's mean surface edge, or 2 % of the
    body's size for its own points), collision ``points`` ``(k, 3)`` (m, at ``t = 0``)."""

    name: str
    shape: ob.Obstacle
    mass: float
    center: np.ndarray
    inertia: np.ndarray
    velocity: np.ndarray
    angular_velocity: np.ndarray
    mu: float
    contact_distance: float | None
    points: np.ndarray

    @property
    def size(self) -> float:
        """The extent (m) of its collision points."""
        return float(np.linalg.norm(np.ptp(self.points, axis=0)))


@dataclass
class Attachment:
    """Nodes of a soft body held by a rigid body: ``nodes`` (ids in ``body``'s mesh) keep, in the
    rigid body's frame, the place they had at ``t = 0`` (three bilateral rows each)."""

    name: str
    body: object
    rigid: RigidBody
    region: object
    nodes: np.ndarray


def mass_properties(shape: ob.Obstacle, density: float) -> tuple[float, np.ndarray, np.ndarray]:
    """Mass (kg), centre of mass (m) and inertia about it (kg m^2, world axes) of a uniform solid."""
    if isinstance(shape, ob.Ball):
        m = density * 4.0 / 3.0 * math.pi * shape.radius ** 3
        return m, np.asarray(shape.center), 0.4 * m * shape.radius ** 2 * np.eye(3)
    if isinstance(shape, ob.Box):
        a, b, c = shape.size
        m = density * a * b * c
        local = m / 12.0 * np.diag([b * b + c * c, a * a + c * c, a * a + b * b])
        r = np.asarray(shape.rotation)
        return m, np.asarray(shape.center), r @ local @ r.T
    if isinstance(shape, (ob.Cylinder, ob.Capsule)):
        a, b, r = np.asarray(shape.a), np.asarray(shape.b), shape.radius
        length = float(np.linalg.norm(b - a))
        u = (b - a) / length
        if isinstance(shape, ob.Cylinder):
            m = density * math.pi * r * r * length
            axial, across = 0.5 * m * r * r, m * (3 * r * r + length * length) / 12.0
        else:  # a cylinder and two half balls whose centres sit at the segment's ends
            mc, mb = density * math.pi * r * r * length, density * 4.0 / 3.0 * math.pi * r ** 3
            m = mc + mb
            axial = 0.5 * mc * r * r + 0.4 * mb * r * r
            # half balls: own inertia 2/5 mb r^2 about their centre, shifted (3/8 r from the flat face) to the middle
            across = (mc * (3 * r * r + length * length) / 12.0
                      + mb * (0.4 * r * r + length * length / 4.0 + 3.0 * length * r / 8.0))
        return m, 0.5 * (a + b), across * np.eye(3) + (axial - across) * np.outer(u, u)
    if isinstance(shape, ob.Mesh):
        return mesh_mass_properties(shape, density)
    raise SceneError(f"a rigid body's solid must be a Ball, Box, Capsule, Cylinder or closed Mesh, got "
                     f"{type(shape).__name__}")


def mesh_mass_properties(mesh: ob.Mesh, density: float) -> tuple[float, np.ndarray, np.ndarray]:
    """Mass properties of the solid a closed, outward-oriented triangle mesh bounds: the sum over
    the tetrahedra from the origin to each triangle (signed volumes and second moments)."""
    if not mesh.closed():
        raise SceneError("a rigid body's Mesh must be closed (every edge shared by two triangles): an open "
                         "surface bounds no solid")
    tri = mesh.vertices[mesh.triangles] @ mesh.rotation.T + mesh.translation  # (m, 3, 3), world
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    vol = np.einsum("ij,ij->i", a, np.cross(b, c)) / 6.0
    volume = float(vol.sum())
    if volume <= 0:
        raise SceneError(f"a rigid body's Mesh must enclose a positive volume with outward normals, got "
                         f"{volume:.3g} m^3 (inward triangles?)")
    center = (vol[:, None] * (a + b + c) / 4.0).sum(axis=0) / volume
    # second moment of each tetrahedron (origin, a, b, c): V/20 (sum x x^T + (sum x)(sum x)^T)
    s = a + b + c
    second = (vol[:, None, None] / 20.0 * (np.einsum("ni,nj->nij", a, a) + np.einsum("ni,nj->nij", b, b)
                                           + np.einsum("ni,nj->nij", c, c) + np.einsum("ni,nj->nij", s, s))).sum(0)
    second = density * second - density * volume * np.outer(center, center)  # about the centre
    return density * volume, center, np.trace(second) * np.eye(3) - second


def collision_points(shape: ob.Obstacle) -> np.ndarray:
    """Default points (m) of a rigid body that touch obstacles and other rigid bodies: a box's 8
    corners, 12 edge middles and 6 face centres (corners alone miss a face resting across
    another box's edge); a ball's
    42 points spread over its surface; a cylinder's or capsule's rings (12 around) at its ends
    and middle (a capsule's also at its poles); a mesh's vertices."""
    if isinstance(shape, ob.Box):
        g = np.array([(i, j, k) for i in (-1, 0, 1) for j in (-1, 0, 1) for k in (-1, 0, 1) if (i, j, k) != (0, 0, 0)])
        return (0.5 * g * np.asarray(shape.size)) @ np.asarray(shape.rotation).T + np.asarray(shape.center)
    if isinstance(shape, ob.Ball):
        return np.asarray(shape.center) + shape.radius * sphere_points(42)
    if isinstance(shape, (ob.Cylinder, ob.Capsule)):
        a, b, r = np.asarray(shape.a), np.asarray(shape.b), shape.radius
        u = (b - a) / np.linalg.norm(b - a)
        e1 = np.cross(u, [1.0, 0.0, 0.0] if abs(u[0]) < 0.9 else [0.0, 1.0, 0.0])
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(u, e1)
        ang = np.linspace(0.0, 2 * math.pi, 12, endpoint=False)
        ring = r * (np.cos(ang)[:, None] * e1 + np.sin(ang)[:, None] * e2)
        pts = [end + ring for end in (a, 0.5 * (a + b), b)]
        pts.append(np.array([a - r * u, b + r * u]) if isinstance(shape, ob.Capsule) else np.array([a, b]))
        return np.vstack(pts)
    if isinstance(shape, ob.Mesh):
        return shape.vertices @ shape.rotation.T + shape.translation
    raise SceneError(f"no default collision points for a {type(shape).__name__}")


def sphere_points(n: int) -> np.ndarray:
    """``n`` unit vectors spread evenly over the sphere (a Fibonacci lattice)."""
    k = np.arange(n) + 0.5
    z = 1.0 - 2.0 * k / n
    phi = math.pi * (3.0 - math.sqrt(5.0)) * k
    r = np.sqrt(1.0 - z * z)
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


def make_rigid(name: str, shape, density, mass, inertia, velocity, angular_velocity, mu, contact_distance,
               points) -> RigidBody:
    """Check a rigid body's declaration (each error names it) and compute what it leaves out."""
    what = f"rigid body '{name}'"
    if not isinstance(shape, ob.Obstacle) or isinstance(shape, ob.Floor):
        raise SceneError(f"{what}: its solid must be one of ws.obstacles Ball, Box, Capsule, Cylinder or a closed "
                         f"Mesh, got {type(shape).__name__}")

    def positive(value, label, unit):
        if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)) \
                or not math.isfinite(value) or value <= 0:
            raise SceneError(f"{what}: {label} must be a finite number > 0 {unit}, got {value!r}")
        return float(value)

    if (density is None) == (mass is None):
        raise SceneError(f"{what}: give its density (kg/m^3) or its mass (kg), one of them")
    try:
        m1, center, inertia1 = mass_properties(shape, 1.0)
    except SceneError as exc:
        raise SceneError(f"{what}: {exc}") from None
    rho = positive(density, "density", "kg/m^3") if density is not None else positive(mass, "mass", "kg") / m1
    m, inertia0 = rho * m1, rho * inertia1
    if inertia is not None:
        given = np.asarray(inertia, dtype=float)
        given = np.diag(given) if given.shape == (3,) else given
        if given.shape != (3, 3) or not np.all(np.isfinite(given)) or not np.allclose(given, given.T, rtol=1e-9) \
                or np.linalg.eigvalsh(0.5 * (given + given.T)).min() <= 0:
            raise SceneError(f"{what}: inertia must be 3 positive numbers or a symmetric positive definite 3x3 "
                             f"(kg m^2, about its centre of mass), got {inertia!r}")
        inertia0 = 0.5 * (given + given.T)
    vel = ob._vec3(velocity, f"{what}: velocity")
    omega = ob._vec3(angular_velocity, f"{what}: angular_velocity")
    if isinstance(mu, bool) or not isinstance(mu, (int, float, np.integer, np.floating)) or not math.isfinite(mu) \
            or mu < 0:
        raise SceneError(f"{what}: friction coefficient mu must be a finite number >= 0, got {mu!r}")
    if contact_distance is not None:
        contact_distance = positive(contact_distance, "contact_distance", "m")
    pts = collision_points(shape) if points is None else np.asarray(points, dtype=float)
    if pts.ndim != 2 or pts.shape[1] != 3 or len(pts) == 0 or not np.all(np.isfinite(pts)):
        raise SceneError(f"{what}: points must be (k, 3) finite numbers (m) with k >= 1, got shape {pts.shape}")
    return RigidBody(str(name), shape, m, np.asarray(center, dtype=float), inertia0, vel, omega, float(mu),
                     contact_distance, pts)


__all__ = ["RigidBody", "collision_points", "make_rigid", "mass_properties"]
