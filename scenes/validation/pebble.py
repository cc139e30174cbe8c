"""Pebble: a small rigid cube on a coarse soft slab (validation scene for rigid points against
soft triangles). The cube is smaller than the slab's elements and set over the middle of a top
surface triangle, where no node of the slab comes within contact distance of it: only its own
points meeting the slab's triangles hold it up (the slab's nodes alone would let it fall
through). At rest its corners sit on the surface and the slab carries its weight.

With friction (``mu > 0``), its first eight steps stop at the Gauss-Seidel's sweep cap and say
so: the cube's nine bottom points all bear on one triangle, and their normal and friction rows
span only three directions each (forces that are not unique, which the sweeps converge to
slowly); the motion does not depend on it. Frictionless, they take 3 to 23 sweeps.
"""

import numpy as np

import warpsoft as ws


def build(side=0.003, density=8000.0, mu=0.5, drop=0.0002, mesh_size=0.01, young_modulus=5e4, poisson_ratio=0.3,
          gravity=9.81, dt=0.01):
    """A slab 60 x 60 x 10 mm (m) on z in ``[0, 0.01]``, held at its bottom, meshed at
    ``mesh_size``; a cube of ``side`` (m) and ``density`` (kg/m^3), friction ``mu``, ``drop``
    (m) above the middle of the top triangle nearest to the slab's axis."""
    scene = ws.Scene("pebble", gravity=(0.0, 0.0, -gravity), dt=dt, steps=40)
    shape = ws.shapes.Box((-0.03, -0.03, 0.0), (0.06, 0.06, 0.01))
    slab = scene.add_body("slab", ws.mesh_shape(shape, mesh_size, name="pebble_slab"),
                          ws.Material(young_modulus, poisson_ratio, 1000.0), element="corotational")
    scene.fix(slab, ws.InBox((-1.0, -1.0, -1.0), (1.0, 1.0, 1e-4)))
    scene.set_damping(1.0, 0.0)
    mesh = slab.mesh
    top = [t for t in mesh.surface() if np.allclose(mesh.nodes[t, 2], 0.01)]
    middle = mesh.nodes[min(top, key=lambda t: np.linalg.norm(mesh.nodes[t, :2].mean(axis=0)))].mean(axis=0)
    scene.add_rigid("cube", ws.obstacles.Box(middle + [0.0, 0.0, 0.5 * side + drop], (side,) * 3),
                    density=density, mu=mu)
    scene.set_contacts(64)
    return scene
