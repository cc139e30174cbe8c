"""Surface loads of 10-node bodies follow their 6-node faces' shape functions: a uniform traction
stretches a bar uniformly, a cavity's pressure loads a flat wall's corners with nothing and its
mid-edges with a third of each face, and the cavity's volume is that of the quadratic surface,
its row the volume's exact gradient."""

import numpy as np
import pytest

import warpsoft as ws
from warpsoft.scene.surface import area_shares, enclosed_volume, quadratic_faces, volume_terms

E, NU = 1e6, 0.45


@pytest.mark.parametrize("element", ["corotational", "quadratic"])
def test_a_uniform_end_traction_stretches_a_bar_uniformly(element):
    """A 3 x 1 x 1 cm bar held on three symmetry planes, pulled by a total force spread over its
    end: the stress is uniaxial and uniform, which both elements represent exactly, so every node
    of the loaded end moves ``F L / (E A)``. Lumping each 6-node face's load over its four flat
    sub-triangles gave its corners a quarter of a sub-triangle's where their share is 0: they moved
    1.1-1.6 % further than the mid-edges."""
    size = np.array([0.03, 0.01, 0.01])
    scene = ws.Scene("bar", static=True, gravity=(0.0, 0.0, 0.0), steps=1)
    body = scene.add_body("bar", ws.box_grid((0.0, 0.0, 0.0), size, (3, 2, 2)), ws.Material(E, NU, 1000.0),
                          element=element)
    for axis, normal in zip("xyz", np.eye(3), strict=True):
        scene.fix(body, ws.OnPlane((0.0, 0.0, 0.0), normal, tol=1e-9), axes=axis)
    strain = 1e-5
    force = strain * E * size[1] * size[2]
    scene.add_force(body, ws.OnPlane(tuple(size), (1.0, 0.0, 0.0), tol=1e-9), (force, 0.0, 0.0))
    sim = ws.Simulator(scene, device="cpu")
    sim.step()
    rest = sim.model.rest_np
    end = np.abs(rest[:, 0] - size[0]) < 1e-9
    stretch = (sim.positions() - rest)[end, 0]
    np.testing.assert_allclose(stretch, strain * size[0], rtol=1e-3)


def hollow_box() -> ws.TetMesh:
    """A 3 cm cube of 27 cells without its middle one: a 1 cm cubic void, 10-node elements."""
    grid = ws.box_grid((0.0, 0.0, 0.0), (0.03, 0.03, 0.03), (3, 3, 3))
    centre = grid.nodes[grid.tets].mean(axis=1)
    solid = ~np.all((centre > 0.01) & (centre < 0.02), axis=1)
    return ws.TetMesh.oriented(grid.nodes, grid.tets[solid]).quadratic_refined()


def test_a_cavity_row_of_a_10_node_body_is_its_faces_consistent_pressure_load():
    """Over a flat face, ``int N n dA`` is 0 at the corners and a third of the face's area at each
    mid-edge; the cubic void's row must be exactly that (before, a quarter of each sub-triangle's
    area went to every node: corners 3-10 % too far on a pressurized wall)."""
    scene = ws.Scene("void", static=True, gravity=(0.0, 0.0, 0.0), steps=1)
    body = scene.add_body("box", hollow_box(), ws.Material(E, NU, 1000.0), element="quadratic")
    scene.fix(body, ws.OnPlane((0.0, 0.0, 0.0), (0.0, 0.0, 1.0), tol=1e-9))
    inside = ws.InBox((0.01 - 1e-9,) * 3, (0.02 + 1e-9,) * 3)
    cavity = scene.add_cavity("void", body, region=inside, mode="pressure", value=100.0)
    sim = ws.Simulator(scene, device="cpu")
    sim.rows.evaluate(sim.state.q)
    h = sim.rows.forces(np.array([1.0]))  # H^T e_void (m^2), (nodes, 3)
    np.testing.assert_allclose(h.sum(axis=0), 0.0, atol=1e-18)  # a closed surface: int n dA = 0
    mesh = body.mesh
    tris = cavity.surface()
    faces = quadratic_faces(mesh, tris, "void")
    assert len(faces) == 6 * 2 * 1  # two 6-node faces on each wall of the 1 cm cube (one cell)
    corners, mids = np.unique(faces[:, :3]), np.unique(faces[:, 3:])
    assert np.abs(h[corners]).max() < 1e-15
    # each mid-edge takes a third of each face it borders, along the face's normal out of the void
    want = np.zeros_like(h)
    x = mesh.nodes[faces]
    normal_area = 0.5 * np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0])
    for k in range(3, 6):
        np.add.at(want, faces[:, k], normal_area / 3.0)
    np.testing.assert_allclose(h[mids], want[mids], atol=1e-15)
    assert np.abs(want).sum() == pytest.approx(6 * 0.01**2, rel=1e-12)  # (the walls are axis-aligned)


def test_the_quadratic_volume_is_exact_and_its_row_is_its_gradient():
    """The weighted triple products give the volume enclosed by the curved quadratic surface (an
    affine map of the void scales it exactly), and the row's coefficients are its derivative
    (central differences, in a shape whose mid-edges left their chords)."""
    mesh = hollow_box()
    inside = ws.InBox((0.01 - 1e-9,) * 3, (0.02 + 1e-9,) * 3)
    boundary = mesh.surface()
    tris = boundary[np.all(inside(mesh.nodes)[boundary], axis=1)][:, [0, 2, 1]]
    triples, weights = volume_terms(mesh, tris, "void")
    origin = np.full(3, 0.015)
    assert enclosed_volume(mesh.nodes, triples, weights, origin) == pytest.approx(1e-6, rel=1e-12)
    a = np.array([[1.1, 0.2, 0.0], [0.0, 0.9, 0.1], [0.05, 0.0, 1.2]])
    stretched = (mesh.nodes - origin) @ a.T + origin
    assert enclosed_volume(stretched, triples, weights, origin) == pytest.approx(1e-6 * np.linalg.det(a), rel=1e-12)
    rng = np.random.default_rng(3)
    curved = mesh.nodes + 1e-3 * rng.standard_normal(mesh.nodes.shape)
    x = curved - origin
    grad = np.zeros_like(x)
    for a_, b_, c_ in ((0, 1, 2), (1, 2, 0), (2, 0, 1)):
        np.add.at(grad, triples[:, a_], weights[:, None] * np.cross(x[triples[:, b_]], x[triples[:, c_]]))
    for node in np.unique(triples)[::7]:
        for axis in range(3):
            step = np.zeros_like(x)
            step[node, axis] = 1e-6
            fd = (enclosed_volume(curved + step, triples, weights, origin)
                  - enclosed_volume(curved - step, triples, weights, origin)) / 2e-6
            assert fd == pytest.approx(grad[node, axis], rel=1e-6, abs=1e-14)


def test_load_shares_follow_the_shape_functions_and_partial_faces_are_named():
    mesh = ws.box_grid((0.0, 0.0, 0.0), (0.02, 0.01, 0.01), (2, 1, 1)).quadratic_refined()
    tris = mesh.surface()
    share = area_shares(mesh, tris, "load")
    assert share.sum() == pytest.approx(2 * (0.02 * 0.01 * 2 + 0.01 * 0.01), rel=1e-12)
    assert np.abs(share[np.unique(mesh.quadratic[:, :4])]).max() < 1e-18
    with pytest.raises(ws.SceneError, match=r"cavity 'c': 3 triangle\(s\), e.g. nodes .* do not make whole 6-node"):
        volume_terms(mesh, tris[1:], "cavity 'c'")
    # a load's region that holds a face in part leaves that face out
    assert area_shares(mesh, tris[1:], "load").sum() < share.sum()


def test_a_pressurized_10_node_cavity_grows_with_its_pressure():
    """In the linear range the void's growth is proportional to its pressure."""
    growth = []
    for p in (50.0, 100.0):
        scene = ws.Scene("void", static=True, gravity=(0.0, 0.0, 0.0), steps=1)
        body = scene.add_body("box", hollow_box(), ws.Material(E, NU, 1000.0), element="quadratic")
        scene.fix(body, ws.OnPlane((0.0, 0.0, 0.0), (0.0, 0.0, 1.0), tol=1e-9))
        scene.add_cavity("void", body, region=ws.InBox((0.01 - 1e-9,) * 3, (0.02 + 1e-9,) * 3), mode="pressure",
                         value=p)
        growth.append(ws.Simulator(scene, device="cpu").step().actuator_delta["void"])
    assert growth[0] > 0.0
    assert growth[1] == pytest.approx(2 * growth[0], rel=1e-3)
