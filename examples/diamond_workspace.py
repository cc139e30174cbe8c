"""The Diamond (``scenes/diamond.py``), quasi-static, for a sweep over its leg radius and its
silicone's Young's modulus: the workspace its top reaches with the cables' full stroke, and
the tension that takes.

    warpsoft sweep examples/diamond_workspace.py --grid leg_radius=[0.009,0.011,0.013] \\
        --grid young_modulus=[1.2e5,1.8e5,2.7e5] --out out/diamond_workspace

Cable 0 is pulled to the full stroke; then each cable in turn hands over to the next (one
released as the next is pulled) round the four, back to cable 0. The top traces the edge of
what one or two neighbouring cables at full stroke reach: its area, seen from above, is the
workspace. The cables' displacements are imposed: without gravity the workspace is set by the
geometry alone (the leg radius) and the tension grows in proportion to the modulus; with it,
soft and slender designs also sag under their own weight (``dip_mm``).

At full stroke the structure can settle on either side of its plane of symmetry, so the top's
place at the end of the loop may differ from its place at the start by millimetres (seen on the
2-core VM: 3 to 10 mm sideways, the area within 5 % from 4 to 8 steps per hand-over)."""

from pathlib import Path

import numpy as np

from warpsoft.io.runner import load_scene_module

diamond = load_scene_module(Path(__file__).resolve().parent.parent / "scenes" / "diamond.py")


def build(leg_radius=0.011, young_modulus=180e3, stroke=0.02, steps_per_cable=4, mesh_size=0.01, **diamond_params):
    """The loop above in ``steps_per_cable`` quasi-static steps per hand-over (five hand-overs,
    the first the pull of cable 0); ``stroke`` (m) the full stroke. Other parameters go to
    ``scenes/diamond.py``."""
    n = int(steps_per_cable)

    def schedule(t: float) -> list[float]:
        phase = t / n  # time is the step index (dt = 1 s): phase k..k+1 hands cable k-1 to cable k
        d = [0.0] * 4
        if phase <= 1.0:
            d[0] = stroke * phase
            return d
        k = min(int(np.ceil(phase)) - 1, 4)  # the hand-over under way, 1..4
        f = phase - k
        d[(k - 1) % 4], d[k % 4] = stroke * (1.0 - f), stroke * f
        return d

    scene = diamond.build(leg_radius=leg_radius, young_modulus=young_modulus, mesh_size=mesh_size, static=True,
                          dt=1.0, max_cable_displacement=stroke, cable_schedule=schedule, **diamond_params)
    scene.steps = 5 * n
    return scene


def metrics(result):
    """``workspace_cm2``: the area the top's path encloses seen from above over the four
    hand-overs (cm^2); ``reach_mm``: the largest horizontal move of the top (mm); ``dip_mm``: its
    largest fall (mm); ``max_tension``: the largest cable force on the way (N)."""
    top = result.probes["top"]  # (steps + 1, 3), the rest position first
    n = (len(top) - 1) // 5
    loop = top[n:, :2]  # cable 0 at full stroke, round the four hand-overs, back to it
    x, y = loop[:, 0], loop[:, 1]
    area = 0.5 * abs(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))
    moved = top - top[0]
    tension = max(float(np.max(v)) for v in result.actuator_lambda.values())
    return {"workspace_cm2": 1e4 * area, "reach_mm": 1e3 * float(np.max(np.hypot(moved[:, 0], moved[:, 1]))),
            "dip_mm": -1e3 * float(np.min(moved[:, 2])), "max_tension": tension}
