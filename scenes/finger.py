"""A cable-finger-like silicone body (after SoftRobots' finger): clamped at its base, sagging
under gravity. The finger runs along -x from its base face at x = 0; z is up."""

import warpsoft as ws


def build(length=0.085, height=0.02, width=0.015, notches=3, notch_depth=0.006, notch_width=0.004,
          young_modulus=600e3, poisson_ratio=0.45, total_mass=0.075, gravity=9.81, dt=0.01,
          rayleigh_mass=0.1, rayleigh_stiffness=0.1, mesh_size=0.004):
    """Finger ``length`` (m) along -x, ``height`` (z) x ``width`` (y), with ``notches`` cut into
    its top between phalanges; silicone E 600 kPa, nu 0.45, 75 g (SoftRobots' values)."""
    shape = ws.shapes.Box((-length, 0.0, 0.0), (length, width, height))
    pitch = length / (notches + 1)
    for k in range(1, notches + 1):
        x = -k * pitch - notch_width / 2
        notch = ws.shapes.Box((x, -0.001, height - notch_depth), (notch_width, width + 0.002, notch_depth + 0.001))
        shape = shape - notch
    scene = ws.Scene("finger", gravity=(0.0, 0.0, -gravity), dt=dt, steps=100)
    finger = scene.add_body("finger", ws.mesh_shape(shape, mesh_size, name="finger"),
                            ws.Material(young_modulus, poisson_ratio), total_mass=total_mass)
    scene.set_damping(rayleigh_mass, rayleigh_stiffness)
    scene.fix(finger, ws.Box((-0.1 * length, -1.0, -1.0), (0.0, 1.0, 1.0)))  # base clamp
    scene.add_probe("tip", (-length, width / 2, height / 2))
    return scene
