"""Cable bar: a bar along +x clamped at x = 0, a cable from its free-end centre pulled toward
a point on the axis behind the clamp (validation scene). With a tension T the bar is in
compression and its mid-point moves by ``T (length / 2) / (E A)`` toward the clamp."""

import warpsoft as ws


def build(length=0.1, width=0.01, height=0.01, young_modulus=1e6, poisson_ratio=0.3, cable_force=None,
          cable_displacement=None, mesh_size=None):
    """``cable_force`` (N) or ``cable_displacement`` (m of shortening) drives the cable; with
    neither, a 1 N tension. Probe ``mid`` at (length/2, 0, 0), probe ``end`` at (length, 0, 0)."""
    if cable_force is not None and cable_displacement is not None:
        raise ws.SceneError("cable_bar: give cable_force or cable_displacement, not both")
    h = mesh_size if mesh_size is not None else min(width, height) / 3
    scene = ws.Scene("cable_bar", static=True, steps=3)
    bar = scene.add_body("bar", ws.mesh_shape(ws.shapes.Box((0.0, -width / 2, -height / 2), (length, width, height)),
                                              h, name="bar"), ws.Material(young_modulus, poisson_ratio, 1000.0))
    scene.fix(bar, ws.Plane((0.0, 0.0, 0.0), (1.0, 0.0, 0.0), tol=1e-9))
    if cable_displacement is not None:
        mode, value = "displacement", cable_displacement
    else:
        mode, value = "force", 1.0 if cable_force is None else cable_force
    scene.add_cable("cable", bar, points=[(length, 0.0, 0.0)], pull_point=(-0.2 * length, 0.0, 0.0), mode=mode,
                    value=value)
    scene.add_probe("mid", (length / 2, 0.0, 0.0))
    scene.add_probe("end", (length, 0.0, 0.0))
    return scene
