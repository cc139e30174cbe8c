"""Vector kernels of the batched block-Jacobi preconditioned conjugate gradient.

``k`` independent systems with the same matrix are solved at once: vectors are 2-D
arrays ``(k, n)`` of vec3d (column ``c``, node ``i``), launched over ``(k, n)``. The CG
scalars of each column live on the device in ``scal[c, slot]`` (float64) so that an
iteration needs no host round trip; the host only reads them to test convergence.
``mask`` holds 1 for a free DOF and 0 for a fixed one: every residual and product is
projected with it, so fixed DOFs of the unknowns stay at zero.
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
def mass_product(x: wp.array2d(dtype=wp.vec3d), mass: wp.array(dtype=wp.float64), scale: wp.float64,
                 y: wp.array2d(dtype=wp.vec3d)):
    """``y = scale * M x`` with a lumped mass (kg); starts a matrix-free product."""
    c, i = wp.tid()
    y[c, i] = (scale * mass[i]) * x[c, i]


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
def project(mask: wp.array(dtype=wp.vec3d), x: wp.array2d(dtype=wp.vec3d)):
    """Zero the fixed DOFs of every column."""
    c, i = wp.tid()
    x[c, i] = wp.cw_mul(mask[i], x[c, i])


@wp.kernel
def cg_start(
    b: wp.array2d(dtype=wp.vec3d),
    ax: wp.array2d(dtype=wp.vec3d),
    mask: wp.array(dtype=wp.vec3d),
    precond: wp.array(dtype=wp.mat33d),
    r: wp.array2d(dtype=wp.vec3d),
    z: wp.array2d(dtype=wp.vec3d),
    p: wp.array2d(dtype=wp.vec3d),
    scal: wp.array2d(dtype=wp.float64),
):
    """``r = P(b - A x0)``, ``z = M^-1 r``, ``p = z``; accumulates ``r.z``, ``r.r``, ``b.b``."""
    c, i = wp.tid()
    m = mask[i]
    bi = wp.cw_mul(m, b[c, i])
    ri = bi - wp.cw_mul(m, ax[c, i])
    zi = precond[i] * ri
    r[c, i] = ri
    z[c, i] = zi
    p[c, i] = zi
    wp.atomic_add(scal, c, RZ, wp.dot(ri, zi))
    wp.atomic_add(scal, c, R2_LAST, wp.dot(ri, ri))
    wp.atomic_add(scal, c, B2, wp.dot(bi, bi))


@wp.kernel
def cg_clear_zero_columns(scal: wp.array2d(dtype=wp.float64), x: wp.array2d(dtype=wp.vec3d),
                          p: wp.array2d(dtype=wp.vec3d)):
    """A column with ``b = 0`` has the solution 0, whatever its warm start."""
    c, i = wp.tid()
    if scal[c, B2] == wp.float64(0.0):
        x[c, i] = wp.vec3d()
        p[c, i] = wp.vec3d()


@wp.kernel
def cg_curvature(p: wp.array2d(dtype=wp.vec3d), ap: wp.array2d(dtype=wp.vec3d), mask: wp.array(dtype=wp.vec3d),
                 scal: wp.array2d(dtype=wp.float64)):
    """Project ``A p`` and accumulate ``p . A p``."""
    c, i = wp.tid()
    api = wp.cw_mul(mask[i], ap[c, i])
    ap[c, i] = api
    wp.atomic_add(scal, c, PAP, wp.dot(p[c, i], api))


@wp.kernel
def cg_update(
    x: wp.array2d(dtype=wp.vec3d),
    r: wp.array2d(dtype=wp.vec3d),
    z: wp.array2d(dtype=wp.vec3d),
    p: wp.array2d(dtype=wp.vec3d),
    ap: wp.array2d(dtype=wp.vec3d),
    precond: wp.array(dtype=wp.mat33d),
    scal: wp.array2d(dtype=wp.float64),
):
    """``x += alpha p``, ``r -= alpha A p``, ``z = M^-1 r``; accumulates ``r.z`` and ``r.r``."""
    c, i = wp.tid()
    alpha = wp.float64(0.0)
    if scal[c, PAP] > wp.float64(0.0):
        alpha = scal[c, RZ] / scal[c, PAP]
    x[c, i] = x[c, i] + alpha * p[c, i]
    ri = r[c, i] - alpha * ap[c, i]
    zi = precond[i] * ri
    r[c, i] = ri
    z[c, i] = zi
    wp.atomic_add(scal, c, RZ_NEW, wp.dot(ri, zi))
    wp.atomic_add(scal, c, R2, wp.dot(ri, ri))


@wp.kernel
def cg_scalars(scal: wp.array2d(dtype=wp.float64)):
    """One thread per column: ``beta = rz_new / rz``, roll the accumulators over."""
    c = wp.tid()
    beta = wp.float64(0.0)
    if scal[c, RZ] > wp.float64(0.0):
        beta = scal[c, RZ_NEW] / scal[c, RZ]
    scal[c, BETA] = beta
    scal[c, RZ] = scal[c, RZ_NEW]
    scal[c, R2_LAST] = scal[c, R2]
    scal[c, RZ_NEW] = wp.float64(0.0)
    scal[c, PAP] = wp.float64(0.0)
    scal[c, R2] = wp.float64(0.0)


@wp.kernel
def cg_direction(z: wp.array2d(dtype=wp.vec3d), p: wp.array2d(dtype=wp.vec3d), scal: wp.array2d(dtype=wp.float64)):
    """``p = z + beta p``."""
    c, i = wp.tid()
    p[c, i] = z[c, i] + scal[c, BETA] * p[c, i]


@wp.kernel
def step_health(x: wp.array(dtype=wp.vec3d), dx: wp.array(dtype=wp.vec3d), bad: wp.array(dtype=wp.int32),
                largest: wp.array(dtype=wp.float64)):
    """``bad[0]`` counts nodes of ``x`` that are NaN or infinite; ``largest[0]`` is the largest
    squared step ``|dx|^2`` (m^2) of a finite node."""
    i = wp.tid()
    if not wp.isfinite(x[i]):
        wp.atomic_add(bad, 0, 1)
    else:
        wp.atomic_max(largest, 0, wp.dot(dx[i], dx[i]))


# ---- preconditioned CG with any preconditioner and a device-side stopping test (solver "pcg") ----
# The preconditioner is applied by its own kernels between these; the loop runs under
# ``wp.capture_while`` on ``active``, which :func:`pcg_check` clears, so no host read is needed.

ITERATIONS = wp.constant(0)  # info[ITERATIONS]: iterations done by the current solve
NONFINITE = wp.constant(1)  # info[NONFINITE]: 1 when a column met NaN or inf


@wp.kernel
def pcg_residual(
    b: wp.array2d(dtype=wp.vec3d),
    ax: wp.array2d(dtype=wp.vec3d),
    mask: wp.array(dtype=wp.vec3d),
    r: wp.array2d(dtype=wp.vec3d),
    scal: wp.array2d(dtype=wp.float64),
):
    """``r = P(b - A x0)``; accumulates ``r.r`` and ``b.b`` (``scal`` zeroed before)."""
    c, i = wp.tid()
    m = mask[i]
    bi = wp.cw_mul(m, b[c, i])
    ri = bi - wp.cw_mul(m, ax[c, i])
    r[c, i] = ri
    wp.atomic_add(scal, c, R2_LAST, wp.dot(ri, ri))
    wp.atomic_add(scal, c, B2, wp.dot(bi, bi))


@wp.kernel
def pcg_begin(r: wp.array2d(dtype=wp.vec3d), z: wp.array2d(dtype=wp.vec3d), x: wp.array2d(dtype=wp.vec3d),
              p: wp.array2d(dtype=wp.vec3d), scal: wp.array2d(dtype=wp.float64)):
    """``p = z``; accumulates ``r.z``. A column with ``b = 0`` has the solution 0, whatever its
    warm start: its ``x``, ``r`` and ``p`` are cleared, so that it stays 0."""
    c, i = wp.tid()
    if scal[c, B2] == wp.float64(0.0):
        x[c, i] = wp.vec3d()
        r[c, i] = wp.vec3d()
        p[c, i] = wp.vec3d()
    else:
        p[c, i] = z[c, i]
        wp.atomic_add(scal, c, RZ, wp.dot(r[c, i], z[c, i]))


@wp.kernel
def pcg_update(x: wp.array2d(dtype=wp.vec3d), r: wp.array2d(dtype=wp.vec3d), p: wp.array2d(dtype=wp.vec3d),
               ap: wp.array2d(dtype=wp.vec3d), scal: wp.array2d(dtype=wp.float64)):
    """``x += alpha p``, ``r -= alpha A p`` with ``alpha = r.z / p.Ap``; accumulates ``r.r``."""
    c, i = wp.tid()
    alpha = wp.float64(0.0)
    if scal[c, PAP] > wp.float64(0.0):
        alpha = scal[c, RZ] / scal[c, PAP]
    x[c, i] = x[c, i] + alpha * p[c, i]
    ri = r[c, i] - alpha * ap[c, i]
    r[c, i] = ri
    wp.atomic_add(scal, c, R2, wp.dot(ri, ri))


@wp.kernel
def pcg_rz(r: wp.array2d(dtype=wp.vec3d), z: wp.array2d(dtype=wp.vec3d), scal: wp.array2d(dtype=wp.float64)):
    """Accumulates the new ``r.z``."""
    c, i = wp.tid()
    wp.atomic_add(scal, c, RZ_NEW, wp.dot(r[c, i], z[c, i]))


@wp.kernel
def pcg_check(scal: wp.array2d(dtype=wp.float64), tolerance: wp.float64, max_iterations: int, done: int,
              info: wp.array(dtype=wp.int32), active: wp.array(dtype=wp.int32)):
    """One thread: count ``done`` more iterations; keep ``active`` while some column has
    ``|r| > tolerance |b|``, every value is finite and the iteration cap is not reached."""
    info[ITERATIONS] = info[ITERATIONS] + done
    more = wp.int32(0)  # wp.int32, not int(): a dynamic variable (ruff would fold int(0) to 0)
    for c in range(scal.shape[0]):
        b2 = scal[c, B2]
        r2 = scal[c, R2_LAST]
        if not (wp.isfinite(b2) and wp.isfinite(r2) and wp.isfinite(scal[c, RZ])):
            info[NONFINITE] = 1
        elif b2 > wp.float64(0.0) and r2 > tolerance * tolerance * b2:
            more = wp.int32(1)
    if info[NONFINITE] != 0 or info[ITERATIONS] >= max_iterations:
        more = wp.int32(0)
    active[0] = more
