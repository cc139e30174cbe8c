"""Octoleg: one tentacle of an octopus-like robot (after the SoftRobots paper's Octoleg), a
tapered silicone arm clamped at its base and bent down by one cable along its underside: it
folds over a rigid cylinder below it until its tip rests on the floor, the cable then held at
its motor's force limit. x runs along the arm from its clamped base at x = 0; z is up."""

import numpy as np

import warpsoft as ws


def build(length=0.1, base_radius=0.008, tip_radius=0.003, young_modulus=100e3, poisson_ratio=0.45, density=1070.0,
          gravity=9.81, dt=0.01, mesh_size=0.006, cable_displacement=0.03, ramp_time=1.0, cylinder_radius=0.01,
          cylinder_x=0.05, cylinder_gap=0.004, floor_depth=0.03, mu=0.3, damping=(0.5, 0.02), max_force=0.5,
          element="corotational"):
    """Arm of ``length`` (m), radius ``base_radius`` tapering to ``tip_radius``; silicone (E, nu,
    density). The cable, ``0.6 radius`` below the axis, shortens linearly to
    ``cable_displacement`` (m) over ``ramp_time`` (s). A cylinder of ``cylinder_radius`` (m), its
    axis along y under ``cylinder_x``, leaves ``cylinder_gap`` (m) below the arm; a floor lies
    ``floor_depth`` (m) below the axis. Both have friction ``mu``. The cable's tension stays below
    ``max_force`` (N, its motor's limit): once the arm lies on the cylinder and the floor, a
    command it cannot reach leaves it at that tension instead of crushing it. ``element``: the arm's
    element model (see ``Scene.add_body``)."""
    shape = ws.Cone((0.0, 0.0, 0.0), (length, 0.0, 0.0), base_radius, tip_radius)
    scene = ws.Scene("octoleg", gravity=(0.0, 0.0, -gravity), dt=dt, steps=150)
    arm = scene.add_body("arm", ws.mesh_shape(shape, mesh_size, name="octoleg"),
                         ws.Material(young_modulus, poisson_ratio, density), element=element)
    scene.set_damping(*damping)
    scene.fix(arm, ws.InBox((-1.0, -1.0, -1.0), (0.1 * length, 1.0, 1.0)))  # the clamp
    xs = np.linspace(0.12, 0.95, 8) * length
    radius = base_radius + (tip_radius - base_radius) * xs / length
    path = [(x, 0.0, -0.6 * r) for x, r in zip(xs, radius, strict=True)]
    scene.add_cable("cable", arm, points=path, pull_point=(-0.01, 0.0, -0.6 * base_radius),
                    value=ws.Ramp(cable_displacement, ramp_time), max_force=max_force)
    under = base_radius + (tip_radius - base_radius) * cylinder_x / length
    axis_z = -(under + cylinder_gap + cylinder_radius)
    scene.add_obstacle("cylinder", ws.obstacles.Cylinder((cylinder_x, -0.03, axis_z), (cylinder_x, 0.03, axis_z),
                                                         cylinder_radius), mu=mu)
    scene.add_obstacle("floor", ws.obstacles.Floor((0.0, 0.0, -floor_depth)), mu=mu)
    scene.set_contacts(96)
    scene.add_effector("tip", (length, 0.0, 0.0))
    scene.add_probe("tip", (length, 0.0, 0.0))
    return scene
