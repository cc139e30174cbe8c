"""Stack: two blocks of one body, one above the other, held apart by self-contact alone
(validation scene). The body is a single mesh of two pieces: the lower block stands on its
base (held in z), the upper one falls the ``gap`` onto it under gravity and comes to rest on
it (mass damping). A quarter is modelled, held sideways by the two symmetry planes. Without
friction the stress is uniaxial: at rest the top has come down by the gap plus
``2 rho g H^2 / E`` (:func:`settlement`): the lower block carries the upper one's weight and
its own, the upper its own. The self-contact carries the upper block's weight, ``rho g H w^2 / 4``
on the quarter.
"""

import numpy as np

import warpsoft as ws


def build(height=0.01, width=0.01, gap=0.001, young_modulus=2e4, poisson_ratio=0.3, density=1000.0, mu=0.0,
          divisions=3, contact_distance=None, dt=0.01, damping=20.0):
    """Quarter blocks ``[0, width/2]^2 x [0, height]`` and ``[0, width/2]^2 x [height + gap, 2 height
    + gap]`` (m), ``divisions`` cubes across the quarter (twice as many along the height);
    probes ``top`` (0, 0, 2 height + gap) and ``joint`` (0, 0, height); ``contact_distance`` (m,
    default 0.3 gap: surfaces closer than twice it at rest would count as neighbours)."""
    n = int(divisions)
    half = width / 2
    lower = ws.box_grid((0.0, 0.0, 0.0), (half, half, height), (n, n, 2 * n))
    upper = ws.box_grid((0.0, 0.0, height + gap), (half, half, 2 * height + gap), (n, n, 2 * n))
    mesh = ws.TetMesh(np.vstack([lower.nodes, upper.nodes]), np.vstack([lower.tets, upper.tets + len(lower.nodes)]),
                      name="stack")
    scene = ws.Scene("stack", gravity=(0.0, 0.0, -9.81), dt=dt, steps=60)
    body = scene.add_body("stack", mesh, ws.Material(young_modulus, poisson_ratio, density), element="corotational")
    scene.set_damping(damping, 0.0)
    scene.fix(body, ws.OnPlane((0.0, 0.0, 0.0), (1.0, 0.0, 0.0), tol=1e-9), axes="x")  # symmetry planes
    scene.fix(body, ws.OnPlane((0.0, 0.0, 0.0), (0.0, 1.0, 0.0), tol=1e-9), axes="y")
    scene.fix(body, ws.OnPlane((0.0, 0.0, 0.0), (0.0, 0.0, 1.0), tol=1e-9), axes="z")  # the base
    scene.add_self_contact(body, mu=mu, contact_distance=contact_distance if contact_distance else 0.3 * gap)
    scene.set_contacts(4 * (n + 1) ** 2)  # both faces' nodes, with room
    scene.add_probe("top", (0.0, 0.0, 2 * height + gap))
    scene.add_probe("joint", (0.0, 0.0, height))
    return scene


def settlement(height=0.01, gap=0.001, young_modulus=2e4, density=1000.0, g=9.81) -> float:
    """How far (m) the top comes down at rest: the gap, then ``1.5 rho g H^2 / E`` in the lower
    block (the upper's weight ``rho g H`` per area over ``H``, its own half of that) and ``0.5 rho
    g H^2 / E`` in the upper."""
    return gap + 2.0 * density * g * height**2 / young_modulus
