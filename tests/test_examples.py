"""The sweep examples of ``examples/``: the Finger's curl against where its cable runs, the
Diamond's workspace against its modulus; checked against beam theory and an exact scaling."""

from pathlib import Path

import pytest

from warpsoft.io.sweep import sweep

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"


def test_finger_curl_per_millimetre_changes_sign_across_the_neutral_axis():
    """theta / delta = e / (e^2 + I / A) for a cable at e from the neutral axis (about 8 mm up):
    the curl per mm of cable turns from down to up as the cable goes from below the axis to
    above it, and is small near it, where the cable mostly squeezes the finger and its tension
    is the largest."""
    heights = [0.004, 0.008, 0.013]
    results = sweep(EXAMPLES / "finger_curl.py", [{"cable_height": h} for h in heights], workers=1)
    m = [r.metrics for r in results]
    assert all(r.status == "completed" for r in results)
    assert m[0]["curl_per_mm"] < -3.0 and m[2]["curl_per_mm"] > 3.0  # deg per mm of cable
    assert abs(m[1]["curl_per_mm"]) < 1.0
    assert m[1]["tension"] > 1.2 * max(m[0]["tension"], m[2]["tension"])
    assert all(r["cable_mm"] == pytest.approx(4.0, rel=0.02) for r in m)  # the stroke asked for


def test_diamond_workspace_is_the_geometry_s_and_tension_follows_the_modulus():
    """Without gravity, with the cables' displacements imposed, a Diamond twice as stiff goes
    through the same positions (the workspace to round-off) with twice the cable tension."""
    designs = [{"young_modulus": 1.5e5}, {"young_modulus": 3e5}]
    soft, stiff = sweep(EXAMPLES / "diamond_workspace.py", designs, workers=1,
                        fixed={"gravity": 0.0, "steps_per_cable": 2})
    assert soft.status == stiff.status == "completed"
    assert soft.metrics["workspace_cm2"] > 10.0 and soft.metrics["reach_mm"] > 20.0
    assert stiff.metrics["workspace_cm2"] == pytest.approx(soft.metrics["workspace_cm2"], rel=1e-8)
    assert abs(stiff.probes["top"] - soft.probes["top"]).max() < 1e-9
    assert stiff.metrics["max_tension"] == pytest.approx(2.0 * soft.metrics["max_tension"], rel=1e-8)
