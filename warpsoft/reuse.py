"""When a world may solve a step with the direct solver's factorization of an earlier
linearization (``factor_reuse``, opt-in: off by default): a modified Newton step, judged world by
world. Its error is not bounded by the Newton tolerance, since the residual is measured with the
kept tangent: a body turning away from it loses angular momentum unseen.

A world keeps its factorization for a step when its step before converged in its first
iteration, without a line search, leaving a nonlinear residual at most ``factor_reuse`` (the
measure of :mod:`warpsoft.newton`: the tangent's error along the step, a stale factorization's
with the rest). The kept step must then end within ``factor_reuse`` too (Newton's ``limit``),
else it iterates on a fresh factorization: the try failed, and cost one iteration more than it
saved. After a failed try a world asks more of its last step: a residual under ``factor_reuse``
times its ``margin``, which each failure divides by :data:`MARGIN_CUT` (down to
:data:`MARGIN_FLOOR`) and each try that held doubles (up to 1). So a body turning faster than a
kept tangent follows (the Finger as its cable starts to pull: a try failed every other step, 1.23
Newton iterations a step against 1.00) soon stops trying, and one held still (the Grasper's cube
in its grip, whose steps leave residuals of 1e-4) keeps its factorization step after step, as an
implicit integrator reuses its Jacobian until its iteration fails to converge. Each world
decides on its own history, as it would alone.
"""

from __future__ import annotations

import numpy as np

MARGIN_CUT = 8.0  # a failed try divides the world's margin by this
MARGIN_FLOOR = 1.0 / 64  # the least margin


class FactorReuse:
    """Each world's keep decision and its record of failed tries.

    Args:
        threshold: ``factor_reuse``, the residual a world's last step must have left, and its kept step must leave.
        worlds: worlds of the model.

    Attributes:
        kept: ``(worlds,)`` bool, the worlds that started the current step on a kept factorization.
        margin: ``(worlds,)`` the share of ``threshold`` a world's last step must have left to try.
        tries, failures: kept steps so far, and those that had to iterate on a fresh factorization.
    """

    def __init__(self, threshold: float, worlds: int):
        self.threshold = float(threshold)
        self.kept = np.zeros(worlds, dtype=bool)
        self.margin = np.ones(worlds)
        self.tries = self.failures = 0

    def decide(self, newton, first_step: bool) -> np.ndarray:
        """The worlds that keep their factorization for the coming step (``(worlds,)`` bool), from
        ``newton``'s record of the last step; sets Newton's ``limit`` for them."""
        keep = np.zeros_like(self.kept)
        if self.threshold and not first_step:
            keep = (newton.iterations == 1) & ~newton.retried & (newton.error <= self.threshold * self.margin)
        self.kept = keep
        newton.limit[:] = np.where(keep, min(newton.tolerance, self.threshold), newton.tolerance)
        return keep

    def learn(self, newton) -> None:
        """After the step: a kept step that iterated (or shortened its step) failed: its world's
        margin shrinks; one that held widens it again."""
        if not self.kept.any():
            return
        failed = self.kept & ((newton.iterations > 1) | newton.retried)
        held = self.kept & ~failed
        self.margin[failed] = np.maximum(self.margin[failed] / MARGIN_CUT, MARGIN_FLOOR)
        self.margin[held] = np.minimum(2.0 * self.margin[held], 1.0)
        self.tries += int(self.kept.sum())
        self.failures += int(failed.sum())

    def forget(self) -> None:
        """The state was changed from outside: no world keeps in this step (its factorization
        knows nothing of the jump)."""
        self.kept[:] = False
