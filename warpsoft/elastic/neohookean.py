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

from .corotational import Corotational


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


class NeoHookean(Corotational):
    """The stable Neo-Hookean tetrahedra of a :class:`~warpsoft.model.Model`: its element group
    ``group`` (:class:`~warpsoft.model.ElementGroup`, 4 nodes an element); the methods are
    :class:`Corotational`'s, on these kernels.

    :meth:`linearize` writes each element's projected tangent (``tangent``, ``(count,)``
    :class:`~warpsoft.kernels.elastic.neohookean.Tangent`) and the rotation of its SVD into
    ``rot`` (for the warped preconditioner); the stiffness kernels read the tangent.
    """

    name = "neohookean"
    kernels = kernels

    def __init__(self, model, group):
        super().__init__(model, group)
        self.tangent = wp.zeros(group.count, dtype=kernels.Tangent, device=model.device)

    def _linearization(self, rot: wp.array) -> list:
        return [rot, self.tangent]

    def _tangent(self, rot: wp.array) -> list:
        g = self.group
        return [g.dm_inv, g.volume, self.tangent]
