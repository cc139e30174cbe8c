"""The warped preconditioner world by world (``preconditioner="blocks"``): one dense inverse per
world, shared by worlds equal up to a factor, a converged world skipping its product."""

import numpy as np
import pytest
import warp as wp
from warpsoft.kernels.linear.cg import DONE, NUM_SCALARS

import warpsoft as ws
from warpsoft.linear import WarpedFactor, WorldBlocks, WorldFactors, blocks


def beam(young_modulus=1e6, poisson_ratio=0.45, cells=20, static=True):
    """A cantilever under gravity and a tip load; quasi-static by default (its system is then
    its stiffness alone, proportional to Young's modulus)."""
    scene = ws.Scene("beam", gravity=(0, 0, -9.81), dt=0.02, static=static)
    body = scene.add_body("beam", ws.box_grid((0, 0, 0), (0.1, 0.01, 0.01), (cells, 2, 2)),
                          ws.Material(young_modulus, poisson_ratio, 1000.0), element="corotational")
    scene.fix(body, ws.OnPlane((0, 0, 0), (1, 0, 0)))
    scene.add_force(body, ws.OnPlane((0.1, 0, 0), (1, 0, 0)), (0, 0, -0.2))
    return scene


def four_designs():
    """The same beam at 1 and 3 MPa (proportional systems), at another Poisson ratio, and shorter cells."""
    return [beam(), beam(3e6), beam(1e6, 0.3), beam(cells=16)]


@pytest.mark.parametrize("kind", [WorldBlocks, WorldFactors])
def test_blocks_apply_each_worlds_inverse_on_turned_bodies(kind):
    """Refreshed at a bent state, the blocks (dense inverses, or sparse factors solved level by
    level) apply the same ``Q A_f^-1 Q^T`` as the whole model's host factor (block diagonal), on
    every column: to round-off in float64, to float32's precision."""
    sim = ws.Simulator(ws.finalize(four_designs()), solver="direct")
    for _ in range(3):
        sim.step()
    r = wp.array(np.random.default_rng(7).standard_normal((3, sim.model.num_nodes, 3)), dtype=wp.vec3d)
    host = WarpedFactor(sim.operator, 3, "host")
    host.prepare()  # factorized at the bent state
    want = wp.zeros_like(r)
    host.apply(r, want)
    want = want.numpy()
    for precision, tol in (("float64", 1e-9), ("float32", 1e-4)):
        pre = kind(sim.operator, 3, precision, share=False)
        pre.prepare()
        assert pre.blocks == 4 and pre.refreshes == 1
        assert kind is WorldBlocks or min(pre.levels) > 1
        for k in (3, 1):  # also fewer columns than it serves
            z = wp.zeros((k, sim.model.num_nodes), dtype=wp.vec3d)
            pre.apply(r[:k], z)
            assert np.abs(z.numpy() - want[:k]).max() < tol * np.abs(want).max(), (precision, k)


@pytest.mark.parametrize("tiled_from", [8, 2])
def test_proportional_worlds_share_a_block_and_step_as_alone(monkeypatch, tiled_from):
    """At rest the 1 and 3 MPa beams have proportional stiffnesses: one block serves both, the
    second scaled by 1/3. Each world then steps as it does alone, in its own iteration count;
    also when the shared block's product is the tiled one (``tiled_from=2``; its sums run in
    another order, so the 1e-10 tolerance may be met one iteration apart)."""
    monkeypatch.setattr(blocks, "TILED_FROM", tiled_from)
    scenes = four_designs()
    sim = ws.Simulator(ws.finalize(scenes), solver="pcg", preconditioner="blocks", precision="float64",
                       tolerance=1e-10)
    together = [sim.step() for _ in range(3)]
    pre = sim.solver.precond
    assert isinstance(pre, WorldBlocks)
    assert pre.blocks == 3 and list(pre.block_of) == [0, 0, 1, 2]
    assert abs(pre.scale_np[1] - 3.0) < 1e-9
    assert pre.tiled_worlds == (2 if tiled_from == 2 else 0)
    # the tiled product sums in another order than the streamed one alone: one iteration either way
    steps_as_alone(scenes, sim, together, "blocks", 0 if tiled_from == 8 else 1)


def steps_as_alone(scenes: list, sim: ws.Simulator, together: list, preconditioner: str, off: int) -> list:
    """Each world of ``sim`` (its ``together`` stats) against its scene stepped alone with the same
    preconditioner: the same positions (to 1e-8 of its motion), iterations at most ``off`` apart.
    Returns the scenes' positions alone."""
    positions = []
    for w, scene in enumerate(scenes):
        alone = ws.Simulator(scene, solver="pcg", preconditioner=preconditioner, precision="float64",
                             tolerance=1e-10)
        history = [alone.step() for _ in together]
        q = alone.positions()
        moved = np.abs(q - sim.model.rest_np[sim.model.world_nodes(w)]).max()
        assert moved > 1e-4
        assert np.abs(sim.positions(w) - q).max() < 1e-8 * moved
        its = np.array([s.worlds[w].cg_iterations for s in together]) - [s.cg_iterations for s in history]
        assert np.abs(its).max() <= off, (w, its)
        positions.append(q)
    return positions


def test_a_shared_block_serves_its_worlds_and_converged_ones_skip_it():
    """At rest the 1 and 3 MPa beams share a block: one thread serves both (a chunk), and the
    product equals the whole model's host factor. A converged column of a world is not touched:
    its operand is not rotated in and its result not written out. A chunk still runs while one
    of its worlds does: with world 0 done (its operand left from another right-hand side),
    world 1, which shares its chunk, gets the fresh product; with worlds 0 and 1 done the chunk
    is skipped, and world 2 is still fresh."""
    sim = ws.Simulator(ws.finalize([beam(), beam(3e6), beam(cells=16)]), solver="direct")
    sim.rot.assign(np.tile(np.eye(3), (sim.model.num_elements, 1, 1)))  # linearized at rest
    pre = WorldBlocks(sim.operator, 2, "float64")
    scal = wp.zeros((2, 3, NUM_SCALARS), dtype=wp.float64)
    pre.watch(scal)
    pre.prepare()
    assert list(pre.block_of) == [0, 0, 1] and 2 in pre.chunks
    host = WarpedFactor(sim.operator, 2, "host")
    host.prepare()
    rng = np.random.default_rng(1)
    n = sim.model.num_nodes
    r1, r2 = (wp.array(rng.standard_normal((2, n, 3)), dtype=wp.vec3d) for _ in range(2))
    fresh, want = (wp.zeros((2, n), dtype=wp.vec3d) for _ in range(2))
    pre.apply(r2, fresh)
    host.apply(r2, want)
    assert np.abs(fresh.numpy() - want.numpy()).max() < 1e-9 * np.abs(want.numpy()).max()
    for done in ([0], [0, 1]):
        scal.zero_()
        pre.apply(r1, wp.zeros((2, n), dtype=wp.vec3d))  # every operand now r1's
        s = np.zeros((2, 3, NUM_SCALARS))
        s[:, done, DONE] = 1.0
        scal.assign(s)
        z = wp.array(np.full((2, n, 3), 7.0), dtype=wp.vec3d)
        pre.apply(r2, z)
        got = z.numpy()
        skipped = np.isin(sim.model.node_world_np, done)
        assert np.all(got[:, skipped] == 7.0), done
        assert np.array_equal(got[:, ~skipped], fresh.numpy()[:, ~skipped]), done


def test_a_block_of_many_worlds_is_one_tiled_product_of_its_running_columns():
    """Three beams at 1, 2 and 3 MPa share a block at rest; from ``tiled_from=2`` on, their
    product is one tiled matrix product (their columns side by side), while the two other
    designs stay streamed. Both equal the whole model's host factor for every column count, in
    float64 and float32. A converged world's result is not written, and the columns of the
    others are packed at the front of the block's region: with some of the three done the
    others' products are fresh; with all three done no tile runs."""
    sim = ws.Simulator(ws.finalize([beam(), beam(2e6), beam(3e6), beam(cells=16), beam(1e6, 0.3)]), solver="direct")
    sim.rot.assign(np.tile(np.eye(3), (sim.model.num_elements, 1, 1)))  # linearized at rest
    host = WarpedFactor(sim.operator, 3, "host")
    host.prepare()
    n = sim.model.num_nodes
    rng = np.random.default_rng(5)
    r1, r2 = (wp.array(rng.standard_normal((3, n, 3)), dtype=wp.vec3d) for _ in range(2))
    want = wp.zeros_like(r2)
    host.apply(r2, want)
    want = want.numpy()
    for precision, tol in (("float64", 1e-9), ("float32", 1e-5)):
        pre = WorldBlocks(sim.operator, 3, precision, tiled_from=2)
        scal = wp.zeros((3, 5, NUM_SCALARS), dtype=wp.float64)
        pre.watch(scal)
        pre.prepare()
        assert list(pre.block_of) == [0, 0, 0, 1, 2] and pre.tiled_worlds == 3
        for k in (3, 2, 1):
            z = wp.zeros((k, n), dtype=wp.vec3d)
            pre.apply(r2[:k], z)
            assert np.abs(z.numpy() - want[:k]).max() < tol * np.abs(want).max(), (precision, k)
    for done in ([1], [0, 2], [0, 1, 2]):  # worlds of the tiled block: the others' columns move to the front
        scal.zero_()
        pre.apply(r1, wp.zeros_like(r1))  # every operand now r1's
        s = np.zeros((3, 5, NUM_SCALARS))
        s[:, done, DONE] = 1.0
        scal.assign(s)
        z = wp.array(np.full((3, n, 3), 7.0), dtype=wp.vec3d)
        pre.apply(r2, z)
        got, skipped = z.numpy(), np.isin(sim.model.node_world_np, done)
        assert np.all(got[:, skipped] == 7.0), done
        assert np.abs(got[:, ~skipped] - want[:, ~skipped]).max() < 1e-5 * np.abs(want).max(), done
        assert pre.count.numpy()[0] == 3 * (3 - len(done))  # the region's columns in use: the running ones
    with pytest.raises(ValueError, match="tiled_from must be at least 1, got 0"):
        WorldBlocks(sim.operator, 3, tiled_from=0)


def test_a_share_tolerance_shares_dynamic_designs_and_keeps_the_answer():
    """Dynamic beams at 1 and 3 MPa are not exact multiples (their mass is the same): by default
    each has its block; with ``share_tolerance=0.01`` one block serves both, the second world's
    preconditioner is then approximate, and its step still reaches the same positions to the CG
    tolerance. A tolerance outside [0, 1), or an unknown preconditioner, is refused by name."""
    scenes = [beam(static=False), beam(3e6, static=False)]
    runs = {}
    for tol in (1e-10, 0.01):
        sim = ws.Simulator(ws.finalize(scenes), solver="pcg", preconditioner="blocks", precision="float64",
                           tolerance=1e-10, share_tolerance=tol)
        for _ in range(3):
            sim.step()
        runs[tol] = (sim.solver.precond.blocks, sim.positions(1))
    assert runs[1e-10][0] == 2 and runs[0.01][0] == 1
    moved = np.abs(runs[1e-10][1] - ws.Simulator(scenes[1]).model.rest_np).max()
    assert moved > 1e-5
    assert np.abs(runs[0.01][1] - runs[1e-10][1]).max() < 1e-7 * moved
    with pytest.raises(ws.SceneError, match="share_tolerance"):
        ws.Simulator(scenes[0], share_tolerance=1.5)
    with pytest.raises(ValueError, match="auto, host, dense, blocks, factors, got 'block'"):
        ws.Simulator(scenes[0], solver="pcg", preconditioner="block")
