"""Point location: barycentric coordinates of material points in tetrahedra (host side).

A point inside the mesh gets the element that contains it. A point just outside (SoftRobots'
own scenes put cable points 0.1-0.5 mm outside their meshes, and SOFA maps them) gets the
nearest element and extrapolated weights (the unclipped barycentric coordinates: they still
sum to 1, so the point follows that element's affine motion exactly), provided it lies
within ``outside`` times that element's mean edge length; farther is an error that says how
far. Candidate elements come from a KD-tree of element centroids (SciPy), not from a solve
against every element; the full scan runs only when no candidate is close enough.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from .errors import SceneError

CANDIDATES = 32  # nearest element centroids tried per point before a full scan
OUTSIDE = 0.5  # default tolerance outside the mesh, in mean edge lengths of the nearest element


def barycentric(nodes: np.ndarray, tets: np.ndarray, point: np.ndarray) -> np.ndarray:
    """Barycentric coordinates of ``point`` (m) in the elements ``tets``: ``(..., 4)`` for
    ``tets`` ``(..., 4)`` and ``point`` ``(3,)`` or broadcasting against ``tets``' leading shape."""
    x = nodes[tets]  # (..., 4, 3)
    Dm = np.stack([x[..., 1, :] - x[..., 0, :], x[..., 2, :] - x[..., 0, :], x[..., 3, :] - x[..., 0, :]], axis=-1)
    rhs = np.broadcast_to(point - x[..., 0, :], x[..., 0, :].shape)
    l123 = np.linalg.solve(Dm, rhs[..., None])[..., 0]
    return np.concatenate([1.0 - l123.sum(axis=-1, keepdims=True), l123], axis=-1)


def _outside_distance(nodes: np.ndarray, tet: np.ndarray, lam: np.ndarray, point: np.ndarray) -> float:
    """Distance (m) from ``point`` to the element's point with clipped, renormalized weights
    (zero inside; an upper bound of the distance to the element outside)."""
    w = np.clip(lam, 0.0, None)
    return float(np.linalg.norm(point - (w / w.sum()) @ nodes[tet]))


def _mean_edge(nodes: np.ndarray, tet: np.ndarray) -> float:
    x = nodes[tet]
    pairs = [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)]
    return float(np.mean([np.linalg.norm(x[a] - x[b]) for a, b in pairs]))


def locate(nodes: np.ndarray, tets: np.ndarray, points: np.ndarray, names: list[str], tol: float = 1e-6,
           outside: float = OUTSIDE) -> tuple[np.ndarray, np.ndarray]:
    """Find, for each point, its element and barycentric weights.

    Args:
        nodes: ``(n, 3)`` rest positions (m); tets: ``(m, 4)`` node ids.
        points: ``(p, 3)`` points (m); names: their labels for errors.
        tol: how far outside an element (in barycentric units) still counts as inside.
        outside: how far outside the mesh a point may lie, in mean edge lengths of its
            nearest element (0: points must be inside).

    Returns:
        ``(node_ids, weights)``, shapes ``(p, 4)`` int32 and ``(p, 4)`` float64; weights sum to 1
        (negative ones extrapolate, for points outside the mesh).

    Raises:
        SceneError: naming the first point farther outside than allowed, with its distance.
    """
    tets = np.asarray(tets)
    points = np.asarray(points, dtype=float).reshape(-1, 3)
    centroids = nodes[tets].mean(axis=1)
    tree = cKDTree(centroids)
    k = min(CANDIDATES, len(tets))
    ids = np.zeros((len(points), 4), dtype=np.int32)
    weights = np.zeros((len(points), 4))
    if len(names) != len(points):
        raise ValueError(f"locate: {len(points)} points and {len(names)} names")
    # every point against its candidates at once; those none of them holds go on one by one below
    with np.errstate(all="ignore"):
        _, near = tree.query(points, k=k)
        near = near.reshape(len(points), k)
        known = near < len(tets)  # (the tree answers len(tets) where a distance overflows)
        lam = barycentric(nodes, tets[np.where(known, near, 0)], points[:, None, :])  # (p, k, 4)
        worst = np.where(known, lam.min(axis=2), -np.inf)
    best = np.argmax(worst, axis=1)
    rows = np.arange(len(points))
    inside = (worst[rows, best] >= -tol) & np.all(np.isfinite(lam[rows, best]), axis=1)
    w = np.clip(lam[rows[inside], best[inside]], 0.0, None)
    ids[inside], weights[inside] = tets[near[rows[inside], best[inside]]], w / w.sum(axis=1, keepdims=True)
    for j in np.flatnonzero(~inside):
        p, name = points[j], names[j]
        cand = near[j][known[j]] if np.any(known[j]) else np.arange(len(tets))
        lam = barycentric(nodes, tets[cand], p)
        worst = lam.min(axis=1)
        best = int(np.argmax(worst))
        if worst[best] < -tol:  # no candidate holds it: look at every element before extrapolating
            cand = np.arange(len(tets))
            lam = barycentric(nodes, tets, p)
            worst = lam.min(axis=1)
            best = int(np.argmax(worst))
        e = int(cand[best])
        if not np.all(np.isfinite(lam[best])):
            raise SceneError(f"point '{name}' at {p.tolist()} m: its barycentric coordinates in the mesh are not "
                             "finite (coordinates too large or elements too flat for float64)")
        if worst[best] >= -tol:
            w = np.clip(lam[best], 0.0, None)
            ids[j], weights[j] = tets[e], w / w.sum()
            continue
        # outside every element: the element it is least outside of, within the tolerance
        distance = _outside_distance(nodes, tets[e], lam[best], p)
        allowed = outside * _mean_edge(nodes, tets[e])
        if distance > allowed:
            raise SceneError(f"point '{name}' at {p.tolist()} m lies outside every element: {distance:.3g} m "
                             f"from the nearest one, more than the {allowed:.3g} m allowed ({outside:g} of its "
                             f"mean edge length)")
        ids[j], weights[j] = tets[e], lam[best]
    return ids, weights


BALL_GRID = 16  # sample points per diameter of an anchor ball (~2,100 inside it)


def ball_weights(nodes: np.ndarray, tets: np.ndarray, center, radius: float,
                 name: str) -> tuple[np.ndarray, np.ndarray]:
    """The mean displacement over the material within ``radius`` (m) of ``center`` (m), as node
    weights: ``u = sum_i w_i u_i`` with ``w_i = int N_i dV / V`` over the ball's part inside the
    mesh (a regular grid of sample points; each one inside an element adds its barycentric
    coordinates). Returns node ids ``(k,)`` int32 and weights ``(k,)`` (summing to 1).

    Raises:
        SceneError: naming ``name`` when no sample point lies in the material.
    """
    nodes, tets = np.asarray(nodes, dtype=float), np.asarray(tets)
    axis = (np.arange(BALL_GRID) + 0.5) / BALL_GRID * 2.0 - 1.0
    grid = np.stack(np.meshgrid(axis, axis, axis, indexing="ij"), axis=-1).reshape(-1, 3)
    samples = np.asarray(center, dtype=float) + radius * grid[np.linalg.norm(grid, axis=1) <= 1.0]
    tree = cKDTree(nodes[tets].mean(axis=1))
    _, cand = tree.query(samples, k=min(CANDIDATES, len(tets)))
    cand = np.minimum(cand.reshape(len(samples), -1), len(tets) - 1)
    lam = barycentric(nodes, tets[cand], samples[:, None, :])  # (samples, candidates, 4)
    best = np.argmax(lam.min(axis=-1), axis=1)
    rows = np.arange(len(samples))
    lam, elem = lam[rows, best], cand[rows, best]
    inside = lam.min(axis=1) >= -1e-9
    if not inside.any():
        raise SceneError(f"{name}: no material within {radius:g} m of {np.asarray(center).tolist()} m")
    ids = tets[elem[inside]].ravel()
    weights = np.clip(lam[inside], 0.0, None).ravel()
    unique, at = np.unique(ids, return_inverse=True)
    total = np.bincount(at, weights)
    return unique.astype(np.int32), total / total.sum()
