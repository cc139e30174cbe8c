"""Element models behind one interface: ``linearize`` (rotations or tangents, and the internal
forces at ``q``), ``apply`` (the tangent stiffness product), ``diagonal`` and ``blocks`` (for
preconditioners and assembly), ``node_rotations`` and ``energy``. A model's bodies choose
their element (``Scene.add_body(..., element=...)``); :class:`Elements` runs each kind over its
group of elements. A new model is one file here, its kernels in ``kernels/elastic/`` and one
line in ELEMENT_MODELS.
"""

from __future__ import annotations

import numpy as np
import warp as wp

from .corotational import Corotational
from .neohookean import NeoHookean
from .quadratic import Quadratic

ELEMENT_MODELS = {"corotational": Corotational, "neohookean": NeoHookean, "quadratic": Quadratic}


class Elements:
    """Every element of a :class:`~warpsoft.model.Model`, each group by its element model.

    The rotations ``rot`` (``(num_elements,)`` mat33d, one per element of every group, group
    after group) are written by :meth:`linearize` and read by the other methods. The blocks of
    :meth:`blocks` (``(num_blocks,)`` mat33d, N/m) couple the node pairs of :meth:`block_nodes`.
    """

    def __init__(self, model):
        self.model = model
        self.groups = [ELEMENT_MODELS[g.kind](model, g) for g in model.element_groups]
        self.num_elements = sum(g.group.count for g in self.groups)
        self.num_blocks = sum(g.nodes_per_element ** 2 * g.group.count for g in self.groups)
        self.kinds = [g.name for g in self.groups]

    def _parts(self, rot: wp.array, per: str | None = None, array: wp.array | None = None):
        """Each group with its slice of ``rot`` (and of ``array``, laid out by ``per``: None or
        "blocks")."""
        one = len(self.groups) == 1
        b0 = 0
        for g in self.groups:
            s, n = g.group.start, g.group.count
            r = rot if one else rot[s:s + n]
            if per == "blocks":
                nb = g.nodes_per_element ** 2 * n
                yield g, r, array if one else array[b0:b0 + nb]
                b0 += nb
            else:
                yield g, r, None

    def linearize(self, q: wp.array, rot: wp.array, force: wp.array, moving: wp.array | None = None) -> None:
        """Rotations ``rot`` at positions ``q`` (m) and the internal forces (N) accumulated into
        ``force`` (``(n,)`` vec3d, zeroed by the caller for the worlds that move); ``moving``
        (``(worlds,)`` int32, ``kernels/worlds.py``; None: all): the worlds that stay keep theirs."""
        for g, r, _ in self._parts(rot):
            g.linearize(q, r, force, moving)

    def apply(self, x: wp.array, y: wp.array, rot: wp.array, scale: float, done: wp.array | None = None) -> None:
        """``y[c] += scale K x[c]`` for ``(k, n)`` vec3d ``x`` and ``y`` (see the element models)."""
        for g, r, _ in self._parts(rot):
            g.apply(x, y, r, scale, done)

    def diagonal(self, rot: wp.array, diag: wp.array) -> None:
        """Accumulate the 3x3 diagonal blocks of ``K`` (N/m) per node into ``diag`` ``(n,)`` mat33d."""
        for g, r, _ in self._parts(rot):
            g.diagonal(r, diag)

    def blocks(self, rot: wp.array, blocks: wp.array, ranges: list[tuple[int, int]] | None = None) -> None:
        """Every element's rotated 3x3 stiffness blocks (N/m) into ``blocks`` ``(num_blocks,)``; with
        ``ranges`` ``[(lo, hi), ...]`` (a model of one element group), those of elements ``lo:hi`` of
        each range alone, one range after another, in one launch (a world's refresh alone: a launch
        per world cost 0.13 ms of the H200's host each, docs/bench-batch/install-before/)."""
        if ranges is not None:
            if len(self.groups) != 1:
                raise ValueError(f"Elements: the blocks of ranges of elements need one element group, got "
                                 f"{self.kinds}")
            listed = [np.arange(lo, hi, dtype=np.int32) for lo, hi in ranges if hi > lo]
            if listed:  # (an empty list of elements would mean every element to the kernel)
                self.groups[0].blocks(rot, blocks, wp.array(np.concatenate(listed), dtype=wp.int32,
                                                            device=rot.device))
            return
        for g, r, b in self._parts(rot, "blocks", blocks):
            g.blocks(r, b)

    def block_nodes(self) -> np.ndarray:
        """The global node ids ``(a, b)`` each block of :meth:`blocks` couples, ``(num_blocks, 2)``."""
        return np.concatenate([block_pairs(g.group.elems_np) for g in self.groups])

    def node_rotations(self, rot: wp.array, node_sum: wp.array, moving: wp.array | None = None) -> None:
        """Accumulate ``V_e R_e`` of every element into each of its nodes, ``node_sum`` ``(n,)`` (not
        for the worlds that stay: ``moving``)."""
        for g, r, _ in self._parts(rot):
            g.node_rotations(r, node_sum, moving)

    def energy(self, q: wp.array, out: wp.array) -> None:
        """Accumulate the elastic energy (J) at positions ``q`` into ``out[0]``."""
        for g in self.groups:
            g.energy(q, out)


def block_pairs(elems: np.ndarray) -> np.ndarray:
    """The node ids ``(a, b)`` each of the ``k^2`` blocks of each element couples, in the order the
    element models form their blocks (block ``k a + b`` of element ``e`` at ``k^2 e + k a + b``):
    ``(k^2 count, 2)`` int64, from ``elems`` ``(count, k)``."""
    e = np.asarray(elems, dtype=np.int64)
    k = e.shape[1]
    return np.stack([np.repeat(e, k, axis=1), np.tile(e, (1, k))], axis=2).reshape(-1, 2)


def element_model(model) -> Elements:
    """The element models of ``model``'s bodies."""
    return Elements(model)


__all__ = ["ELEMENT_MODELS", "Corotational", "Elements", "NeoHookean", "Quadratic", "block_pairs", "element_model"]
