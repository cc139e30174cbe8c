"""Assembly of ``A = mass_scale M + stiffness_scale K`` into a fixed sparse pattern, and its
factorizations (CHOLMOD through cvxopt; SciPy's SuperLU, v1's, for comparison).

The pattern (the lower triangle of ``A`` over the free DOFs, compressed by columns) and the
map from each element block entry to its slot are computed once per world's mesh and supports
(``A`` is block diagonal by worlds); each linearization then costs one Warp kernel (the rotated
element blocks) and one ``np.bincount`` a world through that map. CHOLMOD analyses the pattern
once (ordering, supernodes) and only refactorizes numerically at each linearization. Measured
on the Diamond (4227 free DOFs, 2-core VM, 2026-11-22): SuperLU 46.3 ms per factorization and
5.9 ms to solve 5 right-hand sides; CHOLMOD 2.8 ms analysis once, then 6.3 ms per
refactorization and 1.2 ms per 5 right-hand sides; QDLDL 10.2 ms per refactorization; cholespy
(no refactorization) 31.4 ms.
"""

from __future__ import annotations

import hashlib
from collections.abc import Iterator

import numpy as np
import scipy.sparse as sp
import warp as wp

from ..elastic import block_pairs
from .operator import SystemOperator
from .pattern import Pattern, Sparsity

# numbers of a dense right-hand side per CHOLMOD solve: cvxopt's cholmod.solve crashed (a segmentation
# fault, on the H200's host) on the identity of the PneuNet's 20916 free DOFs (437M numbers, 3.5 GB); runs
# of 2^24 numbers (134 MB) hold the dense preconditioner's refresh of the linear PneuNet (8565 DOFs) to a
# 1.19 GB peak in 7.2 s on the CPU VM, where 2^26 took 2.16 GB and 8.5 s, and the whole identity 2.28 GB, 10.2 s
SOLVE_ENTRIES = 1 << 24
# the most numbers of the dense block in which :meth:`CholmodFactor.gram` multiplies Z's rows (128 MB)
GRAM_DENSE_ENTRIES = 1 << 24
ORDERINGS = ("cholmod", "nested_dissection")  # CholmodFactor's fill-reducing orderings
# element blocks formed at a time when the values are assembled world by world (302 MB of mat33d;
# a world's blocks are formed together however many it has)
CHUNK_BLOCKS = 1 << 22


class Assembly:
    """``A`` over the free DOFs, lower triangle, CSC, its pattern analysed once.

    The worlds of a model are separate bodies, so ``A`` is block diagonal, each world's free DOFs
    a contiguous range of the free ones (:attr:`ranges`). Each world's block has its own
    :class:`Pattern`, in the world's own numbering, and worlds of one mesh and supports share it
    (a sweep over a modulus makes one). The pattern of the whole (:attr:`indptr`, :attr:`indices`,
    :attr:`columns`) is the worlds' one after another, made only when asked for (a factor of the
    whole ``A``). One pattern of all worlds held, as it was made, about 60 bytes an element block
    entry at its peak: 64 different Diamonds (183,637 tetrahedra) peaked at 1.66 GB of Python
    allocations on the 2-core VM, and 1024 were killed for memory before their first step.

    Attributes:
        free: ``(f,)`` ids of the free DOFs among all; ``size`` ``f``; ``renum`` ``(dofs,)`` a DOF's
            place among the free ones (-1: fixed).
        ranges: per world, ``(lo, hi)``: its free DOFs among the free ones.
        patterns: per world, the :class:`Pattern` of its block (shared by worlds of one mesh and
            supports); ``value_start`` ``(worlds + 1,)``: where each world's values begin among the
            ``nnz`` of :meth:`values`.
        mass: ``(f,)`` the free DOFs' lumped masses (kg), or None.
    """

    def __init__(self, operator: SystemOperator):
        self.op = operator
        model = operator.model
        free = model.mask_np.ravel() > 0
        self.free = np.flatnonzero(free)
        self.size = len(self.free)
        self.renum = np.full(len(free), -1, dtype=np.int64)
        self.renum[self.free] = np.arange(self.size)
        node_start = np.asarray(model.world_node_start, dtype=np.int64)
        starts = np.searchsorted(self.free, 3 * node_start)
        self.ranges = [(int(starts[w]), int(starts[w + 1])) for w in range(model.num_worlds)]
        groups = operator.elastic.groups
        # per world and element group: its elements (lo, hi) among the group's (grouped by world)
        bounds = [np.searchsorted(model.node_world_np[g.group.elems_np[:, 0]], np.arange(model.num_worlds + 1))
                  for g in groups]
        self.elements = [[(int(b[w]), int(b[w + 1])) for b in bounds] for w in range(model.num_worlds)]
        self._block_start = np.cumsum([0] + [g.nodes_per_element ** 2 * g.group.count for g in groups])
        self.patterns, shared = [], {}
        for w in range(model.num_worlds):
            n0, n1 = int(node_start[w]), int(node_start[w + 1])
            local = [g.group.elems_np[lo:hi].astype(np.int64) - n0 for g, (lo, hi) in zip(groups, self.elements[w],
                                                                                            strict=True)]
            mask = np.ascontiguousarray(free[3 * n0:3 * n1])
            key = (n1 - n0, hashlib.sha1(b"".join(e.tobytes() + b"|" for e in local) + mask.tobytes()).hexdigest())
            if key not in shared:
                shared[key] = element_pattern(local, mask)
            self.patterns.append(shared[key])
        self.value_start = np.cumsum([0] + [p.nnz for p in self.patterns])
        self.nnz = int(self.value_start[-1])
        self.mass = None if model.mass is None else np.repeat(model.mass_np, 3)[self.free]
        self._buffer = None  # the element blocks formed at a time (:meth:`world_values`)
        self._whole = None  # the whole pattern, made when asked for

    def world_values(self, worlds: np.ndarray | None = None) -> Iterator[tuple[int, np.ndarray]]:
        """Each world's ``nnz`` values of its block's lower triangle, at the operator's current
        rotations and scales: ``(world, values)`` for the worlds listed (ascending; None: all). The
        element blocks are formed for at most :data:`CHUNK_BLOCKS` of them at a time (a model of
        one element group; else all at once), not kept for the whole model (72 bytes a block:
        5.1 GB for 1024 Diamonds, 4.39 million tetrahedra)."""
        op, groups = self.op, self.op.elastic.groups
        worlds = range(len(self.patterns)) if worlds is None else [int(w) for w in worlds]
        k2 = [g.nodes_per_element ** 2 for g in groups]
        count = [sum(k * (hi - lo) for k, (lo, hi) in zip(k2, self.elements[w], strict=True)) for w in worlds]
        if len(groups) == 1:
            need = max(count, default=0)
            size = min(op.elastic.num_blocks, max(CHUNK_BLOCKS, need))
        else:
            size = op.elastic.num_blocks
        if self._buffer is None or self._buffer.shape[0] < size:
            self._buffer = wp.zeros(size, dtype=wp.mat33d, device=op.model.device)
        if len(groups) > 1:
            op.elastic.blocks(op.rot, self._buffer)
            every = self._buffer.numpy().reshape(-1, 9)
        i = 0
        while i < len(worlds):
            if len(groups) == 1:  # the next worlds whose blocks fit the buffer, formed in one launch
                j, held = i, 0
                while j < len(worlds) and (j == i or held + count[j] <= size):
                    held += count[j]
                    j += 1
                op.elastic.blocks(op.rot, self._buffer, [self.elements[w][0] for w in worlds[i:j]])
                chunk = self._buffer.numpy()[:held].reshape(-1, 9)
                starts = np.cumsum([0] + count[i:j])
                parts = [chunk[starts[c]:starts[c + 1]] for c in range(j - i)]
            else:
                j = i + 1
                parts = [np.concatenate([every[b + k * lo:b + k * hi] for b, k, (lo, hi) in
                                         zip(self._block_start[:-1], k2, self.elements[worlds[i]], strict=True)])]
            for w, blocks in zip(worlds[i:j], parts, strict=True):
                yield w, self._values(w, blocks)
            i = j

    def _values(self, w: int, blocks: np.ndarray) -> np.ndarray:
        """World ``w``'s values from its element blocks ``(blocks, 9)`` (N/m)."""
        op, pattern = self.op, self.patterns[w]
        vals = op.stiffness_scale * pattern.lower_values(blocks.reshape(-1))
        if op.mass_scale != 0.0 and self.mass is not None:
            lo, hi = self.ranges[w]
            vals[pattern.diagonal] += op.mass_scale * self.mass[lo:hi]
        return vals

    def values(self) -> np.ndarray:
        """The ``nnz`` values of the whole lower triangle at the operator's current rotations and
        scales, world after world."""
        out = np.empty(self.nnz)
        for w, vals in self.world_values():
            out[self.value_start[w]:self.value_start[w + 1]] = vals
        return out

    def _joined(self) -> Sparsity:
        """The whole pattern, the worlds' blocks one after another (made once, when asked for)."""
        if self._whole is None:
            parts = [(p, lo) for p, (lo, _) in zip(self.patterns, self.ranges, strict=True)]
            indptr = np.concatenate([p.indptr[:-1] + self.value_start[w] for w, (p, _) in enumerate(parts)]
                                    + [[self.nnz]]).astype(np.int64)
            indices = np.concatenate([p.indices + lo for p, lo in parts] + [np.zeros(0, np.int64)])
            columns = np.concatenate([p.columns + lo for p, lo in parts] + [np.zeros(0, np.int64)])
            self._whole = Sparsity(self.size, indptr, indices, columns)
        return self._whole

    @property
    def indptr(self) -> np.ndarray:
        """``(f + 1,)`` the whole lower triangle's column starts (CSC)."""
        return self._joined().indptr

    @property
    def indices(self) -> np.ndarray:
        """``(nnz,)`` the whole lower triangle's rows."""
        return self._joined().indices

    @property
    def columns(self) -> np.ndarray:
        """``(nnz,)`` each slot's column."""
        return self._joined().columns

    @property
    def diagonal(self) -> np.ndarray:
        """``(f,)`` the diagonal's slots (the first of each column)."""
        return self._joined().indptr[:-1]

    def sparsity(self) -> Sparsity:
        """The whole CSC pattern alone."""
        return self._joined()

    def matrix(self, values: np.ndarray | None = None) -> sp.csc_matrix:
        """The full symmetric ``A`` over the free DOFs, ``(f, f)``."""
        vals = self.values() if values is None else values
        lower = sp.csc_matrix((vals, self.indices, self.indptr), shape=(self.size, self.size))
        return (lower + lower.T - sp.diags(lower.diagonal())).tocsc()


def element_pattern(local: list[np.ndarray], free: np.ndarray) -> Pattern:
    """The :class:`Pattern` of one world's element blocks: ``local`` per element group its elements
    ``(count, k)`` (node ids from the world's first), their blocks as :meth:`Elements.blocks` forms
    them; ``free`` ``(3 nodes,)`` bool."""
    return Pattern.of_blocks(np.concatenate([block_pairs(e) for e in local]), free)


def nested_dissection(pattern: Pattern | Sparsity, lo: int = 0, hi: int | None = None) -> np.ndarray:
    """METIS's nested dissection (pymetis) of the free DOFs ``lo:hi`` of ``pattern``'s graph:
    ``(hi - lo,)``, the DOF (counted from ``lo``) at each place of the ordering. It splits the
    graph by small separators, recursively, so the elimination tree is shallow: seven Diamonds'
    sparse factors solve in 9-13 levels each way instead of the 16-36 of CHOLMOD's own choice
    (AMD), with about as many entries (``warpsoft.linear.supernodal``)."""
    import pymetis

    hi = pattern.size if hi is None else hi
    block = slice(int(pattern.indptr[lo]), int(pattern.indptr[hi]))
    r, c = pattern.indices[block] - lo, pattern.columns[block] - lo
    off = r != c
    r, c = np.concatenate([r[off], c[off]]), np.concatenate([c[off], r[off]])  # both triangles
    order = np.lexsort((c, r))
    r, c = r[order], c[order]
    starts = np.searchsorted(r, np.arange(hi - lo + 1))
    perm, _ = pymetis.nested_dissection(pymetis.CSRAdjacency(starts.tolist(), c.tolist()))
    return np.asarray(perm, dtype=np.int64)


class CholmodFactor:
    """Sparse Cholesky of ``A`` (CHOLMOD, supernodal, through cvxopt): analysed once,
    refactorized numerically for new values of the same pattern."""

    name = "cholmod"

    def __init__(self, assembly: Assembly | Pattern | Sparsity, dofs: tuple[int, int] | None = None,
                 ordering: str = "cholmod", permutation: np.ndarray | None = None):
        """``assembly``: the pattern (an :class:`Assembly`, any :class:`Pattern`, or its :class:`Sparsity`). ``dofs``:
        ``(lo, hi)``, the factor of ``A`` over the free DOFs ``lo:hi`` alone, a diagonal block of
        ``A`` (a world's, see :class:`WorldsCholmod`); its solves and values are then of those DOFs.
        ``ordering``: "cholmod" (CHOLMOD picks the ordering of least fill: the host's solves) or
        "nested_dissection" (:func:`nested_dissection`, kept as it is: the device's level solves).
        ``permutation``: with "nested_dissection", the ordering itself (the DOF at each place, as
        :meth:`lower` returns it), when an earlier factor of the pattern found it: METIS is not run
        again (a Diamond's factor on the 2-core VM, 3048 DOFs: 12 -> 4 ms)."""
        import cvxopt
        from cvxopt import cholmod

        if ordering not in ORDERINGS:
            raise ValueError(f"CholmodFactor: ordering must be one of {ORDERINGS}, got {ordering!r}")
        self._cvxopt, self._cholmod = cvxopt, cholmod
        self.assembly, self.ordering = assembly, ordering
        lo, hi = (0, assembly.size) if dofs is None else dofs
        self._dofs = (lo, hi)
        self._perm = None  # the nested dissection, computed at the first analysis (or given)
        self.values_slice = slice(int(assembly.indptr[lo]), int(assembly.indptr[hi]))  # the block's columns
        rows, cols = assembly.indices[self.values_slice] - lo, assembly.columns[self.values_slice] - lo
        if len(rows) and (rows.min() < 0 or rows.max() >= hi - lo):
            raise ValueError(f"CholmodFactor: the free DOFs {lo}:{hi} are coupled to others: not a diagonal block")
        self.size = hi - lo
        if permutation is not None:
            if ordering != "nested_dissection" or len(permutation) != self.size:
                raise ValueError(f"CholmodFactor: a given permutation is a nested dissection's of the {self.size} "
                                 f"DOFs, got {len(permutation)} with ordering {ordering!r}")
            self._perm = cvxopt.matrix(np.asarray(permutation, dtype=np.int64).tolist(), tc="i")
        self._matrix = cvxopt.spmatrix(np.zeros(len(rows)), cvxopt.matrix(rows), cvxopt.matrix(cols),
                                       (self.size, self.size))
        self._symbolic = None
        self._place = None  # where the fill-reducing permutation P puts each DOF (read once, after a factorization)

    def factorize(self, values: np.ndarray) -> None:
        """Refactorize for new values (of its block: ``assembly.values()[values_slice]``); raises
        ArithmeticError when ``A`` is not positive definite."""
        self._matrix.V = self._cvxopt.matrix(values)
        if self._symbolic is None:
            self._symbolic = self._analyse()
        self._cholmod.numeric(self._matrix, self._symbolic)

    def _analyse(self):
        """CHOLMOD's symbolic analysis with the factor's ordering."""
        if self.ordering == "cholmod":
            return self._cholmod.symbolic(self._matrix, uplo="L")
        if self._perm is None:
            self._perm = self._cvxopt.matrix(nested_dissection(self.assembly, *self._dofs).tolist(), tc="i")
        options = self._cholmod.options
        saved = options.get("nmethods")
        options["nmethods"] = 1  # the given ordering alone (with 0 CHOLMOD also tries AMD and keeps the least fill)
        try:
            return self._cholmod.symbolic(self._matrix, p=self._perm, uplo="L")
        finally:  # the options as they were (the key absent if it was)
            if saved is None:
                del options["nmethods"]
            else:
                options["nmethods"] = saved

    def lower(self, values: np.ndarray) -> tuple[sp.csc_matrix, np.ndarray]:
        """Factorize ``values`` and return the factor itself: ``L`` ``(f, f)``, lower, CSC with sorted
        indices, and ``order`` ``(f,)``, with ``A[order][:, order] = L L^T`` (the DOF at each of the
        factor's places). Reading ``L`` out of CHOLMOD (cvxopt's ``getfactor``) leaves its factor
        unusable, so each call analyses anew (the same pattern gives the same ordering and the
        same supernodes) and the factor serves no solve afterwards."""
        self._symbolic = None
        self.factorize(values)
        order = self._cvxopt.matrix(np.arange(self.size, dtype=float))
        self._cholmod.solve(self._symbolic, order, sys=7)  # (P b)[i] = b[order[i]]
        L = self._cholmod.getfactor(self._symbolic)
        self._symbolic = None
        rows, cols, vals = (np.asarray(a).ravel() for a in (L.I, L.J, L.V))
        L = sp.csc_matrix((vals, (rows, cols)), shape=(self.size, self.size))
        L.sort_indices()
        return L, np.asarray(order).ravel().round().astype(np.int64)

    def solve(self, b: np.ndarray) -> np.ndarray:
        """``A^-1 b`` for ``b`` of shape ``(f, k)`` (or ``(f,)``), in runs of columns of at most
        :data:`SOLVE_ENTRIES` numbers each."""
        if b.ndim == 1 or b.size <= SOLVE_ENTRIES or b.shape[1] == 1:
            y = self._cvxopt.matrix(np.asfortranarray(b))
            self._cholmod.solve(self._symbolic, y)
            return np.asarray(y).reshape(b.shape)
        run = max(1, SOLVE_ENTRIES // b.shape[0])
        return np.concatenate([self.solve(b[:, j:j + run]) for j in range(0, b.shape[1], run)], axis=1)

    def forward(self, dof: np.ndarray, column: np.ndarray, value: np.ndarray, columns: int) -> sp.csc_matrix:
        """``Z = L^-1 P B`` for the sparse ``B`` ``(f, columns)`` given by its entries (free DOF,
        column, value), where ``A = P^T L L^T P`` (CHOLMOD's supernodal factor is ``L L^T``), so
        that ``B^T A^-1 B = Z^T Z``. One sparse forward solve: a column of ``Z`` is nonzero only
        along its DOFs' paths up the elimination tree (5 % of the Grasper's entries)."""
        colptr, row, z = self._forward(dof, column, value, columns)
        return sp.csc_matrix((z, row, colptr), shape=(self.size, columns))

    def gram(self, dof: np.ndarray, column: np.ndarray, value: np.ndarray, columns: int) -> np.ndarray:
        """``B^T A^-1 B = Z^T Z`` ``(columns, columns)``, dense, for ``B`` as in :meth:`forward`.
        ``Z``'s rows that hold an entry are gathered into a dense block and multiplied there:
        SciPy's sparse product built five sparse matrices a call. On the Grasper (3-21 columns,
        2-core VM) a compliance took 760 us with it, 266 us with the block (3 columns), and the
        lazy contact set's compliances 1.06-1.23 against 0.70 ms a step."""
        colptr, row, z = self._forward(dof, column, value, columns)
        held, place = np.unique(row, return_inverse=True)
        if len(held) * columns > GRAM_DENSE_ENTRIES:  # a dense block too big: the sparse product
            Z = sp.csc_matrix((z, row, colptr), shape=(self.size, columns))
            return (Z.T @ Z).toarray()
        block = np.zeros((len(held), columns))
        block[place, np.repeat(np.arange(columns), np.diff(colptr))] = z
        return block.T @ block

    def gram_parts(self, dof: np.ndarray, column: np.ndarray, value: np.ndarray,
                   columns: int) -> Iterator[tuple[np.ndarray, np.ndarray]]:
        """:meth:`gram` as one block of every column (:meth:`WorldsCholmod.gram_parts`'s form)."""
        yield np.arange(columns), self.gram(dof, column, value, columns)

    def _forward(self, dof: np.ndarray, column: np.ndarray, value: np.ndarray,
                 columns: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``Z`` of :meth:`forward` as CHOLMOD gives it, compressed columns (``colptr``, ``row``,
        ``values``; the rows of a column not sorted)."""
        cv = self._cvxopt
        if self._place is None:  # P is fixed by the analysis: (P b)[i] = b[order[i]]
            order = cv.matrix(np.arange(self.size, dtype=float))
            self._cholmod.solve(self._symbolic, order, sys=7)
            self._place = np.argsort(np.asarray(order).ravel().round().astype(np.int64))
        # P B, permuted here, its duplicate entries summed and sorted first: cvxopt builds a sparse
        # matrix at about 1 us an entry (a cavity's row repeats each wall node: the PneuNet's 20460
        # entries for 22 rows took 30 ms, summed 3591 took 3.4 ms)
        size = self.size
        key, summed = np.unique(column.astype(np.int64) * size + self._place[dof], return_inverse=True)
        rhs = cv.spmatrix(cv.matrix(np.bincount(summed, weights=value, minlength=len(key))), cv.matrix(key % size),
                          cv.matrix(key // size), (size, columns))
        colptr, row, z = self._cholmod.spsolve(self._symbolic, rhs, sys=4).CCS
        return np.asarray(colptr).ravel(), np.asarray(row).ravel(), np.asarray(z).ravel()


class SuperLUFactor:
    """SciPy's SuperLU, factorized from scratch each time (v1's CPU path, for comparison)."""

    name = "superlu"

    def __init__(self, assembly: Assembly):
        self.assembly = assembly
        self._lu = None

    def factorize(self, values: np.ndarray) -> None:
        import scipy.sparse.linalg as spla

        self._lu = spla.splu(self.assembly.matrix(values))

    def solve(self, b: np.ndarray) -> np.ndarray:
        return self._lu.solve(np.ascontiguousarray(b))


class WorldsCholmod:
    """One :class:`CholmodFactor` per world of a model of several: the worlds are separate
    bodies, so ``A`` is block diagonal, each world's free DOFs a contiguous range of the free
    ones. Each world's solves then cost what they cost alone. One factor of the whole ``A``
    would do as well for the factorization and the free solve, but not for the compliance: CHOLMOD
    solves a sparse right-hand side as dense columns of every DOF, so ``W``'s forward solve cost
    columns x DOFs, both growing with the worlds (16 Diamonds on the 2-core VM: 171 ms of a
    271 ms step; 64: 3.5 s a step)."""

    name = "cholmod"

    def __init__(self, assembly: Assembly):
        self.assembly = assembly
        held = [w for w, (lo, hi) in enumerate(assembly.ranges) if hi > lo]  # worlds with free DOFs
        self.worlds = np.array(held, dtype=np.int64)  # the world of each part
        self.ranges = [assembly.ranges[w] for w in held]
        self.parts = [CholmodFactor(assembly.patterns[w]) for w in held]  # in the world's own numbering
        self._part = {w: i for i, w in enumerate(held)}
        self.size = assembly.size

    def factorize(self, worlds: np.ndarray | None = None) -> None:
        """Each world's block refactorized at the operator's current state (those set in
        ``worlds``, ``(num_worlds,)`` bool, if given; the others keep their factors), its values
        assembled world by world (:meth:`Assembly.world_values`); raises ArithmeticError when
        one is not positive definite."""
        due = self.worlds if worlds is None else self.worlds[np.asarray(worlds, dtype=bool)[self.worlds]]
        for w, values in self.assembly.world_values(due):
            self.parts[self._part[w]].factorize(values)

    def solve(self, b: np.ndarray) -> np.ndarray:
        """``A^-1 b`` for ``b`` of shape ``(f, k)``, world by world."""
        out = np.empty_like(b)
        for (lo, hi), part in zip(self.ranges, self.parts, strict=True):
            out[lo:hi] = part.solve(np.ascontiguousarray(b[lo:hi]))
        return out

    def _by_part(self, dof: np.ndarray) -> Iterator[tuple[int, np.ndarray]]:
        """The entries on each part's DOFs: ``(part, entries)`` for the parts that have some (the
        entries sorted by part once: a mask per world cost worlds x entries, 1.6 s of a 7.8 s step
        for 768 Diamonds on the 2-core VM)."""
        part = np.searchsorted(np.array([lo for lo, _ in self.ranges]), dof, side="right") - 1
        order = np.argsort(part, kind="stable")
        held = part[order]
        bounds = np.searchsorted(held, np.arange(len(self.parts) + 1))
        for p in np.flatnonzero(np.diff(bounds)):
            yield int(p), order[bounds[p]:bounds[p + 1]]

    def forward(self, dof: np.ndarray, column: np.ndarray, value: np.ndarray, columns: int) -> sp.csc_matrix:
        """``Z`` of :meth:`CholmodFactor.forward`, each world's rows from its own factor (a
        column's entries lie in one world: a row is one world's)."""
        rows, cols, vals = [np.zeros(0, np.int64)], [np.zeros(0, np.int64)], [np.zeros(0)]
        for p, mine in self._by_part(dof):
            lo = self.ranges[p][0]
            used, local = np.unique(column[mine], return_inverse=True)  # the world's columns only
            z = self.parts[p].forward(dof[mine] - lo, local, value[mine], len(used)).tocoo()
            rows.append(z.row + lo)
            cols.append(used[z.col])
            vals.append(z.data)
        return sp.csc_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                             shape=(self.size, columns))

    def gram(self, dof: np.ndarray, column: np.ndarray, value: np.ndarray, columns: int) -> np.ndarray:
        """``Z^T Z`` of :meth:`CholmodFactor.gram`, world by world: the worlds do not couple."""
        out = np.zeros((columns, columns))
        for used, block in self.gram_parts(dof, column, value, columns):
            out[np.ix_(used, used)] = block
        return out

    def gram_parts(self, dof: np.ndarray, column: np.ndarray, value: np.ndarray,
                   columns: int) -> Iterator[tuple[np.ndarray, np.ndarray]]:
        """``Z^T Z`` by its diagonal blocks, the others being 0: ``(used, block)`` per world that has
        entries, ``used`` its columns (ascending), ``block`` ``(len(used), len(used))``. The whole
        dense ``Z^T Z`` of 1024 Diamonds' rows is about 7000 x 7000."""
        for p, mine in self._by_part(dof):
            used, local = np.unique(column[mine], return_inverse=True)  # the world's columns only
            yield used, self.parts[p].gram(dof[mine] - self.ranges[p][0], local, value[mine], len(used))


FACTORIZATIONS = {"cholmod": CholmodFactor, "superlu": SuperLUFactor}


def solve_dofs(factor: CholmodFactor | WorldsCholmod | SuperLUFactor, flat: np.ndarray) -> np.ndarray:
    """``A^-1`` applied to ``flat`` ``(k, 3 n)`` over the model's DOFs: gather the free DOFs,
    solve, scatter back; fixed DOFs get 0."""
    free = factor.assembly.free
    out = np.zeros_like(flat)
    out[:, free] = factor.solve(np.ascontiguousarray(flat[:, free].T)).T
    return out
