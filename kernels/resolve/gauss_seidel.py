"""Projected Gauss-Seidel on the actuator rows of every world: one thread per world.

Row ``r`` of world ``w`` (``world_row_start[w] <= r < world_row_start[w] + world_actuators[w]``)
has ``delta_r = delta_free_r + sum_j W[r, j] lambda_(start + j)``; displacement-driven rows
aim at ``clip(value, dmin, dmax)``, force-driven rows impose ``lambda = value`` unless that
leaves ``[dmin, dmax]``; ``lambda`` stays in ``[lo, hi]``. The bounds on ``delta`` are first
narrowed to ``delta_now +- max_step`` (the change allowed in one step). The same sweep order,
update and stopping test as ``warpsoft.resolve.gauss_seidel.projected_gauss_seidel`` (numpy).
"""

import warp as wp

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
    max_iterations: int,
    tolerance: wp.float64,
    lam: wp.array(dtype=wp.float64),
    result: wp.array2d(dtype=wp.float64),
):
    """``lam`` (per row; holds the warm start) of the force rows in use of every world whose
    ``direct`` flag is 1 (actuators, then contacts: a contact's normal row is force-driven at 0
    within ``lambda >= 0`` and ``delta >= 0``, which is Signorini's condition; its two tangent
    rows, when it has friction ``mu = friction[row]``, hold the slip at 0 within
    ``[-mu lambda_n, mu lambda_n]``, and the pair is then projected onto Coulomb's disc)."""
    w = wp.tid()
    s = world_row_start[w]
    na = world_force_rows[w] * direct[w]
    scale = wp.float64(1e-300)
    for i in range(na):
        r = s + i
        lam[r] = clamp(lam[r], inputs[LO, r], inputs[HI, r])
        dmin, dmax = bounds_this_step(inputs, delta_now, r)
        scale = wp.max(scale, wp.max(wp.abs(delta_free[r]), wp.abs(clamp(inputs[VALUE, r], dmin, dmax))))
    change = wp.float64(0.0)
    sweeps = wp.int32(0)  # not int(0): ruff would fold it to a constant
    converged = wp.float64(0.0)
    for it in range(max_iterations):
        change = wp.float64(0.0)
        for i in range(na):
            r = s + i
            lo = inputs[LO, r]
            hi = inputs[HI, r]
            mu = friction[r]
            normal = int(inputs[NORMAL, r])
            if normal > 0:  # a tangent row: Coulomb's bound from its contact's normal force now
                cap = mu * lam[r - normal]
                lo, hi = -cap, cap
            force = inputs[FORCE_MODE, r] != wp.float64(0.0)
            diag = W[r, i]
            new = wp.float64(0.0)
            if diag <= wp.float64(0.0):  # a row that moves nothing: its force is only bounded
                if force:
                    new = inputs[VALUE, r]
                new = clamp(new, lo, hi)
            else:
                dmin, dmax = bounds_this_step(inputs, delta_now, r)
                d = delta_free[r]
                for j in range(na):
                    d += W[r, j] * lam[s + j]
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
            if normal == 2:  # the contact's second tangent: the pair into the disc |lambda_t| <= mu lambda_n
                cap = mu * lam[r - 2]
                norm = wp.sqrt(lam[r - 1] * lam[r - 1] + new * new)
                if norm > cap:
                    f = cap / norm
                    change = wp.max(change, wp.abs(lam[r - 1]) * (wp.float64(1.0) - f) * wp.max(W[r - 1, i - 1],
                                                                                                wp.float64(0.0)))
                    lam[r - 1] = lam[r - 1] * f
                    lam[r] = new * f
        sweeps = it + 1
        if change <= tolerance * scale:
            converged = wp.float64(1.0)
            break
    result[w, ITERATIONS] = wp.float64(sweeps)
    result[w, RESIDUAL] = change
    result[w, CONVERGED] = converged
