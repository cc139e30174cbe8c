"""The inverse model: actuation from desired effector positions, by quadratic programming.

Per step, with the actuator rows ``a`` and the effector rows ``e`` of the constraint space,

    minimize    1/2 |S (W_ea lambda + delta_e_free)|^2 + eps/2 lambda^T W_aa lambda
    subject to  dmin <= W_aa lambda + delta_a_free <= dmax      (displacement bounds, step limit)
                lo <= lambda <= hi                              (force bounds, tension >= 0)

``S`` holds the square roots of the effector weights. ``eps`` is relative: the term uses
``eps * |W_ea^T S^2 W_ea| / |W_aa|`` (spectral norms), so the default means the same thing for
any robot and any units. It makes redundant actuation unique (the least-energy solution) and
smooth in time; its cost in accuracy is proportional to it. Measured on the Diamond (a
14 mm round trip, quasi-static): eps 1e-3 left 88 um, 1e-4 8.9 um, 1e-5 0.9 um; the trunk's
actuation stayed as smooth down to 1e-6. Default 1e-4: about 0.06 % of the effector's motion.
Solved with piqp through qpsolvers (the reference; ``inverse_device.py`` solves the same QP on
the device); a failure or infeasible bounds give a warning and the previous actuation (clipped
to the force bounds), never NaN.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from .gauss_seidel import RowInputs

DEFAULT_EPSILON = 1e-4


@dataclass
class InverseResult:
    """``lam`` (na), ``status`` ("optimal", "infeasible" or "failed"), solve time (s), warning."""

    lam: np.ndarray
    status: str
    seconds: float
    warning: str | None = None


def inverse_hessian(W_aa: np.ndarray, W_ea: np.ndarray, weights: np.ndarray,
                    epsilon: float = DEFAULT_EPSILON) -> np.ndarray:
    """``P = W_ea^T S^2 W_ea + eps |W_ea^T S^2 W_ea| / |W_aa| W_aa`` (na, na): positive definite
    for ``eps > 0`` (``W_aa`` is), so the QP has one solution even with redundant actuators."""
    SW = np.sqrt(weights)[:, None] * W_ea
    task = SW.T @ SW
    return task + least_energy(W_aa, task, epsilon)


def least_energy(W_aa: np.ndarray, task: np.ndarray, epsilon: float = DEFAULT_EPSILON) -> np.ndarray:
    """The regularization ``eps |task| / |W_aa| W_aa`` (na, na) of the task's Hessian ``task``."""
    Wsym = 0.5 * (W_aa + W_aa.T)
    # spectral norms of symmetric matrices: their largest |eigenvalue| (eigvalsh: a third of an SVD's cost)
    task_norm, w_norm = (np.abs(np.linalg.eigvalsh(x)).max() for x in (task, Wsym))
    return epsilon * task_norm / max(w_norm, 1e-300) * Wsym


def solve_inverse(W_aa: np.ndarray, W_ea: np.ndarray, delta_a_free: np.ndarray, delta_e_free: np.ndarray,
                  rows: RowInputs, weights: np.ndarray, previous: np.ndarray,
                  epsilon: float = DEFAULT_EPSILON) -> InverseResult:
    """One inverse step. Shapes: ``W_aa`` (na, na), ``W_ea`` (ne, na), ``delta_*`` (na,), (ne,),
    ``weights`` (ne,) per effector row, ``previous`` (na,) the last actuation."""
    from qpsolvers import solve_qp

    start = time.perf_counter()
    fallback = np.clip(previous, rows.lo, rows.hi)
    bad = np.flatnonzero((rows.dmin > rows.dmax) | (rows.lo > rows.hi))
    if len(bad):
        return InverseResult(fallback, "infeasible", time.perf_counter() - start,
                             f"actuator row {bad[0]}: empty bounds (displacement [{rows.dmin[bad[0]]:.4g}, "
                             f"{rows.dmax[bad[0]]:.4g}], force [{rows.lo[bad[0]]:.4g}, {rows.hi[bad[0]]:.4g}])")
    Wsym = 0.5 * (W_aa + W_aa.T)
    P = inverse_hessian(W_aa, W_ea, weights, epsilon)
    SW = np.sqrt(weights)[:, None] * W_ea
    q = SW.T @ (np.sqrt(weights) * delta_e_free)
    G, h = [], []
    upper, lower = np.isfinite(rows.dmax), np.isfinite(rows.dmin)
    if np.any(upper):
        G.append(Wsym[upper])
        h.append(rows.dmax[upper] - delta_a_free[upper])
    if np.any(lower):
        G.append(-Wsym[lower])
        h.append(delta_a_free[lower] - rows.dmin[lower])
    G = np.vstack(G) if G else None
    h = np.concatenate(h) if h else None
    norm = max(np.abs(P).max(), 1e-300)  # conditioning: scale the objective to order one
    try:
        lam = solve_qp(P / norm, q / norm, G, h, lb=rows.lo, ub=rows.hi, solver="piqp")
    except Exception as exc:  # the solver must never stop a trajectory
        return InverseResult(fallback, "failed", time.perf_counter() - start, f"QP solver error: {exc}")
    seconds = time.perf_counter() - start
    if lam is None or not np.all(np.isfinite(lam)):
        return InverseResult(fallback, "infeasible", seconds, "QP found no solution: the actuator bounds "
                             "cannot all be met this step; the previous actuation is kept")
    return InverseResult(np.clip(lam, rows.lo, rows.hi), "optimal", seconds)
