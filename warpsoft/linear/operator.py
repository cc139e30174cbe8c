"""The step's system ``A = mass_scale M + stiffness_scale K(R)``, applied matrix-free."""

from __future__ import annotations

import warp as wp

from warpsoft.kernels import fem, linalg

from ..model import Model


class SystemOperator:
    """``y[c] = mass_scale M x[c] + stiffness_scale K(rot) x[c]`` for the model's elements.

    ``rot`` (m mat33d) holds the element rotations of the current linearization;
    ``x`` and ``y`` are ``(k, n)`` arrays of vec3d.
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
            wp.launch(linalg.mass_product, x.shape, inputs=[x, m.mass, self.mass_scale], outputs=[y],
                      device=m.device)
        else:
            y.zero_()
        wp.launch(fem.stiffness_product, m.num_elements,
                  inputs=[x, m.tets, m.dm_inv, m.volume, m.mu, m.lam, self.rot, self.stiffness_scale],
                  outputs=[y], device=m.device)
