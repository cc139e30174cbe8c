"""Newton iterations within a step: they land on the equilibrium that repeated linearized steps
reach, they stop at once where one linearization is enough, and a state changed between steps
is linearized again."""

import numpy as np
import pytest

import warpsoft as ws


def cantilever(scene_module, **params):
    return scene_module("scenes/validation/cantilever.py").build(tip_force=-0.05, mesh_size=0.005, **params)


def run(scene, steps, **options):
    sim = ws.Simulator(scene, solver="direct", **options)
    history = [sim.step() for _ in range(steps)]
    return sim, history


def test_one_step_of_newton_finds_the_large_deflection_equilibrium(scene_module):
    """A quasi-static cantilever bent by 11 % of its length: repeated steps of one linearization
    each converge to its equilibrium (a fixed-point iteration); one step that iterates to a tight
    tolerance lands there too (to 1e-8 m), while one linearization alone stays at the linear
    answer, 0.7 mm off (the beam does not shorten as it bends), and says it did not converge."""
    reference, _ = run(cantilever(scene_module), 40, newton_iterations=1)
    ref = reference.probe_positions()["tip"]
    newton, (stats,) = run(cantilever(scene_module), 1, newton_tolerance=1e-6, newton_iterations=60)
    assert np.abs(newton.probe_positions()["tip"] - ref).max() < 1e-8
    assert 1 < stats.newton_iterations < 60 and stats.newton_residual <= 1e-6 and not stats.warnings
    assert stats.line_searches > 0  # the linear step overshoots: the beam stretches as it bends
    linear, (once,) = run(cantilever(scene_module), 1, newton_iterations=1)
    assert np.abs(linear.probe_positions()["tip"] - ref).max() > 5e-4
    assert once.newton_residual > 1.0 and any("did not converge" in m for m in once.warnings)


def test_a_small_load_takes_one_iteration_and_leaves_almost_no_residual(scene_module):
    """Linear regime: one linearization is exact to second order (error ~ rotation ~ 1e-3)."""
    _, (stats,) = run(scene_module("scenes/validation/cantilever.py").build(tip_force=-1e-4, mesh_size=0.005), 1)
    assert stats.newton_iterations == 1 and stats.newton_residual < 1e-3 and stats.line_searches == 0


@pytest.mark.parametrize("static, factor_reuse", [(True, 0.0), (False, 0.0), (True, 0.5), (False, 0.5)])
def test_a_state_changed_between_steps_is_linearized_again(scene_module, static, factor_reuse):
    """The step reuses the linearization made at the end of the last one, unless the state was
    changed from outside: then it makes it again, and the step is the one a fresh simulator
    takes from that state; with ``factor_reuse``, it factorizes that linearization too (the last
    factorization knows nothing of the jump)."""
    scene = cantilever(scene_module, static=static)
    sim, history = run(scene, 6, factor_reuse=factor_reuse, newton_tolerance=0.1)
    if factor_reuse:  # steps kept the factorization, and the next one may
        assert any(s.factorizations < s.newton_iterations for s in history)
        assert history[-1].newton_iterations == 1 and history[-1].newton_residual <= factor_reuse
    moved = sim.model.rest_np + np.array([0.0, 0.0, 1e-3])  # the beam lifted (its clamp too: fixed DOFs move along)
    sim.state.q.assign(moved)
    sim.state.v.zero_()
    stats = sim.step()
    assert stats.factorizations == stats.newton_iterations
    fresh = ws.Simulator(cantilever(scene_module, static=static), solver="direct", newton_tolerance=0.1)
    fresh.state.q.assign(moved)
    fresh.step()
    assert np.abs(sim.state.positions() - fresh.state.positions()).max() < 1e-12


def test_a_kept_factorization_reaches_the_same_equilibrium(scene_module):
    """Quasi-static steps of one linearization each converge to the large-deflection equilibrium
    (see the first test); kept factorizations (``factor_reuse``) change the tangent of those
    steps, not the forces they balance: the same equilibrium, to 1e-8 m, with fewer
    factorizations than steps."""
    reference, every = run(cantilever(scene_module), 40, newton_iterations=1)  # (quasi-static: no reuse by default)
    reuse, kept = run(cantilever(scene_module), 40, newton_iterations=1, factor_reuse=0.5)
    ref = reference.probe_positions()["tip"]
    assert np.abs(reuse.probe_positions()["tip"] - ref).max() < 1e-8
    assert sum(s.factorizations for s in every) == 40
    assert sum(s.factorizations for s in kept) < 10


def test_a_kept_factorization_keeps_a_swinging_beam_on_its_trajectory(scene_module):
    """A soft cantilever swinging under gravity (6 cm of motion in 60 steps), against the same
    swing converged to a Newton tolerance of 1e-4: with factorizations kept while the last
    step's residual stays under 0.01, the trajectory is no further from it than with a
    factorization at every step, and every Newton iteration after a step's first factorizes."""
    def swing(**options):
        scene = scene_module("scenes/validation/cantilever.py").build(gravity=9.81, static=False,
                                                                      young_modulus=2e5, mesh_size=0.005)
        sim = ws.Simulator(scene, solver="direct", **options)
        history, path = [], []
        for _ in range(60):
            history.append(sim.step())
            path.append(sim.probe_positions()["tip"])
        return history, np.array(path)

    _, converged = swing(newton_tolerance=1e-4, newton_iterations=20, factor_reuse=0.0)
    every, fresh = swing(factor_reuse=0.0)
    kept, reused = swing(factor_reuse=0.01)
    assert np.ptp(converged[:, 2]) > 0.03
    error_fresh, error_kept = np.abs(fresh - converged).max(), np.abs(reused - converged).max()
    assert error_kept <= 1.25 * error_fresh
    assert sum(s.factorizations for s in every) == sum(s.newton_iterations for s in every)
    assert sum(s.factorizations for s in kept) < sum(s.newton_iterations for s in kept)
    assert all(s.factorizations >= s.newton_iterations - 1 for s in kept)


def test_a_world_whose_kept_factorizations_fail_asks_more_before_it_tries_again(scene_module, monkeypatch):
    """The Finger as its cable starts to pull: a kept factorization's step misses ``factor_reuse``
    and iterates on a fresh one (a failed try, one iteration more than it saves). With the margin
    each failure divides the residual a world's last step must have left by 8: one try fails in
    30 steps, against four when every step under ``factor_reuse`` tries (the margin held at 1),
    and the run takes fewer Newton iterations. By default no step keeps one (``factor_reuse=0``:
    opt-in, since its error is not bounded by the Newton tolerance)."""
    def finger(**options):
        sim = ws.Simulator(scene_module("scenes/finger.py").build(mesh_size=0.012), solver="direct",
                           factor_reuse=0.005, **options)
        history = [sim.step() for _ in range(30)]
        return sim.reuse, sum(s.newton_iterations for s in history)

    (reuse, iterations) = finger()
    monkeypatch.setattr(ws.reuse, "MARGIN_CUT", 1.0)
    (always, iterations_always) = finger()
    assert reuse.failures <= 1 < 3 <= always.failures and reuse.tries > reuse.failures
    assert iterations < iterations_always
    assert ws.reuse.MARGIN_FLOOR <= reuse.margin[0] < 1.0
    dynamic = ws.Simulator(scene_module("scenes/finger.py").build(mesh_size=0.012), solver="direct")
    static = ws.Simulator(scene_module("scenes/finger.py").build(mesh_size=0.012, static=True), solver="direct")
    assert dynamic.factor_reuse == 0.0 and static.factor_reuse == 0.0
    assert ws.Simulator(scene_module("scenes/finger.py").build(mesh_size=0.012), solver="pcg").factor_reuse == 0.0


def test_newton_options_are_checked(scene_module):
    scene = cantilever(scene_module)
    with pytest.raises(ws.SceneError, match="newton_iterations must be >= 1"):
        ws.Simulator(scene, newton_iterations=0)
    with pytest.raises(ws.SceneError, match=r"newton_tolerance must lie in \(0, 1\)"):
        ws.Simulator(scene, newton_tolerance=0.0)
    with pytest.raises(ws.SceneError, match="line_search must be >= 0"):
        ws.Simulator(scene, line_search=-1)
    with pytest.raises(ws.SceneError, match=r"factor_reuse must lie in \[0, 1\), got 1.5"):
        ws.Simulator(scene, factor_reuse=1.5)
    with pytest.raises(ws.SceneError, match="factor_reuse keeps the direct solver's factorization; solver 'pcg'"):
        ws.Simulator(scene, solver="pcg", factor_reuse=0.01)


def test_a_preconditioner_due_for_a_refresh_is_refreshed_before_the_solve(scene_module):
    """The step linearizes at its end for the next one; a preconditioner found stale after a
    solve is refreshed at the next step's start, so that this step's solve uses it: the warped
    factorization is then exact, one CG iteration (16 when it was refreshed only after)."""
    sim = ws.Simulator(scene_module("scenes/finger.py").build(mesh_size=0.006), solver="pcg")
    history = [sim.step() for _ in range(20)]
    assert history[-1].cg_iterations > 5
    refreshes = sim.solver.precond.refreshes
    sim.solver.precond._stale = True  # as observe() leaves it when the iterations grew
    stats = sim.step()
    assert sim.solver.precond.refreshes == refreshes + 1 and stats.cg_iterations == 1


def test_each_world_keeps_or_makes_its_factorization_as_it_would_alone(scene_module):
    """Three swinging cantilevers of different stiffness as one model, with ``factor_reuse``: each
    world decides on its own history whether to keep its factorization, so the batch makes exactly
    the factorizations the three make alone (their counts differ) and each world swings as it does
    alone. A step that kept one ends within ``factor_reuse`` or iterates on a fresh one."""
    def swing(young):
        return scene_module("scenes/validation/cantilever.py").build(gravity=9.81, static=False, young_modulus=young,
                                                                      mesh_size=0.005)

    moduli, steps, reuse = (1.5e5, 3e5, 1e6), 40, 0.02
    alone = []
    for young in moduli:
        sim = ws.Simulator(swing(young), solver="direct", factor_reuse=reuse)
        history = [sim.step() for _ in range(steps)]
        alone.append((sim.probe_positions()["tip"], history))
    counts = [sum(s.factorizations for s in history) for _, history in alone]
    assert len(set(counts)) == 3
    assert all(any(s.factorizations < s.newton_iterations for s in history) for _, history in alone)  # each kept one
    for _, history in alone:
        kept = [s for s in history if s.factorizations < s.newton_iterations]
        assert all(s.newton_residual <= reuse for s in kept if s.newton_iterations == 1)
    assert any(s.newton_iterations == 2 and s.factorizations == 1 for _, history in alone for s in history)

    batch = ws.Simulator(ws.finalize([swing(young) for young in moduli], "cpu"), solver="direct", factor_reuse=reuse)
    together = [batch.step() for _ in range(steps)]
    assert sum(s.factorizations for s in together) == sum(counts)
    for w, (tip, history) in enumerate(alone):
        assert np.abs(batch.probe_positions(world=w)["tip"] - tip).max() < 1e-12
        assert [s.newton_iterations for s in history] == [s.worlds[w].newton_iterations for s in together]


@pytest.mark.parametrize("gather", [False, True])
def test_a_later_iteration_relinearizes_the_worlds_that_moved_alone(scene_module, monkeypatch, gather):
    """Two cantilevers in one model, one bent by 11 % of its length (it iterates, with line
    searches), one barely loaded (done after its first iteration): the later iterations and the
    line-search trials make the linearization anew for the worlds that move alone (element forces
    and rotations, the assembled blocks, the preconditioner's node rotations), and the others keep
    theirs. The trajectories are those of every world relinearized at every pass, to the bit;
    ``gather``: the CUDA default kernels (blocks summed a thread per slot, node rotations a thread
    per node) run on the CPU."""
    from warpsoft.elastic import Corotational

    monkeypatch.setattr(Corotational, "gather_rotations", gather)

    def run_both(keep: bool):
        scenes = [cantilever(scene_module), scene_module("scenes/validation/cantilever.py").build(
            tip_force=-1e-4, mesh_size=0.005)]
        sim = ws.Simulator(ws.finalize(scenes, "cpu"), solver="pcg", preconditioner="factors", operator="assembled",
                           newton_tolerance=1e-6, newton_iterations=30)
        sim.operator.blocks.fused = gather
        passes = []
        if keep:
            set_moving = sim.newton._set_moving
            monkeypatch.setattr(sim.newton, "_set_moving", lambda m: (passes.append(m.copy()), set_moving(m)))
        else:
            sim.operator.moving = None  # every world made anew at every pass
        history = [sim.step() for _ in range(2)]
        return sim, history, passes

    kept, kept_history, passes = run_both(True)
    every, every_history, _ = run_both(False)
    assert any(not m.all() for m in passes)  # some pass left a world where it was
    assert max(s.line_searches for s in kept_history) > 0 and kept_history[0].newton_iterations > 2
    assert [s.worlds[0].newton_iterations for s in kept_history] == [s.worlds[0].newton_iterations
                                                                     for s in every_history]
    assert kept_history[0].worlds[1].newton_iterations < kept_history[0].worlds[0].newton_iterations
    assert np.array_equal(kept.state.q.numpy(), every.state.q.numpy())
    assert np.array_equal(kept.f_int.numpy(), every.f_int.numpy())
