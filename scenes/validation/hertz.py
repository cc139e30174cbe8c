"""Hertz: a soft sphere pressed on a rigid plane (validation scene).

Hertz's solution for a sphere of radius ``R`` on a rigid plane under a force ``F``: a contact
disc of radius ``a`` with ``a^3 = 3 F R / (4 E*)``, ``E* = E / (1 - nu^2)``, and an approach of
the sphere's centre ``d = a^2 / R`` (:func:`contact_radius`, :func:`approach`).

The model is a sphere squeezed between two planes, reduced by its symmetries: a quarter of its
lower half, held on the symmetry planes x = 0 and y = 0 and on its equator (z = R, which stays
flat and, by symmetry, still: the centre's plane). The floor is raised into it by Hertz's approach
for ``load``: the step is displacement-driven and quasi-static, and what it measures is the force
the floor then carries (against ``load``) and the contact patch (against ``a``).
"""

import math

import numpy as np

import warpsoft as ws


def build(radius=0.01, young_modulus=1e5, poisson_ratio=0.3, load=0.05, mesh_size=None, fine_size=None):
    """Quarter of the lower half of a sphere of ``radius`` (m) centred at (0, 0, radius): its pole
    at the origin, and the floor at ``z = approach(load)``. ``mesh_size`` (m): the elements away
    from the contact (default radius / 5); ``fine_size``: within twice the contact radius of the
    pole (default a / 4, with ``a = contact_radius(load)``). Probe ``pole`` at the origin."""
    a = contact_radius(radius, young_modulus, poisson_ratio, load)
    d = approach(radius, young_modulus, poisson_ratio, load)
    h = mesh_size if mesh_size is not None else radius / 5
    fine = fine_size if fine_size is not None else a / 4
    shape = ws.shapes.Ball((0.0, 0.0, radius), radius) & ws.shapes.Box((0.0, 0.0, 0.0), (radius, radius, radius))
    mesh = ws.mesh_shape(shape, h, name="hemisphere", refine=ws.shapes.Refine((0.0, 0.0, 0.0), fine, 2 * a))
    scene = ws.Scene("hertz", static=True, steps=1)
    ball = scene.add_body("sphere", mesh, ws.Material(young_modulus, poisson_ratio, 1000.0), element="corotational")
    scene.fix(ball, ws.OnPlane((0.0, 0.0, 0.0), (1.0, 0.0, 0.0), tol=1e-9), axes="x")  # symmetry planes
    scene.fix(ball, ws.OnPlane((0.0, 0.0, 0.0), (0.0, 1.0, 0.0), tol=1e-9), axes="y")
    scene.fix(ball, ws.OnPlane((0.0, 0.0, radius), (0.0, 0.0, 1.0), tol=1e-9), axes="z")  # the equator
    # the floor takes every node that the approach, or the patch's growth, can bring to it
    reach = 2.0 * d
    near = int(np.sum(mesh.nodes[:, 2] < d + reach))
    scene.add_obstacle("floor", ws.obstacles.Floor((0.0, 0.0, d), (0.0, 0.0, 1.0)), contact_distance=reach)
    scene.set_contacts(near + 16)
    scene.add_probe("pole", (0.0, 0.0, 0.0))
    return scene


def effective_modulus(young_modulus=1e5, poisson_ratio=0.3) -> float:
    """``E* = E / (1 - nu^2)`` (Pa): a sphere against a rigid plane."""
    return young_modulus / (1.0 - poisson_ratio**2)


def contact_radius(radius=0.01, young_modulus=1e5, poisson_ratio=0.3, load=0.05) -> float:
    """Hertz's contact radius ``a = (3 F R / (4 E*))^(1/3)`` (m)."""
    return (3.0 * load * radius / (4.0 * effective_modulus(young_modulus, poisson_ratio))) ** (1.0 / 3.0)


def approach(radius=0.01, young_modulus=1e5, poisson_ratio=0.3, load=0.05) -> float:
    """Hertz's approach of the sphere's centre to the plane, ``a^2 / R`` (m)."""
    return contact_radius(radius, young_modulus, poisson_ratio, load) ** 2 / radius


def patch_radius(points: np.ndarray, forces: np.ndarray) -> float:
    """The contact radius (m) that fits measured nodal contact forces ``forces`` ``(k,)`` (N) at
    ``points`` ``(k, 3)`` (m), on the axis x = y = 0: under Hertz's pressure
    ``p0 sqrt(1 - r^2 / a^2)`` the force-weighted mean of ``r^2`` is ``2 a^2 / 5``."""
    r2 = points[:, 0] ** 2 + points[:, 1] ** 2
    return math.sqrt(2.5 * float(np.sum(forces * r2)) / float(np.sum(forces)))
