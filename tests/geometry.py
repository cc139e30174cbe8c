"""Test helpers that measure a deformed surface independently of the simulator's own contact code."""

import numpy as np


def winding_numbers(points: np.ndarray, tri_x: np.ndarray) -> np.ndarray:
    """Generalized winding numbers ``(p,)`` of ``points`` ``(p, 3)`` against the closed surface of
    triangles ``tri_x`` ``(t, 3, 3)`` (Van Oosterom and Strackee's solid angles): 1 inside, 0 outside."""
    out = np.zeros(len(points))
    for i0 in range(0, len(points), 64):
        P = points[i0:i0 + 64]
        a, b, c = (tri_x[None, :, k] - P[:, None] for k in range(3))
        la, lb, lc = (np.linalg.norm(v, axis=2) for v in (a, b, c))
        num = np.einsum("ptk,ptk->pt", a, np.cross(b, c))
        den = (la * lb * lc + np.einsum("ptk,ptk->pt", a, b) * lc + np.einsum("ptk,ptk->pt", b, c) * la
               + np.einsum("ptk,ptk->pt", c, a) * lb)
        out[i0:i0 + 64] = np.arctan2(num, den).sum(axis=1) / (2.0 * np.pi)
    return out


def point_triangle_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Distances ``(k,)`` from points ``p`` to triangles ``(a, b, c)``, all ``(k, 3)``: the nearest
    point by its Voronoi region (face, edge or corner)."""
    dot = lambda u, v: np.einsum("ij,ij->i", u, v)  # noqa: E731
    safe = lambda d: np.where(d != 0.0, d, 1.0)  # noqa: E731
    ab, ac = b - a, c - a
    d1, d2 = dot(ab, p - a), dot(ac, p - a)
    d3, d4 = dot(ab, p - b), dot(ac, p - b)
    d5, d6 = dot(ab, p - c), dot(ac, p - c)
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
    denom = safe(va + vb + vc)
    x = a + ab * (vb / denom)[:, None] + ac * (vc / denom)[:, None]  # the face
    regions = [  # later ones take precedence, as the first tests of the sequential algorithm
        ((va <= 0) & (d4 - d3 >= 0) & (d5 - d6 >= 0), b + (c - b) * ((d4 - d3) / safe(d4 - d3 + d5 - d6))[:, None]),
        ((vb <= 0) & (d2 >= 0) & (d6 <= 0), a + ac * (d2 / safe(d2 - d6))[:, None]),
        ((d6 >= 0) & (d5 <= d6), c),
        ((vc <= 0) & (d1 >= 0) & (d3 <= 0), a + ab * (d1 / safe(d1 - d3))[:, None]),
        ((d3 >= 0) & (d4 <= d3), b),
        ((d1 <= 0) & (d2 <= 0), a),
    ]
    for mask, y in regions:
        x = np.where(mask[:, None], y, x)
    return np.linalg.norm(p - x, axis=1)


def penetration_depths(q: np.ndarray, tris: np.ndarray, nodes: np.ndarray, eps: float = 1e-6) -> np.ndarray:
    """How deep (m) each of the surface ``nodes`` lies inside the body bounded by ``tris`` (outward
    triangles, node ids into ``q``): 0 where the point ``eps`` (m) out of the surface along its
    normal is outside the body; else the node's distance to the nearest triangle it is not a
    corner of (a node that went through another part of the body)."""
    normal = np.zeros_like(q)
    face = np.cross(q[tris[:, 1]] - q[tris[:, 0]], q[tris[:, 2]] - q[tris[:, 0]])
    for k in range(3):
        np.add.at(normal, tris[:, k], face)
    n = normal[nodes] / np.linalg.norm(normal[nodes], axis=1)[:, None]
    inside = winding_numbers(q[nodes] + eps * n, q[tris]) > 0.5
    depth = np.zeros(len(nodes))
    for i in np.flatnonzero(inside):
        others = tris[~np.any(tris == nodes[i], axis=1)]
        depth[i] = point_triangle_distance(np.repeat(q[nodes[i]][None], len(others), axis=0),
                                           q[others[:, 0]], q[others[:, 1]], q[others[:, 2]]).min()
    return depth
