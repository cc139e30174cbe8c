"""The sparse pattern of a symmetric matrix assembled from entries: its lower triangle over the
free DOFs, compressed by columns, and the slot each entry adds into (computed once per mesh and
supports; each assembly is then one ``np.bincount`` through that map)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .supernodal import narrow


@dataclass
class Sparsity:
    """The lower triangle's CSC pattern alone over ``size`` free DOFs: ``indptr`` ``(size + 1,)``,
    ``indices`` and ``columns`` ``(nnz,)``, as :class:`Pattern` has them. It is all a factor's
    analysis reads (:class:`CholmodFactor`, :func:`nested_dissection`), and light to send to a
    worker process."""

    size: int
    indptr: np.ndarray
    indices: np.ndarray
    columns: np.ndarray


class Pattern:
    """The lower triangle of a symmetric matrix over its free DOFs, compressed by columns, from
    the (row, col) places of a list of entries (element block numbers, duplicates summed). The
    constructor takes entries at any places; the solvers' element blocks come in 3x3 blocks and take
    :meth:`of_blocks`, which gives the same pattern faster.

    Args:
        rows, cols: ``(entries,)`` each entry's place among all DOFs.
        free: ``(dofs,)`` bool, the DOFs kept (the others are fixed: removed from the system).

    Attributes:
        free: ``(f,)`` ids of the free DOFs among all; ``size`` ``f``; ``renum`` ``(dofs,)`` a DOF's
            place among the free ones (-1: fixed).
        indptr, indices: the CSC pattern of the lower triangle, ``(f + 1,)`` and ``(nnz,)``;
            ``columns`` ``(nnz,)`` each slot's column; ``diagonal`` ``(f,)`` the diagonal's slots.
        keep, slot: the entries kept (free, lower) and the slot each adds into.
    """

    def __init__(self, rows: np.ndarray, cols: np.ndarray, free: np.ndarray):
        self.free = np.flatnonzero(free)
        self.size = len(self.free)
        renum = np.full(len(free), -1, dtype=np.int64)
        renum[self.free] = np.arange(self.size)
        self.renum = renum
        r, c = renum[rows], renum[cols]
        self.keep = np.flatnonzero((r >= 0) & (c >= 0) & (r >= c))  # free, lower triangle
        key = c[self.keep] * self.size + r[self.keep]  # column-major order = CSC order
        unique, self.slot = np.unique(key, return_inverse=True)
        # (kept for every mesh of a batch: in 32 bits where they fit, half the bytes)
        self.keep, self.slot = narrow(self.keep), narrow(self.slot)
        self.indices = (unique % self.size).astype(np.int64)
        col_of = unique // self.size
        self.indptr = np.searchsorted(col_of, np.arange(self.size + 1)).astype(np.int64)
        self.columns = col_of.astype(np.int64)
        self.nnz = len(unique)
        self.diagonal = self.indptr[:-1]  # the first entry of each lower column is its diagonal
        assert np.array_equal(self.indices[self.diagonal], np.arange(self.size))

    def sparsity(self) -> Sparsity:
        """The CSC pattern alone."""
        return Sparsity(self.size, self.indptr, self.indices, self.columns)

    def lower_values(self, entries: np.ndarray, diagonal: np.ndarray | None = None) -> np.ndarray:
        """The ``nnz`` values of the lower triangle: the ``entries`` summed into their slots, plus
        ``diagonal`` ``(dofs,)`` (all DOFs) on the diagonal."""
        vals = np.bincount(self.slot, weights=entries[self.keep], minlength=self.nnz)
        if diagonal is not None:
            vals[self.diagonal] += diagonal[self.free]
        return vals

    @classmethod
    def of_blocks(cls, pairs: np.ndarray, free: np.ndarray) -> Pattern:
        """The pattern of entries that come in 3x3 blocks: block ``b`` couples the nodes
        ``pairs[b]`` ``(row, column)`` and has its nine entries at ``9 b + 3 i + j``, in the DOFs
        ``(3 row + i, 3 column + j)``. The same pattern, entry for entry, as the constructor's
        from those entries, found from the blocks' node pairs: a sort of the blocks, not of their
        entries (nine times fewer: a Diamond's pattern from its elements took 16.8-19.9 ms on the VM, now
        5.3-6.4 ms).

        Args:
            pairs: ``(blocks, 2)`` node ids; free: ``(3 nodes,)`` bool.
        """
        self = object.__new__(cls)
        free = np.asarray(free, dtype=bool)
        nodes = len(free) // 3
        self.free = np.flatnonzero(free)
        self.size = len(self.free)
        self.renum = np.full(len(free), -1, dtype=np.int64)
        self.renum[self.free] = np.arange(self.size)
        row, col = np.asarray(pairs, dtype=np.int64).T
        lower = np.flatnonzero(row >= col)  # a block above the diagonal has no entry in the lower triangle
        # the distinct node pairs, by column node then row node: the order of their entries in CSC
        key, which = np.unique(col[lower] * nodes + row[lower], return_inverse=True)
        pc, pr = key // nodes, key % nodes
        i = np.arange(3)
        R, C = 3 * pr[:, None] + i, 3 * pc[:, None] + i  # (pairs, 3): the rows i and the columns j
        # kept[p, i, j]: entry (R[p, i], C[p, j]) is free and in the lower triangle (a diagonal block: i >= j)
        kept = free[R][:, :, None] & free[C][:, None, :] & ((pr != pc)[:, None, None] | (i[:, None] >= i)[None])
        count = kept.sum(axis=1)  # (pairs, 3): the pair's entries in each of its three columns
        # the entries of each DOF's column
        per_column = np.bincount(C.ravel(), weights=count.ravel(), minlength=3 * nodes).astype(np.int64)
        start = np.cumsum(per_column) - per_column  # where each DOF's column begins among the nnz
        before = np.cumsum(count, axis=0) - count  # the pairs' entries before it, in every column j
        before = before - before[np.searchsorted(pc, pc)]  # ... within its column node's pairs only
        slot = start[C][:, None, :] + before[:, None, :] + np.cumsum(kept, axis=1) - 1  # (pairs, i, j)
        self.nnz = int(per_column.sum())
        self.indices = np.empty(self.nnz, dtype=np.int64)
        self.columns = np.empty(self.nnz, dtype=np.int64)
        self.indices[slot[kept]] = np.broadcast_to(self.renum[R][:, :, None], kept.shape)[kept]
        self.columns[slot[kept]] = np.broadcast_to(self.renum[C][:, None, :], kept.shape)[kept]
        self.indptr = np.append(start[self.free], self.nnz)
        self.diagonal = self.indptr[:-1]
        assert np.array_equal(self.indices[self.diagonal], np.arange(self.size))
        taken = kept[which]  # (lower blocks, 3, 3): each lower block's entries kept
        at = np.flatnonzero(taken)
        self.keep = narrow(9 * lower[at // 9] + at % 9)  # ascending, as the entries come
        self.slot = narrow(slot[which][taken])
        return self
