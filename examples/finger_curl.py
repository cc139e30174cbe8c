"""The cable finger (``scenes/finger.py``), quasi-static, for a sweep over where its cable runs:
how far the tip curls per millimetre of cable, and the tension that takes.

    warpsoft sweep examples/finger_curl.py --grid cable_height=[0.006,0.008,0.0105,0.013] --out out/finger_curl

A cable of tension T at a distance e from the finger's neutral axis bends it by
theta = T e L / (E I) and shortens it by T L / (E A): the cable's shortening is
delta = e theta + T L / (E A), so theta / delta = e / (e^2 + I / A). The curl per millimetre
changes sign across the neutral axis and is largest at e = sqrt(I / A), about 5 mm here; the
tension needed is largest on the axis, where the cable only squeezes the finger."""

from pathlib import Path

import numpy as np

from warpsoft.io.runner import load_scene_module

finger = load_scene_module(Path(__file__).resolve().parent.parent / "scenes" / "finger.py")


def build(cable_height=0.0105, cable_displacement=0.004, young_modulus=600e3, mesh_size=0.004, steps=4,
          **finger_params):
    """The finger's cable (``cable_height`` m above its bottom face) shortened to
    ``cable_displacement`` (m) in ``steps`` quasi-static steps; probes at the top and the bottom
    of the tip's end face. Other parameters go to ``scenes/finger.py`` (``gravity=0`` ...)."""
    scene = finger.build(cable_height=cable_height, cable_displacement=cable_displacement,
                         young_modulus=young_modulus, mesh_size=mesh_size, static=True, dt=1.0, ramp_time=steps,
                         **finger_params)
    length, height, width = 0.085, 0.02, 0.015  # the finger's defaults
    scene.add_probe("tip_top", (-length, width / 2, height))
    scene.add_probe("tip_bottom", (-length, width / 2, 0.0))
    scene.steps = int(steps)
    return scene


def metrics(result):
    """``curl_deg``: the turn of the tip's end face about -y at the end (deg, positive: the tip up,
    gravity's sag included); ``curl_per_mm``: the turn per mm of cable between the first step and
    the last (the sag cancels); ``tension``: the cable's force at the end (N); ``cable_mm``: the
    shortening reached (mm)."""
    face = result.probes["tip_top"] - result.probes["tip_bottom"]  # (steps + 1, 3)
    turn = np.degrees(np.arctan2(face[:, 0], face[:, 2]) - np.arctan2(face[0, 0], face[0, 2]))
    cable = 1e3 * np.asarray(result.actuator_delta["cable"])  # mm, per step
    return {"curl_deg": float(turn[-1]), "curl_per_mm": float((turn[-1] - turn[1]) / (cable[-1] - cable[0])),
            "tension": float(result.actuator_lambda["cable"][-1]), "cable_mm": float(cable[-1])}
