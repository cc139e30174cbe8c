"""Linear solvers: the warped-factorization PCG, the CHOLMOD direct path, the assembly."""

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla
import warp as wp
from warpsoft.kernels.linear.cg import DONE, NUM_SCALARS

import warpsoft as ws
from warpsoft.linear import PCG, SparseDirect, WarpedFactor, assembly
from warpsoft.linear.assembly import CholmodFactor
from warpsoft.linear.operator import AssembledBlocks

RUBBER = ws.Material(1e6, 0.45, 1000.0)


def bent_beam(static=False):
    scene = ws.Scene("bent", gravity=(0, 0, -9.81), dt=0.02, static=static)
    body = scene.add_body("beam", ws.box_grid((0, 0, 0), (0.1, 0.01, 0.01), (20, 2, 2)), RUBBER, element="corotational")
    scene.fix(body, ws.OnPlane((0, 0, 0), (1, 0, 0)))
    scene.add_force(body, ws.OnPlane((0.1, 0, 0), (1, 0, 0)), (0, 0, -0.2))
    return scene


def test_assembled_matrix_equals_the_matrix_free_operator():
    """The pattern-once assembly (lower triangle, index map) reproduces A x of the element
    kernels at a deformed state, so the factorizations solve the system CG iterates on; for one
    column (a thread per column and element) and for three (a thread per element for all)."""
    sim = ws.Simulator(bent_beam(), solver="direct")
    for _ in range(3):
        sim.step()
    sim.solver.prepare()
    A = sim.solver.assembly.matrix()
    free = sim.solver.assembly.free
    x = np.random.default_rng(1).standard_normal((3, sim.model.num_nodes, 3)) * sim.model.mask_np
    for k in (1, 3):
        xw = wp.array(x[:k], dtype=wp.vec3d, device=sim.model.device)
        y = wp.zeros_like(xw)
        sim.operator.apply(xw, y)
        for c in range(k):
            expect = (y.numpy()[c].reshape(-1) * sim.model.mask_np.reshape(-1))[free]
            assert np.abs(A @ x[c].reshape(-1)[free] - expect).max() < 1e-10 * np.abs(expect).max(), (k, c)
    assert abs(A - A.T).max() == 0.0


@pytest.mark.parametrize("operator", ["matrix_free", "assembled"])
@pytest.mark.parametrize("static", [False, True])
def test_the_operator_skips_the_converged_columns_of_their_worlds(static, operator):
    """``A x`` told which columns of which worlds have converged leaves those entries of ``y``
    as they were and computes every other one as the full product does: one column and three
    (the two element kernels, or the assembled blocks), with mass (dynamic) and without
    (quasi-static)."""
    sim = ws.Simulator([bent_beam(static), bent_beam(static)], solver="pcg", preconditioner="blocks",
                       operator=operator)
    sim.step()
    world = sim.model.node_world_np
    x = np.random.default_rng(3).standard_normal((3, sim.model.num_nodes, 3))
    for k in (1, 3):
        xw = wp.array(x[:k], dtype=wp.vec3d)
        full = wp.zeros_like(xw)
        sim.operator.apply(xw, full)
        scal = np.zeros((k, 2, NUM_SCALARS))
        scal[0, 1, DONE] = 1.0  # column 0 of world 1
        scal[k - 1, 0, DONE] = float(k > 1)  # and, of three, the last column of world 0
        y = wp.array(np.full((k, sim.model.num_nodes, 3), 7.0), dtype=wp.vec3d)
        sim.operator.apply(xw, y, wp.array(scal, dtype=wp.float64))
        done = scal[:, :, DONE][:, world] > 0  # (k, nodes)
        got = y.numpy()
        assert done.any() and not done.all()
        assert np.all(got[done] == 7.0), k
        assert np.array_equal(got[~done], full.numpy()[~done]), k


def three_elements(stiffness: float = 1.0, static: bool = False) -> ws.Scene:
    """A beam of each element model side by side, clamped at x = 0 and sagging under gravity."""
    scene = ws.Scene("three", gravity=(0.0, 0.0, -9.81), dt=0.01, static=static)
    for k, element in enumerate(("corotational", "quadratic", "neohookean")):
        mesh = ws.box_grid((0.0, 0.03 * k, 0.0), (0.08, 0.03 * k + 0.01, 0.01), (8, 1, 1))
        body = scene.add_body(element, mesh, ws.Material(stiffness * 1e5, 0.45, 1000.0), element=element)
        scene.fix(body, ws.OnPlane((0.0, 0.0, 0.0), (1.0, 0.0, 0.0), tol=1e-9))
        scene.add_probe(f"tip_{element}", (0.08, 0.03 * k + 0.005, 0.005))
    return scene


@pytest.mark.parametrize("element", ["corotational", "quadratic", "neohookean"])
def test_the_blocks_of_ranges_of_elements_are_those_of_every_element(element):
    """Each element model's stiffness blocks of some ranges of elements (parts of two worlds, the
    later one first), made in one launch, are those the whole model's launch makes for the same
    elements, bit for bit, at a sagged state."""
    scenes = []
    for stiffness in (1.0, 3.0):
        scene = ws.Scene("beam", gravity=(0.0, 0.0, -9.81), dt=0.01)
        body = scene.add_body(element, ws.box_grid((0.0, 0.0, 0.0), (0.08, 0.01, 0.01), (8, 1, 1)),
                              ws.Material(stiffness * 1e5, 0.45, 1000.0), element=element)
        scene.fix(body, ws.OnPlane((0.0, 0.0, 0.0), (1.0, 0.0, 0.0), tol=1e-9))
        scenes.append(scene)
    sim = ws.Simulator(scenes, solver="direct")
    for _ in range(3):
        sim.step()
    elastic, group = sim.elastic, sim.elastic.groups[0].group
    per = elastic.groups[0].nodes_per_element ** 2  # blocks an element
    full = wp.zeros(per * group.count, dtype=wp.mat33d)
    elastic.blocks(sim.rot, full)
    start = np.searchsorted(group.world.numpy(), [0, 1, 2])  # each world's first element of the group
    ranges = [(int(start[1]) + 2, int(start[2])), (int(start[0]), int(start[0]) + 5)]
    some = wp.zeros(per * sum(hi - lo for lo, hi in ranges), dtype=wp.mat33d)
    elastic.blocks(sim.rot, some, ranges)
    want = np.concatenate([full.numpy()[per * lo:per * hi] for lo, hi in ranges])
    assert np.abs(want).max() > 0 and np.array_equal(some.numpy(), want)


@pytest.mark.parametrize("static", [False, True])
def test_the_assembled_operator_applies_every_element_model_as_the_matrix_free_one(static):
    """The 3x3 node blocks gathered from the element models' blocks (linear and 10-node tets,
    corotational and Neo-Hookean, in two worlds of different stiffness) give the element kernels'
    ``A x`` at a sagged state, for one column and five, whatever the rows a chunk (1, the CPU's;
    4; 32, CUDA's: the padding adds nothing), and for float32 columns the product of their values
    in float64; the stored matrix is symmetric."""
    sim = ws.Simulator([three_elements(1.0, static), three_elements(3.0, static)], solver="pcg",
                       preconditioner="host", operator="assembled")
    for _ in range(3):
        sim.step()
    own = sim.operator.blocks
    assert own is not None and own.chunk_rows == 1 and len(sim.elastic.groups) == 3
    x = np.random.default_rng(5).standard_normal((5, sim.model.num_nodes, 3))
    single = x.astype(np.float32)
    for chunk_rows in (1, 4, 32):
        blocks = AssembledBlocks(sim.model, sim.elastic, chunk_rows=chunk_rows)
        blocks.refresh(sim.rot)
        assert (blocks.num_slots > blocks.filled) == (chunk_rows > 1) and blocks.filled == own.filled
        for k in (1, 5):
            for columns, dtype in ((x, wp.vec3d), (single, wp.vec3f)):
                xw = wp.array(columns[:k], dtype=dtype)
                assembled = wp.zeros(xw.shape, dtype=wp.vec3d)
                sim.operator.blocks = blocks
                sim.operator.apply(xw, assembled)
                sim.operator.blocks = None  # the same operator, element by element, on the same numbers
                free = wp.zeros_like(assembled)
                sim.operator.apply(wp.array(columns[:k].astype(np.float64), dtype=wp.vec3d), free)
                expect = free.numpy()
                assert np.abs(assembled.numpy() - expect).max() < 1e-12 * np.abs(expect).max(), (chunk_rows, k)
        assert all(np.array_equal(a, b) for a, b in zip(blocks.by_rows(), own.by_rows(), strict=True))
    sim.operator.blocks = own
    with pytest.raises(ValueError, match="matrix-free product takes vec3d"):
        sim.operator.blocks = None
        sim.operator.apply(wp.array(single, dtype=wp.vec3f), wp.zeros(x.shape[:2], dtype=wp.vec3d))
    rows, cols, values = own.by_rows()
    slot = {(int(i), int(j)): s for s, (i, j) in enumerate(zip(rows, cols, strict=True))}
    transposed = values[[slot[(int(j), int(i))] for i, j in zip(rows, cols, strict=True)]].transpose(0, 2, 1)
    assert np.abs(values - transposed).max() < 1e-12 * np.abs(values).max()


def test_the_assembled_structure_found_world_group_by_group_is_one_groups(monkeypatch):
    """The slots found in groups of whole worlds side by side (nine beams of different lengths in
    up to four groups, in threads) are those found in one group: the same places, columns, chunks,
    starts and element blocks in the same order; and the product is the element kernels'."""
    from warpsoft import processes
    from warpsoft.linear import operator

    from .test_blocks import beam

    sim = ws.Simulator(ws.finalize([beam(cells=c) for c in range(4, 13)]), solver="direct")
    monkeypatch.setattr(processes, "THREADED_FROM", 1)
    made = {}
    for cores in (1, 4):
        monkeypatch.setattr(operator, "usable_cores", lambda c=cores: c)
        monkeypatch.setattr(processes, "usable_cores", lambda c=cores: c)
        assert len(operator._world_groups(sim.model, sim.elastic)) == cores
        made[cores] = AssembledBlocks(sim.model, sim.elastic, chunk_rows=4)
    one, four = made[1], made[4]
    assert one.filled == four.filled and np.array_equal(one.place, four.place)
    for name in ("chunk_start", "chunk_slots", "column", "slot_start", "contributions"):
        assert np.array_equal(getattr(one, name).numpy(), getattr(four, name).numpy()), name
    x = wp.array(np.random.default_rng(4).standard_normal((2, sim.model.num_nodes, 3)), dtype=wp.vec3d)
    sim.rot.assign(np.tile(np.eye(3), (sim.model.num_elements, 1, 1)))  # (at rest)
    four.refresh(sim.rot)
    assembled, free = wp.zeros_like(x), wp.zeros_like(x)
    four.apply(x, assembled, 0.0, 1.0)
    sim.operator.stiffness_scale, sim.operator.mass_scale = 1.0, 0.0
    sim.operator.apply(x, free)
    assert np.abs(assembled.numpy() - free.numpy()).max() < 1e-12 * np.abs(free.numpy()).max()


def test_the_fused_refresh_sums_the_blocks_the_element_model_writes():
    """Corotational blocks formed in each slot's thread (CUDA's way) sum to what the element
    blocks written first and gathered give (the CPU's), on two bent beams of different stiffness."""
    stiff = bent_beam()
    stiff.bodies[0].material = ws.Material(3e6, 0.45, 1000.0)
    sim = ws.Simulator([bent_beam(), stiff], solver="pcg", preconditioner="blocks")
    for _ in range(3):
        sim.step()
    fused, stored = (AssembledBlocks(sim.model, sim.elastic, fused=f) for f in (True, False))
    assert fused.fused and not stored.fused and fused.memory_bytes < stored.memory_bytes
    for blocks in (fused, stored):
        blocks.refresh(sim.rot)
    want = stored.values.numpy()
    assert np.abs(fused.values.numpy() - want).max() < 1e-13 * np.abs(want).max()


def test_assembled_and_matrix_free_steps_agree():
    """Eight dynamic steps of the three beams with the PCG: the assembled operator moves the
    probes as the matrix-free one does, to the solver's tolerance, in as many iterations (one apart)."""
    runs = {}
    for operator in ("matrix_free", "assembled"):
        sim = ws.Simulator(three_elements(), solver="pcg", preconditioner="host", tolerance=1e-9, operator=operator)
        its = [sim.step().cg_iterations for _ in range(8)]
        runs[operator] = (np.array(list(sim.probe_positions().values())), its)
    (p_free, its_free), (p_asm, its_asm) = runs["matrix_free"], runs["assembled"]
    motion = np.abs(p_free - three_elements_rest()).max()
    assert motion > 1e-4  # they sag
    assert np.abs(p_asm - p_free).max() < 1e-6 * motion
    assert max(abs(a - b) for a, b in zip(its_free, its_asm, strict=True)) <= 1


def three_elements_rest() -> np.ndarray:
    """The probes of :func:`three_elements` at rest (m)."""
    return np.array([[0.08, 0.03 * k + 0.005, 0.005] for k in range(3)])


def test_bad_operator_name_is_named():
    with pytest.raises(ws.SceneError, match="operator must be one of auto, matrix_free, assembled, got 'dense'"):
        ws.Simulator(bent_beam(), operator="dense")


def test_cholmod_and_superlu_factorizations_agree():
    sim = ws.Simulator(bent_beam(), solver="direct")
    sim.step()
    b = np.random.default_rng(2).standard_normal((3, sim.model.num_nodes, 3))
    solutions = []
    for name in ("cholmod", "superlu"):
        direct = SparseDirect(sim.operator, name)
        direct.prepare()
        solutions.append(direct.solve_array(b))
    assert np.abs(solutions[0] - solutions[1]).max() < 1e-9 * np.abs(solutions[1]).max()
    assert np.all(solutions[0].reshape(3, -1)[:, sim.model.mask_np.ravel() == 0] == 0.0)


def test_a_factor_per_world_solves_and_gives_the_compliance_of_the_whole_factor(monkeypatch):
    """Three beams (the middle one stiffer) as worlds, bent: one CHOLMOD factor per world solves
    as the factor of the whole block-diagonal A does, and its forward solves give the same
    B^T A^-1 B for columns that each lie in one world; so does ``gram``, from its dense block of
    Z's rows and from the sparse product it falls back on."""
    scenes = [bent_beam(), bent_beam(), bent_beam()]
    scenes[1].bodies[0].material = ws.Material(3e6, 0.45, 1000.0)
    sim = ws.Simulator(ws.finalize(scenes, "cpu"), solver="direct")
    sim.step()
    direct = sim.solver
    direct.prepare()
    direct._ready()
    assert type(direct.factor).__name__ == "WorldsCholmod" and len(direct.factor.parts) == 3
    whole = CholmodFactor(direct.assembly)
    whole.factorize(direct.assembly.values())
    rng = np.random.default_rng(4)
    b = rng.standard_normal((direct.assembly.size, 5))
    x = direct.factor.solve(b)
    assert np.abs(x - whole.solve(b)).max() < 1e-10 * np.abs(x).max()
    # 6 columns, two per world, each on 12 random free DOFs of its world
    dof, column = [], []
    for k, (lo, hi) in enumerate(direct.factor.ranges * 2):
        dof.append(rng.choice(np.arange(lo, hi), 12, replace=False))
        column.append(np.full(12, k))
    dof, column = np.concatenate(dof), np.concatenate(column)
    value = rng.standard_normal(len(dof))
    zz = (lambda z: (z.T @ z).toarray())(direct.factor.forward(dof, column, value, 6))
    ref = (lambda z: (z.T @ z).toarray())(whole.forward(dof, column, value, 6))
    B = np.zeros((direct.assembly.size, 6))
    np.add.at(B, (dof, column), value)
    assert np.abs(zz - ref).max() < 1e-10 * np.abs(ref).max()
    assert np.abs(zz - B.T @ whole.solve(B)).max() < 1e-10 * np.abs(ref).max()
    assert np.all(zz[np.ix_([0, 3], [1, 2, 4, 5])] == 0.0)  # worlds do not couple
    for limit in (assembly.GRAM_DENSE_ENTRIES, 0):  # the dense block, then the sparse product
        monkeypatch.setattr(assembly, "GRAM_DENSE_ENTRIES", limit)
        for factor in (direct.factor, whole):
            gram = factor.gram(dof, column, value, 6)
            assert gram.shape == (6, 6) and np.abs(gram - ref).max() < 1e-10 * np.abs(ref).max()


def wide_beam(static=False):
    """bent_beam's beam on a coarser grid: another mesh."""
    scene = bent_beam(static)
    scene.bodies[0].mesh = ws.box_grid((0, 0, 0), (0.1, 0.01, 0.01), (10, 2, 2))
    return scene


@pytest.mark.parametrize("kind", ["one_group", "three_groups"])
def test_the_world_by_world_assembly_sums_the_element_blocks_of_the_whole_model(kind, monkeypatch):
    """``A`` assembled world by world (a pattern per mesh and supports, shared) is the sum of every
    element block of the whole model plus the scaled masses, over the free DOFs, at a bent state;
    forming the blocks a world at a time gives the same numbers to the bit. One element group (two
    beams of one mesh, different stiffness, and a coarser one) and three (each world a linear, a
    10-node and a Neo-Hookean beam)."""
    if kind == "one_group":
        stiff = bent_beam()
        stiff.bodies[0].material = ws.Material(3e6, 0.45, 1000.0)
        scenes, same = [bent_beam(), stiff, wide_beam()], [(0, 1)]
    else:
        scenes, same = [three_elements(1.0), three_elements(3.0)], [(0, 1)]
    sim = ws.Simulator(scenes, solver="direct")
    for _ in range(3):
        sim.step()
    sim.solver.prepare()
    asm, op, m = sim.solver.assembly, sim.operator, sim.model
    for a, b in same:
        assert asm.patterns[a] is asm.patterns[b]
    assert len({id(p) for p in asm.patterns}) == len(scenes) - len(same)
    blocks = wp.zeros(op.elastic.num_blocks, dtype=wp.mat33d)
    op.elastic.blocks(op.rot, blocks)
    pairs = op.elastic.block_nodes()
    i, shape = np.arange(3), (len(pairs), 3, 3)  # entry (block, i, j) at (3 a + i, 3 b + j)
    rows = np.broadcast_to(3 * pairs[:, 0, None, None] + i[:, None], shape).ravel()
    cols = np.broadcast_to(3 * pairs[:, 1, None, None] + i[None, :], shape).ravel()
    n = 3 * m.num_nodes
    K = sp.coo_matrix((blocks.numpy().ravel(), (rows, cols)), shape=(n, n)).tocsc()
    A = op.stiffness_scale * K + op.mass_scale * sp.diags(np.repeat(m.mass_np, 3))
    want = A[asm.free][:, asm.free].toarray()
    got = asm.matrix().toarray()
    assert op.mass_scale > 0 and np.abs(got - want).max() < 1e-12 * np.abs(want).max()
    values = asm.values()
    monkeypatch.setattr(assembly, "CHUNK_BLOCKS", 1)  # a world's blocks at a time
    assert np.array_equal(asm.values(), values)


@pytest.mark.parametrize("k", [4, 10])
def test_the_pattern_of_node_blocks_is_the_pattern_of_their_entries(k):
    """Pattern.of_blocks, from the blocks' node pairs, equals the pattern made from every entry of
    them: the same slots, rows, columns and map from entries, with DOFs fixed along one axis or
    all three, elements of 4 and 10 nodes (two groups of blocks one after the other), and a block
    repeated by two elements."""
    from warpsoft.elastic import block_pairs
    from warpsoft.linear.pattern import Pattern

    rng = np.random.default_rng(k)
    nodes = 60
    elems = np.array([rng.choice(nodes, size=k, replace=False) for _ in range(40)])
    elems = np.concatenate([rng.permutation(nodes).reshape(-1, k), elems])  # every node in an element
    elems = np.concatenate([elems, elems[:3], rng.permuted(elems[5:9], axis=1)])
    pairs = np.concatenate([block_pairs(elems), block_pairs(elems[:7, :4])])
    free = rng.random(3 * nodes) > 0.15  # some nodes fixed along one axis, a few along all
    free[3 * nodes - 3:] = False
    rows = (3 * pairs[:, 0, None, None] + np.arange(3)[:, None]).repeat(3, axis=2).ravel()
    cols = (3 * pairs[:, 1, None, None] + np.arange(3)[None, :]).repeat(3, axis=1).ravel()
    whole, blocks = Pattern(rows, cols, free), Pattern.of_blocks(pairs, free)
    for name in ("free", "renum", "keep", "slot", "indices", "indptr", "columns", "diagonal"):
        assert np.array_equal(getattr(blocks, name), getattr(whole, name)), name
    assert blocks.nnz == whole.nnz and blocks.size == whole.size == free.sum()
    entries = rng.standard_normal(len(rows))
    assert np.array_equal(blocks.lower_values(entries), whole.lower_values(entries))


def test_a_wide_right_hand_side_is_solved_in_runs_of_columns(monkeypatch):
    """CHOLMOD solves a dense right-hand side of more than SOLVE_ENTRIES numbers in runs of
    columns (one whole solve crashed cvxopt on a 20916-DOF identity): the same numbers, and a
    single vector stays a vector."""
    import warpsoft.linear.assembly as assembly

    sim = ws.Simulator(bent_beam(), solver="direct")
    sim.step()
    factor = sim.solver.factor
    b = np.random.default_rng(5).standard_normal((factor.size, 50))
    whole = factor.solve(b)
    monkeypatch.setattr(assembly, "SOLVE_ENTRIES", 7 * factor.size)  # runs of 7 columns, the last of 1
    assert np.array_equal(factor.solve(b), whole)
    assert np.array_equal(factor.solve(b[:, 3]), whole[:, 3])


def test_bad_factorization_name_is_named():
    with pytest.raises(ValueError, match="factorization must be one of .*got 'lu'"):
        ws.Simulator(bent_beam(), solver="direct", factorization="lu")


def test_pcg_equals_direct_under_large_rotation_and_with_actuators():
    """Dynamic cable beam, bent well past small strain: PCG (host-applied warped factor)
    and the dense-inverse variant agree with the direct path to 1e-8 over the trajectory."""
    def run(solver, **kw):
        scene = bent_beam()
        body = scene.bodies[0]
        scene.add_cable("c", body, points=[(0.05, 0.005, 0.009), (0.095, 0.005, 0.009)],
                        pull_point=(-0.01, 0.005, 0.009), value=lambda t: 0.004 * min(t / 0.1, 1.0))
        sim = ws.Simulator(scene, solver=solver, tolerance=1e-12, **kw)
        for _ in range(8):
            stats = sim.step()
        return sim.state.positions() - sim.model.rest_np, stats

    ref, _ = run("direct")
    assert np.abs(ref).max() > 5e-3
    for kw in ({}, {"preconditioner": "dense"}):
        got, stats = run("pcg", **kw)
        assert stats.converged and 0 < stats.cg_iterations
        assert np.abs(got - ref).max() < 1e-8 * np.abs(ref).max()


def test_pcg_is_exact_at_its_factorization_and_reports_a_cap():
    """At rest the warped factor is A itself: one iteration. A deformed state with an
    iteration cap of 1 is reported as not converged (never silent)."""
    sim = ws.Simulator(bent_beam(static=True), solver="pcg", max_iterations=1, newton_iterations=1)
    stats = sim.step()
    assert stats.cg_iterations == 1 and stats.converged
    with pytest.warns(ws.ConvergenceWarning, match="stopped after 1 iterations"):
        stats = sim.step()
    assert not stats.converged and stats.cg_residual > 1e-6


def test_diamond_pulled_20mm_needs_at_most_60_iterations(scene_module):
    """DESIGN section 4: the rest factorization warped by node rotations keeps PCG in tens of
    iterations on the Diamond bent by a 20 mm cable (block Jacobi: hundreds). Solved from
    zero (no warm start) at the deformed state, the factorization taken at rest."""
    diamond = scene_module("scenes/diamond.py")
    params = {"cable_displacements": (0.02, 0.0, 0.0, 0.0), "ramp_time": 0.3}
    sim = ws.Simulator(diamond.build(**params), solver="direct")
    for _ in range(20):
        stats = sim.step()
    assert stats.actuator_delta["cable0"] == pytest.approx(0.02, rel=1e-4)
    q, v = sim.state.positions(), sim.state.v.numpy()

    counts = {}
    for solver in ("pcg", "jacobi"):
        other = ws.Simulator(sim.model, solver=solver, warm_start=False, max_iterations=3000, newton_iterations=1)
        other.step()  # linearized and factorized at rest
        other.state.q.assign(q)
        other.state.v.assign(v)
        stats = other.step()
        assert stats.converged
        counts[solver] = stats.cg_iterations
    assert counts["pcg"] <= 60
    assert counts["jacobi"] > 5 * counts["pcg"]


def test_direct_matrix_is_spd_like_scipy_says():
    """The assembled A of a dynamic step is symmetric positive definite (CHOLMOD's premise)."""
    sim = ws.Simulator(bent_beam(), solver="direct")
    sim.step()
    A = sim.solver.assembly.matrix()
    smallest = spla.eigsh(A, k=1, which="SA", return_eigenvectors=False)[0]
    assert smallest > 0


def test_refresh_keeps_the_dense_inverse_buffer_and_matches_the_host_factor():
    """A refresh refactorizes in place (a captured CUDA graph holds the buffer's address), and the
    dense inverse (float64) applies the same P^-1 as the host factor."""
    sim = ws.Simulator(bent_beam(), solver="pcg", preconditioner="dense", precision="float64")
    for _ in range(3):
        sim.step()
    pre = sim.solver.precond
    buffer = pre.inverse.ptr
    pre.refresh()
    assert pre.inverse.ptr == buffer and pre.refreshes == 2
    host = WarpedFactor(sim.operator, 1, "host")
    host.prepare()
    r = wp.array(np.random.default_rng(3).standard_normal((1, sim.model.num_nodes, 3)), dtype=wp.vec3d)
    z_dense, z_host = wp.zeros_like(r), wp.zeros_like(r)
    pre.apply(r, z_dense)
    host.apply(r, z_host)
    assert np.abs(z_dense.numpy() - z_host.numpy()).max() < 1e-9 * np.abs(z_host.numpy()).max()


@pytest.mark.parametrize("product, width", [("stream", 1), ("stream", 2), ("stream", 4), ("tiles", 1)])
def test_dense_products_apply_the_host_factor_to_every_column(product, width):
    """Both dense products (the symmetric inverse streamed down its columns, or tiled) apply
    ``Q A_f^-1 Q^T`` to each of several columns as the host factor does, on a turned body:
    to round-off in float64, to float32's precision in float32."""
    sim = ws.Simulator(bent_beam(), solver="direct")
    for _ in range(3):
        sim.step()
    r = wp.array(np.random.default_rng(5).standard_normal((3, sim.model.num_nodes, 3)), dtype=wp.vec3d)
    host = WarpedFactor(sim.operator, 3, "host")
    host.prepare()
    host.refresh()  # at the bent state's rotations, as the dense ones below
    z_host = wp.zeros_like(r)
    host.apply(r, z_host)
    want = z_host.numpy()
    for precision, tol in (("float64", 1e-9), ("float32", 1e-4)):
        pre = WarpedFactor(sim.operator, 3, "dense", precision, product=product, stream=(16, 2, width))
        pre.prepare()
        pre.refresh()
        z = wp.zeros_like(r)
        pre.apply(r, z)
        assert np.abs(z.numpy() - want).max() < tol * np.abs(want).max(), precision


def test_dense_products_serve_fewer_columns_than_they_were_built_for():
    """A solve bounded to its right-hand sides in use applies the preconditioner to the first
    ``k`` columns only: each dense product, compiled for that ``k``, equals the host factor on
    them; "auto" streams 2 columns and tiles 34 (more than STREAM_COLUMNS)."""
    from warpsoft.linear.warped import STREAM_COLUMNS
    sim = ws.Simulator(bent_beam(), solver="direct")
    for _ in range(3):
        sim.step()
    host = WarpedFactor(sim.operator, 40, "host")
    host.prepare()
    host.refresh()
    for k in (2, STREAM_COLUMNS + 2):
        r = wp.array(np.random.default_rng(6).standard_normal((k, sim.model.num_nodes, 3)), dtype=wp.vec3d)
        z_host = wp.zeros_like(r)
        host.apply(r, z_host)
        want = z_host.numpy()
        for product in ("stream", "tiles", "auto"):
            pre = WarpedFactor(sim.operator, 40, "dense", "float64", product=product, stream=(16, 2, 2),
                               tiles=(8, 32, 64, 1))
            pre.prepare()
            pre.refresh()
            z = wp.zeros_like(r)
            pre.apply(r, z)
            assert np.abs(z.numpy() - want).max() < 1e-9 * np.abs(want).max(), (k, product)


@pytest.mark.parametrize("branches", [False, True])
def test_a_bounded_pcg_solves_the_columns_in_use_and_leaves_the_others(branches):
    """``PCG.bound``: with 1 + count[0] = 3 right-hand sides in use of 12, those are solved as the
    direct solver solves them, the others keep their values and read as converged. Both ways of
    bounding run here: the count read on the host (CPU device: exactly 3 solved) and the size
    branches CUDA takes (``capture_if`` on a device count, which on the CPU device reads the
    condition: the smallest size holding 3, 8, is solved)."""
    sim = ws.Simulator(bent_beam(), solver="pcg", tolerance=1e-12)
    for _ in range(3):
        sim.step()
    n = sim.model.num_nodes
    solver = PCG(sim.operator, WarpedFactor(sim.operator, 12, "host"), 12, tolerance=1e-12)
    solver.branches = branches
    solver.prepare()
    count = wp.array([2], dtype=wp.int32)
    solver.bound(count, 1)
    rng = np.random.default_rng(7)
    b = rng.standard_normal((12, n, 3)) * sim.model.mask_np
    x = wp.array(np.full((12, n, 3), 7.0), dtype=wp.vec3d)
    res = solver.solve(wp.array(b, dtype=wp.vec3d), x)
    direct = SparseDirect(sim.operator)
    direct.prepare()
    solved = 8 if branches else 3
    want = direct.solve_array(b[:solved])
    got = x.numpy()
    assert res.converged and res.iterations > 1
    assert np.abs(got[:solved] - want).max() < 1e-9 * np.abs(want).max()
    assert np.all(got[solved:] == 7.0)  # never touched
    count.fill_(11)  # now every right-hand side: the largest size
    res = solver.solve(wp.array(b, dtype=wp.vec3d), x)
    assert res.converged
    assert np.abs(x.numpy() - direct.solve_array(b)).max() < 1e-9 * np.abs(want).max()


def test_pick_size_takes_the_smallest_size_that_holds_the_count():
    from warpsoft.kernels.linear.pcg import pick_size
    sizes = wp.array([8, 32, 128, 289], dtype=wp.int32)
    branch = wp.zeros(4, dtype=wp.int32)
    for count, chosen in ((0, 0), (7, 0), (8, 1), (31, 1), (100, 2), (127, 2), (128, 3), (288, 3), (400, 3)):
        wp.launch(pick_size, 1, inputs=[wp.array([count], dtype=wp.int32), 1, sizes, 289], outputs=[branch])
        assert branch.numpy().tolist() == [int(j == chosen) for j in range(4)], count
    wp.launch(pick_size, 1, inputs=[wp.array([40], dtype=wp.int32), 1, sizes, 20], outputs=[branch])
    assert branch.numpy().tolist() == [0, 1, 0, 0]  # no more than the 20 right-hand sides given


@pytest.mark.parametrize("element", ["corotational", "quadratic"])
def test_node_rotations_gathered_per_node_equal_the_elements_atomic_sums(scene_module, element):
    """The warped preconditioner's node rotations sum ``V_e R_e`` over each node's elements: a
    thread per node over its elements (CUDA's way) gives what the elements' atomic sums give (the
    CPU's), on a beam bent by 11 % of its length (its rotations far from the identity)."""
    scene = scene_module("scenes/validation/cantilever.py").build(tip_force=-0.05, mesh_size=0.01, element=element)
    sim = ws.Simulator(scene, solver="direct")
    sim.step()
    sums = []
    for gather in (True, False):
        for group in sim.elastic.groups:
            group.gather_rotations = gather
        node_sum = wp.zeros(sim.model.num_nodes, dtype=wp.mat33d)
        sim.elastic.node_rotations(sim.rot, node_sum)
        sums.append(node_sum.numpy())
    gathered, atomic = sums
    assert np.abs(gathered - atomic).max() < 1e-13 * np.abs(atomic).max()
    volume = np.linalg.det(atomic) ** (1 / 3)  # a node's elements' volume, for a sum of rotations
    turned = np.abs(atomic / volume[:, None, None] - np.eye(3)).max()
    assert turned > 0.05
