"""Discretisation of the shell energy as a parametric NLP (Gauss collocation).

Scheme
------
The mesh nodes s_0 < … < s_N split the shell into cells.  In each cell r and ψ
are polynomials of degree S (``stages``) through S + 1 equally spaced points
(the two nodes and S − 1 interior points), and the meridional stretch f_s is
known at the S Gauss–Legendre points s_ck of the cell.  The energy is the
Gauss rule

    𝓔 ≈ Σ_c Δs_c Σ_k w_k L(s_ck, r, ψ, f_s,ck, ψ')|_{s_ck},   L = 2π ρ e,

and the compatibility r' = f_s cos ψ is collocated at the same points

    r'(s_ck) − f_s,ck cos ψ(s_ck) = 0.

This is S-stage Gauss collocation of the optimal-control form of the energy:
order 2S on smooth solutions.  ``stages=1`` is the staggered scheme (r, ψ on
nodes, f_s at cell centres, midpoint rule): second order.  ``stages=2``
(default) is fourth order at twice the unknowns per cell, so a given accuracy
needs far fewer cells.  Nothing is evaluated on the axis (Gauss points are
interior), and there are only equality constraints, so derivatives of the
solution with respect to the parameters (implicit function theorem on the KKT
system) are exact.

Poles are imposed by constants (r = 0, ψ = 0 at the start, ψ = π at the end);
free edges need nothing: the no-force, no-torque conditions are natural.

Parametric mesh
---------------
The nodes are material points s_i = Σ + (L − P − Σ) t_i of a fixed graded mesh
t_i (:mod:`morphoshell.mesh`), so Σ and P are NLP parameters like h and the
profile parameters.

Symbolic fields
---------------
Besides the NLP, a :class:`Discretisation` gives the shape as CasADi
expressions of the unknowns x and the physical parameters p: r and ψ at the
points, z and the deformed arclength by exact integration of z' = f_s sin ψ
and S' = f_s, and (r, z, ψ) anywhere inside a cell by its polynomials.  The
observables of :mod:`morphoshell.observables` are built from these, so that
forward evaluation, parametric derivatives and fits share one definition.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import casadi as ca
import numpy as np

from ._buffered import Buffered
from .energy import LOCAL_OUTPUTS, intrinsic_function, pointwise
from .layouts import CELL_DATA, INTRINSIC
from .mesh import Knot, check_monotone, shell_points
from .problem import Structure

__all__ = ["Discretisation", "Layout", "SymbolicShape", "collocation", "within_cells"]


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
        """The unknown vector x from r, ψ at every point (units of R, rad) and f_s at the Gauss points."""
        sl = slice(1 if self.start_pole else 0, -1 if self.end_pole else None)
        return np.concatenate([np.asarray(r)[sl], np.asarray(psi)[sl], np.asarray(f)])


@lru_cache(maxsize=8)
def collocation(stages: int):
    """Lagrange bases of one cell for ``stages`` S (cached per S).

    Returns (tau, w, values, derivatives, integrals, antiderivatives):

    * tau, w: the S Gauss–Legendre points and weights on [0, 1];
    * values[k, l] = ℓ_l(τ_k), derivatives[k, l] = ℓ_l'(τ_k) for the Lagrange
      basis ℓ_l on τ = 0, 1/S, …, 1 (the cell's interpolation points);
    * integrals[l, k] = ∫₀^{l/S} λ_k(τ) dτ for the Lagrange basis λ_k on the
      Gauss points (to integrate z' = f_s sin ψ to the interpolation points);
    * antiderivatives[k]: coefficients (lowest first) of ∫₀^τ λ_k.
    """
    xg, wg = np.polynomial.legendre.leggauss(stages)
    tau, w = (xg + 1) / 2, wg / 2
    nodes = np.linspace(0.0, 1.0, stages + 1)
    values = np.zeros((stages, stages + 1))
    derivs = np.zeros((stages, stages + 1))
    for l in range(stages + 1):
        basis = _lagrange(nodes, l)
        values[:, l], derivs[:, l] = basis(tau), basis.deriv()(tau)
    integrals = np.zeros((stages + 1, stages))
    anti = []
    for k in range(stages):
        antideriv = _lagrange(tau, k).integ()
        integrals[:, k] = antideriv(nodes)
        anti.append(antideriv.coef)
    return tau, w, values, derivs, integrals, anti


def within_cells(nodes, fractions, last: bool = True):
    """Points at ``fractions`` of every cell (cell by cell), and the last node if ``last``.

    ``nodes`` is a NumPy array or a CasADi column of the N + 1 node positions.
    """
    fractions = np.asarray(fractions, dtype=float)
    if isinstance(nodes, (ca.SX, ca.MX)):
        n = nodes.shape[0]
        lo, hi = nodes[:n - 1], nodes[1:]
        inner = ca.vec(ca.horzcat(*[lo + (hi - lo) * f for f in fractions]).T)
        return ca.vertcat(inner, nodes[n - 1]) if last else inner
    inner = (nodes[:-1, None] + np.diff(nodes)[:, None] * fractions[None, :]).ravel()
    return np.append(inner, nodes[-1]) if last else inner


def _lagrange(points: np.ndarray, l: int) -> np.polynomial.Polynomial:
    """The l-th Lagrange basis polynomial on ``points``."""
    others = np.delete(points, l)
    if not len(others):
        return np.polynomial.Polynomial([1.0])
    return np.polynomial.Polynomial.fromroots(others) / np.prod(points[l] - others)


def _poly(coefficients, x):
    """Horner evaluation (works on CasADi expressions)."""
    out = 0 * x + coefficients[-1]
    for c in coefficients[-2::-1]:
        out = out * x + c
    return out


class Discretisation:
    """The discrete energy and constraints for one (structure, mesh, stages).

    Each cell's energy terms and constraints depend on its 3S + 2 local
    unknowns z_c = (r at its S + 1 points, ψ at them, f_s at its S Gauss
    points) and on parameter-only *data* at its Gauss points, laid out as
    :data:`~morphoshell.layouts.CELL_DATA`.  Small SX functions give a cell's
    values, gradients and Hessian; they are mapped over the cells and
    scattered into the global gradient, Jacobian and Hessian by constant
    sparse matrices, so building the NLP costs about the same for any mesh.
    The data are computed once per solve (:meth:`cell_data`) and are the
    NLP's parameter vector, so Ipopt's callbacks never re-evaluate profiles
    or coefficients.

    Parameters
    ----------
    structure : Structure
    t : ndarray
        Nodes in [0, 1] (see :func:`morphoshell.mesh.graded_mesh`).
    stages : int
        Gauss points per cell S (order 2S).
    knots : tuple of Knot (or float)
        Nodes of ``t`` that sit at given material points: the anchors q
        passed with every solve, or the family's breakpoints, which move with
        the parameters (see :class:`morphoshell.mesh.Knot`; a float is an
        anchor).

    Attributes
    ----------
    x : casadi.MX
        Unknowns [r_free, ψ_free, f_s] (:class:`Layout`).
    D : casadi.MX
        NLP parameters: the Gauss-point data, column-major (n_D × cells S).
    p : casadi.MX
        Physical parameters (``structure.parameters``); ``pre(p, q)`` gives ``D``.
    q : casadi.MX
        Positions of the anchors (one per anchor knot; empty without).
    energy, objective : casadi.MX
        Total energy 𝓔(x, D) and the scaled objective handed to Ipopt.
    g : casadi.MX
        Compatibility constraints (cells S,), all equalities g = 0.
    grad_f, jac_g, hess_lag : casadi.Function
        Exact derivatives in the signatures of ``nlpsol``'s options.
    """

    def __init__(self, structure: Structure, t: np.ndarray, stages: int = 2,
                 knots: tuple = ()):
        if stages not in (1, 2, 3):
            raise ValueError(f"stages = {stages!r} must be 1, 2 or 3")
        self.structure = structure
        self.geometry = structure.geometry
        self.t = np.asarray(t, dtype=float)
        self.knot_list = tuple(k if isinstance(k, Knot) else Knot(float(k), "anchor", i)
                               for i, k in enumerate(knots))
        self.knots = tuple(k.t for k in self.knot_list)
        self.anchors = sum(k.source == "anchor" for k in self.knot_list)
        missing = [k for k in self.knots if not np.any(self.t == k)]
        if missing:
            raise ValueError(f"mesh knots {missing} are not nodes of the mesh")
        self.stages = S = stages
        cells = len(self.t) - 1
        self.layout = lay = Layout(cells, S, structure.start == "pole", structure.end == "pole")
        tau, w, self._values, self._derivs, self._integrals, self._anti = collocation(S)
        self.tau, self.weights = tau, w
        n_p = len(structure.parameters)
        n = lay.size
        m = cells * S

        self.p = ca.MX.sym("p", n_p)
        self.q = ca.MX.sym("q", self.anchors)
        a, b = self.shell_ends(self.p)
        s_nodes = self.nodes(self.p, self.q)
        ds = (s_nodes[1:] - s_nodes[:-1])[np.repeat(np.arange(cells), S).tolist()]
        # Energies range over decades with h (bending ~ h³): dividing by h³
        # and by the mean cell size keeps Ipopt's gradients O(1).
        scale = cells / (2 * ca.pi * self.structure.parameters.unpack(self.p)["h"] ** 3 * (b - a))
        pre = self._pre_function(n_p)
        s_gauss = within_cells(s_nodes, tau, last=False)
        weights = ca.DM(np.tile(w, cells)).T
        self.pre = ca.Function(
            "cell_data", [self.p, self.q],
            [ca.vec(pre.map(m)(s_gauss.T, ds.T, weights, scale, self.p))], ["p", "q"], ["D"])
        self._pre_parts = (pre, s_gauss, ds, weights, scale, m)
        n_D = len(CELL_DATA)
        self.x = ca.MX.sym("x", n)
        self.D = ca.MX.sym("D", n_D * m)
        Dc = ca.reshape(self.D, n_D * S, cells)   # one column per cell

        idx = self._cell_indices()
        n_loc = idx.shape[0]
        self._idx = idx
        # Gather the local unknowns of every cell (constants appended to x).
        Z = self.cell_unknowns(self.x)
        cell = _cell_functions(S)
        sigma, lam = ca.MX.sym("lam_f"), ca.MX.sym("lam_g", m)
        self.objective = ca.sum2(cell["f"].map(cells)(Z, Dc))
        self.energy = ca.sum2(cell["energy"].map(cells)(Z, Dc))
        self.g = ca.vec(cell["g"].map(cells)(Z, Dc))
        ell, dell = cell["grad"].map(cells)(Z, Dc)
        g2, dg = cell["jac"].map(cells)(Z, Dc)
        hess = cell["hess"].map(cells)(Z, Dc, sigma, ca.reshape(lam, S, cells))

        free = idx < n  # which local slots are unknowns
        cols = np.arange(n_loc * cells).reshape(cells, n_loc).T  # position of (slot, cell)
        A = ca.DM(ca.Sparsity.triplet(n, n_loc * cells, idx[free].tolist(), cols[free].tolist()),
                  np.ones(int(free.sum())))
        grad = ca.mtimes(A, ca.vec(dell))
        # Jacobian: dg is (S n_loc × cells), row-major in (k, slot) within a cell.
        k_, l_ = np.meshgrid(np.arange(S), np.arange(n_loc), indexing="ij")
        rows = (np.arange(cells)[None, None, :] * S + k_[..., None])
        colv = np.broadcast_to(idx[l_.ravel()].reshape(S, n_loc, cells), rows.shape[:2] + (cells,))
        rows = np.broadcast_to(rows, colv.shape)
        src = (np.arange(cells)[None, None, :] * (S * n_loc)
               + (l_ * S + k_)[..., None])   # column-major jacobian (S × n_loc) per cell
        keep = colv < n
        J = self._assemble((m, n), rows[keep], colv[keep], src[keep], ca.vec(dg), S * n_loc * cells)
        ku, lu = np.triu_indices(n_loc)
        I, Jc = idx[ku], idx[lu]
        ok = (I < n) & (Jc < n)
        n_tri = len(ku)
        srch = (np.arange(n_tri)[:, None] + n_tri * np.arange(cells)[None, :])[ok]
        H = self._assemble((n, n), np.minimum(I, Jc)[ok], np.maximum(I, Jc)[ok], srch,
                           ca.vec(hess), n_tri * cells)
        self.grad_f = ca.Function("grad_f", [self.x, self.D], [ca.sum2(ell), grad],
                                  ["x", "p"], ["f", "grad_f_x"])
        self.jac_g = ca.Function("jac_g", [self.x, self.D], [ca.vec(g2), J],
                                 ["x", "p"], ["g", "jac_g_x"])
        self.hess_lag = ca.Function("hess_lag", [self.x, self.D, sigma, lam], [H],
                                    ["x", "p", "lam_f", "lam_g"], ["triu_hess_gamma_x_x"])
        # Pointwise fields at the Gauss points, for results (one stacked output,
        # so a single copy to NumPy per solve).
        self._field_names = ("s", "ds", "weight", "r", "psi", "f_s", "dpsi", *LOCAL_OUTPUTS)
        self._fields = ca.Function("fields", [self.x, self.D],
                                   [cell["fields"].map(cells)(Z, Dc)])
        # z and S at the points are linear in the Gauss values of z' and S'
        # (per unit of t): the same operators serve numbers and expressions.
        self._integration = self._integration_operators()

    # -- construction helpers ------------------------------------------------
    def nodes(self, p, q):
        """Material points s of the mesh nodes (the parametric map of :mod:`morphoshell.mesh`).

        Each cell is affine in s between its nodes: Gauss and interpolation
        points sit at fixed fractions of it.
        """
        a, b = self.shell_ends(p)
        return shell_points(self.t, a, b, self.knots, self.knot_positions(p, q))

    def knot_positions(self, p, q) -> list:
        """Material points of the knots: anchors from q, breakpoints from the parameters."""
        if not self.knot_list:
            return []
        fam = self.structure.family
        named = self.structure.parameters.unpack(p)
        a, b = self.shell_ends(p)
        bps = fam.breakpoints({n: named[n] for n in fam.parameters}, a, b) \
            if any(k.source == "breakpoint" for k in self.knot_list) else []
        return [q[k.index] if k.source == "anchor" else bps[k.index][0] for k in self.knot_list]

    @property
    def pre_jacobian(self) -> ca.Function:
        """``(p, q) -> dD/dp`` (dense, n_D·cells·S × n_p), built on first use."""
        if not hasattr(self, "_pre_jacobian"):
            self._pre_jacobian = ca.Function(
                "cell_data_jacobian", [self.p, self.q], [self._chain_pre(*self._pre_parts)],
                ["p", "q"], ["dD_dp"])
        return self._pre_jacobian

    def _chain_pre(self, pre, s_gauss, ds, weights, scale, m: int) -> ca.MX:
        """dD/dp by the chain rule through one Gauss point's Jacobian.

        D_k = pre(s_k, Δs_k, w_k, scale, p) with s_k, Δs_k and the scale
        functions of p (the parametric mesh): the per-point Jacobian is a
        small SX function mapped over the points, the mesh's derivatives are
        small; differentiating the mapped graph as a whole cost 24 ms at 200
        nodes (measured).
        """
        args = [pre.sx_in(i) for i in range(pre.n_in())]
        s, dsk, _, sc, p = args
        D = pre(*args)
        local = ca.Function("pre_local", args, [ca.densify(ca.jacobian(D, ca.vertcat(s, dsk, sc, p)))])
        n_p, n_D = p.shape[0], D.shape[0]
        width = 3 + n_p
        JM = local.map(m)(s_gauss.T, ds.T, weights, scale, self.p)     # n_D × width·m
        block = [JM[:, list(range(j, width * m, width))] for j in range(width)]   # n_D × m each
        dS, dDS = ca.jacobian(s_gauss, self.p), ca.jacobian(ds, self.p)
        dSC = ca.jacobian(scale, self.p)
        columns = []
        for l in range(n_p):
            col = (block[3 + l] + block[0] * ca.repmat(dS[:, l].T, n_D, 1)
                   + block[1] * ca.repmat(dDS[:, l].T, n_D, 1) + block[2] * dSC[0, l])
            columns.append(ca.vec(col))
        return ca.horzcat(*columns)

    def _pre_function(self, n_p: int) -> ca.Function:
        """``(s_k, Δs_c, w_k, scale, p) -> D_k``: parameter-only data at one Gauss point."""
        s_k, ds, wk, scale, p = (ca.SX.sym("s"), ca.SX.sym("ds"), ca.SX.sym("wk"),
                                 ca.SX.sym("scale"), ca.SX.sym("p", n_p))
        I = intrinsic_function(self.structure)(s_k, p)
        data = {"s": s_k, "ds": ds, "weight": wk, "scale": scale,
                "h": self.structure.parameters.unpack(p)["h"]}
        off = CELL_DATA.after(INTRINSIC)
        return ca.Function("pre", [s_k, ds, wk, scale, p],
                           [ca.vertcat(*[data[n] for n in CELL_DATA.names[:off]], I)])

    def _cell_indices(self) -> np.ndarray:
        """(3S + 2, cells) positions of each cell's local unknowns in [x, constants]."""
        lay, n, S = self.layout, self.layout.size, self.stages
        pts = np.arange(lay.points)
        r_idx = pts - lay.start_pole
        psi_idx = lay.free_points + pts - lay.start_pole
        if lay.start_pole:
            r_idx[0], psi_idx[0] = n, n + 1
        if lay.end_pole:
            r_idx[-1], psi_idx[-1] = n, n + 2
        cell_pts = np.arange(lay.cells)[None, :] * S + np.arange(S + 1)[:, None]
        f_idx = 2 * lay.free_points + np.arange(lay.cells)[None, :] * S + np.arange(S)[:, None]
        return np.vstack([r_idx[cell_pts], psi_idx[cell_pts], f_idx])

    @staticmethod
    def _assemble(shape, rows, cols, src, values: ca.MX, n_src: int) -> ca.MX:
        """Sparse ``shape`` matrix whose (row, col) entry sums ``values[src]``."""
        n_rows, n_cols = shape
        rows, cols, src = (np.asarray(v, dtype=np.int64).ravel() for v in (rows, cols, src))
        # Sorting by (col, row) is CasADi's compressed-column order of nonzeros.
        uniq, pos = np.unique(cols * n_rows + rows, return_inverse=True)
        B = ca.DM(ca.Sparsity.triplet(len(uniq), n_src, pos.tolist(), src.tolist()),
                  np.ones(len(src)))
        sp = ca.Sparsity.triplet(n_rows, n_cols, (uniq % n_rows).tolist(), (uniq // n_rows).tolist())
        return ca.MX(sp, ca.mtimes(B, values))

    def _integration_operators(self):
        """Sparse operators of ∫ from the first node to every point (Gauss interpolant per cell).

        For values v and widths Δs at the Gauss points (cell by cell), the
        integral to point j = c S + l is the sum of the whole cells before c
        (``B`` holds each cell's Gauss weights) plus the part of cell c (``P``);
        the sum over earlier cells is a cumulative sum, so the cost is linear
        in the mesh size.
        """
        S, cells = self.stages, self.layout.cells
        j = np.arange(self.layout.points)
        c = np.minimum(j // S, cells - 1)
        l = j - c * S
        cols = (c[:, None] * S + np.arange(S)[None, :]).ravel()
        # (DM.triplet takes values in triplet order; DM(sparsity, values) would
        # read them in compressed-column order)
        P = ca.DM.triplet(np.repeat(j, S).tolist(), cols.tolist(), self._integrals[l].ravel(),
                          len(j), cells * S)
        B = ca.DM.triplet(np.repeat(np.arange(cells), S).tolist(), np.arange(cells * S).tolist(),
                          np.tile(self.weights, cells), cells, cells * S)
        return P, B, c

    def _integrate(self, values, ds):
        """∫ from the first node to every point, of Gauss-point ``values`` (CasADi or NumPy).

        ``ds`` holds the cell widths in s at the Gauss points (cell by cell).
        """
        P, B, c = self._integration
        if isinstance(values, (ca.MX, ca.SX)) or isinstance(ds, (ca.MX, ca.SX)):
            v = values * ds
            starts = ca.vertcat(0, ca.cumsum(ca.mtimes(B, v)))
            return starts[c.tolist()] + ca.mtimes(P, v)
        v = np.asarray(values, dtype=float) * ds
        starts = np.concatenate([[0.0], np.cumsum(B.sparse() @ v)])
        return starts[c] + P.sparse() @ v

    # -- numerical interface -------------------------------------------------
    def points(self, p: np.ndarray, q=()) -> np.ndarray:
        """Arclength s of the points (nodes and interior points) for parameters ``p``."""
        return within_cells(self.nodes(np.asarray(p, dtype=float), q),
                            np.arange(self.stages) / self.stages)

    def initial_guess(self, p: np.ndarray, q=()) -> np.ndarray:
        """The undeformed shell: r = ρ, ψ = ψ₀, f_s = 1."""
        rho, _, psi0 = self.geometry.numeric(self.points(p, q))
        return self.layout.pack(rho, psi0, np.ones(self.layout.cells * self.stages))

    def check_anchors(self, p: np.ndarray, q) -> np.ndarray:
        """``q`` as an array, or ValueError unless it holds increasing points inside the shell."""
        q = np.asarray(q, dtype=float).ravel()
        if len(q) != self.anchors:
            raise ValueError(f"this mesh has {self.anchors} anchor(s), got {len(q)}")
        p = np.asarray(p, dtype=float)
        a, b = self.shell_ends(p)
        where = [float(v) for v in self.knot_positions(p, q)]
        if where and not np.all(np.diff(np.concatenate([[a], where, [b]])) > 0):
            names = [f"{k.source} {k.index}" for k in self.knot_list]
            raise ValueError(
                f"this mesh puts nodes at {dict(zip(names, where))}, which must be increasing and "
                f"lie inside the shell ({a:.6g}, {b:.6g}): a breakpoint of the family moved past "
                f"another or out of the shell; solve with solve() (which picks a suitable mesh) "
                f"or build a DirectSolver with mesh_spec for this problem")
        if where:
            check_monotone(self.nodes(p, q))
        return q

    def cell_data(self, p: np.ndarray, q=()) -> np.ndarray:
        """The NLP parameter vector D for physical parameters ``p`` and anchors ``q``."""
        if not hasattr(self, "_pre_buffered"):
            self._pre_buffered = Buffered(self.pre)
        return self._pre_buffered(p, np.asarray(q, dtype=float))[0]

    def gauss_fields(self, x: np.ndarray, D: np.ndarray) -> dict[str, np.ndarray]:
        """Every pointwise quantity at the Gauss points, given the data ``D``."""
        if not hasattr(self, "_fields_buffered"):
            self._fields_buffered = Buffered(self._fields)
        out = self._fields_buffered(x, D)[0].reshape(-1, len(self._field_names)).T
        return dict(zip(self._field_names, out))

    def integrate_to_points(self, values: np.ndarray, p: np.ndarray, q=()) -> np.ndarray:
        """∫ ds from the first node to every point, of a function known at the Gauss points.

        Exact for the degree S − 1 interpolant of ``values`` through the Gauss
        points of each cell.
        """
        nodes = self.nodes(np.asarray(p, dtype=float), q)
        return self._integrate(values, np.repeat(np.diff(nodes), self.stages))

    # -- symbolic interface (for observables) --------------------------------
    def cell_unknowns(self, x) -> ca.MX:
        """(3S + 2, cells): each cell's r, ψ at its points and f_s at its Gauss points."""
        n_loc, cells = self._idx.shape
        xfull = ca.vertcat(x, ca.DM([0.0, 0.0, np.pi]))   # pole values r = 0, ψ = 0, ψ = π
        return ca.reshape(xfull[self._idx.ravel(order="F").tolist()], n_loc, cells)

    def shell_ends(self, p):
        """(Σ, L − P) from the parameter vector (CasADi or NumPy)."""
        named = self.structure.parameters.unpack(p)
        return named["cut"], self.geometry.length - named["opening"]

    def gauss_values(self, Z) -> tuple:
        """f_s and ψ at the Gauss points (vectors, cell by cell) from ``cell_unknowns``."""
        S = self.stages
        psi_g = ca.mtimes(ca.DM(self._values), Z[S + 1:2 * S + 2, :])
        return ca.vec(Z[2 * S + 2:, :]), ca.vec(psi_g)

    def shape(self, x, p, q) -> "SymbolicShape":
        """The discrete shape as CasADi expressions of the unknowns x, parameters p, anchors q."""
        return SymbolicShape(self, x, p, q)

    def symbolic_points(self, x, p, q) -> dict:
        """s, r, ψ, z and the deformed arclength S at the points (see :class:`SymbolicShape`)."""
        return self.shape(x, p, q).points

    def kkt_curvature(self, x, lam, D, mu_F, mu_dz, mu_dS, ds) -> ca.MX:
        """Upper triangle of ∂²/∂(x, λ)² [μ_F·F(x, λ) − Σ_c (μ_dz,c Δz_c + μ_dS,c ΔS_c)].

        F = (∇f + Jᵀλ, g) is the KKT residual of the NLP
        (:attr:`morphoshell.parametric.Parametric.kkt_residual`) and Δz_c, ΔS_c
        the cell increments of z and of the deformed arclength
        (:meth:`SymbolicShape.increments`, cell widths ``ds``): the curvature
        of the equilibrium as constraints of a larger NLP (a fit in one NLP).
        Assembled from one SX kernel per cell (third derivatives of the cell
        energy), as :attr:`hess_lag` is: differentiating the assembled graph
        instead cost ~0.4 s per evaluation at 200 nodes (measured).

        Shapes: x (n,), λ and the constraints (m,), μ_F (n + m,), μ_dz, μ_dS
        and ds (cells,); the result is (n + m) × (n + m), sparse.
        """
        n, m = self.layout.size, self.g.shape[0]
        S, cells = self.stages, self.layout.cells
        n_loc = self._idx.shape[0]
        mu_x = ca.vertcat(mu_F[:n], ca.DM.zeros(3))      # constants: no stationarity row
        Mz = ca.reshape(mu_x[self._idx.ravel(order="F").tolist()], n_loc, cells)
        kernel = _cell_kkt_curvature(S).map(cells)
        values = kernel(self.cell_unknowns(x), ca.reshape(D, -1, cells), ca.reshape(lam, S, cells),
                        Mz, ca.reshape(mu_F[n:], S, cells), ca.reshape(mu_dz, 1, cells),
                        ca.reshape(mu_dS, 1, cells), ca.reshape(ds, 1, cells))
        # global (x, λ) index of each local slot; constants (idx >= n) drop out
        local = np.vstack([np.where(self._idx < n, self._idx, -1),
                           n + np.arange(cells)[None, :] * S + np.arange(S)[:, None]])
        ku, lu = np.triu_indices(n_loc + S)
        I, J = local[ku], local[lu]
        ok = (I >= 0) & (J >= 0)
        n_tri = len(ku)
        src = (np.arange(n_tri)[:, None] + n_tri * np.arange(cells)[None, :])[ok]
        return self._assemble((n + m, n + m), np.minimum(I, J)[ok], np.maximum(I, J)[ok], src,
                              ca.vec(values), n_tri * cells)

    def state_at(self, x: np.ndarray, p: np.ndarray, q, z_points: np.ndarray,
                 s_star: float) -> dict:
        """(r, ψ, z) at the material point ``s_star`` of a solution, numerically.

        The same cell polynomials as :meth:`SymbolicShape.at`; ``z_points`` are
        the solution's z at the points (any gauge: the result is in the same).
        At a node (an anchor) the values are the nodal ones.
        """
        cell = self.cell_of(p, q, s_star)
        s0, s1 = (float(v) for v in self.nodes(np.asarray(p, dtype=float), q)[[cell, cell + 1]])
        Zc = np.append(x, [0.0, 0.0, np.pi])[self._idx[:, cell]]
        out = _cell_state(self.stages)(Zc, s1 - s0, z_points[cell * self.stages], 0.0,
                                       (s_star - s0) / (s1 - s0))
        return {k: float(v) for k, v in zip(("r", "psi", "z"), out)}

    def cell_of(self, p: np.ndarray, q, s_star: float) -> int:
        """Index of the cell that contains the material point ``s_star``."""
        nodes = self.nodes(np.asarray(p, dtype=float), q)
        return int(np.clip(np.searchsorted(nodes, s_star, side="right") - 1, 0,
                           self.layout.cells - 1))


@lru_cache(maxsize=8)
def _cell_functions(stages: int) -> dict[str, ca.Function]:
    """Values, gradients and the Lagrangian's triu Hessian of one cell (SX).

    The family and the theory enter only through the cell data D (profiles,
    η and coefficients are evaluated by the structure's ``pre`` function), so
    these depend on the number of stages alone and every structure shares them.
    """
    S = stages
    _, _, values, derivs, _, _ = collocation(S)
    n_D = len(CELL_DATA)
    off = CELL_DATA.after(INTRINSIC)
    z, D = ca.SX.sym("z", 3 * S + 2), ca.SX.sym("D", n_D * S)
    sigma, lam = ca.SX.sym("sigma"), ca.SX.sym("lam", S)
    zr, zp, zf = z[:S + 1], z[S + 1:2 * S + 2], z[2 * S + 2:]
    V, Dv = ca.DM(values), ca.DM(derivs)
    energy, g, fields = 0, [], []
    for k in range(S):
        Dk = D[k * n_D:(k + 1) * n_D]
        d = CELL_DATA.unpack(Dk)
        I = Dk[off:]
        r_k, psi_k = ca.dot(V[k, :].T, zr), ca.dot(V[k, :].T, zp)
        dr_k, dpsi_k = ca.dot(Dv[k, :].T, zr) / d["ds"], ca.dot(Dv[k, :].T, zp) / d["ds"]
        point = pointwise(r_k, psi_k, zf[k], dpsi_k, I, d["h"])
        energy += d["weight"] * d["ds"] * point["L"]
        g.append(dr_k - zf[k] * ca.cos(psi_k))
        n_shape = len(LOCAL_OUTPUTS) - len(INTRINSIC)
        fields.append(ca.vertcat(d["s"], d["ds"], d["weight"], r_k, psi_k, zf[k], dpsi_k,
                                 *[point[name] for name in LOCAL_OUTPUTS[:n_shape]], I))
    ell = energy * CELL_DATA.unpack(D[:n_D])["scale"]
    g = ca.vertcat(*g)
    H = ca.hessian(sigma * ell + ca.dot(lam, g), z)[0]
    ku, lu = np.triu_indices(3 * S + 2)
    return {
        "f": ca.Function("cell_f", [z, D], [ell]),
        "energy": ca.Function("cell_energy", [z, D], [energy]),
        "g": ca.Function("cell_g", [z, D], [g]),
        "grad": ca.Function("cell_grad", [z, D], [ell, ca.gradient(ell, z)]),
        "jac": ca.Function("cell_jac", [z, D], [g, ca.vec(ca.jacobian(g, z))]),
        "hess": ca.Function("cell_hess", [z, D, sigma, lam],
                            [ca.vertcat(*[H[int(i), int(j)] for i, j in zip(ku, lu)])]),
        "fields": ca.Function("cell_fields", [z, D], [ca.horzcat(*fields)]),
    }


@lru_cache(maxsize=None)
def _cell_kkt_curvature(stages: int) -> ca.Function:
    """One cell's triu ∂²/∂(z, λ)² of μ_z·(∇ℓ + ∇gᵀλ) + μ_λ·g − a Δz − b ΔS (SX)."""
    S = stages
    n_D = len(CELL_DATA)
    z, D, lam = ca.SX.sym("z", 3 * S + 2), ca.SX.sym("D", n_D * S), ca.SX.sym("lam", S)
    mz, ml = ca.SX.sym("mu_z", 3 * S + 2), ca.SX.sym("mu_lam", S)
    a, b, ds = ca.SX.sym("mu_dz"), ca.SX.sym("mu_dS"), ca.SX.sym("ds")
    cell = _cell_functions(S)
    _, dell = cell["grad"](z, D)
    g = cell["g"](z, D)
    dz, dS = _increments(S)(z, ds)
    phi = ca.dot(mz, dell + ca.mtimes(ca.jacobian(g, z).T, lam)) + ca.dot(ml, g) - a * dz - b * dS
    H = ca.hessian(phi, ca.vertcat(z, lam))[0]
    ku, lu = np.triu_indices(4 * S + 2)
    return ca.Function("cell_kkt_curvature", [z, D, lam, mz, ml, a, b, ds],
                       [ca.vertcat(*[H[int(i), int(j)] for i, j in zip(ku, lu)])])


class SymbolicShape:
    """The shape of a :class:`Discretisation` as expressions of (x, p).

    ``points`` holds s, r, ψ, z and the deformed arclength S at all points
    (nodes and interior interpolation points); z is fixed by z(s_0) = z₀(s_0)
    (the undeformed height) and S(s_0) = 0.  :meth:`at` evaluates the cell
    polynomials anywhere, :meth:`at_arclength` finds the material point at a
    given deformed arclength.
    """

    def __init__(self, disc: Discretisation, x, p, q):
        self.disc = d = disc
        S = d.stages
        self.Z = Z = d.cell_unknowns(x)
        self.p, self.q = p, q
        self.a, self.b = a, b = d.shell_ends(p)
        self.s_nodes = d.nodes(p, q)
        self.f_g, self.psi_g = d.gauss_values(Z)
        ds = (self.s_nodes[1:] - self.s_nodes[:-1])[np.repeat(np.arange(d.layout.cells),
                                                                S).tolist()]
        self.points = {
            "s": within_cells(self.s_nodes, np.arange(S) / S),
            "r": ca.vertcat(ca.vec(Z[:S, :]), Z[S, -1]),
            "psi": ca.vertcat(ca.vec(Z[S + 1:2 * S + 1, :]), Z[2 * S + 1, -1]),
            "z": d.geometry.z0(a) + d._integrate(self.f_g * ca.sin(self.psi_g), ds),
            "S": d._integrate(self.f_g, ds),
        }

    def increments(self) -> tuple:
        """(Δz, ΔS) over every cell: ∫ f_s sin ψ ds and ∫ f_s ds by the Gauss rule (columns)."""
        S, cells = self.disc.stages, self.disc.layout.cells
        ds = self.s_nodes[1:] - self.s_nodes[:cells]
        f = self.Z[2 * S + 2:, :]
        psi_g = ca.mtimes(ca.DM(self.disc._values), self.Z[S + 1:2 * S + 2, :])
        w = ca.DM(self.disc.weights).T
        return (ds * ca.mtimes(w, f * ca.sin(psi_g)).T, ds * ca.mtimes(w, f).T)

    def cell_bounds(self, cell: int):
        """(s at the cell's first node, its width in s)."""
        return self.s_nodes[cell], self.s_nodes[cell + 1] - self.s_nodes[cell]

    def _in_cell(self, cell: int, tau) -> dict:
        _, ds = self.cell_bounds(cell)
        first = cell * self.disc.stages
        out = _cell_state(self.disc.stages)(self.Z[:, cell], ds, self.points["z"][first],
                                            self.points["S"][first], tau)
        return dict(zip(("r", "psi", "z", "S"), out))

    def at(self, cell: int, s_star) -> dict:
        """(r, ψ, z, S) at the material point ``s_star`` by the polynomials of ``cell``.

        ``s_star`` may be an expression of p.  The cell should contain it; a
        point just outside is extrapolated smoothly.
        """
        s0, ds = self.cell_bounds(cell)
        tau = (s_star - s0) / ds
        return {**self._in_cell(cell, tau), "s": s_star}

    def at_arclength_selected(self, select, targets) -> dict:
        """(s, r, ψ, z) at deformed arclengths ``targets`` (a row), each in the cell
        chosen by the corresponding column of the one-hot matrix ``select``
        (cells × points).  Vectorised :meth:`at_arclength`."""
        S = self.disc.stages
        n = targets.shape[1]
        cells = self.disc.layout.cells
        first = (np.arange(cells) * S).tolist()
        lo, hi = self.s_nodes[:cells], self.s_nodes[1:]
        starts = ca.horzcat(lo, hi - lo, self.points["z"][first], self.points["S"][first])
        chosen = ca.mtimes(select.T, starts)                    # (points, 4)
        Zc = ca.mtimes(self.Z, select)                          # (3S + 2, points)
        out = _arclength_point(S).map(n)(Zc, chosen[:, 0].T, chosen[:, 1].T, chosen[:, 2].T,
                                         chosen[:, 3].T, targets)
        return dict(zip(("s", "r", "psi", "z"), out))


@lru_cache(maxsize=8)
def _cell_state(stages: int) -> ca.Function:
    """``(z_c, Δs, z_first, S_first, τ) -> (r, ψ, z, S)`` inside one cell.

    r and ψ by the cell's Lagrange polynomials, z and the deformed arclength
    S by exact integration of the Gauss interpolants of f_s sin ψ and f_s
    from the cell's first node (where they are ``z_first``, ``S_first``).
    """
    S = stages
    tau_g, _, values, _, _, anti = collocation(S)
    nodes = np.linspace(0.0, 1.0, S + 1)
    zc, ds, z0, S0, tau = (ca.SX.sym("z_c", 3 * S + 2), ca.SX.sym("ds"), ca.SX.sym("z0"),
                           ca.SX.sym("S0"), ca.SX.sym("tau"))
    ell = [_poly(_lagrange(nodes, l).coef, tau) for l in range(S + 1)]
    Lam = [_poly(c, tau) for c in anti]   # ∫₀^τ of the Gauss-point basis
    f = zc[2 * S + 2:]
    psi_g = ca.mtimes(ca.DM(values), zc[S + 1:2 * S + 2])
    r = sum(ell[l] * zc[l] for l in range(S + 1))
    psi = sum(ell[l] * zc[S + 1 + l] for l in range(S + 1))
    z = z0 + ds * sum(Lam[k] * f[k] * ca.sin(psi_g[k]) for k in range(S))
    arclength = S0 + ds * sum(Lam[k] * f[k] for k in range(S))
    return ca.Function("cell_state", [zc, ds, z0, S0, tau], [r, psi, z, arclength],
                       ["z_c", "ds", "z_first", "S_first", "tau"], ["r", "psi", "z", "S"])


@lru_cache(maxsize=8)
def _arclength_point(stages: int, newton_steps: int = 6) -> ca.Function:
    """``(z_c, s_first, Δs, z_first, S_first, S*) -> (s, r, ψ, z)`` where S = S* in a cell.

    Newton's method on the cell's deformed arclength S(τ) (degree S, S' = f_s
    Δs > 0) from the linear interpolant, unrolled: a cell's stretch varies
    little, so a few steps reach machine precision, and differentiating the
    converged iteration gives the implicit-function derivative.
    """
    S = stages
    tau_g = collocation(S)[0]
    zc, s0, ds, z0, S0, target = (ca.SX.sym("z_c", 3 * S + 2), ca.SX.sym("s0"), ca.SX.sym("ds"),
                                  ca.SX.sym("z0"), ca.SX.sym("S0"), ca.SX.sym("target"))
    state = _cell_state(S)
    f = zc[2 * S + 2:]
    S1 = S0 + ds * ca.dot(ca.DM(collocation(S)[1]), f)
    tau = (target - S0) / (S1 - S0)
    basis = [_lagrange(tau_g, k).coef for k in range(S)]
    for _ in range(newton_steps if S > 1 else 0):   # S is linear in τ for S = 1
        value = state(zc, ds, z0, S0, tau)[3] - target
        slope = ds * sum(_poly(basis[k], tau) * f[k] for k in range(S))
        tau = tau - value / slope
    r, psi, z, _ = state(zc, ds, z0, S0, tau)
    return ca.Function("arclength_point", [zc, s0, ds, z0, S0, target],
                       [s0 + ds * tau, r, psi, z])


@lru_cache(maxsize=8)
def _increments(stages: int) -> ca.Function:
    """``(z_c, Δs) -> (Δz, ΔS)``: ∫ f_s sin ψ ds and ∫ f_s ds over one cell (Gauss rule)."""
    S = stages
    _, w, values, _, _, _ = collocation(S)
    zc, ds = ca.SX.sym("z_c", 3 * S + 2), ca.SX.sym("ds")
    f = zc[2 * S + 2:]
    psi_g = ca.mtimes(ca.DM(values), zc[S + 1:2 * S + 2])
    return ca.Function("increments", [zc, ds], [ds * ca.dot(ca.DM(w), f * ca.sin(psi_g)),
                                                ds * ca.dot(ca.DM(w), f)])
