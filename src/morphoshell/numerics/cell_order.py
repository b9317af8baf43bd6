"""The KKT unknowns in cell order, where every cell's share is one contiguous stretch.

The certified Newton system K
(:meth:`morphoshell.numerics.discretisation.Discretisation.newton_system`) is assembled from one
dense block per cell.  In the NLP's order, x = [r_free, ψ_free, f_s] and then λ, a cell's unknowns
lie in four separate stretches.  Every nonzero of K was then placed by an index list built in NumPy
and handed to CasADi, whose cost per entry and per list made the sparsity
pattern and the gathers a large part of a small mesh's cold solve.  In cell order

    u = [cell 0 | cell 1 | … | cell N−1 | r, ψ at the last node],
    cell c = [r, ψ at its first node, r at its S − 1 interior points, ψ there,
              f_s at its S Gauss points, λ of its S constraints]   (4S entries),

cell c's local slots are u[4S c + OFFSETS] with the same offsets for every
cell (its last node's r, ψ are the next cell's first two entries).  So every
pattern and index of the assembly is periodic in the cells: a build cuts them,
by a few CasADi slices, from one table per power of two of cells, made once
per process in NumPy (:func:`assembly`), and the cells' unknowns are a gather
of u.  The fixed r, ψ at a pole
are entries of u too, the first or last two; one slice drops them from K.

The order is a symmetric permutation of the NLP's, so the system has the
same solution and inertia.  Its LDLᵀ factorisation differs only in round-off.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property, lru_cache

import casadi as ca
import numpy as np

__all__ = ["CellOrder", "Assembly", "assembly", "offsets"]


def offsets(S: int) -> np.ndarray:
    """Where a cell's local slots sit in u, relative to its first entry 4S c.

    Local slots in the cell kernels' order: r at the cell's S + 1 points, ψ
    there, f_s at its S Gauss points, then its S multipliers λ.  The last
    point's r, ψ are at 4S and 4S + 1: the next cell's first node.
    """
    b = 4 * S
    inner = np.arange(1, S)
    return np.concatenate([[0], 1 + inner, [b], [1], S + inner, [b + 1],
                           2 * S + np.arange(S), 3 * S + np.arange(S)]).astype(np.int64)


@dataclass(frozen=True)
class CellOrder:
    """Cell order u of the unknowns x and multipliers λ of a layout (module docstring).

    ``u[lo:hi]`` are the Newton system's unknowns; the first two entries of u
    (start pole) or the last two (end pole) are fixed there.
    """

    cells: int
    stages: int
    start_pole: bool
    end_pole: bool

    @property
    def size(self) -> int:
        """Entries of u: 4S per cell and the last node's r, ψ."""
        return 4 * self.stages * self.cells + 2

    @property
    def lo(self) -> int:
        """First entry of u that is an unknown of the Newton system (2 after a start pole)."""
        return 2 * self.start_pole

    @property
    def hi(self) -> int:
        """One past the last entry of u that is an unknown (2 fewer before an end pole)."""
        return self.size - 2 * self.end_pole

    @cached_property
    def positions(self) -> tuple[np.ndarray, np.ndarray]:
        """(positions of x's entries in u, positions of λ's)."""
        S, cells, b = self.stages, self.cells, 4 * self.stages
        first = b * np.arange(cells)[:, None]
        l = np.arange(S)[None, :]
        r = np.append(first + np.where(l == 0, 0, 1 + l), b * cells).ravel()
        psi = np.append(first + np.where(l == 0, 1, S + l), b * cells + 1).ravel()
        free = slice(int(self.start_pole), len(r) - int(self.end_pole))
        x = np.concatenate([r[free], psi[free], (first + 2 * S + l).ravel()])
        return x, (first + 3 * S + l).ravel()

    def pack(self, x: np.ndarray, lam: np.ndarray, pole_values: tuple) -> np.ndarray:
        """u from x, λ; the poles' fixed r, ψ (r, ψ at a start pole, ψ at an end pole)
        from ``pole_values``."""
        u = np.empty(self.size)
        px, pl = self.positions
        u[px], u[pl] = x, lam
        if self.start_pole:
            u[:2] = pole_values[:2]
        if self.end_pole:
            u[-2:] = pole_values[0], pole_values[2]
        return u

    def unpack(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(x, λ) from u."""
        px, pl = self.positions
        return u[px], u[pl]

    def padded(self, step):
        """A step of u[lo:hi] (CasADi) as a step of u: zeros at the poles' fixed entries."""
        zero = ca.MX if isinstance(step, ca.MX) else ca.DM
        return ca.vertcat(zero(self.lo, 1), step, zero(self.size - self.hi, 1))


#: Cells of the smallest assembly table (:func:`_table`); tables up to LARGEST_TABLE cells are
#: kept, one per power of two; a larger mesh gets its indices made for it alone, not kept
#: (as lists, about what the assembly cost before cell order).  A table is made once per
#: process, in time linear in its cells, and holds about 25 bytes per nonzero of the
#: system it serves (tens of MB at LARGEST_TABLE cells), which bounds the size kept.
SMALLEST_TABLE = 16
LARGEST_TABLE = 4096


@dataclass(frozen=True)
class Assembly:
    """Where the Newton system's entries come from, for one cell order (:func:`assembly`).

    ``local``: u's entries of each cell's L = 4S + 2 local slots, cell by cell
    (a gather of u gives the kernels' (z, λ) input).  ``K``: the sparsity of
    the system; its nonzero k is the cells' triangles' value ``first[k]``
    (values stacked a cell at a time, n_tri + 1 per cell), after the values of
    the entries two cells share are summed into the earlier cell's:
    ``pairs`` = (a, b), value b added to value a.  ``rhs_first``,
    ``rhs_pairs``: the same for u[lo:hi] from the cells' L + 1 local values.
    ``x_mask``: 1 at x's entries of u[lo:hi], 0 at λ's.  Index vectors are DM
    columns (integers as floats), for ``MX.get_nz``.
    """

    local: ca.DM
    K: ca.Sparsity
    first: ca.DM
    pairs: tuple[ca.DM, ca.DM]
    rhs_first: ca.DM
    rhs_pairs: tuple[ca.DM, ca.DM]
    x_mask: ca.DM


def assembly(order: CellOrder) -> Assembly:
    """The :class:`Assembly` of ``order``, cut from a kept table of at least as many cells.

    Every index is periodic in the cells: a mesh's indices are the first
    cells' of a longer mesh's (its pairs those of its inner nodes), and the
    poles' fixed entries are u's first or last two.  So a build cuts them from one
    table per power of two of cells (:func:`_table`) by a few slices in
    CasADi, instead of handing it lists of every nonzero (on small meshes the
    pattern and index lists cost more than the rest of the system's build).  Above
    :data:`LARGEST_TABLE` cells the indices are made for the mesh alone, as such lists.
    """
    S, cells = order.stages, order.cells
    if cells > LARGEST_TABLE:
        return _made(S, cells, order.lo, order.hi)
    M = SMALLEST_TABLE
    while M < cells:
        M *= 2
    t = _table(S, M)
    part = slice(order.lo, order.hi)
    K = ca.DM(t.K, t.first)[part, part]     # (K's pattern and value numbers cut at once)
    return Assembly(
        local=t.local[:(4 * S + 2) * cells], K=K.sparsity(), first=K.get_nz(False, ca.Slice()),
        pairs=_cut(t.pairs, cells, M), rhs_first=t.rhs_first[part],
        rhs_pairs=_cut(t.rhs_pairs, cells, M), x_mask=t.x_mask[part])


def _cut(pairs: tuple[ca.DM, ca.DM], cells: int, M: int) -> tuple[ca.DM, ca.DM]:
    """The ``pairs`` of a table of M cells that a mesh of ``cells`` has: the same number at
    each of its cells − 1 inner nodes, node after node (the last node's are the next
    cell's)."""
    k = ca.Slice(0, (cells - 1) * (pairs[0].numel() // (M - 1)))
    return pairs[0].get_nz(False, k), pairs[1].get_nz(False, k)


@lru_cache(maxsize=None)
def _table(S: int, M: int) -> Assembly:
    """The :class:`Assembly` of M cells of S stages without poles: the table
    :func:`assembly` cuts meshes of up to M cells from."""
    return _made(S, M)


def _made(S: int, M: int, lo: int = 0, hi: int | None = None) -> Assembly:
    """The :class:`Assembly` of M cells of S stages for the unknowns u[lo:hi], from
    :func:`_indices`."""
    i = _indices(S, M, lo, hi)
    n = (4 * S * M + 2 if hi is None else hi) - lo
    return Assembly(_column(i["local"]), _pattern(i["key"], n), _column(i["first"]),
                    _columns(i["pairs"]), _column(i["rhs_first"]), _columns(i["rhs_pairs"]),
                    _column(i["x_mask"]))


def _indices(S: int, M: int, lo: int = 0, hi: int | None = None) -> dict[str, np.ndarray]:
    """The assembly indices of M cells of S stages for the unknowns u[lo:hi], in NumPy.

    Each cell's slots (and pairs of slots, for K) are placed in u, their
    values numbered cell after cell; a stable sort by position groups the
    (at most two) values of each entry, the earlier cell's first, and the
    entries of two values give the pairs to sum.  ``key``: K's nonzeros
    as col (hi − lo) + row, sorted (compressed columns).  Linear in M (the
    same indices from Kronecker and sparse products in CasADi grew faster);
    handing them to CasADi as lists is most of a table's cost.
    """
    b, L = 4 * S, 4 * S + 2
    n_tri = L * (L + 1) // 2
    hi = b * M + 2 if hi is None else hi
    n = hi - lo
    off = offsets(S)
    c = np.arange(M)[:, None, None]
    local = (c[:, :, 0] * b + off[None, :]).ravel()
    _, rhs_first, rhs_pairs = _sources(local, (c[:, :, 0] * (L + 1) + np.arange(L)).ravel())
    ku, lu = np.triu_indices(L)
    tri = np.zeros((L, L), dtype=np.int64)
    tri[ku, lu] = tri[lu, ku] = np.arange(n_tri)
    rows = np.broadcast_to(c * b + off[None, :, None], (M, L, L)).ravel()
    cols = np.broadcast_to(c * b + off[None, None, :], (M, L, L)).ravel()
    src = np.broadcast_to(c * (n_tri + 1) + tri[None], (M, L, L)).ravel()
    if lo > 0 or hi < b * M + 2:        # (a pole's fixed entries)
        keep = (rows >= lo) & (rows < hi) & (cols >= lo) & (cols < hi)
        rows, cols, src = rows[keep], cols[keep], src[keep]
    key, first, pairs = _sources((cols - lo) * n + rows - lo, src)
    mask = np.ones((M, b))
    mask[:, 3 * S:] = 0.0
    # (rhs_pairs may name u's entries outside [lo, hi): summed into values nothing reads)
    return {"local": local, "key": key, "first": first, "pairs": pairs,
            "rhs_first": rhs_first[lo:hi], "rhs_pairs": rhs_pairs,
            "x_mask": np.append(mask.ravel(), [1.0, 1.0])[lo:hi]}


def _pattern(key: np.ndarray, n: int) -> ca.Sparsity:
    """The n × n sparsity of the nonzeros ``key`` = col n + row, sorted."""
    colind = np.concatenate([[0], np.cumsum(np.bincount(key // n, minlength=n))])
    return ca.Sparsity(n, n, colind.tolist(), (key % n).tolist())


def _column(v: np.ndarray) -> ca.DM:
    """``v`` as a DM column (lists convert three times faster than arrays)."""
    return ca.DM(np.asarray(v, dtype=float).tolist())


def _columns(pair: tuple[np.ndarray, np.ndarray]) -> tuple[ca.DM, ca.DM]:
    """Both index vectors of ``pair`` as DM columns (:func:`_column`)."""
    return _column(pair[0]), _column(pair[1])


def _sources(key: np.ndarray, src: np.ndarray) -> tuple:
    """(keys, first, (a, b)): the distinct keys, sorted, each one's first value (``src``,
    given cell after cell: a stable sort keeps the earlier cell's first), and for the keys
    of two values the first (a) and the second (b), each a once, ordered by a (cell
    after cell)."""
    order = np.argsort(key, kind="stable")
    key, src = key[order], src[order]
    head = np.empty(len(key), dtype=bool)
    head[:1] = True
    np.not_equal(key[1:], key[:-1], out=head[1:])
    first = src[head]
    twice = np.flatnonzero(~head)
    a, b = src[twice - 1], src[twice]
    by_a = np.argsort(a, kind="stable")
    a, b = a[by_a], b[by_a]
    # (K's entries (i, j) and (j, i) share their values: each pair once)
    once = np.ones(len(a), dtype=bool)
    np.not_equal(a[1:], a[:-1], out=once[1:])
    return key[head], first, (a[once], b[once])
