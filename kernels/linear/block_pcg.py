"""Kernels of the block preconditioned CG: a world's ``k`` columns share one search space.

The ``k`` right-hand sides of a world have the same matrix, so each iteration can search along
every column's direction at once: ``x`` moves by ``P alpha`` and ``r`` by ``A P alpha``, with
``k x k`` coefficients instead of one number per column. The softest modes, which each column's
own CG finds one at a time, are then found once for all of them (measured on a sagging Diamond:
19 iterations where its columns needed 37-44 each).

Per world ``w`` and iteration, with ``Q = A P`` and the ``k x k`` Gram matrices ``G_PAP = P^T Q``,
``G_PR = P^T R`` and ``G_QZ = Q^T Z``:

    alpha = G_PAP^+ G_PR,   X += P alpha,   R -= Q alpha,   Z = M^-1 R,
    beta = -G_PAP^+ G_QZ,   P = Z + P beta.

This is the breakdown-free form of block CG (Dubrulle 2001; Ji and Li 2017), not O'Leary's
``alpha = G_PAP^-1 R^T Z``, ``beta = (R^T Z)^-1 R_new^T Z_new``. The two agree in exact arithmetic
with a fixed symmetric preconditioner; they part when ``Z`` carries rounding: a float32
preconditioner or float32 directions (:data:`DIRECTIONS`). O'Leary's ratios then lose the
conjugacy they assume, and on bars whose cables run 2 mm apart (nearly dependent columns) a
world's iterations grew from 6 to 16, or met NaN at the 11th step. Here ``alpha`` is the Galerkin
solution on ``span(P)`` of the residual at hand, so each column's error in the ``A`` norm never
grows, whatever ``P`` is, and ``beta`` makes the new directions ``A``-conjugate to the old ones
from the products themselves (the flexible CG's choice for an inexact preconditioner).

Vectors are ``(k, n)`` vec3d as in ``pcg.py``, but for the directions ``P`` and ``Z``, which may
be vec3f (:data:`DIRECTIONS`); the ``k x k`` matrices of world ``w`` live in ``gram[w, slot]`` and
``coef[w, slot]`` (float64), and every sum and product is taken in float64. A world's columns run
until all of them reach the tolerance; a column with ``b = 0`` is left out of its world's block
(its solution is 0). ``G_PAP^+`` is applied through a Cholesky factor of ``G_PAP`` scaled to a unit
diagonal, pivoting out the directions that depend on the others (:data:`DEPENDENT`): two equal
right-hand sides then share one direction instead of breaking the factorization.
"""

from typing import Any

import warp as wp

from .. import OPTIONS
from .cg import B2, DONE, ITS, R2, R2_LAST
from .pcg import ITERATIONS, NODES_PER_BLOCK, NONFINITE

wp.set_module_options(OPTIONS)

MAX_COLUMNS = 16  # a block holds at most this many right-hand sides (k^2 / 2 reductions an iteration)
G_PAP = wp.constant(0)  # gram[w, G_PAP]: P^T A P (symmetric: its upper half is summed)
G_PR = wp.constant(1)  # gram[w, G_PR]: P^T R
G_QZ = wp.constant(2)  # gram[w, G_QZ]: (A P)^T Z
NUM_GRAMS = 3
ALPHA = wp.constant(0)  # coef[w, ALPHA]
BETA = wp.constant(1)  # coef[w, BETA]
# a scaled Cholesky pivot of G_PAP below this drops its direction (the pivot is the squared sine
# of the A-angle between a direction and the span of those before it): a direction that only
# repeats the others, to round-off, adds nothing to the search. The breakdown-free form needs no
# looser floor for float32 directions or preconditioners: on bars whose four cables run 2 mm
# apart, float32 factors take at most one iteration more than float64 with pivots of 1e-14 to
# 1e-10 alike (tests/test_block_pcg.py)
DEPENDENT = 1e-12
# the storage of the directions P and Z: float32 halves their bytes and costs no accuracy when the
# preconditioner works in float32 anyway. X and R stay float64, and A P is the float64 product of
# the P stored, so X moves by P alpha and R by A P alpha with the same P: R stays the residual of X
# (the rounding of P only perturbs the directions' conjugacy, by ~1e-7, as the float32
# preconditioner perturbs Z). A P stored in float32 would not: R would drift from b - A X.
DIRECTIONS = {"float64": wp.vec3d, "float32": wp.vec3f}


@wp.func
def live(scal: wp.array3d(dtype=wp.float64), c: int, w: int) -> bool:
    """Whether column ``c`` takes part in world ``w``'s block (``b != 0``)."""
    return scal[c, w, B2] > wp.float64(0.0)


@wp.func
def running(wdone: wp.array(dtype=wp.int32), w: int) -> bool:
    """Whether world ``w`` still iterates (not converged, not held)."""
    return wdone[w] == 0


CHUNK = 8  # sums added up by one block reduction (a tile of vectors of this length)
Chunk = wp.types.vector(length=CHUNK, dtype=wp.float64)


@wp.func
def chunk_sum(s: Any, c: int) -> Chunk:
    """The block's sum of entries ``c CHUNK`` to ``(c + 1) CHUNK - 1`` of each thread's ``s`` (a
    float64 vector), one block reduction (a tile of :data:`CHUNK`-vectors); lane 0 reads it."""
    part = Chunk()
    for j in range(CHUNK):
        part[j] = s[c * CHUNK + j]
    return wp.tile_sum(wp.tile(part, preserve_type=True))[0]


_grams = {}


def gram_kernel(columns: int, u_vector=wp.vec3d, v_vector=wp.vec3d, w_vector=None):
    """``out[w, slot_v, a, b] += sum_i u[a, i] . (mask v[b, i])`` over the pairs ``a <= b`` (``v`` given:
    a symmetric product, :func:`load` mirrors the other half) and ``out[w, slot_w, a, b] += sum_i
    u[a, i] . (mask w[b, i])`` over all pairs (``w_vector`` given: a general product), of the ``k =
    columns`` columns, summed in float64, in the running worlds, between live columns. Either
    product may be left out (its vector type None; its array is then not read). ``u`` is read once
    for both: ``P^T A P`` and ``P^T R`` take one pass over ``P``.

    A block of threads per world (:func:`launch_worlds`, ``world_start`` its first node, ``(worlds +
    1,)``): each thread reads its nodes' vectors once and adds the products; the block then sums
    them :data:`CHUNK` at a time, one block reduction of a vector each (a launch per pair read 2
    vectors a pair, ``k + 1`` times the bytes; a reduction a sum, ``CHUNK`` times as many
    reductions). A converged world's block returns at once. Cached per ``k`` (a compile-time
    constant: the sums live in registers) and vector types."""
    key = (columns, u_vector, v_vector, w_vector)
    if key in _grams:
        return _grams[key]
    K = columns
    SYM, FULL = v_vector is not None, w_vector is not None
    NS = K * (K + 1) // 2 if SYM else 0
    NF = K * K if FULL else 0
    CHUNKS = (NS + NF + CHUNK - 1) // CHUNK
    Sums = wp.types.vector(length=CHUNKS * CHUNK, dtype=wp.float64)  # the symmetric product's, then the general's
    Vs = wp.types.matrix(shape=(K, 3), dtype=wp.float64)
    v_type = v_vector if SYM else wp.vec3d
    w_type = w_vector if FULL else wp.vec3d

    @wp.func
    def masked(m: wp.vec3d, scal: wp.array3d(dtype=wp.float64), w: int, vec: wp.array2d(dtype=Any), i: int) -> Vs:
        """The live columns of ``vec`` (vec3d or vec3f) at node ``i``, masked, as rows of a ``k x 3``
        matrix."""
        out = Vs()
        for b in range(K):
            if live(scal, b, w):
                vb = wp.cw_mul(m, wp.vec3d(vec[b, i]))
                out[b, 0] = vb[0]
                out[b, 1] = vb[1]
                out[b, 2] = vb[2]
        return out

    @wp.kernel(module="unique", module_options=OPTIONS)
    def gram_pairs(u: wp.array2d(dtype=u_vector), v: wp.array2d(dtype=v_type), wv: wp.array2d(dtype=w_type),
                   mask: wp.array(dtype=wp.vec3d), world_start: wp.array(dtype=wp.int32),
                   scal: wp.array3d(dtype=wp.float64), wdone: wp.array(dtype=wp.int32), slot_v: int, slot_w: int,
                   out: wp.array4d(dtype=wp.float64)):
        w, lane = wp.tid()
        if running(wdone, w):  # (the same for the block's threads)
            s = Sums()
            i = world_start[w] + lane
            while i < world_start[w + 1]:
                m = mask[i]
                vs = Vs()
                ws = Vs()
                if wp.static(SYM):
                    vs = masked(m, scal, w, v, i)
                if wp.static(FULL):
                    ws = masked(m, scal, w, wv, i)
                q = wp.int32(0)
                for a in range(K):
                    ua = wp.vec3d()
                    if live(scal, a, w):
                        ua = wp.vec3d(u[a, i])
                    if wp.static(SYM):
                        for b in range(a, K):
                            s[q] = s[q] + ua[0] * vs[b, 0] + ua[1] * vs[b, 1] + ua[2] * vs[b, 2]
                            q += 1
                    if wp.static(FULL):
                        for b in range(K):
                            f = NS + a * K + b
                            s[f] = s[f] + ua[0] * ws[b, 0] + ua[1] * ws[b, 1] + ua[2] * ws[b, 2]
                i += wp.block_dim()
            total = Sums()  # (lane 0's)
            for c in range(CHUNKS):
                r = chunk_sum(s, c)
                if lane == 0:
                    for j in range(CHUNK):
                        total[c * CHUNK + j] = r[j]
            if lane == 0:
                q = wp.int32(0)
                if wp.static(SYM):
                    for a in range(K):
                        for b in range(a, K):
                            out[w, slot_v, a, b] = out[w, slot_v, a, b] + total[q]
                            q += 1
                if wp.static(FULL):
                    for a in range(K):
                        for b in range(K):
                            out[w, slot_w, a, b] = out[w, slot_w, a, b] + total[NS + a * K + b]

    _grams[key] = gram_pairs
    return gram_pairs


_updates = {}


def block_update_kernel(columns: int, vector=wp.vec3d):
    """``x[a] += sum_b p[b] alpha[b, a]``, ``r[a] -= P(sum_b A p[b] alpha[b, a])`` (``P`` the
    projection on the free DOFs) for the live columns ``a`` of the running worlds; accumulates
    ``r.r`` into ``scal[a, w, R2]``. A block of threads per world (:func:`launch_worlds`), each
    thread reading its nodes' ``2 k`` vectors of ``p`` and ``A p`` once (a thread per column and
    node read them ``k`` times: on the H200, 1024 Diamonds' 5 columns, 431 us a launch; 304-360
    with a thread a node over blocks of 256 nodes; 240 with a reduction a column), the block sums
    :data:`CHUNK` columns' ``r.r`` a reduction. ``p`` holds ``vector`` (vec3d or vec3f),
    the rest vec3d. Cached per ``k = columns`` and ``vector``."""
    key = (columns, vector)
    if key in _updates:
        return _updates[key]
    K = columns
    Vs = wp.types.matrix(shape=(K, 3), dtype=wp.float64)
    CHUNKS = (K + CHUNK - 1) // CHUNK
    Rs = wp.types.vector(length=CHUNKS * CHUNK, dtype=wp.float64)

    @wp.kernel(module="unique", module_options=OPTIONS)
    def block_update(x: wp.array2d(dtype=wp.vec3d), r: wp.array2d(dtype=wp.vec3d), p: wp.array2d(dtype=vector),
                     ap: wp.array2d(dtype=wp.vec3d), mask: wp.array(dtype=wp.vec3d),
                     world_start: wp.array(dtype=wp.int32), scal: wp.array3d(dtype=wp.float64),
                     wdone: wp.array(dtype=wp.int32), coef: wp.array4d(dtype=wp.float64)):
        w, lane = wp.tid()
        if running(wdone, w):  # (the same for the block's threads)
            rr = Rs()
            i = world_start[w] + lane
            while i < world_start[w + 1]:
                ps = Vs()
                aps = Vs()
                for b in range(K):
                    pb = wp.vec3d(p[b, i])
                    apb = ap[b, i]
                    for c in range(3):
                        ps[b, c] = pb[c]
                        aps[b, c] = apb[c]
                m = mask[i]
                for a in range(K):
                    if live(scal, a, w):
                        dx = wp.vec3d()
                        dr = wp.vec3d()
                        for b in range(K):
                            alpha = coef[w, ALPHA, b, a]
                            if alpha != wp.float64(0.0):  # (a direction dropped: none of its p is read)
                                dx += alpha * wp.vec3d(ps[b, 0], ps[b, 1], ps[b, 2])
                                dr += alpha * wp.vec3d(aps[b, 0], aps[b, 1], aps[b, 2])
                        x[a, i] = x[a, i] + dx
                        ri = r[a, i] - wp.cw_mul(m, dr)
                        r[a, i] = ri
                        rr[a] = rr[a] + wp.dot(ri, ri)
                i += wp.block_dim()
            for c in range(CHUNKS):
                sums = chunk_sum(rr, c)
                if lane == 0:
                    for j in range(CHUNK):
                        if c * CHUNK + j < K:
                            a = c * CHUNK + j
                            scal[a, w, R2] = scal[a, w, R2] + sums[j]

    _updates[key] = block_update
    return block_update


_directions = {}


def block_direction_kernel(columns: int, vector=wp.vec3d):
    """``p[a] = z[a] + sum_b p[b] beta[b, a]``: the new directions of the live columns of the
    running worlds, a thread per node, which holds its node's old ``p`` while it writes the new
    one (a thread per column and node made them in ``z``, read ``p`` ``k`` times, and a second
    kernel copied them to ``p``: 1024 Diamonds on the H200, 64 us a launch against 137 + 62).
    ``z`` and ``p`` hold ``vector`` (vec3d or vec3f; the sums are float64). Launched over the nodes;
    cached per ``k = columns`` and ``vector``."""
    key = (columns, vector)
    if key in _directions:
        return _directions[key]
    K = columns
    Vs = wp.types.matrix(shape=(K, 3), dtype=wp.float64)

    @wp.kernel(module="unique", module_options=OPTIONS)
    def block_direction(z: wp.array2d(dtype=vector), p: wp.array2d(dtype=vector),
                        world: wp.array(dtype=wp.int32), scal: wp.array3d(dtype=wp.float64),
                        wdone: wp.array(dtype=wp.int32), coef: wp.array4d(dtype=wp.float64)):
        i = wp.tid()
        w = world[i]
        if not running(wdone, w):
            return
        old = Vs()
        for b in range(K):
            pb = wp.vec3d(p[b, i])
            for c in range(3):
                old[b, c] = pb[c]
        for a in range(K):
            if live(scal, a, w):
                new = wp.vec3d(z[a, i])
                for b in range(K):
                    beta = coef[w, BETA, b, a]
                    if beta != wp.float64(0.0):
                        new += beta * wp.vec3d(old[b, 0], old[b, 1], old[b, 2])
                p[a, i] = vector(new)

    _directions[key] = block_direction
    return block_direction


_begins = {}


def block_begin_kernel(vector=wp.vec3d):
    """``p = z`` (``z`` and ``p`` of ``vector``), a thread per column and node; a column with
    ``b = 0`` (``scal[c, w, B2] = 0``) has the solution 0, whatever its warm start: its ``x``, ``r``
    and ``p`` are cleared, so that it stays 0. Cached per ``vector``."""
    if vector in _begins:
        return _begins[vector]

    @wp.kernel(module="unique", module_options=OPTIONS)
    def block_begin(r: wp.array2d(dtype=wp.vec3d), z: wp.array2d(dtype=vector), x: wp.array2d(dtype=wp.vec3d),
                    p: wp.array2d(dtype=vector), world: wp.array(dtype=wp.int32), scal: wp.array3d(dtype=wp.float64)):
        c, i = wp.tid()
        if scal[c, world[i], B2] == wp.float64(0.0):
            x[c, i] = wp.vec3d()
            r[c, i] = wp.vec3d()
            p[c, i] = vector()
        else:
            p[c, i] = z[c, i]

    _begins[vector] = block_begin
    return block_begin


_small = {}
# on CUDA, a block's k x k loops unroll up to this many columns (then its small matrices live in
# registers); larger blocks loop (compile time grows as k^3 unrolled). On the CPU they stay loops:
# unrolled they cost minutes of compilation, and a thread's small matrices need no registers
SMALL_UNROLL = 8


def small_kernels(columns: int, cuda: bool = True):
    """``(block_alpha, block_scalars)`` for ``k = columns`` columns: a thread per world, whose
    ``k x k`` matrices (the Gram matrices, ``alpha``, ``beta`` and the Cholesky factor) are local
    matrices of ``k x k``, every loop over ``k`` (unrolled up to :data:`SMALL_UNROLL` columns, so
    that each index is a constant and the matrices stay in registers; a loop bounded by the
    column at hand runs over all ``k`` and tests it). For 1024 Diamonds' 5 columns on the H200,
    ``block_alpha`` and ``block_scalars`` took 146 and 178 us a launch with matrices of
    :data:`MAX_COLUMNS`, 48 and 70 with ``k x k`` ones and loops bounded at run time (the matrices
    in local memory), 24 and 47 unrolled. ``cuda``: for a CUDA device (unrolled), else the CPU
    (loops). Cached per ``columns`` and ``cuda``."""
    key = (columns, bool(cuda))
    if key in _small:
        return _small[key]
    K = columns
    Small = wp.types.matrix(shape=(K, K), dtype=wp.float64)  # a world's k x k, local
    Diagonal = wp.types.vector(length=K, dtype=wp.float64)
    Flags = wp.types.vector(length=K, dtype=wp.int32)

    @wp.func
    def load(g: wp.array4d(dtype=wp.float64), w: int, slot: int) -> Small:
        """``g[w, slot]`` (its upper half filled) as a symmetric local matrix."""
        m = Small()
        for a in range(K):
            for b in range(K):
                if b >= a:
                    v = g[w, slot, a, b]
                    m[a, b] = v
                    m[b, a] = v
        return m

    @wp.func
    def load_full(g: wp.array4d(dtype=wp.float64), w: int, slot: int) -> Small:
        """``g[w, slot]`` (every entry filled) as a local matrix."""
        m = Small()
        for a in range(K):
            for b in range(K):
                m[a, b] = g[w, slot, a, b]
        return m

    @wp.func
    def solve_small(g: Small, rhs: Small, dependent: wp.float64) -> Small:
        """``G^-1 rhs`` for the symmetric positive semi-definite ``G = g`` (``k x k`` local
        matrices, this thread's alone). Cholesky of ``D^-1/2 G D^-1/2`` (``D`` its diagonal); a
        pivot below ``dependent``, or a zero diagonal (a column left out), drops its row and
        column, and that row of the solution is 0 (its direction is not taken). One direction
        alone is CG's own quotient."""
        out = Small()
        d = Diagonal()
        keep = Flags()
        kept = wp.int32(0)
        for a in range(K):
            if g[a, a] > wp.float64(0.0):
                keep[a] = 1
                d[a] = wp.sqrt(g[a, a])
                kept += 1
        if kept == 1:
            for a in range(K):
                if keep[a] != 0:
                    for col in range(K):
                        out[a, col] = rhs[a, col] / g[a, a]
        if kept <= 1:
            return out
        lw = Small()
        for j in range(K):  # the scaled factor, column by column (lower triangle)
            if keep[j] != 0:
                s = g[j, j] / (d[j] * d[j])
                for m in range(K):
                    if m < j and keep[m] != 0:
                        s -= lw[j, m] * lw[j, m]
                if s <= dependent:
                    keep[j] = 0
                else:
                    lw[j, j] = wp.sqrt(s)
                    for i in range(K):
                        if i > j and keep[i] != 0:
                            t = g[i, j] / (d[j] * d[i])
                            for m in range(K):
                                if m < j and keep[m] != 0:
                                    t -= lw[i, m] * lw[j, m]
                            lw[i, j] = t / lw[j, j]
        for col in range(K):  # each right-hand side: forward and back substitution, scaled
            for i in range(K):
                if keep[i] != 0:
                    s = rhs[i, col] / d[i]
                    for m in range(K):
                        if m < i and keep[m] != 0:
                            s -= lw[i, m] * out[m, col]
                    out[i, col] = s / lw[i, i]
            for ii in range(K):
                i = K - 1 - ii
                if keep[i] != 0:
                    s = out[i, col]
                    for m in range(K):
                        if m > i and keep[m] != 0:
                            s -= lw[m, i] * out[m, col]
                    out[i, col] = s / lw[i, i]
            for i in range(K):
                if keep[i] != 0:
                    out[i, col] = out[i, col] / d[i]
        return out

    @wp.func
    def store(m: Small, coef: wp.array4d(dtype=wp.float64), w: int, slot: int):
        """``coef[w, slot] = m``."""
        for a in range(K):
            for b in range(K):
                coef[w, slot, a, b] = m[a, b]

    options = OPTIONS | {"max_unroll": SMALL_UNROLL if cuda else 1}

    @wp.kernel(module="unique", module_options=options)
    def block_alpha(g: wp.array4d(dtype=wp.float64), wdone: wp.array(dtype=wp.int32), dependent: wp.float64,
                    coef: wp.array4d(dtype=wp.float64), active: wp.array(dtype=wp.int32)):
        """One thread per world: ``alpha = G_PAP^+ G_PR``; clears the loop flag, which
        :func:`block_scalars` sets again while a world still has to run."""
        w = wp.tid()
        if w == 0:
            active[0] = 0
        if not running(wdone, w):
            return
        store(solve_small(load(g, w, G_PAP), load_full(g, w, G_PR), dependent), coef, w, ALPHA)

    @wp.kernel(module="unique", module_options=options)
    def block_scalars(scal: wp.array3d(dtype=wp.float64), g: wp.array4d(dtype=wp.float64), tolerance: wp.float64,
                      max_iterations: int, advance: int, hold: wp.array(dtype=wp.float64),
                      dependent: wp.float64, wdone: wp.array(dtype=wp.int32), coef: wp.array4d(dtype=wp.float64),
                      info: wp.array(dtype=wp.int32), active: wp.array(dtype=wp.int32)):
        """One thread per world, after an iteration (``advance = 1``: ``beta = -G_PAP^+ G_QZ``, clear
        the accumulators, count it) or after the start (``advance = 0``). A world whose live
        columns all have ``|r| <= tolerance |b|`` is done, and all its columns are marked done (the
        products skip them); one with iterations left and a column above sets ``active``; a
        non-finite value stops it and raises ``info[NONFINITE]``. ``hold[w] = 0`` (``hold`` of
        shape ``(worlds,)``, or empty): not solved; at the start its columns are marked done, keep
        their start, and read as converged."""
        w = wp.tid()
        if advance == 0:
            wdone[w] = 0
            if hold.shape[0] > 0:
                if hold[w] == wp.float64(0.0):
                    wdone[w] = 1
                    for c in range(K):
                        scal[c, w, DONE] = wp.float64(1.0)
                        scal[c, w, R2_LAST] = wp.float64(0.0)
                    return
            for c in range(K):
                if not live(scal, c, w):
                    scal[c, w, DONE] = wp.float64(1.0)  # (a column left out: the products skip it)
        if wdone[w] != 0:
            return
        finite = wp.int32(1)
        if advance != 0:
            beta = -solve_small(load(g, w, G_PAP), load_full(g, w, G_QZ), dependent)
            store(beta, coef, w, BETA)
            for a in range(K):
                for b in range(K):
                    g[w, G_PAP, a, b] = wp.float64(0.0)
                    g[w, G_PR, a, b] = wp.float64(0.0)
                    g[w, G_QZ, a, b] = wp.float64(0.0)
                    if not wp.isfinite(beta[a, b]) or not wp.isfinite(coef[w, ALPHA, a, b]):
                        finite = 0
        converged = wp.int32(1)
        its = wp.int32(0)
        for c in range(K):
            if not wp.isfinite(scal[c, w, B2]):  # (a NaN right-hand side is no column left out)
                finite = 0
            if live(scal, c, w):
                if advance != 0:
                    scal[c, w, R2_LAST] = scal[c, w, R2]
                    scal[c, w, ITS] = scal[c, w, ITS] + wp.float64(1.0)
                scal[c, w, R2] = wp.float64(0.0)
                r2 = scal[c, w, R2_LAST]
                its = wp.int32(scal[c, w, ITS])
                if not wp.isfinite(r2):
                    finite = 0
                elif r2 > tolerance * tolerance * scal[c, w, B2]:
                    converged = 0
        wp.atomic_max(info, ITERATIONS, its)
        if finite == 0:
            info[NONFINITE] = 1
            converged = 1
        if converged != 0 or its >= max_iterations:
            wdone[w] = 1
            for c in range(K):
                scal[c, w, DONE] = wp.float64(1.0)
        else:
            active[0] = 1

    _small[key] = (block_alpha, block_scalars)
    return _small[key]


def launch_worlds(kernel, worlds: int, inputs: list, device) -> None:
    """Launch a kernel of a block per world (:func:`gram_kernel`, :func:`block_update_kernel`),
    ``NODES_PER_BLOCK`` threads a block."""
    wp.launch_tiled(kernel, dim=(worlds,), inputs=inputs, block_dim=NODES_PER_BLOCK, device=device)
