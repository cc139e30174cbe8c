"""Vector kernels of the block-Jacobi preconditioned conjugate gradient.

The CG scalars live on the device in ``scal`` (float64) so that an iteration needs no
host round trip (a CUDA graph can replay it); the host only reads them to test
convergence. Slots: see ``RZ`` ... ``B2`` below. ``mask`` holds 1 for a free DOF and 0
for a fixed one: every residual and product is projected with it, so fixed DOFs of the
unknown stay at zero.
"""

import warp as wp

RZ = wp.constant(0)  # r . z of the current iterate
RZ_NEW = wp.constant(1)  # accumulator for the next r . z
PAP = wp.constant(2)  # accumulator for p . A p
R2 = wp.constant(3)  # accumulator for r . r
R2_LAST = wp.constant(4)  # r . r after the last completed iteration (read by the host)
BETA = wp.constant(5)
B2 = wp.constant(6)  # b . b (projected), the reference of the relative residual
NUM_SCALARS = 8


@wp.kernel
def mass_product(x: wp.array(dtype=wp.vec3d), mass: wp.array(dtype=wp.float64), scale: wp.float64,
                 y: wp.array(dtype=wp.vec3d)):
    """``y = scale * M x`` with a lumped mass (kg); starts a matrix-free product."""
    i = wp.tid()
    y[i] = (scale * mass[i]) * x[i]


@wp.kernel
def block_jacobi_inverse(
    kdiag: wp.array(dtype=wp.mat33d),
    mass: wp.array(dtype=wp.float64),
    mass_scale: wp.float64,
    stiffness_scale: wp.float64,
    mask: wp.array(dtype=wp.vec3d),
    inv: wp.array(dtype=wp.mat33d),
):
    """Inverse of each node's 3x3 diagonal block of ``A = mass_scale M + stiffness_scale K``,
    with fixed axes replaced by identity rows and columns."""
    i = wp.tid()
    D = stiffness_scale * kdiag[i] + (mass_scale * mass[i]) * wp.identity(n=3, dtype=wp.float64)
    m = mask[i]
    for a in range(3):
        for b in range(3):
            D[a, b] = D[a, b] * m[a] * m[b]
        if m[a] == wp.float64(0.0):
            D[a, a] = wp.float64(1.0)
    if wp.abs(wp.determinant(D)) > wp.float64(0.0):
        inv[i] = wp.inverse(D)
    else:
        inv[i] = wp.identity(n=3, dtype=wp.float64)


@wp.kernel
def cg_start(
    b: wp.array(dtype=wp.vec3d),
    ax: wp.array(dtype=wp.vec3d),
    mask: wp.array(dtype=wp.vec3d),
    precond: wp.array(dtype=wp.mat33d),
    r: wp.array(dtype=wp.vec3d),
    z: wp.array(dtype=wp.vec3d),
    p: wp.array(dtype=wp.vec3d),
    scal: wp.array(dtype=wp.float64),
):
    """``r = P(b - A x0)``, ``z = M^-1 r``, ``p = z``; accumulates ``r.z``, ``r.r``, ``b.b``."""
    i = wp.tid()
    m = mask[i]
    bi = wp.cw_mul(m, b[i])
    ri = bi - wp.cw_mul(m, ax[i])
    zi = precond[i] * ri
    r[i] = ri
    z[i] = zi
    p[i] = zi
    wp.atomic_add(scal, RZ, wp.dot(ri, zi))
    wp.atomic_add(scal, R2_LAST, wp.dot(ri, ri))
    wp.atomic_add(scal, B2, wp.dot(bi, bi))


@wp.kernel
def cg_curvature(p: wp.array(dtype=wp.vec3d), ap: wp.array(dtype=wp.vec3d), mask: wp.array(dtype=wp.vec3d),
                 scal: wp.array(dtype=wp.float64)):
    """Project ``A p`` and accumulate ``p . A p``."""
    i = wp.tid()
    api = wp.cw_mul(mask[i], ap[i])
    ap[i] = api
    wp.atomic_add(scal, PAP, wp.dot(p[i], api))


@wp.kernel
def cg_update(
    x: wp.array(dtype=wp.vec3d),
    r: wp.array(dtype=wp.vec3d),
    z: wp.array(dtype=wp.vec3d),
    p: wp.array(dtype=wp.vec3d),
    ap: wp.array(dtype=wp.vec3d),
    precond: wp.array(dtype=wp.mat33d),
    scal: wp.array(dtype=wp.float64),
):
    """``x += alpha p``, ``r -= alpha A p``, ``z = M^-1 r``; accumulates ``r.z`` and ``r.r``."""
    i = wp.tid()
    alpha = wp.float64(0.0)
    if scal[PAP] > wp.float64(0.0):
        alpha = scal[RZ] / scal[PAP]
    x[i] = x[i] + alpha * p[i]
    ri = r[i] - alpha * ap[i]
    zi = precond[i] * ri
    r[i] = ri
    z[i] = zi
    wp.atomic_add(scal, RZ_NEW, wp.dot(ri, zi))
    wp.atomic_add(scal, R2, wp.dot(ri, ri))


@wp.kernel
def cg_scalars(scal: wp.array(dtype=wp.float64)):
    """One thread: ``beta = rz_new / rz``, roll the accumulators over for the next iteration."""
    beta = wp.float64(0.0)
    if scal[RZ] > wp.float64(0.0):
        beta = scal[RZ_NEW] / scal[RZ]
    scal[BETA] = beta
    scal[RZ] = scal[RZ_NEW]
    scal[R2_LAST] = scal[R2]
    scal[RZ_NEW] = wp.float64(0.0)
    scal[PAP] = wp.float64(0.0)
    scal[R2] = wp.float64(0.0)


@wp.kernel
def cg_direction(z: wp.array(dtype=wp.vec3d), p: wp.array(dtype=wp.vec3d), scal: wp.array(dtype=wp.float64)):
    """``p = z + beta p``."""
    i = wp.tid()
    p[i] = z[i] + scal[BETA] * p[i]


@wp.kernel
def count_nonfinite(x: wp.array(dtype=wp.vec3d), flag: wp.array(dtype=wp.int32)):
    """``flag[0]`` counts entries of ``x`` that are NaN or infinite."""
    i = wp.tid()
    if not wp.isfinite(x[i]):
        wp.atomic_add(flag, 0, 1)
