"""Scenes built from random, partly invalid parameters: a clear warpsoft error, or steps that
stay finite; never another exception, a hang or a NaN (hypothesis)."""

import math
import warnings

import numpy as np
import pytest

hypothesis = pytest.importorskip("hypothesis")
from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

import warpsoft as ws  # noqa: E402

ODD = [0.0, -1.0, math.nan, math.inf, -math.inf, 1e300, -1e300, 1e-300]


def number(lo, hi):
    """A value in [lo, hi] nine times in ten, else an odd one."""
    return st.integers(0, 9).flatmap(lambda k: st.sampled_from(ODD) if k == 0 else st.floats(lo, hi))


@settings(max_examples=200, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
@given(length=number(0.01, 0.2), divisions=st.integers(1, 6), young=number(1e3, 1e7), poisson=number(-0.5, 0.499),
       density=number(100.0, 3000.0), dt=number(1e-4, 0.1), static=st.booleans(), gravity=number(-20.0, 20.0),
       force=number(-1.0, 1.0), cable=st.booleans(), pull=number(-0.05, 0.3), cable_value=number(-0.01, 0.02),
       inverse=st.booleans(), target=number(-0.05, 0.3), clamp=st.sampled_from(["face", "node", "none"]))
def test_random_scenes_fail_clearly_or_stay_finite(length, divisions, young, poisson, density, dt, static, gravity,
                                                  force, cable, pull, cable_value, inverse, target, clamp):
    try:
        scene = ws.Scene("fuzz", gravity=(0.0, 0.0, gravity), dt=dt, static=static)
        mesh = ws.box_grid((0, 0, 0), (length, 0.01, 0.01), (divisions, 1, 1))
        body = scene.add_body("beam", mesh, ws.Material(young, poisson, density), element="corotational")
        if clamp == "face":
            scene.fix(body, ws.OnPlane((0, 0, 0), (1, 0, 0)))
        elif clamp == "node":
            scene.fix(body, ws.InBox((-1e-9, -1e-9, -1e-9), (1e-9, 1e-9, 1e-9)))
        scene.add_force(body, ws.OnPlane((length, 0, 0), (1, 0, 0)), (0.0, 0.0, force))
        if cable:
            scene.add_cable("c", body, points=[(0.5 * length, 0.005, 0.009), (length, 0.005, 0.009)],
                            pull_point=(pull, 0.005, 0.009), value=cable_value)
            if inverse:
                scene.add_effector("tip", (length, 0.005, 0.005), target=(length, 0.005, target))
                scene.use_inverse_model()
        sim = ws.Simulator(scene, solver="direct")
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # convergence warnings are allowed; exceptions are not
            for _ in range(3):
                sim.step()
    except ws.WarpsoftError:
        return  # a clear error: what bad input should get
    assert np.all(np.isfinite(sim.positions()))
