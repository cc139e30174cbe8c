"""Kernels of the warped-factorization preconditioner ``P^-1 = Q A_f^-1 Q^T``.

``A_f`` is the system matrix factorized once, at node rotations ``R_f`` (the rest state:
identity). As the body turns, each node's frame turns by ``Q_i = R_i R_f,i^T``, where
``R_i`` is the node's rotation: the polar rotation of the volume-weighted sum of the
rotations of its elements. Rotating the residual into the factorized frame, solving, and
rotating back follows the body's large rotations at the cost of a few vector kernels
(SOFA's WarpPreconditioner; Courtecuisse et al.).

Vectors are ``(k, n)`` arrays of vec3d (column, node); the dense path works on flat
``(N, k)`` float arrays with ``N >= 3 n`` padded to the tile size, DOF ``3 i + a`` in row
``3 i + a``.
"""

import warp as wp

from .. import OPTIONS
from ..elastic.geometry import polar_rotation
from ..worlds import still

wp.set_module_options(OPTIONS)


@wp.kernel
def accumulate_node_rotations(
    tets: wp.array(dtype=wp.vec4i),
    volume: wp.array(dtype=wp.float64),
    rot: wp.array(dtype=wp.mat33d),
    world: wp.array(dtype=wp.int32),
    moving: wp.array(dtype=wp.int32),
    node_sum: wp.array(dtype=wp.mat33d),
):
    """``node_sum[i] += V_e R_e`` over the elements ``e`` around node ``i`` (not for the worlds
    that stay: ``kernels/worlds.py``)."""
    e = wp.tid()
    if still(moving, world[e]):
        return
    t = tets[e]
    w = volume[e] * rot[e]
    for a in range(4):
        wp.atomic_add(node_sum, t[a], w)


@wp.kernel
def gather_node_rotations(
    node_first: wp.array(dtype=wp.int32),
    node_elems: wp.array(dtype=wp.int32),
    volume: wp.array(dtype=wp.float64),
    rot: wp.array(dtype=wp.mat33d),
    node_world: wp.array(dtype=wp.int32),
    moving: wp.array(dtype=wp.int32),
    node_sum: wp.array(dtype=wp.mat33d),
):
    """``node_sum[i] += V_e R_e`` over the elements ``e`` around node ``i``
    (``node_elems[node_first[i]:node_first[i + 1]]``): a thread per node, no atomics (for 1024
    Diamonds on the H200, 0.63 ms against 2.24 by atomic sums from the elements); not for the
    worlds that stay."""
    i = wp.tid()
    if still(moving, node_world[i]):
        return
    acc = wp.mat33d()
    for j in range(node_first[i], node_first[i + 1]):
        e = node_elems[j]
        acc += volume[e] * rot[e]
    node_sum[i] = node_sum[i] + acc


_relative = {}


def relative_node_rotations(kind=wp.mat33d):
    """``relative(node_sum, frame, node_world, moving, node_rot, q_rot)``, a thread per node: ``R_i =
    polar(node_sum[i])`` and ``Q_i = R_i R_f,i^T`` (``frame`` holds ``R_f``), ``q_rot`` of ``kind``
    (mat33d, or mat33f for a preconditioner that works in float32); the nodes of the worlds that stay
    keep theirs (``moving``: ``kernels/worlds.py``; None: every node). Cached per ``kind``."""
    if kind in _relative:
        return _relative[kind]

    @wp.kernel(module="unique", module_options=OPTIONS)
    def relative(node_sum: wp.array(dtype=wp.mat33d), frame: wp.array(dtype=wp.mat33d),
                 node_world: wp.array(dtype=wp.int32), moving: wp.array(dtype=wp.int32),
                 node_rot: wp.array(dtype=wp.mat33d), q_rot: wp.array(dtype=kind)):
        i = wp.tid()
        if still(moving, node_world[i]):
            return
        R = polar_rotation(node_sum[i])
        node_rot[i] = R
        q_rot[i] = kind(R * wp.transpose(frame[i]))

    _relative[kind] = relative
    return relative


@wp.kernel
def rotate_in(
    r: wp.array2d(dtype=wp.vec3d),
    q_rot: wp.array(dtype=wp.mat33d),
    mask: wp.array(dtype=wp.vec3d),
    u: wp.array2d(dtype=wp.vec3d),
):
    """``u[c, i] = mask_i * (Q_i^T r[c, i])``: the residual in the factorized frame."""
    c, i = wp.tid()
    u[c, i] = wp.cw_mul(mask[i], wp.transpose(q_rot[i]) * r[c, i])


@wp.kernel
def rotate_out(
    y: wp.array2d(dtype=wp.vec3d),
    q_rot: wp.array(dtype=wp.mat33d),
    mask: wp.array(dtype=wp.vec3d),
    z: wp.array2d(dtype=wp.vec3d),
):
    """``z[c, i] = mask_i * (Q_i y[c, i])``: back to the current frame."""
    c, i = wp.tid()
    z[c, i] = wp.cw_mul(mask[i], q_rot[i] * y[c, i])


_flat = {}


def flat_rotations(dtype):
    """Kernels ``(rotate_in_flat, rotate_out_flat)``: :func:`rotate_in` into, and
    :func:`rotate_out` from, the flat ``(N, k)`` operand of the dense product, whose
    precision ``dtype`` (wp.float32 or wp.float64) is that of the dense inverse."""
    if dtype in _flat:
        return _flat[dtype]

    @wp.kernel(module="unique", module_options=OPTIONS)
    def rotate_in_flat(r: wp.array2d(dtype=wp.vec3d), q_rot: wp.array(dtype=wp.mat33d),
                       mask: wp.array(dtype=wp.vec3d), u: wp.array2d(dtype=dtype)):
        c, i = wp.tid()
        v = wp.cw_mul(mask[i], wp.transpose(q_rot[i]) * r[c, i])
        for a in range(3):
            u[3 * i + a, c] = dtype(v[a])

    @wp.kernel(module="unique", module_options=OPTIONS)
    def rotate_out_flat(y: wp.array2d(dtype=dtype), q_rot: wp.array(dtype=wp.mat33d),
                        mask: wp.array(dtype=wp.vec3d), z: wp.array2d(dtype=wp.vec3d)):
        c, i = wp.tid()
        v = wp.vec3d(wp.float64(y[3 * i, c]), wp.float64(y[3 * i + 1, c]), wp.float64(y[3 * i + 2, c]))
        z[c, i] = wp.cw_mul(mask[i], q_rot[i] * v)

    _flat[dtype] = (rotate_in_flat, rotate_out_flat)
    return _flat[dtype]


_dense_products = {}


def dense_product(columns: int, dtype, tile_m: int = 32, tile_k: int = 64, splits: int = 1):
    """Kernel ``Y = A U`` for a dense square ``A`` ``(N, N)`` and ``U`` ``(N, columns)``,
    one thread block per ``tile_m`` rows and per ``1/splits`` of the inner dimension, ``N`` a
    multiple of ``tile_m`` and of ``splits * tile_k``. Launch with
    ``wp.launch_tiled(kernel, dim=[N // tile_m, splits], ...)``; with ``splits > 1`` the blocks add
    their partial products into ``Y``, which must be zero before (more blocks in flight: the
    product is bound by how fast ``A`` streams in). Tile shapes are compile-time constants, hence
    one kernel per (columns, dtype, tiles, splits), cached."""
    key = (columns, dtype, tile_m, tile_k, splits)
    if key in _dense_products:
        return _dense_products[key]
    TM, TK, TN, S = tile_m, tile_k, columns, splits

    @wp.kernel(module="unique", module_options=OPTIONS)
    def product(A: wp.array2d(dtype=dtype), U: wp.array2d(dtype=dtype), Y: wp.array2d(dtype=dtype)):
        i, s = wp.tid()
        acc = wp.tile_zeros(shape=(TM, TN), dtype=dtype)
        chunk = A.shape[1] // (TK * S)
        for kk in range(s * chunk, (s + 1) * chunk):
            a = wp.tile_load(A, shape=(TM, TK), offset=(i * TM, kk * TK))
            u = wp.tile_load(U, shape=(TK, TN), offset=(kk * TK, 0))
            wp.tile_matmul(a, u, acc)
        if wp.static(S == 1):
            wp.tile_store(Y, acc, offset=(i * TM, 0))
        else:
            wp.tile_atomic_add(Y, acc, offset=(i * TM, 0))

    _dense_products[key] = product
    return product


# ---- the streaming product: a symmetric A read down its columns, for a few right-hand sides ----
# Y = A U with A = A^T: the thread of (segment s, rows i..i+W-1) sums A[j, i..i+W-1] U[j, :] over
# the rows j of its segment. Neighbouring threads read neighbouring addresses of one row of A
# (coalesced, W numbers per load), U[j, :] (k numbers) is the same for the whole warp, and the
# segments put enough independent loads in flight to stream A at memory bandwidth. Partial sums
# go to P[s, :, i]; the rotation back adds them in a fixed order (the result does not depend on
# scheduling).

_streams = {}
_wide_types = {}


def wide_type(width: int, dtype):
    """``vector(width, dtype)``: the streamed product's load of ``width`` numbers of the inverse,
    one type for every ``k`` (the inverse's wide view is made once, for all of them)."""
    return _wide_types.setdefault((width, dtype), wp.types.vector(length=width, dtype=dtype))


def stream_kernels(columns: int, dtype, segments: int = 32, unroll: int = 4, width: int = 1):
    """``(wide, rotate_in, partial_product, rotate_out)``: ``vector(W, dtype)`` and the kernels of
    the streaming product for ``k = columns`` right-hand sides in precision ``dtype`` (``U`` is ``(N, k)``, ``P`` is
    ``(S, k, N)`` with ``S = segments``; row ``3 i + a`` holds DOF ``a`` of node ``i``).

    - ``rotate_in(r, q_rot, mask, U)``, over ``(k, n)``: ``U[3 i + a, c] = (mask_i Q_i^T r[c, i])_a``;
    - ``partial_product(A, U, segment, P)``, over ``(S, N / W)`` with ``W = width``:
      ``P[s, :, i] = sum_j A[j, i] U[j, :]`` over the ``segment`` rows ``j`` of segment ``s``
      (``segment`` a multiple of ``unroll``, ``S * segment = N``), ``A`` given as an ``(N, N / W)``
      array of ``vector(W, dtype)`` (the same memory: ``W`` neighbouring numbers per load);
    - ``rotate_out(P, q_rot, mask, z)``, over ``(k, n)``: ``z[c, i] = mask_i Q_i (sum_s P[s, c, 3 i + a])``.
    """
    key = (columns, dtype, segments, unroll, width)
    if key in _streams:
        return _streams[key]
    K, S, UN, W = columns, segments, unroll, width
    G = 16 if S % 16 == 0 else (8 if S % 8 == 0 else 1)  # partials added G at a time: their loads go out together
    wide = wide_type(W, dtype)
    sums = wp.types.matrix(shape=(W, K), dtype=dtype)

    @wp.kernel(module="unique", module_options=OPTIONS)
    def stream_rotate_in(r: wp.array2d(dtype=wp.vec3d), q_rot: wp.array(dtype=wp.mat33d),
                         mask: wp.array(dtype=wp.vec3d), U: wp.array2d(dtype=dtype)):
        c, i = wp.tid()
        v = wp.cw_mul(mask[i], wp.transpose(q_rot[i]) * r[c, i])
        U[3 * i, c] = dtype(v[0])
        U[3 * i + 1, c] = dtype(v[1])
        U[3 * i + 2, c] = dtype(v[2])

    @wp.kernel(module="unique", module_options=OPTIONS)
    def stream_partial_product(A: wp.array2d(dtype=wide), U: wp.array2d(dtype=dtype), segment: int,
                               P: wp.array3d(dtype=dtype)):
        s, i = wp.tid()
        acc = sums()
        j = s * segment
        end = j + segment
        while j < end:
            for u in range(UN):  # unrolled: UN independent loads of A in flight per thread
                a = A[j + u, i]
                for c in range(K):
                    uc = U[j + u, c]
                    for w in range(W):
                        acc[w, c] = acc[w, c] + a[w] * uc
            j += UN
        for c in range(K):
            for w in range(W):
                P[s, c, W * i + w] = acc[w, c]  # coalesced: neighbouring threads, neighbouring rows

    @wp.kernel(module="unique", module_options=OPTIONS)
    def stream_rotate_out(P: wp.array3d(dtype=dtype), q_rot: wp.array(dtype=wp.mat33d),
                          mask: wp.array(dtype=wp.vec3d), z: wp.array2d(dtype=wp.vec3d)):
        c, i = wp.tid()
        y = wp.vec3d()
        for g in range(S // G):
            for u in range(G):  # unrolled
                s = g * G + u
                y += wp.vec3d(wp.float64(P[s, c, 3 * i]), wp.float64(P[s, c, 3 * i + 1]),
                              wp.float64(P[s, c, 3 * i + 2]))
        z[c, i] = wp.cw_mul(mask[i], q_rot[i] * y)

    _streams[key] = (wide, stream_rotate_in, stream_partial_product, stream_rotate_out)
    return _streams[key]
