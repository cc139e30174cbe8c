"""Kinematic frames: fixed regions and cable pull points carried by a motion (warpsoft/drive.py)."""

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import warpsoft as ws
from warpsoft.errors import SceneError


def bar_scene(motion, static=True):
    scene = ws.Scene("bar", static=static, dt=0.01)
    bar = scene.add_body("bar", ws.mesh_shape(ws.shapes.Box((0, 0, 0), (0.05, 0.01, 0.01)), 0.005),
                         ws.Material(1e5, 0.3, 1000.0), element="corotational")
    scene.fix(bar, ws.InBox((-1, -1, -1), (0.001, 1, 1)), motion=motion)
    return scene


def turn(t):
    return Rotation.from_rotvec([0.2 * t, 0.0, 0.5 * np.pi * t]).as_matrix(), np.array([0.01 * t, 0.0, 0.02 * t])


def test_a_body_carried_by_its_base_moves_rigidly():
    """Corotational elasticity has no energy in a rigid motion: a quasi-static bar whose clamped
    end is turned and shifted by its frame follows it exactly (to the solver's tolerance), the
    free end included."""
    sim = ws.Simulator(bar_scene(turn), device="cpu", newton_tolerance=1e-4)
    for _ in range(10):
        sim.step()
    rotation, translation = turn(sim.time)
    expected = sim.model.rest_np @ rotation.T + translation
    assert np.abs(sim.state.positions() - expected).max() < 1e-8
    assert np.abs(translation).max() > 1e-3  # it did move


def finger(module, pull_motion, lift):
    scene = module.build(gravity=0.0, mesh_size=0.006, cable_displacement=0.004, ramp_time=0.01)
    scene.static = True
    scene.fixtures[0].motion = lift
    scene.cables[0].pull_motion = pull_motion
    return scene


def test_a_finger_on_a_moving_palm_bends_as_on_a_fixed_one(scene_module):
    """Translation invariance: a quasi-static finger whose base and cable motor ride the same
    frame takes the shape it takes at rest, shifted by the frame; left behind, the fixed pull
    point pulls the cable's first segment at another angle: another shape."""
    def lift(t):
        return np.array([0.0, 0.005 * t, 0.03 * t])

    module = scene_module("scenes/finger.py")
    fixed = ws.Simulator(finger(module, None, None), device="cpu", newton_tolerance=1e-8)
    riding = ws.Simulator(finger(module, lift, lift), device="cpu", newton_tolerance=1e-8)
    behind = ws.Simulator(finger(module, None, lift), device="cpu")
    for _ in range(3):
        fixed.step()
        stats = riding.step()
        behind.step()
    shift = lift(riding.time)
    assert np.abs(riding.state.positions() - fixed.state.positions() - shift).max() < 1e-8
    assert np.abs(behind.state.positions() - fixed.state.positions() - shift).max() > 1e-5
    assert stats.worlds[0].actuator_delta["cable"] == pytest.approx(0.004, abs=1e-9)  # it holds its command
    path = riding.rows.cable_paths()["cable"]
    assert np.allclose(path[0], finger(module, None, None).cables[0].pull_point + shift)  # drawn where it is


def test_bad_motions_are_named():
    with pytest.raises(SceneError, match="fixed region motion must be a function"):
        bar_scene(3.0)
    with pytest.raises(SceneError, match=r"fixed region motion at t = 0 s: the translation must be 3 finite"):
        bar_scene(lambda t: [1.0, 2.0])
    scene = bar_scene(lambda t: [0.0, 0.0, 1e-4 * math.sqrt(0.045 - t)], static=False)
    sim = ws.Simulator(scene, device="cpu")
    with pytest.raises(SceneError, match=r"fixed region .*: motion failed at t = 0.05 s: ValueError"):
        for _ in range(6):
            sim.step()
    scene = bar_scene(lambda t: np.zeros(3))
    scene.fix(scene.bodies[0], ws.InBox((-1, -1, -1), (0.002, 1, 1)), motion=lambda t: np.ones(3) * t)
    with pytest.raises(SceneError, match="is also carried by"):
        ws.Simulator(scene, device="cpu")


def test_the_trunk_keeps_its_tip_on_target_while_its_base_slides(scene_module):
    """The Trunk's base and motors slide 10 mm along its axis and back: its clamped nodes follow the frame
    exactly, and the inverse model keeps the tip within 0.1 mm of a fixed target."""
    trunk = scene_module("scenes/trunk.py")
    scene = trunk.build(base_travel=0.01, base_period=1.0, target=(0.19, 0.02, 0.0), static=True)
    sim = ws.Simulator(scene, device="cpu")
    for _ in range(20):
        stats = sim.step()
    driven = sim.driven
    assert np.abs(sim.state.positions()[driven.ids.numpy()] - driven.host).max() < 1e-12
    assert np.abs(driven.host - driven.rest)[:, 0].max() > 0.005  # it slid (10 mm at t = 0.25 s, 5.9 now)
    assert stats.worlds[0].effector_error["tip"] < 1e-4
