"""A pneumatic bending actuator (PneuNet-like): a solid floor carrying a row of hollow
chambers separated by gaps, joined by a channel in the floor into one sealed cavity. Inflated
chambers push each other apart over the gaps, the top lengthens and the actuator bends toward
its floor. It runs along +x from its clamped base at x = 0; z is up."""

import warpsoft as ws


def build(length=0.115, width=0.02, height=0.02, chambers=6, gap=0.002, wall=0.0025, floor=0.005,
          young_modulus=500e3, poisson_ratio=0.45, density=1070.0, pressure=3e3, ramp_time=0.5, dt=0.01,
          gravity=0.0, rayleigh_mass=0.1, rayleigh_stiffness=0.01, mesh_size=0.007, self_contact=False,
          element="quadratic", static=False, refine=0):
    """``pressure`` (Pa) is reached linearly over ``ramp_time`` (s); ``wall`` (m) is the chamber
    walls' thickness, ``gap`` (m) the space between chambers, ``floor`` (m) the base layer.
    ``self_contact``: the chambers' walls touch each other across the gaps, and the curled body
    touches itself, instead of passing through (above about 10 kPa they meet). ``element``: the
    body's element model ("corotational", "quadratic", "neohookean"). By default 10-node elements
    at a 7 mm mesh, as tools/accuracy.py recommends: the walls bend under the pressure, and linear
    elements lock there (at 3 kPa the tip's motion is 2.4 % short of the converged one at 20916
    DOFs, where linear elements on the same nodes are 44 % short and the former default, linear
    at 3.5 mm, 58 %; docs/accuracy/summary.md). ``static=True``: quasi-static
    steps. ``refine``: the mesh split that many times, each element into eight (nested refinement,
    the chambers' boxes kept exactly)."""
    base = 0.01  # solid block at x in [0, base], clamped
    pitch = (length - base) / chambers
    Box = ws.shapes.Box
    solid = Box((0.0, 0.0, 0.0), (length, width, floor)) + Box((0.0, 0.0, 0.0), (base, width, height))
    eps = 1e-6
    x_first, x_last = base + gap + wall, base + chambers * pitch - wall
    lo_channel, hi_channel = 0.25 * floor, 0.6 * floor  # the channel runs inside the floor
    channel = ((x_first, width / 2 - 0.0015, lo_channel), (x_last, width / 2 + 0.0015, hi_channel))
    voids = Box(channel[0], tuple(b - a for a, b in zip(*channel, strict=True)))
    cavity = ws.InBox(*channel, tol=eps)
    for k in range(chambers):
        x0 = base + gap + k * pitch
        solid = solid + Box((x0, 0.0, floor), (pitch - gap, width, height - floor))
        inner = ((x0 + wall, wall, 0.5 * floor), (x0 + pitch - gap - wall, width - wall, height - wall))
        voids = voids + Box(inner[0], tuple(b - a for a, b in zip(*inner, strict=True)))
        cavity = cavity | ws.InBox(*inner, tol=eps)
    shape = solid - voids
    scene = ws.Scene("pneunet", gravity=(0.0, 0.0, -gravity), dt=dt, steps=100, static=static)
    bar = scene.add_body("pneunet", ws.mesh_shape(shape, mesh_size, name="pneunet").refined(refine),
                         ws.Material(young_modulus, poisson_ratio, density), element=element)
    scene.set_damping(rayleigh_mass, rayleigh_stiffness)
    if self_contact:
        scene.add_self_contact(bar)
        scene.set_contacts(256)  # the gaps' facing walls: about a hundred nodes come near at 60 kPa
    scene.fix(bar, ws.InBox((-1.0, -1.0, -1.0), (0.2 * base, 1.0, 1.0)))
    scene.add_cavity("chambers", bar, region=cavity, mode="pressure",
                     value=ws.Ramp(pressure, ramp_time))
    scene.add_effector("tip", (length, width / 2, floor / 2))
    scene.add_probe("tip", (length, width / 2, floor / 2))
    return scene
