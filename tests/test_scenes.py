"""Robot scenes build and behave."""

import numpy as np

import warpsoft as ws


def test_finger_sags_under_gravity_and_its_base_holds(scene_module):
    scene = scene_module("scenes/finger.py").build(mesh_size=0.006)
    sim = ws.Simulator(scene)
    rest = sim.model.rest_np
    tip0 = sim.probe_positions()["tip"]
    for _ in range(5):
        stats = sim.step()
        assert stats.converged
    q = sim.state.positions()
    fixed = np.all(sim.model.mask_np == 0, axis=1)
    assert fixed.any() and np.array_equal(q[fixed], rest[fixed])
    drop = tip0[2] - sim.probe_positions()["tip"][2]
    # free fall would give g t^2 / 2 = 1.2 mm after 0.05 s; the clamped finger falls less, but falls
    assert 1e-5 < drop < 0.5 * 9.81 * 0.05**2
