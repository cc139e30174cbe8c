"""Integrals over a body's boundary: the load share of each node and the volume a surface
encloses, for linear triangles and for the 6-node faces of quadratic (10-node) elements.

A quadratic body's surface is stored as the four flat sub-triangles of each face (what
:meth:`TetMesh.surface` and the renderers see), but its loads follow the face's own shape
functions ``N`` (corners ``L (2L - 1)``, mid-edges ``4 L_a L_b``): a uniform traction on a flat
face gives its corners nothing and each mid-edge a third, and a cavity's volume is that of the
curved quadratic surface, whose exact gradient is its pressure's nodal load ``int N n dA``.
"""

from __future__ import annotations

import itertools
from functools import cache

import numpy as np

from ..errors import SceneError
from .mesh import KEYED_NODES, TET_EDGES, TET_FACES, triangle_keys

# A 6-node face: corners 0-2, then the mid-edges of (0, 1), (1, 2), (2, 0); its four flat
# sub-triangles, oriented as the face
FACE_SUBTRIANGLES = np.array([[0, 3, 5], [1, 4, 3], [2, 5, 4], [3, 4, 5]])


def triangle_rule(points: int = 4) -> tuple[np.ndarray, np.ndarray]:
    """A rule on the reference triangle ``u, v >= 0, u + v <= 1``: points ``(n, 2)`` and weights
    ``(n,)`` (summing to 1/2), exact for polynomials of degree ``2 points - 2`` (collapsed Gauss)."""
    x, w = np.polynomial.legendre.leggauss(points)
    s, ws = (x + 1.0) / 2.0, w / 2.0
    u, v = np.meshgrid(s, s, indexing="ij")
    return np.stack([u.ravel(), (v * (1.0 - u)).ravel()], axis=1), np.outer(ws * (1.0 - s), ws).ravel()


def quadratic_shapes(uv: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The 6-node face's shape functions at ``uv`` ``(n, 2)``, and their ``u`` and ``v``
    derivatives: three ``(n, 6)`` arrays."""
    u, v = uv[:, 0], uv[:, 1]
    lam = np.stack([1.0 - u - v, u, v], axis=1)
    dl_du, dl_dv = np.array([-1.0, 1.0, 0.0]), np.array([-1.0, 0.0, 1.0])
    pairs = [(0, 1), (1, 2), (2, 0)]
    n = np.concatenate([lam * (2.0 * lam - 1.0), np.stack([4.0 * lam[:, a] * lam[:, b] for a, b in pairs], 1)], 1)

    def derivative(dl):
        corners = (4.0 * lam - 1.0) * dl
        mids = np.stack([4.0 * (dl[a] * lam[:, b] + lam[:, a] * dl[b]) for a, b in pairs], axis=1)
        return np.concatenate([corners, mids], axis=1)

    return n, derivative(dl_du), derivative(dl_dv)


@cache
def quadratic_volume_terms() -> tuple[np.ndarray, np.ndarray]:
    """The volume of a 6-node face seen from the origin, ``1/3 int x . (x_u x x_v) du dv``, as
    ``sum_t w_t x_i . (x_j x x_k)`` over triples ``(i, j, k)`` of its nodes: ``(20, 3)`` node
    triples and ``(20,)`` weights (the integrand is trilinear in the nodes and the triple product
    antisymmetric, so the antisymmetrized coefficients over ``i < j < k`` are the whole of it;
    the integral is exact, degree 4)."""
    uv, w = triangle_rule(4)
    n, nu, nv = quadratic_shapes(uv)
    c = np.einsum("q,qi,qj,qk->ijk", w, n, nu, nv) / 3.0
    triples = np.array(list(itertools.combinations(range(6), 3)))
    weights = np.zeros(len(triples))
    for t, (i, j, k) in enumerate(triples):
        # the six orderings of (i, j, k): even ones with +, odd ones with -
        weights[t] = c[i, j, k] + c[j, k, i] + c[k, i, j] - c[j, i, k] - c[i, k, j] - c[k, j, i]
    return triples, weights


def _local_faces() -> np.ndarray:
    """A 10-node element's four faces as 6-node faces: ``(4, 6)`` local node ids."""

    def mid(a, b):
        return 4 + next(e for e, (i, j) in enumerate(TET_EDGES) if {i, j} == {a, b})

    return np.array([[a, b, c, mid(a, b), mid(b, c), mid(c, a)] for a, b, c in TET_FACES])


def quadratic_faces(mesh, tris: np.ndarray, label: str, partial: bool = False) -> np.ndarray:
    """The 6-node faces ``(k, 6)`` (body node ids, corners then mid-edges, oriented as ``tris``)
    whose four sub-triangles ``tris`` holds. ``tris`` must cover whole faces of the quadratic
    ``mesh``, or with ``partial`` the faces it covers in part are left out."""
    n = mesh.num_nodes
    if n >= KEYED_NODES:  # (a triangle's key must fit 63 bits)
        raise SceneError(f"{label}: quadratic meshes of {KEYED_NODES} nodes or more are not supported, got {n}")
    tris = np.asarray(tris, dtype=np.int64)
    faces = mesh.quadratic.astype(np.int64)[:, _local_faces()].reshape(-1, 6)
    # a face shared by two elements: once
    faces = faces[np.unique(triangle_keys(faces[:, :3], n), return_index=True)[1]]
    wanted = triangle_keys(tris, n)
    order = np.argsort(wanted)
    sub_keys = triangle_keys(faces[:, FACE_SUBTRIANGLES], n)  # (faces, 4)
    held = np.isin(sub_keys, wanted)
    faces, sub_keys = faces[held.all(axis=1)], sub_keys[held.all(axis=1)]
    missing = ~np.isin(wanted, sub_keys)
    if (missing.any() or len(faces) * 4 != len(tris)) and not (partial and len(faces)):
        tri = tris[np.argmax(missing)] if missing.any() else tris[0]
        raise SceneError(f"{label}: {max(int(missing.sum()), 1)} triangle(s), e.g. nodes {tri.tolist()}, do not make "
                         "whole 6-node faces of the quadratic mesh: select every sub-triangle of a face, or none")
    # orient each face as its central sub-triangle is given
    given = tris[order[np.searchsorted(wanted, sub_keys[:, 3], sorter=order)]]
    central = faces[:, 3:]
    at = np.argmax(central == given[:, :1], axis=1)
    same = given[:, 1] == central[np.arange(len(faces)), (at + 1) % 3]
    return np.where(same[:, None], faces, faces[:, [0, 2, 1, 5, 4, 3]])


def volume_terms(mesh, tris: np.ndarray, label: str) -> tuple[np.ndarray, np.ndarray]:
    """The volume enclosed by ``tris`` (body node ids, oriented outward), as weighted triple
    products ``V = sum_t w_t x_i . (x_j x x_k)`` of positions relative to an origin: ``(k, 3)``
    triples and ``(k,)`` weights. Linear triangles are their own triples (``w = 1/6``); a quadratic
    mesh's sub-triangles are taken four at a time, as the 6-node face they split."""
    tris = np.asarray(tris, dtype=np.int64)
    if mesh.quadratic is None:
        return tris, np.full(len(tris), 1.0 / 6.0)
    faces = quadratic_faces(mesh, tris, label)
    local, weights = quadratic_volume_terms()
    return faces[:, local].reshape(-1, 3), np.tile(weights, len(faces))


def enclosed_volume(nodes: np.ndarray, triples: np.ndarray, weights: np.ndarray, origin) -> float:
    """Volume (m^3) of :func:`volume_terms` at positions ``nodes`` ``(n, 3)`` (m) seen from ``origin``."""
    x = nodes[triples] - np.asarray(origin, dtype=float)
    return float(weights @ np.einsum("ij,ij->i", x[:, 0], np.cross(x[:, 1], x[:, 2])))


def area_shares(mesh, tris: np.ndarray, label: str) -> np.ndarray:
    """Each node's share ``int N_i dA`` (m^2, ``(nodes,)``) of the surface ``tris`` (body node
    ids) at rest: a third of each triangle's area at its corners, or the 6-node faces' shape
    functions integrated over the (possibly curved) face; on a quadratic mesh, the faces ``tris``
    holds in part are left out."""
    tris = np.asarray(tris, dtype=np.int64)
    share = np.zeros(mesh.num_nodes)
    if mesh.quadratic is None:
        x = mesh.nodes[tris]
        area = 0.5 * np.linalg.norm(np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]), axis=1)
        np.add.at(share, tris.ravel(), np.repeat(area / 3.0, 3))
        return share
    faces = quadratic_faces(mesh, tris, label, partial=True)
    uv, w = triangle_rule(4)
    n, nu, nv = quadratic_shapes(uv)
    x = mesh.nodes[faces]  # (faces, 6, 3)
    jacobian = np.linalg.norm(np.cross(np.einsum("qi,fid->fqd", nu, x), np.einsum("qi,fid->fqd", nv, x)), axis=2)
    np.add.at(share, faces.ravel(), np.einsum("q,qi,fq->fi", w, n, jacobian).ravel())
    return share
