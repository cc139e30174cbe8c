"""Corotational tetrahedra: patch test, rigid motions, axial bar, inversion, CG vs direct."""

import numpy as np
import pytest
import warp as wp
from warpsoft.kernels.elastic.geometry import polar_rotation

import warpsoft as ws
from warpsoft.scene.mesh import signed_volumes

L, W, H = 0.04, 0.01, 0.01
RUBBER = ws.Material(1e5, 0.3, 1000.0)


def static_block(divisions=(4, 2, 2), material=RUBBER):
    scene = ws.Scene("block", static=True)
    body = scene.add_body("block", ws.box_grid((0, 0, 0), (L, W, H), divisions), material, element="corotational")
    return scene, body


def test_patch_test_reproduces_uniform_strain():
    """Boundary nodes placed by a linear field: the interior follows it exactly."""
    scene, body = static_block((4, 3, 3))
    d = np.array([L / 4, W / 3, H / 3]) / 2
    scene.fix(body, ~ws.InBox(d, np.array([L, W, H]) - d))
    sim = ws.Simulator(scene, tolerance=1e-12)
    X = sim.model.rest_np
    G = np.array([[2e-3, 5e-4, -1e-3], [3e-4, -1e-3, 2e-4], [-4e-4, 1e-4, 1.5e-3]])  # strain and small rotation
    target = X + X @ G.T
    q0 = np.where((sim.model.mask_np == 0), target, X)
    sim.state.q.assign(q0)
    for _ in range(4):
        sim.step()
    assert np.abs(sim.state.positions() - target).max() < 1e-10 * L


@pytest.mark.parametrize("angle", [5.0, 90.0, 180.0])
def test_rigid_motion_makes_no_internal_force(angle):
    scene, body = static_block()
    scene.fix(body, ws.OnPlane((0, 0, 0), (1, 0, 0)))
    sim = ws.Simulator(scene)
    X = sim.model.rest_np
    R = ws.rotation_about("z", angle) @ ws.rotation_about("x", 0.7 * angle)
    sim.state.q.assign(X @ R.T + np.array([0.3, -0.2, 0.1]))
    f_rigid = np.abs(sim.internal_forces()).max()
    sim.state.q.assign(X * np.array([1.01, 1.0, 1.0]))  # 1 % stretch for scale
    f_stretch = np.abs(sim.internal_forces()).max()
    assert f_rigid < 1e-10 * f_stretch


def test_axial_bar_matches_FL_over_EA_and_poisson_contraction():
    force = 0.5  # N
    scene, body = static_block((8, 2, 2))
    scene.fix(body, ws.OnPlane((0, 0, 0), (1, 0, 0)), axes="x")  # symmetry rollers: pure uniaxial stress
    scene.fix(body, ws.OnPlane((0, 0, 0), (0, 1, 0)), axes="y")
    scene.fix(body, ws.OnPlane((0, 0, 0), (0, 0, 1)), axes="z")
    scene.add_force(body, ws.OnPlane((L, 0, 0), (1, 0, 0)), (force, 0, 0))
    scene.add_probe("end", (L, W / 2, H / 2))
    scene.add_probe("corner", (L, W, H))
    sim = ws.Simulator(scene, tolerance=1e-12)
    for _ in range(3):
        sim.step()
    p = sim.probe_positions()
    strain = force / (RUBBER.young_modulus * W * H)
    assert p["end"][0] - L == pytest.approx(strain * L, rel=1e-3)
    assert p["corner"][1] - W == pytest.approx(-RUBBER.poisson_ratio * strain * W, rel=1e-2)


def test_inverted_elements_recover():
    scene, body = static_block((4, 2, 2))
    scene.fix(body, ws.OnPlane((0, 0, 0), (0, 0, 1)))
    sim = ws.Simulator(scene, tolerance=1e-10)
    X = sim.model.rest_np
    q = X.copy()
    top = np.flatnonzero(np.isclose(X[:, 2], H) & np.isclose(X[:, 0], L / 2) & np.isclose(X[:, 1], W / 2))
    q[top, 2] = -0.8 * H  # pushed through the block's bottom plane
    assert np.any(signed_volumes(q, sim.model.tets_np) < 0)
    sim.state.q.assign(q)
    for _ in range(60):
        sim.step()
    assert np.all(signed_volumes(sim.state.positions(), sim.model.tets_np) > 0)
    assert np.abs(sim.state.positions() - X).max() < 1e-6 * H


def test_cg_agrees_with_direct_solve():
    results = []
    for solver in ("direct", "pcg", "jacobi"):
        scene = ws.Scene("sag", gravity=(0, 0, -9.81), dt=0.02)
        body = scene.add_body("beam", ws.box_grid((0, 0, 0), (0.08, W, H), (16, 2, 2)), RUBBER, element="corotational")
        scene.fix(body, ws.OnPlane((0, 0, 0), (1, 0, 0)))
        scene.set_damping(0.1, 0.01)
        sim = ws.Simulator(scene, solver=solver, tolerance=1e-12)
        for _ in range(3):
            sim.step()
        results.append(sim.state.positions() - sim.model.rest_np)
    assert np.abs(results[0]).max() > 1e-4
    for other in results[1:]:
        assert np.abs(other - results[0]).max() < 1e-8 * np.abs(results[0]).max()


def test_residual_checks_every_k_iterations_give_the_same_solution():
    positions = []
    for k in (1, 7):
        scene = ws.Scene("sag", gravity=(0, 0, -9.81), dt=0.02)
        body = scene.add_body("beam", ws.box_grid((0, 0, 0), (0.08, W, H), (16, 2, 2)), RUBBER, element="corotational")
        scene.fix(body, ws.OnPlane((0, 0, 0), (1, 0, 0)))
        sim = ws.Simulator(scene, solver="jacobi", tolerance=1e-10, check_every=k)
        stats = sim.step()
        assert stats.converged and stats.cg_iterations > 0 and stats.cg_iterations % k == 0
        positions.append(sim.state.positions())
    assert np.abs(positions[0] - positions[1]).max() < 1e-8 * np.abs(positions[0] - positions[0][0]).max()


def test_stiffness_contrast_of_1e4_between_parts():
    """A stiff half (1e4 times the modulus) and a soft half: CG still converges and agrees with
    the direct solve, and the stiff half barely deforms."""
    tips = []
    for solver in ("direct", "pcg", "jacobi"):
        scene = ws.Scene("contrast", static=True)
        body = scene.add_body("beam", ws.box_grid((0, 0, 0), (0.08, W, H), (16, 2, 2)), RUBBER, element="corotational")
        body.set_material(ws.InBox((0.0, -1, -1), (0.04, 1, 1)), ws.Material(1e4 * RUBBER.young_modulus, 0.3, 1000.0))
        scene.fix(body, ws.OnPlane((0, 0, 0), (1, 0, 0)))
        scene.add_force(body, ws.OnPlane((0.08, 0, 0), (1, 0, 0)), (0, 0, -1e-3))
        scene.add_probe("joint", (0.04, W / 2, H / 2))
        scene.add_probe("tip", (0.08, W / 2, H / 2))
        sim = ws.Simulator(scene, solver=solver, tolerance=1e-10, max_iterations=20000)
        stats = sim.step()
        assert stats.converged and not stats.warnings
        p = sim.probe_positions()
        tips.append(p["tip"][2] - H / 2)
        assert abs(p["joint"][2] - H / 2) < 1e-3 * abs(tips[-1])  # the stiff half hardly bends
    assert tips[1] == pytest.approx(tips[0], rel=1e-6)
    assert tips[2] == pytest.approx(tips[0], rel=1e-6)


@wp.kernel
def _polar(F: wp.array(dtype=wp.mat33d), R: wp.array(dtype=wp.mat33d)):
    i = wp.tid()
    R[i] = polar_rotation(F[i])


def test_polar_rotation_is_the_svd_rotation_for_every_deformation():
    """The element rotation (Newton's iteration where ``det F > 0``, the SVD elsewhere) is the
    rotation of ``F = U S V^T``: ``U V^T``, with the smallest singular direction flipped when
    ``det F < 0``, for mild and large deformations, inverted ones and elements squashed flat."""
    rng = np.random.default_rng(3)

    def rotation() -> np.ndarray:
        q, r = np.linalg.qr(rng.normal(size=(3, 3)))
        q = q * np.sign(np.diag(r))
        return q * np.linalg.det(q)

    mild = [rotation() @ (np.eye(3) + 0.05 * rng.normal(size=(3, 3))) for _ in range(300)]
    large = [rotation() @ (np.eye(3) + 1.5 * rng.normal(size=(3, 3))) for _ in range(300)]
    flat = [rotation() @ np.diag([1.0, 0.5, 10.0 ** -k]) @ rotation() for k in np.linspace(1, 10, 100)]
    F = np.array(mild + large + flat)
    R = wp.zeros(len(F), dtype=wp.mat33d, device="cpu")
    wp.launch(_polar, len(F), inputs=[wp.array(F, dtype=wp.mat33d, device="cpu")], outputs=[R], device="cpu")
    U, _, Vt = np.linalg.svd(F)
    U[np.linalg.det(U @ Vt) < 0, :, 2] *= -1
    expected = U @ Vt
    assert (np.linalg.det(F) < 0).sum() > 50  # inverted ones are in
    assert np.abs(R.numpy() - expected).max() < 1e-9
    assert np.abs(R.numpy()[:600] - expected[:600]).max() < 1e-12
