"""USD export: one stage per run, time-sampled body surfaces, cavity walls, cables, probe,
effector and target spheres, the obstacles and rigid bodies (each kind under a typed Scope) and, when asked,
the contacts (points with their forces)."""

from __future__ import annotations

import glob
import re
from pathlib import Path

import numpy as np

from ..errors import OutputError, SceneError
from ..model import Model
from .atomic import write_whole

USD_TEMPORARY = re.compile(r"[A-Za-z0-9]{6}")  # USD's atomic writer: <stem>.XXXXXX beside the file it writes


def temporary(path: Path) -> Path:
    """Where the stage of ``path`` is written before it is renamed over it: ``.STEM.tmp.EXT`` (USD
    picks the format by the extension)."""
    return path.with_name(f".{path.stem}.tmp{path.suffix}")


def stale_temporaries(path: Path) -> list[Path]:
    """The temporary files a killed writer of ``path`` can leave: this writer's own
    (``.STEM.tmp.EXT``), and the one USD's atomic writer makes beside it while exporting
    (``.STEM.tmp.XXXXXX``, six letters or digits)."""
    ours = temporary(path)
    theirs = [p for p in path.parent.glob(f".{glob.escape(path.stem)}.tmp.*")
              if USD_TEMPORARY.fullmatch(p.name[len(f".{path.stem}.tmp."):])]
    return [ours, *theirs]


class UsdWriter:
    """Write a run as a USD animation (``.usda`` text or ``.usdc`` binary, by extension).

    Frame ``k`` (time code ``k``) holds the state after step ``k``; frame 0 the initial state.
    Stage metadata: ``upAxis = Z``, ``metersPerUnit = 1``, ``timeCodesPerSecond = 1 / dt``.
    ``contacts=True``: each frame's contacts (world 0) as points, ``/World/contacts/points``,
    with their force on the body (N) in the primvar ``force``, and drawn as segments
    ``/World/contacts/forces`` from each point (their length: the largest force of the first
    frame with contacts is a tenth of the model's size).
    """

    def __init__(self, path: str | Path, model: Model, contacts: bool = False):
        from pxr import Gf, Sdf, Usd, UsdGeom, Vt

        self._Gf, self._Vt, self._UsdGeom = Gf, Vt, UsdGeom
        path = Path(path)
        if path.suffix not in (".usda", ".usdc", ".usd"):
            raise SceneError(f"USD output: extension must be .usda, .usdc or .usd, got {str(path)!r}")
        path.parent.mkdir(parents=True, exist_ok=True)
        self.path, self.model = path, model
        for stale in stale_temporaries(path):  # a killed run's
            stale.unlink(missing_ok=True)
        self.stage = Usd.Stage.CreateInMemory(path.name)
        UsdGeom.SetStageUpAxis(self.stage, UsdGeom.Tokens.z)
        UsdGeom.SetStageMetersPerUnit(self.stage, 1.0)
        self.stage.SetTimeCodesPerSecond(1.0 / model.dt)
        self.stage.SetStartTimeCode(0)
        world = UsdGeom.Xform.Define(self.stage, "/World")
        self.stage.SetDefaultPrim(world.GetPrim())
        self.stage.GetRootLayer().customLayerData = {"generator": "warpsoft", "scene": model.scene.name}

        self.meshes = []  # (UsdGeom.Mesh, surface node ids)
        for body in model.bodies:
            ids, local = np.unique(body.surface, return_inverse=True)
            mesh = UsdGeom.Mesh.Define(self.stage, f"/World/{_name(body.name)}")
            mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
            mesh.CreateFaceVertexCountsAttr(Vt.IntArray([3] * len(body.surface)))
            mesh.CreateFaceVertexIndicesAttr(Vt.IntArray(local.astype(int).ravel().tolist()))
            mesh.CreateDisplayColorAttr(Vt.Vec3fArray([Gf.Vec3f(0.85, 0.45, 0.3)]))
            self.meshes.append((mesh, ids))
        size = float(np.linalg.norm(model.rest_np.max(axis=0) - model.rest_np.min(axis=0)))
        self.probes = {}
        if model.probe_names:
            UsdGeom.Scope.Define(self.stage, "/World/probes")
        for name in model.probe_names:
            sphere = UsdGeom.Sphere.Define(self.stage, f"/World/probes/{_name(name)}")
            sphere.CreateRadiusAttr(0.015 * size)
            sphere.CreateDisplayColorAttr(Vt.Vec3fArray([Gf.Vec3f(0.2, 0.4, 0.9)]))
            self.probes[name] = sphere.AddTranslateOp()
        self.cables, self.effectors, self.targets = {}, {}, {}
        self.movers = {}  # moving obstacle name -> its transform op (world 0)
        self.contacts, self._newtons_to_m, self._size = None, None, size
        if contacts:
            self._group("/World/contacts")
            points = UsdGeom.Points.Define(self.stage, "/World/contacts/points")
            points.CreateDisplayColorAttr(Vt.Vec3fArray([Gf.Vec3f(0.95, 0.75, 0.1)]))
            force = UsdGeom.PrimvarsAPI(points).CreatePrimvar("force", Sdf.ValueTypeNames.Vector3fArray,
                                                              UsdGeom.Tokens.vertex)
            arrows = UsdGeom.BasisCurves.Define(self.stage, "/World/contacts/forces")
            arrows.CreateTypeAttr(UsdGeom.Tokens.linear)
            arrows.CreateDisplayColorAttr(Vt.Vec3fArray([Gf.Vec3f(0.95, 0.75, 0.1)]))
            self.contacts = (points, force, arrows)
        self._marker = 0.02 * size
        self.cavities = []  # (UsdGeom.Mesh, global node ids): the cavities' walls, seen through the body
        for w, scene in enumerate(model.scenes):
            for cavity in scene.cavities:
                if not self.cavities:
                    UsdGeom.Scope.Define(self.stage, "/World/cavities")
                tris = cavity.surface() + model.body_info(cavity.body.name, w).node_start
                ids, local = np.unique(tris, return_inverse=True)
                mesh = UsdGeom.Mesh.Define(self.stage, f"/World/cavities/{_name(cavity.name)}")
                mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
                mesh.CreateFaceVertexCountsAttr(Vt.IntArray([3] * len(tris)))
                mesh.CreateFaceVertexIndicesAttr(Vt.IntArray(local.astype(int).ravel().tolist()))
                mesh.CreateDisplayColorAttr(Vt.Vec3fArray([Gf.Vec3f(0.2, 0.5, 0.95)]))
                mesh.CreateDisplayOpacityAttr(Vt.FloatArray([0.5]))
                mesh.CreateDoubleSidedAttr(True)
                self.cavities.append((mesh, ids))
        self._obstacles(model, size)
        self.frames = 0
        _ = Sdf  # imported for its side effect of loading the USD file formats

    def _obstacles(self, model: Model, size: float) -> None:
        """The scene's obstacles (grey, a floor as a square of 4 model sizes) and rigid bodies
        (orange) as prims; a moving one (a scheduled obstacle, every rigid body) under a
        transform sampled per frame."""
        Gf, Vt, UsdGeom = self._Gf, self._Vt, self._UsdGeom
        solids = [(w, "obstacles", e.name, e.shape, e.motion is not None) for w, scene in enumerate(model.scenes)
                  for e in scene.obstacles]
        solids += [(w, "rigid_bodies", rb.name, rb.shape, True) for w, rb in model.rigid]
        grey, orange = Vt.Vec3fArray([Gf.Vec3f(0.6, 0.6, 0.62)]), Vt.Vec3fArray([Gf.Vec3f(0.95, 0.55, 0.15)])
        for w, group, name, shape, moving in solids:
            self._group(f"/World/{group}")
            path = f"/World/{group}/{_name(name)}" + (f"_{w}" if model.num_worlds > 1 else "")
            if moving:  # the solid as declared, under a transform sampled per frame
                mover = UsdGeom.Xform.Define(self.stage, path)
                if w == 0:  # (the frames record world 0's rows)
                    self.movers[name] = mover.AddTransformOp()
                path += "/shape"
            self._solid(path, shape, size).CreateDisplayColorAttr(grey if group == "obstacles" else orange)

    def _solid(self, path: str, shape, size: float):
        """One solid of ``ws.obstacles`` as a USD prim at ``path`` (where it was declared)."""
        from ..scene import obstacles as ob

        Gf, Vt, UsdGeom = self._Gf, self._Vt, self._UsdGeom
        if isinstance(shape, ob.Floor):
            n = np.asarray(shape.normal) / np.linalg.norm(shape.normal)
            u = np.cross(n, [1.0, 0.0, 0.0] if abs(n[0]) < 0.9 else [0.0, 1.0, 0.0])
            u /= np.linalg.norm(u)
            v = np.cross(n, u)
            c = np.asarray(shape.point)
            corners = [c + 2 * size * (su * u + sv * v) for su, sv in ((-1, -1), (1, -1), (1, 1), (-1, 1))]
            prim = UsdGeom.Mesh.Define(self.stage, path)
            prim.CreatePointsAttr(Vt.Vec3fArray([Gf.Vec3f(*map(float, p)) for p in corners]))
            prim.CreateFaceVertexCountsAttr(Vt.IntArray([4]))
            prim.CreateFaceVertexIndicesAttr(Vt.IntArray([0, 1, 2, 3]))
            prim.CreateDoubleSidedAttr(True)
        elif isinstance(shape, ob.Mesh):
            prim = UsdGeom.Mesh.Define(self.stage, path)
            prim.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(shape.vertices.astype(np.float32)))
            prim.CreateFaceVertexCountsAttr(Vt.IntArray([3] * len(shape.triangles)))
            prim.CreateFaceVertexIndicesAttr(Vt.IntArray(shape.triangles.ravel().tolist()))
            prim.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
            prim.AddTransformOp().Set(_placement(shape.translation, shape.rotation, Gf))
        elif isinstance(shape, ob.Ball):
            prim = UsdGeom.Sphere.Define(self.stage, path)
            prim.CreateRadiusAttr(shape.radius)
            prim.AddTranslateOp().Set(Gf.Vec3d(*shape.center))
        elif isinstance(shape, ob.Box):
            prim = UsdGeom.Cube.Define(self.stage, path)
            prim.CreateSizeAttr(1.0)
            prim.AddTransformOp().Set(_placement(np.asarray(shape.center), np.asarray(shape.rotation), Gf))
            prim.AddScaleOp().Set(Gf.Vec3f(*map(float, shape.size)))
        else:  # a capsule or a cylinder, along its axis a -> b
            a, b = np.asarray(shape.a), np.asarray(shape.b)
            kind = UsdGeom.Capsule if isinstance(shape, ob.Capsule) else UsdGeom.Cylinder
            prim = kind.Define(self.stage, path)
            prim.CreateRadiusAttr(shape.radius)
            prim.CreateHeightAttr(float(np.linalg.norm(b - a)))
            prim.CreateAxisAttr(UsdGeom.Tokens.z)
            prim.AddTransformOp().Set(_placement(0.5 * (a + b), _turn_z_to(b - a), Gf))
        return prim

    def _sphere(self, path: str, color) -> object:
        Gf, Vt = self._Gf, self._Vt
        sphere = self._UsdGeom.Sphere.Define(self.stage, path)
        sphere.CreateRadiusAttr(self._marker)
        sphere.CreateDisplayColorAttr(Vt.Vec3fArray([Gf.Vec3f(*color)]))
        return sphere.AddTranslateOp()

    def _group(self, path: str) -> None:
        """A typed group prim (Scope) for a kind of row, made once."""
        if not self.stage.GetPrimAtPath(path):
            self._UsdGeom.Scope.Define(self.stage, path)

    def write_rows(self, frame: int, geometry: dict) -> None:
        """Cables as linear curves through their path, effectors (green) and targets (red)
        as spheres, moving obstacles' transforms, at time code ``frame`` (``geometry`` from
        ``Simulator.constraint_geometry``)."""
        Gf, Vt, UsdGeom = self._Gf, self._Vt, self._UsdGeom
        for name, path in geometry["cables"].items():
            if name not in self.cables:
                self._group("/World/cables")
                curve = UsdGeom.BasisCurves.Define(self.stage, f"/World/cables/{_name(name)}")
                curve.CreateTypeAttr(UsdGeom.Tokens.linear)
                curve.CreateCurveVertexCountsAttr(Vt.IntArray([len(path)]))
                curve.CreateWidthsAttr(Vt.FloatArray([0.3 * self._marker]))
                curve.CreateDisplayColorAttr(Vt.Vec3fArray([Gf.Vec3f(0.1, 0.1, 0.1)]))
                self.cables[name] = curve
            self.cables[name].GetPointsAttr().Set(Vt.Vec3fArray.FromNumpy(np.asarray(path, dtype=np.float32)), frame)
        for name, (rotation, translation) in geometry.get("obstacles", {}).items():
            if name in self.movers:
                self.movers[name].Set(_placement(translation, rotation, Gf), frame)
        if self.contacts is not None and "contacts" in geometry:
            self._write_contacts(frame, *geometry["contacts"])
        for group, store, color in (("effectors", self.effectors, (0.1, 0.7, 0.2)),
                                    ("targets", self.targets, (0.9, 0.1, 0.1))):
            for name, p in geometry[group].items():
                if name not in store:
                    self._group(f"/World/{group}")
                    store[name] = self._sphere(f"/World/{group}/{_name(name)}", color)
                store[name].Set(Gf.Vec3d(*np.asarray(p, dtype=float).tolist()), frame)

    def _write_contacts(self, frame: int, points: np.ndarray, forces: np.ndarray) -> None:
        """The contacts of a frame: points ``(k, 3)`` (m), forces on the body ``(k, 3)`` (N)."""
        Vt = self._Vt
        prim, force, arrows = self.contacts
        largest = float(np.linalg.norm(forces, axis=1).max(initial=0.0))
        if self._newtons_to_m is None and largest > 0.0:  # fixed from the first frame that has a force
            self._newtons_to_m = 0.1 * self._size / largest
        scale = self._newtons_to_m or 0.0
        f32 = lambda a: Vt.Vec3fArray.FromNumpy(np.asarray(a, dtype=np.float32).reshape(-1, 3))  # noqa: E731
        prim.GetPointsAttr().Set(f32(points), frame)
        prim.GetWidthsAttr().Set(Vt.FloatArray([0.4 * self._marker] * len(points)), frame)
        force.Set(f32(forces), frame)
        arrows.GetPointsAttr().Set(f32(np.stack([points, points + scale * forces], axis=1)), frame)
        arrows.GetCurveVertexCountsAttr().Set(Vt.IntArray([2] * len(points)), frame)

    def write_frame(self, frame: int, q: np.ndarray, probes: dict[str, np.ndarray]) -> None:
        """Store positions ``q`` ``(n, 3)`` (m) and probe positions at time code ``frame``."""
        Gf, Vt = self._Gf, self._Vt
        for mesh, ids in self.meshes:
            pts = q[ids]
            mesh.GetPointsAttr().Set(Vt.Vec3fArray.FromNumpy(pts.astype(np.float32)), frame)
            lo, hi = pts.min(axis=0), pts.max(axis=0)
            mesh.GetExtentAttr().Set(Vt.Vec3fArray([Gf.Vec3f(*lo.tolist()), Gf.Vec3f(*hi.tolist())]), frame)
        for name, op in self.probes.items():
            op.Set(Gf.Vec3d(*np.asarray(probes[name], dtype=float).tolist()), frame)
        for mesh, ids in self.cavities:
            mesh.GetPointsAttr().Set(Vt.Vec3fArray.FromNumpy(q[ids].astype(np.float32)), frame)
        self.frames = max(self.frames, frame + 1)

    def save(self) -> Path:
        """Write the stage: to a temporary file beside it, then renamed over it, so that a full
        disk or a kill leaves the last whole file (and the next writer removes a stale temporary)."""
        self.stage.SetEndTimeCode(max(self.frames - 1, 0))
        def export(tmp: Path) -> None:
            if not self.stage.GetRootLayer().Export(str(tmp)):
                raise OSError(f"USD could not export the stage to {tmp}")

        try:
            return write_whole(self.path, export, temporary(self.path))
        except Exception as exc:  # (USD raises its own error types for a failed write)
            raise OutputError(f"USD: cannot write {self.path}: {exc}") from exc


def _placement(center: np.ndarray, rotation: np.ndarray, Gf) -> object:
    """A USD transform (row vectors: the rotation's transpose, then the translation)."""
    m = np.eye(4)
    m[:3, :3] = rotation.T
    m[3, :3] = center
    return Gf.Matrix4d(*m.ravel().tolist())


def _turn_z_to(direction: np.ndarray) -> np.ndarray:
    """A rotation taking the z axis to ``direction``."""
    z = direction / np.linalg.norm(direction)
    x = np.cross([0.0, 1.0, 0.0] if abs(z[1]) < 0.9 else [1.0, 0.0, 0.0], z)
    x /= np.linalg.norm(x)
    return np.stack([x, np.cross(z, x), z], axis=1)


def _name(name: str) -> str:
    from pxr import Tf

    return Tf.MakeValidIdentifier(name)
