"""Kernels of the preconditioned CG whose loop stays on the device (solver ``pcg``).

Vectors are ``(k, n)`` arrays of vec3d (column ``c``, node ``i``); the CG scalars of column
``c`` in world ``w`` live in ``scal[c, w, slot]`` (slots in ``cg.py``). The preconditioner is
applied by its own kernels between these. The loop runs under ``wp.capture_while`` on
``active``: :func:`pcg_direction` clears it and :func:`pcg_scalars` sets it again while some
column of some world has not converged, so no host read is needed.

Dot products are reduced per thread block before they reach ``scal``: the reducing kernels
are launched with :func:`launch_nodes` over ``(k, node blocks)``, a block of
``NODES_PER_BLOCK`` consecutive nodes (one per thread on CUDA; the CPU device runs a block
as one thread that loops over them). A block whose nodes all belong to one world (all but
those that straddle a world's end, since worlds' nodes are contiguous) adds one sum per
slot; the others add node by node.
"""

import warp as wp

from .. import OPTIONS
from .cg import B2, DONE, ITS, PAP, R2, R2_LAST, RZ, RZ_NEW

wp.set_module_options(OPTIONS)

NODES_PER_BLOCK = wp.constant(256)
ITERATIONS = wp.constant(0)  # info[ITERATIONS]: iterations done by the current solve (the most of any column)
NONFINITE = wp.constant(1)  # info[NONFINITE]: 1 when a column met NaN or inf


def launch_nodes(kernel, columns: int, nodes: int, inputs: list, device) -> None:
    """Launch a reducing kernel over ``(columns, node blocks)``, ``NODES_PER_BLOCK`` threads each."""
    blocks = -(-nodes // NODES_PER_BLOCK)
    wp.launch_tiled(kernel, dim=(columns, blocks), inputs=inputs, block_dim=NODES_PER_BLOCK, device=device)


@wp.func
def block_world(blk: int, n: int, world: wp.array(dtype=wp.int32)):
    """First node, end and world of node block ``blk``, and whether all its nodes share that world."""
    i0 = blk * NODES_PER_BLOCK
    i1 = wp.min(i0 + NODES_PER_BLOCK, n)
    return i0, i1, world[i0], world[i0] == world[i1 - 1]


@wp.func
def node_add(uniform: bool, local: wp.float64, value: wp.float64, scal: wp.array3d(dtype=wp.float64), c: int,
             w: int, slot: int) -> wp.float64:
    """A node's ``value``: into the thread's sum when its block is one world's (returned), else
    straight into ``scal[c, w, slot]`` (the node's own world)."""
    if uniform:
        return local + value
    wp.atomic_add(scal, c, w, slot, value)
    return local


@wp.func
def block_add(value: wp.float64, lane: int, uniform: bool, scal: wp.array3d(dtype=wp.float64), c: int, w: int,
              slot: int):
    """Add the block's sum of ``value`` to ``scal[c, w, slot]`` (when the block is one world's)."""
    total = wp.tile_sum(wp.tile(value))
    if uniform and lane == 0:
        wp.atomic_add(scal, c, w, slot, total[0])


@wp.func
def first_running(i: int, i1: int, uniform: bool, scal: wp.array3d(dtype=wp.float64), c: int, w: int) -> int:
    """A thread's first node ``i``, or ``i1`` (none) when its block is one world's and that
    column of the world has converged: the iteration's kernels skip converged columns."""
    if uniform and scal[c, w, DONE] != wp.float64(0.0):
        return i1
    return i


@wp.func
def converged_node(uniform: bool, scal: wp.array3d(dtype=wp.float64), c: int, w: int) -> bool:
    """In a block that straddles two worlds, whether this node's world ``w`` has converged in
    column ``c`` (a block of one world was judged once, by :func:`first_running`)."""
    return not uniform and scal[c, w, DONE] != wp.float64(0.0)


@wp.kernel
def pcg_residual(
    b: wp.array2d(dtype=wp.vec3d),
    ax: wp.array2d(dtype=wp.vec3d),
    mask: wp.array(dtype=wp.vec3d),
    r: wp.array2d(dtype=wp.vec3d),
    world: wp.array(dtype=wp.int32),
    scal: wp.array3d(dtype=wp.float64),
):
    """``r = P(b - A x0)``; accumulates ``r.r`` and ``b.b`` (``scal`` zeroed before)."""
    c, blk, lane = wp.tid()
    i0, i1, w, uniform = block_world(blk, r.shape[1], world)
    rr, bb = wp.float64(0.0), wp.float64(0.0)
    i = i0 + lane
    while i < i1:
        m = mask[i]
        bi = wp.cw_mul(m, b[c, i])
        ri = bi - wp.cw_mul(m, ax[c, i])
        r[c, i] = ri
        rr = node_add(uniform, rr, wp.dot(ri, ri), scal, c, world[i], R2_LAST)
        bb = node_add(uniform, bb, wp.dot(bi, bi), scal, c, world[i], B2)
        i += wp.block_dim()
    block_add(rr, lane, uniform, scal, c, w, R2_LAST)
    block_add(bb, lane, uniform, scal, c, w, B2)


@wp.kernel
def pcg_begin(r: wp.array2d(dtype=wp.vec3d), z: wp.array2d(dtype=wp.vec3d), x: wp.array2d(dtype=wp.vec3d),
              p: wp.array2d(dtype=wp.vec3d), world: wp.array(dtype=wp.int32), scal: wp.array3d(dtype=wp.float64)):
    """``p = z``; accumulates ``r.z``. A column with ``b = 0`` has the solution 0, whatever its
    warm start: its ``x``, ``r`` and ``p`` are cleared, so that it stays 0."""
    c, blk, lane = wp.tid()
    i0, i1, w, uniform = block_world(blk, r.shape[1], world)
    rz = wp.float64(0.0)
    i = i0 + lane
    while i < i1:
        if scal[c, world[i], B2] == wp.float64(0.0):
            x[c, i] = wp.vec3d()
            r[c, i] = wp.vec3d()
            p[c, i] = wp.vec3d()
        else:
            p[c, i] = z[c, i]
            rz = node_add(uniform, rz, wp.dot(r[c, i], z[c, i]), scal, c, world[i], RZ)
        i += wp.block_dim()
    block_add(rz, lane, uniform, scal, c, w, RZ)


@wp.kernel
def pcg_curvature(p: wp.array2d(dtype=wp.vec3d), ap: wp.array2d(dtype=wp.vec3d), mask: wp.array(dtype=wp.vec3d),
                  world: wp.array(dtype=wp.int32), scal: wp.array3d(dtype=wp.float64)):
    """Project ``A p`` and accumulate ``p . A p`` (not in converged columns)."""
    c, blk, lane = wp.tid()
    i0, i1, w, uniform = block_world(blk, p.shape[1], world)
    pap = wp.float64(0.0)
    i = first_running(i0 + lane, i1, uniform, scal, c, w)
    while i < i1:
        if converged_node(uniform, scal, c, world[i]):
            i += wp.block_dim()
            continue
        api = wp.cw_mul(mask[i], ap[c, i])
        ap[c, i] = api
        pap = node_add(uniform, pap, wp.dot(p[c, i], api), scal, c, world[i], PAP)
        i += wp.block_dim()
    block_add(pap, lane, uniform, scal, c, w, PAP)


@wp.func
def step_length(scal: wp.array3d(dtype=wp.float64), c: int, w: int) -> wp.float64:
    """``alpha = r.z / p.Ap``; 0 for a converged column (it no longer moves)."""
    if scal[c, w, PAP] > wp.float64(0.0) and scal[c, w, DONE] == wp.float64(0.0):
        return scal[c, w, RZ] / scal[c, w, PAP]
    return wp.float64(0.0)


@wp.kernel
def pcg_update(x: wp.array2d(dtype=wp.vec3d), r: wp.array2d(dtype=wp.vec3d), p: wp.array2d(dtype=wp.vec3d),
               ap: wp.array2d(dtype=wp.vec3d), world: wp.array(dtype=wp.int32), scal: wp.array3d(dtype=wp.float64)):
    """``x += alpha p``, ``r -= alpha A p``; accumulates ``r.r`` (not in converged columns: their
    ``x`` and ``r`` stay, and :func:`pcg_scalars` keeps their last ``r.r``)."""
    c, blk, lane = wp.tid()
    i0, i1, w, uniform = block_world(blk, r.shape[1], world)
    rr = wp.float64(0.0)
    i = first_running(i0 + lane, i1, uniform, scal, c, w)
    while i < i1:
        if converged_node(uniform, scal, c, world[i]):
            i += wp.block_dim()
            continue
        alpha = step_length(scal, c, world[i])
        x[c, i] = x[c, i] + alpha * p[c, i]
        ri = r[c, i] - alpha * ap[c, i]
        r[c, i] = ri
        rr = node_add(uniform, rr, wp.dot(ri, ri), scal, c, world[i], R2)
        i += wp.block_dim()
    block_add(rr, lane, uniform, scal, c, w, R2)


@wp.kernel
def pcg_rz(r: wp.array2d(dtype=wp.vec3d), z: wp.array2d(dtype=wp.vec3d), world: wp.array(dtype=wp.int32),
           scal: wp.array3d(dtype=wp.float64)):
    """Accumulates the new ``r.z`` (not in converged columns)."""
    c, blk, lane = wp.tid()
    i0, i1, w, uniform = block_world(blk, r.shape[1], world)
    rz = wp.float64(0.0)
    i = first_running(i0 + lane, i1, uniform, scal, c, w)
    while i < i1:
        if converged_node(uniform, scal, c, world[i]):
            i += wp.block_dim()
            continue
        rz = node_add(uniform, rz, wp.dot(r[c, i], z[c, i]), scal, c, world[i], RZ_NEW)
        i += wp.block_dim()
    block_add(rz, lane, uniform, scal, c, w, RZ_NEW)


@wp.kernel
def pcg_direction(z: wp.array2d(dtype=wp.vec3d), p: wp.array2d(dtype=wp.vec3d), world: wp.array(dtype=wp.int32),
                  scal: wp.array3d(dtype=wp.float64), active: wp.array(dtype=wp.int32)):
    """``p = z + beta p`` with ``beta = r.z_new / r.z``; clears the loop flag, which
    :func:`pcg_scalars` (launched next) sets again while a column still has to run."""
    c, i = wp.tid()
    if c == 0 and i == 0:
        active[0] = 0
    w = world[i]
    if scal[c, w, DONE] != wp.float64(0.0):
        return  # converged: its p is no longer used
    beta = wp.float64(0.0)
    if scal[c, w, RZ] > wp.float64(0.0):
        beta = scal[c, w, RZ_NEW] / scal[c, w, RZ]
    p[c, i] = z[c, i] + beta * p[c, i]


@wp.kernel
def pcg_scalars(scal: wp.array3d(dtype=wp.float64), tolerance: wp.float64, max_iterations: int, advance: int,
                hold: wp.array(dtype=wp.float64), info: wp.array(dtype=wp.int32), active: wp.array(dtype=wp.int32)):
    """One thread per column and world, after an iteration (``advance = 1``: roll the
    accumulators over, count it) or after the start (``advance = 0``). A column that has
    ``|r| > tolerance |b|``, finite values and iterations left sets ``active``; one that
    reached the tolerance is marked done and frozen, as if its world were alone; one that met
    NaN or inf stops and raises ``info[NONFINITE]``. ``hold`` (``(worlds,)``, or None): a world
    with ``hold[w] = 0`` is not solved; at the start its columns are marked done, keep their
    start, and read as converged (residual 0, no iterations)."""
    c, w = wp.tid()
    if advance == 0 and hold.shape[0] > 0:
        if hold[w] == wp.float64(0.0):
            scal[c, w, DONE] = wp.float64(1.0)
            scal[c, w, R2_LAST] = wp.float64(0.0)
            return
    if advance != 0:
        if scal[c, w, DONE] == wp.float64(0.0):  # a converged column keeps its last r.z and r.r
            scal[c, w, RZ] = scal[c, w, RZ_NEW]
            scal[c, w, R2_LAST] = scal[c, w, R2]
            scal[c, w, ITS] = scal[c, w, ITS] + wp.float64(1.0)
        scal[c, w, RZ_NEW] = wp.float64(0.0)
        scal[c, w, PAP] = wp.float64(0.0)
        scal[c, w, R2] = wp.float64(0.0)
    b2 = scal[c, w, B2]
    r2 = scal[c, w, R2_LAST]
    its = wp.int32(scal[c, w, ITS])
    if not (wp.isfinite(b2) and wp.isfinite(r2) and wp.isfinite(scal[c, w, RZ])):
        info[NONFINITE] = 1
    elif b2 > wp.float64(0.0) and r2 > tolerance * tolerance * b2:
        if its < max_iterations:
            active[0] = 1
    elif scal[c, w, DONE] == wp.float64(0.0):
        scal[c, w, DONE] = wp.float64(1.0)
    wp.atomic_max(info, ITERATIONS, its)


@wp.kernel
def pick_size(count: wp.array(dtype=wp.int32), offset: int, sizes: wp.array(dtype=wp.int32), most: int,
              branch: wp.array(dtype=wp.int32)):
    """One thread: ``branch[j] = 1`` for the smallest ``sizes[j]`` (ascending) that holds
    ``min(offset + count[0], most)`` right-hand sides (the last one when none does), 0 for the others."""
    need = wp.min(offset + count[0], most)
    chosen = sizes.shape[0] - 1
    for j in range(sizes.shape[0] - 1, -1, -1):
        branch[j] = 0
        if sizes[j] >= need:
            chosen = j
    branch[chosen] = 1
