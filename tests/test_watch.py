"""What a step watches for: a very soft finger says that it turns elements inside out and that
its cable misses the command; the default finger says nothing of the kind."""

import numpy as np


def run(scene_module, steps, **params):
    import warpsoft as ws

    sim = ws.Simulator(scene_module("scenes/finger.py").build(**params), solver="direct")
    return [sim.step() for _ in range(steps)]


def test_a_very_soft_finger_reports_inverted_elements_and_a_missed_command(scene_module):
    """E = 1 kPa under gravity (v1: 295 inverted elements and a cable 4.6 mm short of its
    command, chattering, with no warning)."""
    history = run(scene_module, 60, young_modulus=1e3, mesh_size=0.005)
    said = [m for s in history for m in s.warnings]
    assert max(s.inverted_elements for s in history) > 0
    assert any("turned inside out" in m for m in said)
    assert max(s.actuator_residual["cable"] for s in history) > 1e-3  # a millimetre or more short
    assert any("missing their command: cable" in m for m in said)


def test_the_default_finger_meets_its_command_and_stays_right_side_out(scene_module):
    history = run(scene_module, 60, mesh_size=0.005)
    assert all(s.inverted_elements == 0 for s in history)
    assert max(s.actuator_residual["cable"] for s in history) < 1e-5
    assert not any(s.warnings for s in history)
    assert np.isclose(history[-1].actuator_delta["cable"], 0.012 * min(1.0, history[-1].time / 0.5), rtol=1e-3)


def test_a_time_step_too_large_for_one_linearization_is_said(scene_module):
    """The finger at dt = 0.5 s (v1: a period-2 cycle, the cable meeting 8.4 mm of a 12-mm command,
    no warning): the rows end far from the step's linear prediction, and the cable misses its
    command; both are said. (Newton iterations within the step are not built yet.)"""
    history = run(scene_module, 12, dt=0.5, mesh_size=0.005)
    said = [m for s in history for m in s.warnings]
    assert max(s.linearization_error for s in history) > 1e-3
    assert any("linear prediction" in m for m in said) and any("missing their command" in m for m in said)
    calm = run(scene_module, 12, mesh_size=0.005)
    assert max(s.linearization_error for s in calm) < 1e-5
