"""Incline: a soft block resting on a rigid plane tilted by ``angle`` under gravity (validation
scene). Coulomb friction ``mu`` holds it where ``tan(angle) < mu``; otherwise it slides down the
slope with the acceleration ``g (sin(angle) - mu cos(angle))`` (:func:`sliding_acceleration`).

The plane goes through the origin and rises along +x (its downhill direction is -x turned by
``angle``); the block sits on it, turned with it.
"""

import numpy as np

import warpsoft as ws

G = 9.81


def build(angle=20.0, mu=0.5, mesh_size=None, size=0.02, young_modulus=1e5, poisson_ratio=0.3, density=1000.0,
          dt=0.005):
    """Block of edge ``size`` (m) on a plane tilted by ``angle`` (degrees) about y; floor friction
    ``mu``; probe ``center`` at the middle of the block's bottom face."""
    turn = ws.rotation_about("y", -angle)  # the plane's frame: x up the slope, z its normal
    h = mesh_size if mesh_size is not None else size / 4
    mesh = ws.mesh_shape(ws.shapes.Box((-size / 2, -size / 2, 0.0), (size, size, size / 2)), h, name="block")
    scene = ws.Scene("incline", gravity=(0.0, 0.0, -G), dt=dt, steps=100)
    scene.add_body("block", mesh.transformed(rotation=turn), ws.Material(young_modulus, poisson_ratio, density),
                   element="corotational")
    scene.add_obstacle("slope", ws.obstacles.Floor((0.0, 0.0, 0.0), turn @ np.array([0.0, 0.0, 1.0])), mu=mu)
    scene.set_contacts(int(np.sum(np.abs(mesh.nodes[:, 2]) < 1e-9)) + 8)  # the bottom face's nodes, with room
    scene.add_probe("center", (0.0, 0.0, 0.0))
    return scene


def sliding_acceleration(angle=20.0, mu=0.5) -> float:
    """Down-slope acceleration (m/s^2) of a block on the incline: 0 when it sticks."""
    a = np.radians(angle)
    return max(0.0, G * (np.sin(a) - mu * np.cos(a)))


def downhill(angle=20.0) -> np.ndarray:
    """Unit vector down the slope."""
    return ws.rotation_about("y", -angle) @ np.array([-1.0, 0.0, 0.0])
