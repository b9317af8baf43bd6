"""Second-order discretisation of the shell energy as a parametric NLP.

Scheme
------
Nodes s_0 < … < s_N carry r and ψ; cell centres s_c = (s_i + s_{i+1})/2 carry
the meridional stretch f_s.  The energy is the midpoint rule

    𝓔 ≈ Σ_c L(s_c, r_c, ψ_c, f_s,c, ψ'_c) Δs_c,   L = 2π ρ e,

with r_c, ψ_c the averages of the neighbouring nodes and ψ'_c = Δψ/Δs, and
the compatibility r' = f_s cos ψ is imposed as N equality constraints

    (r_{i+1} − r_i)/Δs_c − f_s,c cos ψ_c = 0.

Nothing is evaluated on the axis (cell centres never lie on a pole), the
scheme is second order on smoothly graded meshes, and the problem has only
equality constraints, so that derivatives of the solution with respect to
the parameters (implicit function theorem on the KKT system) are exact.

Poles are imposed by constants (r = 0, ψ = 0 at the start, ψ = π at the end);
free edges need nothing: the no-force, no-torque conditions are natural.

Parametric mesh
---------------
The nodes are s_i = Σ + (L − P − Σ) t_i with a fixed graded mesh t_i in
[0, 1], so Σ and P are NLP parameters like h and the profile parameters.  The
grading concentrates nodes near free edges, whose boundary layers have width
δ = (h/√12)^(1/2) (Supplementary, toy problem 2).
"""
from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np
from scipy.special import erf

from .energy import intrinsic_function, local_function, pointwise, LOCAL_OUTPUTS
from .geometry import get_geometry
from ._buffered import Buffered
from .problem import Structure

__all__ = ["graded_mesh", "boundary_layer_width", "Discretisation"]


def boundary_layer_width(h: float) -> float:
    """δ = √ε, ε = h/√12: the width of the edge boundary layer (Supplementary)."""
    return float(np.sqrt(h / np.sqrt(12)))


def graded_mesh(cells: int, length: float, start: str, end: str, width: float,
                ratio: float = 6.0, pole_width: float = 0.05) -> np.ndarray:
    """Nodes t_0 = 0 < … < t_N = 1 of a smoothly graded mesh.

    The node density (per unit of t) is

        1 + (ratio − 1) exp(−d/ℓ)              near a free edge, ℓ = 3 width/length,
        + (d/ℓ_p)^(−1/2) exp(−d/ℓ_p)           near a pole, ℓ_p = pole_width,

    with d the distance to that end.  Free edges thus get ``ratio`` times
    finer cells across their boundary layer; near a pole the nodes follow
    s ∝ t², which restores second order for the weakly singular s^β
    behaviour of the solution there (see :mod:`morphoshell.reference`).
    The map t ↦ s is fixed, so refinement keeps the order of the scheme.

    Parameters
    ----------
    cells : int
    length : float
        Length of the shell in s (sets the free-edge grading in t).
    start, end : {"pole", "free"}
    width : float
        Boundary-layer width in s (see :func:`boundary_layer_width`).
    """
    if cells < 4:
        raise ValueError(f"need at least 4 cells, got {cells}")
    ell = 3 * width / length

    def cumulative(d, kind):
        # ∫₀^d of the extra density of an end of this kind
        if kind == "free":
            return (ratio - 1) * ell * -np.expm1(-d / ell)
        return pole_width * np.sqrt(np.pi) * erf(np.sqrt(d / pole_width))

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


@dataclass(frozen=True)
class Layout:
    """Where the unknowns sit in the NLP vector x = [r_free, ψ_free, f_s]."""

    cells: int
    start_pole: bool
    end_pole: bool

    @property
    def nodes(self) -> int:
        return self.cells + 1

    @property
    def free_nodes(self) -> int:
        return self.nodes - self.start_pole - self.end_pole

    @property
    def size(self) -> int:
        return 2 * self.free_nodes + self.cells

    def split(self, x):
        """Full nodal r, ψ and cell f_s from x (NumPy or CasADi)."""
        n = self.free_nodes
        r, psi, f = x[:n], x[n:2 * n], x[2 * n:]
        return self._pad(r, 0.0, 0.0), self._pad(psi, 0.0, np.pi), f

    def _pad(self, v, start, end):
        if isinstance(v, np.ndarray):
            parts = ([np.array([start])] if self.start_pole else []) + [v] + \
                    ([np.array([end])] if self.end_pole else [])
            return np.concatenate(parts)
        parts = ([ca.DM(start)] if self.start_pole else []) + [v] + \
                ([ca.DM(end)] if self.end_pole else [])
        return ca.vertcat(*parts)

    def pack(self, r, psi, f) -> np.ndarray:
        sl = slice(1 if self.start_pole else 0, -1 if self.end_pole else None)
        return np.concatenate([np.asarray(r)[sl], np.asarray(psi)[sl], np.asarray(f)])


class Discretisation:
    """The discrete energy and constraints for one (structure, mesh).

    The energy is a sum of cell terms, each depending on the five local
    unknowns z_c = (r_i, r_{i+1}, ψ_i, ψ_{i+1}, f_s,c) and on parameter-only
    *cell data* D_c = [Δs, objective scale, h, ρ, profiles, η, α, β, γ]; so
    are the constraints.  Small SX functions give a cell's values, gradients
    and 5×5 Hessian; they are mapped over the cells and scattered into the
    global gradient, Jacobian and Hessian by constant sparse matrices, so
    building the NLP costs the same for any number of cells.  The cell data
    are computed once per solve (:meth:`cell_data`) and are the NLP's
    parameter vector, so Ipopt's callbacks never re-evaluate profiles or
    coefficients.

    Parameters
    ----------
    structure : Structure
    t : ndarray
        Nodes in [0, 1] (see :func:`graded_mesh`).

    Attributes
    ----------
    x : casadi.MX
        Unknowns [r_free, ψ_free, f_s].
    D : casadi.MX
        NLP parameters: the cell data, column-major (n_D × cells).
    p : casadi.MX
        Physical parameters [h, Σ, P, family...]; ``pre(p)`` gives ``D``.
    energy, objective : casadi.MX
        Total energy 𝓔(x, D) and the scaled objective handed to Ipopt.
    g : casadi.MX
        Compatibility constraints (N,), all equalities g = 0.
    grad_f, jac_g, hess_lag : casadi.Function
        Exact derivatives in the signatures of ``nlpsol``'s options.
    """

    def __init__(self, structure: Structure, t: np.ndarray):
        self.structure = structure
        self.geometry = get_geometry(structure.geometry)
        self.t = np.asarray(t, dtype=float)
        cells = len(self.t) - 1
        self.layout = Layout(cells, structure.start == "pole", structure.end == "pole")
        self.local = local_function(structure)
        n_p = self.local.size1_in(5)
        n = self.layout.size
        tc = ca.DM((self.t[1:] + self.t[:-1]).reshape(1, -1) / 2)
        dt = ca.DM(np.diff(self.t).reshape(1, -1))

        self.p = ca.MX.sym("p", n_p)
        pre = self._pre_function(n_p, cells)
        self.pre = ca.Function("cell_data", [self.p], [ca.vec(pre.map(cells)(tc, dt, self.p))],
                               ["p"], ["D"])
        n_D = pre.size1_out(0)
        self.x = ca.MX.sym("x", n)
        self.D = ca.MX.sym("D", n_D * cells)
        D = ca.reshape(self.D, n_D, cells)

        idx = self._cell_indices()
        # Gather the local unknowns of every cell (constants appended to x).
        xfull = ca.vertcat(self.x, ca.DM([0.0, 0.0, np.pi]))
        Z = ca.reshape(xfull[list(idx.ravel(order="F"))], 5, cells)
        cell = self._cell_functions(n_D)
        sigma, lam = ca.MX.sym("lam_f"), ca.MX.sym("lam_g", cells)
        ell = cell["f"].map(cells)(Z, D)
        self.objective = ca.sum2(ell)
        self.energy = ca.sum2(cell["energy"].map(cells)(Z, D))
        self.g = cell["g"].map(cells)(Z, D).T
        ell2, dell = cell["grad"].map(cells)(Z, D)
        g2, dg = cell["jac"].map(cells)(Z, D)
        hess = cell["hess"].map(cells)(Z, D, sigma, lam.T)

        free = idx < n  # which local slots are unknowns
        cols = np.arange(5 * cells).reshape(cells, 5).T  # column-major position of (k, c)
        A = ca.DM(ca.Sparsity.triplet(n, 5 * cells, idx[free].tolist(), cols[free].tolist()),
                  np.ones(int(free.sum())))
        grad = ca.mtimes(A, ca.vec(dell))
        rows_j = np.broadcast_to(np.arange(cells), (5, cells))
        J = self._assemble((cells, n), rows_j[free], idx[free], cols[free], ca.vec(dg), 5 * cells)
        k, l = np.triu_indices(5)
        I, Jc = idx[k], idx[l]
        ok = (I < n) & (Jc < n)
        src = (np.arange(15)[:, None] + 15 * np.arange(cells)[None, :])[ok]
        H = self._assemble((n, n), np.minimum(I, Jc)[ok], np.maximum(I, Jc)[ok], src,
                           ca.vec(hess), 15 * cells)
        self.grad_f = ca.Function("grad_f", [self.x, self.D], [ca.sum2(ell2), grad],
                                  ["x", "p"], ["f", "grad_f_x"])
        self.jac_g = ca.Function("jac_g", [self.x, self.D], [g2.T, J], ["x", "p"], ["g", "jac_g_x"])
        self.hess_lag = ca.Function("hess_lag", [self.x, self.D, sigma, lam], [H],
                                    ["x", "p", "lam_f", "lam_g"], ["triu_hess_gamma_x_x"])

        # Fields for the result, from the same cell data (one stacked output,
        # so a single copy to NumPy per solve).
        r_c, psi_c = (Z[0, :] + Z[1, :]) / 2, (Z[2, :] + Z[3, :]) / 2
        dpsi, f = (Z[3, :] - Z[2, :]) / D[0, :], Z[4, :]
        point = cell["point"].map(cells)(Z, D)
        self._field_names = ("s_c", "ds", "r_c", "psi_c", "f_s", "dpsi", *LOCAL_OUTPUTS)
        self._fields = ca.Function("fields", [self.x, self.D],
                                   [ca.vertcat(D[3, :], D[0, :], r_c, psi_c, f, dpsi, point, D[4:, :])])

    def _pre_function(self, n_p: int, cells: int) -> ca.Function:
        """``(t_c, Δt_c, p) -> D_c``: one cell's parameter-only data."""
        tc, dt, p = ca.SX.sym("tc"), ca.SX.sym("dt"), ca.SX.sym("p", n_p)
        a, b = p[1], self.geometry.length - p[2]
        ds = (b - a) * dt
        # Energies range over decades with h (bending ~ h³): dividing by h³
        # and by the mean cell size keeps Ipopt's gradients O(1).
        scale = cells / (2 * ca.pi * p[0] ** 3 * (b - a))
        s_c = a + (b - a) * tc
        I = intrinsic_function(self.structure)(s_c, p)
        return ca.Function("pre", [tc, dt, p], [ca.vertcat(ds, scale, p[0], s_c, I)])

    def _cell_functions(self, n_D: int) -> dict[str, ca.Function]:
        """Values, gradients and the Lagrangian's triu Hessian of one cell (SX)."""
        z, D = ca.SX.sym("z", 5), ca.SX.sym("D", n_D)
        sigma, lam = ca.SX.sym("sigma"), ca.SX.sym("lam")
        ds, scale, h, I = D[0], D[1], D[2], D[4:]
        psi_c = (z[2] + z[3]) / 2
        energy = pointwise((z[0] + z[1]) / 2, psi_c, z[4], (z[3] - z[2]) / ds, I, h)["L"] * ds
        ell = energy * scale
        g = (z[1] - z[0]) / ds - z[4] * ca.cos(psi_c)
        H = ca.hessian(sigma * ell + lam * g, z)[0]
        k, l = np.triu_indices(5)
        point = pointwise((z[0] + z[1]) / 2, psi_c, z[4], (z[3] - z[2]) / ds, I, h)
        return {
            "point": ca.Function("cell_point", [z, D], [ca.vertcat(*[point[k] for k in LOCAL_OUTPUTS[:10]])]),
            "f": ca.Function("cell_f", [z, D], [ell]),
            "energy": ca.Function("cell_energy", [z, D], [energy]),
            "g": ca.Function("cell_g", [z, D], [g]),
            "grad": ca.Function("cell_grad", [z, D], [ell, ca.gradient(ell, z)]),
            "jac": ca.Function("cell_jac", [z, D], [g, ca.gradient(g, z)]),
            "hess": ca.Function("cell_hess", [z, D, sigma, lam],
                                [ca.vertcat(*[H[int(i), int(j)] for i, j in zip(k, l)])]),
        }

    def cell_data(self, p: np.ndarray) -> np.ndarray:
        """The NLP parameter vector D for physical parameters ``p``."""
        if not hasattr(self, "_pre_buffered"):
            self._pre_buffered = Buffered(self.pre)
        return self._pre_buffered(p)[0]

    def _cell_indices(self) -> np.ndarray:
        """(5, cells) positions of each cell's local unknowns in [x, constants]."""
        lay, n = self.layout, self.layout.size
        nodes = np.arange(lay.nodes)
        r_idx = nodes - lay.start_pole
        psi_idx = lay.free_nodes + nodes - lay.start_pole
        if lay.start_pole:
            r_idx[0], psi_idx[0] = n, n + 1
        if lay.end_pole:
            r_idx[-1], psi_idx[-1] = n, n + 2
        f_idx = 2 * lay.free_nodes + np.arange(lay.cells)
        return np.vstack([r_idx[:-1], r_idx[1:], psi_idx[:-1], psi_idx[1:], f_idx])

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

    def nodes(self, p: np.ndarray) -> np.ndarray:
        """Node positions s_i for parameters ``p``."""
        a, b = p[1], self.geometry.length - p[2]
        return a + (b - a) * self.t

    def initial_guess(self, p: np.ndarray) -> np.ndarray:
        """The undeformed shell: r = ρ, ψ = ψ₀, f_s = 1."""
        s = self.nodes(p)
        rho, _, psi0 = self.geometry.numeric(s)
        if self.layout.start_pole:
            rho[0] = 0.0
        if self.layout.end_pole:
            rho[-1] = 0.0
        return self.layout.pack(rho, psi0, np.ones(self.layout.cells))

    def cell_fields(self, x: np.ndarray, D: np.ndarray) -> dict[str, np.ndarray]:
        """Every pointwise quantity at the cell centres, given the cell data ``D``."""
        if not hasattr(self, "_fields_buffered"):
            self._fields_buffered = Buffered(self._fields)
        out = self._fields_buffered(x, D)[0].reshape(-1, len(self._field_names)).T
        return dict(zip(self._field_names, out))
