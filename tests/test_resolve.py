"""The device Gauss-Seidel equals v1's NumPy one, for every row mode and bound, many worlds at once."""

import numpy as np
import pytest
import warp as wp
from warpsoft.kernels.resolve import gauss_seidel as k

from warpsoft.resolve import RowInputs, projected_gauss_seidel


def random_world(rng, na, case):
    B = rng.standard_normal((na, na))
    W = B @ B.T + 0.1 * np.eye(na)  # symmetric positive definite (m/N)
    if case == "dead row" and na > 1:
        W[0, :] = W[:, 0] = 0.0  # a row that moves nothing
    force = rng.random(na) < 0.5 if case != "all displacement" else np.zeros(na, bool)
    if case == "all force":
        force[:] = True
    value = np.where(force, rng.uniform(-1, 2, na), rng.uniform(-1, 1, na))
    lo = np.where(rng.random(na) < 0.5, 0.0, -np.inf) if case != "free" else np.full(na, -np.inf)
    hi = np.where(rng.random(na) < 0.3, rng.uniform(0.2, 1.0, na), np.inf) if case != "free" else np.full(na, np.inf)
    dmin = np.where(rng.random(na) < 0.4, rng.uniform(-1.0, -0.1, na), -np.inf)
    dmax = np.where(rng.random(na) < 0.4, rng.uniform(0.1, 1.0, na), np.inf)
    max_step = np.where(rng.random(na) < 0.3, rng.uniform(0.05, 0.5, na), np.inf) if case == "step" else \
        np.full(na, np.inf)
    return W, rng.standard_normal(na), force, value, lo, hi, dmin, dmax, max_step, 0.3 * rng.standard_normal(na)


CASES = ["mixed", "all displacement", "all force", "free", "step", "dead row"]


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_device_gauss_seidel_equals_numpy(seed):
    rng = np.random.default_rng(seed)
    worlds = [random_world(rng, int(rng.integers(1, 7)), case) for case in CASES for _ in range(3)]
    counts = [len(w[1]) for w in worlds]
    starts = np.concatenate([[0], np.cumsum(counts)]).astype(np.int32)
    rows, cols = int(starts[-1]), max(counts)
    W = np.zeros((rows, cols))
    inputs = np.zeros((k.NUM_INPUTS, rows))
    delta_free, delta_now, lam0 = np.zeros(rows), np.zeros(rows), np.zeros(rows)
    expected = []
    for w, (Ww, df, force, value, lo, hi, dmin, dmax, step, now) in enumerate(worlds):
        s, na = starts[w], counts[w]
        W[s:s + na, :na] = Ww
        inputs[:k.NORMAL, s:s + na] = [force, value, lo, hi, dmin, dmax, step]  # (no contact rows)
        delta_free[s:s + na], delta_now[s:s + na] = df, now
        lam0[s:s + na] = rng.uniform(-0.5, 1.0, na)
        narrowed = RowInputs(force, value, lo, hi, np.clip(dmin, now - step, now + step),
                             np.clip(dmax, now - step, now + step))
        expected.append(projected_gauss_seidel(Ww, df, narrowed, lam0[s:s + na], tolerance=1e-12))

    d = "cpu"
    lam = wp.array(lam0, dtype=wp.float64, device=d)
    result = wp.zeros((len(worlds), 3), dtype=wp.float64, device=d)
    wp.launch(k.projected_gauss_seidel, len(worlds),
              inputs=[wp.array(W, dtype=wp.float64, device=d), wp.array(delta_free, dtype=wp.float64, device=d),
                      wp.array(delta_now, dtype=wp.float64, device=d), wp.array(inputs, dtype=wp.float64, device=d),
                      wp.array(starts[:-1], dtype=wp.int32, device=d), wp.array(np.array(counts, np.int32),
                                                                                dtype=wp.int32, device=d),
                      wp.ones(len(worlds), dtype=wp.int32, device=d), wp.zeros(len(lam0), dtype=wp.float64, device=d),
                      wp.array(np.array(counts, np.int32), dtype=wp.int32, device=d),
                      wp.zeros(len(worlds), dtype=wp.int32, device=d), 1000, 1e-12],  # (no bilateral rows)
              outputs=[lam, result, wp.zeros((len(worlds), 1, 1), dtype=wp.float64, device=d),
                       wp.zeros((len(worlds), 1), dtype=wp.float64, device=d)], device=d)
    lam, result = lam.numpy(), result.numpy()
    for w, ref in enumerate(expected):
        s, na = starts[w], counts[w]
        assert np.abs(lam[s:s + na] - ref.lam).max() <= 1e-12 * max(1.0, np.abs(ref.lam).max())
        assert result[w, k.ITERATIONS] == ref.iterations
        assert result[w, k.CONVERGED] == float(ref.converged)
        assert result[w, k.RESIDUAL] == pytest.approx(ref.residual, rel=1e-9, abs=1e-14)  # summation order
    assert any(r.iterations > 2 for r in expected)  # the problems need real sweeps
    at_force_bound = [np.any(np.isclose(r.lam, worlds[w][4]) | np.isclose(r.lam, worlds[w][5]))
                      for w, r in enumerate(expected)]
    assert any(at_force_bound)  # the force bounds did bind somewhere


# ---- the inverse model's QP on the device (dual active set) against piqp, the reference ----
def dense_qps(P, q, G, bounds, n):
    """Solve each QP with the device kernel; returns x (k, n) and status (k,)."""
    from warpsoft.kernels.resolve import inverse_qp

    x = wp.zeros((len(P), n), dtype=wp.float64)
    status = wp.zeros(len(P), dtype=wp.int32)
    dense_qp = inverse_qp.qp_kernels(inverse_qp.size_for(n))[1]  # local matrices as large as n needs
    arrays = [wp.array(a, dtype=wp.float64) for a in (P, q, G, bounds)]
    wp.launch(dense_qp, len(P), inputs=[*arrays, n, 400], outputs=[x, status])
    return x.numpy(), status.numpy()


def reference_qp(P, q, G, b):
    from qpsolvers import solve_qp

    up, lw = np.isfinite(b[3]), np.isfinite(b[2])
    Gs, hs = np.vstack([G[up], -G[lw]]), np.concatenate([b[3][up], -b[2][lw]])
    return solve_qp(P, q, Gs if len(hs) else None, hs if len(hs) else None, lb=b[0], ub=b[1], solver="piqp",
                    eps_abs=1e-12, eps_rel=1e-12)


def as_feasible_and_low_as_piqp(P, q, G, b, x, violation: float, objective: float, relative: bool = False) -> list:
    """Each solution ``x[i]`` meets its bounds to ``violation`` (times ``1 + max |x|`` if
    ``relative``) and its objective is piqp's or lower, to ``objective`` of its size; returns
    piqp's solutions."""
    refs = []
    for i in range(len(P)):
        ref = reference_qp(P[i], q[i], G[i], b[i])
        Gx = G[i] @ x[i]
        worst = max(np.max(b[i, 0] - x[i]), np.max(x[i] - b[i, 1]), np.max(b[i, 2] - Gx), np.max(Gx - b[i, 3]))
        assert worst < violation * ((1.0 + np.abs(x[i]).max()) if relative else 1.0)
        f = lambda v, i=i: 0.5 * v @ P[i] @ v + q[i] @ v  # noqa: E731
        assert f(x[i]) <= f(ref) + objective * max(1.0, abs(f(ref)))
        refs.append(ref)
    return refs


@pytest.mark.parametrize("n", [1, 4, 8, 16])
def test_device_qp_is_the_exact_optimum_piqp_approaches(n):
    """Random strictly convex QPs with force bounds and two-sided bounds on ``W_sym lambda``, some
    of them duplicated (dependent constraints): the device solution is feasible to round-off and
    its objective is piqp's, or lower (piqp, an interior-point method, may end ~1e-8 outside a
    bound); at piqp's tolerance the two agree."""
    rng = np.random.default_rng(n)
    k = 24
    P, q, G, b = np.zeros((k, n, n)), np.zeros((k, n)), np.zeros((k, n, n)), np.zeros((k, 4, n))
    for i in range(k):
        M = rng.standard_normal((n, n))
        P[i] = M @ M.T + 0.05 * np.eye(n)
        q[i] = 3 * rng.standard_normal(n)
        Gm = rng.standard_normal((n, n))
        G[i] = Gm @ Gm.T / n + np.eye(n)
        if n > 1 and i % 3 == 0:
            G[i, 1] = G[i, 0]  # two actuators with the same row: dependent constraints
        b[i, 0] = np.where(rng.random(n) < 0.7, 0.0, -np.inf)
        b[i, 1] = np.where(rng.random(n) < 0.4, 1.0, np.inf)
        b[i, 2] = np.where(rng.random(n) < 0.5, -0.5, -np.inf)
        b[i, 3] = np.where(rng.random(n) < 0.5, 0.8, np.inf)
    x, status = dense_qps(P, q, G, b, n)
    assert np.all(status == 0)
    for i, ref in enumerate(as_feasible_and_low_as_piqp(P, q, G, b, x, 1e-10, 1e-7)):  # (piqp: ~1e-8 outside)
        assert np.abs(x[i] - ref).max() < 1e-5 * max(1.0, np.abs(ref).max())


@pytest.mark.parametrize("n", [2, 4, 8])
@pytest.mark.parametrize("eps", [0.0, 1e-4])
def test_device_qp_on_dependent_actuators_is_optimal_like_piqp(n, eps):
    """The inverse model's QPs when actuators 0 and 1 are identical cables (equal columns of
    ``W_aa`` and ``W_ea``): ``P = task + eps W_sym`` is singular along their difference, and with
    ``eps = 0`` along every actuation the fewer effector rows cannot see. The objective is flat
    there; the device QP picks an optimum of least norm and must be as feasible and as low as
    piqp's (a Cholesky without a pivot floor met a zero pivot: NaN, clipped to zero tensions,
    labelled optimal)."""
    rng = np.random.default_rng(10 * n + int(eps > 0))
    k = 30
    P, q, G, b = np.zeros((k, n, n)), np.zeros((k, n)), np.zeros((k, n, n)), np.zeros((k, 4, n))
    for i in range(k):
        ne = int(rng.integers(1, n + 1)) if eps == 0.0 else 3
        A = rng.standard_normal((n, n))
        A[:, 1] = A[:, 0]
        W = A.T @ A / n
        Wea = rng.standard_normal((ne, n))
        Wea[:, 1] = Wea[:, 0]
        task = Wea.T @ Wea
        Pm = task + eps * np.abs(np.linalg.eigvalsh(task)).max() / np.abs(np.linalg.eigvalsh(W)).max() * W
        scale = np.abs(Pm).max()
        P[i], q[i], G[i] = Pm / scale, Wea.T @ (3.0 * rng.standard_normal(ne)) / scale, W
        b[i, 0] = 0.0  # cables pull
        b[i, 1] = np.where(rng.random(n) < 0.3, 2.0, np.inf)
        b[i, 2] = np.where(rng.random(n) < 0.3, -0.5, -np.inf)
        b[i, 3] = np.where(rng.random(n) < 0.3, 0.8, np.inf)
    x, status = dense_qps(P, q, G, b, n)
    assert np.all(status == 0)
    as_feasible_and_low_as_piqp(P, q, G, b, x, 1e-6, 1e-6, relative=True)


def test_device_qp_reports_infeasible_constraints():
    """``lambda >= 1`` and ``lambda <= -1`` through ``W_sym = I``: no solution, said so."""
    n = 2
    P, q, G = np.eye(n)[None], np.zeros((1, n)), np.eye(n)[None]
    b = np.array([[[1.0, 0.0], [np.inf, np.inf], [-np.inf, -np.inf], [-1.0, np.inf]]])
    _, status = dense_qps(P, q, G, b, n)
    assert status[0] == 2  # INFEASIBLE


def test_the_stopping_test_measures_deltas_not_a_force_driven_rows_force():
    """A pressure row (force-driven at 60 kPa, and at least what keeps its volume change above
    -5e-6 m^3; W in m^3/Pa) coupled to a cable row aimed at 1 mm: the sweeps stop on the change
    of the deltas (m, m^3) relative to their scale, not to the pressure's 6e4 Pa. (With the
    pressure in the scale, the default tolerance stopped them with the volume 1.1e-9 m^3 off.)"""
    W = np.array([[2e-10, -3e-7], [-3e-7, 1e-3]])  # m^3/Pa, m/N; symmetric positive definite
    delta_free = np.array([-2e-5, 0.0])
    rows = RowInputs(force_mode=np.array([True, False]), value=np.array([6e4, 1e-3]),
                     lo=np.array([0.0, 0.0]), hi=np.full(2, np.inf), dmin=np.array([-5e-6, -np.inf]),
                     dmax=np.full(2, np.inf))
    res = projected_gauss_seidel(W, delta_free, rows)
    exact = np.linalg.solve(W, np.array([-5e-6, 1e-3]) - delta_free)  # the volume at its bound, the cable at 1 mm
    assert exact[0] > 6e4 and exact[1] > 0.0 and res.converged and res.iterations > 5
    delta = delta_free + W @ res.lam
    assert abs(delta[1] - 1e-3) < 1e-12 and abs(delta[0] + 5e-6) < 1e-14
