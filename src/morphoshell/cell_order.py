"""The KKT unknowns in cell order, where every cell's share is one contiguous stretch.

The certified Newton system K (:meth:`morphoshell.discretisation.Discretisation.newton_system`)
is assembled from one dense block per cell.  In the NLP's order,
x = [r_free, ψ_free, f_s] and then λ, a cell's unknowns lie in four separate
stretches.  Every nonzero of K was then placed by an index list built in NumPy
and handed to CasADi, at 40-80 ns an entry and 17 µs a list.  That cost a
25-node cold solve 0.9 ms of its 8.5 ms (sparsity pattern and gathers), and
12 800 nodes 0.45 s.  In cell order

    u = [cell 0 | cell 1 | … | cell N−1 | r, ψ at the last node],
    cell c = [r, ψ at its first node, r at its S − 1 interior points, ψ there,
              f_s at its S Gauss points, λ of its S constraints]   (4S entries),

cell c's local slots are u[4S c + OFFSETS] with the same offsets for every
cell (its last node's r, ψ are the next cell's first two entries).  So every
pattern and index of the assembly is a Kronecker product of one cell's,
cut by CasADi from one table per power of two of cells (:func:`assembly`),
and the cells' unknowns are a gather of u.  The fixed r, ψ at a pole
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
#: kept, one per power of two; larger meshes get a table of their own size, not kept.  A
#: table costs 2-5 ms at 16-64 cells, about 45 us a cell (S = 2) at thousands, and holds
#: about 25 bytes per nonzero of the system it serves: 40 MB (S = 2) and 80 MB (S = 3) at
#: 16 384 cells, a fraction of what a Newton system of that size takes itself.
SMALLEST_TABLE = 16
LARGEST_TABLE = 16384


@dataclass(frozen=True)
class Assembly:
    """Where the Newton system's entries come from, for one cell order (:func:`assembly`).

    ``local``: u's entries of each cell's L = 4S + 2 local slots, cell by cell
    (a gather of u gives the kernels' (z, λ) input).  ``K``: the sparsity of
    the system; its nonzero k sums the cells' triangles' entries ``first[k]``
    and ``second[k]`` (values stacked a cell at a time, n_tri + 1 per cell, the
    last a zero: a slot of one cell only takes that zero second).  ``rhs_first``,
    ``rhs_second``: the same for u[lo:hi] from the cells' L + 1 local values.
    ``x_mask``: 1 at x's entries of u[lo:hi], 0 at λ's.  Index vectors are DM
    columns (integers as floats), for ``MX.get_nz``.
    """

    local: ca.DM
    K: ca.Sparsity
    first: ca.DM
    second: ca.DM
    rhs_first: ca.DM
    rhs_second: ca.DM
    x_mask: ca.DM


def assembly(order: CellOrder) -> Assembly:
    """The :class:`Assembly` of ``order``, cut from a kept table of at least as many cells.

    Every index is periodic in the cells: a mesh's indices are the first
    cells' of a longer mesh's (but for the last node's second values, which
    would be the next cell's: clamped to the last cell's zero), and the poles'
    fixed entries are u's first or last two.  So a build cuts them from one
    table per power of two of cells (:func:`_table`) by a few slices in
    CasADi, instead of handing it lists of every nonzero (the pattern and
    index lists of a 25-node cold solve, 0.9 ms, cost more than the rest of
    the system's build).
    """
    S, cells = order.stages, order.cells
    M = SMALLEST_TABLE
    while M < cells:
        M *= 2
    t = _table(S, M) if M <= LARGEST_TABLE else _table.__wrapped__(S, cells)
    L = 4 * S + 2
    n_tri = L * (L + 1) // 2
    part = slice(order.lo, order.hi)
    K1, K2 = t.first[part, part], t.second[part, part]
    return Assembly(
        local=t.local[:cells * L], K=K1.sparsity(), first=K1.get_nz(False, ca.Slice()),
        second=ca.fmin(K2.get_nz(False, ca.Slice()), cells * (n_tri + 1) - 1),
        rhs_first=t.rhs_first[part], rhs_second=ca.fmin(t.rhs_second[part], cells * (L + 1) - 1),
        x_mask=t.x_mask[part])


@dataclass(frozen=True)
class _Table:
    local: ca.DM
    first: ca.DM
    second: ca.DM
    rhs_first: ca.DM
    rhs_second: ca.DM
    x_mask: ca.DM


@lru_cache(maxsize=None)
def _table(S: int, M: int) -> _Table:
    """The assembly indices of M cells of S stages without poles (:func:`assembly`).

    Built from one cell's by Kronecker products in CasADi (a few dozen
    operations, nothing handed over entry by entry): the first values are
    A (V ∘ keep) Aᵀ, A the 0/1 matrix putting each cell's local slots in u
    and V the cells' blocks of value numbers, with a later cell's entries of
    its first node masked (the earlier cell's come first); a second value is
    the same cell's zero, or for a shared node's entry the next cell's entry
    of the same pair of slots.
    """
    b, L = 4 * S, 4 * S + 2
    n_tri = L * (L + 1) // 2
    off = offsets(S)
    node, last = np.array([0, S + 1]), np.array([S, 2 * S + 1])     # first, last node's r, ψ
    ku, lu = np.triu_indices(L)
    tri = np.zeros((L, L))
    tri[ku, lu] = tri[lu, ku] = np.arange(n_tri)
    c = ca.DM(np.arange(float(M)).tolist())                           # 0, 1, …, M − 1
    diagonal = ca.Sparsity.diag(M)
    later = ca.DM(diagonal, ca.fmin(c, 1))                            # cells after the first
    eye = ca.DM.eye(M)
    A = _placement(S, M, off)
    E = np.zeros((L, L))
    E[np.ix_(node, node)] = 1.0
    V = ((ca.kron(eye, ca.DM(tri + 1)) + ca.kron(ca.DM(diagonal, c * (n_tri + 1)), ca.DM.ones(L, L)))
         * (ca.kron(eye, ca.DM.ones(L, L)) - ca.kron(later, ca.DM(E))))
    first = _shifted(ca.mtimes(A, ca.mtimes(V, A.T)), -1)
    # a shared node's pair (i, j) of the last node's slots pairs with the next cell's (i', j')
    step = n_tri - np.arange(n_tri + 1.0)                             # to the cell's own zero
    for i, j in np.ndindex(2, 2):
        t = tri[last[i], last[j]]
        step[int(t)] = n_tri + 1 + tri[node[i], node[j]] - t
    e = ca.DM.ones(L)
    e[node.tolist()] = 0
    u_src = ca.vec(ca.repmat(ca.DM(np.arange(L) + 1.0), 1, M) + ca.repmat((L + 1) * c.T, L, 1))
    u_keep = ca.vec(ca.horzcat(ca.DM.ones(L), ca.repmat(e, 1, M - 1)))
    rhs_first = _shifted(ca.mtimes(A, u_src * u_keep), -1)
    u_step = L - np.arange(L + 1.0)
    u_step[last] = L + 1 + node - last
    mask = ca.vertcat(ca.vec(ca.repmat(ca.vertcat(ca.DM.ones(3 * S), ca.DM.zeros(S)), 1, M)),
                      ca.DM.ones(2))
    local = ca.vec(ca.repmat(ca.DM(off.astype(float)), 1, M) + ca.repmat(b * c.T, L, 1))
    return _Table(local, first, _then(first, step), rhs_first, _then(rhs_first, u_step), mask)


def _placement(S: int, M: int, off: np.ndarray) -> ca.DM:
    """The 0/1 matrix (u's size × M L) putting each cell's L local slots (a column per cell,
    stacked) in u; a node between two cells receives both cells' slots."""
    b, L = 4 * S, len(off)
    own, nxt = off < b, off >= b
    Q = ca.DM(ca.Sparsity.triplet(b, L, off[own].tolist(), np.flatnonzero(own).tolist()), 1.0)
    Qn = ca.DM(ca.Sparsity.triplet(b, L, (off[nxt] - b).tolist(), np.flatnonzero(nxt).tolist()),
               1.0)
    eye, n = ca.DM.eye(M), M * L
    # each cell's own slots, then its last node's (rows shifted down by a cell)
    return (ca.vertcat(ca.kron(eye, Q), ca.DM(2, n))
            + ca.vertcat(ca.DM(b, n), ca.kron(eye, Qn))[:b * M + 2, :])


def _shifted(m: ca.DM, k: float) -> ca.DM:
    """``m`` with k added to its nonzeros (its structural zeros stay)."""
    return ca.DM(m.sparsity(), m.get_nz(False, ca.Slice()) + k)


def _then(first: ca.DM, step: np.ndarray) -> ca.DM:
    """The second value numbers from the first: first + step[first mod (values a cell)]."""
    per = len(step)
    nz = first.get_nz(False, ca.Slice())
    return ca.DM(first.sparsity(), ca.DM(step).get_nz(False, ca.fmod(nz, per)) + nz)
