"""Rigid bodies: mass properties, free fall, resting on the floor, on a soft body and on another
rigid body, and the Grasper holding or dropping its cube by friction."""

import numpy as np
import pytest

import warpsoft as ws
from warpsoft.scene import obstacles as ob
from warpsoft.scene.rigid import mass_properties

from .geometry import point_triangle_distance, winding_numbers

G = 9.81


def box_mesh(center, size) -> ob.Mesh:
    """A closed box of triangles, normals out."""
    c, h = np.asarray(center), 0.5 * np.asarray(size)
    v = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]) * h + c
    faces = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    tris = [t for a, b, cc, d in faces for t in ((a, b, cc), (a, cc, d))]
    return ob.Mesh(v, tris)


def test_mass_properties_of_solids():
    m, c, inertia = mass_properties(ob.Box((0.1, 0.2, 0.3), (0.02, 0.04, 0.06)), 1000.0)
    assert m == pytest.approx(0.048)
    assert np.allclose(inertia, m / 12 * np.diag([0.04**2 + 0.06**2, 0.02**2 + 0.06**2, 0.02**2 + 0.04**2]))
    mm, cm, im = mass_properties(box_mesh((0.1, 0.2, 0.3), (0.02, 0.04, 0.06)), 1000.0)  # the same box as triangles
    assert mm == pytest.approx(m) and np.allclose(cm, c) and np.allclose(im, inertia, rtol=1e-12, atol=1e-15)
    m, _, inertia = mass_properties(ob.Ball((0, 0, 0), 0.01), 1000.0)
    assert inertia[0, 0] == pytest.approx(0.4 * m * 1e-4)
    # a capsule is a cylinder and a ball: its axial inertia adds up
    r, length = 0.01, 0.04
    m, c, inertia = mass_properties(ob.Capsule((0, 0, 0), (0, 0, length), r), 1.0)
    mc, _, ic = mass_properties(ob.Cylinder((0, 0, 0), (0, 0, length), r), 1.0)
    mb, _, ib = mass_properties(ob.Ball((0, 0, 0), r), 1.0)
    assert m == pytest.approx(mc + mb) and np.allclose(c, [0, 0, length / 2])
    assert inertia[2, 2] == pytest.approx(ic[2, 2] + ib[2, 2])
    assert inertia[0, 0] > ic[0, 0] + ib[0, 0]  # its ends sit away from the middle


def drop_scene(drop=0.05, mu=0.5, soft_floor=False):
    scene = ws.Scene("drop", gravity=(0, 0, -G), dt=0.01)
    if soft_floor:  # a soft slab on the floor, held at its bottom, the cube on it
        slab = scene.add_body("slab", ws.mesh_shape(ws.shapes.Box((-0.03, -0.03, 0), (0.06, 0.06, 0.01)), 0.005),
                              ws.Material(5e4, 0.3, 1000.0), element="corotational")
        scene.fix(slab, ws.InBox((-1, -1, -1), (1, 1, 1e-4)))
        scene.set_damping(1.0, 0.0)
        base = 0.01
    else:  # a soft pad aside (a scene has a soft body), held above the floor
        pad = scene.add_body("pad", ws.mesh_shape(ws.shapes.Box((0.1, 0, 0.01), (0.02, 0.02, 0.01)), 0.005),
                             ws.Material(1e5, 0.3, 1000.0), element="corotational")
        scene.fix(pad, ws.InBox((-1, -1, -1), (1, 1, 0.0101)))
        base = 0.0
    if not soft_floor:  # (the slab is held: its bottom needs no floor)
        scene.add_obstacle("floor", ws.obstacles.Floor(), mu=mu)
    scene.add_rigid("cube", ws.obstacles.Box((0, 0, base + 0.0125 + drop), (0.025,) * 3), density=1000.0, mu=mu)
    scene.set_contacts(128)
    return scene


def test_a_cube_falls_and_rests_on_the_floor_without_drift():
    """Free fall: implicit Euler's ``z_n = z_0 - g h^2 n (n + 1) / 2`` to round-off (within
    ``g h t / 2`` of ``g t^2 / 2``); then it lands flat, at its half size, and stays there with
    no drift in position or orientation, its contacts carrying its weight."""
    sim = ws.Simulator(drop_scene(), device="cpu")
    h, z0 = 0.01, 0.0625
    heights = []
    for _ in range(60):
        stats = sim.step()
        rotation, p = sim.rigid_poses()["cube"]
        heights.append(p[2])
    n = np.arange(1, 10)  # in the air (the 10th step would end 4 mm inside the floor: it lands)
    assert np.allclose(heights[:9], z0 - G * h * h * n * (n + 1) / 2, atol=1e-14, rtol=0)
    assert np.all(np.abs(np.array(heights[:9]) - (z0 - G * (n * h) ** 2 / 2)) <= G * h * (n * h) / 2 + 1e-14)
    assert heights[-1] == pytest.approx(0.0125, abs=1e-9)
    assert np.ptp(heights[-20:]) < 1e-9 and np.allclose(rotation, np.eye(3), atol=1e-9)
    assert stats.worlds[0].contacts >= 4
    points, forces = sim.constraint_geometry()["contacts"]
    weight = sim.model.rigid[0][1].mass * G
    assert forces[:, 2].sum() == pytest.approx(weight, rel=1e-6)  # the floor carries the cube
    assert np.all(points[:, 2] > -1e-9)  # none of its points below the floor


def test_a_cube_rests_on_a_soft_slab():
    """The slab carries the cube's weight (the contact forces on its nodes add up to it), through
    both kinds of contact: its surface nodes against the cube (pushed down) and the cube's points
    against its triangles (pushed up); the cube sinks by the slab's compression, tens of
    micrometres, and tilts by no more than that compression across its width (the slab's mesh
    is not symmetric)."""
    sim = ws.Simulator(drop_scene(drop=0.0005, soft_floor=True), device="cpu")
    for _ in range(60):
        sim.step()
    rotation, p = sim.rigid_poses()["cube"]
    weight = sim.model.rigid[0][1].mass * G
    on_nodes = sim.rows.forces(sim.gauss_seidel.lam.numpy())
    assert on_nodes[:, 2].sum() == pytest.approx(-weight, rel=1e-4)
    points, forces = sim.constraint_geometry()["contacts"]  # the force on each contact's point
    assert forces[:, 2].min() < -1e-3 * weight and forces[:, 2].max() > 1e-3 * weight  # nodes down, cube points up
    sink = 0.0225 - p[2]
    assert 0.0 < sink < 1e-4
    tilt = np.arccos(np.clip((np.trace(rotation) - 1) / 2, -1, 1))
    assert tilt < 2 * sink / 0.025


def test_a_small_cube_rests_between_the_nodes_of_a_coarse_slab(scene_module):
    """Rigid points against soft triangles (``scenes/validation/pebble.py``): a steel cube
    smaller than the slab's elements, set over the middle of a surface triangle, where no slab
    node comes within contact distance of it (the slab's nodes alone could not hold it). Its
    corners and edges rest on the triangle: none of its points enters the slab, the forces on
    the slab's nodes carry its weight (equal and opposite to those on the cube), and it stays
    there without drift."""
    scene = scene_module("scenes/validation/pebble.py").build()
    mesh, cube = scene.bodies[0].mesh, scene.rigid_bodies[0]
    side = 0.003
    top = [t for t in mesh.surface() if np.allclose(mesh.nodes[t, 2], 0.01)]
    middle = cube.center - [0.0, 0.0, 0.5 * side + 0.0002]
    reach = 0.25 * np.mean(np.linalg.norm(mesh.nodes[top] - np.roll(mesh.nodes[top], 1, axis=1), axis=2))
    assert cube.shape.distance(mesh.nodes).min() > 1.2 * reach  # no slab node can reach the cube
    sim = ws.Simulator(scene, device="cpu")
    heights = []
    for _ in range(40):
        stats = sim.step()
        heights.append(sim.rigid_poses()["cube"][1][2])
    assert not stats.warnings and stats.worlds[0].contacts >= 4
    rotation, center = sim.rigid_poses()["cube"]
    offsets = 0.5 * side * np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)])
    corners = center + offsets @ rotation.T
    q, surface = sim.state.positions(), mesh.surface()
    tris = q[surface]
    depth = [point_triangle_distance(np.repeat(c[None], len(surface), axis=0), *tris.transpose(1, 0, 2)).min()
             for c in corners]
    inside = winding_numbers(corners, tris) > 0.5
    assert np.max(np.where(inside, depth, 0.0)) < 1e-12  # the bottom corners on the surface, none in
    sink = middle[2] + 0.5 * side - center[2]
    assert 0.0 <= sink < 2e-5  # the slab's surface gives by micrometres under 2 mN
    weight = cube.mass * G
    forces = sim.rows.forces(sim.gauss_seidel.lam.numpy())
    assert forces[:, 2].sum() == pytest.approx(-weight, rel=1e-6)
    assert np.abs(forces[:, :2].sum(axis=0)).max() < 1e-6 * weight
    assert np.ptp(heights[-10:]) < 1e-9


def test_a_cube_rests_on_a_cube():
    """Rigid on rigid: a cube dropped on another cube stays on it, its points on the lower one's
    top face; the lower one carries both weights to the floor."""
    scene = drop_scene(drop=0.0)
    scene.add_rigid("top", ws.obstacles.Box((0.003, 0.0, 0.025 + 0.0101), (0.02,) * 3), density=1000.0, mu=0.5)
    sim = ws.Simulator(scene, device="cpu")
    for _ in range(60):
        sim.step()
    poses = sim.rigid_poses()
    assert poses["top"][1][2] == pytest.approx(0.025 + 0.01, abs=1e-6)
    assert poses["cube"][1][2] == pytest.approx(0.0125, abs=1e-6)
    assert np.allclose(poses["top"][0], np.eye(3), atol=1e-6)
    points, forces = sim.constraint_geometry()["contacts"]
    floor = np.abs(points[:, 2]) < 1e-6
    total = sum(rb.mass for _, rb in sim.model.rigid) * G
    assert forces[floor, 2].sum() == pytest.approx(total, rel=1e-5)


@pytest.mark.parametrize("mu, lifted", [(0.8, True), (0.05, False)])
def test_the_grasper_lifts_its_cube_only_with_friction(scene_module, mu, lifted):
    """Three fingers squeeze the cube and the palm rises 20 mm: with mu = 0.8 the cube rises
    with it (friction holds its weight), with mu = 0.05 it stays on the floor; the fingers'
    nodes never enter it."""
    grasper = scene_module("scenes/grasper.py")
    sim = ws.Simulator(grasper.build(mu=mu, dt=0.02), device="cpu")
    for _ in range(int(2.5 / 0.02)):  # close, lift, hold
        sim.step()
    _, p = sim.rigid_poses()["cube"]
    rise = p[2] - 0.015
    if lifted:
        assert rise > 0.018
    else:
        assert rise < 0.001
    cube = sim.model.scenes[0].rigid_bodies[0]
    rotation, center = sim.rigid_poses()["cube"]
    inside = cube.shape.moved(rotation, center - rotation @ cube.center).distance(sim.state.positions())
    assert inside.min() > -2e-4  # no finger node more than 0.2 mm inside the cube


def test_bad_rigid_bodies_are_named():
    scene = ws.Scene("s", gravity=(0, 0, -G))
    with pytest.raises(ws.SceneError, match="rigid body 'c': give its density"):
        scene.add_rigid("c", ob.Box((0, 0, 0), (1, 1, 1)))
    with pytest.raises(ws.SceneError, match="rigid body 'c': mass must be a finite number > 0"):
        scene.add_rigid("c", ob.Box((0, 0, 0), (1, 1, 1)), mass=-1.0)
    with pytest.raises(ws.SceneError, match="rigid body 'c': its solid must be"):
        scene.add_rigid("c", ob.Floor(), mass=1.0)
    with pytest.raises(ws.SceneError, match="friction coefficient mu must be a finite number >= 0"):
        scene.add_rigid("c", ob.Ball((0, 0, 0), 0.1), mass=1.0, mu=-0.1)
    with pytest.raises(ws.SceneError, match="velocity must be 3 finite numbers"):
        scene.add_rigid("c", ob.Ball((0, 0, 0), 0.1), mass=1.0, velocity=(0, np.nan, 0))
    with pytest.raises(ws.SceneError, match="inertia must be 3 positive numbers"):
        scene.add_rigid("c", ob.Ball((0, 0, 0), 0.1), mass=1.0, inertia=(1.0, -1.0, 1.0))
    open_mesh = ob.Mesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]])
    with pytest.raises(ws.SceneError, match="rigid body 'c': a rigid body's Mesh must be closed"):
        scene.add_rigid("c", open_mesh, mass=1.0)
    static = drop_scene()
    static.static = True
    with pytest.raises(ws.SceneError, match="rigid body 'cube' needs a dynamic scene"):
        ws.Simulator(static, device="cpu")


def test_a_dropped_cube_to_usd_and_report(tmp_path):
    """The run writes the cube as a prim whose transform follows it, and its pose per step in the
    report: the transform carries the declared cube's centre to the reported centre."""
    import json

    from pxr import Usd, UsdGeom

    from warpsoft.io.runner import run

    usd, report = tmp_path / "drop.usda", tmp_path / "drop.json"
    run(drop_scene(drop=0.01), steps=6, device="cpu", usd=usd, report=report)
    positions = json.loads(report.read_text())["rigid_bodies"]["cube"]["position"]
    assert len(positions) == 6 and positions[-1][2] < 0.0225
    stage = Usd.Stage.Open(str(usd))
    op = UsdGeom.Xformable(stage.GetPrimAtPath("/World/rigid_bodies/cube")).GetOrderedXformOps()[0]
    assert len(op.GetTimeSamples()) == 7  # the initial state, then one per step
    moved = np.array(op.Get(6.0)).T @ np.array([0.0, 0.0, 0.0225, 1.0])  # the declared centre, carried
    assert np.allclose(moved[:3], positions[-1], atol=1e-12)
    assert stage.GetPrimAtPath("/World/rigid_bodies/cube/shape").IsA(UsdGeom.Cube)


def test_gauss_seidel_on_the_host_equals_the_device_one():
    """On CUDA, worlds with contacts sweep on the host between two graphs; forced here on the CPU
    device, the same sweeps give the same motion (a cube landing with friction)."""
    device, host = (ws.Simulator(drop_scene(drop=0.005), device="cpu", lazy_contacts=False) for _ in range(2))
    host.host_gauss_seidel = True
    calls, sweep = [], host.gauss_seidel.solve_host
    host.gauss_seidel.solve_host = lambda arrays: (calls.append(1), sweep(arrays))
    for _ in range(15):
        a, b = device.step(), host.step()
    assert len(calls) == 15
    assert b.worlds[0].contacts > 0 and b.worlds[0].resolve_iterations == a.worlds[0].resolve_iterations
    assert np.array_equal(device.state.positions(), host.state.positions())
    assert np.array_equal(device.rigid_poses()["cube"][1], host.rigid_poses()["cube"][1])


def test_two_worlds_of_one_scene_drop_their_own_cubes():
    """The same scene twice in one model: each world's cube lands on its own floor as alone."""
    alone = ws.Simulator(drop_scene(drop=0.005), device="cpu")
    scene = drop_scene(drop=0.005)
    both = ws.Simulator(ws.finalize([scene, scene], "cpu"))
    for _ in range(12):
        alone.step()
        both.step()
    for w in range(2):
        assert np.allclose(both.rigid_poses(w)["cube"][1], alone.rigid_poses()["cube"][1], atol=1e-12)


@pytest.mark.slow  # (800 steps: 13 s)
def test_a_frictionless_cube_on_a_coarse_damped_slab_comes_to_rest():
    """A 10 g frictionless cube set on a damped slab one 10 mm element thick: the slab's coarse,
    dented surface pushes it sideways (its contacts' normals tilt by the dents) into a shallow
    well. The scene's Rayleigh mass damping acts on every body the step integrates, the cube
    too, as SOFA's implicit Euler does; it used to act on the slab alone, and the cube, free to
    slide and turn, kept swinging: 2.5 degrees about the vertical and 1 mm across in its last 2 s
    of 8. Now it settles, and the total energy (slab and cube) falls: a step that raises it by
    more than 1e-8 J fails. Before, each step where one of the cube's points came over a
    triangle's corner gained ~5.4e-8 J: its row was handed to the corner node's row against the
    cube, which measures the gap along another normal (17 such rises in 800 steps, 1.6 % of what
    the damping took)."""
    scene = ws.Scene("rest", gravity=(0, 0, -G), dt=0.01)
    slab = scene.add_body("slab", ws.mesh_shape(ws.shapes.Box((-0.03, -0.03, 0), (0.06, 0.06, 0.01)), 0.01),
                          ws.Material(5e4, 0.3, 1000.0), element="corotational")
    scene.fix(slab, ws.InBox((-1, -1, -1), (1, 1, 1e-4)))
    scene.set_damping(1.0, 0.0)
    scene.add_rigid("cube", ws.obstacles.Box((0, 0, 0.0230), (0.025,) * 3), density=640.0, mu=0.0)
    scene.set_contacts(128)
    sim = ws.Simulator(scene, device="cpu")
    mass, inertia = sim.model.rigid[0][1].mass, sim.model.rigid_inertia.numpy()[0]

    def total_energy() -> float:
        s = sim.state
        v, w, p = s.body_v.numpy()[0], s.body_w.numpy()[0], s.body_p.numpy()[0]
        r = sim.rigid_poses()["cube"][0]
        return sim.energy()["total"] + 0.5 * mass * v @ v + 0.5 * w @ (r @ inertia @ r.T) @ w + mass * G * p[2]

    energy, place, yaw = [], [], []
    for _ in range(800):
        sim.step()
        energy.append(total_energy())
        rotation, p = sim.rigid_poses()["cube"]
        place.append(p[:2].copy())
        yaw.append(np.degrees(np.arctan2(rotation[1, 0], rotation[0, 0])))
    rises = np.diff(energy)[np.diff(energy) > 0.0]
    assert energy[-1] < energy[0] and rises.max() < 1e-8 and rises.sum() < 1e-3 * (energy[0] - energy[-1])
    place, yaw = np.array(place[-200:]), np.array(yaw[-200:])  # the last 2 s
    assert np.ptp(place, axis=0).max() < 2e-4 and np.ptp(yaw) < 1.0
