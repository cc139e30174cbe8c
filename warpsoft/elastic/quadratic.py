"""Corotational quadratic (10-node) tetrahedra: linear elasticity in each element's rotated
frame, a node at each edge's midpoint, integrated by the four-point rule.

Linear tetrahedra lock in bending and near incompressibility: on the clamped cantilever at the
default mesh they are 8.6 %, 15 % and 30 % too stiff at Poisson ratios 0.3, 0.45 and 0.49,
while 10-node ones on a mesh four times coarser (fewer DOFs) are within 0.9 %, 2.4 % and 3.4 %
of Timoshenko (``tools/element_study.py``, ``docs/accuracy/element_choice``). The rotation is one
per element, of its mean deformation gradient (see ``kernels/elastic/quadratic.py``); ``K x``
is applied element by element from the corner gradients, no 30x30 matrix stored.
"""

from __future__ import annotations

from warpsoft.kernels.elastic import quadratic as kernels

from .corotational import Corotational


class Quadratic(Corotational):
    """The quadratic tetrahedra of a :class:`~warpsoft.model.Model` (10 nodes an element: the
    corners, then the midpoints of edges 01, 02, 03, 12, 13, 23); the methods are
    :class:`Corotational`'s, on these kernels."""

    name = "quadratic"
    nodes_per_element = 10
    kernels = kernels
    node_rotation_kernel = kernels.accumulate_node_rotations
