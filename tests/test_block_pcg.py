"""Block CG (``PCG(block=True)``): a world's right-hand sides share one search space."""

import functools
import warnings

import numpy as np
import pytest
import warp as wp

import warpsoft as ws
from warpsoft.linear import PCG, SparseDirect, WarpedFactor

RUBBER = ws.Material(1e6, 0.45, 1000.0)


def bent_beam():
    """A dynamic beam bent by gravity and a tip load."""
    scene = ws.Scene("bent", gravity=(0, 0, -9.81), dt=0.02)
    body = scene.add_body("beam", ws.box_grid((0, 0, 0), (0.1, 0.01, 0.01), (20, 2, 2)), RUBBER, element="corotational")
    scene.fix(body, ws.OnPlane((0, 0, 0), (1, 0, 0)))
    scene.add_force(body, ws.OnPlane((0.1, 0, 0), (1, 0, 0)), (0, 0, -2.0))
    return ws.Simulator(scene, solver="pcg", tolerance=1e-12)


def solvers(sim, k, tolerance=1e-10, max_iterations=2000):
    """Block and column PCG for ``k`` right-hand sides, their warped factors made at rest, then
    the beam three steps in: the factor of rest no longer equals the matrix, so CG iterates."""
    made = [PCG(sim.operator, WarpedFactor(sim.operator, k, "host"), k, tolerance=tolerance,
                max_iterations=max_iterations, block=block) for block in (True, False)]
    for s in made:
        s.prepare()
    for _ in range(3):
        sim.step()
    for s in made:
        s.prepare()
    return made


def solve(solver, b):
    x = wp.zeros(b.shape[:2], dtype=wp.vec3d)
    res = solver.solve(wp.array(b, dtype=wp.vec3d), x)
    return x.numpy(), res


def test_block_cg_solves_each_column_as_the_direct_solver_does():
    """Five independent right-hand sides, a repeated one, a multiple of another and a zero one
    (the last three make the block's Gram matrices singular: the dependent directions are
    pivoted out, not divided by zero): every column is the direct solution to the tolerance,
    the zero column's is 0, whatever its start."""
    sim = bent_beam()
    block, _ = solvers(sim, 8)
    n = sim.model.num_nodes
    rng = np.random.default_rng(11)
    b = rng.standard_normal((8, n, 3)) * sim.model.mask_np
    b[5] = b[1]
    b[6] = -3.0 * b[2]
    b[7] = 0.0
    x, res = solve(block, b)
    assert block.block and res.converged and res.iterations > 1 and np.isfinite(res.residual)
    direct = SparseDirect(sim.operator)
    direct.prepare()
    want = direct.solve_array(b)
    scale = np.abs(want).max()
    assert np.abs(x - want).max() < 1e-8 * scale
    assert np.abs(x[5] - x[1]).max() < 1e-8 * scale
    assert np.all(x[7] == 0.0)


def test_block_cg_needs_fewer_iterations_than_each_column_alone():
    """The block searches every column's direction at once: fewer iterations than the slowest
    column of column-by-column CG, to the same solutions."""
    sim = bent_beam()
    solve_block, solve_columns = solvers(sim, 5, tolerance=1e-8)
    n = sim.model.num_nodes
    b = np.random.default_rng(5).standard_normal((5, n, 3)) * sim.model.mask_np
    xb, block = solve(solve_block, b)
    xc, columns = solve(solve_columns, b)
    assert block.converged and columns.converged
    assert block.iterations < columns.iterations
    assert np.abs(xb - xc).max() < 1e-6 * np.abs(xc).max()


def test_block_cg_reports_a_cap_and_a_nan():
    """The iteration cap is reported as not converged; a NaN in a right-hand side stops the
    solve and reads as a NaN residual (never a silent result)."""
    sim = bent_beam()
    solver, _ = solvers(sim, 3, tolerance=1e-12, max_iterations=2)
    n = sim.model.num_nodes
    b = np.random.default_rng(2).standard_normal((3, n, 3)) * sim.model.mask_np
    _, res = solve(solver, b)
    assert res.iterations == 2 and not res.converged and res.residual > 1e-12
    b[1, 5, 2] = np.nan
    solver.max_iterations = 100
    _, res = solve(solver, b)
    assert not res.converged and np.isnan(res.residual) and res.iterations < 100


@pytest.mark.parametrize("block", [False, True])
def test_two_worlds_iterate_as_alone(block):
    """A world's block holds only its own columns: two different beams batched take each the
    solution they take alone, and as many iterations to within two (block CG and column CG
    alike). The batch's sums group the nodes differently (the residual norms by blocks of 256
    nodes that straddle the worlds, the block CG's Gram matrices by world), so the solutions
    differ by round-off (1e-12 to 1e-10 here), which moves a step's iterations near the
    tolerance by one or two (the first world: none); from the last step's solution rather than
    the extrapolated start (3 x - 3 last + before), which magnifies it."""
    def scene(load):
        s = ws.Scene("bent", gravity=(0, 0, -9.81), dt=0.02)
        body = s.add_body("beam", ws.box_grid((0, 0, 0), (0.1, 0.01, 0.01), (20, 2, 2)), RUBBER, element="corotational")
        s.fix(body, ws.OnPlane((0, 0, 0), (1, 0, 0)))
        s.add_force(body, ws.OnPlane((0.1, 0, 0), (1, 0, 0)), (0, 0, load))
        s.add_cable("c", body, points=[(0.05, 0.005, 0.009), (0.095, 0.005, 0.009)],
                    pull_point=(-0.01, 0.005, 0.009), value=lambda t: 0.004 * min(t / 0.1, 1.0))
        return s

    def run(scenes):
        sim = ws.Simulator(scenes, solver="pcg", preconditioner="blocks", precision="float64", tolerance=1e-9,
                           block_cg=block, warm_start="last")
        assert sim.solver.block == block
        out = [[w.cg_iterations for w in sim.step().worlds] for _ in range(4)]
        return np.array(out), sim.state.positions()

    together, q = run([scene(-2.0), scene(-0.5)])
    split = len(q) // 2
    for w, load in enumerate((-2.0, -0.5)):
        alone, qa = run([scene(load)])
        assert np.abs(together[:, w] - alone[:, 0]).max() <= (0 if w == 0 else 2)
        assert np.abs(q[w * split:(w + 1) * split] - qa).max() < 1e-10
    assert together.max() > 1


def cabled_bar(young_modulus: float) -> ws.Scene:
    """A 10 cm bar of four coarse boxes, clamped at x = 0, pulled by four cables 2 mm apart: their
    compliance columns are nearly equal (a near-dependent block)."""
    scene = ws.Scene("cabled", gravity=(0, 0, -9.81), dt=0.01)
    body = scene.add_body("bar", ws.box_grid((0, 0, 0), (0.1, 0.01, 0.01), (4, 1, 1)),
                          ws.Material(young_modulus, 0.45, 1000.0), element="corotational")
    scene.fix(body, ws.OnPlane((0, 0, 0), (1, 0, 0)))
    for c in range(4):
        scene.add_cable(f"cable{c}", body, points=[(0.05, 0.002 * c, 0.009), (0.095, 0.002 * c, 0.009)],
                        pull_point=(-0.01, 0.002 * c, 0.009), value=lambda t: 0.002 * min(t / 0.1, 1.0))
    return scene


@functools.cache
def direct_bars(steps: int) -> list[np.ndarray]:
    """Positions of :data:`STIFFNESSES`' bars after each of ``steps`` steps, by the direct solver
    (factorized at every step, as the CG's preconditioners are)."""
    sim = ws.Simulator(ws.finalize([cabled_bar(e) for e in STIFFNESSES]), solver="direct", factor_reuse=0.0)
    out = []
    for _ in range(steps):
        sim.step()
        out.append(sim.state.q.numpy().copy())
    return out


STIFFNESSES = [float(e) for e in np.geomspace(5e4, 2e6, 16)]


@pytest.mark.parametrize("preconditioner, directions", [("blocks", "float64"), ("factors", "float64"),
                                                        ("factors", "float32")])
def test_nearly_equal_columns_in_single_precision_do_not_break_the_block(preconditioner, directions):
    """Four cables 2 mm apart make a world's five columns nearly dependent; 16 bars from 50 kPa to
    2 MPa. With a float32 preconditioner (and float32 directions), ``Z = P^-1 R`` carries ~1e-7 of
    rounding. O'Leary's block CG (``beta = (R^T Z)^-1 R_new^T Z_new``) lost its conjugacy on it:
    iterations grew to 21 a solve, and the float32 factors and blocks met NaN at the 11th step.
    The breakdown-free form keeps every solve within a few iterations of float64 (at most 9 here,
    float64 at most 8; the bound leaves room for another BLAS's rounding) and the bars on the
    direct solver's path."""
    steps = 12
    block = ws.Simulator(ws.finalize([cabled_bar(e) for e in STIFFNESSES]), solver="pcg", block_cg=True,
                         preconditioner=preconditioner, precision="float32", operator="assembled",
                         directions=directions, tolerance=1e-8)
    assert block.solver.directions == directions
    want = direct_bars(steps)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # (a ConvergenceWarning fails the test)
        for k in range(steps):
            stats = block.step()
            assert stats.converged and stats.cg_iterations <= 15 * stats.newton_iterations
            x = block.state.q.numpy()
            motion = np.abs(want[k] - block.model.rest_np).max()
            assert np.abs(x - want[k]).max() < 1e-6 * motion
    assert motion > 1e-3


def test_single_precision_directions_meet_the_same_tolerance():
    """The block CG's directions ``P`` and ``Z`` stored in float32 (``directions``, "auto" with a
    float32 factor and the assembled operator): ``X``, ``R`` and ``A P`` stay float64, so four cabled
    bars of different stiffness end at the direct solver's positions as closely as with float64
    directions, in about as many iterations. The iterations are bounded, not matched: the rounding
    of float32 directions moves a step's count by one or two, differently on each BLAS and
    compiler (O'Leary's block CG, before, took 16 where float64 took 6 on one machine). The
    matrix-free operator takes no float32 column."""
    designs = [cabled_bar(e) for e in (1e5, 2e5, 4e5, 6e5)]
    runs = {}
    for directions in ("float64", "auto"):
        sim = ws.Simulator(ws.finalize(designs), solver="pcg", preconditioner="factors", precision="float32",
                           operator="assembled", tolerance=1e-8, directions=directions)
        its = [[w.cg_iterations for w in sim.step().worlds] for _ in range(6)]
        runs[directions] = (sim, np.array(its), sim.state.q.numpy())
    single = runs["auto"][0].solver
    assert single.directions == "float32" and single.bp.dtype == wp.vec3f and single.bz.dtype == wp.vec3f
    assert runs["float64"][0].solver.bp.dtype == wp.vec3d
    single_its, double_its = runs["auto"][1], runs["float64"][1]
    assert double_its.max() > 3  # (the case iterates)
    assert single_its.max() <= double_its.max() + 3 and single_its.sum() <= 1.25 * double_its.sum()
    direct = ws.Simulator(ws.finalize(designs), solver="direct", factor_reuse=0.0)
    for _ in range(6):
        direct.step()
    want = direct.state.q.numpy()
    motion = np.abs(want - direct.model.rest_np).max()
    assert motion > 1e-3
    for _, _, q in runs.values():
        assert np.abs(q - want).max() < 1e-8 * motion
    with pytest.raises(ValueError, match="assembled operator"):
        ws.Simulator(ws.finalize(designs[:2]), solver="pcg", preconditioner="factors", operator="matrix_free",
                     directions="float32")
    with pytest.raises(ws.SceneError, match="directions must be"):
        ws.Simulator(designs[0], solver="pcg", directions="half")
    matrix_free = ws.Simulator(ws.finalize(designs[:2]), solver="pcg", preconditioner="factors",
                               operator="matrix_free")
    assert matrix_free.solver.directions == "float64"
