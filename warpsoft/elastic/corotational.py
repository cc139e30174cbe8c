"""Corotational linear tetrahedra: linear elasticity in each element's rotated frame.

Per element, ``F = Ds Dm^-1``, ``R`` the rotation of its polar decomposition (reflection-safe),
``f = -V R sigma(sym(R^T F) - I) g`` and the stiffness ``K = R K0 R^T`` with the rotation held
fixed over the step (see ``kernels/elastic/corotational.py``). ``K x`` is applied element by
element; no 12x12 matrix is stored.
"""

from __future__ import annotations

import warp as wp

from warpsoft.kernels.elastic import corotational as kernels

from ..launch import launch

# From this many elements on CUDA (and always on the CPU), ``K x`` of several columns takes one
# thread per element for all of them: on an H200, 1024 Diamonds' 5 columns took 3.48 ms against
# 4.12 ms with a thread per column and element; below it, a column's threads are needed to fill
# the device. One column keeps the thread per column and element.
ELEMENT_MAJOR_FROM = 1 << 16


class Corotational:
    """The corotational element model of a :class:`~warpsoft.model.Model`.

    Every method takes the element rotations ``rot`` (``(elements,)`` mat33d) of the current
    linearization, written by :meth:`linearize`.
    """

    name = "corotational"

    def __init__(self, model):
        self.model = model

    def _material(self) -> list:
        m = self.model
        return [m.dm_inv, m.volume, m.mu, m.lam]

    def linearize(self, q: wp.array, rot: wp.array, force: wp.array) -> None:
        """Rotations ``rot`` at positions ``q`` (m) and the internal forces (N) accumulated into
        ``force`` (``(n,)`` vec3d, zeroed by the caller)."""
        m = self.model
        launch(kernels.corotational_forces, m.num_elements, inputs=[q, m.tets, *self._material()],
               outputs=[rot, force], device=m.device)

    def apply(self, x: wp.array, y: wp.array, rot: wp.array, scale: float, done: wp.array | None = None) -> None:
        """``y[c] += scale K x[c]`` for ``(k, n)`` vec3d ``x`` and ``y`` (N per m of ``x``). ``done``:
        CG scalars ``(k, worlds, slots)``; a column of a world they mark converged is skipped."""
        m = self.model
        inputs = [x, m.tets, *self._material(), rot, scale, m.elem_world, done]
        if x.shape[0] > 1 and (m.device.is_cpu or m.num_elements >= ELEMENT_MAJOR_FROM):
            launch(kernels.stiffness_product_columns, m.num_elements, inputs=inputs, outputs=[y], device=m.device)
            return
        launch(kernels.stiffness_product, (x.shape[0], m.num_elements), inputs=inputs, outputs=[y], device=m.device)

    def diagonal(self, rot: wp.array, diag: wp.array) -> None:
        """Accumulate the 3x3 diagonal blocks of ``K`` (N/m) per node into ``diag`` ``(n,)`` mat33d."""
        m = self.model
        launch(kernels.stiffness_diagonal, m.num_elements, inputs=[m.tets, *self._material(), rot],
               outputs=[diag], device=m.device)

    def blocks(self, rot: wp.array, blocks: wp.array) -> None:
        """The sixteen 3x3 blocks (N/m) of each element's ``K``, ``(16 elements,)`` mat33d."""
        m = self.model
        launch(kernels.stiffness_blocks, m.num_elements, inputs=[*self._material(), rot], outputs=[blocks],
               device=m.device)

    def energy(self, q: wp.array, out: wp.array) -> None:
        """Accumulate the elastic energy (J) at positions ``q`` into ``out[0]``."""
        m = self.model
        launch(kernels.elastic_energy, m.num_elements, inputs=[q, m.tets, *self._material()], outputs=[out],
               device=m.device)
