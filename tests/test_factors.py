"""The warped preconditioner world by world with sparse factors (``preconditioner="factors"``):
CHOLMOD's factor of each world, its triangular solves run as levels on the device."""

import contextlib

import numpy as np
import pytest
import scipy.sparse as sp
import warp as wp
from warpsoft.kernels.linear import factors as kernels
from warpsoft.kernels.linear.cg import DONE, NUM_SCALARS

import warpsoft as ws
from warpsoft.linear import WarpedFactor, WorldFactors, factors
from warpsoft.linear.assembly import CholmodFactor
from warpsoft.linear.supernodal import Supernodal, sliced

from .test_blocks import beam, four_designs, steps_as_alone


def bent(scenes):
    """The designs as one model, three steps in (the bodies bent, their rotations no longer I)."""
    sim = ws.Simulator(ws.finalize(scenes), solver="direct")
    for _ in range(3):
        sim.step()
    return sim


@pytest.mark.parametrize("ordering", ["cholmod", "nested_dissection"])
def test_the_level_programs_solve_with_the_factor_cholmod_made(ordering):
    """CHOLMOD's factor read out is the permuted system's (``A[order][:, order] = L L^T``); its
    supernodes' forward and backward programs, run level by level, solve ``A x = b`` to
    round-off; and every row of a level reads only rows of earlier levels. In either ordering."""
    sim = bent([beam(cells=24)])
    assembly = sim.solver.assembly
    values = assembly.values()
    A = assembly.matrix(values)
    L, order = CholmodFactor(assembly, ordering=ordering).lower(values)
    assert np.abs((A[order][:, order] - L @ L.T).toarray()).max() < 1e-12 * np.abs(A).max()
    analysis = Supernodal(L)
    forward, backward = analysis.programs(L)
    assert len(analysis.first) < assembly.size  # columns were merged into supernodes
    assert forward.levels == analysis.levels[0] and backward.levels == analysis.levels[1]
    for program in (forward, backward):
        level_of_row = np.empty(assembly.size, dtype=np.int64)
        level_of_row[program.row] = program.level
        for t in range(len(program.row)):
            s0, s1, s2 = program.start[t]
            assert np.all(level_of_row[program.col[s1:s2]] < program.level[t])  # solved before
    b = np.random.default_rng(3).standard_normal((assembly.size, 2))
    x = np.empty_like(b)
    x[order] = backward.run(forward.run(b[order]))
    assert np.abs(A @ x - b).max() < 1e-10 * np.abs(b).max()
    # the same solves as panels of up to 1, 3 or 8 rows of a supernode, which list their columns
    # once: the rows of a panel are consecutive, each row in one panel, and a panel reads only
    # rows of earlier levels
    for rows in (1, 3, 8):
        panels = analysis.panels(L, rows)
        assert [p.levels for p in panels] == list(analysis.levels)
        for p in panels:
            assert p.height.max() == min(rows, (analysis.end - analysis.first).max())
            covered = np.concatenate([np.arange(r, r + h) for r, h in zip(p.row, p.height, strict=True)])
            assert np.array_equal(np.sort(covered), np.arange(assembly.size))
            level_of_row = np.empty(assembly.size, dtype=np.int64)
            level_of_row[covered] = np.repeat(p.level, p.height)
            for t in range(len(p.row)):
                c0, (ni, no) = p.col_start[t], p.reads[t]
                assert np.all(level_of_row[p.col[c0 + ni:c0 + ni + no]] < p.level[t])
        x[order] = panels[1].run(panels[0].run(b[order]))
        assert np.abs(A @ x - b).max() < 1e-10 * np.abs(b).max()
    assert len(analysis.panels(L, 8)[0].col) < len(forward.col) / 4  # (the columns listed once a panel)
    with pytest.raises(ValueError, match="a panel needs at least one row, got 0"):
        analysis.panels(L, 0)
    L.data[0] *= 2.0  # new values, same pattern: accepted
    analysis.programs(L)
    with pytest.raises(ValueError, match="pattern changed"):
        analysis.programs(sp.csc_matrix(sp.tril(L.toarray() != 0, format="csc") * 1.0 + sp.eye(L.shape[0])))


@pytest.mark.parametrize("width", [1, 2, 3])
def test_sliced_programs_solve_as_the_programs_do(width):
    """A program laid out in slices of ``width`` rows (their entries interleaved, a level's last
    slice padded), every other level kept contiguous, run task by task as the
    kernels read it: the same solve, and each entry placed once."""
    sim = bent([beam(cells=24)])
    assembly = sim.solver.assembly
    L, _ = CholmodFactor(assembly, ordering="nested_dissection").lower(assembly.values())
    b = np.random.default_rng(4).standard_normal((assembly.size, 2))
    for program in Supernodal(L).programs(L):
        contiguous = np.arange(program.levels) % 2 == 1
        s = sliced(program, width, contiguous)
        assert len(np.unique(s.place)) == len(program.val) and s.place.max() < s.size
        val, col = np.zeros(s.size), np.zeros(s.size, dtype=np.int64)
        val[s.place], col[s.place] = program.val, program.col
        out = np.zeros_like(b)
        assert np.all(np.diff(s.level) >= 0) and np.array_equal(np.unique(s.row[s.row >= 0]), np.arange(assembly.size))
        for t in range(len(s.row)):
            if s.row[t] >= 0:
                e0, e1, e2, step = *s.start[t], 1 if contiguous[s.level[t]] else width
                out[s.row[t]] = val[e0:e1:step] @ b[col[e0:e1:step]] + val[e1:e2:step] @ out[col[e1:e2:step]]
        assert np.abs(out - program.run(b)).max() < 1e-12 * np.abs(program.run(b)).max()
        # a sliced level's tasks come in whole slices: every world's start at a multiple of width
        for level in np.flatnonzero(~contiguous):
            assert np.sum(s.level == level) % width == 0


@pytest.mark.parametrize("layout", ["rows", "slices", "lanes", "sliced lanes", "panels"])
def test_a_shared_factor_serves_its_worlds_and_converged_ones_skip_it(layout, monkeypatch):
    """At rest the 1 and 3 MPa beams share a factor, the second's inverse scaled by 1/3; the
    product equals the host factor's. A world whose columns all converged is not touched. So
    with each row's entries one after another, as the CPU lays them out; in slices of 4 rows,
    as CUDA does (a warp of 32 there); with every level through the kernel that CUDA gives
    long rows, whose lanes add by warp shuffles (one lane a row here); and with the slices'
    rows through that kernel, as CUDA's tail runs them (their entries ``width`` apart); and as
    panels (up to 4 rows of a supernode a task, their columns read once). With few worlds
    running, their tasks alone, the same numbers; so too with a block a panel (CUDA's wide
    panels in the tail; one thread a block here)."""
    sim = ws.Simulator(ws.finalize([beam(), beam(3e6), beam(cells=16)]), solver="direct")
    sim.rot.assign(np.tile(np.eye(3), (sim.model.num_elements, 1, 1)))  # linearized at rest
    pre = WorldFactors(sim.operator, 2, "float64", layout="panels" if layout == "panels" else "rows")
    unrolled = "panel_unroll" if layout == "panels" else "unroll"  # (the attribute of the columns loaded at a time)
    if layout == "lanes":
        pre.lanes, pre.lanes_from = 1, 0.0
    if layout == "sliced lanes":  # (the lanes' kernel with one lane: the CPU has no shuffles)
        monkeypatch.setattr(kernels, "level_kernel", lambda k, dtype, step, unroll, whole, compact, entry:
                            kernels.level_kernel_lanes(k, dtype, 1, unroll, whole, compact, step, entry))
    pre.width = 4 if layout in ("slices", "sliced lanes") else 1
    scal = wp.zeros((2, 3, NUM_SCALARS), dtype=wp.float64)
    pre.watch(scal)
    pre.prepare()
    assert list(pre.block_of) == [0, 0, 1] and abs(pre.scale_np[1] - 3.0) < 1e-9
    host = WarpedFactor(sim.operator, 2, "host")
    host.prepare()
    n = sim.model.num_nodes
    r = wp.array(np.random.default_rng(1).standard_normal((2, n, 3)), dtype=wp.vec3d)
    fresh, want = (wp.zeros((2, n), dtype=wp.vec3d) for _ in range(2))
    pre.apply(r, fresh)
    host.apply(r, want)
    assert np.abs(fresh.numpy() - want.numpy()).max() < 1e-10 * np.abs(want.numpy()).max()
    s = np.zeros((2, 3, NUM_SCALARS))
    s[:, 0, DONE] = 1.0
    scal.assign(s)
    pre.x.zero_()  # world 0's solved rows: only a fresh solve would fill them again
    z = wp.zeros((2, n), dtype=wp.vec3d)
    pre.apply(r, z)
    skipped = sim.model.node_world_np == 0
    assert np.all(z.numpy()[:, skipped] == 0.0)
    assert np.array_equal(z.numpy()[:, ~skipped], fresh.numpy()[:, ~skipped])
    # the entries a thread loads together, then sums in order, give the rounding of one at a time
    scal.zero_()
    for unroll in (1, 3):
        setattr(pre, unrolled, unroll)
        pre.apply(r, z)
        assert np.array_equal(z.numpy(), fresh.numpy())
    # operand rows indexed number by number, as CUDA reads them (the CPU reads them from their
    # address): the same numbers
    pre.whole_rows = False
    for unroll in (1, 3):
        setattr(pre, unrolled, unroll)
        pre.apply(r, z)
        assert np.array_equal(z.numpy(), fresh.numpy())
    # few worlds running: their tasks alone, launched for a tier of running worlds (1 or 2 of
    # them here, or never: every world's tasks): the same numbers, the others untouched; with
    # every world running, the branch whose panels do not test their world
    for done in ([], [0], [0, 1], [1]):
        s = np.zeros((2, 3, NUM_SCALARS))
        s[:, done, DONE] = 1.0
        scal.assign(s)
        skipped = np.isin(sim.model.node_world_np, done)
        for tiers, wide in (([], None), ([1], None), ([2], None), ([1, 2], None), ([1, 2], 0.0)):
            pre.tail(tiers)
            pre.wide_from = wide  # (0: every level of the tail's, as wide panels)
            pre.x.zero_()
            z.zero_()
            pre.apply(r, z)
            assert np.all(z.numpy()[:, skipped] == 0.0)
            assert np.array_equal(z.numpy()[:, ~skipped], fresh.numpy()[:, ~skipped]), (done, tiers)
    with pytest.raises(ValueError, match=r"the tail's tiers must ascend, got \[2, 1\]"):
        pre.tail([2, 1])
    pre.lanes = 2  # (lanes add by warp shuffles: CUDA's)
    with pytest.raises(ValueError, match="2 lanes a row add by warp shuffles"):
        pre.apply(r, z)


def test_columns_take_16_bits_where_every_factor_has_room_and_32_elsewhere(monkeypatch):
    """An entry's column is a place of its factor: 16 bits hold the beams' (and a Diamond's), and
    the product is the one of 32-bit columns, which a factor of more places than the narrow
    limit takes (the limit lowered here below the beams' places)."""
    sim = bent([beam(), beam(3e6), beam(cells=16)])
    n = sim.model.num_nodes
    r = wp.array(np.random.default_rng(2).standard_normal((2, n, 3)), dtype=wp.vec3d)
    got = {}
    for narrow in (factors.NARROW_PLACES, 10):
        monkeypatch.setattr(factors, "NARROW_PLACES", narrow)
        pre = WorldFactors(sim.operator, 2, "float64")
        pre.watch(wp.zeros((2, 3, NUM_SCALARS), dtype=wp.float64))
        pre.prepare()
        z = wp.zeros((2, n), dtype=wp.vec3d)
        pre.apply(r, z)
        got[pre.index_dtype] = z.numpy().copy()
        assert all(s[1].dtype == pre.index_dtype for s in pre.solves)
    assert set(got) == {wp.uint16, wp.int32}
    assert np.array_equal(got[wp.uint16], got[wp.int32]) and np.abs(got[wp.int32]).max() > 0


def test_each_world_steps_as_alone_and_as_with_dense_blocks(monkeypatch):
    """Four designs stepped with the factors: each world as it steps alone (its positions and
    its CG iterations), and as with the dense inverses per world (the same preconditioner,
    another way to apply it, rounded otherwise: its first step's solves take 83-113 iterations,
    whose count the rounding moves by up to 2 (one BLAS thread or two for the factors' products
    gave 109 or 110 against the dense inverse's 111); 2 apart at most). No world refactorizes
    alone here: the first two share a block, which alone they would not."""
    monkeypatch.setattr(factors, "WORLD_FLOOR", None)
    scenes = four_designs()
    runs = {}
    for pre in ("factors", "blocks"):
        sim = ws.Simulator(ws.finalize(scenes), solver="pcg", preconditioner=pre, precision="float64",
                           tolerance=1e-10)
        runs[pre] = (sim, [sim.step() for _ in range(3)])
    sim, together = runs["factors"]
    assert isinstance(sim.solver.precond, WorldFactors)
    alone = steps_as_alone(scenes, sim, together, "factors", 0)
    dense_sim, dense = runs["blocks"]
    for w, q in enumerate(alone):
        its = np.subtract([s.worlds[w].cg_iterations for s in dense], [s.worlds[w].cg_iterations for s in together])
        assert np.abs(its).max() <= 2
        moved = np.abs(q - sim.model.rest_np[sim.model.world_nodes(w)]).max()
        assert np.abs(dense_sim.positions(w) - q).max() < 1e-8 * moved


def test_nested_dissection_keeps_the_levels_from_growing_with_the_length():
    """A beam twice as long: CHOLMOD's own ordering (AMD) makes an elimination tree whose depth,
    so the solves' levels, grows with the length (31 -> 67 here); nested dissection halves the
    beam by a cross-section, recursively, so its levels grow by a step or two (10 -> 10). That is
    the launches of every CG iteration on the device. CHOLMOD's options are left as they were."""
    from cvxopt import cholmod

    before = dict(cholmod.options)
    levels = {}
    for cells in (24, 48):
        sim = bent([beam(cells=cells)])
        values = sim.solver.assembly.values()
        for ordering in ("cholmod", "nested_dissection"):
            L, _ = CholmodFactor(sim.solver.assembly, ordering=ordering).lower(values)
            levels[ordering, cells] = Supernodal(L).levels[0]
    assert levels["cholmod", 48] > 1.8 * levels["cholmod", 24]
    assert levels["nested_dissection", 48] <= levels["nested_dissection", 24] + 2
    assert levels["nested_dissection", 48] < levels["cholmod", 48] / 3
    assert dict(cholmod.options) == before


def test_bad_input_is_named():
    sim = bent([beam()])
    with pytest.raises(ValueError, match="WorldFactors: precision must be 'float64' or 'float32', got 'half'"):
        WorldFactors(sim.operator, 1, "half")
    with pytest.raises(ValueError, match="WorldFactors: ordering must be one of .*, got 'metis'"):
        WorldFactors(sim.operator, 1, ordering="metis")
    with pytest.raises(ValueError, match="WorldFactors: layout must be 'rows' or 'panels', got 'columns'"):
        WorldFactors(sim.operator, 1, layout="columns")
    with pytest.raises(ValueError, match="CholmodFactor: ordering must be one of .*, got 'amd'"):
        CholmodFactor(sim.solver.assembly, ordering="amd")
    with pytest.raises(ValueError, match="auto, host, dense, blocks, factors, got 'factor'"):
        ws.Simulator(beam(), solver="pcg", preconditioner="factor")


def test_each_level_kernel_is_its_own():
    """The kernels of a step of 32 and of 32 lanes are cached apart (one key once served both:
    the slices then ran through the lanes' kernel on CUDA, and met NaN)."""
    assert kernels.level_kernel(2, wp.float32, 32) is not kernels.level_kernel_lanes(2, wp.float32, 32)
    assert kernels.level_kernel(2, wp.float32, 32) is kernels.level_kernel(2, wp.float32, 32)


def _product(scenes, workers):
    """The factors' product of one random ``r`` for the designs linearized at rest, with
    ``workers`` processes factorizing; and the preconditioner."""
    sim = ws.Simulator(ws.finalize(scenes), solver="direct")
    sim.rot.assign(np.tile(np.eye(3), (sim.model.num_elements, 1, 1)))
    pre = WorldFactors(sim.operator, 2, "float64")
    pre.workers = workers
    pre.watch(wp.zeros((2, sim.model.num_worlds, NUM_SCALARS), dtype=wp.float64))
    pre.prepare()
    r = wp.array(np.random.default_rng(2).standard_normal((2, sim.model.num_nodes, 3)), dtype=wp.vec3d)
    z = wp.zeros_like(r)
    pre.apply(r, z)
    return z.numpy(), pre


@pytest.mark.parametrize("ahead, fits", [(4, True), (1, True), (4, False)])
def test_worker_processes_factorize_as_the_host_does(monkeypatch, ahead, fits):
    """Three different meshes, their blocks factorized by two forked processes: the same
    orderings and the same product, to the bit, as factorized here one after another. Their
    programs come back through the shared slots where they fit (a slot is the largest element
    blocks' size: the 12-cell beam's programs take about half of it), else pickled (``fits``
    False: none fits); with one slot a worker, the third block's slot is the first's, reused once
    its programs were taken."""
    from warpsoft.linear import factors

    monkeypatch.setattr(factors, "POOL_FROM", 2)
    monkeypatch.setattr(factors, "AHEAD", ahead)
    if not fits:
        monkeypatch.setattr(factors, "_placed_bytes", lambda result: 1 << 62)
    pools, placed = [], []
    real, taken = factors.ProcessPoolExecutor, factors._taken
    monkeypatch.setattr(factors, "ProcessPoolExecutor", lambda *a, **k: pools.append(a) or real(*a, **k))
    monkeypatch.setattr(factors, "_taken", lambda arena, future, device: placed.append(
        isinstance(future.result()[0], factors._Placed)) or taken(arena, future, device))
    scenes = [beam(cells=c) for c in (12, 16, 20)]
    here, pre_here = _product(scenes, 1)
    assert not pools and not placed
    there, pre_there = _product(scenes, 2)
    assert pools == [(2,)] and len(placed) == 3 and placed[0] == fits and (fits or not any(placed))
    assert np.array_equal(here, there) and np.abs(here).max() > 0
    assert all(np.array_equal(a, b) for a, b in zip(pre_here.orders, pre_there.orders, strict=True))


@pytest.mark.parametrize("workers", [1, 2])
def test_a_block_not_positive_definite_names_its_world(monkeypatch, workers):
    """A block whose factorization fails is reported with the world (and scene) it serves, here
    and from a worker process."""
    from warpsoft.linear import factors

    monkeypatch.setattr(factors, "POOL_FROM", 2)

    real = factors.factor_programs

    def failing(sparsity, values, ordering, panel_rows=0, kept=None):
        if sparsity.size == 3 * 17 * 3 * 3 - 27:  # the 16-cell beam's free DOFs
            raise ArithmeticError("3")
        return real(sparsity, values, ordering, panel_rows, kept)

    monkeypatch.setattr(factors, "factor_programs", failing)
    with pytest.raises(ws.SceneError, match="WorldFactors: world 1 \\(scene 'beam'\\): its system is not positive"):
        _product([beam(cells=12), beam(cells=16)], workers)


def test_a_world_whose_cg_grew_is_refactorized_alone():
    """Factorized at one state, the four designs then bend further. A world whose CG count grew
    past the floor marks its block due; the refresh between steps factorizes that block alone, at
    the world's current rotations (installed at the same boundary, with a lag of 0): its ``P^-1``
    is then the host factor's at the current state (to round-off), while the other worlds keep the
    warped factor of the old state."""
    sim = ws.Simulator(ws.finalize(four_designs()), solver="direct")
    sim.step()
    pre = WorldFactors(sim.operator, 3, "float64", share=False)
    assert (pre.world_floor, pre.world_ratio, pre.world_lag) == (factors.WORLD_FLOOR, factors.WORLD_RATIO,
                                                                 factors.WORLD_LAG) == (10, 1.5, 2)  # (on by default)
    pre.world_ratio, pre.world_lag = 2.0, 0
    pre.prepare()  # factorized at the first step's state
    for _ in range(3):
        sim.step()
    pre.prepare()  # the node rotations now (not stale: no factorization)
    assert pre.refresh_worlds() == 0  # nothing observed, nothing due
    pre.observe_worlds(np.array([6, 6, 6, 6]))  # each world's first solve after its factorization
    pre.observe_worlds(np.array([6, 6 * 2 + 1, 6, 12]))  # world 1: more than twice and than the floor
    assert pre.refresh_worlds() == 1 and pre.world_refreshes == 1 and pre.refreshes == 1
    host = WarpedFactor(sim.operator, 3, "host")
    host.prepare()  # the whole model factorized at the current state
    r = wp.array(np.random.default_rng(3).standard_normal((3, sim.model.num_nodes, 3)), dtype=wp.vec3d)
    want, got = wp.zeros_like(r), wp.zeros_like(r)
    host.apply(r, want)
    pre.apply(r, got)
    want, got = want.numpy(), got.numpy()
    for w in range(4):
        nodes = sim.model.world_nodes(w)
        error = np.abs(got[:, nodes] - want[:, nodes]).max() / np.abs(want[:, nodes]).max()
        assert (error < 1e-9) if w == 1 else (error > 1e-6), (w, error)
    assert np.allclose(pre.q_rot.numpy()[sim.model.world_nodes(1)], np.eye(3), atol=1e-12)
    assert pre.refresh_worlds() == 0  # done: nothing due until its count grows again


def test_a_world_alone_in_its_block_leaves_the_whole_model_to_the_worlds_that_share_one():
    """With the worlds' own refreshes on, a world alone in its block whose CG grew past the whole
    model's rule is left to its own refresh: nothing marks every block stale (with 1024 Diamonds
    that one step took 30 s). A world that shares a block still does, by the same rule (past
    ``refresh_ratio`` times the shared worlds' first count and ``refresh_floor``). With them off,
    a solve's count (its slowest world's) does, as in :class:`WarpedFactor`."""
    sim = ws.Simulator(ws.finalize(four_designs()), solver="direct")
    sim.rot.assign(np.tile(np.eye(3), (sim.model.num_elements, 1, 1)))  # linearized at rest
    pre = WorldFactors(sim.operator, 3, "float64")  # worlds 0 and 1 proportional there: one block
    pre.prepare()
    assert list(pre.block_of) == [0, 0, 1, 2] and pre.refreshes_alone
    assert (pre.refresh_ratio, pre.refresh_floor) == (2.0, 40)
    pre.observe(6)
    pre.observe_worlds(np.array([6, 6, 6, 6]))
    pre.observe(100)  # world 3's count, alone in its block
    pre.observe_worlds(np.array([6, 6, 6, 100]))
    assert not pre.stale and pre.worlds_due  # its own refresh, not the whole model's
    pre.observe(40)
    pre.observe_worlds(np.array([6, 40, 6, 6]))  # world 1 shares block 0: not past the floor
    assert not pre.stale
    pre.observe(41)
    pre.observe_worlds(np.array([6, 41, 6, 6]))
    assert pre.stale
    pre.prepare()
    assert pre.refreshes == 2 and not pre.stale
    pre.world_floor = None  # no own refreshes: the slowest world's count, whichever world
    assert not pre.refreshes_alone
    pre.observe(6)
    pre.observe_worlds(np.array([6, 6, 6, 6]))
    pre.observe(41)
    assert pre.stale


def factorized_then_stepped(steps: int, **settings) -> tuple:
    """The four designs after a step, their factors made there (float64, one block a world) with
    ``settings`` (attributes of the factors), then ``steps`` steps on, the node rotations taken
    there. Returns the simulator and the factors."""
    sim = ws.Simulator(ws.finalize(four_designs()), solver="direct")
    sim.step()
    pre = WorldFactors(sim.operator, 3, "float64", share=False)
    for name, value in settings.items():
        setattr(pre, name, value)
    pre.prepare()
    for _ in range(steps):
        sim.step()
    pre.prepare()
    return sim, pre


def test_a_world_installed_beside_a_solve_passes_over_that_solves_count():
    """The step refreshes the worlds beside its first solve (``solving``): that solve ran on the
    old factors, so the count it reports for a world installed meanwhile neither marks it due again
    nor starts its new factor's count; the world's next solve does."""
    _, pre = factorized_then_stepped(2, world_ratio=2.0, world_lag=0)
    pre.observe_worlds(np.array([6, 6, 6, 6]))
    pre.observe_worlds(np.array([6, 13, 6, 6]))  # world 1 due
    assert pre.refresh_worlds(solving=True) == 1
    pre.observe_worlds(np.array([6, 30, 6, 6]))  # the solve in flight: world 1 on its old factor
    assert not pre.worlds_due  # not due again
    pre.observe_worlds(np.array([6, 7, 6, 6]))  # its first solve on the new factor: 7 to grow from
    pre.observe_worlds(np.array([6, 14, 6, 6]))
    assert not pre.worlds_due  # (14 is not more than twice 7)
    pre.observe_worlds(np.array([6, 15, 6, 6]))
    assert pre.worlds_due and pre.refresh_worlds() == 1


def test_a_boundary_sends_the_slowest_worlds_first_and_at_most_its_batch():
    """With a batch of one block a boundary, of two worlds due the one whose CG took more goes
    first (its frame becomes its current rotations); the other, still grown at its next solve,
    goes at the next boundary."""
    sim = ws.Simulator(ws.finalize(four_designs()), solver="direct")
    sim.step()
    pre = WorldFactors(sim.operator, 3, "float64", share=False)
    assert pre.world_batch == factors.WORLD_BATCH == 16
    pre.world_floor, pre.world_lag, pre.world_batch = 10, 0, 1
    pre.prepare()
    for _ in range(3):
        sim.step()
    pre.prepare()

    def turned(w: int) -> bool:  # world w's nodes turned from the frame of its factor
        return not np.allclose(pre.q_rot.numpy()[sim.model.world_nodes(w)], np.eye(3), atol=1e-12)

    assert turned(1) and turned(3)  # (both moved since their factorization)
    pre.observe_worlds(np.array([6, 6, 6, 6]))
    pre.observe_worlds(np.array([6, 13, 6, 15]))  # worlds 1 and 3 due, 3 the slower
    assert pre.refresh_worlds() == 1 and not turned(3) and turned(1)
    pre.observe_worlds(np.array([6, 13, 6, 6]))  # (world 3's first solve on its new factor)
    assert pre.refresh_worlds() == 1 and not turned(1) and pre.world_refreshes == 2
    assert pre.refresh_worlds() == 0


def test_a_world_refactorized_beside_the_step_is_installed_a_boundary_later():
    """With a lag of 1, a block found due at one boundary is factorized (by a worker) at that
    state and installed at the next boundary, whatever the worlds did in between: until then its
    world's ``P^-1`` is unchanged; then the world's frame is its node rotations of the state
    factorized, and its ``Q`` turns from those to the current ones."""
    sim, pre = factorized_then_stepped(2, world_floor=10, world_lag=1)
    r = wp.array(np.random.default_rng(4).standard_normal((3, sim.model.num_nodes, 3)), dtype=wp.vec3d)
    before, after = wp.zeros_like(r), wp.zeros_like(r)
    pre.apply(r, before)
    pre.observe_worlds(np.array([6, 6, 6, 6]))
    pre.observe_worlds(np.array([6, 6, 13, 6]))  # world 2 due
    factorized = pre.node_rot.numpy().copy()  # the rotations of the state it is factorized at
    frame = pre.frame.numpy().copy()  # (on the CPU, numpy() is a view)
    assert pre.refresh_worlds() == 0 and pre.worlds_due  # sent: pending until the next boundary
    pre.apply(r, after)
    assert np.array_equal(before.numpy(), after.numpy())  # nothing installed yet
    sim.step()
    pre.prepare()  # a later state
    now = pre.node_rot.numpy()
    assert pre.refresh_worlds() == 1 and not pre.worlds_due and pre.world_refreshes == 1
    nodes = sim.model.world_nodes(2)
    others = np.ones(sim.model.num_nodes, dtype=bool)
    others[nodes] = False
    assert np.array_equal(pre.frame.numpy()[nodes], factorized[nodes])
    assert np.array_equal(pre.frame.numpy()[others], frame[others])
    assert np.abs(now[nodes] - factorized[nodes]).max() > 1e-6  # (the state moved on)
    q = pre.q_rot.numpy()[nodes]
    assert np.allclose(q, now[nodes] @ np.transpose(factorized[nodes], (0, 2, 1)), atol=1e-12)


def test_a_block_analysed_ahead_refactorizes_as_one_analysed_at_its_first():
    """With a world's own refresh on, the workers fork with the first factorization, and each
    analyses its blocks' supernodes while it has nothing to do, on a made-up matrix of the pattern
    (``refactor.warm``). A block's refactorization after that analysis writes the same panels, bit
    for bit, as one that analysed its own system, and finds the same supernodes."""
    import mmap

    from warpsoft.linear import refactor

    sim = ws.Simulator(ws.finalize(four_designs()), solver="direct")
    for _ in range(3):
        sim.step()
    pre = WorldFactors(sim.operator, 3, "float32", share=False)
    pre.world_floor = 10
    pre.prepare()
    assert pre.refactorizer is not None and pre.refactorizer.submitted == 0  # forked before any due
    m, b = sim.model, 2
    w = int(pre.first_world[b])
    info = pre.refactorizer.blocks[b]
    e0, e1 = int(m.world_elem_start[w]), int(m.world_elem_start[w + 1])
    blocks = wp.zeros(16 * (e1 - e0), dtype=wp.mat33d, device=m.device)
    pre.op.elastic.blocks(pre.op.rot, blocks, [(e0, e1)])  # the world's state three steps on
    (_, forward), (_, backward) = info.values  # (this block alone in a fresh arena: its element blocks, its values)
    values = ((8 * info.elements, forward), (8 * info.elements + 8 * -(-forward // 2), backward))
    local = refactor.Block(info.patterns, info.mesh, info.order, info.masses, info.elements, values)
    panels, supernodes = [], []
    for ahead in (True, False):
        arena, cache = mmap.mmap(-1, values[1][0] + 4 * backward), {}
        np.frombuffer(arena, np.float64, info.elements, 0)[:] = blocks.numpy().ravel()
        if ahead:
            refactor.warm(cache, b, local, pre.panel_rows)
            assert cache[b][1] is not None and pre.panel_rows in cache[b][1]._layouts  # before any real system
        refactor.refactor(cache, arena, b, local, 0, 2.0, 0.0, pre.panel_rows, np.float32)
        panels.append([np.frombuffer(arena, np.float32, n, o).copy() for o, n in local.values])
        supernodes.append(cache[b][1])
    for x, y in zip(*panels, strict=True):
        assert np.array_equal(x, y) and np.abs(x).max() > 0
    assert np.array_equal(supernodes[0].first, supernodes[1].first)
    assert np.array_equal(supernodes[0].indices, supernodes[1].indices)


@pytest.mark.parametrize("workers", [2, 1])
def test_a_world_refactorized_alone_not_positive_definite_names_its_world(monkeypatch, workers):
    """A world's own refactorization that fails, in a worker process or in this one, is reported
    where it is installed, with the world and its scene."""
    from warpsoft.linear import refactor

    class Failing(CholmodFactor):
        def lower(self, values):
            raise ArithmeticError("7")

    monkeypatch.setattr(refactor, "CholmodFactor", Failing)  # (before the workers fork)
    monkeypatch.setattr(factors, "WORKERS", workers)
    sim = ws.Simulator(ws.finalize(four_designs()), solver="direct")
    sim.step()
    pre = WorldFactors(sim.operator, 3, "float64", share=False)
    pre.world_floor, pre.world_lag = 10, 1  # (reported at the next boundary)
    pre.prepare()
    pre.observe_worlds(np.array([6, 6, 6, 6]))
    pre.observe_worlds(np.array([6, 6, 13, 6]))
    assert pre.refresh_worlds() == 0
    assert pre.refactorizer.workers == (2 if workers == 2 else 0)
    with pytest.raises(ws.SceneError, match="WorldFactors: world 2 \\(scene 'beam'\\): its system is not positive"):
        pre.refresh_worlds()


def test_worlds_refactorized_in_workers_step_as_in_this_process(monkeypatch):
    """The workers' factors are this process's: four designs refreshed world by world (a floor of
    1, a ratio of 1) step to the same positions, bit for bit, with two worker processes as with
    none; and so they do where a worker, or this process, keeps one block's analysis alone (the
    others dropped, analysed anew at their next refactorization), and where a worker has one
    slot for the element blocks (each job waits for the one before it to be answered)."""
    from warpsoft.linear import refactor

    monkeypatch.setattr(factors, "WORLD_FLOOR", 1)
    monkeypatch.setattr(factors, "WORLD_RATIO", 1.0)
    runs, kept, real = [], [], refactor._keep
    monkeypatch.setattr(refactor, "_keep", lambda cache, block, keep: kept.append(block) or real(cache, block, keep))
    waits, inside = [], [False]  # per answer read, whether a job was taking its slot
    slot_for, answer = refactor.Refactorizer._slot_for, refactor.Refactorizer._answer

    def taking(self, block, job):
        inside[0] = True
        try:
            return slot_for(self, block, job)
        finally:
            inside[0] = False

    monkeypatch.setattr(refactor.Refactorizer, "_slot_for", taking)
    monkeypatch.setattr(refactor.Refactorizer, "_answer", lambda self, k: waits.append(inside[0]) or answer(self, k))
    plain = refactor.KEEP_ANALYSES, refactor.SLOTS
    for workers, keep, slots in ((2, *plain), (1, *plain), (2, 1, plain[1]), (1, 1, plain[1]), (2, plain[0], 1)):
        monkeypatch.setattr(factors, "WORKERS", workers)
        monkeypatch.setattr(refactor, "KEEP_ANALYSES", keep)
        monkeypatch.setattr(refactor, "SLOTS", slots)
        waits.clear()
        sim = ws.Simulator(ws.finalize(four_designs()), solver="pcg", preconditioner="factors",
                           precision="float64", tolerance=1e-10, share_tolerance=0.0)
        stats = [sim.step() for _ in range(5)]
        pre = sim.solver.precond
        assert pre.world_refreshes > 0 and pre.refactorizer.workers == (workers if workers > 1 else 0)
        assert pre.refactorizer.keep == keep and len(pre.refactorizer._cache) <= keep
        assert all(len(k) == min(slots, 4 // workers) for k in pre.refactorizer.slots)  # (the blocks a worker)
        # (with one slot, a worker's second job waited there for its first; with more, none did)
        assert any(waits) == (slots == 1 and workers > 1) and min(pre.refactorizer._sent) > 1
        runs.append((sim.positions(), [s.cg_iterations for s in stats], pre.world_refreshes))
    for run in runs[1:]:
        assert np.array_equal(runs[0][0], run[0]) and runs[0][1:] == run[1:]
    assert len(set(kept)) > 1  # (this process refactorized more blocks than it kept analyses of)


def test_worlds_refactorized_alone_step_as_alone(monkeypatch):
    """With a world's own refresh on (a floor of 1, a ratio of 1: due whenever its CG takes more
    than right after its last factorization), three designs batched refresh world by world and
    each steps as it does alone, refreshing the same way: the same positions, the same CG counts
    to one (with no refresh at all, the 16-cell beam's second step takes 127 iterations batched and
    128 alone: its sums in another order, at the tolerance's edge)."""
    monkeypatch.setattr(factors, "WORLD_FLOOR", 1)
    monkeypatch.setattr(factors, "WORLD_RATIO", 1.0)
    scenes = [beam(3e6, static=False), beam(1e6, 0.3, static=False), beam(cells=16, static=False)]
    sim = ws.Simulator(ws.finalize(scenes), solver="pcg", preconditioner="factors", precision="float64",
                       tolerance=1e-10)
    together = [sim.step() for _ in range(5)]
    pre = sim.solver.precond
    assert pre.blocks == 3 and pre.refreshes == 1 and pre.world_refreshes > 0
    steps_as_alone(scenes, sim, together, "factors", 1)


def test_pages_locked_by_a_refactorizer_shut_down_in_a_capture_are_unlocked_after_it(monkeypatch):
    """A refactorizer shut down while its device captures a graph (the garbage collector may end one
    inside another simulator's capture: on the H200, the driver's unlock there broke that capture)
    leaves its pages locked, its arenas kept, and calls no driver; the next shut-down outside a
    capture unlocks those pages and its own, each on its device."""
    import mmap

    from warpsoft.linear import refactor

    calls = []

    class Driver:
        def cuMemHostUnregister(self, address):  # noqa: N802  (the driver's name)
            calls.append(address.value)

    class Device:  # (a CUDA device as the unlock sees it)
        def __init__(self, capturing):
            self.is_capturing = capturing

    monkeypatch.setattr(refactor, "_UNLOCK_LATER", [])
    monkeypatch.setattr(refactor.ctypes, "CDLL", lambda name: Driver())
    monkeypatch.setattr(refactor.wp, "ScopedDevice", lambda device: contextlib.nullcontext())
    capturing, arenas = Device(True), [mmap.mmap(-1, 4096)]
    locked = [4096, 8192]
    refactor._shut_down([], locked, capturing, arenas)
    assert calls == [] and locked == [] and refactor._UNLOCK_LATER == [(capturing, [4096, 8192], arenas)]
    refactor._shut_down([], [12288], Device(False), [])  # (a second device's, outside a capture)
    assert calls == [12288] and len(refactor._UNLOCK_LATER) == 1  # (the first device still captures)
    capturing.is_capturing = False
    refactor._shut_down([], [16384], capturing, [])
    assert calls == [12288, 4096, 8192, 16384] and refactor._UNLOCK_LATER == []
