"""Sparse matrices assembled from per-cell values by constant index gathers.

The transcription evaluates small dense kernels cell by cell and stacks their
outputs; the NLP's gradient, Jacobian and Hessian, the Newton system and the
parametric blocks are those values summed into place.  Where each value goes is
known before any number is: the patterns here are computed once, numerically
(NumPy), and the assembly is one gather of the stacked values (plus a sum for the
few entries that two cells share), so no symbolic work grows with the mesh.

The sparsity patterns are written in CasADi's compressed-column storage directly
(:func:`compressed`), and every entry sums its values in increasing source order,
as the product ``B @ values`` of the scatter matrix (:func:`scatter`) does: a gather
(:func:`gather`, :func:`assembled`) gives the same bits as the product, with less work.
"""
from __future__ import annotations

from functools import lru_cache

import casadi as ca
import numpy as np

__all__ = ["triu", "compressed", "positions", "distinct", "scatter", "gather", "assembled",
           "summed", "take"]


@lru_cache(maxsize=None)
def triu(n: int) -> tuple[np.ndarray, np.ndarray]:
    """``np.triu_indices(n)``, kept per n (read-only: every build of a size asks for it).

    Returns
    -------
    rows, cols : ndarray of int, shape (n (n + 1) / 2,)
    """
    ku, lu = np.triu_indices(n)
    ku.flags.writeable = lu.flags.writeable = False
    return ku, lu


def compressed(n_rows: int, n_cols: int, cols: np.ndarray, rows: np.ndarray) -> ca.Sparsity:
    """The sparsity of entries (rows, cols), given sorted by (col, row) and distinct.

    CasADi's compressed-column storage directly: ``Sparsity.triplet`` would sort
    them again.
    """
    colind = np.concatenate([[0], np.cumsum(np.bincount(cols, minlength=n_cols))])
    # (Sparsity.compressed of one list: the constructor tries its overloads on both lists)
    return ca.Sparsity.compressed([n_rows, n_cols, *colind.tolist(), *rows.tolist()])


def positions(shape, rows, cols, src) -> tuple:
    """The pattern of the entries (rows, cols) and each entry's nonzero.

    Returns
    -------
    sparsity : casadi.Sparsity, shape ``shape``
    pos : ndarray of int, shape (k,)
        The nonzero of each of the k entries (repeated entries share one).
    src : ndarray of int, shape (k,)
        ``src`` as a flat integer array.
    """
    n_rows, n_cols = shape
    rows, cols, src = (np.asarray(v, dtype=np.int64).ravel() for v in (rows, cols, src))
    # Sorting by (col, row) is CasADi's compressed-column order of nonzeros
    # (np.unique's steps without its overhead)
    key = cols * n_rows + rows
    order = np.argsort(key, kind="stable")
    ordered = key[order]
    new = np.empty(len(key), dtype=bool)
    new[:1] = True
    np.not_equal(ordered[1:], ordered[:-1], out=new[1:])
    pos = np.empty(len(key), dtype=np.int64)
    pos[order] = np.cumsum(new) - 1
    uniq = ordered[new]
    return compressed(n_rows, n_cols, uniq // n_rows, uniq % n_rows), pos, src


def distinct(key: np.ndarray) -> np.ndarray:
    """The distinct values of ``key``, sorted (np.unique without index outputs imports numpy.ma)."""
    key = np.sort(key)
    return key[np.append(True, key[1:] != key[:-1])[:len(key)]]


def scatter(shape, rows, cols, src, n_src: int, weights=None) -> tuple:
    """The sparse ``shape`` matrix whose (row, col) entry sums ``values[src]`` (times ``weights``).

    Parameters
    ----------
    shape : (int, int)
    rows, cols, src : array_like of int, shape (k,)
        Entry (rows[i], cols[i]) takes ``values[src[i]]``; a triplet given twice counts once.
    n_src : int
        Length of the values.
    weights : array_like, shape (k,), optional
        Factors on the values (default 1).

    Returns
    -------
    sparsity : casadi.Sparsity, shape ``shape``
    B : casadi.DM, shape (nnz, n_src)
        The matrix's nonzeros are ``B @ values``.
    """
    sp, pos, src = positions(shape, rows, cols, src)
    nnz = sp.nnz()
    if weights is None:
        # B[pos, src] = 1 (a repeated triplet too, as DM.triplet gives it), in
        # compressed form directly
        key = distinct(src * nnz + pos)
        B = ca.DM(compressed(nnz, n_src, key // nnz, key % nnz), 1.0)
    else:   # (DM.triplet: the weights in the triplets' order, not the nonzeros')
        B = ca.DM.triplet(pos.tolist(), src.tolist(),
                          ca.DM(np.asarray(weights, float).ravel()), nnz, n_src)
    return sp, B


def gather(shape, rows, cols, src, n_src: int) -> tuple:
    """:func:`scatter` (without weights) as index lists, for :func:`assembled`.

    Every nonzero takes the value ``values[first[i]]``; then, for each
    ``(pos, more)`` in ``extras``, the nonzeros ``pos`` add ``values[more]``.
    Each nonzero sums its values in increasing ``src``, as ``B @ values`` does,
    so the results are the same to the bit with half the work: an entry of the
    Newton system has at most two values, from the cells on either side of a
    node.  Only the few shared entries are listed twice (a full second list,
    padded with a zero, would cost every build its conversion to CasADi).

    Returns
    -------
    sparsity : casadi.Sparsity, shape ``shape``
    first : list of int, length nnz
    extras : list of (list of int, list of int)
    """
    sp, pos, src = positions(shape, rows, cols, src)
    nnz = sp.nnz()
    key = distinct(pos * n_src + src)            # by nonzero, then by value
    pos, src = key // n_src, key % n_src
    counts = np.bincount(pos, minlength=nnz)
    start = np.cumsum(counts) - counts
    extras = []
    for r in range(1, int(counts.max(initial=0))):
        has = np.flatnonzero(counts > r)
        extras.append((has.tolist(), src[start[has] + r].tolist()))
    return sp, src[start].tolist() if nnz else [], extras


def assembled(sp: ca.Sparsity, first: list, extras: list, values) -> ca.MX:
    """The matrix of pattern ``sp`` assembled from ``values`` by the lists of :func:`gather`."""
    v = ca.vec(values)
    nz = take(v, first)
    for pos, more in extras:
        # (MX.binary: `+` tries CasADi's DM and SX overloads first)
        nz[pos] = ca.MX.binary(ca.OP_ADD, take(nz, pos), take(v, more))
    return ca.MX(sp, nz)


def summed(values: ca.MX, first: ca.DM, pairs: tuple[ca.DM, ca.DM]) -> ca.MX:
    """``values``' nonzeros ``first`` after adding, for ``pairs`` = (a, b), nonzero b to
    nonzero a (index columns, as DM; :class:`morphoshell.numerics.cell_order.Assembly`).

    Only the entries two cells share are summed, in place, and the result is
    gathered once: two gathers of every entry and their sum would do the
    gather's work twice.  ``values`` is consumed: its handle is rebound to the
    sums (a copy of the handle would add to every build).
    """
    a, b = pairs
    if a.numel():
        # (MX.binary: `+` tries CasADi's DM and SX overloads first)
        values.set_nz(ca.MX.binary(ca.OP_ADD, values.get_nz(False, a), values.get_nz(False, b)),
                      False, a)
    return values.get_nz(False, first)


def take(v: ca.MX, idx: list) -> ca.MX:
    """The entries ``idx`` of the column ``v``, as a column (empty for no ``idx``)."""
    if not idx:
        return ca.MX(0, 1)
    out = v[idx]
    return out.T if out.size2() > 1 else out   # (a 1x1 value indexed by a list gives a row)
