"""Constraint rows and the direct model: compliance, bounds, analytic checks, Jacobian."""

import numpy as np
import pytest
import warp as wp

import warpsoft as ws
from warpsoft import step as step_module
from warpsoft.linear import SparseDirect

L, H = 0.1, 0.01
MAT = ws.Material(1e6, 0.3, 1000.0)


def beam(static=True, divisions=(20, 2, 2)):
    scene = ws.Scene("beam", static=static, dt=0.01)
    body = scene.add_body("beam", ws.box_grid((0, -H / 2, -H / 2), (L, H / 2, H / 2), divisions), MAT,
                          element="corotational")
    scene.fix(body, ws.OnPlane((0, 0, 0), (1, 0, 0)))
    return scene, body


def cable_beam(inputs=((0.002, "displacement"), (0.5, "force"), (0.001, "displacement")), **bounds):
    """A clamped beam with three cables along its top, side and bottom, and a tip effector."""
    scene, body = beam()
    offsets = [(0, 0.004), (0.004, 0), (0, -0.004)]
    for k, ((value, mode), (y, z)) in enumerate(zip(inputs, offsets, strict=True)):
        scene.add_cable(f"c{k}", body, points=[(x, y, z) for x in (0.03, 0.06, 0.095)], pull_point=(-0.01, y, z),
                        mode=mode, value=value, **bounds)
    scene.add_effector("tip", (L, 0, 0))
    return scene


def run(scene, steps, **kw):
    sim = ws.Simulator(scene, **kw)
    stats = None
    for _ in range(steps):
        stats = sim.step()
    return sim, stats


def test_compliance_is_symmetric_positive_definite():
    sim, _ = run(cable_beam(), 2, tolerance=1e-10)
    W = sim.last_W[:3]
    assert np.abs(W - W.T).max() < 1e-7 * np.abs(W).max()
    assert np.linalg.eigvalsh(0.5 * (W + W.T)).min() > 0


@pytest.mark.parametrize("static", [True, False])
def test_lambda_as_external_force_agrees_with_X_lambda(static):
    scene = cable_beam()
    scene.static = static
    sim, _ = run(scene, 1, solver="pcg", tolerance=1e-12, newton_iterations=1)  # one linearization, at rest
    cs = sim.rows
    rest = wp.clone(sim.model.rest)
    cs.evaluate(rest)  # H and A where the step linearized: the rest state (the simulator holds the next one)
    sim.elastic.linearize(rest, sim.rot, wp.zeros_like(sim.f_int))
    lam = np.zeros(cs.num_rows)
    lam[:3] = sim.lam
    direct = SparseDirect(sim.operator)
    direct.prepare()
    full = direct.solve_array(cs.forces(lam)[None])[0] * sim.constraint_scale
    via_columns = np.einsum("c,cnk->nk", sim.lam, sim.X.numpy()) * sim.constraint_scale
    assert np.abs(full).max() > 1e-6
    assert np.abs(full - via_columns).max() < 1e-8 * np.abs(full).max()


def test_compliance_from_the_factor_equals_the_solved_columns():
    """The CPU's direct solver gives ``W`` from its Cholesky factor (``Z^T Z``, ``Z = L^-1 P H^T``)
    and the correction by one solve of ``s H^T lambda``, never forming the columns ``X``: both
    equal what the columns give, on a world of cables and an effector beside a world where a
    soft bar presses on the floor with friction (contact rows on its nodes)."""
    contact = ws.Scene("press", gravity=(0, 0, -9.81), dt=0.01)
    bar = contact.add_body("bar", ws.box_grid((0, -H / 2, 0), (L, H / 2, H), (10, 2, 2)), MAT, element="corotational")
    contact.add_obstacle("floor", ws.obstacles.Floor(), mu=0.5)
    contact.add_force(bar, ws.InBox((-1, -1, H - 1e-6), (1, 1, 1)), (0.0, 0.0, -5.0))
    contact.add_cable("c", bar, points=[(x, 0, H / 2) for x in (0.03, 0.06, 0.095)], pull_point=(-0.01, 0, H / 2),
                      value=0.001)
    moving = cable_beam()
    moving.static, moving.steps = False, 10
    sim = ws.Simulator(ws.finalize([moving, contact], device="cpu"), solver="direct", lazy_contacts=False)
    for _ in range(3):
        sim.step()
    rows, s = sim.rows, sim.constraint_scale
    assert step_module.from_factor(sim) and rows.world_force_rows.numpy()[1] > 1 + 3  # contacts in use
    sim.solver.compliance(rows, s)
    from_factor = rows.W.numpy().copy()
    rows.actuator_columns(sim.columns)  # (not formed where W comes from the factor)
    x = wp.array(sim.solver.solve_array(sim.columns.numpy()), dtype=wp.vec3d, device="cpu")
    rows.compliance(x, s)  # H X from the solved columns
    assert np.abs(from_factor).max() > 0
    assert np.abs(from_factor - rows.W.numpy()).max() < 1e-12 * np.abs(from_factor).max()
    lam = sim.gauss_seidel.lam
    lam.assign(np.random.default_rng(1).uniform(-1.0, 1.0, lam.shape[0]))
    e = step_module.correction(sim, True).numpy().copy()  # dx_free + A^-1 (s H^T lambda)
    rows.correct(sim.dx_free[0], x, lam, s, sim.dx)
    assert np.abs(e - sim.dx.numpy()).max() < 1e-12 * np.abs(e).max()


def test_displacement_input_is_met_when_forces_stay_within_bounds():
    sim, stats = run(cable_beam(), 8, tolerance=1e-10)
    assert stats.actuator_delta["c0"] == pytest.approx(0.002, rel=1e-6)
    assert stats.actuator_delta["c2"] == pytest.approx(0.001, rel=1e-6)
    assert stats.actuator_lambda["c1"] == pytest.approx(0.5)  # force input kept
    assert all(v >= 0 for v in stats.actuator_lambda.values())


def test_force_bound_binds():
    scene = cable_beam(inputs=((0.004, "displacement"),) * 3, max_force=1.0)
    sim, stats = run(scene, 8, tolerance=1e-10)
    lam = stats.actuator_lambda
    assert max(lam.values()) == pytest.approx(1.0)  # the bound holds ...
    bound = [k for k, v in lam.items() if v == pytest.approx(1.0)]
    assert all(stats.actuator_delta[k] < 0.004 - 1e-5 for k in bound)  # ... and the input is not met there


def test_displacement_bounds_and_step_limit_bind():
    scene = cable_beam(inputs=((5.0, "force"), (0.01, "displacement"), (0.0, "displacement")),
                       max_displacement=0.003, max_step=0.001)
    sim = ws.Simulator(scene, tolerance=1e-10)
    previous = np.zeros(3)
    for _ in range(8):
        stats = sim.step()
        delta = np.array([stats.actuator_delta[k] for k in ("c0", "c1", "c2")])
        assert np.all(np.abs(delta - previous) <= 0.001 + 1e-6)  # at most 1 mm per step
        assert np.all(delta <= 0.003 + 1e-6)
        previous = delta
    assert delta[1] == pytest.approx(0.003, rel=1e-4)  # displacement input clipped at its bound
    assert delta[0] == pytest.approx(0.003, rel=1e-4)  # 5 N would pull further: the bound stops it


def test_pushed_cable_stays_slack():
    scene, body = beam()
    scene.add_force(body, ws.OnPlane((L, 0, 0), (1, 0, 0)), (-0.5, 0, 0))  # the tip moves toward the pull point
    scene.add_cable("cable", body, points=[(L, 0, 0)], pull_point=(-0.02, 0, 0), value=0.0)
    sim, stats = run(scene, 3, tolerance=1e-10)
    assert stats.actuator_lambda["cable"] == 0.0  # it cannot push back
    assert stats.actuator_delta["cable"] > 1e-5  # it went slack: shorter than its rest length
    assert sim.probe_positions() == {}


def test_cable_bar_matches_axial_theory(scene_module):
    sim, _ = run(scene_module("scenes/validation/cable_bar.py").build(cable_force=0.2), 3)
    mid = sim.probe_positions()["mid"][0] - 0.05
    assert mid == pytest.approx(-0.2 * 0.05 / (1e6 * 1e-4), rel=0.02)


def test_cable_bar_buckles_above_its_critical_tension(scene_module):
    """Below the Rayleigh-Ritz buckling tension (0.68 N) the bar stays straight; above it the
    straight bar is an unstable equilibrium and the step's Newton iterations leave it within a few
    steps (one linearization per step, as v1, drifts off it only slowly: 0.1 mm in six steps)."""
    bar = scene_module("scenes/validation/cable_bar.py")
    critical = bar.buckling_tension()
    assert critical == pytest.approx(0.68, abs=0.01)

    def sideways(tension, **kw):
        sim, _ = run(bar.build(cable_force=tension), 6, **kw)
        return float(np.linalg.norm(sim.probe_positions()["end"][1:]))

    assert sideways(0.5 * critical) < 2e-5  # the mesh is not quite symmetric: micrometres
    assert sideways(1.5 * critical) > 5e-3  # buckled: the end moved millimetres sideways
    assert sideways(1.5 * critical, newton_iterations=1) < 1e-3


def test_pressure_sphere_matches_lame_and_converges(scene_module):
    sphere = scene_module("scenes/validation/pressure_sphere.py")
    errors = []
    for h in (0.0025, None):  # None: the default, (b - a) / 6
        sim, stats = run(sphere.build(mesh_size=h), 3, solver="direct")
        errors.append(abs(stats.actuator_delta["cavity"] / sphere.lame_volume_growth() - 1.0))
    assert errors[1] < errors[0] and errors[1] < 0.06


def test_kinematic_jacobian_matches_finite_differences():
    inputs = ((0.002, "displacement"), (0.0018, "displacement"), (0.001, "displacement"))
    sim, stats = run(cable_beam(inputs), 10, tolerance=1e-11)
    assert min(stats.actuator_lambda.values()) > 0.05  # every cable taut: all displacement-controlled
    J = sim.kinematic_jacobian()
    eps = 1e-5
    for i in range(3):
        shifted = [(v + (eps if k == i else 0.0), m) for k, (v, m) in enumerate(inputs)]
        sim2, _ = run(cable_beam(tuple(shifted)), 10, tolerance=1e-11)
        fd = (sim2.constraint_geometry()["effectors"]["tip"] - sim.constraint_geometry()["effectors"]["tip"]) / eps
        assert np.abs(fd - J[:, i]).max() < 0.02 * np.abs(J).max()


def test_cavity_row_is_the_volume_gradient(scene_module):
    sim = ws.Simulator(scene_module("scenes/validation/pressure_sphere.py").build(mesh_size=0.004))
    cs, rng = sim.rows, np.random.default_rng(1)
    q0 = sim.model.rest_np + 2e-4 * rng.standard_normal(sim.model.rest_np.shape)
    direction = rng.standard_normal(q0.shape)

    def volume(q):
        cs.evaluate(wp.array(q, dtype=wp.vec3d))
        return cs.delta.numpy()[0]

    eps = 1e-7
    fd = (volume(q0 + eps * direction) - volume(q0 - eps * direction)) / (2 * eps)
    volume(q0)
    grad = cs.forces(np.array([1.0]))  # H^T e_cavity
    assert np.sum(grad * direction) == pytest.approx(fd, rel=1e-7)


def test_coincident_cable_points_make_no_nan():
    scene, body = beam()
    scene.add_cable("c", body, points=[(0.0, 0, 0.004), (0.05, 0, 0.004), (0.05, 0, 0.004), (0.09, 0, 0.004)],
                    pull_point=(0.0, 0, 0.004), value=0.002)  # zero-length first and third segments
    sim, stats = run(scene, 3)
    assert np.all(np.isfinite(sim.state.positions()))
    assert stats.actuator_delta["c"] == pytest.approx(0.002, rel=1e-3)


def test_a_pull_point_on_a_moving_part_is_an_error():
    """A cable pulled from a point inside the moving beam, or from its own first path point where
    that point moves, would turn or reverse its command: clear errors. On the clamped face the
    same coincident pull point is still fine (the v1 case just above)."""
    scene, body = beam()
    scene.add_cable("inside", body, points=[(0.08, 0, 0.004)], pull_point=(0.04, 0, 0.004))
    with pytest.raises(ws.SceneError, match=r"cable 'inside': its pull point .* lies inside body 'beam' where the "
                                            r"body moves"):
        ws.Simulator(scene)
    scene, body = beam()
    on_top = (0.05, 0, H / 2 + 1e-4)  # just above the top face: mapped by extrapolation, and moving
    scene.add_cable("own", body, points=[on_top, (0.09, 0, 0.004)], pull_point=on_top)
    with pytest.raises(ws.SceneError, match=r"cable 'own': its pull point is its first path point .* which moves"):
        ws.Simulator(scene)


def test_bad_rows_are_named():
    scene, body = beam()
    with pytest.raises(ws.SceneError, match=r"cable 'c': min_force must be >= 0 N"):
        scene.add_cable("c", body, points=[(0.05, 0, 0)], pull_point=(0, 0, 0), min_force=-1.0)
    with pytest.raises(ws.SceneError, match=r"cable 'c': mode must be"):
        scene.add_cable("c", body, points=[(0.05, 0, 0)], pull_point=(0, 0, 0), mode="speed")
    scene.add_cable("far", body, points=[(0.05, 0, 0), (0.5, 0, 0)], pull_point=(0, 0, 0))
    with pytest.raises(ws.SceneError, match=r"point 'cable 'far' point 1' at \[0.5, 0.0, 0.0\] m lies outside"):
        ws.Simulator(scene)
    scene2, body2 = beam()
    with pytest.raises(ws.SceneError, match=r"effector 'e': target at t = 0 s must be 3 finite numbers"):
        scene2.add_effector("e", (L, 0, 0), target=(0.0, float("nan"), 0.0))


def test_open_or_misoriented_cavity_is_a_clear_error(scene_module):
    sphere = scene_module("scenes/validation/pressure_sphere.py")
    scene = sphere.build(mesh_size=0.004)
    shell = scene.bodies[0]
    region = ws.InSphere((0, 0, 0), 0.01, tol=1e-8)
    with pytest.raises(ws.SceneError, match=r"cavity 'open': the surface is open"):
        scene.add_cavity("open", shell, region=region)  # no symmetry planes given: open along them
    tris = scene.cavities[0].surface()
    with pytest.raises(ws.SceneError, match=r"cavity 'flipped': the surface is mis-oriented"):
        scene.add_cavity("flipped", shell, triangles=tris[:, [0, 2, 1]],
                         symmetry_planes=scene.cavities[0].symmetry_planes)
    mixed = tris.copy()
    mixed[0] = mixed[0, [0, 2, 1]]
    with pytest.raises(ws.SceneError, match=r"mis-oriented: edge"):
        scene.add_cavity("mixed", shell, triangles=mixed, symmetry_planes=scene.cavities[0].symmetry_planes)


def anchored_bar_shortening(divisions: int, anchor_radius: float) -> float:
    """A 10 cm bar (1 cm square, E 100 kPa) clamped at x = 0, a cable through it from behind the
    clamp fastened 1 cm before its end, pulled at 0.01 N: the cable's shortening over
    ``T L / (E A)`` of the 9 cm between clamp and fastening."""
    scene = ws.Scene("bar", static=True, gravity=(0.0, 0.0, 0.0), steps=1)
    body = scene.add_body("bar", ws.box_grid((0, 0, 0), (0.1, 0.01, 0.01), (10 * divisions, divisions, divisions)),
                          ws.Material(1e5, 0.3, 1000.0), element="corotational")
    scene.fix(body, ws.OnPlane((0, 0, 0), (1, 0, 0), tol=1e-9))
    scene.add_cable("c", body, points=[(0.09, 0.005, 0.005)], pull_point=(-0.01, 0.005, 0.005), mode="force",
                    value=0.01, anchor_radius=anchor_radius)
    sim = ws.Simulator(scene, device="cpu", solver="direct")
    for _ in range(2):
        stats = sim.step()
    return stats.actuator_delta["c"] / (0.01 * 0.09 / (1e5 * 1e-4))


def test_a_cable_fastened_over_an_anchor_converges_under_refinement_where_a_point_does_not():
    """Fastened at one point, the pull is a point load in a solid: the fastening moves further
    with every refinement (0.99, 1.05, 1.14 of ``T L / (E A)`` at 1, 2, 4 elements across; 1.35
    at 8). Spread over the material within 3 mm (a knot, a washer), its mean motion converges
    (0.974, 0.993, 1.001; 1.009 at 8, 1.012 at 12)."""
    point = [anchored_bar_shortening(d, 0.0) for d in (1, 2, 4)]
    anchor = [anchored_bar_shortening(d, 0.003) for d in (1, 2, 4)]
    assert point[2] - point[1] > 1.5 * (point[1] - point[0]) > 0.0
    assert 0.0 < anchor[2] - anchor[1] < 0.6 * (anchor[1] - anchor[0])
    assert all(0.95 < a < 1.05 for a in anchor)


def test_bad_anchors_are_named():
    scene = ws.Scene("bar", static=True, steps=1)
    body = scene.add_body("bar", ws.box_grid((0, 0, 0), (0.1, 0.01, 0.01), (10, 1, 1)), ws.Material(1e5, 0.3, 1000.0),
                          element="corotational")
    for bad in (-1e-3, float("nan"), "wide"):
        with pytest.raises(ws.SceneError, match=r"cable 'c': anchor_radius must be a finite length >= 0 m"):
            scene.add_cable("c", body, points=[(0.09, 0.005, 0.005)], pull_point=(-0.01, 0.005, 0.005),
                            anchor_radius=bad)


def test_an_anchored_cable_row_is_its_shortening_gradient():
    """Through two points, the last fastened over 3 mm: ``H`` is ``d delta / dq`` (central
    differences along a random direction), at rest and bent."""
    scene = ws.Scene("bar", static=True, gravity=(0.0, 0.0, 0.0), steps=1)
    body = scene.add_body("bar", ws.box_grid((0, 0, 0), (0.1, 0.01, 0.01), (20, 2, 2)), ws.Material(1e5, 0.3, 1000.0),
                          element="corotational")
    scene.fix(body, ws.OnPlane((0, 0, 0), (1, 0, 0), tol=1e-9))
    scene.add_cable("c", body, points=[(0.05, 0.002, 0.008), (0.09, 0.005, 0.005)], pull_point=(-0.01, 0.002, 0.008),
                    anchor_radius=0.003)
    sim = ws.Simulator(scene, device="cpu")
    cs, rng = sim.rows, np.random.default_rng(4)
    rest = sim.model.rest_np
    for q0 in (rest, rest + 2e-3 * np.array([0.0, 0.0, 1.0]) * (rest[:, :1] / 0.1) ** 2):
        q0 = q0 + 1e-5 * rng.standard_normal(q0.shape)
        direction = rng.standard_normal(q0.shape)

        def delta(q):
            cs.evaluate(wp.array(q, dtype=wp.vec3d))
            return cs.delta.numpy()[0]

        fd = (delta(q0 + 1e-7 * direction) - delta(q0 - 1e-7 * direction)) / 2e-7
        delta(q0)
        assert np.sum(cs.forces(np.array([1.0])) * direction) == pytest.approx(fd, rel=1e-6)


def test_many_bodies_checked_side_by_side_name_the_first_bad_cable_in_order(monkeypatch):
    """Rows of many worlds locate their points and check their cables in threads: the same weights
    as one by one, and of two worlds whose pull point lies inside the moving body (the 4th and the
    9th of 10), the first is the error raised, named, as in the loop."""
    from warpsoft import processes
    from warpsoft.rows import Rows

    def scene(inside: bool, name: str = "c") -> ws.Scene:
        s, body = beam()
        s.add_cable(name, body, points=[(x, 0.0, 0.004) for x in (0.03, 0.06, 0.095)],
                    pull_point=(0.02, 0.0, 0.004) if inside else (-0.01, 0.0, 0.004))
        return s

    monkeypatch.setattr(processes, "usable_cores", lambda: 4)
    model = ws.Model([scene(False) for _ in range(10)], "cpu")
    threaded = Rows(model)
    monkeypatch.setattr(processes, "THREADED_FROM", 10**9)
    alone = Rows(model)
    assert np.array_equal(threaded.point_weights.numpy(), alone.point_weights.numpy())
    assert np.array_equal(threaded.point_nodes.numpy(), alone.point_nodes.numpy())
    monkeypatch.setattr(processes, "THREADED_FROM", 2)
    with pytest.raises(ws.SceneError, match="cable 'c3': its pull point .* lies inside body"):
        Rows(ws.Model([scene(k in (3, 8), f"c{k}") for k in range(10)], "cpu"))
