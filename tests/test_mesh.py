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


def test_refine_makes_small_elements_near_its_point_only():
    """A refinement point: edges within its radius about its size, edges far away the mesh's;
    the volume unchanged, every node in an element; bad refinements are named."""
    box = ws.shapes.Box((0, 0, 0), (0.04, 0.02, 0.02))
    plain = ws.mesh_shape(box, 0.004)
    fine = ws.mesh_shape(box, 0.004, refine=ws.shapes.Refine((0.0, 0.0, 0.0), 0.001, 0.003))
    edges = fine.tets[:, [0, 0, 0, 1, 1, 2]], fine.tets[:, [1, 2, 3, 2, 3, 3]]
    x0, x1 = fine.nodes[edges[0]], fine.nodes[edges[1]]
    length = np.linalg.norm(x1 - x0, axis=-1)
    middle = np.linalg.norm(0.5 * (x0 + x1), axis=-1)
    assert np.median(length[middle < 0.003]) < 0.0015 and np.median(length[middle > 0.015]) > 0.003
    assert fine.num_elements > plain.num_elements and fine.volume == pytest.approx(plain.volume, rel=1e-9)
    assert len(np.unique(fine.tets)) == fine.num_nodes
    with pytest.raises(ws.SceneError, match="Refine: size -0.001 m"):
        ws.shapes.Refine((0, 0, 0), -0.001, 0.003)
    with pytest.raises(ws.SceneError, match="refine must be a ws.shapes.Refine, got tuple"):
        ws.mesh_shape(box, 0.004, refine=((0, 0, 0), 0.001, 0.003))


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


def test_softrobots_finger_stl_is_filled_with_tetrahedra_that_step(reference_dir, monkeypatch, tmp_path):
    """SoftRobots ships its robots as closed STL surfaces in millimetres: mesh_surface fills them
    with tetrahedra whose volume is the volume the surface encloses and whose box is the file's,
    in metres; finer sizes give more elements of the same volume; the result simulates."""
    monkeypatch.setenv("WARPSOFT_MESH_CACHE", str(tmp_path))  # (and the cache keeps it)
    coarse = ws.mesh_surface(reference_dir / "finger.stl", 0.006)
    fine = ws.mesh_surface(reference_dir / "finger.stl", 0.003)
    assert np.all(signed_volumes(coarse.nodes, coarse.tets) > 0)
    assert np.allclose(np.ptp(coarse.nodes, axis=0), [0.10337, 0.015, 0.015], rtol=1e-3)  # 103.4 x 15 x 15 mm
    assert fine.num_elements > 4 * coarse.num_elements
    assert fine.volume == pytest.approx(coarse.volume, rel=0.01) and coarse.volume == pytest.approx(1.8455e-5, rel=0.01)
    assert ws.mesh_surface(reference_dir / "finger.stl", 0.006).num_elements == coarse.num_elements  # from the cache
    scene = ws.Scene("finger", dt=0.01)
    body = scene.add_body("finger", coarse, ws.Material(5e5, 0.45, 1000.0), element="corotational")
    scene.fix(body, ws.OnPlane((0, 0, 0), (1, 0, 0)))  # its base, at x = 0
    sim = ws.Simulator(scene, solver="direct")
    for _ in range(3):
        sim.step()
    assert np.all(np.isfinite(sim.positions())) and sim.positions()[:, 2].min() < coarse.nodes[:, 2].min()  # sags


def test_a_mesh_size_too_small_is_refused_before_gmsh_runs(tmp_path, monkeypatch):
    """A mesh_size that would make tens of millions of elements hung gmsh for minutes: the
    estimate refuses it at once, and the limit can be raised."""
    import time

    monkeypatch.delenv("WARPSOFT_MESH_CACHE", raising=False)  # gmsh's path, not a cached mesh
    t0 = time.perf_counter()
    with pytest.raises(ws.MeshError, match=r"mesh 'tiny': mesh_size 0.0002 m would make about .* elements .* "
                                           r"more than the limit"):
        ws.mesh_shape(ws.Cylinder((0, 0, 0), (0, 0, 0.05), 0.01), 0.0002, name="tiny")
    assert time.perf_counter() - t0 < 5.0
    monkeypatch.setenv("WARPSOFT_MAX_ELEMENTS", "lots")
    with pytest.raises(ws.SceneError, match="WARPSOFT_MAX_ELEMENTS must be a number, got 'lots'"):
        ws.mesh_shape(ws.Cylinder((0, 0, 0), (0, 0, 0.05), 0.01), 0.005, name="tiny")
    with pytest.raises(ws.MeshError, match="does not exist"):
        ws.mesh_surface(tmp_path / "none.stl", 0.01)
