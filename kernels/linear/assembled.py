"""Kernels of the assembled system operator: ``A = mass_scale M + stiffness_scale K`` kept as 3x3
blocks by node rows, refreshed at each linearization and applied to every column of a batched
solve in one pass over the blocks.

The rows are cut in chunks of ``C`` consecutive rows (sliced ELLPACK): slot ``s`` of the chunk's
rows lie side by side, at ``(chunk_start[ch] + s) C + lane``, each row padded to the chunk's
longest (``chunk_slots[ch]`` slots; a padding slot holds a zero block). On CUDA a chunk is a
warp's 32 rows, whose threads then read one stretch of memory at each slot instead of 32 rows'
scattered blocks (1024 Diamonds on the H200, 5 float32 columns: 876 -> 708 us a product at 1.31
times the slots; docs/performance.md); with ``C = 1`` (the CPU) it is the rows compressed (BSR).

The pattern couples the node pairs of every element (both triangles); a block's slot sums the
element blocks that land on it, listed per slot (``slot_start``, ``contributions``: indexes into
the element models' blocks), so the refresh is a gather with no atomics. The product reads each
stored block once for all the columns (``k``, a compile-time constant: the sums stay in
registers), which the matrix-free product cannot: there every element's four nodes take twelve
atomic additions per column.
"""

import warp as wp

from .. import OPTIONS
from .cg import column_done

wp.set_module_options(OPTIONS)

_kernels = {}


@wp.kernel
def gather_blocks(blocks: wp.array(dtype=wp.mat33d), slot_start: wp.array(dtype=wp.int32),
                  contributions: wp.array(dtype=wp.int32), values: wp.array(dtype=wp.mat33d)):
    """``values[s] = sum(blocks[contributions[j]])`` over ``slot_start[s] <= j < slot_start[s + 1]``:
    the stiffness blocks (N/m) of the element models summed into the stored slots, a thread per slot."""
    s = wp.tid()
    acc = wp.mat33d()
    for j in range(slot_start[s], slot_start[s + 1]):
        acc += blocks[contributions[j]]
    values[s] = acc


def block_product(columns: int, vector=wp.vec3d):
    """``block_product(x, chunk_start, chunk_slots, chunk_rows, column, values, scale, mass, mass_scale,
    world, done, y)`` for ``k = columns`` columns (a compile-time constant, hence cached per ``k`` and
    ``vector``), a thread per node row ``i``: ``y[c, i] = mass_scale mass[i] x[c, i] + scale sum_j
    values[j] x[c, column[j]]`` over the row's slots (chunks of ``chunk_rows``: the module doc); a
    converged column of the row's world (``done``, the CG scalars ``(k, worlds, slots)``, or empty)
    keeps what ``y`` held. ``mass`` is empty when ``mass_scale`` is 0. ``x`` holds ``vector`` (vec3d,
    or vec3f: the block CG's directions in single precision), the sums and ``y`` float64 (the
    product of the stored directions, exact to float64's rounding)."""
    key = (columns, vector)
    if key in _kernels:
        return _kernels[key]
    K = columns
    sums = wp.types.matrix(shape=(K, 3), dtype=wp.float64)
    flags = wp.types.vector(length=K, dtype=wp.int32)

    @wp.kernel(module="unique", module_options=OPTIONS)
    def assembled_product(x: wp.array2d(dtype=vector), chunk_start: wp.array(dtype=wp.int32),
                          chunk_slots: wp.array(dtype=wp.int32), chunk_rows: int,
                          column: wp.array(dtype=wp.int32), values: wp.array(dtype=wp.mat33d),
                          scale: wp.float64, mass: wp.array(dtype=wp.float64), mass_scale: wp.float64,
                          world: wp.array(dtype=wp.int32), done: wp.array3d(dtype=wp.float64),
                          y: wp.array2d(dtype=wp.vec3d)):
        i = wp.tid()
        w = world[i]
        active = flags()
        any_active = wp.int32(0)
        for c in range(wp.static(K)):
            if not column_done(done, c, w):
                active[c] = 1
                any_active = 1
        if any_active == 0:
            return
        acc = sums()
        ch = i // chunk_rows
        j = chunk_start[ch] * chunk_rows + i - ch * chunk_rows  # the row's first slot
        for _s in range(chunk_slots[ch]):
            block = values[j]
            n = column[j]
            for c in range(wp.static(K)):
                if active[c] != 0:
                    acc[c] = acc[c] + block * wp.vec3d(x[c, n])
            j += chunk_rows
        m = wp.float64(0.0)
        if mass.shape[0] > 0:
            m = mass_scale * mass[i]
        for c in range(wp.static(K)):
            if active[c] != 0:
                y[c, i] = m * wp.vec3d(x[c, i]) + scale * acc[c]

    _kernels[key] = assembled_product
    return assembled_product
