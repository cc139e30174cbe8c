"""What a body gets when its scene chooses nothing: 10-node tetrahedra, which do not lock, so that
a bending body at silicone's Poisson ratio is not too stiff (linear tetrahedra are the opt-in
for speed)."""


import warpsoft as ws

E, NU, TIP = 1e6, 0.45, 0.01  # Pa, -, N
H = 0.005  # m: the mesh size


def tip_deflection(scene_module, **element) -> float:
    """Tip deflection (m) of the 10 x 1 x 1 cm cantilever under a small end load, built with
    ``add_body`` given ``element`` (or nothing)."""
    shape = ws.shapes.Box((0.0, -0.005, -0.005), (0.1, 0.01, 0.01))
    scene = ws.Scene("cantilever", static=True, steps=1)
    beam = scene.add_body("beam", ws.mesh_shape(shape, H, name="beam"), ws.Material(E, NU, 1000.0), **element)
    scene.fix(beam, ws.OnPlane((0.0, 0.0, 0.0), (1.0, 0.0, 0.0), tol=1e-9))
    scene.add_force(beam, ws.OnPlane((0.1, 0.0, 0.0), (1.0, 0.0, 0.0), tol=1e-9), (0.0, 0.0, -TIP))
    scene.add_probe("tip", (0.1, 0.0, 0.0))
    sim = ws.Simulator(scene, device="cpu", tolerance=1e-10, newton_iterations=30)
    sim.step()
    return -sim.probe_positions()["tip"][2]


def test_a_body_given_no_element_bends_as_beam_theory_at_nu_045(scene_module):
    """At nu 0.45 and a 5 mm mesh the default body is within 5 % of Timoshenko (10-node elements);
    linear tetrahedra on the same mesh, asked for by name, lock: more than 25 % too stiff."""
    body = ws.Scene("s").add_body("b", ws.box_grid((0, 0, 0), (1, 1, 1), (1, 1, 1)), ws.Material(E, NU, 1000.0))
    assert body.element == "quadratic" and body.mesh.quadratic is not None
    theory = scene_module("scenes/validation/cantilever.py").timoshenko_tip_deflection(
        poisson_ratio=NU, young_modulus=E, tip_force=TIP)
    assert abs(tip_deflection(scene_module) / theory - 1.0) < 0.05
    assert tip_deflection(scene_module, element="corotational") / theory < 0.75
