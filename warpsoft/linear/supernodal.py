"""Triangular solves with a sparse Cholesky factor as a few parallel levels (for the device).

``A = P^T L L^T P`` (CHOLMOD's supernodal factor). ``A^-1 b`` is two triangular solves, a
forward ``L y = P b`` and a backward ``L^T x' = y``, ``x = P^T x'``. Solved one column of ``L`` at a
time they are thousands of dependent steps; here they are cut into levels of independent work:

- **Supernodes.** Consecutive columns of ``L`` with nested patterns (column ``j`` has the pattern
  of column ``j + 1`` plus row ``j + 1``; CHOLMOD's relaxed supernodes store such dense panels)
  form a supernode ``S = [a, b)``: a dense lower triangle ``T = L_SS`` and, below it, a dense
  panel ``L_RS`` on the rows ``R`` that all its columns share.
- **Forward, from the leaves.** ``y_S = T^-1 (b_S - G y_J)``, where ``G = L_{S,J}`` holds the
  entries of ``S``'s rows left of ``a``, in the columns ``J`` of its descendants. With ``T^-1``
  formed, each row of ``S`` is one sum: ``y_i = sum_k (T^-1)_ik b_k - sum_j (T^-1 G)_ij y_j``,
  independent of the other rows of ``S``. A supernode's forward level is one more than its
  children's highest; the rows of one level read only the rows of lower ones.
- **Backward, from the root.** ``x_S = T^-T (y_S - L_RS^T x_R)``: ``x_i = sum_k (T^-T)_ik y_k -
  sum_r (T^-T L_RS^T)_ir x_r``, ``R`` in the ancestors. A supernode's backward level is its depth.

A level is then one kernel launch over its rows (``kernels/linear/factors.py``), each row a
sum over two lists of entries: one read from the solve's input, one from the rows already
solved. The Diamond's factors (3048-5157 free DOFs) have 9-16 levels in nested dissection
(16-53 in CHOLMOD's AMD ordering); their programs hold 2.4-3 times the entries of ``L`` (``T^-1
G`` fills the rows of a supernode with the union of their patterns), against the ``N^2`` of a
dense inverse (60-90 times fewer).

**Panels.** The rows of a supernode read the same columns: in the backward solve all of ``R``,
in the forward one the union of their patterns, which grows down the supernode (row ``i`` of
``T^-1 G`` holds the patterns of rows ``0..i``). :meth:`Supernodal.panels` cuts each supernode
into panels of a few consecutive rows, each a dense ``(rows, columns)`` block over the columns its
last row reads (zeros where an earlier row reads none, and right of the triangle's diagonal),
whose columns are listed once and whose operand rows are read once for the panel's rows. For
4-row panels of two Diamonds that is 1.03-1.04 times the values of a task a row, and 3.6 times
fewer columns listed and operand rows read (H200, 1024 Diamonds: ``P^-1`` 4.90 -> 3.45 ms).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import scipy.sparse as sp


class _Levelled:
    """A solve cut into levels: ``level`` ``(tasks,)`` each task's, from 0."""

    level: np.ndarray

    @property
    def levels(self) -> int:
        """Launches: the last level + 1 (0 with no task)."""
        return int(self.level.max()) + 1 if len(self.level) else 0


@dataclass
class Program(_Levelled):
    """One triangular solve as levels of rows, each row ``out[row] = sum(val * inp[col]) over
    its first part + sum(val * out[col]) over its second`` (the second part's values negated).

    Attributes (positions are those of ``L``'s columns):
        row: ``(n,)`` the position each task writes, tasks sorted by level.
        level: ``(n,)`` each task's level (0 first).
        start: ``(n, 3)`` each task's entries: ``start[t, 0]:start[t, 1]`` read the input,
            ``start[t, 1]:start[t, 2]`` the output.
        col: ``(entries,)`` the position each entry reads.
        val: ``(entries,)`` its coefficient.
    """

    row: np.ndarray
    level: np.ndarray
    start: np.ndarray
    col: np.ndarray
    val: np.ndarray

    def run(self, b: np.ndarray) -> np.ndarray:
        """The solve on the host, level by level, for ``b`` ``(n,)`` or ``(n, k)`` (the reference of
        the kernels, in the tests)."""
        out = np.zeros_like(b, dtype=np.float64)
        for lev in range(self.levels):
            for t in np.flatnonzero(self.level == lev):
                s0, s1, s2 = self.start[t]
                out[self.row[t]] = (self.val[s0:s1] @ b[self.col[s0:s1]]
                                    + self.val[s1:s2] @ out[self.col[s1:s2]])
        return out


@dataclass
class Panels(_Levelled):
    """One triangular solve as levels of panels: a panel is ``height`` consecutive rows of one
    supernode, from ``row``, that read the same columns: ``out[row + i] = sum_q val[i, q]
    src_q[col_q]`` over its columns ``q``, the first ``reads[0]`` read from the input, the next
    ``reads[1]`` from the output (rows solved at earlier levels). A column is listed once for the
    panel's rows (a task a row lists it once a row) and its operand is read once for them.

    Attributes (positions are those of ``L``'s columns; ``panels`` of them, sorted by level):
        level: ``(panels,)``.
        row: ``(panels,)`` the first row each writes.
        height: ``(panels,)`` its rows.
        reads: ``(panels, 2)`` its input and output columns.
        col_start: ``(panels,)`` its first column in ``col`` (the inputs', then the outputs').
        val_start: ``(panels,)`` its first value in ``val``: ``(height, columns)``, by rows.
        col: ``(columns,)`` the position each column reads.
        val: ``(values,)`` the coefficients.
    """

    level: np.ndarray
    row: np.ndarray
    height: np.ndarray
    reads: np.ndarray
    col_start: np.ndarray
    val_start: np.ndarray
    col: np.ndarray
    val: np.ndarray

    def run(self, b: np.ndarray) -> np.ndarray:
        """The solve on the host, level by level, for ``b`` ``(n,)`` or ``(n, k)`` (the kernels'
        reference, in the tests)."""
        out = np.zeros_like(b, dtype=np.float64)
        for t in range(len(self.level)):  # (sorted by level: a panel reads earlier levels' rows)
            h, (ni, no), c0, v0 = self.height[t], self.reads[t], self.col_start[t], self.val_start[t]
            V = self.val[v0:v0 + h * (ni + no)].reshape(h, ni + no)
            out[self.row[t]:self.row[t] + h] = (V[:, :ni] @ b[self.col[c0:c0 + ni]]
                                                + V[:, ni:] @ out[self.col[c0 + ni:c0 + ni + no]])
        return out


class Supernodal:
    """The supernodes and levels of a factor's pattern, found once; :meth:`programs` then turns
    the factor's values (the same pattern: a refactorization) into the two solves.

    Args:
        L: the lower Cholesky factor ``(n, n)``, CSC with sorted indices.
    """

    def __init__(self, L: sp.csc_matrix):
        n = L.shape[0]
        self.n, self.indptr, self.indices = n, L.indptr.copy(), L.indices.copy()
        count = np.diff(L.indptr)
        if n and (count.min() < 1 or not np.array_equal(L.indices[L.indptr[:-1]], np.arange(n))):
            raise ValueError("Supernodal: every column of L needs its diagonal entry first")
        parent = np.full(n, -1)
        below = count > 1
        parent[below] = L.indices[L.indptr[:-1][below] + 1]  # the elimination tree
        cols = np.arange(n)
        chained = (parent[:-1] == cols[1:]) & (count[:-1] == count[1:] + 1)  # column j+1 continues j's panel
        self.first = np.flatnonzero(np.concatenate([[True], ~chained]))  # (supernodes,) first column of each
        self.end = np.append(self.first[1:], n)
        self.of = np.repeat(np.arange(len(self.first)), self.end - self.first)  # each column's supernode
        last = self.end - 1
        sparent = np.where(parent[last] >= 0, self.of[np.maximum(parent[last], 0)], -1)
        ns = len(self.first)
        up, forward, backward = sparent.tolist(), [0] * ns, [0] * ns  # (Python lists: a scalar loop)
        for s in range(ns):  # children come before parents: a level one above the highest child's
            p = up[s]
            if p >= 0:
                forward[p] = max(forward[p], forward[s] + 1)
        for s in range(ns - 1, -1, -1):  # parents come after children: a level one below the parent's
            if up[s] >= 0:
                backward[s] = backward[up[s]] + 1
        self.forward_level = np.array(forward, dtype=np.int64)
        self.backward_level = np.array(backward, dtype=np.int64)
        # the rows left of each supernode (its G: the entries of its rows in earlier columns), read
        # by rows: each entry's place in L's (column-ordered) data, so that G is gathered from it
        place = sp.csc_matrix((np.arange(1, len(self.indices) + 1), self.indices, self.indptr), shape=(n, n)).tocsr()
        place.sort_indices()
        row = np.repeat(np.arange(n), np.diff(place.indptr))
        s = self.of[row]
        left = place.indices < self.first[s]
        row, col, s = row[left], place.indices[left], s[left]
        src = place.data[left] - 1
        within = row - self.first[s]  # the entry's row in its supernode
        # J per supernode: its distinct columns, in order; an entry's first occurrence is its column's
        # top row (the entries come by rows), from which the column is in the rows' pattern
        key, top, index = np.unique(s * n + col, return_index=True, return_inverse=True)
        per = np.bincount(key // n, minlength=ns)  # |J| a supernode
        dest = within * per[s] + (index - _starts(per)[s])
        cuts = np.cumsum(per)[:-1]
        entries = np.cumsum(np.bincount(s, minlength=ns))[:-1]
        width = self.end - self.first
        steps = np.arange(width.max(initial=0))[:, None]
        # per supernode: J, its rows' patterns in J, G's places in L and in (w, |J|)
        self.left = [(J, steps[:w] >= t, g, d)
                     for J, t, w, g, d in zip(np.split((key % n).astype(place.indices.dtype), cuts),
                                              np.split(within[top], cuts), width.tolist(),
                                              np.split(narrow(src), entries), np.split(narrow(dest), entries),
                                              strict=True)]
        self._below = None  # per supernode: R and the places of L_RS^T in L's data (made at the first solves)
        self._layouts = {}  # rows -> the panels, each value its place in the supernode rows (_panel_layout)

    @property
    def levels(self) -> tuple[int, int]:
        """The forward and backward solves' levels."""
        return int(self.forward_level.max()) + 1, int(self.backward_level.max()) + 1

    def _solves(self, L: sp.csc_matrix):
        """Per supernode ``s = [a, b)`` of ``L`` (its pattern the one analysed): ``(s, a, b, T^-1, J,
        pattern, -T^-1 G, R, -T^-T L_RS^T)``, the forward solve's rows reading ``J`` (``pattern``:
        ``(w, |J|)``, the columns each row reads) and the backward's ``R``."""
        if not (np.array_equal(L.indptr, self.indptr) and np.array_equal(L.indices, self.indices)):
            raise ValueError("Supernodal: the factor's pattern changed since it was analysed")
        data = L.data
        width = self.end - self.first
        # every supernode's triangle T inverted, a stack per width (one LAPACK call a width, not
        # one a supernode: 10k triangular solves took 1.5 s of 5.7 for 32 Diamonds on the CPU VM);
        # column j of a supernode starts with T's column j: T[i, j] = data[indptr[a + j] + i - j]
        inverses = [None] * len(width)
        for w in np.unique(width):
            group = np.flatnonzero(width == w)
            i, j = np.tril_indices(w)
            T = np.zeros((len(group), w, w))
            T[:, i, j] = data[self.indptr[self.first[group][:, None] + j] + (i - j)]
            for s, inverse in zip(group, np.linalg.inv(T), strict=True):
                inverses[s] = inverse
        if self._below is None:  # L_RS^T (w, |R|): the rows R below each triangle, after T's part of its columns
            self._below = []
            for a, b in zip(self.first.tolist(), self.end.tolist(), strict=True):
                w, start = b - a, self.indptr[a]
                R = self.indices[start + w:self.indptr[a + 1]]
                self._below.append((R, self.indptr[a:b][:, None] + (w - np.arange(w))[:, None] + np.arange(len(R))))
        for s, (a, b, (R, below), (J, pattern, src, dest)) in enumerate(zip(
                self.first.tolist(), self.end.tolist(), self._below, self.left, strict=True)):
            Tinv = inverses[s]
            G = np.zeros((b - a, len(J)))
            G.flat[dest] = data[src]
            yield s, a, b, Tinv, J, pattern, -(Tinv @ G), R, -(Tinv.T @ data[below])

    def programs(self, L: sp.csc_matrix) -> tuple[Program, Program]:
        """The forward and backward programs of ``L`` (its pattern the one analysed): a task a row."""
        parts = {"forward": [], "backward": []}  # per supernode: (row, part, col, val) of its entries
        for _, a, b, Tinv, J, pattern, M, R, N in self._solves(L):
            w = b - a
            (ti, tj), (ui, uj) = np.tril_indices(w), np.triu_indices(w)  # by rows
            mi, mj = np.nonzero(pattern)  # by rows
            # forward: y_i = (T^-1 b_S)_i - (T^-1 G y_J)_i
            parts["forward"].append((np.concatenate([a + ti, a + mi]),
                                     np.concatenate([np.zeros(len(ti), dtype=np.int64),
                                                     np.ones(len(mi), dtype=np.int64)]),
                                     np.concatenate([a + tj, J[mj]]), np.concatenate([Tinv[ti, tj], M[mi, mj]])))
            # backward: x_i = (T^-T y_S)_i - (T^-T L_RS^T x_R)_i
            parts["backward"].append((np.concatenate([a + ui, np.repeat(np.arange(a, b), len(R))]),
                                      np.concatenate([np.zeros(len(ui), dtype=np.int64),
                                                      np.ones(w * len(R), dtype=np.int64)]),
                                      np.concatenate([a + uj, np.tile(R, w)]),
                                      np.concatenate([Tinv.T[ui, uj], N.ravel()])))
        forward_row, backward_row = (np.repeat(lev, self.end - self.first) for lev in (self.forward_level,
                                                                                       self.backward_level))
        return _program(parts["forward"], forward_row), _program(parts["backward"], backward_row)

    def panels(self, L: sp.csc_matrix, rows: int) -> tuple[Panels, Panels]:
        """The forward and backward solves of ``L`` (its pattern the one analysed) as panels of at
        most ``rows`` consecutive rows of a supernode, each panel's columns listed once."""
        values = self.panel_values(L, rows)
        return tuple(replace(p, val=v) for p, v in zip(self._panel_layout(rows), values, strict=True))

    def panel_values(self, L: sp.csc_matrix, rows: int) -> tuple[np.ndarray, np.ndarray]:
        """The values of :meth:`panels` alone, in its order (a refactorization's, the panels being
        the same): each supernode's forward rows ``[T^-1, -T^-1 G]`` and backward rows ``[T^-T,
        -T^-T L_RS^T]`` laid out whole, then gathered where the panels read them (the places are
        found once per ``rows``; a Diamond's refactorization on the CPU VM, 3048 DOFs: 23 -> 15 ms)."""
        forward, backward = self._panel_layout(rows)
        F, B = np.empty(self._rows_size[0]), np.empty(self._rows_size[1])
        for s, a, b, Tinv, J, _, M, R, N in self._solves(L):
            w = b - a
            f = F[self._rows_at[0][s]:self._rows_at[0][s] + w * (w + len(J))].reshape(w, w + len(J))
            f[:, :w], f[:, w:] = Tinv, M
            g = B[self._rows_at[1][s]:self._rows_at[1][s] + w * (w + len(R))].reshape(w, w + len(R))
            g[:, :w], g[:, w:] = Tinv.T, N
        return F[forward.val], B[backward.val]

    def _panel_layout(self, rows: int) -> tuple[Panels, Panels]:
        """The panels of ``rows`` rows (:meth:`panels`), each value the place it is read from in
        :meth:`panel_values`' supernode rows (found once per ``rows``). A supernode ``[a, b)``'s
        panel of rows ``i0..i1``: forward, it reads the input's ``a..a + i1`` (``T^-1`` lower: zeros
        right of each row's diagonal) and the columns of ``J`` its last row reads (the patterns
        grow down a supernode: the earlier rows' are inside, with zeros elsewhere); backward, the
        input's ``a + i0..b`` (``T^-T`` upper) and all of ``R``."""
        if rows < 1:
            raise ValueError(f"Supernodal: a panel needs at least one row, got {rows}")
        if rows in self._layouts:
            return self._layouts[rows]
        width = self.end - self.first
        left = np.array([len(j[0]) for j in self.left], dtype=np.int64)  # |J| a supernode
        below = np.diff(self.indptr)[self.first] - width  # |R|
        at = [np.concatenate([[0], np.cumsum(width * (width + left))]),
              np.concatenate([[0], np.cumsum(width * (width + below))])]
        per = -(-width // rows)  # panels a supernode
        s = np.repeat(np.arange(len(width)), per)  # each panel's supernode
        i0 = (np.arange(len(s)) - np.repeat(_starts(per), per)) * rows
        i1 = np.minimum(i0 + rows, width[s])
        a, w = self.first[s], width[s]
        # forward: the columns of J the last row reads (its pattern's), where in J, and each panel's count
        last = [self.left[k][1][r - 1] for k, r in zip(s.tolist(), i1.tolist(), strict=True)]
        hit = np.flatnonzero(np.concatenate(last)) if last else np.zeros(0, dtype=np.int64)
        hit_panel = np.searchsorted(np.cumsum(left[s]), hit, side="right")
        in_J = hit - _starts(left[s])[hit_panel]
        J = np.concatenate([j[0] for j in self.left]) if self.left else np.zeros(0, dtype=np.int64)
        forward = _panels(self.forward_level[s], a + i0, i1 - i0, (a, i1), (J[_starts(left)[s[hit_panel]] + in_J],
                          np.bincount(hit_panel, minlength=len(s))), (np.zeros(len(s), dtype=np.int64),
                          w[hit_panel] + in_J), at[0][s], i0, w + left[s])
        # backward: the rows R below each supernode's triangle, read whole
        R = self.indices[_ranges(self.indptr[a] + w, below[s])]
        backward = _panels(self.backward_level[s], a + i0, i1 - i0, (a + i0, w - i0), (R, below[s]),
                           (i0, _ranges(w, below[s])), at[1][s], i0, w + below[s])
        self._rows_at, self._rows_size = at, (int(at[0][-1]), int(at[1][-1]))
        self._layouts[rows] = forward, backward
        return self._layouts[rows]


def _starts(counts: np.ndarray) -> np.ndarray:
    """Where each of ``counts`` consecutive runs starts (an exclusive cumulative sum, int64)."""
    out = np.zeros(len(counts), dtype=np.int64)
    np.cumsum(counts[:-1], out=out[1:])
    return out


def _ranges(starts: np.ndarray, counts: np.ndarray) -> np.ndarray:
    """The runs ``starts[i] + arange(counts[i])`` one after another."""
    counts = np.asarray(counts, dtype=np.int64)
    return np.repeat(np.asarray(starts, dtype=np.int64) - _starts(counts), counts) + np.arange(int(counts.sum()))


def _panels(level, row, height, inputs: tuple, outputs: tuple, places: tuple, base, i0, stride) -> Panels:
    """:class:`Panels` sorted by level (stable), of per-panel ``level``, first ``row`` and
    ``height``; ``inputs`` ``(first, count)``: each reads ``count`` input columns from ``first``;
    ``outputs`` ``(columns, count)``: the output columns, all panels' one after another, and each
    one's count; ``places`` ``(first, places)``: in its supernode's rows, the place of its input
    columns (``count`` from ``first``) and of its output columns (one after another). Its row
    ``i0 + r``'s value of column ``q`` is read at ``base + (i0 + r) stride + place_q``."""
    (in_first, n_in), (out_col, n_out) = inputs, outputs
    n_in, n_out = np.asarray(n_in, dtype=np.int64), np.asarray(n_out, dtype=np.int64)
    columns = n_in + n_out
    start = _starts(columns)  # (unsorted) each panel's first column, its inputs', then its outputs'
    col, place = np.empty(int(columns.sum()), dtype=np.int64), np.empty(int(columns.sum()), dtype=np.int64)
    inside, outside = _ranges(start, n_in), _ranges(start + n_in, n_out)
    col[inside], place[inside] = _ranges(in_first, n_in), _ranges(places[0], n_in)
    col[outside], place[outside] = out_col, places[1]
    order = np.argsort(level, kind="stable")
    listed = _ranges(start[order], columns[order])
    col, place, height = col[listed], place[listed], np.asarray(height, dtype=np.int64)[order]
    col_start = _starts(columns[order])
    of = np.repeat(order, height)  # each panel row's panel, in order
    first = base[of] + _ranges(i0[order], height) * stride[of]  # its row's first place
    val = np.repeat(first, columns[of]) + place[_ranges(np.repeat(col_start, height), columns[of])]
    return Panels(np.asarray(level, dtype=np.int64)[order], np.asarray(row, dtype=np.int64)[order], height,
                  np.stack([n_in[order], n_out[order]], axis=1).reshape(-1, 2), col_start,
                  _starts(height * columns[order]), narrow(col), narrow(val))


def narrow(index: np.ndarray) -> np.ndarray:
    """``index`` (integers, at least 0) as int32 where they fit, else int64: a worker keeps every
    block's panels' places (:meth:`Supernodal.panel_values`), 4096 Diamonds of them on the H200's
    host (docs/performance.md)."""
    fits = index.size == 0 or int(index.max()) <= np.iinfo(np.int32).max
    return index.astype(np.int32 if fits else np.int64, copy=False)


def _program(parts: list, level: np.ndarray) -> Program:
    """The tasks (one per row) sorted by level (stable: within a level, by row), each row's entries
    (``parts``: per supernode, the ``(row, part, col, val)`` of its entries, part 0 read from the
    input, 1 from the output) laid out in that order, input first."""
    n = len(level)
    row, part, col, val = (np.concatenate([p[k] for p in parts]) for k in range(4))
    order = np.argsort(level, kind="stable")
    rank = np.empty(n, dtype=np.int64)
    rank[order] = np.arange(n)
    key = 2 * rank[row] + part
    by = np.argsort(key, kind="stable")  # within a (row, part), the columns keep their order
    count = np.bincount(key, minlength=2 * n).reshape(n, 2)
    ends = np.cumsum(count.sum(axis=1))
    start = np.stack([ends - count.sum(axis=1), ends - count[:, 1], ends], axis=1)
    return Program(order, level[order], start, col[by].astype(np.int64), val[by])


@dataclass
class Sliced:
    """A program's entries laid out for ``width`` threads reading side by side (sliced ELLPACK):
    the rows of each level, longest first, are cut into slices of ``width`` (the last of a level
    padded with empty rows); the ``j``-th entry of a slice's ``l``-th row lies at ``base + l +
    width j``, so that a warp's threads, a row each, read neighbouring numbers at each step. The
    rows of the levels marked ``contiguous`` keep their entries one after another (a level whose
    long rows are read by several threads each).

    Attributes:
        row: ``(tasks,)`` the position each task writes, -1 for the padding that fills a level's last
            slice (so that every world's slices start at a multiple of ``width``).
        level: ``(tasks,)`` each task's level, sorted.
        start: ``(tasks, 3)`` the task's first input entry, first output entry, end; its entries
            are ``width`` apart (1 in a contiguous level).
        place: ``(entries,)`` where each of the program's entries goes.
        size: the laid-out entries, padding included.
    """

    row: np.ndarray
    level: np.ndarray
    start: np.ndarray
    place: np.ndarray
    size: int


def sliced(p: Program, width: int, contiguous: np.ndarray) -> Sliced:
    """``p``'s entries in slices of ``width`` rows (``width = 1``: as they are), but for the levels
    where ``contiguous[level]``."""
    length = p.start[:, 2] - p.start[:, 0]
    together = contiguous[p.level] | (width == 1)
    order = np.lexsort((np.where(together, 0, -length), p.level))  # by level, then longest first
    level, length, together = p.level[order], length[order], together[order]
    counts = np.bincount(level, minlength=p.levels)
    firsts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    # each sliced level padded to whole slices: the rows' places among the tasks
    padded = np.where(contiguous[:len(counts)] | (width == 1), counts, -(-counts // width) * width)
    pad_first = np.concatenate([[0], np.cumsum(padded)[:-1]])
    rank = np.arange(len(order)) - firsts[level]  # within its level
    slot = pad_first[level] + rank
    lane = np.where(together, 0, rank % width)
    # a slice's room is width times its first (longest) row (the kernels read with a constant
    # step: a level's last slice keeps room for the padding); a contiguous row's, its length
    step = np.where(together, 1, width)
    head = together | (lane == 0)
    room = step * length
    base = np.zeros(len(order), dtype=np.int64)
    base[head] = np.concatenate([[0], np.cumsum(room[head])[:-1]])
    base = np.maximum.accumulate(np.where(head, base, 0)) + lane  # a slice's rows: its head's base
    tasks = int(padded.sum())
    row = np.full(tasks, -1, dtype=np.int64)
    row[slot] = p.row[order]
    start = np.zeros((tasks, 3), dtype=np.int64)
    parts = (p.start[order] - p.start[order][:, :1])  # 0, inputs, inputs + outputs
    start[slot] = base[:, None] + step[:, None] * parts
    levels = np.repeat(np.arange(len(counts)), padded)
    # entry e of row r (its j-th) goes to base_r + step_r j
    first_entry = p.start[order][:, 0]
    j = np.arange(int(length.sum())) - np.repeat(np.cumsum(length) - length, length)
    place = np.empty(len(p.val), dtype=np.int64)
    place[np.repeat(first_entry, length) + j] = np.repeat(base, length) + np.repeat(step, length) * j
    size = int(room[head].sum())
    return Sliced(row, levels, start, place, size)
