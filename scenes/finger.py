"""A cable finger (after SoftRobots' finger): a notched silicone finger clamped at its base,
under gravity, curled by a cable running along it under the notches. The finger runs along
-x from its base face at x = 0; z is up."""

import warpsoft as ws


def build(length=0.085, height=0.02, width=0.015, notches=3, notch_depth=0.006, notch_width=0.004,
          young_modulus=600e3, poisson_ratio=0.45, total_mass=0.075, gravity=9.81, dt=0.01,
          rayleigh_mass=0.1, rayleigh_stiffness=0.1, mesh_size=0.004, cable_displacement=0.012, ramp_time=0.5,
          max_cable_displacement=0.03, cable_height=None, static=False, element="corotational", refine=0,
          anchor_radius=0.0):
    """Finger ``length`` (m) along -x, ``height`` (z) x ``width`` (y), ``notches`` cut into its
    top; silicone E 600 kPa, nu 0.45, 75 g (SoftRobots' values). The cable shortens linearly
    to ``cable_displacement`` (m) over ``ramp_time`` (s), within ``max_cable_displacement``; it
    runs at ``cable_height`` (m) above the bottom face, under the notches (by default at three
    quarters of their floor's height). ``static=True``: quasi-static steps. ``element``: the body's
    element model ("corotational", "quadratic", "neohookean"; see docs/accuracy). ``refine``: the
    mesh split that many times, each element into eight (nested refinement). ``anchor_radius``
    (m): the cable's end fastened over the material within it (a knot); 0: at a point."""
    floor = height - notch_depth  # the notches' floor
    if cable_height is None:
        cable_height = floor - 0.25 * floor
    if not 0.0 < cable_height < floor:
        raise ws.SceneError(f"finger: cable_height must lie in the body under the notches, in (0, {floor:g}) m, "
                            f"got {cable_height!r}")
    shape = ws.shapes.Box((-length, 0.0, 0.0), (length, width, height))
    pitch = length / (notches + 1)
    for k in range(1, notches + 1):
        x = -k * pitch - notch_width / 2
        notch = ws.shapes.Box((x, -0.001, height - notch_depth), (notch_width, width + 0.002, notch_depth + 0.001))
        shape = shape - notch
    scene = ws.Scene("finger", gravity=(0.0, 0.0, -gravity), dt=dt, steps=100, static=static)
    finger = scene.add_body("finger", ws.mesh_shape(shape, mesh_size, name="finger").refined(refine),
                            ws.Material(young_modulus, poisson_ratio), total_mass=total_mass,
                            element=element)
    scene.set_damping(rayleigh_mass, rayleigh_stiffness)
    scene.fix(finger, ws.InBox((-0.1 * length, -1.0, -1.0), (0.0, 1.0, 1.0)))  # base clamp
    z = cable_height
    path = [(-length * k / 10, width / 2, z) for k in range(1, 10)] + [(-length + 0.003, width / 2, z)]
    scene.add_cable("cable", finger, points=path, pull_point=(0.01, width / 2, z), mode="displacement",
                    value=ws.Ramp(cable_displacement, ramp_time),
                    max_displacement=max_cable_displacement, anchor_radius=anchor_radius)
    scene.add_effector("fingertip", (-length, width / 2, height / 2))
    scene.add_probe("tip", (-length, width / 2, height / 2))
    return scene
