"""Kernels of the warped preconditioner applied world by world: ``z = Q blockdiag(s_w A_b(w)^-1) Q^T r``.

The worlds of a model are independent bodies, so ``A`` is block diagonal and so is its inverse:
each world ``w`` keeps a dense inverse ``A_b^-1`` of its own free DOFs (``b = b(w)``; worlds
whose rest systems are equal up to a factor share one block, scaled by ``s_w``). The flat operand
``U`` ``(N, k)`` holds world ``w`` in rows ``first_row[w] .. first_row[w] + size[w]``, node ``i``'s
DOF ``a`` in row ``node_row[i] + a`` (each world's rows padded to the segment size; padding
rows stay 0). The blocks are the rows of one ``(sum of block sizes, largest / W)`` array of
``vector(W)``: block ``b`` starts at row ``block_row``.

The product streams each block down its columns, as the whole-model product does
(``warped.py``): the thread of (segment ``s``, wide row ``g``) sums ``A_b[j, i..i+W-1] U[j, :]``
over the ``size / S`` rows ``j`` of its segment, and its world's scale multiplies the sum. A
world whose columns have all converged (``scal[c, w, DONE]``) skips its product: its ``z`` is no
longer used (its step length is 0), so a converged world stops costing the dense product's
bandwidth.
"""

import warp as wp

from .cg import DONE
from .warped import wide_type

_kernels = {}


def block_kernels(columns: int, dtype, segments: int, unroll: int, width: int):
    """``(rotate_in, partial_product, rotate_out)`` for ``k = columns`` right-hand sides, inverse
    precision ``dtype``, ``S = segments`` segments of each world's rows, ``unroll`` loads in flight
    per thread and ``W = width`` numbers per load (compile-time constants, hence cached per key).

    - ``rotate_in(r, q_rot, mask, node_row, U)`` over ``(k, n)``: ``U[node_row[i] + a, c] = (mask_i Q_i^T r[c, i])_a``;
    - ``partial_product(A, U, row_world, first_row, block_row, size, scale, scal, P)`` over
      ``(S, N / W)``: ``P[s, c, rows] = scale[w] sum_j A[block_row[w] + j, cols] U[first_row[w] + j, c]``
      over the segment ``s`` of world ``w``'s ``size[w]`` rows;
    - ``rotate_out(P, q_rot, mask, node_row, z)`` over ``(k, n)``:
      ``z[c, i] = mask_i Q_i sum_s P[s, c, node_row[i] + a]``.
    """
    key = (columns, dtype, segments, unroll, width)
    if key in _kernels:
        return _kernels[key]
    K, S, UN, W = columns, segments, unroll, width
    wide = wide_type(W, dtype)
    sums = wp.types.matrix(shape=(W, K), dtype=dtype)

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
                               row_world: wp.array(dtype=wp.int32), first_row: wp.array(dtype=wp.int32),
                               block_row: wp.array(dtype=wp.int32), size: wp.array(dtype=wp.int32),
                               scale: wp.array(dtype=dtype), scal: wp.array3d(dtype=wp.float64),
                               P: wp.array3d(dtype=dtype)):
        s, g = wp.tid()
        w = row_world[g]
        running = wp.int32(0)
        for c in range(K):
            if scal[c, w, DONE] == wp.float64(0.0):
                running = 1
        if running == 0:
            return  # every column of this world converged
        u0 = first_row[w]
        i = g - u0 // W  # this thread's W columns of the world's block
        segment = size[w] // S
        a0 = block_row[w]
        acc = sums()
        j = s * segment
        end = j + segment
        while j < end:
            for u in range(UN):  # unrolled: UN independent loads of A in flight per thread
                a = A[a0 + j + u, i]
                for c in range(K):
                    uc = U[u0 + j + u, c]
                    for v in range(W):
                        acc[v, c] = acc[v, c] + a[v] * uc
            j += UN
        f = scale[w]
        for c in range(K):
            for v in range(W):
                P[s, c, W * g + v] = f * acc[v, c]

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
