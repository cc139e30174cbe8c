"""Vector kernels of the batched preconditioned conjugate gradients (``pcg`` and ``jacobi``).

``k`` independent systems with the same matrix are solved at once: vectors are 2-D
arrays ``(k, n)`` of vec3d (column ``c``, node ``i``), launched over ``(k, n)``. Each world
is its own system (its nodes are ``world == w``): the CG scalars of column ``c`` in world
``w`` live on the device in ``scal[c, w, slot]`` (float64), so that an iteration needs no host
round trip and every world converges on its own residual, exactly as it would alone.
``mask`` holds 1 for a free DOF and 0 for a fixed one: every residual and product is
projected with it, so fixed DOFs of the unknowns stay at zero.
"""

import warp as wp

from .. import OPTIONS

wp.set_module_options(OPTIONS)

RZ = wp.constant(0)  # r . z of the current iterate
RZ_NEW = wp.constant(1)  # accumulator for the next r . z
PAP = wp.constant(2)  # accumulator for p . A p
R2 = wp.constant(3)  # accumulator for r . r
R2_LAST = wp.constant(4)  # r . r after the last completed iteration (read by the host)
BETA = wp.constant(5)
B2 = wp.constant(6)  # b . b (projected), the reference of the relative residual
DONE = wp.constant(7)  # 1 once this column of this world has converged (pcg): it no longer moves
ITS = wp.constant(8)  # iterations this column of this world needed (pcg)
NUM_SCALARS = 9


@wp.func
def column_done(done: wp.array3d(dtype=wp.float64), c: int, w: int) -> bool:
    """Whether column ``c`` of world ``w`` has converged, by the CG scalars ``done`` (``(k, worlds,
    NUM_SCALARS)``); never when ``done`` is None (a product that skips nothing)."""
    if done.shape[0] == 0:
        return False
    return done[c, w, DONE] != wp.float64(0.0)


@wp.kernel
def mass_product(x: wp.array2d(dtype=wp.vec3d), mass: wp.array(dtype=wp.float64), scale: wp.float64,
                 world: wp.array(dtype=wp.int32), done: wp.array3d(dtype=wp.float64),
                 y: wp.array2d(dtype=wp.vec3d)):
    """``y = scale * M x`` with a lumped mass (kg); starts a matrix-free product. A converged
    column of a world (:func:`column_done`) is left as it was."""
    c, i = wp.tid()
    if column_done(done, c, world[i]):
        return
    y[c, i] = (scale * mass[i]) * x[c, i]


@wp.kernel
def zero_columns(world: wp.array(dtype=wp.int32), done: wp.array3d(dtype=wp.float64), y: wp.array2d(dtype=wp.vec3d)):
    """``y = 0`` but in the converged columns of their worlds (:func:`column_done`)."""
    c, i = wp.tid()
    if not column_done(done, c, world[i]):
        y[c, i] = wp.vec3d()


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
    world: wp.array(dtype=wp.int32),
    scal: wp.array3d(dtype=wp.float64),
):
    """``r = P(b - A x0)``, ``z = M^-1 r``, ``p = z``; accumulates ``r.z``, ``r.r``, ``b.b``."""
    c, i = wp.tid()
    w = world[i]
    m = mask[i]
    bi = wp.cw_mul(m, b[c, i])
    ri = bi - wp.cw_mul(m, ax[c, i])
    zi = precond[i] * ri
    r[c, i] = ri
    z[c, i] = zi
    p[c, i] = zi
    wp.atomic_add(scal, c, w, RZ, wp.dot(ri, zi))
    wp.atomic_add(scal, c, w, R2_LAST, wp.dot(ri, ri))
    wp.atomic_add(scal, c, w, B2, wp.dot(bi, bi))


@wp.kernel
def cg_clear_zero_columns(world: wp.array(dtype=wp.int32), scal: wp.array3d(dtype=wp.float64),
                          x: wp.array2d(dtype=wp.vec3d), p: wp.array2d(dtype=wp.vec3d)):
    """A column with ``b = 0`` has the solution 0, whatever its warm start."""
    c, i = wp.tid()
    w = world[i]
    if scal[c, w, B2] == wp.float64(0.0):
        x[c, i] = wp.vec3d()
        p[c, i] = wp.vec3d()


@wp.kernel
def cg_curvature(p: wp.array2d(dtype=wp.vec3d), ap: wp.array2d(dtype=wp.vec3d), mask: wp.array(dtype=wp.vec3d),
                 world: wp.array(dtype=wp.int32), scal: wp.array3d(dtype=wp.float64)):
    """Project ``A p`` and accumulate ``p . A p``."""
    c, i = wp.tid()
    w = world[i]
    api = wp.cw_mul(mask[i], ap[c, i])
    ap[c, i] = api
    wp.atomic_add(scal, c, w, PAP, wp.dot(p[c, i], api))


@wp.kernel
def cg_update(
    x: wp.array2d(dtype=wp.vec3d),
    r: wp.array2d(dtype=wp.vec3d),
    z: wp.array2d(dtype=wp.vec3d),
    p: wp.array2d(dtype=wp.vec3d),
    ap: wp.array2d(dtype=wp.vec3d),
    precond: wp.array(dtype=wp.mat33d),
    world: wp.array(dtype=wp.int32),
    scal: wp.array3d(dtype=wp.float64),
):
    """``x += alpha p``, ``r -= alpha A p``, ``z = M^-1 r``; accumulates ``r.z`` and ``r.r``."""
    c, i = wp.tid()
    w = world[i]
    alpha = wp.float64(0.0)
    if scal[c, w, PAP] > wp.float64(0.0) and scal[c, w, DONE] == wp.float64(0.0):
        alpha = scal[c, w, RZ] / scal[c, w, PAP]
    x[c, i] = x[c, i] + alpha * p[c, i]
    ri = r[c, i] - alpha * ap[c, i]
    zi = precond[i] * ri
    r[c, i] = ri
    z[c, i] = zi
    wp.atomic_add(scal, c, w, RZ_NEW, wp.dot(ri, zi))
    wp.atomic_add(scal, c, w, R2, wp.dot(ri, ri))


@wp.kernel
def cg_scalars(scal: wp.array3d(dtype=wp.float64)):
    """One thread per column and world: ``beta = rz_new / rz``, roll the accumulators over."""
    c, w = wp.tid()
    beta = wp.float64(0.0)
    if scal[c, w, RZ] > wp.float64(0.0):
        beta = scal[c, w, RZ_NEW] / scal[c, w, RZ]
    scal[c, w, BETA] = beta
    scal[c, w, RZ] = scal[c, w, RZ_NEW]
    scal[c, w, R2_LAST] = scal[c, w, R2]
    scal[c, w, RZ_NEW] = wp.float64(0.0)
    scal[c, w, PAP] = wp.float64(0.0)
    scal[c, w, R2] = wp.float64(0.0)


@wp.kernel
def cg_direction(z: wp.array2d(dtype=wp.vec3d), p: wp.array2d(dtype=wp.vec3d), world: wp.array(dtype=wp.int32),
                 scal: wp.array3d(dtype=wp.float64)):
    """``p = z + beta p``."""
    c, i = wp.tid()
    w = world[i]
    p[c, i] = z[c, i] + scal[c, w, BETA] * p[c, i]


@wp.kernel
def step_health(x: wp.array(dtype=wp.vec3d), dx: wp.array(dtype=wp.vec3d), node_world: wp.array(dtype=wp.int32),
                bad: wp.array(dtype=wp.int32), largest: wp.array(dtype=wp.float64)):
    """Per world (``node_world``): ``bad[w]`` counts its nodes of ``x`` that are NaN or
    infinite; ``largest[w]`` is the largest squared step ``|dx|^2`` (m^2) of its finite nodes."""
    i = wp.tid()
    w = node_world[i]
    if not wp.isfinite(x[i]):
        wp.atomic_add(bad, w, 1)
    else:
        wp.atomic_max(largest, w, wp.dot(dx[i], dx[i]))
