"""Stable Neo-Hookean linear tetrahedra: large deformation, robust to inversion.

The energy (``kernels/elastic/neohookean.py``) is Smith, de Goes and Kim's stable Neo-Hookean
one, written with the Lame parameters of linear elasticity: at small strain it is the same
material as the corotational element, and in a bar stretched uniaxially it follows
:func:`uniaxial_stress`. It has no ``log J``, so an inverted element has a finite energy and a
force that turns it back. The step's Newton iterations take its projected tangent (the
Hessian with its negative eigenvalues clamped to zero, per element, in the SVD frame of ``F``):
exact where the Hessian is positive, so Newton converges quadratically there, and positive
semi-definite everywhere, so the conjugate gradient and the Cholesky factorization apply.
"""

from __future__ import annotations

import math

import warp as wp

from warpsoft.kernels.elastic import neohookean as kernels
from warpsoft.kernels.linear import warped as warped_kernels

from ..launch import launch
from .corotational import ELEMENT_MAJOR_FROM


def uniaxial_stress(stretch: float, mu: float, lam: float) -> tuple[float, float]:
    """The nominal stress ``P_11`` (Pa, force over the rest area) and the lateral stretch of a
    bar of this material stretched by ``stretch`` along its axis, its sides free.

    With ``F = diag(s, t, t)``, ``J = s t^2``: the sides are free when
    ``P_22 = t (mu + c s) = 0``, i.e. ``c = -mu / s``, which gives
    ``s t^2 = 1 + mu (1 - 1/s) / (lam + mu)``; then ``P_11 = mu s + c t^2 = mu (s - t^2 / s)``.
    """
    s = float(stretch)
    if not s > 0.0:
        raise ValueError(f"uniaxial_stress: stretch must be > 0, got {stretch!r}")
    t2 = (1.0 + mu * (1.0 - 1.0 / s) / (lam + mu)) / s
    return mu * (s - t2 / s), math.sqrt(t2)


class NeoHookean:
    """The stable Neo-Hookean tetrahedra of a :class:`~warpsoft.model.Model`: its element group
    ``group`` (:class:`~warpsoft.model.ElementGroup`, 4 nodes an element).

    :meth:`linearize` writes each element's projected tangent (``tangent``, ``(count,)``
    :class:`~warpsoft.kernels.elastic.neohookean.Tangent`) and the rotation of its SVD into
    ``rot``; the other methods read the tangent of the last linearization.
    """

    name = "neohookean"
    nodes_per_element = 4

    def __init__(self, model, group):
        self.model, self.group = model, group
        self.tangent = wp.zeros(group.count, dtype=kernels.Tangent, device=model.device)

    def linearize(self, q: wp.array, rot: wp.array, force: wp.array) -> None:
        """Tangents and rotations at positions ``q`` (m), and the internal forces (N) accumulated
        into ``force`` (``(n,)`` vec3d, zeroed by the caller)."""
        g = self.group
        launch(kernels.element_forces, g.count, inputs=[q, g.elems, g.dm_inv, g.volume, g.mu, g.lam],
               outputs=[rot, self.tangent, force], device=self.model.device)

    def apply(self, x: wp.array, y: wp.array, rot: wp.array, scale: float, done: wp.array | None = None) -> None:
        """``y[c] += scale K x[c]`` for ``(k, n)`` vec3d ``x`` and ``y`` (N per m of ``x``). ``done``:
        CG scalars ``(k, worlds, slots)``; a column of a world they mark converged is skipped."""
        m, g = self.model, self.group
        inputs = [x, g.elems, g.dm_inv, g.volume, self.tangent, scale, g.world, done]
        if x.shape[0] > 1 and (m.device.is_cpu or g.count >= ELEMENT_MAJOR_FROM):
            launch(kernels.stiffness_product_columns, g.count, inputs=inputs, outputs=[y], device=m.device)
            return
        launch(kernels.stiffness_product, (x.shape[0], g.count), inputs=inputs, outputs=[y], device=m.device)

    def diagonal(self, rot: wp.array, diag: wp.array) -> None:
        """Accumulate the 3x3 diagonal blocks of ``K`` (N/m) per node into ``diag`` ``(n,)`` mat33d."""
        g = self.group
        launch(kernels.stiffness_diagonal, g.count, inputs=[g.elems, g.dm_inv, g.volume, self.tangent],
               outputs=[diag], device=self.model.device)

    def blocks(self, rot: wp.array, blocks: wp.array) -> None:
        """The sixteen 3x3 blocks (N/m) of each element's tangent, ``(16 count,)`` mat33d, block
        ``4 a + b`` of element ``e`` at ``16 e + 4 a + b``."""
        g = self.group
        launch(kernels.stiffness_blocks, g.count, inputs=[g.dm_inv, g.volume, self.tangent], outputs=[blocks],
               device=self.model.device)

    def node_rotations(self, rot: wp.array, node_sum: wp.array) -> None:
        """Accumulate ``V_e R_e`` into each node of element ``e``, ``node_sum`` ``(n,)`` mat33d."""
        g = self.group
        launch(warped_kernels.accumulate_node_rotations, g.count, inputs=[g.elems, g.volume, rot],
               outputs=[node_sum], device=self.model.device)

    def energy(self, q: wp.array, out: wp.array) -> None:
        """Accumulate the elastic energy (J) at positions ``q`` into ``out[0]``."""
        g = self.group
        launch(kernels.elastic_energy, g.count, inputs=[q, g.elems, g.dm_inv, g.volume, g.mu, g.lam],
               outputs=[out], device=self.model.device)
