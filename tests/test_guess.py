"""The extrapolated warm starts of the step's first solve (``warpsoft.linear.guess``)."""

import numpy as np
import pytest
import warp as wp

import warpsoft as ws
from warpsoft.linear.guess import Extrapolation


def test_the_start_is_the_quadratic_through_the_last_three_solutions():
    """Solutions that follow a quadratic in the step number are met exactly once three are known
    (with one, the start is that solution; with two, their line); a contact's column (past the
    world's held rows) keeps its last solution; after a state moved from outside, or the history
    forgotten, it starts again."""
    k, n = 3, 4
    rng = np.random.default_rng(1)
    a, b, c = (rng.standard_normal((k, n, 3)) for _ in range(3))
    exact = [a + b * s + c * s * s for s in range(6)]
    guess = Extrapolation(k, n, np.array([1]), wp.zeros(n, dtype=wp.int32, device="cpu"), "cpu")
    still, moved = wp.zeros(1, dtype=wp.int32, device="cpu"), wp.ones(1, dtype=wp.int32, device="cpu")
    x = wp.zeros((k, n), dtype=wp.vec3d, device="cpu")

    def start(s, flag=still):  # the solve of step s - 1 left exact[s - 1]; the start of step s
        x.assign(exact[s - 1])
        guess.predict(x, flag)
        return x.numpy()

    x.zero_()
    guess.predict(x, still)  # the first step: no solution yet
    assert not x.numpy().any()
    assert np.array_equal(start(1), exact[0])  # one solution known
    got = start(2)
    assert np.allclose(got[:2], 2 * exact[1][:2] - exact[0][:2], rtol=0, atol=1e-12)
    assert np.array_equal(got[2], exact[1][2])
    for s in (3, 4):
        got = start(s)
        assert np.allclose(got[:2], exact[s][:2], rtol=0, atol=1e-12)  # the free motion and the held row's column
        assert np.array_equal(got[2], exact[s - 1][2])  # a contact's column
    assert np.array_equal(start(5, moved), exact[4])
    assert np.array_equal(start(6), exact[5])  # (one solution known since the move)
    guess.forget()
    assert np.array_equal(start(6), exact[5])


def test_extrapolated_starts_save_iterations_and_leave_the_trajectory(scene_module):
    """The Finger pulled by its cable, PCG: from the extrapolated starts the solves take fewer
    iterations than from the last solution (354 against 430 over 30 steps when written), and the
    trajectory is the same to the solver's tolerance."""
    def run(warm_start):
        sim = ws.Simulator(scene_module("scenes/finger.py").build(mesh_size=0.008), solver="pcg", tolerance=1e-8,
                           warm_start=warm_start)
        history = [sim.step() for _ in range(30)]
        return sum(s.cg_iterations for s in history), sim.state.positions() - sim.model.rest_np

    (last, moved), (extrapolated, moved_x) = run("last"), run("extrapolate")
    assert extrapolated < 0.9 * last
    assert np.abs(moved_x - moved).max() < 1e-8 * np.abs(moved).max()


def test_a_bad_warm_start_is_named(scene_module):
    with pytest.raises(ws.SceneError, match="warm_start must be 'extrapolate', 'last', 'none', True or False, "
                                            "got 'quadratic'"):
        ws.Simulator(scene_module("scenes/finger.py").build(mesh_size=0.01), warm_start="quadratic")


def test_worlds_that_turn_abruptly_start_from_the_last_solution(scene_module):
    """A world with contacts starts from its last solutions (none of its columns extrapolated), a
    world of a cable alone extrapolates its free motion and its cable's column, and a quasi-static
    model extrapolates nothing."""
    block = ws.Scene("block", gravity=(0.0, 0.0, -9.81), dt=0.005)
    block.add_body("block", ws.box_grid((-0.01, -0.01, 0.0005), (0.01, 0.01, 0.0105), (3, 3, 2)),
                   ws.Material(1e5, 0.3, 1000.0), element="corotational")
    block.add_obstacle("floor", ws.obstacles.Floor(), mu=0.5, contact_distance=0.002)
    finger = scene_module("scenes/finger.py").build(mesh_size=0.01)
    assert ws.Simulator(finger, solver="pcg").guess.held.numpy().tolist() == [1]
    assert ws.Simulator(block, solver="pcg").guess.held.numpy().tolist() == [-1]
    static = scene_module("scenes/validation/cantilever.py").build(mesh_size=0.01)
    assert static.static and ws.Simulator(static, solver="pcg").guess is None
