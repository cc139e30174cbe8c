"""Bad input gets a clear error naming the component and the value; nothing is lost."""

import math
import warnings

import numpy as np
import pytest

import warpsoft as ws

MESH = ws.box_grid((0, 0, 0), (0.04, 0.01, 0.01), (4, 1, 1))
MAT = ws.Material(1e5, 0.3, 1000.0)
CLAMP = ws.OnPlane((0, 0, 0), (1, 0, 0))


@pytest.mark.parametrize("kw,match", [
    ({"young_modulus": 0.0}, r"young_modulus must be > 0 Pa, got 0.0"),
    ({"young_modulus": -5.0}, r"young_modulus must be > 0 Pa, got -5.0"),
    ({"poisson_ratio": 0.5}, r"poisson_ratio must lie in \(-1, 0.5\), got 0.5"),
    ({"poisson_ratio": -1.2}, r"poisson_ratio .* got -1.2"),
    ({"young_modulus": math.nan}, r"young_modulus must be a finite number, got nan"),
    ({"density": math.inf}, r"density must be a finite number, got inf"),
])
def test_bad_material(kw, match):
    args = {"young_modulus": 1e5, "poisson_ratio": 0.3, "density": 1000.0} | kw
    with pytest.raises(ws.SceneError, match=match):
        ws.Material(**args)


def test_quasi_static_body_without_fixture_is_singular():
    scene = ws.Scene("free", static=True)
    scene.add_body("blob", MESH, MAT)
    with pytest.raises(ws.SceneError, match=r"quasi-static body 'blob' is free along xyz"):
        ws.Simulator(scene)
    scene.fix(scene.bodies[0], CLAMP, axes="x")
    with pytest.raises(ws.SceneError, match=r"'blob' is free along yz"):
        ws.Simulator(scene)


@pytest.mark.parametrize("held, free", [
    (ws.InBox((-1e-6, -1e-6, -1e-6), (1e-6, 1e-6, 1e-6)), 3),  # one corner node: rotations about it
    (ws.InBox((-1e-6, -1e-6, -1), (1e-6, 1e-6, 1)), 1),  # one edge: rotation about it
])
def test_quasi_static_body_held_at_a_node_or_an_edge_is_singular(held, free):
    """Held at one node (or along one line of nodes), a static body still turns freely about it:
    K is singular (v1 gave tips at 5.8e8 m with the direct solver, 1e27 m with CG)."""
    scene = ws.Scene("pinned", static=True)
    scene.fix(scene.add_body("beam", MESH, MAT), held)
    with pytest.raises(ws.SceneError, match=rf"body 'beam' is held at \d+ node\(s\): {free} rigid-body motion\(s\) "
                                            r"stay free"):
        ws.Simulator(scene)
    ok = ws.Scene("clamped", static=True)
    ok.fix(ok.add_body("beam", MESH, MAT), CLAMP)
    ws.Simulator(ok)  # a clamped face holds all six


def test_bad_scene_components_are_named():
    scene = ws.Scene("s", static=True)
    body = scene.add_body("beam", MESH, MAT)
    with pytest.raises(ws.SceneError, match=r"body 'beam': fixed region InBox.* selects no node"):
        scene.fix(body, ws.InBox((1, 1, 1), (2, 2, 2)))
    with pytest.raises(ws.SceneError, match=r"fix axes .* got 'xw'"):
        scene.fix(body, CLAMP, axes="xw")
    with pytest.raises(ws.SceneError, match=r"load 'push'.*no surface triangle"):
        scene.add_force(body, ws.InBox((1, 1, 1), (2, 2, 2)), (1, 0, 0), name="push")
    with pytest.raises(ws.SceneError, match=r"load 'nan': total force must be finite"):
        scene.add_force(body, CLAMP, (math.nan, 0, 0), name="nan")
    with pytest.raises(ws.SceneError, match=r"gravity must be finite"):
        ws.Scene("g", gravity=(0, 0, math.inf))
    with pytest.raises(ws.SceneError, match=r"dt must be > 0 s, got -0.1"):
        ws.Scene("g", dt=-0.1)
    with pytest.raises(ws.SceneError, match=r"a body named 'beam' exists already"):
        scene.add_body("beam", MESH, MAT)
    with pytest.raises(ws.SceneError, match=r"total_mass must be > 0 kg"):
        scene.add_body("b2", MESH, MAT, total_mass=0.0)
    scene.fix(body, CLAMP)
    scene.add_probe("far", (1.0, 0.0, 0.0))
    with pytest.raises(ws.SceneError, match=r"point 'far' at \[1.0, 0.0, 0.0\] m lies outside every element"):
        ws.Simulator(scene)


def test_time_dependent_load_returning_nan_is_named():
    scene = ws.Scene("s", static=True)
    body = scene.add_body("beam", MESH, MAT)
    scene.fix(body, CLAMP)
    scene.add_force(body, ws.OnPlane((0.04, 0, 0), (1, 0, 0)), lambda t: (0.0, math.nan, 0.0), name="bad")
    sim = ws.Simulator(scene)
    with pytest.raises(ws.SceneError, match=r"load 'bad': total\(0.01\) must return 3 finite numbers"):
        sim.step()


def test_a_cable_schedule_that_fails_is_named_and_a_numpy_number_is_taken():
    """Each step reads the actuators' own schedules at once: one that returns NaN, a word or
    raises is still named with its value and time, and the state before the step is kept; one
    that returns a NumPy number is read as that number."""
    def beam(schedule):
        scene = ws.Scene("s", dt=0.01)
        body = scene.add_body("beam", MESH, MAT)
        scene.fix(body, CLAMP)
        scene.add_cable("steady", body, points=[(0.02, 0.005, 0.009), (0.04, 0.005, 0.009)],
                        pull_point=(-0.01, 0.005, 0.009), value=lambda t: 1e-4 * t)
        scene.add_cable("c", body, points=[(0.02, 0.005, 0.001), (0.04, 0.005, 0.001)],
                        pull_point=(-0.01, 0.005, 0.001), value=schedule)
        return ws.Simulator(scene)

    cases = [(lambda t: math.nan if t > 0.015 else 0.0, r"cable 'c': value\(0.02\) must be finite, got nan"),
             (lambda t: "pull" if t > 0.015 else 0.0, r"cable 'c': value\(0.02\) must be a number, got 'pull'"),
             (lambda t: 0.0 if t < 0.015 else 1.0 / 0.0, r"cable 'c': its input schedule raised ZeroDivisionError")]
    for schedule, match in cases:
        sim = beam(schedule)
        sim.step()
        q = sim.state.positions().copy()
        with pytest.raises(ws.SceneError, match=match):
            sim.step()
        assert np.array_equal(sim.state.positions(), q) and sim.step_index == 1
    sim = beam(lambda t: np.float32(0.25) * t)
    sim.step()
    assert sim.values.tolist() == [1e-4 * 0.01, float(np.float32(0.25) * 0.01)]


def test_nan_never_leaves_a_step_and_state_is_kept():
    scene = ws.Scene("s", dt=0.01)
    body = scene.add_body("beam", MESH, MAT)
    scene.fix(body, CLAMP)
    sim = ws.Simulator(scene)
    before = sim.state.positions().copy()
    v = np.zeros((sim.model.num_nodes, 3))
    v[-1, 2] = np.nan
    sim.state.v.assign(v)
    with pytest.raises(ws.SimulationError, match=r"step 1 .*non-finite.*state before the step is kept"):
        sim.step()
    assert np.array_equal(sim.state.positions(), before)
    assert sim.step_index == 0


def test_cg_that_does_not_converge_is_reported():
    scene = ws.Scene("s", static=True)
    body = scene.add_body("beam", ws.box_grid((0, 0, 0), (0.1, 0.01, 0.01), (20, 2, 2)), MAT)
    scene.fix(body, CLAMP)
    scene.add_force(body, ws.OnPlane((0.1, 0, 0), (1, 0, 0)), (0, 0, -0.01))
    sim = ws.Simulator(scene, solver="jacobi", max_iterations=5)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        stats = sim.step()
    assert not stats.converged and stats.cg_iterations == 5
    assert stats.warnings and "CG (free solve) stopped after 5 iterations" in stats.warnings[0]
    assert any(issubclass(w.category, ws.ConvergenceWarning) for w in caught)
    assert "ill-conditioned" in stats.warnings[0] and "use solver='pcg'" in stats.warnings[0]  # what to do


def test_a_nearly_incompressible_body_that_stops_cg_is_named_as_such():
    """Poisson ratio 0.49: the warning says why CG stalls (incompressibility, locking) and what to
    do, not only that it stopped."""
    scene = ws.Scene("s", static=True)
    body = scene.add_body("beam", ws.box_grid((0, 0, 0), (0.1, 0.01, 0.01), (20, 2, 2)), ws.Material(1e5, 0.49))
    scene.fix(body, CLAMP)
    scene.add_force(body, ws.OnPlane((0.1, 0, 0), (1, 0, 0)), (0, 0, -0.01))
    with pytest.warns(ws.ConvergenceWarning, match=r"nearly incompressible \(Poisson ratio up to 0.49\).*lock.*"
                                                   r"use solver='pcg'"):
        ws.Simulator(scene, solver="jacobi", max_iterations=20).step()


def test_bad_simulator_options():
    scene = ws.Scene("s", static=True)
    scene.fix(scene.add_body("beam", MESH, MAT), CLAMP)
    with pytest.raises(ws.SceneError, match="solver must be one of auto, pcg, direct, jacobi, got 'lu'"):
        ws.Simulator(scene, solver="lu")
    with pytest.raises(ws.SceneError, match="tolerance must lie in"):
        ws.Simulator(scene, tolerance=0.0)


def test_a_finite_but_absurd_load_is_rejected_and_the_state_kept():
    """A load of -1e300 N at step 5: positions would be ~1e298 m (finite); the step is refused
    like a NaN one, the state of step 4 kept."""
    scene = ws.Scene("absurd", dt=0.01)
    body = scene.add_body("beam", MESH, MAT)
    scene.fix(body, CLAMP)
    scene.add_force(body, ws.OnPlane((0.04, 0, 0), (1, 0, 0)), lambda t: (0.0, 0.0, -1e300 if t > 0.045 else -0.01))
    sim = ws.Simulator(scene, solver="direct")
    for _ in range(4):
        sim.step()
    before = sim.positions()
    with pytest.raises(ws.SimulationError, match=r"step 5 .* more than 10 times the model's size"):
        sim.step()
    assert np.array_equal(sim.positions(), before) and np.abs(before).max() < 1.0


def test_a_shape_given_as_a_region_and_a_region_given_as_a_shape_say_which_is_which():
    """Regions say where nodes are (ws.InBox, ws.OnPlane, ...), shapes are solids (ws.shapes.Box,
    ws.Cylinder, ...): mixing them up was a TypeError ('object is not callable')."""
    scene = ws.Scene("s", static=True)
    body = scene.add_body("beam", MESH, MAT)
    with pytest.raises(ws.SceneError, match=r"fixed region must be a region .* got Cylinder: ws.Cylinder is a "
                                            r"solid shape for meshing"):
        scene.fix(body, ws.Cylinder((0, 0, 0), (0, 0, 0.01), 0.005))
    with pytest.raises(ws.SceneError, match=r"load 'push': region must be a region .* got str"):
        scene.add_force(body, "the tip", (0, 0, -1), name="push")
    with pytest.raises(ws.SceneError, match=r"expected a Shape, got InBox: ws.InBox is a region .* ws.shapes.Box"):
        ws.mesh_shape(ws.InBox((0, 0, 0), (1, 1, 1)), 0.1)
    with pytest.raises(ws.SceneError, match=r"got Box: ws.shapes.Box is a solid shape"):
        scene.fix(body, ws.shapes.Box((0, 0, 0), (0.01, 0.01, 0.01)))


def test_the_first_region_names_still_work_and_say_their_new_names():
    """ws.Box was a region while ws.shapes.Box is a solid, and ws.Sphere a region next to the
    solid ws.Ball: regions are now named by where the nodes are. The first names select the same
    nodes, with a DeprecationWarning naming the new one."""
    points = np.random.default_rng(0).uniform(-1.0, 1.0, (200, 3))
    pairs = [(lambda m: m.Box((-0.5, -0.5, -0.5), (0.5, 0.2, 0.5)), ws.InBox((-0.5, -0.5, -0.5), (0.5, 0.2, 0.5))),
             (lambda m: m.Plane((0, 0, 0.1), (0, 0, 1), tol=0.2), ws.OnPlane((0, 0, 0.1), (0, 0, 1), tol=0.2)),
             (lambda m: m.HalfSpace((0, 0, 0), (1, 1, 0)), ws.InHalfSpace((0, 0, 0), (1, 1, 0))),
             (lambda m: m.Sphere((0, 0.2, 0), 0.6), ws.InSphere((0, 0.2, 0), 0.6))]
    for old, new in pairs:
        with pytest.warns(DeprecationWarning, match=f"is now ws.{type(new).__name__}"):
            region = old(ws)
        assert isinstance(region, type(new)) and np.array_equal(region(points), new(points))
        assert 0 < new(points).sum() < len(points)


@pytest.mark.parametrize("at_once", [0, 32])
def test_ramp_inputs_are_evaluated_at_once_as_each_would_be_alone(monkeypatch, at_once):
    """A Ramp goes linearly from its initial input to its value over its duration and holds
    before and after; the step evaluates a batch's ramps in one array expression (from
    ``RAMPS_AT_ONCE`` of them; 0 here: always), to the bit what each gives called alone, beside
    numbers and other schedules. Bad numbers are named."""
    from warpsoft import inputs

    monkeypatch.setattr(inputs, "RAMPS_AT_ONCE", at_once)
    ramps = [ws.Ramp(0.004, 0.05), ws.Ramp(2.0, 0.0, start=0.1, initial=1.0), ws.Ramp(-3e-3, 1.5, 0.2, 5e-4)]
    assert ramps[0](0.0) == 0.0 and ramps[0](0.025) == pytest.approx(0.002) and ramps[0](1.0) == 0.004
    assert ramps[1](0.0999) == 1.0 and ramps[1](0.1) == 2.0  # duration 0: a step at its start
    assert ramps[2](0.0) == 5e-4 and ramps[2](0.95) == pytest.approx(0.5 * (5e-4 - 3e-3)) and ramps[2](9.0) == -3e-3
    table = np.array([r.row() for r in ramps])
    for t in (-1.0, 0.0, 0.01, 0.05, 0.1, 0.2, 0.73, 1.7, 3.0):
        assert ws.Ramp.at(table, t).tolist() == [r(t) for r in ramps]  # (== on floats: to the bit)
    for kw, match in [({"value": 1.0, "duration": -0.1}, r"Ramp: duration must be >= 0 s, got -0.1"),
                      ({"value": math.nan, "duration": 1.0}, r"Ramp: value must not be NaN"),
                      ({"value": 1.0, "duration": 1.0, "start": math.inf}, r"Ramp: start must be finite"),
                      ({"value": "far", "duration": 1.0}, r"Ramp: value must be a number, got 'far'")]:
        with pytest.raises(ws.SceneError, match=match):
            ws.Ramp(**kw)

    scene = ws.Scene("s", dt=0.01)
    body = scene.add_body("beam", MESH, MAT)
    scene.fix(body, CLAMP)
    for k, value in enumerate([ws.Ramp(2e-4, 0.025), 1e-4, lambda t: 3e-3 * t, ws.Ramp(1e-4, 0.0, start=0.02)]):
        z = 0.001 + 0.002 * k
        scene.add_cable(f"c{k}", body, points=[(0.02, 0.005, z), (0.04, 0.005, z)], pull_point=(-0.01, 0.005, z),
                        value=value)
    sim = ws.Simulator(scene)
    for _ in range(3):
        stats = sim.step()
        t = stats.time  # (the inputs are the step's end's)
        assert sim.values.tolist() == [ws.Ramp(2e-4, 0.025)(t), 1e-4, 3e-3 * t, 1e-4 if t >= 0.02 else 0.0]
        assert set(stats.actuator_delta) == {"c0", "c1", "c2", "c3"}
