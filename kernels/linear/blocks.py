"""Kernels of the warped preconditioner applied world by world: ``z = Q blockdiag(s_w A_b(w)^-1) Q^T r``.

The worlds of a model are independent bodies, so ``A`` is block diagonal and so is its inverse:
each world ``w`` keeps a dense inverse ``A_b^-1`` of its own free DOFs (``b = b(w)``; worlds
whose rest systems are equal up to a factor share one block, scaled by ``s_w``). The flat operand
``U`` ``(N, k)`` holds world ``w`` in rows ``first_row[w] .. first_row[w] + size[w]``, node ``i``'s
DOF ``a`` in row ``node_row[i] + a`` (each world's rows padded to the segment size; padding
rows stay 0). The blocks are the rows of one ``(sum of block sizes, largest / W)`` array of
``vector(W)``: block ``b`` starts at row ``block_row``.

The product streams each block down its columns, as the whole-model product does
(``warped.py``): a thread sums ``A_b[j, i..i+W-1] U_w[j, :]`` over the ``size / S`` rows ``j`` of
its segment (the world's scale multiplies the segments' sum on the way out). A block shared by several worlds is read
once for up to ``G`` of them: the thread keeps ``G`` worlds' sums (the block's bytes, which bound
the product, are divided by ``G``; the operands of the ``G`` worlds are the same for the whole
warp). A chunk of worlds whose columns have all converged (``scal[c, w, DONE]``) skips its
product: their ``z`` is no longer used (their step length is 0), so converged worlds stop
costing the dense product's bandwidth.

A block shared by many worlds is a matrix product instead, ``Z_b = A_b^-1 [U_w1 .. U_wn]``
(:func:`tiled_kernel`): its worlds' operands are the columns of one ``(size, k n)`` region of a
second flat array ``G``, and the product runs in tiles through shared memory (Warp's
``tile_matmul``), so each number of the block loaded serves a whole tile of columns. Streamed, a
thread serves at most ``G = 8`` worlds and reloads its operands for each; tiled, the product is
bound by arithmetic, not by loads. The columns still running are packed at the front of their
region at each application (:func:`pack_tiled_columns`), and only the tiles that hold them run:
the product's cost follows the worlds that have not converged, in whatever order they converge.
"""

import warp as wp

from .. import OPTIONS
from .cg import DONE
from .warped import wide_type

wp.set_module_options(OPTIONS)

_kernels = {}


def block_kernels(columns: int, dtype, segments: int, unroll: int, width: int, group: int = 1):
    """``(rotate_in, partial_product, rotate_out)`` for ``k = columns`` right-hand sides, inverse
    precision ``dtype``, ``S = segments`` segments of each world's rows, ``unroll`` loads in flight
    per thread, ``W = width`` numbers per load, and up to ``G = group`` worlds of one block served by
    each thread (compile-time constants, hence cached per key).

    - ``rotate_in(r, q_rot, mask, node_row, node_world, first_row, tiled, tiled_col, scal, U, G)`` over
      ``(k, n)``: ``U[node_row[i] + a, c] = (mask_i Q_i^T r[c, i])_a``, or for a world ``w`` of a tiled
      block (``tiled[w] != 0``) ``G[node_row[i] - first_row[w] + a, tiled_col[c, w]]`` (the column
      :func:`pack_tiled_columns` gave it); a converged column (``scal[c, w, DONE]``) is skipped;
    - ``partial_product(A, U, row_chunk, chunk_first, chunk_worlds, first_row, block_row, size, scal, P)``
      over ``(S, T)``: the worlds are dealt into chunks of at most ``G`` worlds sharing a block
      (``chunk_worlds`` ``(chunks, G)``, -1 where a chunk has fewer); thread ``t`` serves the ``W``
      columns ``t - chunk_first[ch]`` of chunk ``ch = row_chunk[t]``'s block for each of its worlds:
      ``P[s, c, first_row[w] + cols] = sum_j A[block_row[w] + j, cols] U[first_row[w] + j, c]``
      over the segment ``s`` of the block's ``size`` rows. One load of the block serves ``G`` worlds;
    - ``rotate_out(P, Z, q_rot, mask, node_row, node_world, first_row, tiled, tiled_col, scale, scal, z)``
      over ``(k, n)``: ``z[c, i] = mask_i Q_i scale[w] sum_s P[s, c, node_row[i] + a]``, or for a world of a
      tiled block ``Z[...]`` at the place ``rotate_in`` took its operand instead of the sum (both
      products leave the world's scale, ``s_w`` of a shared block, to this last step).
    """
    key = (columns, dtype, segments, unroll, width, group)
    if key in _kernels:
        return _kernels[key]
    K, S, UN, W, G = columns, segments, unroll, width, group
    wide = wide_type(W, dtype)
    sums = wp.types.matrix(shape=(G * W, K), dtype=dtype)
    rows = wp.types.vector(length=G, dtype=wp.int32)

    @wp.kernel(module="unique", module_options=OPTIONS)
    def blocks_rotate_in(r: wp.array2d(dtype=wp.vec3d), q_rot: wp.array(dtype=wp.mat33d),
                         mask: wp.array(dtype=wp.vec3d), node_row: wp.array(dtype=wp.int32),
                         node_world: wp.array(dtype=wp.int32), first_row: wp.array(dtype=wp.int32),
                         tiled: wp.array(dtype=wp.int32), tiled_col: wp.array2d(dtype=wp.int32),
                         scal: wp.array3d(dtype=wp.float64), U: wp.array2d(dtype=dtype), G: wp.array2d(dtype=dtype)):
        c, i = wp.tid()
        w = node_world[i]
        if scal[c, w, DONE] != wp.float64(0.0):
            return  # converged: its operand is not used (the products skip it or leave its result unread)
        v = wp.cw_mul(mask[i], wp.transpose(q_rot[i]) * r[c, i])
        row = node_row[i]
        if tiled[w] != 0:  # a world of a tiled block: its column of G, rows local to the world
            row = row - first_row[w]
            col = tiled_col[c, w]
            G[row, col] = dtype(v[0])
            G[row + 1, col] = dtype(v[1])
            G[row + 2, col] = dtype(v[2])
        else:
            U[row, c] = dtype(v[0])
            U[row + 1, c] = dtype(v[1])
            U[row + 2, c] = dtype(v[2])

    @wp.kernel(module="unique", module_options=OPTIONS)
    def blocks_partial_product(A: wp.array2d(dtype=wide), U: wp.array2d(dtype=dtype),
                               row_chunk: wp.array(dtype=wp.int32), chunk_first: wp.array(dtype=wp.int32),
                               chunk_worlds: wp.array2d(dtype=wp.int32), first_row: wp.array(dtype=wp.int32),
                               block_row: wp.array(dtype=wp.int32), size: wp.array(dtype=wp.int32),
                               scal: wp.array3d(dtype=wp.float64), P: wp.array3d(dtype=dtype)):
        s, t = wp.tid()
        ch = row_chunk[t]
        w0 = chunk_worlds[ch, 0]
        u0 = rows()
        running = wp.int32(0)
        for g in range(G):
            w = chunk_worlds[ch, g]
            u0[g] = first_row[w0]  # a missing world reads the first one's operand (never written out)
            if w >= 0:
                u0[g] = first_row[w]
                for c in range(K):
                    if scal[c, w, DONE] == wp.float64(0.0):
                        running = 1
        if running == 0:
            return  # every column of every world of this chunk converged
        i = t - chunk_first[ch]  # this thread's W columns of the block
        segment = size[w0] // S
        a0 = block_row[w0]
        acc = sums()
        j = s * segment
        end = j + segment
        while j < end:
            for u in range(UN):  # unrolled: UN independent loads of A in flight per thread
                a = A[a0 + j + u, i]
                for g in range(G):
                    for c in range(K):
                        uc = U[u0[g] + j + u, c]
                        for v in range(W):
                            acc[g * W + v, c] = acc[g * W + v, c] + a[v] * uc
            j += UN
        for g in range(G):
            w = chunk_worlds[ch, g]
            if w >= 0:
                for c in range(K):
                    for v in range(W):
                        P[s, c, u0[g] + W * i + v] = acc[g * W + v, c]

    @wp.kernel(module="unique", module_options=OPTIONS)
    def blocks_rotate_out(P: wp.array3d(dtype=dtype), Z: wp.array2d(dtype=dtype), q_rot: wp.array(dtype=wp.mat33d),
                          mask: wp.array(dtype=wp.vec3d), node_row: wp.array(dtype=wp.int32),
                          node_world: wp.array(dtype=wp.int32), first_row: wp.array(dtype=wp.int32),
                          tiled: wp.array(dtype=wp.int32), tiled_col: wp.array2d(dtype=wp.int32),
                          scale: wp.array(dtype=dtype), scal: wp.array3d(dtype=wp.float64),
                          z: wp.array2d(dtype=wp.vec3d)):
        c, i = wp.tid()
        w = node_world[i]
        if scal[c, w, DONE] != wp.float64(0.0):
            return  # converged: its z is not used
        row = node_row[i]
        y = wp.vec3d()
        if tiled[w] != 0:
            row = row - first_row[w]
            col = tiled_col[c, w]
            y = wp.vec3d(wp.float64(Z[row, col]), wp.float64(Z[row + 1, col]), wp.float64(Z[row + 2, col]))
        else:
            for s in range(S):
                y += wp.vec3d(wp.float64(P[s, c, row]), wp.float64(P[s, c, row + 1]), wp.float64(P[s, c, row + 2]))
        z[c, i] = wp.cw_mul(mask[i], q_rot[i] * (wp.float64(scale[w]) * y))

    _kernels[key] = (blocks_rotate_in, blocks_partial_product, blocks_rotate_out)
    return _kernels[key]


@wp.kernel
def pack_tiled_columns(world_list: wp.array(dtype=wp.int32), list_region: wp.array(dtype=wp.int32),
                       region_col: wp.array(dtype=wp.int32), scal: wp.array3d(dtype=wp.float64),
                       count: wp.array(dtype=wp.int32), tiled_col: wp.array2d(dtype=wp.int32)):
    """Launched over ``(k, tiled worlds)``, ``count`` zeroed before: column ``c`` of world
    ``w = world_list[j]``, when it has not converged, takes the next free column of its region
    ``g = list_region[j]``: ``tiled_col[c, w] = region_col[g] + count[g]++``. The order within a
    region is that of the atomics; a column's product does not depend on where it sits."""
    c, j = wp.tid()
    w = world_list[j]
    if scal[c, w, DONE] == wp.float64(0.0):
        g = list_region[j]
        tiled_col[c, w] = region_col[g] + wp.atomic_add(count, g, 1)


def tiled_kernel(dtype, tile_m: int, tile_n: int, tile_k: int):
    """The product of the blocks shared by many worlds, in ``(TM, TN)`` tiles of the result over
    ``TK``-deep slices (compile-time constants, hence cached per key); launched tiled over the
    tile list: ``tiled_product(A, G, tiles, region_size, region_col, count, Z)``.

    Tile ``t`` is ``tiles[t] = (a0, r0, c0, g)``: rows ``r0 .. r0 + TM`` of region ``g``'s block,
    which starts at row ``a0 - r0`` of ``A``; columns ``c0 .. c0 + TN`` of ``G`` and ``Z``. Region
    ``g``'s columns start at ``region_col[g]``, the first ``count[g]`` of them in use
    (:func:`pack_tiled_columns`). It computes
    ``Z[r0:r0+TM, c0:c0+TN] = sum_j A[a0:a0+TM, j:j+TK] G[j:j+TK, c0:c0+TN]`` over the block's
    ``region_size[g]`` rows; a tile whose columns are all past those in use is skipped.
    """
    key = ("tiled", dtype, tile_m, tile_n, tile_k)
    if key in _kernels:
        return _kernels[key]
    TM, TN, TK = tile_m, tile_n, tile_k

    @wp.kernel(module="unique", module_options=OPTIONS)
    def blocks_tiled_product(A: wp.array2d(dtype=dtype), G: wp.array2d(dtype=dtype), tiles: wp.array(dtype=wp.vec4i),
                             region_size: wp.array(dtype=wp.int32), region_col: wp.array(dtype=wp.int32),
                             count: wp.array(dtype=wp.int32), Z: wp.array2d(dtype=dtype)):
        t = wp.tid()
        tile = tiles[t]
        g = tile[3]
        if tile[2] - region_col[g] >= count[g]:
            return  # every column of the tile is past those in use
        acc = wp.tile_zeros(shape=(TM, TN), dtype=dtype)
        for j in range(region_size[g] // TK):
            a = wp.tile_load(A, shape=(TM, TK), offset=(tile[0], j * TK))
            u = wp.tile_load(G, shape=(TK, TN), offset=(j * TK, tile[2]))
            wp.tile_matmul(a, u, acc)
        wp.tile_store(Z, acc, offset=(tile[1], tile[2]))

    _kernels[key] = blocks_tiled_product
    return blocks_tiled_product
