"""Column: a square block standing on a rigid floor at z = 0, held by contact alone
(validation scene). Its quarter is modelled, held sideways by its two symmetry planes;
``load`` (N, the whole column's) presses down on its top face. Frictionless (``mu = 0``),
nothing holds the bottom sideways, so the stress is uniaxial: the top comes down by
``load height / (E width^2)`` (:func:`uniaxial_shortening`) and the bottom spreads by the
Poisson ratio. With a large ``mu`` the bottom does not slide: probe ``bottom_corner``.

The step is dynamic (a quasi-static body held by contact alone has no stiffness against lifting
off): the load is applied at once and mass damping brings the column to rest.
"""

import warpsoft as ws


def build(height=0.03, width=0.02, young_modulus=1e5, poisson_ratio=0.3, load=0.2, mu=0.0, mesh_size=None,
          density=1000.0, dt=0.01, damping=20.0):
    """Quarter column ``[0, width/2]^2 x [0, height]`` (m); probe ``top`` at the top face's centre
    (0, 0, height), probe ``bottom_corner`` at (width/2, width/2, 0); ``load`` (N) over the whole
    top face (a quarter of it on the model's); ``mu`` the floor's friction coefficient."""
    h = mesh_size if mesh_size is not None else width / 8
    shape = ws.shapes.Box((0.0, 0.0, 0.0), (width / 2, width / 2, height))
    scene = ws.Scene("column", dt=dt, steps=80)
    column = scene.add_body("column", ws.mesh_shape(shape, h, name="column"),
                            ws.Material(young_modulus, poisson_ratio, density), element="corotational")
    scene.set_damping(damping, 0.0)
    scene.fix(column, ws.OnPlane((0.0, 0.0, 0.0), (1.0, 0.0, 0.0), tol=1e-9), axes="x")  # symmetry planes
    scene.fix(column, ws.OnPlane((0.0, 0.0, 0.0), (0.0, 1.0, 0.0), tol=1e-9), axes="y")
    scene.add_force(column, ws.OnPlane((0.0, 0.0, height), (0.0, 0.0, 1.0), tol=1e-9), (0.0, 0.0, -load / 4),
                    name="load")
    scene.add_obstacle("floor", ws.obstacles.Floor((0.0, 0.0, 0.0), (0.0, 0.0, 1.0)), mu=mu)
    scene.set_contacts(2 * round(width / (2 * h) + 1) ** 2)  # the bottom face's nodes, with room
    scene.add_probe("top", (0.0, 0.0, height))
    scene.add_probe("bottom_corner", (width / 2, width / 2, 0.0))
    return scene


def uniaxial_shortening(height=0.03, width=0.02, young_modulus=1e5, load=0.2) -> float:
    """How far (m) the top of a frictionless column comes down under ``load``: ``F H / (E A)``."""
    return load * height / (young_modulus * width * width)
