"""Assembled sparse direct solve of ``A = mass_scale M + stiffness_scale K`` on the host.

The CPU path (Warp's CPU device runs one thread, so a factorization beats any iteration)
and the accuracy reference of the iterative solvers. Fixed DOFs are removed from the system.
"""

from __future__ import annotations

import numpy as np
import warp as wp

from .assembly import FACTORIZATIONS, Assembly, CholmodFactor, WorldsCholmod, solve_dofs
from .operator import SystemOperator
from .pcg import SolveResult


class SparseDirect:
    """Factorize at each linearization (the pattern analysed once), solve all columns at once.

    The factorization is made when a solve first needs it after :meth:`prepare`. A world whose
    :attr:`keep` is set (the step allows it, see ``factor_reuse`` in :mod:`warpsoft.step`) solves
    with the factorization it has, of an earlier linearization, and the one due is not made:
    its factor then stands for the tangent of a modified Newton iteration. With several worlds
    (one CHOLMOD factor each, :class:`WorldsCholmod`) each world is kept or factorized on its
    own, so a world steps in a batch as it does alone; a single factor of all worlds (SuperLU)
    is kept only when every world may keep it.

    Args:
        operator: the system; its rotations and scales are read when the factorization is made.
        factorization: "cholmod" (default) or "superlu" (v1's, for comparison).

    Attributes:
        keep: ``(worlds,)`` bool, the worlds whose next solves may use their current factorization
            though a newer linearization is due (set by the step; False: factorized at every
            linearization).
        factorizations: numeric factorizations made so far, a world's block counting one (one
            robot: its factorizations).
    """

    capturable = False

    def __init__(self, operator: SystemOperator, factorization: str = "cholmod"):
        if factorization not in FACTORIZATIONS:
            raise ValueError(f"SparseDirect: factorization must be one of {sorted(FACTORIZATIONS)}, "
                             f"got {factorization!r}")
        self.op = operator
        self.assembly = Assembly(operator)
        worlds = operator.model.num_worlds
        if factorization == "cholmod" and worlds > 1:
            self.factor = WorldsCholmod(self.assembly)  # each world's solves as it has them alone
        else:
            self.factor = FACTORIZATIONS[factorization](self.assembly)
        # W straight from the factor (no compliance columns solved): CHOLMOD on the CPU device
        self.factor_compliance = (isinstance(self.factor, (CholmodFactor, WorldsCholmod))
                                  and operator.model.device.is_cpu)
        self.keep = np.zeros(worlds, dtype=bool)
        self.factorizations = 0
        self._due = np.ones(worlds, dtype=bool)  # worlds linearized since their factorization (or never factorized)
        self._made = np.zeros(worlds, dtype=bool)  # worlds that have a factorization

    def prepare(self) -> None:
        """A new linearization: ``A`` at the operator's current rotations and scales is factorized
        when a solve next needs it, in the worlds that :attr:`keep` does not let use the one they have."""
        self._due[:] = True

    def _ready(self) -> None:
        """Assemble ``A`` and factorize the worlds whose linearization is due and may not be skipped."""
        due = self._due & ~(self.keep & self._made)
        if not due.any():
            return
        if isinstance(self.factor, WorldsCholmod):  # each world's values assembled as it is factorized
            self.factor.factorize(due)
        else:  # one factor of every world
            due[:] = True
            self.factor.factorize(self.assembly.values())
        self._made |= due
        self._due &= ~due
        self.factorizations += int(due.sum())

    def solve(self, b: wp.array, x: wp.array) -> SolveResult:
        """``x[c] = A^-1 b[c]`` for ``(k, n)`` vec3d arrays. Zero columns (contact slots that
        no contact took this step) are not solved: they stay 0."""
        self._ready()
        flat = b.numpy().reshape(b.shape[0], -1)  # on the CPU device, views: no copy
        used = np.flatnonzero(flat.any(axis=1))
        on_host = x.device.is_cpu
        out = x.numpy().reshape(flat.shape) if on_host else np.empty_like(flat)
        out.fill(0.0)
        if len(used):
            free = self.assembly.free
            out[np.ix_(used, free)] = self.factor.solve(np.ascontiguousarray(flat[np.ix_(used, free)].T)).T
        if not on_host:
            x.assign(out.reshape(x.shape[0], -1, 3))
        return SolveResult(0, 0.0, True)

    def solve_array(self, b: np.ndarray) -> np.ndarray:
        """Solve for right-hand sides ``(k, n, 3)`` (host arrays); fixed DOFs get 0."""
        self._ready()
        return solve_dofs(self.factor, b.reshape(b.shape[0], -1)).reshape(b.shape)

    def compliance(self, rows, scale: float, only: np.ndarray | None = None) -> None:
        """``W = scale H A^-1 H_f^T`` into ``rows.W`` (every row against its world's force rows in
        use) from the factor, without the columns ``X = A^-1 H_f^T``: ``Z = L^-1 P H^T`` over the
        rows that have soft entries, by one sparse forward solve, then ``W = Z^T Z_f``. Measured
        on the Grasper (108 force rows, 2-core VM): 2.7 ms, against 7.4 ms for solving the 108
        columns. With ``only`` (bool, ``(rows,)``), the rows outside it get no ``Z`` column: their
        row and column of ``W`` stay 0 (the contacts left out of the lazy set, see
        :mod:`warpsoft.resolve.contact_set`). CPU device only (the rows' arrays are read in place)."""
        self._ready()
        h_row, h_node, h_coef = rows.h_row.numpy(), rows.h_node.numpy(), rows.h_coef.numpy()
        dof = self.assembly.renum[3 * h_node[:, None] + np.arange(3)]  # (entries, 3)
        keep = (dof >= 0) & (h_coef != 0.0)
        if only is not None:
            keep &= only[h_row][:, None]
        row = np.broadcast_to(h_row[:, None], dof.shape)[keep]
        used, column = np.unique(row, return_inverse=True)  # the rows with soft entries, as Z's columns
        W = rows.W.numpy()
        W.fill(0.0)
        if not len(used):
            return
        starts, force_rows = rows.world_row_start, rows.world_force_rows.numpy()
        # Z^T Z by blocks of columns (a world's, or all of them), every pair of a block's columns
        for cols, zz in self.factor.gram_parts(dof[keep], column, h_coef[keep], len(used)):
            row = used[cols]
            world = np.searchsorted(starts, row, side="right") - 1
            local = row - starts[world]  # a row's place in its world: its column of W if a force row
            i, j = np.nonzero((world[:, None] == world[None, :]) & (local < force_rows[world])[None, :])
            W[row[i], local[j]] = scale * zz[i, j]
