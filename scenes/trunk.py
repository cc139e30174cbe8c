"""The Trunk (after SoftRobots): a tapered silicone trunk with eight cables at 90 degrees, four
running to the tip and four to the middle, controlled by the inverse model. It lies along +x
from its clamped base (gravity along -z). Its tip sweeps sideways while pointing straight
ahead (a second effector, the "neck" behind the tip, moves sideways with it): a single bend
would turn the tip, so the trunk must take an S-shape. With ``obstacles=True`` it sweeps between
two posts that it touches (the paper's Trunk with contacts)."""

import math

import numpy as np

import warpsoft as ws


def build(length=0.195, base_radius=0.013, tip_radius=0.005, young_modulus=450e3, poisson_ratio=0.45,
          total_mass=0.042, gravity=9.81, dt=0.02, rayleigh_mass=0.1, rayleigh_stiffness=0.02, mesh_size=0.006,
          sweep=0.025, period=4.0, target=None, neck=0.85, max_long=0.07, max_short=0.04, max_step=0.001,
          static=False, obstacles=False, post_radius=0.008, post_x=0.13, post_gap=0.004, base_travel=0.0,
          base_period=None, element="corotational"):
    """Cables shorten by at most ``max_long`` / ``max_short`` (m) and ``max_step`` (m) per step
    (SoftRobots: 70 mm, 40 mm, 1 mm). ``target`` (x, y, z) (m) fixes the tip alone; by default
    the tip and the neck (at ``neck * length``) follow ``y = sweep sin(2 pi t / period)``,
    ``z = 0`` (their x is left free). ``static=True``: quasi-static steps (``dt`` is pseudo-time).
    ``element``: the body's element model ("corotational", "quadratic", "neohookean").

    ``obstacles=True``: two upright rigid posts of ``post_radius`` (m) at ``x = post_x``, one on
    each side, ``post_gap`` (m) from the trunk's surface at rest; the sweep presses the trunk
    against them and the inverse model (a QPCC) steers the tip around what they hold.

    ``base_travel`` (m): the base slides back and forth along the trunk's axis by this much
    (``x = base_travel sin(2 pi t / base_period)``, ``base_period`` the sweep's by default), its
    cable motors with it (a kinematic frame); the inverse model keeps the tip on its target."""
    shape = ws.Cone((0.0, 0.0, 0.0), (length, 0.0, 0.0), base_radius, tip_radius)
    scene = ws.Scene("trunk", gravity=(0.0, 0.0, -gravity), dt=dt, static=static, steps=int(round(period / dt)))
    trunk = scene.add_body("trunk", ws.mesh_shape(shape, mesh_size, name="trunk"),
                           ws.Material(young_modulus, poisson_ratio), total_mass=total_mass,
                           element=element)
    scene.set_damping(rayleigh_mass, rayleigh_stiffness)
    base = None
    if base_travel:
        def base(t, travel=base_travel, period=base_period or period):  # the sliding base (m)
            return np.array([travel * math.sin(2 * math.pi * t / period), 0.0, 0.0])
    scene.fix(trunk, ws.InBox((-0.001, -0.02, -0.02), (0.02, 0.02, 0.02)), motion=base)  # SoftRobots' 20 mm base box

    def radius(x):
        return base_radius + (tip_radius - base_radius) * x / length

    for k, angle in enumerate(np.radians([0.0, 90.0, 180.0, 270.0])):
        u = np.array([0.0, math.cos(angle), math.sin(angle)])
        for kind, end, share, bound in (("long", 0.97 * length, 0.75, max_long),
                                        ("short", 0.5 * length, 0.5, max_short)):
            xs = np.linspace(0.02, end, 12 if kind == "long" else 7)
            points = [tuple(np.array([x, 0.0, 0.0]) + share * radius(x) * u) for x in xs]
            pull = tuple(np.array([-0.01, 0.0, 0.0]) + share * base_radius * u)
            scene.add_cable(f"{kind}{k}", trunk, points=points, pull_point=pull, min_displacement=0.0,
                            max_displacement=bound, max_step=max_step, pull_motion=base)
    if obstacles:  # frictionless: the inverse model's contacts have no friction rows
        side = radius(post_x) + post_gap + post_radius
        for name, y in (("left_post", side), ("right_post", -side)):
            scene.add_obstacle(name, ws.obstacles.Cylinder((post_x, y, -0.04), (post_x, y, 0.04), post_radius))
        scene.set_contacts(64)
    if target is not None:
        scene.add_effector("tip", (length, 0.0, 0.0), target=target)
    else:
        def lateral(t):  # enter the sweep smoothly over the first quarter period
            return sweep * min(4.0 * t / period, 1.0) * math.sin(2 * math.pi * t / period)

        for name, x in (("tip", length), ("neck", neck * length)):
            scene.add_effector(name, (x, 0.0, 0.0), target=lambda t, x=x: np.array([x, lateral(t), 0.0]),
                               axes="yz")
    scene.use_inverse_model()
    for k in range(1, 5):
        scene.add_probe(f"c{k}", (k * length / 4, 0.0, 0.0))
    return scene
