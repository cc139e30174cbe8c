"""Self-contact: a body's surface nodes against its own surface triangles (rows on four nodes),
checked against a uniaxial stack, the conservation of momentum, Coulomb's threshold, and a
winding-number measure of interpenetration that does not use the simulator's contact code."""

import numpy as np
import pytest

import warpsoft as ws
from warpsoft.errors import SceneError

from .geometry import penetration_depths

G = 9.81


def two_blocks(gap=0.001, side=0.01, height=0.01, n=2):
    """One mesh of two pieces: a block on ``[0, side]^2 x [0, height]`` and one ``gap`` above it."""
    lower = ws.box_grid((0.0, 0.0, 0.0), (side, side, height), (n, n, 2 * n))
    upper = ws.box_grid((0.0, 0.0, height + gap), (side, side, 2 * height + gap), (n, n, 2 * n))
    mesh = ws.TetMesh(np.vstack([lower.nodes, upper.nodes]), np.vstack([lower.tets, upper.tets + len(lower.nodes)]),
                      name="two blocks")
    return mesh, len(lower.nodes)


def face_gaps(rest: np.ndarray, q: np.ndarray, z_lower: float, z_upper: float) -> np.ndarray:
    """``z`` of the upper piece's bottom nodes less that of the lower piece's top nodes below
    them (m): the two faces' nodes, at ``z_lower`` and ``z_upper`` at rest, paired by ``(x, y)``."""
    lower, upper = (np.flatnonzero(np.isclose(rest[:, 2], z)) for z in (z_lower, z_upper))
    lower, upper = (ids[np.lexsort(rest[ids, :2].T)] for ids in (lower, upper))
    return q[upper, 2] - q[lower, 2]


def test_a_block_rests_on_a_block_of_the_same_body_as_a_uniaxial_stack(scene_module):
    """The upper piece falls on the lower one and rests there (``scenes/validation/stack.py``): the
    top comes down by the gap plus ``2 rho g H^2 / E``, the self-contact carries the upper
    piece's weight, no node passes the other face, and the contact forces, internal to the
    body, add up to nothing."""
    stack = scene_module("scenes/validation/stack.py")
    scene = stack.build()
    sim = ws.Simulator(scene, device="cpu")
    top0 = sim.probe_positions()["top"][2]
    for _ in range(60):
        stats = sim.step()
    assert not stats.warnings
    world = stats.worlds[0]
    settlement = stack.settlement()
    assert top0 - sim.probe_positions()["top"][2] == pytest.approx(settlement, abs=0.01 * (settlement - 0.001))
    weight = 1000.0 * G * 0.01 * 0.005**2  # the upper quarter block (N)
    assert world.contact_force == pytest.approx(weight, rel=1e-3)
    assert world.penetration < 1e-4 * (settlement - 0.001)
    body = scene.bodies[0].mesh
    q = sim.positions()
    tol = 1e-4 * (settlement - 0.001)  # 10 nm: a ten-thousandth of the compression
    assert face_gaps(body.nodes, q, 0.01, 0.011).min() >= -tol
    forces = sim.rows.forces(sim.gauss_seidel.lam.numpy())
    assert np.abs(forces.sum(axis=0)).max() < 1e-12 * weight
    upper = body.nodes[:, 2] > 0.0105
    assert forces[upper, 2].sum() == pytest.approx(weight, rel=1e-3)


def test_two_pieces_of_one_body_collide_and_keep_their_momentum():
    """In free flight, the upper piece thrown down onto the lower one: the contact forces are
    equal and opposite, so the body's momentum stays what it was through the impact; the pieces
    do not pass through each other, and the impact adds no kinetic energy."""
    mesh, n_lower = two_blocks()
    scene = ws.Scene("throw", dt=0.005)
    body = scene.add_body("blocks", mesh, ws.Material(2e4, 0.3, 1000.0), element="corotational")
    scene.add_self_contact(body, contact_distance=0.0003)
    scene.set_contacts(64)
    sim = ws.Simulator(scene, device="cpu")
    v = np.zeros((len(mesh.nodes), 3))
    v[n_lower:, 2] = -0.1
    sim.state.v.assign(v)
    mass = sim.model.mass.numpy()
    p0 = (mass[:, None] * v).sum(axis=0)
    energy0 = 0.5 * (mass * (v**2).sum(axis=1)).sum()
    met = False
    for _ in range(60):
        stats = sim.step()
        met |= stats.worlds[0].contacts > 0
        vel = sim.state.v.numpy()
        # (round-off over the 60 steps: 3e-13 with a factorization each step, 1.1e-12 with kept ones)
        assert np.allclose((mass[:, None] * vel).sum(axis=0), p0, rtol=0, atol=1e-11 * np.abs(p0).max())
        assert face_gaps(mesh.nodes, sim.positions(), 0.01, 0.011).min() >= -1e-7  # the step's linearization
    assert met
    assert 0.5 * (mass * (vel**2).sum(axis=1)).sum() <= energy0


@pytest.mark.parametrize("angle, mu, slides", [(20.0, 0.5, False), (35.0, 0.5, True)])
def test_friction_holds_the_upper_piece_below_coulombs_threshold(angle, mu, slides):
    """The lower piece clamped at its base, gravity tilted by ``angle``: the upper piece sticks
    on it when ``tan(angle) < mu`` (it moves only by the blocks' shear) and slides when above."""
    mesh, n_lower = two_blocks(gap=0.0003, n=2)
    a = np.radians(angle)
    scene = ws.Scene("tilted", gravity=(G * np.sin(a), 0.0, -G * np.cos(a)), dt=0.005)
    body = scene.add_body("blocks", mesh, ws.Material(5e4, 0.3, 1000.0), element="corotational")
    scene.set_damping(20.0, 0.0)
    scene.fix(body, ws.InBox((-1, -1, -1), (1, 1, 1e-6)))
    scene.add_self_contact(body, mu=mu, contact_distance=0.0001)
    scene.set_contacts(64)
    sim = ws.Simulator(scene, device="cpu")
    top = np.flatnonzero(np.isclose(mesh.nodes[:, 2], 0.0103))  # the upper piece's bottom
    bottom = np.flatnonzero(np.isclose(mesh.nodes[:, 2], 0.01))  # the lower piece's top

    def offset():  # how far (m, along x) the upper piece's bottom is ahead of the lower piece's top
        q = sim.positions()
        return q[top, 0].mean() - q[bottom, 0].mean()

    for _ in range(20):  # it falls the gap (drifting sideways in flight), lands and settles
        stats = sim.step()
    assert stats.worlds[0].contacts > 0
    landed = offset()
    for _ in range(30):
        stats = sim.step()
    slip = offset() - landed
    if slides:  # Coulomb: it slides down the tilt, at about g (sin - mu cos) t^2 / 2
        assert slip > 0.25 * G * (np.sin(a) - mu * np.cos(a)) * (30 * 0.005) ** 2 / 2
    else:
        assert abs(slip) < 1e-7
    assert stats.worlds[0].friction_force <= mu * stats.worlds[0].contact_force * (1 + 1e-9)


@pytest.mark.slow
def test_the_pneunet_chambers_meet_instead_of_passing_through(scene_module):
    """At 60 kPa the pneunet's chambers bulge across the 2 mm gaps between them. Without
    self-contact their walls pass through each other by about a millimetre; with it, no node of
    a gap's walls lies inside the body (a winding-number measure on the deformed surface)."""
    pneunet = scene_module("scenes/pneunet.py")
    depths = {}
    for self_contact in (False, True):  # linear elements at 3.5 mm, the setting this was measured on
        scene = pneunet.build(pressure=60e3, ramp_time=0.2, self_contact=self_contact, element="corotational",
                              mesh_size=0.0035)
        sim = ws.Simulator(scene, device="cpu")
        for _ in range(45):
            stats = sim.step()
        mesh = scene.bodies[0].mesh
        tris = mesh.surface()
        nodes = np.unique(tris)
        x, z = mesh.nodes[nodes, 0], mesh.nodes[nodes, 2]
        walls = nodes[(z > 0.0055) & np.isin(np.round(x, 6), np.round(gap_faces(), 6))]
        depths[self_contact] = penetration_depths(sim.positions(), tris, walls).max()
        if self_contact:
            assert stats.worlds[0].contacts > 0 and stats.worlds[0].penetration < 1e-6
    assert depths[False] > 5e-4
    assert depths[True] < 1e-5


def gap_faces(length=0.115, chambers=6, gap=0.002, base=0.01) -> list[float]:
    """The x (m) of the walls that face each other across the pneunet's gaps (its defaults)."""
    pitch = (length - base) / chambers
    faces = [base]
    for k in range(chambers):
        x0 = base + gap + k * pitch
        faces += [x0, x0 + pitch - gap]
    return faces


def test_self_contact_input_is_checked():
    mesh, _ = two_blocks()
    scene = ws.Scene("bad")
    body = scene.add_body("b", mesh, ws.Material(1e5, 0.3, 1000.0), element="corotational")
    other = ws.Scene("other").add_body("c", mesh, ws.Material(1e5, 0.3, 1000.0), element="corotational")
    with pytest.raises(SceneError, match="friction coefficient mu must be >= 0"):
        scene.add_self_contact(body, mu=-0.1)
    with pytest.raises(SceneError, match="contact_distance must be > 0 m"):
        scene.add_self_contact(body, contact_distance=0.0)
    with pytest.raises(SceneError, match="not in this scene"):
        scene.add_self_contact(other)
    scene.add_self_contact(body, mu=0.3)
    with pytest.raises(SceneError, match="already touches itself"):
        scene.add_self_contact(body)
