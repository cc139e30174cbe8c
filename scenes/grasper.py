"""The Grasper (after SoftRobots' Table 1): three cable fingers hanging from a palm around a rigid
cube that rests on the floor. One cable input drives all three fingers: they close on the cube,
the palm lifts, holds, and the fingers open again. Friction between the fingers and the cube
(``mu``) is what lifts it: with a large ``mu`` the cube rises with the palm, with a small one it
stays on the floor while the fingers slide up its faces.

Layout (z up, the cube's centre on the z axis): one finger on the +x side faces two on the -x
side (a thumb against two fingers), so that each finger's inner face meets a face of the cube.
A finger is a notched silicone bar hanging down from the palm; its cable runs behind the notches
on its inner side, so pulling it curls the tip towards the cube.
"""

import numpy as np

import warpsoft as ws


def finger_shape(inner: float, side: int, y: float, top: float, length: float, thickness: float, width: float,
                 notches: int, notch_depth: float, notch_width: float):
    """A notched finger hanging from ``top`` (m): its inner face at ``x = side * inner``, centred
    at ``y``; the notches are cut into the inner face."""
    x_lo = inner if side > 0 else -inner - thickness
    shape = ws.shapes.Box((x_lo, y - width / 2, top - length), (thickness, width, length))
    pitch = length / (notches + 1)
    for k in range(1, notches + 1):
        z = top - k * pitch - notch_width / 2
        x_cut = inner - 0.001 if side > 0 else -inner - notch_depth
        shape = shape - ws.shapes.Box((x_cut, y - width / 2 - 0.001, z), (notch_depth + 0.001, width + 0.002,
                                                                          notch_width))
    return shape


def build(mu=0.8, floor_mu=0.5, cube_size=0.03, cube_mass=0.01, length=0.06, thickness=0.012, width=0.012,
          gap=0.004, notches=3, notch_depth=0.004, notch_width=0.003, young_modulus=600e3, poisson_ratio=0.45,
          density=1070.0, gravity=9.81, dt=0.01, rayleigh_mass=0.5, rayleigh_stiffness=0.01, mesh_size=0.008,
          close=0.008, lift=0.02, times=(1.0, 2.0, 2.5, 3.0, 3.5), contact_distance=0.001, element="corotational"):
    """Fingers ``length`` x ``thickness`` x ``width`` (m), ``gap`` (m) from the cube's faces at
    rest, their tips ``gap`` above the floor; a cube of ``cube_size`` (m) and ``cube_mass`` (kg)
    with friction ``mu`` against the fingers (``floor_mu`` on the floor). The sequence, at
    ``times`` (s): the cables shorten by ``close`` (m) until the first, the palm rises by
    ``lift`` (m) until the second, holds until the third, the cables let go until the fourth,
    and the run ends at the fifth. ``element``: the fingers' element model (see ``Scene.add_body``)."""
    t_close, t_lift, t_hold, t_open, t_end = times
    half = cube_size / 2
    top = gap + length  # the palm's underside (m)
    inner = half + gap
    scene = ws.Scene("grasper", gravity=(0.0, 0.0, -gravity), dt=dt, steps=int(round(t_end / dt)))
    scene.set_damping(rayleigh_mass, rayleigh_stiffness)

    def palm(t):  # the palm's rise (m)
        return np.array([0.0, 0.0, lift * np.clip((t - t_close) / (t_lift - t_close), 0.0, 1.0)])

    def cable(t):  # one input for the three cables: shortening (m)
        if t <= t_close:
            return close * t / t_close
        return close * float(np.clip((t_open - t) / (t_open - t_hold), 0.0, 1.0))

    material = ws.Material(young_modulus, poisson_ratio, density)
    fingers = (("thumb", 1, 0.0), ("index", -1, width / 2 + 0.001), ("middle", -1, -width / 2 - 0.001))
    for name, side, y in fingers:
        shape = finger_shape(inner, side, y, top, length, thickness, width, notches, notch_depth, notch_width)
        finger = scene.add_body(name, ws.mesh_shape(shape, mesh_size, name=f"grasper_{name}"), material,
                                element=element)
        scene.fix(finger, ws.InBox((-1.0, -1.0, top - 0.1 * length), (1.0, 1.0, 1.0)), motion=palm)
        x = side * (inner + notch_depth + 0.3 * (thickness - notch_depth))  # behind the notches
        path = [(x, y, top - length * k / 10) for k in range(1, 10)] + [(x, y, top - length + 0.003)]
        scene.add_cable(f"{name}_cable", finger, points=path, pull_point=(x, y, top + 0.01), value=cable,
                        pull_motion=palm, max_displacement=2 * close)
        scene.add_probe(f"{name}_tip", (side * (inner + thickness / 2), y, top - length))
    scene.add_obstacle("floor", ws.obstacles.Floor(), mu=floor_mu)
    scene.add_rigid("cube", ws.obstacles.Box((0.0, 0.0, half), (cube_size,) * 3), mass=cube_mass, mu=mu,
                    contact_distance=contact_distance)
    scene.set_contacts(96)
    return scene
