"""Cantilever beam: clamped at x = 0, tip force and/or gravity along -z (validation scene).

Timoshenko beam theory gives the tip deflection of a small load
``P L^3 / (3 E I) + P L / (kappa G A)`` (see ``timoshenko_tip_deflection``).
"""

import warpsoft as ws


def build(length=0.1, width=0.01, height=0.01, young_modulus=1e6, poisson_ratio=0.3, density=1000.0,
          gravity=0.0, tip_force=0.0, mesh_size=None, static=True, dt=0.01, element="corotational",
          integrator="implicit_euler", refine=0):
    """Beam along +x from 0 to ``length`` (m), section ``width`` (y) x ``height`` (z) centred on
    the axis; ``tip_force`` (N) along -z over the end face; probe ``tip`` at (length, 0, 0).
    ``element``: "corotational" (linear tetrahedra), "quadratic" (10-node ones on the same mesh) or
    "neohookean" (linear tetrahedra of stable Neo-Hookean material). ``integrator``: the dynamic
    step's, "implicit_euler" or "trapezoidal". ``refine``: the mesh split that many times, each
    element into eight (nested refinement, for convergence studies)."""
    h = mesh_size if mesh_size is not None else min(width, height) / 6  # within 10% of beam theory
    shape = ws.shapes.Box((0.0, -width / 2, -height / 2), (length, width, height))
    scene = ws.Scene("cantilever", gravity=(0.0, 0.0, -gravity), dt=dt, static=static, steps=1 if static else 100,
                     integrator=integrator)
    beam = scene.add_body("beam", ws.mesh_shape(shape, h, name="beam").refined(refine),
                          ws.Material(young_modulus, poisson_ratio, density), element=element)
    scene.fix(beam, ws.OnPlane((0.0, 0.0, 0.0), (1.0, 0.0, 0.0), tol=1e-9))
    if tip_force:
        scene.add_force(beam, ws.OnPlane((length, 0.0, 0.0), (1.0, 0.0, 0.0), tol=1e-9), (0.0, 0.0, -tip_force),
                        name="tip_force")
    scene.add_probe("tip", (length, 0.0, 0.0))
    return scene


def timoshenko_tip_deflection(length=0.1, width=0.01, height=0.01, young_modulus=1e6, poisson_ratio=0.3,
                              tip_force=1.0):
    """Tip deflection (m) of a cantilever under an end load, bending plus shear (Cowper's kappa)."""
    inertia = width * height**3 / 12.0
    shear_modulus = young_modulus / (2.0 * (1.0 + poisson_ratio))
    kappa = 10.0 * (1.0 + poisson_ratio) / (12.0 + 11.0 * poisson_ratio)
    return tip_force * length**3 / (3.0 * young_modulus * inertia) + tip_force * length / (
        kappa * shear_modulus * width * height)
