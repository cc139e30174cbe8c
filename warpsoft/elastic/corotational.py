"""Corotational linear tetrahedra: linear elasticity in each element's rotated frame.

Per element, ``F = Ds Dm^-1``, ``R`` the rotation of its polar decomposition (reflection-safe),
``f = -V R sigma(sym(R^T F) - I) g`` and the stiffness ``K = R K0 R^T`` with the rotation held
fixed over the step (see ``kernels/elastic/corotational.py``). ``K x`` is applied element by
element; no 12x12 matrix is stored.
"""

from __future__ import annotations

import numpy as np
import warp as wp

from warpsoft.kernels.elastic import corotational as kernels
from warpsoft.kernels.linear import warped as warped_kernels

from ..launch import launch
from ..processes import stable_order

# From this many elements on CUDA (and always on the CPU), ``K x`` of several columns takes one
# thread per element for all of them: on an H200, 1024 Diamonds' 5 columns took 3.48 ms against
# 4.12 ms with a thread per column and element; below it, a column's threads are needed to fill
# the device. One column keeps the thread per column and element.
ELEMENT_MAJOR_FROM = 1 << 16


class Corotational:
    """The corotational linear tetrahedra of a :class:`~warpsoft.model.Model`: its element
    group ``group`` (:class:`~warpsoft.model.ElementGroup`, 4 nodes an element).

    Every method takes the group's element rotations ``rot`` (``(count,)`` mat33d) of the
    current linearization, written by :meth:`linearize`.
    """

    name = "corotational"
    nodes_per_element = 4
    kernels = kernels
    node_rotation_kernel = warped_kernels.accumulate_node_rotations
    # node_rotations by a thread per node over its elements (True) or by atomic sums from the
    # elements (False); None: the first on CUDA (1024 Diamonds on the H200: 0.63 against 2.24 ms)
    gather_rotations: bool | None = None

    def __init__(self, model, group):
        self.model, self.group = model, group
        self._incidence = None  # (node_first, node_elems): the elements around each node, made when first needed
        self._gradients = None  # (grads, moduli) of rotated_gradients, made when first needed

    def _material(self) -> list:
        g = self.group
        return [g.dm_inv, g.volume, g.mu, g.lam]

    def _linearization(self, rot: wp.array) -> list:
        """What :meth:`linearize` writes besides the forces: here the rotations."""
        return [rot]

    def _tangent(self, rot: wp.array) -> list:
        """The kernels' inputs that define the tangent stiffness of the last linearization."""
        return [*self._material(), rot]

    def linearize(self, q: wp.array, rot: wp.array, force: wp.array, moving: wp.array | None = None) -> None:
        """Rotations ``rot`` at positions ``q`` (m) and the internal forces (N) accumulated into
        ``force`` (``(n,)`` vec3d, zeroed by the caller); with ``moving`` (``(worlds,)`` int32,
        ``kernels/worlds.py``), the elements of the worlds that stay are left as they were."""
        m, g = self.model, self.group
        launch(self.kernels.element_forces, g.count, inputs=[q, g.elems, *self._material(), g.world, moving],
               outputs=self._linearization(rot) + [force], device=m.device)

    def apply(self, x: wp.array, y: wp.array, rot: wp.array, scale: float, done: wp.array | None = None) -> None:
        """``y[c] += scale K x[c]`` for ``(k, n)`` vec3d ``x`` and ``y`` (N per m of ``x``). ``done``:
        CG scalars ``(k, worlds, slots)``; a column of a world they mark converged is skipped."""
        m, g = self.model, self.group
        inputs = [x, g.elems, *self._tangent(rot), scale, g.world, done]
        if x.shape[0] > 1 and (m.device.is_cpu or g.count >= ELEMENT_MAJOR_FROM):
            launch(self.kernels.stiffness_product_columns, g.count, inputs=inputs, outputs=[y], device=m.device)
            return
        launch(self.kernels.stiffness_product, (x.shape[0], g.count), inputs=inputs, outputs=[y], device=m.device)

    def diagonal(self, rot: wp.array, diag: wp.array) -> None:
        """Accumulate the 3x3 diagonal blocks of ``K`` (N/m) per node into ``diag`` ``(n,)`` mat33d."""
        m, g = self.model, self.group
        launch(self.kernels.stiffness_diagonal, g.count, inputs=[g.elems, *self._tangent(rot)], outputs=[diag],
               device=m.device)

    def blocks(self, rot: wp.array, blocks: wp.array, elements: wp.array | None = None) -> None:
        """The ``k^2`` 3x3 blocks (N/m) of each element's ``K`` (``k`` nodes an element),
        ``(k^2 count,)`` mat33d, block ``k a + b`` of element ``e`` at ``k^2 e + k a + b``;
        with ``elements`` (``(m,)`` int32 on the device, the group's elements), those alone, in
        one launch: the ``i``-th's block ``k a + b`` at ``k^2 i + k a + b`` (``blocks``
        ``(k^2 m,)``)."""
        count = self.group.count if elements is None else elements.shape[0]
        launch(self.kernels.stiffness_blocks, count, inputs=[*self._tangent(rot), elements], outputs=[blocks],
               device=self.model.device)

    def gather_blocks(self, rot: wp.array, slot_start: wp.array, contributions: wp.array, values: wp.array,
                      moving: wp.array | None = None) -> bool:
        """The blocks of :meth:`blocks` summed into slots, none stored: ``values[s]`` (N/m) sums the
        blocks ``contributions[slot_start[s]:slot_start[s + 1]]`` (indexes as in :meth:`blocks`); the
        slots of the worlds that stay (``moving``) keep theirs. Returns False where the element model
        has no such kernel (the caller stores the blocks)."""
        m, g = self.model, self.group
        if getattr(self.kernels, "rotated_gradients", None) is None:
            return False
        if self._gradients is None:  # each element's rotated gradients, then the slots read them
            self._gradients = (wp.zeros(4 * g.count, dtype=wp.vec3d, device=m.device),
                               wp.zeros(g.count, dtype=wp.vec2d, device=m.device))
        launch(self.kernels.rotated_gradients, g.count, inputs=[*self._tangent(rot), g.world, moving],
               outputs=list(self._gradients), device=m.device)
        launch(self.kernels.stiffness_slots_from, len(values),
               inputs=[*self._gradients, slot_start, contributions, g.world, moving], outputs=[values], device=m.device)
        return True

    def node_rotations(self, rot: wp.array, node_sum: wp.array, moving: wp.array | None = None) -> None:
        """Accumulate ``V_e R_e`` into each node of element ``e``, ``node_sum`` ``(n,)`` mat33d (not
        for the worlds that stay: ``moving``)."""
        m, g = self.model, self.group
        if m.device.is_cuda if self.gather_rotations is None else self.gather_rotations:
            if self._incidence is None:
                self._incidence = incidence(g.elems.numpy(), m.num_nodes, m.device)
            launch(warped_kernels.gather_node_rotations, m.num_nodes,
                   inputs=[*self._incidence, g.volume, rot, m.node_world, moving], outputs=[node_sum], device=m.device)
            return
        launch(self.node_rotation_kernel, g.count, inputs=[g.elems, g.volume, rot, g.world, moving],
               outputs=[node_sum], device=m.device)

    def energy(self, q: wp.array, out: wp.array) -> None:
        """Accumulate the elastic energy (J) at positions ``q`` into ``out[0]``."""
        m, g = self.model, self.group
        launch(self.kernels.elastic_energy, g.count, inputs=[q, g.elems, *self._material()], outputs=[out],
               device=m.device)


def incidence(elems: np.ndarray, nodes: int, device) -> tuple[wp.array, wp.array]:
    """The elements around each node: ``(node_first, node_elems)``, ``(nodes + 1,)`` and
    ``(elements x nodes an element,)`` int32, ``node_elems[node_first[i]:node_first[i + 1]]``
    the elements of node ``i`` (``elems`` ``(elements, nodes an element)``)."""
    node = elems.reshape(-1)
    owner = np.repeat(np.arange(len(elems), dtype=np.int32), elems.shape[1])
    order = stable_order(node)  # (world by world: sorted a piece a thread)
    first = np.concatenate([[0], np.cumsum(np.bincount(node, minlength=nodes))]).astype(np.int32)
    return wp.array(first, dtype=wp.int32, device=device), wp.array(owner[order], dtype=wp.int32, device=device)
