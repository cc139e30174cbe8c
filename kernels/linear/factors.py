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

from .. import OPTIONS
from .cg import DONE

wp.set_module_options(OPTIONS)

_kernels = {}


def rotate_in_scaled(dtype, columns: int, frame=wp.mat33d):
    """``rotate_in(r, q_rot, mask, node_world, place, inv_scale, scal, u)``, a thread per node:
    ``u[place[3 i + a], c] = (inv_scale[w] Q_i^T r[c, i])_a`` for the ``k = columns`` columns of
    each free DOF ``3 i + a`` (``place``: its row among the operands, in its factor's order; -1
    for a fixed DOF, which the factor does not hold), in precision ``dtype`` (world ``w``'s system
    is ``s_w`` times its factor's: ``(s_w A)^-1 = A^-1 / s_w``). A thread writes each of its DOFs'
    ``k`` numbers side by side and reads its rotation once. A world whose columns all converged is
    skipped, as the levels skip it. ``q_rot`` holds ``frame`` (mat33d, or mat33f: the rotations in
    the precision of the factors, which costs them nothing, the same ``Q`` rotating in and out)."""
    key = ("rotate_in", dtype, columns, frame)
    if key in _kernels:
        return _kernels[key]
    K = columns
    running, _ = _row_funcs(columns, dtype)

    @wp.kernel(module="unique", module_options=OPTIONS)
    def factor_rotate_in(r: wp.array2d(dtype=wp.vec3d), q_rot: wp.array(dtype=frame),
                         mask: wp.array(dtype=wp.vec3d), node_world: wp.array(dtype=wp.int32),
                         place: wp.array(dtype=wp.int32), inv_scale: wp.array(dtype=dtype),
                         scal: wp.array3d(dtype=wp.float64), u: wp.array2d(dtype=dtype)):
        i = wp.tid()
        w = node_world[i]
        if not running(scal, w):
            return
        qt = wp.transpose(wp.mat33d(q_rot[i]))
        m = wp.float64(inv_scale[w]) * mask[i]
        rows = wp.vec3i(place[3 * i], place[3 * i + 1], place[3 * i + 2])
        for c in range(K):
            v = wp.cw_mul(m, qt * r[c, i])
            for a in range(3):
                if rows[a] >= 0:
                    u[rows[a], c] = dtype(v[a])

    _kernels[key] = factor_rotate_in
    return factor_rotate_in


def rotate_out(dtype, columns: int, vector=wp.vec3d, frame=wp.mat33d):
    """``rotate_out(x, q_rot, mask, node_world, place, scal, z)``, a thread per node: ``z[c, i] =
    mask_i Q_i x_i[c]`` for the ``k = columns`` columns, ``x_i[c]`` the node's three DOFs' numbers
    at their rows ``place`` (0 for a fixed one); it reads its rotation once. A world whose columns
    all converged is skipped (its ``z`` is no longer read). ``z`` holds ``vector`` (vec3d, or vec3f:
    the block CG's directions in single precision), ``q_rot`` ``frame`` (as :func:`rotate_in_scaled`)."""
    key = ("rotate_out", dtype, columns, vector, frame)
    if key in _kernels:
        return _kernels[key]
    K = columns
    running, _ = _row_funcs(columns, dtype)

    @wp.kernel(module="unique", module_options=OPTIONS)
    def factor_rotate_out(x: wp.array2d(dtype=dtype), q_rot: wp.array(dtype=frame),
                          mask: wp.array(dtype=wp.vec3d), node_world: wp.array(dtype=wp.int32),
                          place: wp.array(dtype=wp.int32), scal: wp.array3d(dtype=wp.float64),
                          z: wp.array2d(dtype=vector)):
        i = wp.tid()
        if not running(scal, node_world[i]):
            return
        q = wp.mat33d(q_rot[i])
        m = mask[i]
        rows = wp.vec3i(place[3 * i], place[3 * i + 1], place[3 * i + 2])
        for c in range(K):
            v = wp.vec3d()
            for a in range(3):
                if rows[a] >= 0:
                    v[a] = wp.float64(x[rows[a], c])
            z[c, i] = vector(wp.cw_mul(m, q * v))

    _kernels[key] = factor_rotate_out
    return factor_rotate_out


UNROLL = 4  # entries a thread loads before it sums them (docs/performance.md)


def _row_load(width: int, dtype):
    """``load_row(src, j)``: row ``j`` of a ``(rows, width)`` operand as a ``(width,)`` vector, read
    from the row's address, found once, rather than indexed number by number: on the CPU the
    levels' ``P^-1`` of 4 Diamonds took 6.0 -> 4.8 ms. On CUDA a task a row is the faster indexed
    (1024 Diamonds: 5.0 against 5.9 ms; rows padded to 16-byte loads, 5.2), a panel read whole
    (3.30 -> 3.21 ms): docs/performance.md."""
    key = ("load", width, dtype)
    if key in _kernels:
        return _kernels[key]
    ctype = "float" if dtype == wp.float32 else "double"
    snippet = "\n".join([
        f"wp::vec_t<{width}, {ctype}> v;",
        f"const {ctype}* at = reinterpret_cast<const {ctype}*>(reinterpret_cast<const char*>(src.data)"
        " + size_t(j) * size_t(src.strides[0]));",
        f"for (int i = 0; i < {width}; ++i) v.c[i] = at[i];",
        "return v;"])
    row = wp.types.vector(length=width, dtype=dtype)

    @wp.func_native(snippet)
    def load_row(src: wp.array2d(dtype=dtype), j: int) -> row: ...

    _kernels[key] = load_row
    return load_row


def _row_funcs(columns: int, dtype, unroll: int = UNROLL, whole: bool = False, entry: tuple | None = None):
    """The two functions a level's kernels share for ``k = columns`` and ``dtype``: ``running(scal,
    w)``, whether some column of world ``w`` has not converged, and ``entries(acc, e0, e1, step,
    base, col, val, src)``, ``acc`` plus the sums ``sum_e val[e] src[base + col[e], c]`` over
    ``e0 <= e < e1`` by ``step``, ``(k,)``. The entries are taken ``unroll`` at a time: their
    loads are issued together, then summed in order (the rounding of one loop), so that a thread
    waits for memory once per ``unroll`` entries rather than twice per entry (the column, then
    the operand it points to). ``whole``: an operand row is read whole (:func:`_row_load`), else
    indexed number by number. ``entry``: the types ``(index, value)`` of ``col`` and ``val``
    (None: ``(int32, dtype)``; ``uint16`` columns and ``float16`` values read fewer bytes, the
    sums stay in ``dtype``)."""
    index, value = (wp.int32, dtype) if entry is None else entry
    key = ("funcs", columns, dtype, unroll, whole, index, value)
    if key in _kernels:
        return _kernels[key]
    K, U = columns, unroll
    sums = wp.types.vector(length=K, dtype=dtype)
    loads = wp.types.vector(length=U, dtype=dtype)
    places = wp.types.vector(length=U, dtype=wp.int32)
    load_row = _row_load(K, dtype)

    @wp.func
    def running(scal: wp.array3d(dtype=wp.float64), w: int) -> bool:
        for c in range(K):
            if scal[c, w, DONE] == wp.float64(0.0):
                return True
        return False

    @wp.func
    def add_row(total: sums, v: dtype, src: wp.array2d(dtype=dtype), j: int) -> sums:
        """``total + v src[j, :k]``, the row read whole or indexed."""
        out = total
        if wp.static(whole):
            o = load_row(src, j)
            for c in range(K):
                out[c] = out[c] + v * o[c]
        else:
            for c in range(K):
                out[c] = out[c] + v * src[j, c]
        return out

    @wp.func
    def entries(acc: sums, e0: int, e1: int, step: int, base: int, col: wp.array(dtype=index),
                val: wp.array(dtype=value), src: wp.array2d(dtype=dtype)) -> sums:
        total = acc + sums()
        e = wp.int32(e0)
        while e + (U - 1) * step < e1:  # U whole entries left
            v = loads()
            j = places()
            for u in range(U):
                v[u] = dtype(val[e + u * step])
                j[u] = base + wp.int32(col[e + u * step])
            for u in range(U):
                total = add_row(total, v[u], src, j[u])
            e = e + U * step
        while e < e1:
            total = add_row(total, dtype(val[e]), src, base + wp.int32(col[e]))
            e = e + step
        return total

    _kernels[key] = (running, entries)
    return running, entries


def _task_at(compact: bool):
    """``task_at(i, first, count, worlds, spans, per)``: the task (an index into ``tasks``) of a
    level's ``i``-th thread group, or -1 for none. Every world's tasks (``compact`` False): the
    level's ``i``-th of its ``per``. The running worlds' alone (``compact``): world
    ``worlds[i // per]`` (the first ``count[0]`` of ``worlds`` run) takes its ``(i % per)``-th
    task of the level, where its ``spans[w] = (offset, tasks)`` from the level's first."""
    key = ("task_at", compact)
    if key in _kernels:
        return _kernels[key]

    @wp.func
    def task_at(i: int, first: int, count: wp.array(dtype=wp.int32), worlds: wp.array(dtype=wp.int32),
                spans: wp.array(dtype=wp.vec2i), per: int) -> int:
        if wp.static(compact):
            slot = i // per
            if slot >= count[0]:
                return -1
            span = spans[worlds[slot]]
            local = i - slot * per
            if local >= span[1]:
                return -1
            return first + span[0] + local
        if i >= per:
            return -1  # (a launch rounded up to whole warps)
        return first + i

    _kernels[key] = task_at
    return task_at


def level_kernel(columns: int, dtype, step: int = 1, unroll: int = UNROLL, whole: bool = False,
                 compact: bool = False, entry: tuple | None = None):
    """``factor_level(tasks, first, col, val, node_world, world_row, scal, inp, out, count, worlds,
    spans, per)`` for ``k = columns`` right-hand sides in precision ``dtype``, a task's entries
    ``step`` apart, a thread per task, over a level's tasks, which start at ``tasks[first]``,
    ``unroll`` entries at a time, operand rows read ``whole`` or not (:func:`_row_funcs`): every
    world's tasks (a converged world's return), or with ``compact`` the running worlds' alone
    (:func:`_task_at`: a launch of ``running x per`` threads, however many worlds there are). The
    six are compile-time constants, hence cached per key (a step read from the task, the task
    then five numbers, took the solve from 7.2 to 15.3 ms on the H200). ``entry``: the types of
    ``col`` and ``val``, :func:`_row_funcs`'."""
    index, value = (wp.int32, dtype) if entry is None else entry
    key = ("level", columns, dtype, step, unroll, whole, compact, index, value)
    if key in _kernels:
        return _kernels[key]
    K, STEP = columns, step
    sums = wp.types.vector(length=K, dtype=dtype)
    running, entries = _row_funcs(columns, dtype, unroll, whole, (index, value))
    task_at = _task_at(compact)

    @wp.kernel(module="unique", module_options=OPTIONS)
    def factor_level(tasks: wp.array(dtype=wp.vec4i), first: int, col: wp.array(dtype=index),
                     val: wp.array(dtype=value), node_world: wp.array(dtype=wp.int32),
                     world_row: wp.array(dtype=wp.int32), scal: wp.array3d(dtype=wp.float64),
                     inp: wp.array2d(dtype=dtype), out: wp.array2d(dtype=dtype), count: wp.array(dtype=wp.int32),
                     worlds: wp.array(dtype=wp.int32), spans: wp.array(dtype=wp.vec2i), per: int):
        at = task_at(wp.tid(), first, count, worlds, spans, per)
        if at < 0:
            return  # a running world's thread past its tasks
        t = tasks[at]
        row = t[0]
        if row < 0:
            return  # padding at the end of a slice
        w = node_world[row // 3]
        if wp.static(not compact):
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


def _check_lanes(lanes: int) -> None:
    """The threads that share a task add by shuffles within a warp: a power of 2 up to 32."""
    if lanes & (lanes - 1) or not 1 <= lanes <= 32:
        raise ValueError(f"level lanes must be a power of 2 up to 32, got {lanes}")


def _lane_sum(columns: int, dtype, lanes: int):
    """``lane_sum(v)``: on CUDA the sum of ``v`` (``(k,)``) over the ``lanes`` neighbouring threads
    of a warp that share a task (``lanes`` a power of 2 up to 32, the task's threads aligned on
    it), in each of them, by shuffles (no shared memory, no barrier: several tasks a block);
    elsewhere, where a task has one thread, ``v``."""
    key = ("lane_sum", columns, dtype, lanes)
    if key in _kernels:
        return _kernels[key]
    _check_lanes(lanes)
    ctype = "float" if dtype == wp.float32 else "double"
    snippet = "\n".join([
        f"wp::vec_t<{columns}, {ctype}> s = v;",
        "#if defined(__CUDA_ARCH__)",
        f"for (int o = {lanes // 2}; o > 0; o >>= 1)",
        f"    for (int c = 0; c < {columns}; ++c) s.c[c] += __shfl_xor_sync(0xffffffffu, s.c[c], o, {lanes});",
        "#endif",
        "return s;"])
    sums = wp.types.vector(length=columns, dtype=dtype)

    @wp.func_native(snippet)
    def lane_sum(v: sums) -> sums: ...

    _kernels[key] = lane_sum
    return lane_sum


def level_kernel_lanes(columns: int, dtype, lanes: int, unroll: int = UNROLL, whole: bool = False,
                       compact: bool = False, step: int = 1, entry: tuple | None = None):
    """:func:`level_kernel` with ``lanes`` neighbouring threads per task (``lanes`` dividing 32; a
    launch of ``tasks x lanes`` threads, or ``running x per x lanes`` with ``compact``, rounded
    up to whole warps): they stride the task's entries (lane ``l`` its ``l``-th, ``l + lanes``-th,
    ..., each ``step`` apart), so that a long row keeps ``lanes`` loads in flight, and warp
    shuffles add their shares (:func:`_lane_sum`). Every thread of a warp reaches the shuffles (a
    thread with no task adds nothing), so tasks may share warps. A block holds ``block_dim /
    lanes`` tasks: with a tile a task (a block of 32 threads, a tile sum) the SM held half its
    warps at most (32 blocks), and a level of long rows launched a block a row however few worlds
    still ran (1024 Diamonds: ``P^-1`` 5.54 -> 5.01 ms, docs/performance.md). ``step`` > 1: the
    rows of slices (their entries interleaved), which take lanes in the tail, where few worlds
    run and a row's thread would walk its entries alone. ``entry``: the types of ``col`` and
    ``val``, :func:`_row_funcs`'."""
    index, value = (wp.int32, dtype) if entry is None else entry
    key = ("lanes", columns, dtype, lanes, unroll, whole, compact, step, index, value)
    if key in _kernels:
        return _kernels[key]
    K, L, STEP = columns, lanes, step
    sums = wp.types.vector(length=K, dtype=dtype)
    running, entries = _row_funcs(columns, dtype, unroll, whole, (index, value))
    lane_sum = _lane_sum(columns, dtype, lanes)
    task_at = _task_at(compact)

    @wp.kernel(module="unique", module_options=OPTIONS)
    def factor_level_lanes(tasks: wp.array(dtype=wp.vec4i), first: int, col: wp.array(dtype=index),
                           val: wp.array(dtype=value), node_world: wp.array(dtype=wp.int32),
                           world_row: wp.array(dtype=wp.int32), scal: wp.array3d(dtype=wp.float64),
                           inp: wp.array2d(dtype=dtype), out: wp.array2d(dtype=dtype),
                           count: wp.array(dtype=wp.int32), worlds: wp.array(dtype=wp.int32),
                           spans: wp.array(dtype=wp.vec2i), per: int):
        tid = wp.tid()
        lane = tid % L
        at = task_at(tid // L, first, count, worlds, spans, per)
        row = wp.int32(-1)  # -1: nothing to write (no task, padding, or a converged world's)
        acc = sums()
        if at >= 0:
            t = tasks[at]
            if t[0] >= 0:
                w = node_world[t[0] // 3]
                live = True
                if wp.static(not compact):
                    live = running(scal, w)  # (the same for the task's lanes)
                if live:
                    row = t[0]
                    base = world_row[w]
                    acc = entries(acc, t[1] + lane * STEP, t[2], L * STEP, base, col, val, inp)
                    acc = entries(acc, t[2] + lane * STEP, t[3], L * STEP, base, col, val, out)
        total = lane_sum(acc)
        if lane == 0 and row >= 0:
            for c in range(K):
                out[row, c] = total[c]

    _kernels[key] = factor_level_lanes
    return factor_level_lanes


def _lane_scatter(size: int, dtype, lanes: int):
    """``(scatter_sum(v, lane), scatter_place(lane), kept)``: on CUDA, the sums of ``v`` (``(size,)``)
    over the ``lanes`` neighbouring threads that share a task, spread over them (a reduce-scatter
    by shuffles): at each of ``log2(lanes)`` rounds a thread keeps one half of what it holds and
    sends the other to its partner, which keeps the other half, so that ``size`` numbers take about
    ``size`` shuffles in all (:func:`_lane_sum`'s butterfly: ``size log2(lanes)``). ``scatter_sum``
    returns the ``kept`` numbers a thread holds at the end; ``scatter_place`` gives, for the thread
    ``lane``, the index in ``v`` of the first and how many of them are sums (the others pad).
    Elsewhere (one thread a task) ``v`` itself, ``(0, size)``."""
    key = ("lane_scatter", size, dtype, lanes)
    if key in _kernels:
        return _kernels[key]
    _check_lanes(lanes)
    ctype = "float" if dtype == wp.float32 else "double"
    rounds, n = [], size  # (partner offset, the half a thread keeps), from the widest
    o = lanes // 2
    while o > 0:
        rounds.append((o, (n + 1) // 2))
        n, o = (n + 1) // 2, o // 2
    kept = n
    code = [f"{ctype} s[{size}];", f"for (int i = 0; i < {size}; ++i) s[i] = v.c[i];", "#if defined(__CUDA_ARCH__)"]
    n = size
    for o, half in rounds:
        code.append(f"{{ const bool up = (lane & {o}) != 0;")
        for i in range(half):
            hi = f"s[{half + i}]" if half + i < n else ("0.0f" if ctype == "float" else "0.0")
            code.append(f"  {{ const {ctype} lo = s[{i}], hi = {hi};"
                        f" s[{i}] = (up ? hi : lo) + __shfl_xor_sync(0xffffffffu, up ? lo : hi, {o}, {lanes}); }}")
        code.append("}")
        n = half
    code += ["#endif", f"wp::vec_t<{kept}, {ctype}> out;", f"for (int i = 0; i < {kept}; ++i) out.c[i] = s[i];",
             "return out;"]
    place = ["int first = 0, count = " + str(size) + ";"]
    for o, half in rounds:  # the kept half's place and its numbers that are sums (the upper half may pad)
        place.append(f"if (lane & {o}) {{ first += {half}; count = count > {half} ? count - {half} : 0; }} "
                     f"else {{ count = count < {half} ? count : {half}; }}")
    place.append("return wp::vec_t<2, int>(first, count);")
    full = wp.types.vector(length=size, dtype=dtype)

    @wp.func_native("\n".join(code))
    def scatter_sum(v: full, lane: int) -> wp.types.vector(length=kept, dtype=dtype): ...

    @wp.func_native("\n".join(place))
    def scatter_place(lane: int) -> wp.vec2i: ...

    _kernels[key] = (scatter_sum, scatter_place, kept)
    return _kernels[key]


# a panel task: its first row (world-flat), rows, first value, first column, input and output columns,
# its world and the world's first row (so that a lane finds them in the task it loads, not by two more
# loads one after the other)
panel_task = wp.types.vector(length=8, dtype=wp.int32)
PANEL_UNROLL = 4  # columns a panel's lane loads at a time


def _panel_columns(columns: int, dtype, rows: int, unroll: int, whole: bool, entry: tuple):
    """``columns_of(acc, height, v0, stride, c0, q0, q1, lane, lanes, base, col, val, src)``: a panel
    lane's walk (:func:`panel_kernel`), ``acc`` (``(rows x k,)``, the panel's sums row by row) plus
    ``sum_q val[v0 + i stride + q] src[base + col[c0 + q], c]`` for each of its ``height`` rows ``i``
    and columns ``c``, over the columns ``q = q0 + lane, q0 + lane + lanes, ... < q1``, ``unroll`` at
    a time (their loads issued together, then summed in order)."""
    index, value = entry
    key = ("panel_columns", columns, dtype, rows, unroll, whole, index, value)
    if key in _kernels:
        return _kernels[key]
    K, H, U = columns, rows, unroll
    sums = wp.types.vector(length=K, dtype=dtype)
    block = wp.types.vector(length=H * K, dtype=dtype)  # a panel's sums, row by row
    loaded = wp.types.vector(length=U * K, dtype=dtype)
    load_row = _row_load(K, dtype)

    @wp.func
    def operand(src: wp.array2d(dtype=dtype), j: int) -> sums:
        """Row ``j`` of ``src``, ``(k,)``: read whole or indexed (:func:`_row_funcs`)."""
        if wp.static(whole):
            return load_row(src, j)
        x = sums()
        for c in range(K):
            x[c] = src[j, c]
        return x

    @wp.func
    def columns_of(acc: block, height: int, v0: int, stride: int, c0: int, q0: int, q1: int, lane: int, lanes: int,
                   base: int, col: wp.array(dtype=index), val: wp.array(dtype=value),
                   src: wp.array2d(dtype=dtype)) -> block:
        """``acc`` plus the panel's columns ``q0 + lane, q0 + lane + lanes, ... < q1`` read from ``src``."""
        total = acc + block()
        q = wp.int32(q0 + lane)
        while q + (U - 1) * lanes < q1:  # U whole columns left
            xs = loaded()
            for u in range(U):
                x = operand(src, base + wp.int32(col[c0 + q + u * lanes]))
                for c in range(K):
                    xs[u * K + c] = x[c]
            for u in range(U):
                for i in range(H):
                    if i < height:
                        v = dtype(val[v0 + i * stride + q + u * lanes])
                        for c in range(K):
                            total[i * K + c] = total[i * K + c] + v * xs[u * K + c]
            q = q + U * lanes
        while q < q1:
            x = operand(src, base + wp.int32(col[c0 + q]))
            for i in range(H):
                if i < height:
                    v = dtype(val[v0 + i * stride + q])
                    for c in range(K):
                        total[i * K + c] = total[i * K + c] + v * x[c]
            q = q + lanes
        return total

    _kernels[key] = columns_of
    return columns_of


def panel_kernel(columns: int, dtype, rows: int, lanes: int, unroll: int = PANEL_UNROLL, whole: bool = False,
                 compact: bool = False, entry: tuple | None = None, check: bool = True):
    """``factor_panel(tasks, first, col, val, scal, inp, out, count, worlds, spans, per)``: one
    level of panels (``warpsoft/linear/supernodal.py``'s :class:`Panels`), for ``k = columns``
    right-hand sides in precision ``dtype``, at most ``rows`` rows a panel, ``lanes`` neighbouring
    threads a panel (a power of 2 up to 32; a launch of ``tasks x lanes`` threads, or ``running x
    per x lanes`` with ``compact``: :func:`_task_at`, rounded up to whole warps). Task ``(row, h,
    v0, c0, ni, no, w, base)`` of world ``w``, whose first row is ``base``, writes ``out[row + i, c]
    = sum_q val[v0 + i (ni + no) + q] src_q[base + col[c0 + q], c]`` for its ``h`` rows, ``src_q``
    the input for ``q < ni``, the output after. Lane ``l`` takes the columns ``q = l, l + lanes,
    ...``: it reads each column's operand row once for the panel's rows (a thread a row reads it
    once a row), ``unroll`` columns at a time (their loads issued together, then summed in order),
    and warp shuffles add the lanes' ``rows x k`` sums, each lane then writing a share
    (:func:`_lane_scatter`). ``whole``, ``compact`` and ``entry``: as :func:`level_kernel`'s.
    ``check`` False: every world's tasks run, with no test of their world's columns (when every
    world runs: a task's lanes then wait for two loads, the task and its first columns, before the
    operands, not three)."""
    index, value = (wp.int32, dtype) if entry is None else entry
    key = ("panel", columns, dtype, rows, lanes, unroll, whole, compact, index, value, check)
    if key in _kernels:
        return _kernels[key]
    K, H, L = columns, rows, lanes
    block = wp.types.vector(length=H * K, dtype=dtype)  # a panel's sums, row by row
    running, _ = _row_funcs(columns, dtype, 1, whole, (index, value))
    scatter_sum, scatter_place, KEPT = _lane_scatter(H * K, dtype, lanes)
    task_at = _task_at(compact)
    columns_of = _panel_columns(columns, dtype, rows, unroll, whole, (index, value))

    @wp.kernel(module="unique", module_options=OPTIONS)
    def factor_panel(tasks: wp.array(dtype=panel_task), first: int, col: wp.array(dtype=index),
                     val: wp.array(dtype=value), scal: wp.array3d(dtype=wp.float64), inp: wp.array2d(dtype=dtype),
                     out: wp.array2d(dtype=dtype), count: wp.array(dtype=wp.int32), worlds: wp.array(dtype=wp.int32),
                     spans: wp.array(dtype=wp.vec2i), per: int):
        tid = wp.tid()
        lane = tid % L
        at = task_at(tid // L, first, count, worlds, spans, per)
        row = wp.int32(-1)  # -1: nothing to write (no task, or a converged world's)
        height = wp.int32(0)
        acc = block()
        if at >= 0:
            t = tasks[at]
            live = True
            if wp.static(check and not compact):
                live = running(scal, t[6])  # (the same for the task's lanes)
            if live:
                row = t[0]
                height = t[1]
                base = t[7]
                stride = t[4] + t[5]
                # the diagonal block's inverse on the input, then the rows solved at earlier levels
                acc = columns_of(acc, height, t[2], stride, t[3], 0, t[4], lane, L, base, col, val, inp)
                acc = columns_of(acc, height, t[2], stride, t[3], t[4], stride, lane, L, base, col, val, out)
        # the lanes' sums spread over them: each writes those it holds (sum m is the panel's number
        # first + m, row (first + m) // k)
        if wp.static(L == 1):  # (a thread holds them all)
            if row >= 0:
                for i in range(H):
                    if i < height:
                        for c in range(K):
                            out[row + i, c] = acc[i * K + c]
        else:
            total = scatter_sum(acc, lane)
            place = scatter_place(lane)
            if row >= 0:
                for m in range(wp.static(KEPT)):  # (unrolled: the sums stay in registers)
                    if m < place[1]:
                        i = (place[0] + m) // K
                        if i < height:
                            out[row + i, place[0] + m - i * K] = total[m]

    _kernels[key] = factor_panel
    return factor_panel


def wide_panel_kernel(columns: int, dtype, rows: int, unroll: int = PANEL_UNROLL, whole: bool = False,
                      entry: tuple | None = None):
    """``factor_wide_panel(tasks, first, col, val, inp, out, count, worlds, spans, per)``: one level of
    the running worlds' panels alone (the tail: :func:`_task_at`'s ``compact``), a block of threads a
    panel (``wp.launch_tiled`` of ``running x per`` blocks), for :func:`panel_kernel`'s ``columns``,
    ``dtype``, ``rows``, ``unroll``, ``whole`` and ``entry``. In the tail threads are spare, and a
    level lasts as long as its longest panel's walk: 32 lanes walk a panel of the root's 2,208
    columns 69 columns each, 17 rounds of loads one after the other. Here the block's threads stride
    the columns (``q = lane, lane + block_dim, ...``) and a tile sum adds their ``rows x k`` sums,
    which the block's first thread writes. On the CPU a block has one thread: it walks every column."""
    index, value = (wp.int32, dtype) if entry is None else entry
    key = ("wide_panel", columns, dtype, rows, unroll, whole, index, value)
    if key in _kernels:
        return _kernels[key]
    K, H = columns, rows
    block = wp.types.vector(length=H * K, dtype=dtype)  # a panel's sums, row by row
    task_at = _task_at(True)
    columns_of = _panel_columns(columns, dtype, rows, unroll, whole, (index, value))

    @wp.kernel(module="unique", module_options=OPTIONS)
    def factor_wide_panel(tasks: wp.array(dtype=panel_task), first: int, col: wp.array(dtype=index),
                          val: wp.array(dtype=value), inp: wp.array2d(dtype=dtype), out: wp.array2d(dtype=dtype),
                          count: wp.array(dtype=wp.int32), worlds: wp.array(dtype=wp.int32),
                          spans: wp.array(dtype=wp.vec2i), per: int):
        slot, lane = wp.tid()
        at = task_at(slot, first, count, worlds, spans, per)
        if at < 0:
            return  # (the whole block: no running world in this slot, or one past its tasks)
        t = tasks[at]
        height, stride, lanes = t[1], t[4] + t[5], wp.block_dim()
        # the diagonal block's inverse on the input, then the rows solved at earlier levels
        acc = columns_of(block(), height, t[2], stride, t[3], 0, t[4], lane, lanes, t[7], col, val, inp)
        acc = columns_of(acc, height, t[2], stride, t[3], t[4], stride, lane, lanes, t[7], col, val, out)
        total = wp.tile_sum(wp.tile(acc, preserve_type=True))
        if lane == 0:
            sums = total[0]
            for i in range(H):
                if i < height:
                    for c in range(K):
                        out[t[0] + i, c] = sums[i * K + c]

    _kernels[key] = factor_wide_panel
    return factor_wide_panel



def running_worlds(columns: int):
    """``running_worlds(scal, count, worlds)``, a thread per world: a world with a column not
    converged appends itself to ``worlds`` (``count[0]`` of them, in no set order: each task's
    sums are its own, so the product does not depend on it)."""
    key = ("running", columns)
    if key in _kernels:
        return _kernels[key]
    running, _ = _row_funcs(columns, wp.float32)

    @wp.kernel(module="unique", module_options=OPTIONS)
    def factor_running(scal: wp.array3d(dtype=wp.float64), count: wp.array(dtype=wp.int32),
                       worlds: wp.array(dtype=wp.int32)):
        w = wp.tid()
        if running(scal, w):
            worlds[wp.atomic_add(count, 0, 1)] = w

    _kernels[key] = factor_running
    return factor_running


@wp.kernel
def pick_tail(count: wp.array(dtype=wp.int32), tiers: wp.array(dtype=wp.int32), worlds: int,
              branch: wp.array(dtype=wp.int32)):
    """One thread: ``branch[j] = 1`` for the smallest tier ``j`` that holds the ``count[0]``
    running worlds (``tiers`` ascending, ``n`` of them); else ``branch[n] = 1`` (every world's
    tasks, each testing its world) when some of the ``worlds`` have converged, ``branch[n + 1] =
    1`` (every world's tasks, untested) when none has; 0 elsewhere."""
    n = tiers.shape[0]
    pick = wp.int32(n)
    for j in range(n):
        branch[j] = 0
        if pick == n and count[0] <= tiers[j]:
            pick = wp.int32(j)
    branch[n] = 0
    branch[n + 1] = 0
    if pick == n and count[0] >= worlds:
        pick = n + 1
    branch[pick] = 1
