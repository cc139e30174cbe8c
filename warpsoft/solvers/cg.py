"""Block-Jacobi preconditioned conjugate gradient on ``A = mass_scale M + stiffness_scale K``.

Matrix-free: ``K`` is applied element by element from the rotations of the last
linearization. Fixed DOFs are projected out (the unknown stays 0 there).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import warp as wp

from warpsoft.kernels import fem, linalg

from ..model import Model


class SystemOperator:
    """``y = mass_scale M x + stiffness_scale K(rot) x`` for the model's elements.

    ``rot`` (m mat33d) holds the element rotations of the current linearization.
    """

    def __init__(self, model: Model, rot: wp.array):
        self.model, self.rot = model, rot
        self.mass_scale = 0.0
        self.stiffness_scale = 1.0

    def set_scales(self, mass_scale: float, stiffness_scale: float) -> None:
        if mass_scale != 0.0 and self.model.mass is None:
            raise ValueError("SystemOperator: mass_scale != 0 in a model without mass")
        self.mass_scale, self.stiffness_scale = float(mass_scale), float(stiffness_scale)

    def apply(self, x: wp.array, y: wp.array) -> None:
        m = self.model
        if self.mass_scale != 0.0:
            wp.launch(linalg.mass_product, m.num_nodes, inputs=[x, m.mass, self.mass_scale], outputs=[y],
                      device=m.device)
        else:
            y.zero_()
        wp.launch(fem.stiffness_product, m.num_elements,
                  inputs=[x, m.tets, m.dm_inv, m.volume, m.mu, m.lam, self.rot, self.stiffness_scale],
                  outputs=[y], device=m.device)


@dataclass
class CGResult:
    """Outcome of one solve: iterations, relative residual ``|r| / |b|``, convergence."""

    iterations: int
    residual: float
    converged: bool


class BlockJacobiCG:
    """PCG with a 3x3 block-Jacobi preconditioner rebuilt at each linearization.

    Args:
        operator: the system (its model gives sizes, device, mask, mass).
        tolerance: relative residual ``|r| / |b|`` to reach.
        max_iterations: cap; reaching it is reported, not hidden.
        check_every: read the residual back to the host every this many iterations.
    """

    def __init__(self, operator: SystemOperator, tolerance: float = 1e-6, max_iterations: int = 2000,
                 check_every: int = 1):
        self.op = operator
        self.tolerance, self.max_iterations, self.check_every = float(tolerance), int(max_iterations), int(check_every)
        m = operator.model
        n, d = m.num_nodes, m.device
        self.r, self.z, self.p, self.ap = (wp.zeros(n, dtype=wp.vec3d, device=d) for _ in range(4))
        self.kdiag = wp.zeros(n, dtype=wp.mat33d, device=d)
        self.precond = wp.zeros(n, dtype=wp.mat33d, device=d)
        self.scal = wp.zeros(linalg.NUM_SCALARS, dtype=wp.float64, device=d)
        self._zero_mass = None

    def update_preconditioner(self) -> None:
        """Rebuild the block diagonal of ``A`` from the operator's current rotations."""
        m, op = self.op.model, self.op
        self.kdiag.zero_()
        wp.launch(fem.stiffness_diagonal, m.num_elements,
                  inputs=[m.tets, m.dm_inv, m.volume, m.mu, m.lam, op.rot], outputs=[self.kdiag], device=m.device)
        mass = m.mass
        if mass is None:
            if self._zero_mass is None:
                self._zero_mass = wp.zeros(m.num_nodes, dtype=wp.float64, device=m.device)
            mass = self._zero_mass
        wp.launch(linalg.block_jacobi_inverse, m.num_nodes,
                  inputs=[self.kdiag, mass, op.mass_scale, op.stiffness_scale, m.mask], outputs=[self.precond],
                  device=m.device)

    def solve(self, b: wp.array, x: wp.array) -> CGResult:
        """Solve ``A x = b`` in place; ``x`` holds the warm start on entry (fixed DOFs are zeroed)."""
        m, n, d = self.op.model, self.op.model.num_nodes, self.op.model.device
        wp.launch(_project, n, inputs=[m.mask], outputs=[x], device=d)
        self.op.apply(x, self.ap)
        self.scal.zero_()
        wp.launch(linalg.cg_start, n, inputs=[b, self.ap, m.mask, self.precond],
                  outputs=[self.r, self.z, self.p, self.scal], device=d)
        s = self.scal.numpy()
        b_norm = math.sqrt(s[linalg.B2])
        if b_norm == 0.0:
            x.zero_()
            return CGResult(0, 0.0, True)
        rel = math.sqrt(s[linalg.R2_LAST]) / b_norm
        if rel <= self.tolerance:
            return CGResult(0, rel, True)
        it = 0
        while it < self.max_iterations:
            self.op.apply(self.p, self.ap)
            wp.launch(linalg.cg_curvature, n, inputs=[self.p, self.ap, m.mask], outputs=[self.scal], device=d)
            wp.launch(linalg.cg_update, n, inputs=[x, self.r, self.z, self.p, self.ap, self.precond],
                      outputs=[self.scal], device=d)
            wp.launch(linalg.cg_scalars, 1, inputs=[self.scal], device=d)
            it += 1
            if it % self.check_every == 0 or it == self.max_iterations:
                rel = math.sqrt(max(float(self.scal.numpy()[linalg.R2_LAST]), 0.0)) / b_norm
                if rel <= self.tolerance or not math.isfinite(rel):
                    break
            wp.launch(linalg.cg_direction, n, inputs=[self.z, self.p], outputs=[self.scal], device=d)
        return CGResult(it, rel, bool(rel <= self.tolerance))


@wp.kernel
def _project(mask: wp.array(dtype=wp.vec3d), x: wp.array(dtype=wp.vec3d)):
    i = wp.tid()
    x[i] = wp.cw_mul(mask[i], x[i])
