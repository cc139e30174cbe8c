"""Projected Gauss-Seidel on the force rows of every world (actuators, then contacts): one
thread per world.

Row ``r`` of world ``w`` (``world_row_start[w] <= r < world_row_start[w] + world_force_rows[w]``)
has ``delta_r = delta_free_r + sum_j W[r, j] lambda_(start + j)``; displacement-driven rows
aim at ``clip(value, dmin, dmax)``, force-driven rows impose ``lambda = value`` unless that
leaves ``[dmin, dmax]``; ``lambda`` stays in ``[lo, hi]``. The bounds on ``delta`` are first
narrowed to ``delta_now +- max_step`` (the change allowed in one step). On actuator rows, the
same sweep order, update and stopping test as ``warpsoft.resolve.gauss_seidel.projected_gauss_seidel``
(numpy); a contact's two friction rows are one block (:func:`friction_pair`); a world's bilateral
rows (attachments, after its actuators) are one block solved exactly (:func:`bilateral_block`).
"""

import warp as wp

from .. import OPTIONS

wp.set_module_options(OPTIONS)

FORCE_MODE = wp.constant(0)  # inputs[FORCE_MODE, r]: 1 for a force-driven row, 0 for displacement
VALUE = wp.constant(1)  # imposed delta (m, m^3) or lambda (N, Pa)
LO = wp.constant(2)  # force bounds
HI = wp.constant(3)
DMIN = wp.constant(4)  # displacement bounds
DMAX = wp.constant(5)
MAX_STEP = wp.constant(6)  # bound on the change of delta in one step
NORMAL = wp.constant(7)  # a contact's tangent row: how many rows before it its normal row is (1 or 2), else 0
NUM_INPUTS = 8

ITERATIONS = wp.constant(0)  # result[w, ITERATIONS]: sweeps done
RESIDUAL = wp.constant(1)  # largest change of a row's delta in the last sweep
CONVERGED = wp.constant(2)  # 1.0 when it met the tolerance


@wp.func
def clamp(x: wp.float64, lo: wp.float64, hi: wp.float64) -> wp.float64:
    return wp.min(wp.max(x, lo), hi)


@wp.func
def bounds_this_step(inputs: wp.array2d(dtype=wp.float64), delta_now: wp.array(dtype=wp.float64), r: int):
    """``[dmin, dmax]`` narrowed to ``delta_now +- max_step``."""
    lo_step = delta_now[r] - inputs[MAX_STEP, r]
    hi_step = delta_now[r] + inputs[MAX_STEP, r]
    return clamp(inputs[DMIN, r], lo_step, hi_step), clamp(inputs[DMAX, r], lo_step, hi_step)


@wp.func
def row_delta(W: wp.array2d(dtype=wp.float64), delta_free: wp.array(dtype=wp.float64),
              lam: wp.array(dtype=wp.float64), s: int, i: int, na: int) -> wp.float64:
    """``delta`` of row ``s + i`` at the multipliers now: ``delta_free + sum_j W[i, j] lambda_j``."""
    d = delta_free[s + i]
    for j in range(na):
        d += W[s + i, j] * lam[s + j]
    return d


@wp.func
def friction_pair(W: wp.array2d(dtype=wp.float64), delta_free: wp.array(dtype=wp.float64),
                  lam: wp.array(dtype=wp.float64), s: int, i: int, na: int, mu: wp.float64) -> wp.float64:
    """Update the tangent rows ``i, i + 1`` of a contact whose normal row is ``i - 1`` together:
    the forces that stop the slip if they lie in Coulomb's disc ``|lambda_t| <= mu lambda_n``
    (sticking), else a projected step onto the disc, ``lambda_t - slip / L`` with ``L`` the
    largest eigenvalue of the pair's ``W`` block, whose fixed point opposes the slip exactly
    (sliding; maximal dissipation). Returns the largest change of a row's delta it made (m)."""
    r = s + i
    a = W[r, i]
    b = W[r, i + 1]
    c = W[r + 1, i + 1]
    cap = mu * wp.max(lam[r - 1], wp.float64(0.0))
    d1 = row_delta(W, delta_free, lam, s, i, na)
    d2 = row_delta(W, delta_free, lam, s, i + 1, na)
    old1 = lam[r]
    old2 = lam[r + 1]
    det = a * c - b * b
    new1 = wp.float64(0.0)
    new2 = wp.float64(0.0)
    if det > wp.float64(0.0):  # the forces that hold both slips at 0
        new1 = old1 - (c * d1 - b * d2) / det
        new2 = old2 - (a * d2 - b * d1) / det
    if det <= wp.float64(0.0) or new1 * new1 + new2 * new2 > cap * cap:  # slides: a projected step
        big = wp.float64(0.5) * (a + c) + wp.sqrt(wp.float64(0.25) * (a - c) * (a - c) + b * b)
        new1 = old1
        new2 = old2
        if big > wp.float64(0.0):
            new1 = old1 - d1 / big
            new2 = old2 - d2 / big
        norm = wp.sqrt(new1 * new1 + new2 * new2)
        if norm > cap:
            f = cap / norm
            new1 = new1 * f
            new2 = new2 * f
    lam[r] = new1
    lam[r + 1] = new2
    return wp.max(wp.abs(new1 - old1) * wp.max(a, wp.float64(0.0)), wp.abs(new2 - old2) * wp.max(c, wp.float64(0.0)))


@wp.func
def factor_block(W: wp.array2d(dtype=wp.float64), s: int, b0: int, nb: int, L: wp.array3d(dtype=wp.float64),
                 w: int):
    """``L[w] L[w]^T = W_bb``, the Cholesky factor of the world's bilateral block (rows and
    columns ``b0 .. b0 + nb`` of the world's force rows; symmetric positive definite: distinct
    nodes, each with its own compliance). A pivot that is not positive (a row that moves nothing)
    is floored at 1e-12 of its diagonal, which leaves that row's force near 0."""
    for i in range(nb):
        for j in range(i + 1):
            v = W[s + b0 + i, b0 + j]
            for k in range(j):
                v -= L[w, i, k] * L[w, j, k]
            if i == j:
                floor = wp.float64(1e-12) * wp.abs(W[s + b0 + i, b0 + i]) + wp.float64(1e-300)
                L[w, i, i] = wp.sqrt(wp.max(v, floor))
            else:
                L[w, i, j] = v / L[w, j, j]


@wp.func
def bilateral_block(W: wp.array2d(dtype=wp.float64), delta_free: wp.array(dtype=wp.float64),
                    lam: wp.array(dtype=wp.float64), s: int, b0: int, nb: int, na: int,
                    L: wp.array3d(dtype=wp.float64), y: wp.array2d(dtype=wp.float64), w: int) -> wp.float64:
    """Update the bilateral rows ``b0 .. b0 + nb`` together: the forces that bring all their
    ``delta`` to 0 given the other rows' (``W_bb dlambda = -delta``, by the factor ``L``). Held
    rows couple strongly through the body that holds them (a rigid body turning moves them all),
    which one row at a time resolves in thousands of sweeps. Returns the largest change of a
    row's delta it made."""
    for i in range(nb):  # forward: L z = -delta
        v = -row_delta(W, delta_free, lam, s, b0 + i, na)
        for k in range(i):
            v -= L[w, i, k] * y[w, k]
        y[w, i] = v / L[w, i, i]
    change = wp.float64(0.0)
    for ii in range(nb):  # backward: L^T dlambda = z
        i = nb - 1 - ii
        v = y[w, i]
        for k in range(i + 1, nb):
            v -= L[w, k, i] * y[w, k]
        y[w, i] = v / L[w, i, i]
    for i in range(nb):
        lam[s + b0 + i] += y[w, i]
        change = wp.max(change, wp.abs(y[w, i]) * W[s + b0 + i, b0 + i])
    return change


@wp.kernel
def projected_gauss_seidel(
    W: wp.array2d(dtype=wp.float64),
    delta_free: wp.array(dtype=wp.float64),
    delta_now: wp.array(dtype=wp.float64),
    inputs: wp.array2d(dtype=wp.float64),
    world_row_start: wp.array(dtype=wp.int32),
    world_force_rows: wp.array(dtype=wp.int32),
    direct: wp.array(dtype=wp.int32),
    friction: wp.array(dtype=wp.float64),
    world_actuators: wp.array(dtype=wp.int32),
    world_bilateral: wp.array(dtype=wp.int32),
    max_iterations: int,
    tolerance: wp.float64,
    lam: wp.array(dtype=wp.float64),
    result: wp.array2d(dtype=wp.float64),
    factor: wp.array3d(dtype=wp.float64),
    work: wp.array2d(dtype=wp.float64),
):
    """``lam`` (per row; holds the warm start) of the force rows in use of every world whose
    ``direct`` flag is 1 (actuators, then contacts: a contact's normal row is force-driven at 0
    within ``lambda >= 0`` and ``delta >= 0``, which is Signorini's condition; its two tangent
    rows, when it has friction ``mu = friction[row]``, are updated as one block by
    :func:`friction_pair`: no slip inside Coulomb's disc, sliding against the slip on its rim); its
    bilateral rows, as one block by :func:`bilateral_block` (``factor`` ``(worlds, b, b)`` and
    ``work`` ``(worlds, b)`` its scratch, ``b`` the most bilateral rows of a world)."""
    w = wp.tid()
    s = world_row_start[w]
    na = world_force_rows[w] * direct[w]
    b0 = world_actuators[w]
    nb = world_bilateral[w] * direct[w]
    if nb > 0:
        factor_block(W, s, b0, nb, factor, w)
    scale = wp.float64(1e-300)
    for i in range(na):
        r = s + i
        lam[r] = clamp(lam[r], inputs[LO, r], inputs[HI, r])
        scale = wp.max(scale, wp.abs(delta_free[r]))
        if inputs[FORCE_MODE, r] == wp.float64(0.0):  # a displacement-driven row's target (a force-driven
            dmin, dmax = bounds_this_step(inputs, delta_now, r)  # row's value is a force, not a delta)
            scale = wp.max(scale, wp.abs(clamp(inputs[VALUE, r], dmin, dmax)))
    change = wp.float64(0.0)
    sweeps = wp.int32(0)  # not int(0): ruff would fold it to a constant
    converged = wp.float64(0.0)
    for it in range(max_iterations):
        change = wp.float64(0.0)
        i = wp.int32(0)
        while i < na:
            r = s + i
            if i == b0 and nb > 0:  # the attachments' rows, as one block
                change = wp.max(change, bilateral_block(W, delta_free, lam, s, b0, nb, na, factor, work, w))
                i += nb
                continue
            if int(inputs[NORMAL, r]) == 1:  # a contact's two tangent rows, as one block
                change = wp.max(change, friction_pair(W, delta_free, lam, s, i, na, friction[r]))
                i += 2
                continue
            lo = inputs[LO, r]
            hi = inputs[HI, r]
            force = inputs[FORCE_MODE, r] != wp.float64(0.0)
            diag = W[r, i]
            new = wp.float64(0.0)
            if diag <= wp.float64(0.0):  # a row that moves nothing: its force is only bounded
                if force:
                    new = inputs[VALUE, r]
                new = clamp(new, lo, hi)
            else:
                dmin, dmax = bounds_this_step(inputs, delta_now, r)
                d = row_delta(W, delta_free, lam, s, i, na)
                if force:
                    new = inputs[VALUE, r]
                    d_new = d + diag * (new - lam[r])
                    if d_new > dmax:
                        new += (dmax - d_new) / diag
                    elif d_new < dmin:
                        new += (dmin - d_new) / diag
                else:
                    new = lam[r] + (clamp(inputs[VALUE, r], dmin, dmax) - d) / diag
                new = clamp(new, lo, hi)
            change = wp.max(change, wp.abs(new - lam[r]) * wp.max(diag, wp.float64(0.0)))
            lam[r] = new
            i += 1
        sweeps = it + 1
        if change <= tolerance * scale:
            converged = wp.float64(1.0)
            break
    result[w, ITERATIONS] = wp.float64(sweeps)
    result[w, RESIDUAL] = change
    result[w, CONVERGED] = converged
