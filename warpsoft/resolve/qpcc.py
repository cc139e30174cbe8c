"""The inverse model with contacts: a QP with complementarity constraints, solved by pivoting.

With contact rows ``c`` (frictionless: a gap ``delta_c`` and a normal force ``lambda_c``) the
inverse model's QP (``inverse.py``) gains the contact forces as unknowns it does not choose:

    minimize    1/2 |S delta_e|^2 + eps/2 lambda_a^T W_aa lambda_a
    subject to  the actuator bounds (force, displacement, step), and for every contact
                lambda_c >= 0,  delta_c >= 0,  lambda_c delta_c = 0      (Signorini)

where every ``delta = delta_free + W_(., a) lambda_a + W_(., b) lambda_b + W_(., c) lambda_c``
(``b``: the attachments' rows, held at ``delta_b = 0`` by free forces ``lambda_b`` in every
contact set's QP). The last condition makes it a QPCC. Fixing which contacts touch (a contact
set: ``delta_c = 0, lambda_c >= 0`` for those, ``lambda_c = 0, delta_c >= 0`` for the others)
leaves a convex QP (piqp). The pivoting starts from the contacts of an LCP at the previous
actuation (the attachments held) and moves one contact at a time to the other side, the one
whose multiplier says the objective falls fastest if it does (a touching contact whose
``lambda_c >= 0`` binds lifts off; a free one whose ``delta_c >= 0`` binds comes into contact),
when that lowers the objective, until no pivot does: a local minimum of the QPCC, whose contact
set satisfies its QP's KKT conditions. A cap on the pivots ends it with a warning.
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
    lam_b: np.ndarray | None = None  # the attachments' forces (N), where solved
    rounds: int = 0  # with friction: the rounds between the inverse QP and the direct model's contacts


@dataclass
class SetSolution:
    """The QP of one contact set: ``x = (lambda_a, lambda_b, lambda_touching)``, the objective,
    the multipliers that ask for a pivot, per contact (0 where none; scaled to force units), and
    the attachments' forces ``lam_b`` (N)."""

    lam_a: np.ndarray
    lam_c: np.ndarray
    objective: float
    asks: np.ndarray
    lam_b: np.ndarray


class ContactQP:
    """The blocks of one world's inverse problem with contacts, and the QP of a contact set."""

    def __init__(self, W: np.ndarray, delta_free: np.ndarray, a: np.ndarray, c: np.ndarray, e: np.ndarray,
                 rows: RowInputs, weights: np.ndarray, epsilon: float = DEFAULT_EPSILON,
                 b: np.ndarray | None = None):
        """``W`` ``(rows, columns)`` and ``delta_free`` of the world's rows; ``a``, ``c``, ``e`` the
        row ids of its actuators, contacts and effector axes, ``b`` of its bilateral rows
        (attachments: ``delta_b = 0`` always, their forces free), ``W``'s columns ``a``, ``b``
        then ``c``."""
        b = np.zeros(0, dtype=int) if b is None else np.asarray(b)
        na, nb, nc = len(a), len(b), len(c)
        cols_a, cols_b, cols_c = np.arange(na), na + np.arange(nb), na + nb + np.arange(nc)
        self.na, self.nb, self.nc, self.rows = na, nb, nc, rows
        held = np.concatenate([cols_a, cols_b])  # the columns always in the QP: actuators, attachments
        self.W_aa, self.W_ac = W[np.ix_(a, cols_a)], W[np.ix_(a, cols_c)]
        self.W_ca, self.W_cc = W[np.ix_(c, cols_a)], W[np.ix_(c, cols_c)]
        self.W_ah, self.W_bh, self.W_bc = W[np.ix_(a, held)], W[np.ix_(b, held)], W[np.ix_(b, cols_c)]
        self.W_ch = W[np.ix_(c, held)]
        s = np.sqrt(weights)
        self.M = s[:, None] * W[np.ix_(e, np.concatenate([held, cols_c]))]  # S [W_ea W_eb W_ec]
        self.target = s * delta_free[e]
        self.d_a, self.d_b, self.d_c = delta_free[a], delta_free[b], delta_free[c]
        self.reg = least_energy(self.W_aa, self.M[:, :na].T @ self.M[:, :na], epsilon)  # (inverse.py's)
        self.diag_c = np.maximum(np.diag(self.W_cc), 1e-300)

    def objective(self, lam_a: np.ndarray, lam_c: np.ndarray, lam_b: np.ndarray | None = None) -> float:
        lam_b = np.zeros(self.nb) if lam_b is None else lam_b
        r = self.target + self.M @ np.concatenate([lam_a, lam_b, lam_c])
        return 0.5 * float(r @ r) + 0.5 * float(lam_a @ self.reg @ lam_a)

    def solve(self, touching: np.ndarray) -> SetSolution | None:
        """The QP of contact set ``touching`` (nc bool), or None when it has no feasible point."""
        from qpsolvers import Problem, solve_problem

        na, nh, rows = self.na, self.na + self.nb, self.rows
        t, f = np.flatnonzero(touching), np.flatnonzero(~touching)
        keep = np.concatenate([np.arange(nh), nh + t])  # unknowns: actuators, attachments, touching forces
        M = self.M[:, keep]
        P = M.T @ M
        P[:na, :na] += self.reg
        P[na:, na:] += 1e-12 * max(np.abs(P).max(), 1e-300) * np.eye(len(keep) - na)  # (set by A x = b)
        q = M.T @ self.target
        W_a = np.hstack([self.W_ah, self.W_ac[:, t]])  # delta_a = d_a + W_a x
        W_t = np.vstack([np.hstack([self.W_bh, self.W_bc[:, t]]),  # the attachments held, the touching closed
                         np.hstack([self.W_ch[t], self.W_cc[np.ix_(t, t)]])])
        W_f = np.hstack([self.W_ch[f], self.W_cc[np.ix_(f, t)]])
        G, h = [-W_f], [self.d_c[f]]  # the free contacts stay open: delta_f >= 0
        upper, lower = np.isfinite(rows.dmax), np.isfinite(rows.dmin)
        G += [W_a[upper], -W_a[lower]]
        h += [rows.dmax[upper] - self.d_a[upper], self.d_a[lower] - rows.dmin[lower]]
        G, h = np.vstack(G), np.concatenate(h)
        lb = np.concatenate([rows.lo, np.full(self.nb, -np.inf), np.zeros(len(t))])
        ub = np.concatenate([rows.hi, np.full(self.nb + len(t), np.inf)])
        closed = -np.concatenate([self.d_b, self.d_c[t]])
        norm = max(np.abs(P).max(), 1e-300)  # conditioning: the objective to order one
        problem = Problem(P / norm, q / norm, G if len(h) else None, h if len(h) else None,
                          W_t if len(closed) else None, closed if len(closed) else None, lb, ub)
        sol = solve_problem(problem, solver="piqp", eps_abs=1e-11, eps_rel=1e-11)
        if not sol.found or sol.x is None or not np.all(np.isfinite(sol.x)):
            return None
        lam_a, lam_b, lam_c = np.clip(sol.x[:na], rows.lo, rows.hi), sol.x[na:nh], np.zeros(self.nc)
        lam_c[t] = np.maximum(sol.x[nh:], 0.0)
        asks = np.zeros(self.nc)
        # a touching contact whose lambda >= 0 binds would lift off (box multiplier < 0 at the lower bound);
        # a free one whose gap >= 0 binds would touch (its row's multiplier > 0); both in N of force
        asks[t] = np.maximum(-sol.z_box[nh:], 0.0) * norm
        asks[f] = np.maximum(sol.z[: len(f)], 0.0) * norm * self.diag_c[f]
        return SetSolution(lam_a, lam_c, self.objective(lam_a, lam_c, lam_b), asks, lam_b)

    def contact_lcp(self, lam_a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The attachments' and contacts' forces at actuation ``lam_a``: the mixed LCP ``delta_b =
        0`` (``lambda_b`` free), ``0 <= lambda_c _|_ delta_c >= 0``, with ``delta = d + W_.a
        lambda_a + W_.b lambda_b + W_.c lambda_c``, as the QP ``min 1/2 x W x + q x`` over ``x =
        (lambda_b, lambda_c)``, ``lambda_c >= 0``; and the contacts' gaps there (m)."""
        from qpsolvers import solve_qp

        na = self.na
        W = np.block([[self.W_bh[:, na:], self.W_bc], [self.W_ch[:, na:], self.W_cc]])
        q = np.concatenate([self.d_b + self.W_bh[:, :na] @ lam_a, self.d_c + self.W_ca @ lam_a])
        W = 0.5 * (W + W.T)
        norm = max(np.abs(W).max(), 1e-300)
        lb = np.concatenate([np.full(self.nb, -np.inf), np.zeros(self.nc)])
        x = solve_qp(W / norm, q / norm, lb=lb, solver="piqp")
        x = np.zeros(self.nb + self.nc) if x is None else x
        forces = np.maximum(x[self.nb:], 0.0)
        return forces, q[self.nb:] + W[self.nb:, :self.nb] @ x[:self.nb] + self.W_cc @ forces


def solve_inverse_contacts(qp: ContactQP, previous: np.ndarray, max_pivots: int = MAX_PIVOTS,
                           tolerance: float = 1e-6) -> ContactInverseResult:
    """Pivot from the LCP's contact set at the ``previous`` actuation (na) to a local minimum:
    each pivot switches the contact whose multiplier asks most, if its set's QP is feasible and
    better (else the next one asking). ``tolerance``: the multiplier (relative to the largest
    force) below which a contact does not ask (above the interior-point QP's own accuracy)."""
    start = time.perf_counter()
    fallback = np.clip(previous, qp.rows.lo, qp.rows.hi)
    try:
        forces, gaps = qp.contact_lcp(fallback) if qp.nc else (np.zeros(0), np.zeros(0))
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
                                time.perf_counter() - start, warning, sol.lam_b)
