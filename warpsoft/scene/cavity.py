"""Pneumatic cavity: a closed void in a body, inflated by a pressure.

``delta = V - V0`` is the cavity's volume growth (m^3), ``lambda`` its pressure (Pa, >= 0
unless vacuum is allowed with a negative ``min_force``). ``H = dV/dq`` per node is the exact
gradient of the volume: over linear triangles, a third of each one's area x normal; over a
quadratic body's 6-node faces, ``int N n dA`` (:mod:`warpsoft.scene.surface`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import SceneError
from .actuator import Actuator
from .surface import enclosed_volume, volume_terms


@dataclass
class Cavity(Actuator):
    """A cavity (scene side): the body's boundary triangles inside ``region`` (or explicit
    ``triangles``: body node ids, oriented out of the void) must form a closed surface, or
    one closed by ``symmetry_planes`` (ws.OnPlane) of a symmetric model: its open edges
    must lie on them, and the volume is measured from a point common to them all."""

    body: object = None
    region: object = None
    triangles: np.ndarray | None = None
    symmetry_planes: list | None = None
    kind = "cavity"

    def origin(self, tris: np.ndarray) -> np.ndarray:
        """Reference point (m) of the volume formula: on every symmetry plane, else the centroid."""
        centroid = self.body.mesh.nodes[np.unique(tris)].mean(axis=0)
        if not self.symmetry_planes:
            return centroid
        N = np.array([p.normal for p in self.symmetry_planes])
        c = np.array([p.normal @ p.point for p in self.symmetry_planes])
        # the point of the planes' intersection nearest the centroid (least norm correction)
        return centroid + np.linalg.pinv(N) @ (c - N @ centroid)

    def surface(self) -> np.ndarray:
        """The cavity's triangles (body node ids), oriented out of the void; validated."""
        mesh = self.body.mesh
        if self.triangles is not None:
            tris = np.asarray(self.triangles, dtype=np.int64)
            if tris.ndim != 2 or tris.shape[1] != 3 or tris.min() < 0 or tris.max() >= mesh.num_nodes:
                raise SceneError(f"cavity '{self.name}': triangles must be (k, 3) node ids of body "
                                 f"'{self.body.name}'")
        else:
            boundary = mesh.surface()
            inside = self.region(mesh.nodes)
            tris = boundary[np.all(inside[boundary], axis=1)][:, [0, 2, 1]]  # body-outward -> void-outward
            if len(tris) == 0:
                raise SceneError(f"cavity '{self.name}': region {self.region!r} holds no boundary triangle of "
                                 f"body '{self.body.name}'")
        planes = self.symmetry_planes or []
        on_plane = [p(mesh.nodes) for p in planes]
        check_closed_surface(tris, f"cavity '{self.name}'", on_plane)
        triples, weights = volume_terms(mesh, tris, f"cavity '{self.name}'")
        volume = enclosed_volume(mesh.nodes, triples, weights, self.origin(tris))
        if volume <= 0:
            raise SceneError(f"cavity '{self.name}': the surface is mis-oriented (it encloses {volume:.3e} m^3; "
                             "its normals must point out of the void, into the material)")
        return tris


def check_closed_surface(tris: np.ndarray, label: str, on_plane: list[np.ndarray] = ()) -> None:
    """Every edge must be shared by exactly two triangles, traversed once in each direction,
    except edges lying on a symmetry plane (``on_plane``: per plane, a node mask)."""
    directed = tris[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    keys, counts = np.unique(directed, axis=0, return_counts=True)
    if np.any(counts > 1):
        a, b = keys[np.argmax(counts > 1)]
        raise SceneError(f"{label}: the surface is mis-oriented: edge ({a}, {b}) runs the same way in two "
                         "triangles (neighbouring normals disagree)")
    forward = {tuple(k) for k in keys}
    missing = [k for k in forward if (k[1], k[0]) not in forward
               and not any(mask[k[0]] and mask[k[1]] for mask in on_plane)]
    if missing:
        raise SceneError(f"{label}: the surface is open: {len(missing)} edge(s) belong to one triangle only, "
                         f"e.g. ({missing[0][0]}, {missing[0][1]})")
