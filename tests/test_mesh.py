"""Meshes: reading real files, validation, surfaces, parametric gmsh shapes."""

import numpy as np
import pytest

import warpsoft as ws
from warpsoft.scene.mesh import signed_volumes


def surface_closed_and_outward(mesh: ws.TetMesh) -> tuple[bool, float]:
    tris = mesh.surface()
    edges = np.sort(tris[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    _, counts = np.unique(edges, axis=0, return_counts=True)
    x = mesh.nodes[tris]
    # divergence theorem: V = 1/3 sum over faces of (centroid . area-normal)
    vol = np.sum(np.einsum("ij,ij->i", x.mean(axis=1), np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]) / 2)) / 3
    return bool(np.all(counts == 2)), vol


@pytest.mark.parametrize("name,nodes,tets", [("diamond.vtk", 1628, 4147), ("finger.vtk", 158, 389),
                                             ("trunk.vtk", 709, 1972), ("pneunet_coarse.vtk", 376, 1195)])
def test_softrobots_meshes_load_in_metres(reference_dir, name, nodes, tets):
    mesh = ws.load_mesh(reference_dir / name, scale=1e-3)
    assert (mesh.num_nodes, mesh.num_elements) == (nodes, tets)
    assert np.all(signed_volumes(mesh.nodes, mesh.tets) > 0)
    closed, vol = surface_closed_and_outward(mesh)
    assert closed and vol == pytest.approx(mesh.volume, rel=1e-9)
    assert np.ptp(mesh.nodes, axis=0).max() < 0.25  # metres, not millimetres


def test_surface_only_file_is_a_clear_error(reference_dir):
    with pytest.raises(ws.MeshError, match=r"finger.stl.*no tetrahedra.*triangle"):
        ws.load_mesh(reference_dir / "finger.stl")


def test_unreadable_vtk_is_an_error_not_an_exit(tmp_path):
    bad = tmp_path / "broken.vtk"
    bad.write_text("# vtk DataFile Version 2.0\nnonsense\nASCII\nDATASET NOPE\n")
    with pytest.raises(ws.MeshError, match="broken.vtk.*cannot read"):
        ws.load_mesh(bad)
    with pytest.raises(ws.MeshError, match="no such file"):
        ws.load_mesh(tmp_path / "missing.vtu")


def test_file_round_trip_keeps_mesh(tmp_path):
    mesh = ws.box_grid((0, 0, 0), (0.02, 0.01, 0.01), (4, 2, 2))
    ws.save_mesh(mesh, tmp_path / "m.vtu")
    back = ws.load_mesh(tmp_path / "m.vtu")
    assert np.allclose(back.nodes, mesh.nodes) and back.volume == pytest.approx(2e-6)


def test_degenerate_and_inverted_elements_are_named():
    nodes = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 0]], dtype=float)
    with pytest.raises(ws.MeshError, match=r"element 1 .*zero volume"):
        ws.TetMesh(nodes, [[0, 1, 2, 3], [0, 1, 2, 4]])
    with pytest.raises(ws.MeshError, match=r"element 0 .*negative volume"):
        ws.TetMesh(nodes, [[0, 2, 1, 3]])
    fixed = ws.TetMesh.oriented(nodes, [[0, 2, 1, 3]])
    assert fixed.volume == pytest.approx(1 / 6) and fixed.num_nodes == 4
    with pytest.raises(ws.MeshError, match="non-finite"):
        ws.TetMesh(np.where(nodes == 1, np.nan, nodes), [[0, 1, 2, 3]])
    with pytest.raises(ws.MeshError, match="node ids"):
        ws.TetMesh(nodes, [[0, 1, 2, 9]])


def test_gmsh_shapes_and_booleans_have_their_volume():
    box = ws.shapes.Box((0, 0, 0), (0.04, 0.02, 0.02))
    hole = ws.Cylinder((0.02, 0.01, -0.01), (0, 0, 0.04), 0.005)
    mesh = ws.mesh_shape(box - hole, 0.003)
    assert mesh.volume == pytest.approx(0.04 * 0.02 * 0.02 - np.pi * 0.005**2 * 0.02, rel=0.01)
    cone = ws.mesh_shape(ws.Cone((0, 0, 0), (0, 0, 0.1), 0.02, 0.01), 0.005)
    assert cone.volume == pytest.approx(np.pi * 0.1 / 3 * (0.02**2 + 0.02 * 0.01 + 0.01**2), rel=0.02)
    closed, vol = surface_closed_and_outward(mesh)
    assert closed and vol == pytest.approx(mesh.volume, rel=1e-9)


def test_bad_shape_parameters_are_named():
    with pytest.raises(ws.SceneError, match="Box.size"):
        ws.shapes.Box((0, 0, 0), (0.1, 0, 0.1))
    with pytest.raises(ws.SceneError, match="mesh_size"):
        ws.mesh_shape(ws.shapes.Box((0, 0, 0), (1, 1, 1)), float("nan"))


def test_mesh_cache_returns_the_same_mesh(tmp_path, monkeypatch):
    monkeypatch.setenv("WARPSOFT_MESH_CACHE", str(tmp_path))
    shape = ws.shapes.Box((0, 0, 0), (0.02, 0.01, 0.01)) - ws.Ball((0.01, 0.005, 0.01), 0.004)
    first = ws.mesh_shape(shape, 0.003, name="part")
    files = list(tmp_path.glob("part-*.npz"))
    assert len(files) == 1
    again = ws.mesh_shape(shape, 0.003, name="part")
    assert np.array_equal(first.nodes, again.nodes) and np.array_equal(first.tets, again.tets)
    ws.mesh_shape(shape, 0.004, name="part")  # another size is another entry
    assert len(list(tmp_path.glob("part-*.npz"))) == 2
