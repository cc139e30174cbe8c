"""Kernel of the sparse factor preconditioner world by world: one level of a triangular solve.

Each world's free DOFs have a sparse Cholesky factor (shared by worlds equal up to a factor),
and its two triangular solves are cut into levels of rows that depend only on rows of earlier
levels (``warpsoft/linear/supernodal.py``). One launch per level runs every world's rows of
that level, a thread per row: task ``(row, e0, e1, e2)`` writes
``out[row, c] = sum_e val[e] inp[base + col[e], c]`` over ``e = e0, e0 + step, ... < e1``, plus
the same sum from ``e1`` to ``e2`` read from ``out`` (rows solved at earlier levels), for each
column ``c`` (``step``, a constant of the kernel: 1, or the width of the slices of rows whose
entries interleave, read side by side by a warp's threads; ``row = -1``: padding, nothing to do);
``base`` is the first row of the task's world (the entries are numbered within a world, so
worlds that share a factor share its entries). The operands are flat ``(3 nodes, k)`` arrays in
each factor's own order (world ``w``'s factor place ``p`` at row ``3 n_w + p``, ``n_w`` its first
node), so that the columns a row reads, which the ordering keeps together (a supernode's own,
its descendants' or its ancestors' separators), lie together in memory. A world whose columns
have all converged (``scal[c, w, DONE]``) skips its rows: its result is no longer read.
"""

import warp as wp

from .cg import DONE

_kernels = {}


def rotate_in_scaled(dtype, columns: int):
    """``rotate_in(r, q_rot, mask, node_world, place, inv_scale, scal, u)``, a thread per node:
    ``u[place[3 i + a], c] = (inv_scale[w] Q_i^T r[c, i])_a`` for the ``k = columns`` columns of
    each free DOF ``3 i + a`` (``place``: its row among the operands, in its factor's order; -1
    for a fixed DOF, which the factor does not hold), in precision ``dtype`` (world ``w``'s system
    is ``s_w`` times its factor's: ``(s_w A)^-1 = A^-1 / s_w``). A thread writes each of its DOFs'
    ``k`` numbers side by side and reads its rotation once. A world whose columns all converged is
    skipped, as the levels skip it."""
    key = ("rotate_in", dtype, columns)
    if key in _kernels:
        return _kernels[key]
    K = columns
    running, _ = _row_funcs(columns, dtype)

    @wp.kernel(module="unique")
    def factor_rotate_in(r: wp.array2d(dtype=wp.vec3d), q_rot: wp.array(dtype=wp.mat33d),
                         mask: wp.array(dtype=wp.vec3d), node_world: wp.array(dtype=wp.int32),
                         place: wp.array(dtype=wp.int32), inv_scale: wp.array(dtype=dtype),
                         scal: wp.array3d(dtype=wp.float64), u: wp.array2d(dtype=dtype)):
        i = wp.tid()
        w = node_world[i]
        if not running(scal, w):
            return
        qt = wp.transpose(q_rot[i])
        m = wp.float64(inv_scale[w]) * mask[i]
        rows = wp.vec3i(place[3 * i], place[3 * i + 1], place[3 * i + 2])
        for c in range(K):
            v = wp.cw_mul(m, qt * r[c, i])
            for a in range(3):
                if rows[a] >= 0:
                    u[rows[a], c] = dtype(v[a])

    _kernels[key] = factor_rotate_in
    return factor_rotate_in


def rotate_out(dtype, columns: int):
    """``rotate_out(x, q_rot, mask, node_world, place, scal, z)``, a thread per node: ``z[c, i] =
    mask_i Q_i x_i[c]`` for the ``k = columns`` columns, ``x_i[c]`` the node's three DOFs' numbers
    at their rows ``place`` (0 for a fixed one); it reads its rotation once. A world whose columns
    all converged is skipped (its ``z`` is no longer read)."""
    key = ("rotate_out", dtype, columns)
    if key in _kernels:
        return _kernels[key]
    K = columns
    running, _ = _row_funcs(columns, dtype)

    @wp.kernel(module="unique")
    def factor_rotate_out(x: wp.array2d(dtype=dtype), q_rot: wp.array(dtype=wp.mat33d),
                          mask: wp.array(dtype=wp.vec3d), node_world: wp.array(dtype=wp.int32),
                          place: wp.array(dtype=wp.int32), scal: wp.array3d(dtype=wp.float64),
                          z: wp.array2d(dtype=wp.vec3d)):
        i = wp.tid()
        if not running(scal, node_world[i]):
            return
        q = q_rot[i]
        m = mask[i]
        rows = wp.vec3i(place[3 * i], place[3 * i + 1], place[3 * i + 2])
        for c in range(K):
            v = wp.vec3d()
            for a in range(3):
                if rows[a] >= 0:
                    v[a] = wp.float64(x[rows[a], c])
            z[c, i] = wp.cw_mul(m, q * v)

    _kernels[key] = factor_rotate_out
    return factor_rotate_out


UNROLL = 4  # entries a thread loads before it sums them (docs/performance.md)


def _row_funcs(columns: int, dtype, unroll: int = UNROLL):
    """The two functions a level's kernels share for ``k = columns`` and ``dtype``: ``running(scal,
    w)``, whether some column of world ``w`` has not converged, and ``entries(acc, e0, e1, step,
    base, col, val, src)``, ``acc`` plus the sums ``sum_e val[e] src[base + col[e], c]`` over
    ``e0 <= e < e1`` by ``step``, ``(k,)``. The entries are taken ``unroll`` at a time: their
    loads are issued together, then summed in order (the rounding of one loop), so that a thread
    waits for memory once per ``unroll`` entries rather than twice per entry (the column, then
    the operand it points to)."""
    key = ("funcs", columns, dtype, unroll)
    if key in _kernels:
        return _kernels[key]
    K, U = columns, unroll
    sums = wp.types.vector(length=K, dtype=dtype)
    loads = wp.types.vector(length=U, dtype=dtype)
    places = wp.types.vector(length=U, dtype=wp.int32)

    @wp.func
    def running(scal: wp.array3d(dtype=wp.float64), w: int) -> bool:
        for c in range(K):
            if scal[c, w, DONE] == wp.float64(0.0):
                return True
        return False

    @wp.func
    def entries(acc: sums, e0: int, e1: int, step: int, base: int, col: wp.array(dtype=wp.int32),
                val: wp.array(dtype=dtype), src: wp.array2d(dtype=dtype)) -> sums:
        total = acc + sums()
        e = wp.int32(e0)
        while e + (U - 1) * step < e1:  # U whole entries left
            v = loads()
            j = places()
            for u in range(U):
                v[u] = val[e + u * step]
                j[u] = base + col[e + u * step]
            for u in range(U):
                for c in range(K):
                    total[c] = total[c] + v[u] * src[j[u], c]
            e = e + U * step
        while e < e1:
            v1 = val[e]
            j1 = base + col[e]
            for c in range(K):
                total[c] = total[c] + v1 * src[j1, c]
            e = e + step
        return total

    _kernels[key] = (running, entries)
    return running, entries


def level_kernel(columns: int, dtype, step: int = 1, unroll: int = UNROLL):
    """``factor_level(tasks, first, col, val, node_world, world_row, scal, inp, out)`` for ``k =
    columns`` right-hand sides in precision ``dtype``, a task's entries ``step`` apart, a thread
    per task, over a level's tasks, which start at ``tasks[first]``, ``unroll`` entries at a time.
    The four are compile-time constants, hence cached per key (a step read from the task, the task
    then five numbers, took the solve from 7.2 to 15.3 ms on the H200)."""
    key = ("level", columns, dtype, step, unroll)
    if key in _kernels:
        return _kernels[key]
    K, STEP = columns, step
    sums = wp.types.vector(length=K, dtype=dtype)
    running, entries = _row_funcs(columns, dtype, unroll)

    @wp.kernel(module="unique")
    def factor_level(tasks: wp.array(dtype=wp.vec4i), first: int, col: wp.array(dtype=wp.int32),
                     val: wp.array(dtype=dtype), node_world: wp.array(dtype=wp.int32),
                     world_row: wp.array(dtype=wp.int32), scal: wp.array3d(dtype=wp.float64),
                     inp: wp.array2d(dtype=dtype), out: wp.array2d(dtype=dtype)):
        t = tasks[first + wp.tid()]
        row = t[0]
        if row < 0:
            return  # padding at the end of a slice
        w = node_world[row // 3]
        if not running(scal, w):
            return  # every column of the world converged
        base = world_row[w]
        # the diagonal block's inverse on the input, then the rows solved at earlier levels
        acc = entries(sums(), t[1], t[2], STEP, base, col, val, inp)
        acc = entries(acc, t[2], t[3], STEP, base, col, val, out)
        for c in range(K):
            out[row, c] = acc[c]

    _kernels[key] = factor_level
    return factor_level


def level_kernel_lanes(columns: int, dtype, lanes: int, unroll: int = UNROLL):
    """:func:`level_kernel` with ``lanes`` threads per task (a tiled launch, ``block_dim = lanes``,
    CUDA): they stride the task's entries, so that a long row keeps ``lanes`` loads in flight
    and neighbouring threads read neighbouring entries, and a tile sum adds their shares."""
    key = ("lanes", columns, dtype, lanes, unroll)
    if key in _kernels:
        return _kernels[key]
    K = columns
    L = lanes
    sums = wp.types.vector(length=K, dtype=dtype)
    running, entries = _row_funcs(columns, dtype, unroll)

    @wp.kernel(module="unique")
    def factor_level_lanes(tasks: wp.array(dtype=wp.vec4i), first: int, col: wp.array(dtype=wp.int32),
                           val: wp.array(dtype=dtype), node_world: wp.array(dtype=wp.int32),
                           world_row: wp.array(dtype=wp.int32), scal: wp.array3d(dtype=wp.float64),
                           inp: wp.array2d(dtype=dtype), out: wp.array2d(dtype=dtype)):
        i, lane = wp.tid()
        t = tasks[first + i]
        row = t[0]
        w = node_world[row // 3]
        if not running(scal, w):
            return  # every column of the world converged (the whole block returns)
        base = world_row[w]
        acc = entries(sums(), t[1] + lane, t[2], L, base, col, val, inp)  # (contiguous entries: step 1)
        acc = entries(acc, t[2] + lane, t[3], L, base, col, val, out)
        total = wp.tile_sum(wp.tile(acc, preserve_type=True))
        if lane == 0:
            s = total[0]
            for c in range(K):
                out[row, c] = s[c]

    _kernels[key] = factor_level_lanes
    return factor_level_lanes
