"""10-node (quadratic) corotational tetrahedra: patch test, rigid motions, energy, the cantilever
against Timoshenko at silicone's Poisson ratio, and bodies of both elements in one model."""

import numpy as np
import pytest
import warp as wp

import warpsoft as ws
from warpsoft.scene.mesh import signed_volumes

E, NU = 1e6, 0.45


def quadratic_box(divisions=(2, 2, 2), size=(0.02, 0.01, 0.01), nu=NU, static=False, gravity=0.0):
    scene = ws.Scene("box", static=static, gravity=(0.0, 0.0, -gravity), steps=1)
    body = scene.add_body("box", ws.box_grid((0.0, 0.0, 0.0), size, divisions), ws.Material(E, nu, 1000.0),
                          element="quadratic")
    return scene, body


def forces_at(sim: ws.Simulator, q: np.ndarray) -> np.ndarray:
    state = sim.model.state()
    state.q.assign(wp.array(q, dtype=wp.vec3d, device=sim.model.device))
    return sim.internal_forces(state)


def energy_at(sim: ws.Simulator, q: np.ndarray) -> float:
    state = sim.model.state()
    state.q.assign(wp.array(q, dtype=wp.vec3d, device=sim.model.device))
    return sim.energy(state)["elastic"]


def test_the_refined_mesh_keeps_volume_and_puts_midpoints_on_edges():
    mesh = ws.box_grid((0.0, 0.0, 0.0), (1.0, 2.0, 3.0), (2, 1, 3))
    quad = mesh.quadratic_refined()
    assert quad.num_elements == 8 * mesh.num_elements
    assert quad.volume == pytest.approx(mesh.volume, rel=1e-12)
    e = quad.quadratic
    edges = [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)]
    for k, (i, j) in enumerate(edges):
        midpoint = 0.5 * (quad.nodes[e[:, i]] + quad.nodes[e[:, j]])
        np.testing.assert_allclose(quad.nodes[e[:, 4 + k]], midpoint, atol=1e-15)
    # each element's eight tetrahedra fill it
    parent = signed_volumes(mesh.nodes, mesh.tets)
    np.testing.assert_allclose(signed_volumes(quad.nodes, quad.tets).reshape(-1, 8).sum(axis=1), parent, rtol=1e-12)


def test_patch_test_a_uniform_strain_leaves_interior_nodes_free_of_force():
    """Every node placed on ``x = (I + eps) X``: the stress is uniform, so a node inside the box
    gets no net force, and the energy is ``V eps : C eps / 2`` (exact for any element that passes
    the patch test)."""
    scene, body = quadratic_box(divisions=(3, 2, 2))
    sim = ws.Simulator(scene)
    X = sim.model.rest_np
    eps = 1e-4 * np.array([[1.0, 0.3, -0.2], [0.3, -0.5, 0.4], [-0.2, 0.4, 0.7]])
    f = forces_at(sim, X + X @ eps.T)
    lo, hi = X.min(axis=0), X.max(axis=0)
    inside = np.all((X > lo + 1e-9) & (X < hi - 1e-9), axis=1)
    assert inside.sum() >= 10
    scale = np.abs(f).max()
    assert np.abs(f[inside]).max() < 1e-9 * scale
    mu, lam = E / (2 * (1 + NU)), E * NU / ((1 + NU) * (1 - 2 * NU))
    sigma = 2 * mu * eps + lam * np.trace(eps) * np.eye(3)
    volume = np.prod(hi - lo)
    assert energy_at(sim, X + X @ eps.T) == pytest.approx(0.5 * volume * np.sum(eps * sigma), rel=1e-9)
    # the boundary forces are the tractions sigma n: their total moment-free sum is zero
    np.testing.assert_allclose(f.sum(axis=0), 0.0, atol=1e-9 * scale)


def test_a_rigid_motion_makes_no_force_and_no_energy():
    scene, _ = quadratic_box()
    sim = ws.Simulator(scene)
    X = sim.model.rest_np
    Q = ws.rotation_about("x", 35.0) @ ws.rotation_about("z", -70.0)
    q = X @ Q.T + np.array([0.3, -0.1, 0.2])
    assert np.abs(forces_at(sim, q)).max() < 1e-8
    assert abs(energy_at(sim, q)) < 1e-14


def test_forces_are_minus_the_energy_gradient_to_first_order_in_the_strain():
    """The rotation is held fixed in the force (as for linear tetrahedra), but one rotation cannot
    follow a quadratic element's varying local rotation, so the force differs from the energy's
    gradient by a term of second order: relative to the force, it shrinks with the strain."""
    scene, _ = quadratic_box(divisions=(2, 1, 1))
    sim = ws.Simulator(scene)
    X = sim.model.rest_np
    rng = np.random.default_rng(3)
    direction = rng.standard_normal(X.shape)
    picks = [(int(n), a) for n in rng.choice(len(X), 6, replace=False) for a in range(3)]

    def mismatch(amplitude: float) -> float:
        q = X + amplitude * direction
        f = forces_at(sim, q)
        worst = 0.0
        for node, axis in picks:
            h = 1e-3 * amplitude
            qp, qm = q.copy(), q.copy()
            qp[node, axis] += h
            qm[node, axis] -= h
            grad = (energy_at(sim, qp) - energy_at(sim, qm)) / (2 * h)
            worst = max(worst, abs(-grad - f[node, axis]))
        return worst / np.abs(f).max()

    coarse, fine = mismatch(1e-5), mismatch(1e-6)
    assert fine < 2e-3
    assert fine < 0.2 * coarse


def cantilever_error(mesh_size: float, nu: float, solver: str = "direct") -> float:
    from warpsoft.io.runner import load_scene_module

    beam = load_scene_module("scenes/validation/cantilever.py")
    scene = beam.build(young_modulus=E, poisson_ratio=nu, tip_force=0.01, mesh_size=mesh_size, element="quadratic")
    sim = ws.Simulator(scene, solver=solver, tolerance=1e-10, newton_iterations=30)
    sim.step()
    deflection = -sim.probe_positions()["tip"][2]
    return deflection / beam.timoshenko_tip_deflection(poisson_ratio=nu, young_modulus=E, tip_force=0.01) - 1.0


def test_the_cantilever_at_nu_045_is_within_5_percent_of_timoshenko_and_converges():
    """Linear tetrahedra at the scene's default mesh (1.67 mm) are 15 % too stiff at nu 0.45;
    10-node ones at 5 mm come within 3 %. The 3D clamped beam converges to about 1.5-2 % below
    beam theory (its clamp also holds the Poisson contraction), so the error falls towards that."""
    errors = [abs(cantilever_error(h, 0.45)) for h in (0.01, 0.005, 0.0033)]
    assert errors[1] < 0.05
    assert errors[0] > errors[1] > errors[2]


def test_pcg_and_the_direct_solve_agree_on_quadratic_elements():
    assert cantilever_error(0.005, 0.45, "pcg") == pytest.approx(cantilever_error(0.005, 0.45, "direct"), abs=1e-6)


def test_linear_and_quadratic_bodies_in_one_model_step_as_each_alone():
    """Two hanging beams, one of each element, in one dynamic scene under gravity: each moves as
    in a scene of its own."""
    def beams(which):
        scene = ws.Scene("two", gravity=(0.0, 0.0, -9.81), dt=0.01, steps=5)
        for k, element in enumerate(("corotational", "quadratic")):
            if element not in which:
                continue
            mesh = ws.box_grid((0.0, 0.03 * k, 0.0), (0.05, 0.03 * k + 0.01, 0.01), (5, 1, 1))
            body = scene.add_body(element, mesh, ws.Material(1e5, 0.45, 1000.0), element=element)
            scene.fix(body, ws.OnPlane((0.0, 0.0, 0.0), (1.0, 0.0, 0.0), tol=1e-9))
            scene.add_probe(f"tip_{element}", (0.05, 0.03 * k + 0.005, 0.005))
        return scene

    converged = {"newton_tolerance": 1e-9, "newton_iterations": 50}  # each model's Newton stops where it must
    both = ws.Simulator(beams(("corotational", "quadratic")), **converged)
    alone = {e: ws.Simulator(beams((e,)), **converged) for e in ("corotational", "quadratic")}
    for _ in range(5):
        both.step()
        for sim in alone.values():
            sim.step()
    for element, sim in alone.items():
        name = f"tip_{element}"
        np.testing.assert_allclose(both.probe_positions()[name], sim.probe_positions()[name], atol=1e-10)
    # the quadratic beam, less stiff in bending, hangs lower
    assert both.probe_positions()["tip_quadratic"][2] < both.probe_positions()["tip_corotational"][2]


def test_mass_of_a_quadratic_body_is_its_density_times_volume():
    scene, _ = quadratic_box(static=False, gravity=9.81)
    model = ws.finalize(scene)
    assert model.mass_np.sum() == pytest.approx(1000.0 * 0.02 * 0.01 * 0.01, rel=1e-12)
    assert np.all(model.mass_np > 0)


def test_a_region_gives_its_material_to_whole_10_node_elements():
    """The eight tetrahedra of an element share its material, chosen by the element's centroid."""
    scene, body = quadratic_box(divisions=(4, 1, 1))
    body.set_material(ws.InBox((0.0, 0.0, 0.0), (0.01, 0.01, 0.01)), ws.Material(5e6, 0.45, 1000.0))
    mu = body.element_materials()[0].reshape(-1, 8)
    assert np.all(mu == mu[:, :1])  # whole elements
    soft, stiff = E / (2 * 1.45), 5e6 / (2 * 1.45)
    np.testing.assert_allclose(np.unique(mu), [soft, stiff])
    half = body.mesh.nodes[body.mesh.quadratic[:, :4]].mean(axis=1)[:, 0] < 0.01
    np.testing.assert_allclose(mu[half, 0], stiff)
    np.testing.assert_allclose(mu[~half, 0], soft)


def test_a_quadratic_mesh_needs_the_quadratic_element():
    quad = ws.box_grid((0.0, 0.0, 0.0), (1.0, 1.0, 1.0), (1, 1, 1)).quadratic_refined()
    with pytest.raises(ws.SceneError, match="element='quadratic'"):
        ws.Scene("s").add_body("b", quad, ws.Material(1e5, 0.3, 1000.0), element="corotational")
    with pytest.raises(ws.SceneError, match="element must be"):
        ws.Scene("s").add_body("b", quad, ws.Material(1e5, 0.3, 1000.0), element="hexahedral")
