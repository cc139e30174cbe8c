"""Point location: inside, just outside (extrapolated, as SOFA's barycentric mapping), too far."""

import numpy as np
import pytest

import warpsoft as ws
from warpsoft.mapping import locate

H = 0.01  # element size of the grid (m)


def grid():
    return ws.box_grid((0, 0, 0), (0.05, 0.02, 0.02), (5, 2, 2))


def test_point_just_outside_follows_its_element_affinely():
    mesh = grid()
    p = np.array([[0.031, 0.013, 0.02 + 0.2 * H]])  # 2 mm above the top face
    ids, w = locate(mesh.nodes, mesh.tets, p, ["above"])
    assert w.sum() == pytest.approx(1.0) and w.min() < 0  # extrapolated weights
    assert np.allclose(w[0] @ mesh.nodes[ids[0]], p[0], atol=1e-15)
    R = ws.rotation_about("z", 30.0) @ ws.rotation_about("x", 50.0)
    moved = mesh.nodes @ R.T + np.array([0.1, -0.2, 0.3])
    assert np.allclose(w[0] @ moved[ids[0]], R @ p[0] + np.array([0.1, -0.2, 0.3]), atol=1e-15)


def test_inside_points_keep_convex_weights():
    mesh = grid()
    p = np.array([[0.012, 0.007, 0.015], [0.0, 0.0, 0.0]])
    ids, w = locate(mesh.nodes, mesh.tets, p, ["a", "corner"])
    assert np.all(w >= 0) and np.allclose(w.sum(axis=1), 1.0)
    assert np.allclose(np.einsum("pk,pkd->pd", w, mesh.nodes[ids]), p, atol=1e-15)


def test_point_too_far_outside_says_how_far():
    mesh = grid()
    with pytest.raises(ws.SceneError, match=r"point 'far' at .* lies outside every element: 0.02\d* m from the nearest "
                                            r"one, more than the .* m allowed"):
        locate(mesh.nodes, mesh.tets, np.array([[0.025, 0.01, 0.04]]), ["far"])
    with pytest.raises(ws.SceneError, match="lies outside every element"):
        locate(mesh.nodes, mesh.tets, np.array([[0.031, 0.013, 0.022]]), ["near"], outside=0.0)


def test_softrobots_diamond_cable_points_map_as_in_sofa(reference_dir):
    """SoftRobots.Inverse's Diamond scene puts its cable points 0.1-0.5 mm outside its own mesh
    (rotated +90 deg about x, moved +35 mm in z): they map to their nearest elements."""
    mesh = ws.load_mesh(reference_dir / "diamond.vtk", scale=1e-3).transformed(
        rotation=ws.rotation_about("x", 90.0), translation=(0.0, 0.0, 0.035))
    points = 1e-3 * np.array([[0.0, 97.0, 45.0], [-97.0, 0.0, 45.0], [0.0, -97.0, 45.0], [97.0, 0.0, 45.0]])
    names = [f"cable{i}" for i in range(4)]
    with pytest.raises(ws.SceneError, match="lies outside every element"):
        locate(mesh.nodes, mesh.tets, points, names, outside=0.0)
    ids, w = locate(mesh.nodes, mesh.tets, points, names)
    assert np.allclose(np.einsum("pk,pkd->pd", w, mesh.nodes[ids]), points, atol=1e-12)
    nearest = [np.min(np.linalg.norm(mesh.nodes - p, axis=1)) for p in points]
    assert max(nearest) < 0.005
