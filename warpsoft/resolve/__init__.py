"""Constraint-space solvers: the multipliers ``lambda`` from ``W`` and ``delta_free``.

``gauss_seidel``: the direct model (inputs in, motion out), on the device for every world.
``inverse``: the inverse model (effector targets in, actuation out), a QP per world (piqp, the
reference); ``inverse_device``: the same QP on the device for every world at once (an exact
dual active-set method, up to 16 actuators per world).
"""

from .gauss_seidel import GaussSeidel, ResolveResult, RowInputs, kinematic_jacobian, projected_gauss_seidel
from .inverse import DEFAULT_EPSILON, InverseResult, inverse_hessian, solve_inverse

__all__ = ["DEFAULT_EPSILON", "GaussSeidel", "InverseResult", "ResolveResult", "RowInputs", "inverse_hessian",
           "kinematic_jacobian", "projected_gauss_seidel", "solve_inverse"]
