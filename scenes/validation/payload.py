"""Payload: a rigid weight glued under a soft bar that hangs from its top (validation scene for
attachments). The bar's bottom face is held by the weight (``Scene.attach``), so at rest the
bar carries the weight as a rod in tension: with ``poisson_ratio = 0`` the stress is uniaxial
and the bottom comes down by ``m g L / (E A)`` under the weight plus ``rho g L^2 / (2 E)``
under the bar's own (:func:`stretch`). ``swing`` (m/s) starts the weight sideways: the bar then
bends and sways with it.
"""

import warpsoft as ws


def build(length=0.05, side=0.01, young_modulus=1e5, poisson_ratio=0.0, density=100.0, mass=0.05, swing=0.0,
          mesh_size=0.005, gravity=9.81, dt=0.01):
    """A bar ``side x side x length`` (m) on z in ``[0, length]``, fixed at its top face; a cube
    of side ``side`` and ``mass`` (kg) glued under its bottom face, moving sideways (x) at
    ``swing`` (m/s) at t = 0; probes ``bottom`` (the bottom face's centre) and ``middle``."""
    scene = ws.Scene("payload", gravity=(0.0, 0.0, -gravity), dt=dt, steps=100)
    shape = ws.shapes.Box((-side / 2, -side / 2, 0.0), (side, side, length))
    bar = scene.add_body("bar", ws.mesh_shape(shape, mesh_size, name="payload_bar"),
                         ws.Material(young_modulus, poisson_ratio, density), element="corotational")
    scene.fix(bar, ws.InBox((-1.0, -1.0, length - 1e-9), (1.0, 1.0, 1.0)))
    weight = scene.add_rigid("weight", ws.obstacles.Box((0.0, 0.0, -side / 2), (side,) * 3), mass=mass,
                             velocity=(swing, 0.0, 0.0))
    scene.attach(bar, ws.InBox((-1.0, -1.0, -1.0), (1.0, 1.0, 1e-9)), weight, name="glue")
    scene.add_probe("bottom", (0.0, 0.0, 0.0))
    scene.add_probe("middle", (0.0, 0.0, length / 2))
    return scene


def stretch(length=0.05, side=0.01, young_modulus=1e5, density=100.0, mass=0.05, gravity=9.81) -> float:
    """How far (m) the bottom of the hanging bar comes down at rest (uniaxial, nu = 0)."""
    return (mass * length / (young_modulus * side * side) + density * length**2 / (2 * young_modulus)) * gravity
