"""The inverse model with contacts that have friction: the QPCC of ``qpcc.py``, each contact's
friction state taken from the direct model's own contact solution.

With friction the contact forces of an actuation are those of a nonlinear complementarity
problem (Signorini and Coulomb's cone, ``delta_n >= 0 _|_ lambda_n >= 0``, ``|lambda_t| <= mu
lambda_n``, a slip straight against the friction on the cone). Its states (open, sticking,
sliding along a direction) are not chosen by the inverse model: they follow from the
actuation. So each round

1. solves the direct model's contact problem at the actuation (``physics``: the same
   Gauss-Seidel as a direct-model world, the actuators held at their forces, the exact cone),
2. reads each contact's state from it: open (``lambda_n = 0``), sliding (its friction on the
   cone, within 1e-6) along its friction's direction ``d``, else sticking,
3. solves the inverse QP with those states: open ``delta_n >= 0``; touching ``delta_n = 0,
   lambda_n >= 0``, sticking ``delta_t = 0`` with the friction inside the polygon of
   :data:`FACETS` facets around the cone, sliding ``lambda_t = mu lambda_n d``; and pivots as
   ``qpcc.py`` does while the objective falls: a contact switches side (an opening one stops
   touching, a closing one starts sticking), or a sticking contact slides where the
   multiplier of its no-slip rows says the objective falls if it slips (against that slip),

until the actuation stops changing (relative 1e-6) or a cap on the rounds (then the best
actuation seen is kept, by the objective with the direct model's forces at it). The step keeps
that actuation and the direct model's contact forces at it: whatever the rounds end at, the
motion is the direct model's for that actuation, and a replay of the actuation in the direct
model moves the same.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from .gauss_seidel import RowInputs
from .inverse import DEFAULT_EPSILON, least_energy
from .qpcc import MAX_PIVOTS, ContactInverseResult

OPEN, STICK, SLIDE = 0, 1, 2  # a contact's state
# a sticking contact's friction stays inside this polygon, whose facets touch Coulomb's circle
# (a polygon around it: a sticking state the direct model found is never infeasible in the QP,
# and the forces kept are the direct model's, inside the circle)
FACETS = 16
ANGLES = 2.0 * np.pi * np.arange(FACETS) / FACETS
FACET_NORMAL = np.stack([np.cos(ANGLES), np.sin(ANGLES)], axis=1)  # (FACETS, 2), in the contact's (t1, t2)
MAX_ROUNDS = 12
ON_CONE = 1e-6  # a friction within this share of mu lambda_n of the cone slides


@dataclass
class StateSolution:
    """The QP of one state of the contacts: ``lam_a`` (na), ``lam_b`` (nb), ``lam_c`` (3 nc), the
    objective, per contact the multiplier asking it to switch side (``asks``, N) and, for a
    sticking one, that of its no-slip rows (``pull`` ``(nc, 2)``, N: the objective falls fastest
    if it slips that way)."""

    lam_a: np.ndarray
    lam_b: np.ndarray
    lam_c: np.ndarray
    objective: float
    asks: np.ndarray
    pull: np.ndarray


class FrictionQP:
    """The blocks of one world's inverse problem with frictional contacts (three rows each:
    normal, two tangents), and the QP of a state of them."""

    def __init__(self, W: np.ndarray, delta_free: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray,
                 e: np.ndarray, rows: RowInputs, weights: np.ndarray, mu: np.ndarray,
                 epsilon: float = DEFAULT_EPSILON):
        """``W`` ``(rows, columns)`` and ``delta_free`` of the world's rows; ``a``, ``b``, ``c``,
        ``e`` the row ids of its actuators, attachments, contacts (3 each) and effector axes
        (``W``'s columns: ``a``, ``b`` then ``c``); ``mu`` ``(nc,)`` the contacts' friction."""
        na, nb = len(a), len(b)
        self.na, self.nb, self.nc, self.rows, self.mu = na, nb, len(c) // 3, rows, np.asarray(mu, dtype=float)
        force = np.concatenate([a, b, c])
        cols = np.arange(len(force))
        self.W = W[np.ix_(force, cols)]  # the force rows' deltas: d + W x over (lambda_a, lambda_b, lambda_c)
        self.d = delta_free[force]
        s = np.sqrt(weights)
        self.M = s[:, None] * W[np.ix_(e, cols)]
        self.target = s * delta_free[e]
        W_aa = W[np.ix_(a, cols[:na])]
        self.reg = least_energy(W_aa, self.M[:, :na].T @ self.M[:, :na], epsilon)  # (inverse.py's)
        self.diag = np.maximum(np.diag(self.W), 1e-300)

    def objective(self, lam: np.ndarray) -> float:
        """The objective at all force rows' multipliers ``lam`` (a, b, c)."""
        r = self.target + self.M @ lam
        lam_a = lam[:self.na]
        return 0.5 * float(r @ r) + 0.5 * float(lam_a @ self.reg @ lam_a)

    def solve(self, state: np.ndarray, direction: np.ndarray) -> StateSolution | None:
        """The QP of the contacts' ``state`` (nc: ``OPEN``, ``STICK``, ``SLIDE``), sliding ones
        along ``direction`` ``(nc, 2)`` (unit, their friction's direction in their tangents),
        or None when it has no feasible point. A touching contact with ``mu = 0`` slips freely."""
        from qpsolvers import Problem, solve_problem

        na, nh, rows = self.na, self.na + self.nb, self.rows
        touch = np.flatnonzero(state != OPEN)
        keep = np.concatenate([np.arange(nh), nh + (3 * touch[:, None] + np.arange(3)).ravel()])
        first = {int(i): nh + 3 * k for k, i in enumerate(touch)}  # a touching contact's lambda_n unknown
        M = self.M[:, keep]
        P = M.T @ M
        P[:na, :na] += self.reg
        P[na:, na:] += 1e-12 * max(np.abs(P).max(), 1e-300) * np.eye(len(keep) - na)  # (set by A x = b)
        q = M.T @ self.target
        Wk, d = self.W[:, keep], self.d  # the delta of force row i is d[i] + Wk[i] x
        G, h, A, b, stuck = [], [], [], [], []  # stuck: (a sticking contact, its first no-slip row in A)
        for i in range(self.nb):  # the attachments held
            A.append(Wk[na + i])
            b.append(-d[na + i])
        opened = np.flatnonzero(state == OPEN)
        for i in opened:  # the gap stays open
            G.append(-Wk[nh + 3 * i])
            h.append(d[nh + 3 * i])
        for i in touch:
            n, j = nh + 3 * i, first[int(i)]
            A.append(Wk[n])  # the gap closed
            b.append(-d[n])
            if state[i] == STICK and self.mu[i] > 0.0:  # no slip, the friction inside the polygon
                stuck.append((int(i), len(A)))
                A += [Wk[n + 1], Wk[n + 2]]
                b += [-d[n + 1], -d[n + 2]]
                for k in range(FACETS):
                    row = np.zeros(len(keep))
                    row[j + 1:j + 3], row[j] = FACET_NORMAL[k], -self.mu[i]
                    G.append(row)
                    h.append(0.0)
            else:  # sliding (or frictionless): lambda_t = mu lambda_n d, the slip against it (d . slip <= 0)
                for m in range(2):
                    row = np.zeros(len(keep))
                    row[j + 1 + m], row[j] = 1.0, -self.mu[i] * direction[i, m]
                    A.append(row)
                    b.append(0.0)
                if self.mu[i] > 0.0:
                    G.append(direction[i] @ Wk[n + 1:n + 3])
                    h.append(-(direction[i] @ d[n + 1:n + 3]))
        upper, lower = np.isfinite(rows.dmax), np.isfinite(rows.dmin)
        W_a, d_a = Wk[:na], d[:na]
        G += list(W_a[upper]) + list(-W_a[lower])
        h += list(rows.dmax[upper] - d_a[upper]) + list(d_a[lower] - rows.dmin[lower])
        lb, ub = np.full(len(keep), -np.inf), np.full(len(keep), np.inf)
        lb[:na], ub[:na] = rows.lo, rows.hi
        lb[nh::3] = 0.0  # the normal forces push; attachments and friction either way
        norm = max(np.abs(P).max(), 1e-300)  # conditioning: the objective to order one
        G_, h_ = (np.array(G), np.array(h)) if G else (None, None)
        A_, b_ = (np.array(A), np.array(b)) if A else (None, None)
        sol = solve_problem(Problem(P / norm, q / norm, G_, h_, A_, b_, lb, ub), solver="piqp", eps_abs=1e-11,
                            eps_rel=1e-11)
        if not sol.found or sol.x is None or not np.all(np.isfinite(sol.x)):
            return None
        lam = np.zeros(len(self.d))
        lam[keep] = sol.x
        lam[:na] = np.clip(lam[:na], rows.lo, rows.hi)
        lam[nh::3] = np.maximum(lam[nh::3], 0.0)
        # in N of force: a touching contact whose lambda_n >= 0 binds would lift off (box multiplier
        # < 0 at the lower bound); an open one whose gap >= 0 binds would touch (its row's
        # multiplier > 0, times its compliance); a sticking one's no-slip multipliers likewise
        asks, pull = np.zeros(self.nc), np.zeros((self.nc, 2))
        if len(opened):
            asks[opened] = np.maximum(sol.z[:len(opened)], 0.0) * norm * self.diag[nh + 3 * opened]
        for i in touch:
            asks[i] = max(-sol.z_box[first[int(i)]], 0.0) * norm
        for i, row in stuck:
            pull[i] = sol.y[row:row + 2] * norm * self.diag[nh + 3 * i + 1]
        return StateSolution(lam[:na], lam[na:nh], lam[nh:], self.objective(lam), asks, pull)


def friction_states(lam_c: np.ndarray, mu: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each contact's state and friction direction ``(nc, 2)`` in a contact solution ``lam_c``
    (3 nc): open where ``lambda_n = 0``, sliding along its friction where that is on the cone
    (within :data:`ON_CONE`), else sticking."""
    lam = lam_c.reshape(-1, 3)
    size = np.linalg.norm(lam[:, 1:], axis=1)
    state = np.where(lam[:, 0] > 0.0, STICK, OPEN)
    sliding = (state == STICK) & (mu > 0.0) & (size >= (1.0 - ON_CONE) * mu * lam[:, 0])
    state[sliding] = SLIDE
    direction = np.zeros((len(lam), 2))
    direction[sliding] = lam[sliding, 1:] / size[sliding, None]
    return state, direction


def pivot(qp: FrictionQP, state: np.ndarray, direction: np.ndarray, sol: StateSolution, max_pivots: int,
          tolerance: float) -> tuple[np.ndarray, np.ndarray, StateSolution, int]:
    """``qpcc.py``'s pivoting on the contact sets, and a sticking contact that slides where its
    no-slip multipliers ask, each while the objective falls; the state, directions, solution
    and pivots at the end."""
    pivots = 0
    while pivots < max_pivots:
        scale = max(np.abs(sol.lam_c).max(initial=0.0), np.abs(sol.lam_a).max(initial=0.0), 1e-300)
        tries = [(sol.asks[i], i, OPEN if state[i] != OPEN else STICK, None) for i in range(qp.nc)]
        for i in np.flatnonzero((state == STICK) & (qp.mu > 0.0)):
            size = float(np.linalg.norm(sol.pull[i]))
            if size > 0.0:  # slipping along pull lowers the objective: the friction opposes that slip
                tries.append((size, i, SLIDE, -sol.pull[i] / size))
        moved = False
        for ask, i, to, d in sorted(tries, key=lambda t: -t[0]):
            if ask <= tolerance * scale:
                break
            trial, trial_direction = state.copy(), direction.copy()
            trial[i] = to
            if d is not None:
                trial_direction[i] = d
            new = qp.solve(trial, trial_direction)
            if new is not None and new.objective < sol.objective * (1 - 1e-9):  # only a strict decrease
                state, direction, sol, moved = trial, trial_direction, new, True
                pivots += 1
                break
        if not moved:
            break
    return state, direction, sol, pivots


def solve_inverse_friction(qp: FrictionQP, previous: np.ndarray,
                           physics: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]],
                           max_rounds: int = MAX_ROUNDS, max_pivots: int = MAX_PIVOTS,
                           tolerance: float = 1e-6) -> ContactInverseResult:
    """The rounds of the module's text from the ``previous`` actuation (na); ``physics(lam_a)``
    gives the direct model's attachment and contact forces ``(lam_b, lam_c)`` at an actuation.
    The result holds the actuation, the direct model's forces at it (``lam_b`` too), the pivots
    of all rounds, and ``rounds``; its status is "optimal" when the actuation settled (the last
    one is kept), else "pivot cap" or "infeasible" with a warning, and the best actuation seen
    (by the objective with the direct model's forces at it) is kept."""
    start = time.perf_counter()
    lam_a = np.clip(previous, qp.rows.lo, qp.rows.hi)
    pivots, status, warning = 0, "pivot cap", None
    try:
        lam_b, lam_c = physics(lam_a)
        best = (qp.objective(np.concatenate([lam_a, lam_b, lam_c])), lam_a, lam_b, lam_c)
        rounds = 0
        for rounds in range(1, max_rounds + 1):  # noqa: B007 (the count is reported)
            state, direction = friction_states(lam_c, qp.mu)
            sol = qp.solve(state, direction)
            if sol is None:
                status, warning = "infeasible", ("QPCC with friction: no actuation within the bounds keeps the "
                                                 "contacts as the direct model has them; the best actuation so far "
                                                 "is kept")
                break
            state, direction, sol, made = pivot(qp, state, direction, sol, max_pivots, tolerance)
            pivots += made
            change = np.abs(sol.lam_a - lam_a).max(initial=0.0)
            lam_a = sol.lam_a
            lam_b, lam_c = physics(lam_a)
            objective = qp.objective(np.concatenate([lam_a, lam_b, lam_c]))  # with the direct model's forces
            if objective <= best[0]:
                best = (objective, lam_a, lam_b, lam_c)
            if change <= 1e-6 * max(np.abs(lam_a).max(initial=0.0), 1e-300):
                status = "optimal"
                break
        if status == "pivot cap":
            warning = (f"QPCC with friction: the actuation still changed after {rounds} rounds with the direct "
                       "model's contact states; the best of them (by the objective with its contact forces) is kept")
        if status != "optimal":
            _, lam_a, lam_b, lam_c = best
    except Exception as exc:  # the solver must never stop a trajectory
        return ContactInverseResult(np.clip(previous, qp.rows.lo, qp.rows.hi), np.zeros(3 * qp.nc), "failed", 0,
                                    np.zeros(qp.nc, bool), np.nan, time.perf_counter() - start,
                                    f"QPCC solver error: {exc}")
    lam = np.concatenate([lam_a, lam_b, lam_c])
    return ContactInverseResult(lam_a, lam_c, status, pivots, lam_c[::3] > 0.0, qp.objective(lam),
                                time.perf_counter() - start, warning, lam_b, rounds)
