"""The inverse model with contacts: a QP with complementarity constraints, solved by pivoting.

With contact rows ``c`` (frictionless: a gap ``delta_c`` and a normal force ``lambda_c``) the
inverse model's QP (``inverse.py``) gains the contact forces as unknowns it does not choose:

    minimize    1/2 |S delta_e|^2 + eps/2 lambda_a^T W_aa lambda_a
    subject to  the actuator bounds (force, displacement, step), and for every contact
                lambda_c >= 0,  delta_c >= 0,  lambda_c delta_c = 0      (Signorini)

where every ``delta = delta_free + W_(., a) lambda_a + W_(., c) lambda_c``. The last condition
makes it a QPCC. Fixing which contacts touch (a contact set: ``delta_c = 0, lambda_c >= 0``
for those, ``lambda_c = 0, delta_c >= 0`` for the others) leaves a convex QP (piqp). The pivoting
starts from the contacts of an LCP at the previous actuation and moves one contact at a time
to the other side, the one whose multiplier says the objective falls fastest if it does (a
touching contact whose ``lambda_c >= 0`` binds lifts off; a free one whose ``delta_c >= 0``
binds comes into contact), when that lowers the objective, until no pivot does: a local
minimum of the QPCC, whose contact set satisfies its QP's KKT conditions. A cap on the pivots
ends it with a warning.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from .gauss_seidel import RowInputs
from .inverse import DEFAULT_EPSILON, least_energy

MAX_PIVOTS = 50


@dataclass
class ContactInverseResult:
    """``lam_a`` (na) and ``lam_c`` (nc) the multipliers, ``status`` ("optimal", "pivot cap",
    "infeasible" or "failed"), ``pivots`` made, ``touching`` (nc bool) the final contact set,
    ``objective``, solve time (s), warning."""

    lam_a: np.ndarray
    lam_c: np.ndarray
    status: str
    pivots: int
    touching: np.ndarray
    objective: float
    seconds: float
    warning: str | None = None


@dataclass
class SetSolution:
    """The QP of one contact set: ``x = (lambda_a, lambda_touching)``, the objective, and the
    multipliers that ask for a pivot, per contact (0 where none; scaled to force units)."""

    lam_a: np.ndarray
    lam_c: np.ndarray
    objective: float
    asks: np.ndarray


class ContactQP:
    """The blocks of one world's inverse problem with contacts, and the QP of a contact set."""

    def __init__(self, W: np.ndarray, delta_free: np.ndarray, a: np.ndarray, c: np.ndarray, e: np.ndarray,
                 rows: RowInputs, weights: np.ndarray, epsilon: float = DEFAULT_EPSILON):
        """``W`` ``(rows, columns)`` and ``delta_free`` of the world's rows; ``a``, ``c``, ``e`` the
        row ids of its actuators, contacts and effector axes (``W``'s columns: ``a`` then ``c``)."""
        na, nc = len(a), len(c)
        cols_a, cols_c = np.arange(na), na + np.arange(nc)
        self.na, self.nc, self.rows = na, nc, rows
        self.W_aa, self.W_ac = W[np.ix_(a, cols_a)], W[np.ix_(a, cols_c)]
        self.W_ca, self.W_cc = W[np.ix_(c, cols_a)], W[np.ix_(c, cols_c)]
        s = np.sqrt(weights)
        self.M = s[:, None] * np.hstack([W[np.ix_(e, cols_a)], W[np.ix_(e, cols_c)]])  # S [W_ea W_ec]
        self.target = s * delta_free[e]
        self.d_a, self.d_c = delta_free[a], delta_free[c]
        self.reg = least_energy(self.W_aa, self.M[:, :na].T @ self.M[:, :na], epsilon)  # (inverse.py's)
        self.diag_c = np.maximum(np.diag(self.W_cc), 1e-300)

    def objective(self, lam_a: np.ndarray, lam_c: np.ndarray) -> float:
        r = self.target + self.M @ np.concatenate([lam_a, lam_c])
        return 0.5 * float(r @ r) + 0.5 * float(lam_a @ self.reg @ lam_a)

    def solve(self, touching: np.ndarray) -> SetSolution | None:
        """The QP of contact set ``touching`` (nc bool), or None when it has no feasible point."""
        from qpsolvers import Problem, solve_problem

        na, rows = self.na, self.rows
        t, f = np.flatnonzero(touching), np.flatnonzero(~touching)
        keep = np.concatenate([np.arange(na), na + t])  # unknowns: the actuators and the touching forces
        M = self.M[:, keep]
        P = M.T @ M
        P[:na, :na] += self.reg
        P[na:, na:] += 1e-12 * max(np.abs(P).max(), 1e-300) * np.eye(len(t))  # (their values are set by A x = b)
        q = M.T @ self.target
        W_a = np.hstack([self.W_aa, self.W_ac[:, t]])  # delta_a = d_a + W_a x
        W_t = np.hstack([self.W_ca[t], self.W_cc[np.ix_(t, t)]])
        W_f = np.hstack([self.W_ca[f], self.W_cc[np.ix_(f, t)]])
        G, h = [-W_f], [self.d_c[f]]  # the free contacts stay open: delta_f >= 0
        upper, lower = np.isfinite(rows.dmax), np.isfinite(rows.dmin)
        G += [W_a[upper], -W_a[lower]]
        h += [rows.dmax[upper] - self.d_a[upper], self.d_a[lower] - rows.dmin[lower]]
        G, h = np.vstack(G), np.concatenate(h)
        lb = np.concatenate([rows.lo, np.zeros(len(t))])
        ub = np.concatenate([rows.hi, np.full(len(t), np.inf)])
        norm = max(np.abs(P).max(), 1e-300)  # conditioning: the objective to order one
        problem = Problem(P / norm, q / norm, G if len(h) else None, h if len(h) else None,
                          W_t if len(t) else None, -self.d_c[t] if len(t) else None, lb, ub)
        sol = solve_problem(problem, solver="piqp", eps_abs=1e-11, eps_rel=1e-11)
        if not sol.found or sol.x is None or not np.all(np.isfinite(sol.x)):
            return None
        lam_a, lam_c = np.clip(sol.x[:na], rows.lo, rows.hi), np.zeros(self.nc)
        lam_c[t] = np.maximum(sol.x[na:], 0.0)
        asks = np.zeros(self.nc)
        # a touching contact whose lambda >= 0 binds would lift off (box multiplier < 0 at the lower bound);
        # a free one whose gap >= 0 binds would touch (its row's multiplier > 0); both in N of force
        asks[t] = np.maximum(-sol.z_box[na:], 0.0) * norm
        asks[f] = np.maximum(sol.z[: len(f)], 0.0) * norm * self.diag_c[f]
        return SetSolution(lam_a, lam_c, self.objective(lam_a, lam_c), asks)

    def contact_lcp(self, lam_a: np.ndarray) -> np.ndarray:
        """The contact forces at actuation ``lam_a``: the LCP ``0 <= lambda_c _|_ d_c + W_ca
        lambda_a + W_cc lambda_c >= 0``, as the QP ``min 1/2 x W_cc x + q x, x >= 0``."""
        from qpsolvers import solve_qp

        q = self.d_c + self.W_ca @ lam_a
        Wcc = 0.5 * (self.W_cc + self.W_cc.T)
        norm = max(np.abs(Wcc).max(), 1e-300)
        x = solve_qp(Wcc / norm, q / norm, lb=np.zeros(self.nc), solver="piqp")
        return np.zeros(self.nc) if x is None else np.maximum(x, 0.0)


def solve_inverse_contacts(qp: ContactQP, previous: np.ndarray, max_pivots: int = MAX_PIVOTS,
                           tolerance: float = 1e-6) -> ContactInverseResult:
    """Pivot from the LCP's contact set at the ``previous`` actuation (na) to a local minimum:
    each pivot switches the contact whose multiplier asks most, if its set's QP is feasible and
    better (else the next one asking). ``tolerance``: the multiplier (relative to the largest
    force) below which a contact does not ask (above the interior-point QP's own accuracy)."""
    start = time.perf_counter()
    fallback = np.clip(previous, qp.rows.lo, qp.rows.hi)
    try:
        forces = qp.contact_lcp(fallback)
        gaps = qp.d_c + qp.W_ca @ fallback + qp.W_cc @ forces
        touching = forces * qp.diag_c > gaps  # (the interior-point LCP leaves both slightly positive)
        sol = qp.solve(touching)
        if sol is None:  # the LCP's set admits no actuation within the bounds: start with every contact open
            touching = np.zeros(qp.nc, dtype=bool)
            sol = qp.solve(touching)
        if sol is None:
            return ContactInverseResult(fallback, forces, "infeasible", 0, touching, qp.objective(fallback, forces),
                                        time.perf_counter() - start, "QPCC: no actuation within the bounds keeps "
                                        "the contacts closed or open; the previous actuation is kept")
        pivots, status, warning = 0, "optimal", None
        while True:
            scale = max(np.abs(sol.lam_c).max(initial=0.0), np.abs(sol.lam_a).max(initial=0.0), 1e-300)
            moved = False
            for i in np.argsort(-sol.asks):
                if sol.asks[i] <= tolerance * scale:
                    break
                trial = touching.copy()
                trial[i] = not trial[i]
                new = qp.solve(trial)
                # only a strict decrease: a contact both touching and free (gap and force 0) whose
                # two multipliers ask is already at a local minimum (both sides would cost)
                if new is not None and new.objective < sol.objective * (1 - 1e-9):
                    touching, sol, moved = trial, new, True
                    pivots += 1
                    break
            if not moved:
                break
            if pivots >= max_pivots:
                status = "pivot cap"
                warning = f"QPCC: stopped after {pivots} pivots with a contact still asking to switch"
                break
    except Exception as exc:  # the solver must never stop a trajectory
        return ContactInverseResult(fallback, np.zeros(qp.nc), "failed", 0, np.zeros(qp.nc, bool), np.nan,
                                    time.perf_counter() - start, f"QPCC solver error: {exc}")
    return ContactInverseResult(sol.lam_a, sol.lam_c, status, pivots, touching, sol.objective,
                                time.perf_counter() - start, warning)
