"""Cable bar: a bar along +x clamped at x = 0, a cable from its free-end centre pulled toward
a point on the axis behind the clamp (validation scene). With a tension T the bar is in
compression and its mid-point moves by ``T (length / 2) / (E A)`` toward the clamp.

Above a critical tension the straight bar is unstable and buckles: bending stiffness against the
compression's softening, helped a little by the cable, whose line of action stays through the
pull point. :func:`buckling_tension` estimates it (Rayleigh-Ritz with the cantilever's cubic
deflection shape): 0.68 N with the defaults.
"""

import warpsoft as ws


def build(length=0.1, width=0.01, height=0.01, young_modulus=1e6, poisson_ratio=0.3, cable_force=None,
          cable_displacement=None, mesh_size=None, element="corotational"):
    """``cable_force`` (N) or ``cable_displacement`` (m of shortening) drives the cable; with
    neither, a 0.2 N tension (below the buckling tension). Probe ``mid`` at (length/2, 0, 0),
    probe ``end`` at (length, 0, 0). ``element``: the bar's element model (``Scene.add_body``)."""
    if cable_force is not None and cable_displacement is not None:
        raise ws.SceneError("cable_bar: give cable_force or cable_displacement, not both")
    h = mesh_size if mesh_size is not None else min(width, height) / 3
    scene = ws.Scene("cable_bar", static=True, steps=3)
    bar = scene.add_body("bar", ws.mesh_shape(ws.shapes.Box((0.0, -width / 2, -height / 2), (length, width, height)),
                                              h, name="bar"), ws.Material(young_modulus, poisson_ratio, 1000.0),
                         element=element)
    scene.fix(bar, ws.OnPlane((0.0, 0.0, 0.0), (1.0, 0.0, 0.0), tol=1e-9))
    if cable_displacement is not None:
        mode, value = "displacement", cable_displacement
    else:
        mode, value = "force", 0.2 if cable_force is None else cable_force
    scene.add_cable("cable", bar, points=[(length, 0.0, 0.0)], pull_point=(-0.2 * length, 0.0, 0.0), mode=mode,
                    value=value)
    scene.add_probe("mid", (length / 2, 0.0, 0.0))
    scene.add_probe("end", (length, 0.0, 0.0))
    return scene


def buckling_tension(length=0.1, width=0.01, height=0.01, young_modulus=1e6, pull_behind=None):
    """Cable tension (N) above which the straight bar buckles (Rayleigh-Ritz, tip deflection ``v``
    with the cubic shape ``v (3 s^2 - s^3) / 2``, ``s = x / length``): bending ``3 E I / L^3``,
    compression ``-(6/5) T / L``, the cable's turn toward its pull point (``pull_behind`` m
    behind the clamp, the scene's ``0.2 length`` by default) ``+T / (L + c)``, per unit
    ``v^2 / 2``."""
    c = 0.2 * length if pull_behind is None else pull_behind
    inertia = min(width * height ** 3, height * width ** 3) / 12.0  # the weaker bending axis
    bending = 3.0 * young_modulus * inertia / length ** 3
    return bending / (1.2 / length - 1.0 / (length + c))
