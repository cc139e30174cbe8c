"""Stifface (after the SoftRobots paper's haptic interface; the geometry here is ours, the
reference folder has no Stifface mesh): a silicone block, its base held, with four cables
running under its top face, two along x and two along y around its centre, each anchored on
the far side and pulled from a motor beyond the near one. A fingertip presses the top's centre;
the inverse model shortens the cables so that the pressed point stays at its target (by
default where it rests): shortened, they squeeze the block's upper layer, which, nearly
incompressible, rises, and they straighten where the finger bowed them. The block is of stable
Neo-Hookean silicone (around the cables' anchors it is squeezed to about half its volume),
quasi-static. z is up; the top face's centre is the effector.
"""

import math

import warpsoft as ws


def build(size=0.04, height=0.015, cable_depth=0.006, cable_offset=0.005, young_modulus=100e3, poisson_ratio=0.45,
          density=1100.0, mesh_size=0.004, element="neohookean", press=1.0, finger_radius=0.005, ramp_time=1.0,
          dt=0.02, steps=100, mode="inverse", target_height=None, cable_displacement=0.0,
          max_cable_displacement=0.01, max_cable_step=0.0005, axes="xyz"):
    """A ``size x size x height`` block (m) on the plane z = 0, its base face held; the four
    cables ``cable_depth`` (m) under the top, ``cable_offset`` (m) either side of its centre
    lines. The fingertip presses ``press`` (N, down) on the top within ``finger_radius`` (m) of
    its centre, reached linearly over ``ramp_time`` (s) and held. ``mode="inverse"``: the cables
    keep the top's centre at ``(0, 0, target_height)`` (m; None: its rest height ``height``)
    along ``axes``, each shortening within [0, ``max_cable_displacement``] m and by at most
    ``max_cable_step`` m a step. ``mode="direct"``: every cable shortens by
    ``cable_displacement`` (m) over the same ramp. ``element``: the block's element model."""
    if mode not in ("direct", "inverse"):
        raise ws.SceneError(f"stifface: mode must be 'direct' or 'inverse', got {mode!r}")
    if not 0.0 < cable_depth < height:
        raise ws.SceneError(f"stifface: cable_depth must lie in (0, height={height:g}) m, got {cable_depth!r}")
    if not 0.0 <= cable_offset < size / 2:
        raise ws.SceneError(f"stifface: cable_offset must lie in [0, size/2={size / 2:g}) m, got {cable_offset!r}")
    half = size / 2
    scene = ws.Scene("stifface", static=True, dt=dt, steps=steps)
    block = scene.add_body("block", ws.mesh_shape(ws.shapes.Box((-half, -half, 0.0), (size, size, height)), mesh_size,
                                                  name="stifface"),
                           ws.Material(young_modulus, poisson_ratio, density), element=element)
    scene.fix(block, ws.OnPlane((0.0, 0.0, 0.0), (0.0, 0.0, 1.0), tol=1e-9))  # the base, glued to the device
    ramp = lambda t: min(t / ramp_time, 1.0)  # noqa: E731
    scene.add_force(block, ws.InSphere((0.0, 0.0, height), finger_radius), lambda t: (0.0, 0.0, -press * ramp(t)),
                    name="fingertip")
    z = height - cable_depth
    inside = 0.97 * half  # the path's ends, just inside the sides
    count = max(2, math.ceil(2 * inside / mesh_size)) + 1  # about a point per element along the way
    step = max_cable_step if mode == "inverse" else math.inf
    # a pinwheel: each cable pulled from the side its neighbour across the centre is anchored on,
    # so that the block is the same turned by half a turn about its axis (equal pulls keep the
    # pressed point from moving sideways)
    for axis in (0, 1):
        for side in (-1.0, 1.0):
            near = side if axis == 0 else -side  # the side its motor is on, along its axis

            def at(s, axis=axis, side=side, near=near):  # a point on this cable, s from the centre towards its motor
                p = [0.0, 0.0, z]
                p[axis], p[1 - axis] = near * s, side * cable_offset
                return tuple(p)
            path = [at(inside - 2 * inside * k / (count - 1)) for k in range(count)]  # near side to anchor
            name = f"cable_{'xy'[axis]}{'-+'[side > 0]}"
            scene.add_cable(name, block, points=path, pull_point=at(half + 0.01), mode="displacement",
                            value=lambda t: cable_displacement * ramp(t), min_displacement=0.0,
                            max_displacement=max_cable_displacement, max_step=step)
    top = (0.0, 0.0, height)
    if mode == "inverse":
        scene.add_effector("press_point", top, target=(0.0, 0.0, height if target_height is None else target_height),
                           axes=axes)
        scene.use_inverse_model()
    scene.add_probe("top", top)
    return scene
