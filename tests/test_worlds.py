"""Worlds: a model of several different scenes steps each of them exactly as it steps alone."""

import numpy as np
import pytest

import warpsoft as ws
from warpsoft.stats import WorldRecord, Worlds, WorldStats


def static_trio(scene_module):
    """Three different quasi-static scenes: cables on a bar, a pressurized cavity, a loaded beam."""
    return [scene_module("scenes/validation/cable_bar.py").build(cable_displacement=0.0002, mesh_size=0.005),
            scene_module("scenes/validation/pressure_sphere.py").build(mesh_size=0.005),
            scene_module("scenes/validation/cantilever.py").build(tip_force=-0.05, mesh_size=0.005)]


def dynamic_trio(scene_module):
    """Three different dynamic robots under gravity: an inverse Diamond, an inverse Trunk and a
    Diamond driven directly by its cables, each its own mesh."""
    diamond, trunk = scene_module("scenes/diamond.py"), scene_module("scenes/trunk.py")
    return [diamond.build(mesh_size=0.02, mode="inverse", circle_period=0.2),
            trunk.build(mesh_size=0.014, rayleigh_stiffness=0.1, period=0.2),
            diamond.build(mesh_size=0.017, cable_displacements=(0.004, 0.0, 0.002, 0.0), ramp_time=0.06)]


def run_alone_and_together(scenes, steps, **options):
    """Each scene alone, then all as one model. With ``pcg``, both take block CG (by default a
    model of one world takes column CG, and it would then match its batch to the CG tolerance
    only, not to round-off)."""
    if options.get("solver") == "pcg":
        options["block_cg"] = True
    alone = []
    for s in scenes:
        sim = ws.Simulator(s, **options)
        alone.append([sim.step() for _ in range(steps)])
        alone[-1].append(sim.positions())
    sim = ws.Simulator(ws.finalize(scenes), **options)
    together = [sim.step() for _ in range(steps)]
    return sim, alone, together


def assert_same(sim, alone, together, tol):
    m = sim.model
    for w, history in enumerate(alone):
        q_alone, q_world = history[-1], sim.positions(w)
        rest = m.rest_np[m.world_nodes(w)]
        scale = np.abs(q_alone - rest).max()
        assert scale > 1e-6  # the world did move
        assert np.abs(q_world - q_alone).max() <= tol * scale
        for k, stats in enumerate(history[:-1]):
            mine = together[k].worlds[w]
            assert mine.actuator_delta.keys() == stats.actuator_delta.keys()
            for name, v in stats.actuator_delta.items():
                assert mine.actuator_delta[name] == pytest.approx(v, rel=tol, abs=tol * 1e-3)
            for name, v in stats.actuator_lambda.items():
                assert mine.actuator_lambda[name] == pytest.approx(v, rel=1e3 * tol, abs=1e-9)
            for name, v in stats.effectors.items():
                assert np.abs(mine.effectors[name] - v).max() <= tol * scale
            assert mine.qp_status == stats.qp_status


@pytest.mark.parametrize("solver, preconditioner", [("direct", "auto"), ("pcg", "auto"), ("pcg", "blocks")])
def test_three_static_worlds_step_as_alone(scene_module, solver, preconditioner):
    scenes = static_trio(scene_module)
    sim, alone, together = run_alone_and_together(scenes, 3, solver=solver, tolerance=1e-10,
                                                  preconditioner=preconditioner)
    assert sim.model.num_worlds == 3 and list(sim.rows.world_actuators) == [1, 1, 0]
    assert_same(sim, alone, together, 1e-8)
    if solver == "pcg":  # each world converges on its own residual, in its own iteration count
        assert assert_own_iterations(alone, together) == 1  # the beam's first step iterates Newton, alone


@pytest.mark.parametrize("solver, qp, preconditioner", [("direct", "piqp", "auto"), ("pcg", "piqp", "auto"),
                                                        ("direct", "device", "auto"), ("pcg", "piqp", "blocks")])
def test_three_dynamic_robots_step_as_alone(scene_module, solver, qp, preconditioner):
    scenes = dynamic_trio(scene_module)
    # float64 blocks: in float32 a block's product sums in an order set by the batch's size (its
    # segments), so a world then matches its run alone to the CG tolerance, not to round-off
    sim, alone, together = run_alone_and_together(scenes, 4, solver=solver, qp=qp, preconditioner=preconditioner,
                                                  precision="float64")
    assert [s.inverse for s in sim.model.scenes] == [True, True, False]
    assert list(sim.rows.world_actuators) == [4, 8, 4] and sim.rows.num_columns == 8
    assert_same(sim, alone, together, 1e-8)
    assert assert_own_iterations(alone, together) == 4  # the Trunk iterates Newton at every step, the Diamonds do not


def assert_own_iterations(alone, together):
    """Each world's CG iterations are its own, the same as alone, also in a step where another
    world iterated Newton: a world held in place is not solved again (not even its compliance
    columns: a solve's worth of iterations more). The first world's exactly; the others' to
    within two: the residual norms are summed by blocks of 256 nodes, which straddle the worlds
    in a batch, so that the round-off differs from the run alone and moves a count near the
    tolerance by one or two. Returns the steps where some worlds iterated and others did not."""
    mixed = 0
    for k, step in enumerate(together):
        counts = {mine.newton_iterations for mine in step.worlds}
        mixed += len(counts) > 1
        for w, mine in enumerate(step.worlds):
            own = alone[w][k]
            assert mine.newton_iterations == own.newton_iterations
            assert abs(mine.cg_iterations - own.cg_iterations) <= (0 if w == 0 else 2), (k, w)
    return mixed


def test_one_world_model_is_the_scene(scene_module):
    scene = static_trio(scene_module)[0]
    a, b = ws.Simulator(scene), ws.Simulator(ws.finalize([scene]))
    for _ in range(2):
        a.step()
        b.step()
    assert np.array_equal(a.state.positions(), b.state.positions())


def test_worlds_must_share_the_step(scene_module):
    scenes = static_trio(scene_module)
    scenes[1].dt = 0.02
    with pytest.raises(ws.SceneError, match=r"world 1 \(scene 'pressure_sphere'\) has dt = 0.02"):
        ws.finalize(scenes)
    sim = ws.Simulator(ws.finalize(static_trio(scene_module)))
    with pytest.raises(ws.SceneError, match=r"control: this model has 3 worlds"):
        sim.step(ws.Control({"cable": 0.001}))
    with pytest.raises(ws.SceneError, match=r"control \(world 0\): no actuator named nope"):
        sim.step([ws.Control({"nope": 1.0}), None, None])
    with pytest.raises(ws.SceneError, match=r"stats.worlds\[w\].actuator_delta"):
        _ = sim.step().actuator_delta


def test_world_stats_are_read_from_the_step_record():
    """A step records every world's numbers at once and each world's stats are made when read:
    a world reads its own column, a dictionary read twice is the same one and keeps what is put
    in it, what is set on a world stays its own, and an unknown field is an error."""
    record = WorldRecord(3)
    record.add("cg_iterations", np.array([4, 5, 6]))
    record.add("cg_iterations", np.array([1, 0, 2]))  # (a second Newton iteration's solve adds)
    record.makers["actuator_delta"] = lambda w: {"cable": 0.001 * w}
    worlds = Worlds(record)
    assert len(worlds) == 3 and [w.cg_iterations for w in worlds] == [5, 5, 8]
    assert isinstance(worlds[2].cg_iterations, int) and worlds[-1] is worlds[2]
    assert worlds[0:2] == [worlds[0], worlds[1]]
    assert worlds[1].actuator_delta == {"cable": 0.001} and worlds[1].actuator_delta is worlds[1].actuator_delta
    worlds[0].rigid_bodies["cube"] = "pose"
    worlds[0].qp_status = "solved"
    assert worlds[0].rigid_bodies == {"cube": "pose"} and worlds[1].rigid_bodies == {}
    assert worlds[0].qp_status == "solved" and worlds[1].qp_status == ""
    with pytest.raises(IndexError):
        _ = worlds[3]
    with pytest.raises(TypeError, match="no field named nope"):
        WorldStats(nope=1)
    assert "cg_iterations=8" in repr(worlds[2]) and WorldStats(contacts=2).contacts == 2
