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
its segment, and the world's scale multiplies the sum. A block shared by several worlds is read
once for up to ``G`` of them: the thread keeps ``G`` worlds' sums (the block's bytes, which bound
the product, are divided by ``G``; the operands of the ``G`` worlds are the same for the whole
warp). A chunk of worlds whose columns have all converged (``scal[c, w, DONE]``) skips its
product: their ``z`` is no longer used (their step length is 0), so converged worlds stop
costing the dense product's bandwidth.
"""

import warp as wp

from .cg import DONE
from .warped import wide_type

_kernels = {}


def block_kernels(columns: int, dtype, segments: int, unroll: int, width: int, group: int = 1):
    """``(rotate_in, partial_product, rotate_out)`` for ``k = columns`` right-hand sides, inverse
    precision ``dtype``, ``S = segments`` segments of each world's rows, ``unroll`` loads in flight
    per thread, ``W = width`` numbers per load, and up to ``G = group`` worlds of one block served by
    each thread (compile-time constants, hence cached per key).

    - ``rotate_in(r, q_rot, mask, node_row, U)`` over ``(k, n)``: ``U[node_row[i] + a, c] = (mask_i Q_i^T r[c, i])_a``;
    - ``partial_product(A, U, row_chunk, chunk_first, chunk_worlds, first_row, block_row, size, scale, scal, P)``
      over ``(S, T)``: the worlds are dealt into chunks of at most ``G`` worlds sharing a block
      (``chunk_worlds`` ``(chunks, G)``, -1 where a chunk has fewer); thread ``t`` serves the ``W``
      columns ``t - chunk_first[ch]`` of chunk ``ch = row_chunk[t]``'s block for each of its worlds:
      ``P[s, c, first_row[w] + cols] = scale[w] sum_j A[block_row[w] + j, cols] U[first_row[w] + j, c]``
      over the segment ``s`` of the block's ``size`` rows. One load of the block serves ``G`` worlds;
    - ``rotate_out(P, q_rot, mask, node_row, z)`` over ``(k, n)``:
      ``z[c, i] = mask_i Q_i sum_s P[s, c, node_row[i] + a]``.
    """
    key = (columns, dtype, segments, unroll, width, group)
    if key in _kernels:
        return _kernels[key]
    K, S, UN, W, G = columns, segments, unroll, width, group
    wide = wide_type(W, dtype)
    sums = wp.types.matrix(shape=(G * W, K), dtype=dtype)
    rows = wp.types.vector(length=G, dtype=wp.int32)

    @wp.kernel(module="unique")
    def blocks_rotate_in(r: wp.array2d(dtype=wp.vec3d), q_rot: wp.array(dtype=wp.mat33d),
                         mask: wp.array(dtype=wp.vec3d), node_row: wp.array(dtype=wp.int32),
                         U: wp.array2d(dtype=dtype)):
        c, i = wp.tid()
        v = wp.cw_mul(mask[i], wp.transpose(q_rot[i]) * r[c, i])
        row = node_row[i]
        U[row, c] = dtype(v[0])
        U[row + 1, c] = dtype(v[1])
        U[row + 2, c] = dtype(v[2])

    @wp.kernel(module="unique")
    def blocks_partial_product(A: wp.array2d(dtype=wide), U: wp.array2d(dtype=dtype),
                               row_chunk: wp.array(dtype=wp.int32), chunk_first: wp.array(dtype=wp.int32),
                               chunk_worlds: wp.array2d(dtype=wp.int32), first_row: wp.array(dtype=wp.int32),
                               block_row: wp.array(dtype=wp.int32), size: wp.array(dtype=wp.int32),
                               scale: wp.array(dtype=dtype), scal: wp.array3d(dtype=wp.float64),
                               P: wp.array3d(dtype=dtype)):
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
                f = scale[w]
                for c in range(K):
                    for v in range(W):
                        P[s, c, u0[g] + W * i + v] = f * acc[g * W + v, c]

    @wp.kernel(module="unique")
    def blocks_rotate_out(P: wp.array3d(dtype=dtype), q_rot: wp.array(dtype=wp.mat33d),
                          mask: wp.array(dtype=wp.vec3d), node_row: wp.array(dtype=wp.int32),
                          z: wp.array2d(dtype=wp.vec3d)):
        c, i = wp.tid()
        row = node_row[i]
        y = wp.vec3d()
        for s in range(S):
            y += wp.vec3d(wp.float64(P[s, c, row]), wp.float64(P[s, c, row + 1]), wp.float64(P[s, c, row + 2]))
        z[c, i] = wp.cw_mul(mask[i], q_rot[i] * y)

    _kernels[key] = (blocks_rotate_in, blocks_partial_product, blocks_rotate_out)
    return _kernels[key]
