"""Tetrahedral meshes: validation, boundary surface, transforms, and reading files with meshio."""

from __future__ import annotations

import io
from contextlib import redirect_stderr, redirect_stdout
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import MeshError

# Faces of a positively oriented tetrahedron (i0, i1, i2, i3), each listed with an outward normal.
TET_FACES = np.array([[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]], dtype=np.int64)
# A quadratic element's edges, in the order of its nodes 4-9
TET_EDGES = np.array([[0, 1], [0, 2], [0, 3], [1, 2], [1, 3], [2, 3]], dtype=np.int64)
# A quadratic element (corners 0-3, midpoints 4-9) split into eight tetrahedra: one at each
# corner, and the inner octahedron cut along the diagonal 5-8 (midpoints of 02 and 13)
SUBDIVISION = np.array([[0, 4, 5, 6], [4, 1, 7, 8], [5, 7, 2, 9], [6, 8, 9, 3],
                        [5, 8, 4, 7], [5, 8, 7, 9], [5, 8, 9, 6], [5, 8, 6, 4]], dtype=np.int64)


KEYED_NODES = 2**21  # meshes with fewer nodes give each triangle one int64 key (three ids in base n)


def triangle_keys(tris: np.ndarray, n: int) -> np.ndarray:
    """One number per triangle ``(..., 3)`` of node ids below ``n`` (< ``KEYED_NODES``), the same
    in any node order: its sorted ids in base ``n``."""
    k = np.sort(tris, axis=-1).astype(np.int64)
    return (k[..., 0] * n + k[..., 1]) * n + k[..., 2]


def signed_volumes(nodes: np.ndarray, tets: np.ndarray) -> np.ndarray:
    """Signed volume (m^3) of each tetrahedron, shape ``(m,)``."""
    x = nodes[tets]
    return np.einsum("ij,ij->i", x[:, 1] - x[:, 0], np.cross(x[:, 2] - x[:, 0], x[:, 3] - x[:, 0])) / 6.0


@dataclass
class TetMesh:
    """A linear tetrahedral mesh, or a quadratic one (:meth:`quadratic_refined`).

    Attributes:
        nodes: rest positions, shape ``(n, 3)``, float64 (m).
        tets: node ids of each element, shape ``(m, 4)``, int32, positive volumes. In a
            quadratic mesh, the eight tetrahedra that split each quadratic element, element after
            element: what mappings, surfaces, contacts and drawings see.
        name: a label used in error messages.
        quadratic: None, or the 10-node elements ``(m / 8, 10)`` int32 (corners, then the
            midpoints of edges 01, 02, 03, 12, 13, 23) that the elastic forces use.
    """

    nodes: np.ndarray
    tets: np.ndarray
    name: str = "mesh"
    _surface: np.ndarray | None = field(default=None, repr=False, compare=False)
    quadratic: np.ndarray | None = field(default=None, repr=False, compare=False)

    def __post_init__(self) -> None:
        nodes = np.asarray(self.nodes, dtype=np.float64)
        tets = np.asarray(self.tets)
        if nodes.ndim != 2 or nodes.shape[1] != 3 or len(nodes) == 0:
            raise MeshError(f"mesh '{self.name}': nodes must have shape (n, 3), got {nodes.shape}")
        if tets.ndim != 2 or tets.shape[1] != 4 or len(tets) == 0:
            raise MeshError(f"mesh '{self.name}': tets must have shape (m, 4) with m > 0, got {tets.shape}")
        if not np.issubdtype(tets.dtype, np.integer):
            raise MeshError(f"mesh '{self.name}': tets must hold integer node ids, got dtype {tets.dtype}")
        bad = np.flatnonzero(~np.all(np.isfinite(nodes), axis=1))
        if len(bad):
            raise MeshError(f"mesh '{self.name}': node {bad[0]} has a non-finite position {nodes[bad[0]].tolist()}")
        if tets.min() < 0 or tets.max() >= len(nodes):
            raise MeshError(
                f"mesh '{self.name}': node ids must lie in [0, {len(nodes) - 1}], got range "
                f"[{tets.min()}, {tets.max()}]"
            )
        vol = signed_volumes(nodes, tets)
        scale = np.mean(np.abs(vol))
        tiny = np.flatnonzero(np.abs(vol) <= 1e-9 * scale) if scale > 0 else np.arange(len(vol))
        if len(tiny):
            e = tiny[0]
            raise MeshError(
                f"mesh '{self.name}': element {e} (nodes {tets[e].tolist()}) has zero volume {vol[e]:.3e} m^3 "
                f"({len(tiny)} degenerate element(s) in all)"
            )
        neg = np.flatnonzero(vol < 0)
        if len(neg):
            e = neg[0]
            raise MeshError(
                f"mesh '{self.name}': element {e} (nodes {tets[e].tolist()}) has negative volume {vol[e]:.3e} m^3 "
                f"({len(neg)} inverted element(s)); reorder its nodes or build with TetMesh.oriented(...)"
            )
        self.nodes, self.tets = nodes, tets.astype(np.int32)
        if self.quadratic is not None:
            quad = np.asarray(self.quadratic)
            if quad.shape != (len(tets) // 8, 10) or 8 * len(quad) != len(tets):
                raise MeshError(f"mesh '{self.name}': quadratic elements must have shape ({len(tets) // 8}, 10) "
                                f"(eight tetrahedra each), got {quad.shape}")
            self.quadratic = quad.astype(np.int32)

    def quadratic_refined(self) -> TetMesh:
        """The mesh of 10-node elements on this one: a node at each edge's midpoint (straight
        edges), each element split into eight tetrahedra at them (:data:`SUBDIVISION`, oriented)."""
        if self.quadratic is not None:
            return self
        pairs = np.sort(self.tets[:, TET_EDGES].reshape(-1, 2), axis=1)
        edges, which = np.unique(pairs, axis=0, return_inverse=True)
        nodes = np.concatenate([self.nodes, 0.5 * (self.nodes[edges[:, 0]] + self.nodes[edges[:, 1]])])
        elems = np.concatenate([self.tets, self.num_nodes + which.reshape(len(self.tets), 6)], axis=1)
        sub = elems[:, SUBDIVISION].reshape(-1, 4)
        neg = signed_volumes(nodes, sub) < 0
        sub[neg] = sub[neg][:, [0, 2, 1, 3]]
        return TetMesh(nodes, sub, name=self.name, quadratic=elems)

    def refined(self, times: int = 1) -> TetMesh:
        """The mesh split ``times`` times, each element into eight at its edges' midpoints: a
        nested refinement halving the element size each time (for convergence studies of a mesh
        given as a file). Linear meshes only."""
        if self.quadratic is not None:
            raise MeshError(f"mesh '{self.name}': refined() splits linear meshes; this one is quadratic")
        if int(times) < 0:
            raise MeshError(f"mesh '{self.name}': refined() takes times >= 0, got {times!r}")
        mesh = self
        for _ in range(int(times)):
            split = mesh.quadratic_refined()
            mesh = TetMesh(split.nodes, split.tets, name=self.name)
        return mesh

    @classmethod
    def oriented(cls, nodes, tets, name: str = "mesh", drop_unused: bool = True) -> TetMesh:
        """Build a mesh after making every element positively oriented (swapping two nodes of
        the negative ones) and, by default, dropping nodes no element uses."""
        nodes = np.asarray(nodes, dtype=np.float64)
        tets = np.array(tets, dtype=np.int64)
        if tets.ndim == 2 and tets.shape[1] == 4 and len(tets) and nodes.ndim == 2 and nodes.shape[1:] == (3,):
            if tets.min() >= 0 and tets.max() < len(nodes):
                neg = signed_volumes(nodes, tets) < 0
                tets[neg] = tets[neg][:, [0, 2, 1, 3]]
                if drop_unused:
                    used = np.unique(tets)
                    remap = np.full(len(nodes), -1, dtype=np.int64)
                    remap[used] = np.arange(len(used))
                    nodes, tets = nodes[used], remap[tets]
        return cls(nodes, tets, name=name)

    @property
    def num_nodes(self) -> int:
        return len(self.nodes)

    @property
    def num_elements(self) -> int:
        return len(self.tets)

    @property
    def volume(self) -> float:
        """Total volume (m^3)."""
        return float(signed_volumes(self.nodes, self.tets).sum())

    def mean_surface_edge(self) -> float:
        """Mean edge length (m) of the boundary triangles."""
        x = self.nodes[self.surface()]
        return float(np.mean(np.linalg.norm(x - np.roll(x, 1, axis=1), axis=2)))

    def surface(self) -> np.ndarray:
        """Boundary triangles, outward oriented, shape ``(k, 3)`` (node ids)."""
        if self._surface is None:
            faces = self.tets[:, TET_FACES].reshape(-1, 3)
            n = self.num_nodes
            # a face as one number: one sort of numbers, not of rows
            key = triangle_keys(faces, n) if n < KEYED_NODES else np.sort(faces, axis=1)
            _, inverse, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
            self._surface = faces[counts[inverse.ravel()] == 1].astype(np.int32)
        return self._surface

    def transformed(self, scale: float = 1.0, rotation=None, translation=(0.0, 0.0, 0.0)) -> TetMesh:
        """A copy with ``x' = rotation @ (scale * x) + translation`` (rotation: 3x3, det > 0)."""
        R = np.eye(3) if rotation is None else np.asarray(rotation, dtype=float)
        if R.shape != (3, 3) or not np.isclose(np.linalg.det(R), 1.0, atol=1e-6):
            raise MeshError(f"mesh '{self.name}': rotation must be a 3x3 proper rotation, got {R.tolist()}")
        if not np.isfinite(scale) or scale <= 0:
            raise MeshError(f"mesh '{self.name}': scale must be a finite number > 0, got {scale!r}")
        nodes = scale * self.nodes @ R.T + np.asarray(translation, dtype=float)
        quad = None if self.quadratic is None else self.quadratic.copy()
        return TetMesh(nodes, self.tets.copy(), name=self.name, quadratic=quad)


def rotation_about(axis: str, degrees: float) -> np.ndarray:
    """Rotation matrix about the x, y or z axis (right-handed)."""
    c, s = np.cos(np.radians(degrees)), np.sin(np.radians(degrees))
    i = "xyz".index(axis)
    j, k = (i + 1) % 3, (i + 2) % 3
    R = np.eye(3)
    R[j, j], R[j, k], R[k, j], R[k, k] = c, -s, s, c
    return R


def _sniff_format(path: Path) -> str | None:
    """Return a meshio format name when the content contradicts the extension."""
    with open(path, "rb") as f:
        head = f.read(256).lstrip()
    if path.suffix.lower() == ".vtk" and (head.startswith(b"<?xml") or head.startswith(b"<VTKFile")):
        return "vtu"  # SoftRobots ships XML VTU content under .vtk names
    return None


def load_mesh(path: str | Path, scale: float = 1.0, name: str | None = None) -> TetMesh:
    """Read a volume mesh file with meshio and keep its tetrahedra.

    Args:
        path: any format meshio reads (VTK legacy or XML, MSH, ...).
        scale: factor from file units to metres (1e-3 for files in mm).
        name: label for errors; the file name by default.

    Other cell types (vertices, lines, triangles) are ignored; elements are reoriented to
    positive volume; nodes used by no tetrahedron are dropped. Any reader failure, even a
    reader that tries to exit the process, becomes a :class:`MeshError`.
    """
    import meshio

    path = Path(path)
    label = name or path.name
    if not path.is_file():
        raise MeshError(f"mesh '{label}': no such file {str(path)!r}")
    if not np.isfinite(scale) or scale <= 0:
        raise MeshError(f"mesh '{label}': scale must be a finite number > 0, got {scale!r}")
    fmt = _sniff_format(path)
    sink = io.StringIO()
    try:
        with redirect_stdout(sink), redirect_stderr(sink):
            m = meshio.read(path, file_format=fmt)
    except (Exception, SystemExit) as exc:  # meshio's legacy VTK reader calls sys.exit on bad input
        detail = sink.getvalue().strip().splitlines()
        why = f"{type(exc).__name__}: {exc}" + (f" ({detail[-1]})" if detail else "")
        raise MeshError(f"mesh '{label}': cannot read {str(path)!r}: {why}") from None
    blocks = [c.data for c in m.cells if c.type == "tetra"]
    if not blocks:
        kinds = sorted({c.type for c in m.cells}) or ["none"]
        raise MeshError(f"mesh '{label}': {str(path)!r} holds no tetrahedra (cell types: {', '.join(kinds)})")
    return TetMesh.oriented(np.asarray(m.points[:, :3], dtype=np.float64) * scale, np.concatenate(blocks), name=label)


def save_mesh(mesh: TetMesh, path: str | Path) -> None:
    """Write the mesh with meshio (format from the extension, e.g. .vtu, .msh)."""
    import meshio

    meshio.write(path, meshio.Mesh(mesh.nodes, [("tetra", mesh.tets)]))


def box_grid(lo, hi, divisions) -> TetMesh:
    """Structured tetrahedral mesh of the box ``lo``-``hi`` (m): ``divisions = (nx, ny, nz)``
    cubes, each split into six tetrahedra sharing its main diagonal (conforming, symmetric)."""
    lo, hi = np.asarray(lo, dtype=float), np.asarray(hi, dtype=float)
    n = np.asarray(divisions, dtype=int)
    if lo.shape != (3,) or hi.shape != (3,) or n.shape != (3,) or np.any(n < 1) or np.any(hi <= lo):
        raise MeshError(f"box_grid: need lo < hi (3 numbers each) and 3 divisions >= 1, got {lo}, {hi}, {n}")
    axes = [np.linspace(lo[k], hi[k], n[k] + 1) for k in range(3)]
    X, Y, Z = np.meshgrid(*axes, indexing="ij")
    nodes = np.stack([X.ravel(), Y.ravel(), Z.ravel()], axis=1)

    def nid(i, j, k):
        return (i * (n[1] + 1) + j) * (n[2] + 1) + k

    i, j, k = (a.ravel() for a in np.meshgrid(*(np.arange(m) for m in n), indexing="ij"))
    c = [nid(i + (b & 1), j + ((b >> 1) & 1), k + ((b >> 2) & 1)) for b in range(8)]  # cube corners
    # six tetrahedra around the diagonal c0-c7, one per path of edges 0 -> 7
    paths = [(1, 3), (1, 5), (2, 3), (2, 6), (4, 5), (4, 6)]
    tets = np.concatenate([np.stack([c[0], c[a], c[b], c[7]], axis=1) for a, b in paths])
    return TetMesh.oriented(nodes, tets, name="box_grid", drop_unused=False)
