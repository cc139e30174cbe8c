"""The Diamond parallel robot (after SoftRobots.Inverse): one silicone piece, four legs from a
fixed base out to four corners and four arms up to a top platform; four cables pull the
corners toward the base. z is up; the effector is the top of the platform.

``mesh``: a path to SoftRobots.Inverse's own ``diamond.vtk`` (mm) to run its mesh instead of
the one generated here, placed as SoftRobots places it (+90 deg about x, then +35 mm in z),
with its exact pull points (0, 10, 30) mm and so on; its cable points lie 0.1-0.5 mm outside
that mesh and map to their nearest elements, as in SOFA."""

import math

import numpy as np

import warpsoft as ws


def build(radius=0.097, corner_height=0.045, top_height=0.125, leg_radius=0.011, young_modulus=180e3,
          poisson_ratio=0.45, total_mass=0.5, gravity=9.81, dt=0.02, rayleigh_mass=0.1, rayleigh_stiffness=0.1,
          mesh_size=0.01, mode="direct", cable_displacements=(0.0, 0.0, 0.0, 0.0), ramp_time=1.0,
          max_cable_displacement=0.02, max_cable_step=0.001, target=None, circle_radius=0.015, circle_depth=0.003,
          circle_period=4.0, static=False, mesh=None, cable_schedule=None, cable_forces=None, refine=0,
          element="corotational", anchor_radius=0.0):
    """``mode="direct"``: each cable i shortens linearly to ``cable_displacements[i]`` (m) over
    ``ramp_time`` (s). ``mode="inverse"``: the cables follow the effector's ``target`` (x, y, z)
    (m), or by default a circle of ``circle_radius`` (m), ``circle_depth`` (m) below the rest top,
    one turn per ``circle_period`` (s), entered over the first quarter turn. Cables stay in
    [0, ``max_cable_displacement``] (SoftRobots: 20 mm) with tension >= 0; in inverse mode they
    change by at most ``max_cable_step`` (m) per step. ``static=True``: quasi-static steps.
    ``cable_schedule``: in direct mode, a function of time (s) giving the four cable
    displacements (m), instead of the ramp to ``cable_displacements``. ``cable_forces``: in
    direct mode, four tensions (N) or None each: a cable given one is driven by force, ramped to
    it over ``ramp_time`` (0: a free cable), the others by displacement. ``refine``: the mesh
    (generated or ``mesh``) split that many times, each element into eight (nested refinement).
    ``element``: the body's element model (``Scene.add_body``: "corotational", "quadratic",
    "neohookean"). ``anchor_radius`` (m): each cable fastened over the material within it of its
    corner (a knot); 0: at the corner point."""
    if mode not in ("direct", "inverse"):
        raise ws.SceneError(f"diamond: mode must be 'direct' or 'inverse', got {mode!r}")
    if cable_schedule is not None and (mode != "direct" or not callable(cable_schedule)):
        raise ws.SceneError(f"diamond: cable_schedule must be a function of time, in direct mode; got "
                            f"{cable_schedule!r} in mode {mode!r}")
    if len(cable_displacements) != 4:
        raise ws.SceneError(f"diamond: cable_displacements must have 4 values, got {cable_displacements!r}")
    forces = (None,) * 4 if cable_forces is None else tuple(cable_forces)
    if len(forces) != 4 or (cable_forces is not None and (mode != "direct" or cable_schedule is not None)):
        raise ws.SceneError(f"diamond: cable_forces must have 4 values (N or None), in direct mode without a "
                            f"cable_schedule; got {cable_forces!r} in mode {mode!r}")
    base_top = 0.01
    hub = np.array([0.0, 0.0, 0.0])
    top = np.array([0.0, 0.0, top_height - leg_radius])
    corners = [np.array([radius * math.cos(a), radius * math.sin(a), corner_height])
               for a in np.radians([90.0, 180.0, 270.0, 0.0])]
    shape = ws.Cylinder((0.0, 0.0, -0.03), (0.0, 0.0, 0.03 + base_top), 0.015) + ws.Ball(tuple(top), 1.3 * leg_radius)
    for c in corners:
        shape = shape + ws.Ball(tuple(c), 1.3 * leg_radius)
        shape = shape + ws.Cylinder(tuple(hub), tuple(c - hub), leg_radius)
        shape = shape + ws.Cylinder(tuple(c), tuple(top - c), leg_radius)
    pulls = [0.1 * c * np.array([1.0, 1.0, 0.0]) + np.array([0.0, 0.0, 0.03]) for c in corners]
    if mesh is None:
        tets = ws.mesh_shape(shape, mesh_size, name="diamond", curvature=0)
    else:  # SoftRobots' mesh and placement, its pull points 10 mm from the axis
        tets = ws.load_mesh(mesh, scale=1e-3).transformed(rotation=ws.rotation_about("x", 90.0),
                                                           translation=(0.0, 0.0, 0.035))
        pulls = [0.01 * c / np.linalg.norm(c[:2]) * np.array([1.0, 1.0, 0.0]) + np.array([0.0, 0.0, 0.03])
                 for c in corners]
    tets = tets.refined(refine)
    scene = ws.Scene("diamond", gravity=(0.0, 0.0, -gravity), dt=dt, static=static, steps=100)
    body = scene.add_body("diamond", tets, ws.Material(young_modulus, poisson_ratio), total_mass=total_mass,
                         element=element)
    scene.set_damping(rayleigh_mass, rayleigh_stiffness)
    scene.fix(body, ws.InBox((-0.015, -0.015, -0.04), (0.015, 0.015, base_top)))  # SoftRobots' base box
    step = max_cable_step if mode == "inverse" else math.inf
    for i, (c, d, pull) in enumerate(zip(corners, cable_displacements, pulls, strict=True)):
        if forces[i] is not None:  # driven by its tension
            scene.add_cable(f"cable{i}", body, points=[tuple(c)], pull_point=tuple(pull), mode="force",
                            value=ws.Ramp(float(forces[i]), ramp_time), anchor_radius=anchor_radius)
            continue
        if cable_schedule is None:
            value = ws.Ramp(d, ramp_time)
        else:
            value = lambda t, i=i: cable_schedule(t)[i]  # noqa: E731
        scene.add_cable(f"cable{i}", body, points=[tuple(c)], pull_point=tuple(pull), mode="displacement",
                        value=value, min_displacement=0.0,
                        max_displacement=max_cable_displacement, max_step=step, anchor_radius=anchor_radius)
    top_point = np.array([0.0, 0.0, top_height])
    if mode == "inverse":
        if target is None:
            def circle(t):  # enter the circle over a quarter turn, then go round
                w, ramp = 2.0 * math.pi * t / circle_period, min(4.0 * t / circle_period, 1.0)
                r = circle_radius * ramp
                return top_point + np.array([r * math.cos(w), r * math.sin(w), -circle_depth * ramp])
            target = circle
        scene.add_effector("effector", tuple(top_point), target=target)
        scene.use_inverse_model()
    else:
        scene.add_effector("effector", tuple(top_point))
    scene.add_probe("top", (0.0, 0.0, top_height))
    return scene
