"""The inverse model's QP on the device: one thread per world, for up to ``NMAX`` actuators.

Per world, with its actuator rows ``a`` and effector rows ``e`` (``warpsoft/resolve/inverse.py``
states the problem and its reference solver, piqp):

    minimize    1/2 lambda^T P lambda + q^T lambda
    subject to  lo <= lambda <= hi,  dmin - delta_a_free <= W_sym lambda <= dmax - delta_a_free

with ``P = W_ea^T S^2 W_ea + eps |.|/|W_sym| W_sym`` and ``q = W_ea^T S^2 delta_e_free``. Solved
exactly (to round-off) by the dual active-set method of Goldfarb and Idnani: start from the
unconstrained minimum, add the most violated constraint, step along the primal and dual
directions, drop a constraint whose multiplier reaches zero; the step directions are recomputed
from ``P^-1`` and the active normals each time (a few actuators: a few hundred flops). Every
constraint is one-sided ``n_i . x >= b_i``: constraint ``4 k + t`` is ``x_k >= lo_k`` (t = 0),
``-x_k >= -hi_k`` (1), ``W_sym,k x >= dmin_k - delta_k`` (2) or ``-W_sym,k x >= delta_k - dmax_k``
(3); an infinite bound is no constraint.
"""

import warp as wp

from .. import OPTIONS
from .gauss_seidel import HI, LO, bounds_this_step

wp.set_module_options(OPTIONS)

OPTIMAL = wp.constant(0)  # result[w, STATUS]
EMPTY_BOUNDS = wp.constant(1)  # some row has dmin > dmax or lo > hi (result[w, DETAIL]: its index)
INFEASIBLE = wp.constant(2)  # the constraints cannot all hold
ITERATION_CAP = wp.constant(3)
NOT_SOLVED = wp.constant(4)  # not an inverse world, or no actuators
BREAKDOWN = wp.constant(5)  # the solution is not finite (never labelled optimal)
STATUS = wp.constant(0)
ITERATIONS = wp.constant(1)
DETAIL = wp.constant(2)
NUM_RESULTS = 3


# a pivot of P below this, relative to its largest diagonal entry, says P is singular (flat directions)
SINGULAR = wp.constant(wp.float64(1e-6))
NMAX = 16  # actuators per world the device QP takes (more: the host QP)
SIZES = (4, 8, 16)  # the QP's local matrices come in these sizes: the smallest that holds a model's actuators
_kernels = {}


def size_for(actuators: int) -> int:
    """The smallest local-matrix size that holds ``actuators`` (<= NMAX)."""
    return next(s for s in SIZES if s >= actuators)


def qp_kernels(size: int):
    """``(inverse_qp, dense_qp)`` with local matrices of ``size`` x ``size`` (one of ``SIZES``):
    a thread walks matrices as large as its problem needs, not NMAX's."""
    if size in _kernels:
        return _kernels[size]
    matn = wp.types.matrix(shape=(size, size), dtype=wp.float64)
    vecn = wp.types.vector(length=size, dtype=wp.float64)
    veci = wp.types.vector(length=size, dtype=wp.int32)
    NS = size

    @wp.func
    def cholesky(M: matn, n: int, floor: wp.float64) -> matn:
        """Lower ``L`` with ``M = L L^T`` (``M`` symmetric positive semidefinite, its first ``n``
        rows); a pivot below ``floor`` is raised to it: ``L L^T`` is then ``M`` plus a diagonal
        of at most ``floor`` where ``M`` is singular along a direction no earlier pivot spans."""
        L = matn()
        for j in range(n):
            s = M[j, j]
            for k in range(j):
                s -= L[j, k] * L[j, k]
            d = wp.sqrt(wp.max(s, floor))
            L[j, j] = d
            for i in range(j + 1, n):
                t = M[i, j]
                for k in range(j):
                    t -= L[i, k] * L[j, k]
                L[i, j] = t / d
        return L


    @wp.func
    def cholesky_solve(L: matn, b: vecn, n: int) -> vecn:
        """``x`` with ``L L^T x = b``."""
        y = vecn()
        for i in range(n):
            t = b[i]
            for k in range(i):
                t -= L[i, k] * y[k]
            y[i] = t / L[i, i]
        x = vecn()
        for ii in range(n):
            i = n - 1 - ii
            t = y[i]
            for k in range(i + 1, n):
                t -= L[k, i] * x[k]
            x[i] = t / L[i, i]
        return x


    @wp.func
    def spectral_norm(S: matn, n: int) -> wp.float64:
        """Largest ``|eigenvalue|`` of the symmetric ``S`` (cyclic Jacobi rotations)."""
        A = S
        for _sweep in range(30):
            off = wp.float64(0.0)
            total = wp.float64(0.0)
            for i in range(n):
                for j in range(n):
                    total += A[i, j] * A[i, j]
                    if i != j:
                        off += A[i, j] * A[i, j]
            if off <= wp.float64(1e-30) * total:
                break
            for p in range(n):
                for q in range(p + 1, n):
                    if A[p, q] != wp.float64(0.0):
                        theta = (A[q, q] - A[p, p]) / (wp.float64(2.0) * A[p, q])
                        t = wp.sign(theta) / (wp.abs(theta) + wp.sqrt(theta * theta + wp.float64(1.0)))
                        if theta == wp.float64(0.0):
                            t = wp.float64(1.0)
                        c = wp.float64(1.0) / wp.sqrt(t * t + wp.float64(1.0))
                        s = t * c
                        for k in range(n):  # A <- J^T A J, rows then columns p and q
                            akp = A[k, p]
                            akq = A[k, q]
                            A[k, p] = c * akp - s * akq
                            A[k, q] = s * akp + c * akq
                        for k in range(n):
                            apk = A[p, k]
                            aqk = A[q, k]
                            A[p, k] = c * apk - s * aqk
                            A[q, k] = s * apk + c * aqk
        largest = wp.float64(0.0)
        for i in range(n):
            largest = wp.max(largest, wp.abs(A[i, i]))
        return largest


    @wp.func
    def constraint_normal(i: int, G: matn, n: int) -> vecn:
        k = i // 4
        t = i % 4
        v = vecn()
        if t < 2:
            v[k] = wp.float64(1.0)
        else:
            for j in range(n):
                v[j] = G[k, j]
        if t % 2 == 1:
            v = -v
        return v


    @wp.func
    def constraint_bound(i: int, lo: vecn, hi: vecn, gl: vecn, gu: vecn) -> wp.float64:
        k = i // 4
        t = i % 4
        b = lo[k]
        if t == 1:
            b = -hi[k]
        elif t == 2:
            b = gl[k]
        elif t == 3:
            b = -gu[k]
        return b


    @wp.func
    def matvec(B: matn, v: vecn, n: int) -> vecn:
        out = vecn()
        for i in range(n):
            s = wp.float64(0.0)
            for j in range(n):
                s += B[i, j] * v[j]
            out[i] = s
        return out


    @wp.func
    def dot_n(a: vecn, b: vecn, n: int) -> wp.float64:
        s = wp.float64(0.0)
        for i in range(n):
            s += a[i] * b[i]
        return s


    @wp.func
    def dual_active_set(P: matn, q: vecn, G: matn, lo: vecn, hi: vecn, gl: vecn, gu: vecn, n: int, max_iterations: int):
        """Goldfarb-Idnani on ``min 1/2 x^T P x + q^T x`` under the one-sided constraints (see the
        module doc); returns ``(x, status, iterations)``."""
        # P is only semidefinite when actuators depend on each other (two identical cables) and
        # the least-energy term cannot tell them apart, or eps = 0 with fewer effector rows than
        # actuators: the objective is then flat along some actuations. A pivot at the floor says
        # so; P then gets the floor on its whole diagonal, which picks the optimum of least norm
        # among them (identical cables share the tension) for an objective SINGULAR higher
        largest = wp.float64(1e-300)
        for i in range(n):
            largest = wp.max(largest, P[i, i])
        floor = SINGULAR * largest
        Lp = cholesky(P, n, floor)
        flat = wp.int32(0)
        for i in range(n):
            if Lp[i, i] * Lp[i, i] <= floor:
                flat = wp.int32(1)
        if flat == 1:
            Pf = P
            for i in range(n):
                Pf[i, i] = Pf[i, i] + floor
            Lp = cholesky(Pf, n, floor)
        B = matn()  # P^-1
        for j in range(n):
            e = vecn()
            e[j] = wp.float64(1.0)
            col = cholesky_solve(Lp, e, n)
            for i in range(n):
                B[i, j] = col[i]
        x = -matvec(B, q, n)
        act = veci()
        u = vecn()
        na = wp.int32(0)  # wp.int32, not int(): dynamic variables (ruff would fold int(0) to 0)
        p = wp.int32(-1)
        up = wp.float64(0.0)
        status = wp.int32(ITERATION_CAP)
        its = wp.int32(0)
        for it in range(max_iterations):
            its = it + 1
            if p < 0:  # the most violated constraint (per unit normal: the units of x)
                xmax = wp.float64(0.0)
                for i in range(n):
                    xmax = wp.max(xmax, wp.abs(x[i]))
                worst = -wp.float64(1e-10) * (wp.float64(1.0) + xmax)
                for i in range(4 * n):
                    b = constraint_bound(i, lo, hi, gl, gu)
                    active = wp.int32(0)
                    for a in range(na):
                        if act[a] == i:
                            active = wp.int32(1)
                    if wp.isfinite(b) and active == 0:
                        ni = constraint_normal(i, G, n)
                        norm = wp.sqrt(dot_n(ni, ni, n))
                        if norm > wp.float64(0.0):
                            s = (dot_n(ni, x, n) - b) / norm
                            if s < worst:
                                worst = s
                                p = i
                if p < 0:
                    status = wp.int32(OPTIMAL)
                    break
                up = wp.float64(0.0)
            n_p = constraint_normal(p, G, n)
            Bn = matvec(B, n_p, n)
            z = Bn
            r = vecn()
            if na > 0:  # r = (N^T B N)^-1 N^T B n_p, z = B n_p - B N r
                BN = matn()
                M = matn()
                rhs = vecn()
                for a in range(na):
                    na_vec = constraint_normal(act[a], G, n)
                    col = matvec(B, na_vec, n)
                    for i in range(n):
                        BN[i, a] = col[i]
                    rhs[a] = dot_n(na_vec, Bn, n)
                for a in range(na):
                    na_vec = constraint_normal(act[a], G, n)
                    for c in range(na):
                        s = wp.float64(0.0)
                        for i in range(n):
                            s += na_vec[i] * BN[i, c]
                        M[a, c] = s
                r = cholesky_solve(cholesky(M, na, wp.float64(1e-300)), rhs, na)
                for i in range(n):
                    s = wp.float64(0.0)
                    for a in range(na):
                        s += BN[i, a] * r[a]
                    z[i] = Bn[i] - s
            zn = dot_n(z, n_p, n)
            t2 = wp.float64(wp.inf)
            if zn > wp.float64(1e-12) * dot_n(n_p, Bn, n):
                t2 = -(dot_n(n_p, x, n) - constraint_bound(p, lo, hi, gl, gu)) / zn
            t1 = wp.float64(wp.inf)
            k = wp.int32(-1)
            for a in range(na):
                if r[a] > wp.float64(1e-12):
                    ratio = u[a] / r[a]
                    if ratio < t1:
                        t1 = ratio
                        k = a
            if not wp.isfinite(t1) and not wp.isfinite(t2):
                status = wp.int32(INFEASIBLE)
                break
            t = wp.min(t1, t2)
            if wp.isfinite(t2):
                x = x + t * z
            for a in range(na):
                u[a] = u[a] - t * r[a]
            up += t
            if t2 <= t1:  # the constraint is met: it joins the active set
                act[na] = p
                u[na] = up
                na += 1
                p = -1
            else:  # a multiplier reached zero: that constraint leaves, p is tried again
                for a in range(k, na - 1):
                    act[a] = act[a + 1]
                    u[a] = u[a + 1]
                na -= 1
        return x, status, its


    @wp.func
    def clamp(v: wp.float64, lo: wp.float64, hi: wp.float64) -> wp.float64:
        return wp.min(wp.max(v, lo), hi)


    @wp.kernel(module="unique", module_options=OPTIONS)
    def inverse_qp(
        W: wp.array2d(dtype=wp.float64),
        delta_free: wp.array(dtype=wp.float64),
        delta_now: wp.array(dtype=wp.float64),
        inputs: wp.array2d(dtype=wp.float64),
        world_row_start: wp.array(dtype=wp.int32),
        world_actuators: wp.array(dtype=wp.int32),
        effector_start: wp.array(dtype=wp.int32),
        effector_count: wp.array(dtype=wp.int32),
        row_weight: wp.array(dtype=wp.float64),
        epsilon: wp.array(dtype=wp.float64),
        max_iterations: int,
        lam: wp.array(dtype=wp.float64),
        result: wp.array2d(dtype=wp.float64),
    ):
        """``lam`` of the actuator rows of every world with ``epsilon[w] >= 0`` (an inverse world;
        ``lam`` holds the previous actuation, kept, clipped to the force bounds, when the QP fails)."""
        w = wp.tid()
        s = world_row_start[w]
        n = world_actuators[w]
        result[w, STATUS] = wp.float64(NOT_SOLVED)
        result[w, ITERATIONS] = wp.float64(0.0)
        result[w, DETAIL] = wp.float64(-1.0)
        if epsilon[w] < wp.float64(0.0) or n == 0 or n > NS:
            return
        e0 = effector_start[w]
        ne = effector_count[w]
        Wsym = matn()
        task = matn()
        q = vecn()
        lo = vecn()
        hi = vecn()
        gl = vecn()
        gu = vecn()
        empty = wp.int32(-1)
        for i in range(n):
            r = s + i
            for j in range(n):
                Wsym[i, j] = wp.float64(0.5) * (W[r, j] + W[s + j, i])
                acc = wp.float64(0.0)
                for e in range(e0, e0 + ne):
                    acc += row_weight[e] * W[e, i] * W[e, j]
                task[i, j] = acc
            acc_q = wp.float64(0.0)
            for e in range(e0, e0 + ne):
                acc_q += row_weight[e] * W[e, i] * delta_free[e]
            q[i] = acc_q
            lo[i] = inputs[LO, r]
            hi[i] = inputs[HI, r]
            dmin, dmax = bounds_this_step(inputs, delta_now, r)
            gl[i] = dmin - delta_free[r]
            gu[i] = dmax - delta_free[r]
            if (dmin > dmax or lo[i] > hi[i]) and empty < 0:
                empty = i
        if empty >= 0:
            status = wp.int32(EMPTY_BOUNDS)
            result[w, DETAIL] = wp.float64(empty)
        else:
            scale = epsilon[w] * spectral_norm(task, n) / wp.max(spectral_norm(Wsym, n), wp.float64(1e-300))
            P = matn()
            norm = wp.float64(1e-300)
            for i in range(n):
                for j in range(n):
                    P[i, j] = task[i, j] + scale * Wsym[i, j]
                    norm = wp.max(norm, wp.abs(P[i, j]))
            x, status, its = dual_active_set(P / norm, q / norm, Wsym, lo, hi, gl, gu, n, max_iterations)
            for i in range(n):
                if not wp.isfinite(x[i]):
                    status = wp.int32(BREAKDOWN)
            result[w, ITERATIONS] = wp.float64(its)
            if status == OPTIMAL:
                for i in range(n):
                    lam[s + i] = clamp(x[i], lo[i], hi[i])
        result[w, STATUS] = wp.float64(status)
        if status != OPTIMAL:
            for i in range(n):
                lam[s + i] = clamp(lam[s + i], lo[i], hi[i])


    @wp.kernel(module="unique", module_options=OPTIONS)
    def dense_qp(P: wp.array3d(dtype=wp.float64), q: wp.array2d(dtype=wp.float64), G: wp.array3d(dtype=wp.float64),
                 bounds: wp.array3d(dtype=wp.float64), n: int, max_iterations: int, x_out: wp.array2d(dtype=wp.float64),
                 status_out: wp.array(dtype=wp.int32)):
        """One QP per thread in the form :func:`dual_active_set` solves, given explicitly (for tests):
        ``bounds[k]`` rows lo, hi, gl, gu."""
        k = wp.tid()
        Pm = matn()
        Gm = matn()
        qv = vecn()
        lo = vecn()
        hi = vecn()
        gl = vecn()
        gu = vecn()
        for i in range(n):
            for j in range(n):
                Pm[i, j] = P[k, i, j]
                Gm[i, j] = G[k, i, j]
            qv[i] = q[k, i]
            lo[i] = bounds[k, 0, i]
            hi[i] = bounds[k, 1, i]
            gl[i] = bounds[k, 2, i]
            gu[i] = bounds[k, 3, i]
        x, status, its = dual_active_set(Pm, qv, Gm, lo, hi, gl, gu, n, max_iterations)
        for i in range(n):
            x_out[k, i] = x[i]
        status_out[k] = status

    _kernels[size] = (inverse_qp, dense_qp)
    return _kernels[size]
