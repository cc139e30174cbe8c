"""Point location: barycentric coordinates of material points inside tetrahedra (host side)."""

from __future__ import annotations

import numpy as np

from .errors import SceneError


def barycentric(nodes: np.ndarray, tets: np.ndarray, point: np.ndarray) -> np.ndarray:
    """Barycentric coordinates of ``point`` (m) in every element, shape ``(m, 4)``."""
    x = nodes[tets]
    Dm = np.stack([x[:, 1] - x[:, 0], x[:, 2] - x[:, 0], x[:, 3] - x[:, 0]], axis=2)
    l123 = np.linalg.solve(Dm, (point - x[:, 0])[:, :, None])[:, :, 0]
    return np.concatenate([1.0 - l123.sum(axis=1, keepdims=True), l123], axis=1)


def locate(nodes: np.ndarray, tets: np.ndarray, points: np.ndarray, names: list[str],
           tol: float = 1e-6) -> tuple[np.ndarray, np.ndarray]:
    """Find, for each point, an element containing it and its barycentric weights.

    Args:
        nodes: ``(n, 3)`` rest positions (m); tets: ``(m, 4)`` node ids.
        points: ``(p, 3)`` points (m); names: their labels for errors.
        tol: how far outside an element (in barycentric units) still counts as inside.

    Returns:
        ``(node_ids, weights)``, shapes ``(p, 4)`` int32 and ``(p, 4)`` float64.

    Raises:
        SceneError: naming the first point that lies outside every element.
    """
    ids = np.zeros((len(points), 4), dtype=np.int32)
    weights = np.zeros((len(points), 4))
    for k, (p, name) in enumerate(zip(points, names, strict=True)):
        lam = barycentric(nodes, tets, np.asarray(p, dtype=float))
        worst = lam.min(axis=1)
        e = int(np.argmax(worst))
        if worst[e] < -tol:
            d = np.min(np.linalg.norm(nodes - p, axis=1))
            raise SceneError(f"point '{name}' at {np.asarray(p).tolist()} m lies outside every element "
                             f"(nearest node {d:.3g} m away)")
        w = np.clip(lam[e], 0.0, None)
        ids[k], weights[k] = tets[e], w / w.sum()
    return ids, weights
