"""Pressurised thick sphere, one octant with symmetry planes (validation scene).

Lamé's solution gives the inner-wall displacement
``u(a) = p a^3 / (E (b^3 - a^3)) ((1 - 2 nu) a + (1 + nu) b^3 / (2 a^2))``; the octant's
cavity grows by ``((a + u)^3 - a^3) pi / 6`` (see ``lame_volume_growth``).
"""

import math

import warpsoft as ws


def build(inner_radius=0.01, outer_radius=0.02, young_modulus=1e5, poisson_ratio=0.3, pressure=100.0,
          mesh_size=None, element="corotational"):
    a, b = inner_radius, outer_radius
    h = mesh_size if mesh_size is not None else (b - a) / 6
    shape = (ws.Ball((0.0, 0.0, 0.0), b) & ws.shapes.Box((0.0, 0.0, 0.0), (b, b, b))) - ws.Ball((0.0, 0.0, 0.0), a)
    scene = ws.Scene("pressure_sphere", static=True, steps=3)
    shell = scene.add_body("shell", ws.mesh_shape(shape, h, name="shell"),
                           ws.Material(young_modulus, poisson_ratio, 1000.0), element=element)
    planes = [ws.OnPlane((0.0, 0.0, 0.0), n, tol=1e-9) for n in ((1, 0, 0), (0, 1, 0), (0, 0, 1))]
    for plane, axis in zip(planes, "xyz", strict=True):
        scene.fix(shell, plane, axes=axis)  # symmetry: no motion across the plane
    scene.add_cavity("cavity", shell, region=ws.InSphere((0.0, 0.0, 0.0), a, tol=1e-6 * a), mode="pressure",
                     value=pressure, symmetry_planes=planes)
    scene.add_probe("inner", (a, 0.0, 0.0))
    return scene


def lame_volume_growth(inner_radius=0.01, outer_radius=0.02, young_modulus=1e5, poisson_ratio=0.3, pressure=100.0):
    """Volume growth (m^3) of the octant's cavity by Lamé's thick-sphere solution."""
    a, b, nu = inner_radius, outer_radius, poisson_ratio
    u = pressure * a**3 / (young_modulus * (b**3 - a**3)) * ((1 - 2 * nu) * a + (1 + nu) * b**3 / (2 * a**2))
    return ((a + u) ** 3 - a**3) * math.pi / 6
