"""The collocation scheme: where the unknowns sit in a cell and how a cell is integrated.

The mesh nodes s_0 < … < s_N split the shell into cells.  In each cell r and ψ
are polynomials of degree S (``stages``) through S + 1 equally spaced points
(the two nodes and S − 1 interior points), and the meridional stretch f_s is
known at the S Gauss–Legendre points s_ck of the cell.  The energy is the
Gauss rule

    𝓔 ≈ Σ_c Δs_c Σ_k w_k L(s_ck, r, ψ, f_s,ck, ψ')|_{s_ck},   L = 2π ρ e,

and the compatibility r' = f_s cos ψ is collocated at the same points

    r'(s_ck) − f_s,ck cos ψ(s_ck) = 0.

This is S-stage Gauss collocation of the optimal-control form of the energy
(the paper's energy, Methods, Eq. 7, minimised directly): order 2S on smooth
solutions.  ``stages=1`` is the staggered scheme (r, ψ on nodes, f_s at cell
centres, midpoint rule): second order.  ``stages=2`` (default) is fourth order
at twice the unknowns per cell, so a given accuracy needs far fewer cells.
Nothing is evaluated on the axis (Gauss points are interior), and there are
only equality constraints, so derivatives of the solution with respect to the
parameters (implicit function theorem on the KKT system) are exact.

Poles are imposed by constants (r = 0, ψ = 0 at the start, ψ = π at the end,
:data:`POLE_VALUES`); free edges need nothing: the no-force, no-torque
conditions (Methods, "Numerical solution of the toy problems") are natural.

This module holds what depends on the scheme alone: the layout of the unknowns
(:class:`Layout`), the Lagrange and Gauss bases of a cell (:func:`collocation`),
the points of a mesh (:func:`within_cells`, :class:`PointData`) and the
integrals from the first node to every point (:func:`integration_operators`,
:func:`integrate_numeric`, :func:`integrate_symbolic`).
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from typing import NamedTuple

import casadi as ca
import numpy as np

__all__ = ["POLE_VALUES", "Layout", "collocation", "reconstruction", "lagrange", "horner",
           "within_cells",
           "between", "PointData", "mesh_point_data", "integration_operators",
           "integrate_numeric", "integrate_symbolic"]

#: r, ψ at a start pole and ψ at an end pole: the constants that :meth:`Layout.cell_indices`
#: places after the unknowns (indices n, n + 1, n + 2).
POLE_VALUES = (0.0, 0.0, np.pi)


@dataclass(frozen=True)
class Layout:
    """Where the unknowns sit in the NLP vector x = [r_free, ψ_free, f_s].

    Points are the nodes and the S − 1 interior interpolation points of each
    cell, in increasing s: point j = c S + l (l = 0 … S) of cell c.
    """

    cells: int
    stages: int
    start_pole: bool
    end_pole: bool

    @property
    def points(self) -> int:
        """Number of points: the nodes and the interior interpolation points of every cell."""
        return self.cells * self.stages + 1

    @property
    def free_points(self) -> int:
        """Points whose r and ψ are unknowns (all but the poles, where they are fixed)."""
        return self.points - self.start_pole - self.end_pole

    @property
    def size(self) -> int:
        """Number of unknowns: r and ψ at the free points, f_s at the Gauss points."""
        return 2 * self.free_points + self.cells * self.stages

    def split(self, x: np.ndarray, derivative: bool = False):
        """Full r, ψ at the points and f_s at the Gauss points, from x.

        With ``derivative``, x is a derivative of the unknowns and the fixed
        pole values contribute zeros.
        """
        n = self.free_points
        return (self._pad(x[:n], 0.0), self._pad(x[n:2 * n], 0.0 if derivative else np.pi),
                x[2 * n:])

    def _pad(self, v, end_value):
        parts = ([np.zeros(1)] if self.start_pole else []) + [v] + \
                ([np.array([end_value])] if self.end_pole else [])
        return np.concatenate(parts)

    def pack(self, r, psi, f) -> np.ndarray:
        """The unknown vector x from r, ψ at every point (units of R, rad) and f_s at the Gauss
        points."""
        sl = slice(1 if self.start_pole else 0, -1 if self.end_pole else None)
        return np.concatenate([np.asarray(r)[sl], np.asarray(psi)[sl], np.asarray(f)])

    def cell_indices(self) -> np.ndarray:
        """Positions of each cell's local unknowns in [x, :data:`POLE_VALUES`].

        Returns
        -------
        idx : ndarray of int, shape (3S + 2, cells)
            Column c: r at the cell's S + 1 points, ψ there, f_s at its S Gauss
            points; a pole's fixed r or ψ is n, n + 1 or n + 2 (n = :attr:`size`).
        """
        n, S = self.size, self.stages
        pts = np.arange(self.points)
        r_idx = pts - self.start_pole
        psi_idx = self.free_points + pts - self.start_pole
        if self.start_pole:
            r_idx[0], psi_idx[0] = n, n + 1
        if self.end_pole:
            r_idx[-1], psi_idx[-1] = n, n + 2
        cell_pts = np.arange(self.cells)[None, :] * S + np.arange(S + 1)[:, None]
        f_idx = 2 * self.free_points + np.arange(self.cells)[None, :] * S + np.arange(S)[:, None]
        return np.vstack([r_idx[cell_pts], psi_idx[cell_pts], f_idx])


@lru_cache(maxsize=8)
def collocation(stages: int):
    """Lagrange bases of one cell for ``stages`` S (cached per S).

    Returns
    -------
    tau, w : ndarray, shape (S,)
        The S Gauss–Legendre points and weights on [0, 1].
    values, derivatives : ndarray, shape (S, S + 1)
        values[k, l] = ℓ_l(τ_k), derivatives[k, l] = ℓ_l'(τ_k) for the Lagrange
        basis ℓ_l on τ = 0, 1/S, …, 1 (the cell's interpolation points).
    integrals : ndarray, shape (S + 1, S)
        integrals[l, k] = ∫₀^{l/S} λ_k(τ) dτ for the Lagrange basis λ_k on the
        Gauss points (to integrate z' = f_s sin ψ to the interpolation points).
    antiderivatives : list of ndarray
        antiderivatives[k]: coefficients (lowest first) of ∫₀^τ λ_k.
    """
    xg, wg = np.polynomial.legendre.leggauss(stages)
    tau, w = (xg + 1) / 2, wg / 2
    nodes = np.linspace(0.0, 1.0, stages + 1)
    values = np.zeros((stages, stages + 1))
    derivs = np.zeros((stages, stages + 1))
    for l in range(stages + 1):
        basis = lagrange(nodes, l)
        values[:, l], derivs[:, l] = basis(tau), basis.deriv()(tau)
    integrals = np.zeros((stages + 1, stages))
    anti = []
    for k in range(stages):
        antideriv = lagrange(tau, k).integ()
        integrals[:, k] = antideriv(nodes)
        anti.append(antideriv.coef)
    return tau, w, values, derivs, integrals, anti


@lru_cache(maxsize=8)
def reconstruction(stages: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Weights that put a field known at a cell's nodes and Gauss points at its other points.

    A cell's data are the field at τ = 0, its S Gauss points and τ = 1 (S + 2 values,
    in that order).  Its interior points τ = l/S (l = 1 … S − 1) take the polynomial
    of degree S + 1 through all of them: within the cell, so never across a node, where
    a profile may kink.  A pole, where the fields are not evaluated, takes the
    polynomial of degree S through the cell's other S + 1 values.

    Returns
    -------
    inner : ndarray, shape (S − 1, S + 2)
        Weights of the interior points.
    start, end : ndarray, shape (S + 2,)
        Weights of the first and of the last node (zero on that node's own value).
    """
    tau = collocation(stages)[0]
    data = np.concatenate([[0.0], tau, [1.0]])
    inner = np.array([[lagrange(data, j)(l / stages) for j in range(stages + 2)]
                      for l in range(1, stages)]).reshape(stages - 1, stages + 2)
    start, end = np.zeros(stages + 2), np.zeros(stages + 2)
    start[1:] = [lagrange(data[1:], j)(0.0) for j in range(stages + 1)]
    end[:-1] = [lagrange(data[:-1], j)(1.0) for j in range(stages + 1)]
    return inner, start, end


def lagrange(points: np.ndarray, l: int) -> np.polynomial.Polynomial:
    """The l-th Lagrange basis polynomial on ``points``.

    Returns
    -------
    numpy.polynomial.Polynomial
        1 at ``points[l]``, 0 at the others (degree len(points) − 1).
    """
    others = np.delete(points, l)
    if not len(others):
        return np.polynomial.Polynomial([1.0])
    return np.polynomial.Polynomial.fromroots(others) / np.prod(points[l] - others)


def horner(coefficients, x):
    """The polynomial of ``coefficients`` (lowest first) at ``x``, by Horner's rule.

    Works on numbers and on CasADi expressions (a cell's polynomials at a
    symbolic τ).
    """
    out = 0 * x + coefficients[-1]
    for c in coefficients[-2::-1]:
        out = out * x + c
    return out


class PointData(NamedTuple):
    """The points of a mesh and what depends on them alone (:func:`mesh_point_data`).

    Attributes
    ----------
    s : ndarray (n,)
        The nodes and the S − 1 interior points of each cell, at fractions l/S.
    rho, z0, psi0 : ndarray (n,)
        The undeformed shell there; ρ is exactly 0 at a pole.
    off : ndarray of bool (n,)
        The points off the axis (ρ > 0).
    """

    s: np.ndarray
    rho: np.ndarray
    z0: np.ndarray
    psi0: np.ndarray
    off: np.ndarray


def mesh_point_data(nodes: np.ndarray, tau: np.ndarray, geometry, layout: Layout) -> PointData:
    """:class:`PointData` of the mesh ``nodes`` (N + 1,) with Gauss fractions ``tau`` (S,).

    The arrays are read-only: a discretisation keeps them for as long as its
    nodes stay put.
    """
    S = len(tau)
    s = within_cells(nodes, np.arange(S) / S)
    rho, z0, psi0 = geometry.numeric(s)
    # a pole is on the axis exactly, whatever sin(pi) rounds to
    rho[[0, -1]] = np.where([layout.start_pole, layout.end_pole], 0.0, rho[[0, -1]])
    out = PointData(s, rho, z0, psi0, rho > 0)
    for a in out:
        a.flags.writeable = False
    return out


def within_cells(nodes, fractions, last: bool = True):
    """Points at ``fractions`` of every cell (cell by cell), and the last node if ``last``.

    Parameters
    ----------
    nodes : ndarray or casadi.SX or casadi.MX, shape (N + 1,)
        The node positions.
    fractions : array_like, shape (k,)
        Places inside a cell, in [0, 1].
    last : bool
        Append the last node.

    Returns
    -------
    ndarray or CasADi column, shape (N k + last,)
        Cell 0's k points, then cell 1's, …
    """
    fractions = np.asarray(fractions, dtype=float)
    if isinstance(nodes, (ca.SX, ca.MX)):
        # cell by cell in few CasADi operations (each operation costs the build about the
        # same whatever its size): the nodes and widths repeated per fraction
        n = nodes.shape[0]
        cell = np.repeat(np.arange(n - 1), len(fractions)).tolist()
        inner = between(nodes[cell], nodes[1:][cell], ca.DM(np.tile(fractions, n - 1)))
        return ca.vertcat(inner, nodes[n - 1]) if last else inner
    inner = between(nodes[:-1, None], nodes[1:, None], fractions[None, :]).ravel()
    return np.append(inner, nodes[-1]) if last else inner


def between(s0, s1, fraction):
    """The point at ``fraction`` of the cell from ``s0`` to ``s1`` (numbers or CasADi).

    One expression for every caller, so that the points of a mesh are the same
    bits however they are computed (numbers, expressions, compiled kernels).
    """
    return s0 + (s1 - s0) * fraction


def integration_operators(layout: Layout) -> tuple:
    """Sparse operators of ∫ from the first node to every point (Gauss interpolant per cell).

    For values v and widths Δs at the Gauss points (cell by cell), the
    integral to point j = c S + l is the sum of the whole cells before c
    (``B`` holds each cell's Gauss weights) plus the part of cell c (``P``);
    the sum over earlier cells is a cumulative sum, so the cost is linear
    in the mesh size.

    Returns
    -------
    P : casadi.DM, shape (points, cells S)
    B : casadi.DM, shape (cells, cells S)
    c : ndarray of int, shape (points,)
        The cell of each point (the last node's is the last cell).
    """
    S, cells = layout.stages, layout.cells
    _, weights, _, _, integrals, _ = collocation(S)
    j = np.arange(layout.points)
    c = np.minimum(j // S, cells - 1)
    l = j - c * S
    cols = (c[:, None] * S + np.arange(S)[None, :]).ravel()
    # (DM.triplet takes values in triplet order; DM(sparsity, values) would
    # read them in compressed-column order)
    P = ca.DM.triplet(np.repeat(j, S).tolist(), cols.tolist(), integrals[l].ravel(),
                      len(j), cells * S)
    B = ca.DM.triplet(np.repeat(np.arange(cells), S).tolist(), np.arange(cells * S).tolist(),
                      np.tile(weights, cells), cells, cells * S)
    return P, B, c


def integrate_symbolic(values, ds, operators: tuple):
    """∫ from the first node to every point, of Gauss-point ``values`` (CasADi).

    ``ds`` holds the cell widths at the Gauss points (cell by cell), ``operators``
    are :func:`integration_operators`.  Returns a column (points,).
    """
    P, B, c = operators
    v = values * ds
    starts = ca.vertcat(0, ca.cumsum(ca.mtimes(B, v)))
    return starts[c.tolist()] + ca.mtimes(P, v)


def integrate_numeric(values, ds, stages: int) -> np.ndarray:
    """:func:`integrate_symbolic` in NumPy: the same sums per cell, shape (points,).

    (The sparse operators would need scipy.sparse, whose import a fresh
    process would pay for.)
    """
    S = stages
    _, weights, _, _, integrals, _ = collocation(S)
    v = (np.asarray(values, dtype=float) * ds).reshape(-1, S)     # (cells, S)
    starts = np.concatenate([[0.0], np.cumsum(v @ weights)])
    inner = starts[:-1, None] + v @ integrals[:S].T                 # point l of cell c
    return np.append(inner.ravel(), starts[-2] + integrals[S] @ v[-1])
