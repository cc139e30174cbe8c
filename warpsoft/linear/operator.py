"""The step's system ``A = mass_scale M + stiffness_scale K(R)``, applied matrix-free."""

from __future__ import annotations

import warp as wp

from warpsoft.kernels.linear import cg as linalg

from ..elastic import element_model
from ..launch import launch
from ..model import Model


class SystemOperator:
    """``y[c] = mass_scale M x[c] + stiffness_scale K(rot) x[c]`` for the model's elements.

    ``rot`` (m mat33d) holds the element rotations of the current linearization;
    ``x`` and ``y`` are ``(k, n)`` arrays of vec3d. ``elastic`` is the element model (the
    model's corotational one by default).
    """

    def __init__(self, model: Model, rot: wp.array, elastic=None):
        self.model, self.rot = model, rot
        self.elastic = elastic if elastic is not None else element_model(model)
        self.mass_scale = 0.0
        self.stiffness_scale = 1.0

    def set_scales(self, mass_scale: float, stiffness_scale: float) -> None:
        if mass_scale != 0.0 and self.model.mass is None:
            raise ValueError("SystemOperator: mass_scale != 0 in a model without mass")
        self.mass_scale, self.stiffness_scale = float(mass_scale), float(stiffness_scale)

    def apply(self, x: wp.array, y: wp.array, done: wp.array | None = None) -> None:
        """``y = A x``. ``done``: a solver's CG scalars ``(k, worlds, slots)``; the columns of the
        worlds they mark converged are skipped and keep what ``y`` held (a converged world stops
        costing work)."""
        m = self.model
        if self.mass_scale != 0.0:
            launch(linalg.mass_product, x.shape, inputs=[x, m.mass, self.mass_scale, m.node_world, done],
                   outputs=[y], device=m.device)
        elif done is None:
            y.zero_()
        else:
            launch(linalg.zero_columns, x.shape, inputs=[m.node_world, done], outputs=[y], device=m.device)
        self.elastic.apply(x, y, self.rot, self.stiffness_scale, done)
