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
The nodes are s_i = Σ + (L − P − Σ) t_i with a fixed graded mesh t_i in
[0, 1], so Σ and P are NLP parameters like h and the profile parameters.  The
grading concentrates nodes near free edges, whose boundary layers have width
δ = (h/√12)^(1/2) (Supplementary, toy problem 2), and near poles, where the
solution behaves like s^β with β not an integer (see
:mod:`morphoshell.reference`).
"""
from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np
from scipy.special import gamma, gammainc

from ._buffered import Buffered
from .energy import LOCAL_OUTPUTS, intrinsic_function, local_function, pointwise
from .geometry import get_geometry
from .problem import Structure

__all__ = ["graded_mesh", "boundary_layer_width", "pole_exponent", "Discretisation", "Layout"]


def boundary_layer_width(h: float) -> float:
    """δ = √ε, ε = h/√12: the width of the edge boundary layer (Supplementary)."""
    return float(np.sqrt(h / np.sqrt(12)))


def pole_exponent(stages: int) -> float:
    """Grading exponent q (s ∝ t^q) at poles that keeps order 2S.

    With a local solution ~ s^β the first cells cost O(N^(−2qβ)) and the
    others sum to O(N^(−2S)) if qβ > S; β ≥ 0.7 in the problems of the paper
    (measured, see ``reference._PoleSolution``), so q = 2S leaves a margin.
    """
    return 2.0 * stages


def graded_mesh(cells: int, length: float, start: str, end: str, width: float,
                ratio: float = 6.0, pole_width: float = 0.05, q: float = 2.0,
                edge_scale: float | None = None) -> np.ndarray:
    """Nodes t_0 = 0 < … < t_N = 1 of a smoothly graded mesh.

    The node density (per unit of t) is

        1 + (ratio − 1) exp(−d/ℓ)              near a free edge, ℓ = 3 width/length,
        + B ℓ_c [1/(d + ℓ_c) − 1/(d + ℓ)]      near a free edge, if ℓ_c < ℓ/3,
        + (d/ℓ_p)^(1/q − 1) exp(−d/ℓ_p)        near a pole, ℓ_p = pole_width,

    with d the distance to that end, so free edges get ``ratio`` times finer
    cells across their boundary layer and near a pole the nodes follow
    s ∝ t^q.  A free edge closer to the axis than the boundary-layer width
    (a cut Σ smaller than δ: ``edge_scale`` ℓ_c = Σ/length) also varies on
    the scale Σ, like log s between Σ and δ (the (σ + ξ) terms of the
    Supplementary's small-cut equations): the second term spends B ℓ_c = 5 %
    of the density per e-fold of d there.  The map t ↦ s is fixed and smooth,
    so refinement keeps the order of the scheme.

    Parameters
    ----------
    cells : int
    length : float
        Length of the shell in s (sets the free-edge grading in t).
    start, end : {"pole", "free"}
    width : float
        Boundary-layer width in s (see :func:`boundary_layer_width`).
    q : float
        Pole grading exponent (see :func:`pole_exponent`).
    """
    if cells < 2:
        raise ValueError(f"need at least 2 cells, got {cells}")
    ell = 3 * width / length
    ell_c = None if edge_scale is None else edge_scale / length
    small_edge = ell_c is not None and ell_c < ell / 3

    def cumulative(d, kind):
        # ∫₀^d of the extra density of an end of this kind
        if kind == "free":
            out = (ratio - 1) * ell * -np.expm1(-d / ell)
            if small_edge:
                out = out + 0.05 * (np.log1p(d / ell_c) - np.log1p(d / ell))
            return out
        return pole_width * gamma(1 / q) * gammainc(1 / q, d / pole_width)

    def W(x):
        return x + cumulative(x, start) + cumulative(1.0, end) - cumulative(1 - x, end)

    target = np.linspace(0.0, W(1.0), cells + 1)
    lo, hi = np.zeros_like(target), np.ones_like(target)
    for _ in range(60):   # bisection: W is increasing
        mid = (lo + hi) / 2
        below = W(mid) < target
        lo, hi = np.where(below, mid, lo), np.where(below, hi, mid)
    t = (lo + hi) / 2
    t[0], t[-1] = 0.0, 1.0
    return t


_CELL_CACHE: dict[tuple, dict[str, ca.Function]] = {}


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
        return self.cells * self.stages + 1

    @property
    def free_points(self) -> int:
        return self.points - self.start_pole - self.end_pole

    @property
    def size(self) -> int:
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
        sl = slice(1 if self.start_pole else 0, -1 if self.end_pole else None)
        return np.concatenate([np.asarray(r)[sl], np.asarray(psi)[sl], np.asarray(f)])


def _collocation(stages: int):
    """Lagrange basis on τ = 0, 1/S, …, 1 at the Gauss points, and Gauss data.

    Returns (tau_gauss, weights, values, derivatives, integrals) where
    values[k, l] = ℓ_l(τ_k), derivatives[k, l] = ℓ_l'(τ_k) and
    integrals[l, k] = ∫₀^{l/S} λ_k(τ) dτ for the Lagrange basis λ_k on the
    Gauss points (to integrate z' = f_s sin ψ to the interpolation points).
    """
    xg, wg = np.polynomial.legendre.leggauss(stages)
    tau, w = (xg + 1) / 2, wg / 2
    nodes = np.linspace(0.0, 1.0, stages + 1)
    values = np.zeros((stages, stages + 1))
    derivs = np.zeros((stages, stages + 1))
    for l in range(stages + 1):
        others = np.delete(nodes, l)
        poly = np.poly1d(others, r=True) / np.prod(nodes[l] - others)
        values[:, l], derivs[:, l] = poly(tau), poly.deriv()(tau)
    integrals = np.zeros((stages + 1, stages))
    for k in range(stages):
        others = np.delete(tau, k)
        poly = np.poly1d(others, r=True) / np.prod(tau[k] - others) if stages > 1 else np.poly1d([1.0])
        antideriv = poly.integ()
        integrals[:, k] = antideriv(nodes) - antideriv(0.0)
    return tau, w, values, derivs, integrals


class Discretisation:
    """The discrete energy and constraints for one (structure, mesh, stages).

    Each cell's energy terms and constraints depend on its 3S + 2 local
    unknowns z_c = (r at its S + 1 points, ψ at them, f_s at its S Gauss
    points) and on parameter-only *data* at its Gauss points,
    D = [s, Δs, weight, objective scale, h, ρ, profiles, η, α, β, γ].  Small SX
    functions give a cell's values, gradients and Hessian; they are mapped over
    the cells and scattered into the global gradient, Jacobian and Hessian by
    constant sparse matrices, so building the NLP costs about the same for any
    mesh.  The data are computed once per solve (:meth:`cell_data`) and are the
    NLP's parameter vector, so Ipopt's callbacks never re-evaluate profiles or
    coefficients.

    Parameters
    ----------
    structure : Structure
    t : ndarray
        Nodes in [0, 1] (see :func:`graded_mesh`).
    stages : int
        Gauss points per cell S (order 2S).

    Attributes
    ----------
    x : casadi.MX
        Unknowns [r_free, ψ_free, f_s].
    D : casadi.MX
        NLP parameters: the Gauss-point data, column-major (n_D × cells S).
    p : casadi.MX
        Physical parameters [h, Σ, P, family...]; ``pre(p)`` gives ``D``.
    energy, objective : casadi.MX
        Total energy 𝓔(x, D) and the scaled objective handed to Ipopt.
    g : casadi.MX
        Compatibility constraints (cells S,), all equalities g = 0.
    grad_f, jac_g, hess_lag : casadi.Function
        Exact derivatives in the signatures of ``nlpsol``'s options.
    """

    def __init__(self, structure: Structure, t: np.ndarray, stages: int = 2):
        if stages not in (1, 2, 3):
            raise ValueError(f"stages = {stages!r} must be 1, 2 or 3")
        self.structure = structure
        self.geometry = get_geometry(structure.geometry)
        self.t = np.asarray(t, dtype=float)
        self.stages = S = stages
        cells = len(self.t) - 1
        self.layout = lay = Layout(cells, S, structure.start == "pole", structure.end == "pole")
        self.local = local_function(structure)
        tau, w, self._values, self._derivs, self._integrals = _collocation(S)
        self.tau, self.weights = tau, w
        n_p = self.local.size1_in(5)
        n = lay.size
        # Points in t: nodes and interior interpolation points; Gauss points.
        self.t_points = np.concatenate(
            [self.t[:-1, None] + np.diff(self.t)[:, None] * np.arange(S)[None, :] / S]
            + [], axis=None) if S > 1 else self.t[:-1].copy()
        self.t_points = np.append(self.t_points.ravel(), 1.0)
        t_gauss = (self.t[:-1, None] + np.diff(self.t)[:, None] * tau[None, :]).ravel()
        dt_gauss = np.repeat(np.diff(self.t), S)
        w_gauss = np.tile(w, cells)

        self.p = ca.MX.sym("p", n_p)
        pre = self._pre_function(n_p, cells)
        m = cells * S
        self.pre = ca.Function("cell_data", [self.p],
                               [ca.vec(pre.map(m)(ca.DM(t_gauss).T, ca.DM(dt_gauss).T,
                                                  ca.DM(w_gauss).T, self.p))], ["p"], ["D"])
        n_D = pre.size1_out(0)
        self.x = ca.MX.sym("x", n)
        self.D = ca.MX.sym("D", n_D * m)
        Dc = ca.reshape(self.D, n_D * S, cells)   # one column per cell

        idx = self._cell_indices()
        n_loc = idx.shape[0]
        # Gather the local unknowns of every cell (constants appended to x).
        xfull = ca.vertcat(self.x, ca.DM([0.0, 0.0, np.pi]))
        Z = ca.reshape(xfull[idx.ravel(order="F").tolist()], n_loc, cells)
        cell = self._cell_functions(n_D)
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

    def _pre_function(self, n_p: int, cells: int) -> ca.Function:
        """``(t_k, Δt_c, w_k, p) -> D_k``: parameter-only data at one Gauss point."""
        tk, dt, wk, p = ca.SX.sym("tk"), ca.SX.sym("dt"), ca.SX.sym("wk"), ca.SX.sym("p", n_p)
        a, b = p[1], self.geometry.length - p[2]
        s_k = a + (b - a) * tk
        # Energies range over decades with h (bending ~ h³): dividing by h³
        # and by the mean cell size keeps Ipopt's gradients O(1).
        scale = cells / (2 * ca.pi * p[0] ** 3 * (b - a))
        I = intrinsic_function(self.structure)(s_k, p)
        return ca.Function("pre", [tk, dt, wk, p], [ca.vertcat(s_k, (b - a) * dt, wk, scale, p[0], I)])

    def _cell_functions(self, n_D: int) -> dict[str, ca.Function]:
        """Values, gradients and the Lagrangian's triu Hessian of one cell (SX).

        They depend on the structure and the number of stages only, so meshes
        of one structure share them.
        """
        key = (self.structure, self.stages)
        if key not in _CELL_CACHE:
            _CELL_CACHE[key] = self._build_cell_functions(n_D)
        return _CELL_CACHE[key]

    def _build_cell_functions(self, n_D: int) -> dict[str, ca.Function]:
        S = self.stages
        z, D = ca.SX.sym("z", 3 * S + 2), ca.SX.sym("D", n_D * S)
        sigma, lam = ca.SX.sym("sigma"), ca.SX.sym("lam", S)
        zr, zp, zf = z[:S + 1], z[S + 1:2 * S + 2], z[2 * S + 2:]
        V, Dv = ca.DM(self._values), ca.DM(self._derivs)
        energy, g, fields = 0, [], []
        for k in range(S):
            Dk = D[k * n_D:(k + 1) * n_D]
            s_k, ds, wk, scale, h, I = Dk[0], Dk[1], Dk[2], Dk[3], Dk[4], Dk[5:]
            r_k, psi_k = ca.dot(V[k, :].T, zr), ca.dot(V[k, :].T, zp)
            dr_k, dpsi_k = ca.dot(Dv[k, :].T, zr) / ds, ca.dot(Dv[k, :].T, zp) / ds
            point = pointwise(r_k, psi_k, zf[k], dpsi_k, I, h)
            energy += wk * ds * point["L"]
            g.append(dr_k - zf[k] * ca.cos(psi_k))
            fields.append(ca.vertcat(s_k, ds, wk, r_k, psi_k, zf[k], dpsi_k,
                                     *[point[name] for name in LOCAL_OUTPUTS[:10]], I))
        scale = D[3]
        ell = energy * scale
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

    def points(self, p: np.ndarray) -> np.ndarray:
        """Arclength s of the points (nodes and interior points) for parameters ``p``."""
        a, b = p[1], self.geometry.length - p[2]
        return a + (b - a) * self.t_points

    def initial_guess(self, p: np.ndarray) -> np.ndarray:
        """The undeformed shell: r = ρ, ψ = ψ₀, f_s = 1."""
        rho, _, psi0 = self.geometry.numeric(self.points(p))
        return self.layout.pack(rho, psi0, np.ones(self.layout.cells * self.stages))

    def cell_data(self, p: np.ndarray) -> np.ndarray:
        """The NLP parameter vector D for physical parameters ``p``."""
        if not hasattr(self, "_pre_buffered"):
            self._pre_buffered = Buffered(self.pre)
        return self._pre_buffered(p)[0]

    def gauss_fields(self, x: np.ndarray, D: np.ndarray) -> dict[str, np.ndarray]:
        """Every pointwise quantity at the Gauss points, given the data ``D``."""
        if not hasattr(self, "_fields_buffered"):
            self._fields_buffered = Buffered(self._fields)
        out = self._fields_buffered(x, D)[0].reshape(-1, len(self._field_names)).T
        return dict(zip(self._field_names, out))

    def integrate_to_points(self, values: np.ndarray) -> np.ndarray:
        """∫ from the start to every point of a function known at the Gauss points.

        Exact for the degree S − 1 interpolant of ``values`` (z' = f_s sin ψ).
        """
        S, cells = self.stages, self.layout.cells
        ds = np.diff(self.t)  # in t; the caller scales by the shell length
        v = values.reshape(cells, S)
        partial = ds[:, None] * (v @ self._integrals.T)      # (cells, S + 1): to each point
        start = np.concatenate([[0.0], np.cumsum(partial[:, -1])])
        out = (start[:-1, None] + partial[:, :-1]).ravel()
        return np.append(out, start[-1])
