"""Parametric solids (gmsh OpenCASCADE) and their tetrahedral meshing.

Shapes are plain descriptions; nothing touches gmsh until :func:`mesh_shape`. They
combine with ``a + b`` (union), ``a - b`` (difference) and ``a & b`` (intersection), so a
robot design is a function of its parameters and a design sweep is a loop.
"""

from __future__ import annotations

import hashlib
import math
import os
import warnings
import zipfile
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import MeshError, SceneError
from .mesh import TetMesh
from .regions import Region


def _check(name: str, **values) -> None:
    for key, v in values.items():
        arr = np.atleast_1d(np.asarray(v, dtype=float))
        if not np.all(np.isfinite(arr)):
            raise SceneError(f"{name}.{key} must be finite, got {v!r}")


class Shape:
    """A solid; subclasses add themselves to the current gmsh OCC model."""

    def _add(self, occ) -> list[tuple[int, int]]:
        raise NotImplementedError

    def __add__(self, other: Shape) -> Shape:
        return Boolean("fuse", self, other)

    def __sub__(self, other: Shape) -> Shape:
        return Boolean("cut", self, other)

    def __and__(self, other: Shape) -> Shape:
        return Boolean("intersect", self, other)


@dataclass(frozen=True)
class Box(Shape):
    """Box with corner ``origin`` and edge lengths ``size`` (m)."""

    origin: tuple[float, float, float]
    size: tuple[float, float, float]

    def __post_init__(self):
        _check("Box", origin=self.origin, size=self.size)
        if min(self.size) <= 0:
            raise SceneError(f"Box.size must be > 0 on every axis, got {tuple(self.size)}")

    def _add(self, occ):
        return [(3, occ.addBox(*self.origin, *self.size))]


@dataclass(frozen=True)
class Cylinder(Shape):
    """Cylinder from ``base`` along ``axis`` (its length is the height) of ``radius`` (m)."""

    base: tuple[float, float, float]
    axis: tuple[float, float, float]
    radius: float

    def __post_init__(self):
        _check("Cylinder", base=self.base, axis=self.axis, radius=self.radius)
        if self.radius <= 0 or np.linalg.norm(self.axis) == 0:
            raise SceneError(f"Cylinder: radius {self.radius} and axis length must be > 0")

    def _add(self, occ):
        return [(3, occ.addCylinder(*self.base, *self.axis, self.radius))]


@dataclass(frozen=True)
class Cone(Shape):
    """Truncated cone from ``base`` along ``axis``, radius ``r1`` at the base, ``r2`` at the top (m)."""

    base: tuple[float, float, float]
    axis: tuple[float, float, float]
    r1: float
    r2: float

    def __post_init__(self):
        _check("Cone", base=self.base, axis=self.axis, r1=self.r1, r2=self.r2)
        if self.r1 < 0 or self.r2 < 0 or max(self.r1, self.r2) == 0 or np.linalg.norm(self.axis) == 0:
            raise SceneError(f"Cone: radii ({self.r1}, {self.r2}) must be >= 0, not both 0, axis non-zero")

    def _add(self, occ):
        return [(3, occ.addCone(*self.base, *self.axis, self.r1, self.r2))]


@dataclass(frozen=True)
class Ball(Shape):
    """Sphere of ``radius`` (m) around ``center``."""

    center: tuple[float, float, float]
    radius: float

    def __post_init__(self):
        _check("Ball", center=self.center, radius=self.radius)
        if self.radius <= 0:
            raise SceneError(f"Ball.radius must be > 0 m, got {self.radius}")

    def _add(self, occ):
        return [(3, occ.addSphere(*self.center, self.radius))]


@dataclass(frozen=True)
class Boolean(Shape):
    """Union, difference or intersection of two shapes."""

    op: str
    a: Shape
    b: Shape

    def _add(self, occ):
        a, b = self.a._add(occ), self.b._add(occ)
        out, _ = getattr(occ, self.op)(a, b)
        return [d for d in out if d[0] == 3]


@dataclass(frozen=True)
class Refine:
    """Smaller elements near a point: edge ``size`` (m) within ``radius`` (m) of ``point``, growing
    to the mesh's size over the next ``2 radius`` (where a contact patch or a load needs them)."""

    point: tuple[float, float, float]
    size: float
    radius: float

    def __post_init__(self):
        _check("Refine", point=self.point, size=self.size, radius=self.radius)
        if self.size <= 0 or self.radius <= 0:
            raise SceneError(f"Refine: size {self.size} m and radius {self.radius} m must be > 0")

    def volume(self) -> float:
        """The volume (m^3) within which elements are smaller than the mesh's size."""
        return 4.0 / 3.0 * math.pi * (3.0 * self.radius) ** 3

    def _field(self, gmsh, mesh_size: float) -> None:
        x, y, z = (float(c) for c in self.point)
        field = gmsh.model.mesh.field
        distance = field.add("MathEval")  # no geometric point: it would become a node outside every element
        field.setString(distance, "F", f"Sqrt((x-({x!r}))^2+(y-({y!r}))^2+(z-({z!r}))^2)")
        size = field.add("Threshold")
        field.setNumber(size, "InField", distance)
        field.setNumber(size, "SizeMin", float(self.size))
        field.setNumber(size, "SizeMax", mesh_size)
        field.setNumber(size, "DistMin", float(self.radius))
        field.setNumber(size, "DistMax", 3.0 * float(self.radius))
        field.setAsBackgroundMesh(size)


MAX_ELEMENTS = 1_000_000  # estimated elements above which meshing refuses (a too small mesh_size hangs gmsh)
REGULAR_TET = 1.0 / (6.0 * math.sqrt(2.0))  # volume of a regular tetrahedron of unit edge


def max_elements() -> int:
    """The element limit: ``MAX_ELEMENTS``, or the environment's ``WARPSOFT_MAX_ELEMENTS``."""
    text = os.environ.get("WARPSOFT_MAX_ELEMENTS")
    try:
        return int(float(text)) if text else MAX_ELEMENTS
    except ValueError:
        raise SceneError(f"WARPSOFT_MAX_ELEMENTS must be a number, got {text!r}") from None


def check_size(name: str, volume: float, mesh_size: float) -> None:
    """Refuse, before gmsh starts, a mesh whose estimated element count (``volume`` over a
    regular tetrahedron of edge ``mesh_size``, times 1.5) exceeds :func:`max_elements`."""
    estimate = 1.5 * volume / (REGULAR_TET * mesh_size ** 3)
    limit = max_elements()
    if estimate > limit:
        raise MeshError(f"mesh '{name}': mesh_size {mesh_size:g} m would make about {estimate:.2g} elements "
                        f"(volume {volume:.3g} m^3), more than the limit of {limit:.2g}; use a larger mesh_size, "
                        "or raise the limit with the environment variable WARPSOFT_MAX_ELEMENTS")


def _cached(name: str, key: str, make) -> TetMesh:
    """``make()``, or the mesh kept under ``WARPSOFT_MESH_CACHE`` for ``key``."""
    cache = os.environ.get("WARPSOFT_MESH_CACHE")
    if not cache:
        return make()
    path = Path(cache) / f"{name}-{hashlib.sha1(key.encode()).hexdigest()[:16]}.npz"
    if path.is_file():
        try:
            with np.load(path) as data:
                return TetMesh(data["nodes"], data["tets"], name=name)
        except (OSError, ValueError, KeyError, zipfile.BadZipFile) as exc:  # unreadable: meshed again
            warnings.warn(f"mesh cache: {path} cannot be read ({exc}); meshing '{name}' again", stacklevel=2)
    mesh = make()
    part = path.with_name(f"{path.stem}.{os.getpid()}.part.npz")  # processes meshing at once (a sweep's)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        np.savez(part, nodes=mesh.nodes, tets=mesh.tets)
        os.replace(part, path)  # never read half-written
    except OSError as exc:  # the cache only saves time: a full disk or a read-only folder turns it off
        if part.parent.is_dir():
            part.unlink(missing_ok=True)
        os.environ.pop("WARPSOFT_MESH_CACHE", None)
        warnings.warn(f"mesh cache: cannot write {path} ({exc}); the cache is off for the rest of this run",
                      stacklevel=2)
    return mesh


@contextmanager
def _gmsh(name: str, failure: str):
    """A gmsh session on a new model ``name``; gmsh's own errors become MeshErrors that say
    ``failure`` (Ctrl-C, a KeyboardInterrupt, goes through: gmsh is interruptible in the main
    thread, where it may install its signal handler)."""
    import threading

    import gmsh

    gmsh.initialize(interruptible=threading.current_thread() is threading.main_thread())
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.option.setNumber("General.Verbosity", 1)
        gmsh.model.add(name)
        yield gmsh
    except MeshError:
        raise
    except Exception as exc:
        raise MeshError(f"mesh '{name}': {failure}: {exc}") from None
    finally:
        gmsh.finalize()


def _gmsh_tets(gmsh, name: str, scale: float = 1.0) -> TetMesh:
    """The tetrahedra of gmsh's current model (node coordinates times ``scale``)."""
    tags, coords, _ = gmsh.model.mesh.getNodes()
    etypes, _, enodes = gmsh.model.mesh.getElements(3)
    tets = [n for t, n in zip(etypes, enodes, strict=True) if t == 4]
    if not tets:
        raise MeshError(f"mesh '{name}': gmsh produced no tetrahedra (mesh_size too large?)")
    index = np.full(int(tags.max()) + 1, -1, dtype=np.int64)
    index[tags.astype(np.int64)] = np.arange(len(tags))
    conn = index[np.concatenate(tets).astype(np.int64).reshape(-1, 4)]
    return TetMesh.oriented(scale * coords.reshape(-1, 3), conn, name=name)


def mesh_surface(path: str | Path, mesh_size: float, scale: float = 1e-3, name: str | None = None,
                 feature_angle: float = 40.0) -> TetMesh:
    """Fill a closed surface mesh file (STL, as SoftRobots ships its robots; any format gmsh
    reads) with linear tetrahedra of edge about ``mesh_size`` (m).

    ``scale``: metres per file unit (1e-3 for millimetres, SoftRobots' unit). ``feature_angle``
    (degrees): surface edges sharper than this are kept as edges of the remeshed surface.
    Meshes are cached as :func:`mesh_shape`'s are (``WARPSOFT_MESH_CACHE``), keyed by the file's
    content and the settings.
    """
    path = Path(path)
    name = name or path.stem
    if not path.is_file():
        raise MeshError(f"mesh_surface: file {str(path)!r} does not exist")
    for key, v in (("mesh_size", mesh_size), ("scale", scale)):
        if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
            raise SceneError(f"mesh '{name}': {key} must be a finite number > 0, got {v!r}")
    digest = hashlib.sha1(path.read_bytes()).hexdigest()
    return _cached(name, f"surface|{digest}|{float(mesh_size)!r}|{float(scale)!r}|{feature_angle!r}",
                   lambda: _gmsh_fill(path, float(mesh_size), float(scale), name, float(feature_angle)))


def _gmsh_fill(path: Path, mesh_size: float, scale: float, name: str, feature_angle: float) -> TetMesh:
    with _gmsh(name, f"gmsh failed to fill {str(path)!r}") as gmsh:
        try:
            gmsh.merge(str(path))
        except Exception as exc:
            raise MeshError(f"mesh '{name}': gmsh cannot read {str(path)!r}: {exc}") from None
        tags, coords, _ = gmsh.model.mesh.getNodes()
        etypes, _, enodes = gmsh.model.mesh.getElements(2)
        tris = [n for t, n in zip(etypes, enodes, strict=True) if t == 2]
        if not tris or not len(tags):
            raise MeshError(f"mesh '{name}': {str(path)!r} holds no triangles")
        index = np.full(int(tags.max()) + 1, -1, dtype=np.int64)
        index[tags.astype(np.int64)] = np.arange(len(tags))
        x = scale * coords.reshape(-1, 3)[index[np.concatenate(tris).astype(np.int64).reshape(-1, 3)]]
        volume = abs(float(np.einsum("ij,ij->i", x[:, 0], np.cross(x[:, 1], x[:, 2])).sum()) / 6.0)
        if volume <= 0.0:
            raise MeshError(f"mesh '{name}': the surface in {str(path)!r} encloses no volume (not closed?)")
        check_size(name, volume, mesh_size)
        gmsh.model.mesh.classifySurfaces(math.radians(feature_angle), True, True, math.pi)
        gmsh.model.mesh.createGeometry()
        loop = gmsh.model.geo.addSurfaceLoop([e[1] for e in gmsh.model.getEntities(2)])
        gmsh.model.geo.addVolume([loop])
        gmsh.model.geo.synchronize()
        gmsh.option.setNumber("Mesh.MeshSizeMin", 0.5 * mesh_size / scale)
        gmsh.option.setNumber("Mesh.MeshSizeMax", mesh_size / scale)
        gmsh.option.setNumber("Mesh.Optimize", 1)
        gmsh.model.mesh.generate(3)
        return _gmsh_tets(gmsh, name, scale)


def mesh_shape(shape: Shape, mesh_size: float, name: str = "shape", optimize: bool = True,
               curvature: int = 12, refine: Refine | None = None) -> TetMesh:
    """Mesh a shape with linear tetrahedra of characteristic edge length ``mesh_size`` (m).

    ``curvature``: elements per full turn on curved surfaces (refines small radii, down to
    half of ``mesh_size``); 0 meshes curved and flat surfaces alike. ``refine``: smaller
    elements around a point (:class:`Refine`).

    If the environment variable ``WARPSOFT_MESH_CACHE`` names a folder, meshes are kept
    there (keyed by the shape's description and the settings) and read back instead of
    re-meshed: design sweeps skip gmsh, and machines without gmsh can run prepared scenes.
    """
    if not isinstance(shape, Shape):
        hint = ""
        if isinstance(shape, Region):
            hint = (f": ws.{type(shape).__name__} is a region (it selects nodes); the solids are ws.shapes.Box, "
                    "ws.Cylinder, ws.Cone and ws.Ball")
        raise SceneError(f"mesh_shape: expected a Shape, got {type(shape).__name__}{hint}")
    if not (isinstance(mesh_size, (int, float)) and math.isfinite(mesh_size) and mesh_size > 0):
        raise SceneError(f"mesh '{name}': mesh_size must be a finite number > 0 m, got {mesh_size!r}")
    if refine is not None and not isinstance(refine, Refine):
        raise SceneError(f"mesh '{name}': refine must be a ws.shapes.Refine, got {type(refine).__name__}")
    key = f"{shape!r}|{float(mesh_size)!r}|{optimize}|{curvature}" + (f"|{refine!r}" if refine else "")
    return _cached(name, key, lambda: _gmsh_mesh(shape, float(mesh_size), name, optimize, curvature, refine))


def _gmsh_mesh(shape: Shape, mesh_size: float, name: str, optimize: bool, curvature: int,
               refine: Refine | None) -> TetMesh:
    with _gmsh(name, "gmsh failed") as gmsh:
        vols = shape._add(gmsh.model.occ)
        gmsh.model.occ.synchronize()
        if not vols:
            raise MeshError(f"mesh '{name}': the shape has no volume (an empty boolean result?)")
        volume = sum(gmsh.model.occ.getMass(3, v) for _, v in gmsh.model.getEntities(3))
        check_size(name, volume, mesh_size)
        smallest = 0.5 * mesh_size
        if refine is not None and refine.size < mesh_size:
            check_size(name, min(volume, refine.volume()), refine.size)
            refine._field(gmsh, mesh_size)
            smallest = min(smallest, float(refine.size))
        gmsh.option.setNumber("Mesh.MeshSizeMin", smallest)
        gmsh.option.setNumber("Mesh.MeshSizeMax", mesh_size)
        gmsh.option.setNumber("Mesh.MeshSizeFromCurvature", int(curvature))
        gmsh.option.setNumber("Mesh.Optimize", 1 if optimize else 0)
        gmsh.model.mesh.generate(3)
        return _gmsh_tets(gmsh, name)
