"""Derivatives of the KKT conditions beyond the Newton system: what fits need.

A fit that keeps the equilibrium as constraints of a larger NLP (the KKT fit of
:mod:`morphoshell.fitting`) needs the curvature of the KKT residual
F = (∇f + Jᵀλ, g) in (x, λ), and its derivatives in the fitted parameters θ
through the cell data D (T = ∂D/∂θ).  Differentiating the assembled graph is far too
slow on real meshes, so, as for the NLP's own derivatives, each is one small kernel
per cell, mapped over the cells and summed into place by constant index patterns
(:mod:`morphoshell.numerics.gathers`):

* :meth:`KKTDerivatives.curvature`: the upper triangle of
  ∂²/∂(x, λ)² [μ_F·F − Σ_c (μ_dz,c Δz_c + μ_dS,c ΔS_c)] (third derivatives of the
  cell energy; Δz_c, ΔS_c the cell increments of :func:`morphoshell.numerics.shape.increments`);
* :meth:`KKTDerivatives.curvature_theta`: that function's curvature across D along T;
* :meth:`KKTDerivatives.residual_theta` and :meth:`KKTDerivatives.residual_theta_numeric`:
  ∂F/∂θ = (∂F/∂D) T, as expressions and in numbers.

The derivatives in D are taken once per scheme (and compiled where possible); the
directions T are contracted with them afterwards, so the compiled code does not
depend on the fitted parameters.
"""
from __future__ import annotations

from functools import lru_cache

import casadi as ca
import numpy as np

from .._runtime.buffered import Buffered
from .._runtime.compiled import LARGE, compiled_point_function
from ..model.layouts import CELL_DATA
from .cell_kernels import cell_functions
from .gathers import assembled, gather, scatter, triu
from .scheme import Layout
from .shape import increments

__all__ = ["KKTDerivatives"]


class KKTDerivatives:
    """The KKT residual's curvature and θ-derivatives of one transcription, cell by cell.

    Parameters
    ----------
    layout : Layout
        The transcription's layout: n = ``layout.size`` unknowns, m = cells S constraints.
    idx : ndarray of int, shape (3S + 2, cells)
        Each cell's unknowns in [x, pole values] (:meth:`Layout.cell_indices`).
    kkt_data : casadi.Function
        The cell kernel ``"kkt_data"`` of :func:`morphoshell.numerics.cell_kernels.cell_functions`
        (compiled or not): ``(z, D, λ) -> ∂F_c/∂D``.
    cell_unknowns : callable
        ``x -> (3S + 2, cells)`` each cell's unknowns, as expressions.
    local : callable
        ``() -> (Z, D_c)``: the cells' unknowns and data as expressions of the
        symbols ``x`` and ``D``.
    x, D : casadi.MX
        The symbols of the unknowns (n,) and of the cell data.
    """

    def __init__(self, layout: Layout, idx: np.ndarray, kkt_data: ca.Function, cell_unknowns,
                 local, x: ca.MX, D: ca.MX):
        self.layout, self._idx, self._idx_flat = layout, idx, idx.ravel(order="F")
        self._kkt_data_kernel, self._cell_unknowns, self._local = kkt_data, cell_unknowns, local
        self._x, self._D = x, D
        self._theta_scatters: dict = {}
        self._numeric_data = None

    @property
    def _constraints(self) -> int:
        return self.layout.cells * self.layout.stages

    def curvature(self, x, lam, D, mu_F, mu_dz, mu_dS, ds) -> ca.MX:
        """Upper triangle of ∂²/∂(x, λ)² [μ_F·F(x, λ) − Σ_c (μ_dz,c Δz_c + μ_dS,c ΔS_c)].

        Assembled from one SX kernel per cell (third derivatives of the cell
        energy), as the NLP's Hessian is.  Shapes: x (n,), λ (m,), μ_F (n + m,),
        μ_dz, μ_dS and ds (cells,); the result is (n + m) × (n + m), sparse.
        """
        n, S, cells = self.layout.size, self.layout.stages, self.layout.cells
        n_loc = self._idx.shape[0]
        mu_x = ca.vertcat(mu_F[:n], ca.DM.zeros(3))      # constants: no stationarity row
        Mz = ca.reshape(mu_x[self._idx_flat.tolist()], n_loc, cells)
        kernel = _cell_kkt_curvature(S).map(cells)
        values = kernel(self._cell_unknowns(x), ca.reshape(D, -1, cells),
                        ca.reshape(lam, S, cells), Mz, ca.reshape(mu_F[n:], S, cells),
                        ca.reshape(mu_dz, 1, cells), ca.reshape(mu_dS, 1, cells),
                        ca.reshape(ds, 1, cells))
        return assembled(*self._local_kkt_gather(), values)

    def curvature_theta(self, x, lam, D, T, mu_F, mu_dz, mu_dS) -> tuple:
        """The curvature of :meth:`curvature`'s function across the cell data D.

        With D moving along D + T t (T = ∂D/∂θ, rows as D, k columns) and the
        cell widths read from D.  The second derivatives of D itself are the
        caller's (they need the parameters).  Per-cell kernels, the derivatives
        in D compiled and contracted with T afterwards.

        Returns
        -------
        cross : casadi.MX, shape (n + m, k)
            The mixed block ∂²/∂(x, λ)∂t (sparse rows).
        tt : casadi.MX, shape (k, k)
            The block ∂²/∂t².
        grad : casadi.MX, shape (len(D),)
            The gradient ∂/∂D.
        """
        n = self.layout.size
        S, cells = self.layout.stages, self.layout.cells
        n_loc, k = self._idx.shape[0], T.shape[1]
        mu_x = ca.vertcat(mu_F[:n], ca.DM.zeros(3))      # constants: no stationarity row
        Mz = ca.reshape(mu_x[self._idx_flat.tolist()], n_loc, cells)
        X, H, grad = _compiled_kkt_data_curvature(S).map(cells)(
            self._cell_unknowns(x), ca.reshape(D, -1, cells), ca.reshape(lam, S, cells), Mz,
            ca.reshape(mu_F[n:], S, cells), ca.reshape(mu_dz, 1, cells),
            ca.reshape(mu_dS, 1, cells))
        cross, tt = _cell_kkt_theta(S, k).map(cells)(X, H, self._cell_rows(T))
        return self._local_theta(cross, k), ca.reshape(ca.sum2(tt), k, k), ca.vec(grad)

    def residual_theta(self, x, lam, D, T) -> ca.MX:
        """∂F/∂θ = (∂F/∂D) T of the KKT residual F = (∇f + Jᵀλ, g), cell by cell.

        T = ∂D/∂θ (rows as D, k columns).  One SX kernel per cell.  Returns
        (n + m) × k, sparse rows.
        """
        S, cells = self.layout.stages, self.layout.cells
        k = T.shape[1]
        F_D = self._kkt_data_kernel.map(cells)(
            self._cell_unknowns(x), ca.reshape(D, -1, cells), ca.reshape(lam, S, cells))
        return self._local_theta(_cell_kkt_dtheta(S, k).map(cells)(F_D, self._cell_rows(T)), k)

    def residual_theta_numeric(self, x: np.ndarray, lam: np.ndarray, D: np.ndarray,
                               T: np.ndarray) -> np.ndarray:
        """:meth:`residual_theta`'s (∂F/∂D) T in numbers, shape (n + m, k), dense.

        Each cell's ∂F/∂D by the cell kernel ``kkt_data`` (compiled where
        possible), times the cell's rows of T by NumPy and summed into place by
        the scatter of :meth:`_local_theta`, in place of the assembled ∂F/∂D
        (an MX Jacobian) times T.
        """
        S, cells = self.layout.stages, self.layout.cells
        kernel, rows, B = self._numeric_kkt_data()
        n_cell, n_blk = len(CELL_DATA) * S, self._idx.shape[0] + S
        T = np.asarray(T, dtype=float)
        # blocks[c, j, i] = ∂F_i/∂D_j of cell c; T's rows of cell c follow its D
        blocks = kernel(x, D, lam)[0].reshape(cells, n_cell, n_blk)
        local = np.matmul(blocks.transpose(0, 2, 1), T.reshape(cells, n_cell, T.shape[1]))
        out = np.zeros((self.layout.size + self._constraints, T.shape[1]))
        out[rows] = B @ local.reshape(cells * n_blk, T.shape[1])
        return out

    def _numeric_kkt_data(self) -> tuple:
        """(evaluator of the cells' ∂F/∂D blocks, rows of the scatter, its matrix as CSR),
        built on first use."""
        if self._numeric_data is None:
            import scipy.sparse   # on use, as in parametric: keeps the package's start-up fast

            S, cells = self.layout.stages, self.layout.cells
            lam_s = ca.MX.sym("lam", self._constraints)
            blocks = self._kkt_data_kernel.map(cells)(*self._local(),
                                                      ca.reshape(lam_s, S, cells))
            sp, B = self._theta_scatter(1)
            self._numeric_data = (
                Buffered(ca.Function("kkt_data", [self._x, self._D, lam_s], [blocks])),
                np.array(sp.row()), scipy.sparse.csr_matrix(B.sparse()))
        return self._numeric_data

    def _local_kkt_gather(self) -> tuple:
        """(sparsity, first, extras) of :func:`~morphoshell.numerics.gathers.gather`: each
        cell's triu (x, λ) block in the upper triangle of the (n + m)² matrix.

        The cell's local slots are its unknowns (constants drop out) and its
        S constraints.
        """
        n, m = self.layout.size, self._constraints
        S, cells = self.layout.stages, self.layout.cells
        n_loc = self._idx.shape[0]
        local = self._local_slots()
        ku, lu = triu(n_loc + S)
        I, J = local[ku], local[lu]
        ok = (I >= 0) & (J >= 0)
        n_tri = len(ku)
        src = (np.arange(n_tri)[:, None] + n_tri * np.arange(cells)[None, :])[ok]
        rows, cols = np.minimum(I, J)[ok], np.maximum(I, J)[ok]
        return gather((n + m, n + m), rows, cols, src, n_tri * cells)

    def _cell_rows(self, T) -> ca.MX:
        """T's rows cell by cell, each cell's block flattened row by row (one column per cell)."""
        cells, k = self.layout.cells, T.shape[1]
        n_cell = len(CELL_DATA) * self.layout.stages
        return ca.reshape(ca.reshape(T, n_cell, cells * k).T, cells, n_cell * k).T

    def _local_slots(self) -> np.ndarray:
        """Global (x, λ) index of each cell's local slot (its unknowns, then its S
        constraints; −1 for the constants), ((3S + 2) + S) × cells."""
        n, S, cells = self.layout.size, self.layout.stages, self.layout.cells
        return np.vstack([np.where(self._idx < n, self._idx, -1),
                          n + np.arange(cells)[None, :] * S + np.arange(S)[:, None]])

    def _local_theta(self, cross, k: int) -> ca.MX:
        """Scatter of the cells' ((3S + 2) + S) × k blocks (side by side) into (n + m) × k."""
        sp, B = self._theta_scatter(k)
        return ca.MX(sp, ca.mtimes(B, ca.vec(cross)))

    def _theta_scatter(self, k: int) -> tuple:
        """(sparsity, B) of :meth:`_local_theta`, built once per k (the KKT fit's
        Jacobian and Hessian share it)."""
        if k not in self._theta_scatters:
            n, m, cells = self.layout.size, self._constraints, self.layout.cells
            local = self._local_slots()
            # cell c's local row i, column j sits at i + n_blk (c k + j) of vec(cross)
            n_blk = local.shape[0]
            rows = np.repeat(local.T[:, :, None], k, axis=2)
            cols = np.broadcast_to(np.arange(k), rows.shape)
            src = (np.arange(n_blk)[None, :, None]
                   + n_blk * (k * np.arange(cells)[:, None, None] + np.arange(k)[None, None, :]))
            ok = rows >= 0
            self._theta_scatters[k] = scatter((n + m, k), rows[ok], cols[ok], src[ok],
                                              n_blk * cells * k)
        return self._theta_scatters[k]


# -- the cell kernels ------------------------------------------------------------------

@lru_cache(maxsize=None)
def _cell_kkt_curvature(stages: int) -> ca.Function:
    """One cell's triu ∂²/∂(z, λ)² of μ_z·(∇ℓ + ∇gᵀλ) + μ_λ·g − a Δz − b ΔS (SX)."""
    S = stages
    n_D = len(CELL_DATA)
    z, D, lam = ca.SX.sym("z", 3 * S + 2), ca.SX.sym("D", n_D * S), ca.SX.sym("lam", S)
    mz, ml = ca.SX.sym("mu_z", 3 * S + 2), ca.SX.sym("mu_lam", S)
    a, b, ds = ca.SX.sym("mu_dz"), ca.SX.sym("mu_dS"), ca.SX.sym("ds")
    dz, dS = increments(S)(z, ds)
    phi = ca.dot(ca.vertcat(mz, ml), cell_functions(S)["kkt"](z, D, lam)) - a * dz - b * dS
    H = ca.hessian(phi, ca.vertcat(z, lam))[0]
    ku, lu = np.triu_indices(4 * S + 2)
    return ca.Function("cell_kkt_curvature", [z, D, lam, mz, ml, a, b, ds],
                       [ca.vertcat(*[H[int(i), int(j)] for i, j in zip(ku, lu)])])


@lru_cache(maxsize=None)
def _cell_kkt_data_curvature(stages: int) -> tuple:
    """One cell's second derivatives of :func:`_cell_kkt_curvature`'s function in D (SX).

    ``(z, D, λ, μ_z, μ_λ, a, b) -> (X, H, g)``: the structural nonzeros of
    X = ∂²φ/∂D∂(z, λ) and of the upper triangle H of ∂²φ/∂D², and g = ∂φ/∂D;
    the cell width is D's.  Independent of the fitted parameters (the
    directions θ are :func:`_cell_kkt_theta`'s), so it is compiled once, and
    stays small: the same blocks taken along k directions grow with k (and so
    does the compiler's time).  Returned with the sparsities of X and H.
    """
    S = stages
    n_D = len(CELL_DATA)
    z, D, lam = ca.SX.sym("z", 3 * S + 2), ca.SX.sym("D", n_D * S), ca.SX.sym("lam", S)
    mz, ml = ca.SX.sym("mu_z", 3 * S + 2), ca.SX.sym("mu_lam", S)
    a, b = ca.SX.sym("mu_dz"), ca.SX.sym("mu_dS")
    dz, dS = increments(S)(z, D[CELL_DATA.index("ds")])
    phi = ca.dot(ca.vertcat(mz, ml), cell_functions(S)["kkt"](z, D, lam)) - a * dz - b * dS
    g = ca.gradient(phi, D)
    X, H = ca.jacobian(g, ca.vertcat(z, lam)), ca.triu(ca.jacobian(g, D))
    return ca.Function("cell_kkt_data_curvature", [z, D, lam, mz, ml, a, b],
                       [ca.vertcat(*X.nonzeros()), ca.vertcat(*H.nonzeros()), g]), \
        X.sparsity(), H.sparsity()


@lru_cache(maxsize=None)
def _compiled_kkt_data_curvature(stages: int) -> ca.Function:
    """:func:`_cell_kkt_data_curvature` compiled for evaluation (at :data:`LARGE`'s level)."""
    return compiled_point_function(_cell_kkt_data_curvature(stages)[0], LARGE)


@lru_cache(maxsize=None)
def _cell_kkt_theta(stages: int, k: int) -> ca.Function:
    """One cell's curvature of :func:`_cell_kkt_curvature`'s function along D + T t (MX).

    ``(X, H, T) -> (∂²/∂(z, λ)∂t ((4S + 2) × k), ∂²/∂t² (k², column-major))``
    at t = 0 from :func:`_cell_kkt_data_curvature`'s blocks X and H (their
    nonzeros); T is the cell's block of ∂D/∂θ, row by row.
    """
    _, X_sp, H_sp = _cell_kkt_data_curvature(stages)
    n_D = len(CELL_DATA) * stages
    # (MX: CasADi's matrix products in C, faster than the same SX products)
    X, H = ca.MX.sym("X", X_sp.nnz()), ca.MX.sym("H", H_sp.nnz())
    T = ca.MX.sym("T", n_D * k)
    TD = ca.reshape(T, k, n_D).T
    Xm, Hm = ca.MX(X_sp, X), ca.MX(H_sp, H)
    HT = ca.mtimes(Hm + Hm.T - ca.diag(ca.diag(Hm)), TD)
    return ca.Function("cell_kkt_theta", [X, H, T],
                       [ca.mtimes(Xm.T, TD), ca.vec(ca.mtimes(TD.T, HT))])


@lru_cache(maxsize=None)
def _cell_kkt_dtheta(stages: int, k: int) -> ca.Function:
    """``(F_D, T) -> F_D T``: one cell's ∂/∂t of its KKT residual (∇ℓ + ∇gᵀλ, g) at D + T t (MX).

    F_D = ∂F/∂D is the cell's ``kkt_data`` block (compiled with the cell
    kernels), T the cell's block of ∂D/∂θ, row by row; ((4S + 2) × k).
    """
    n_D = len(CELL_DATA) * stages
    # (MX: CasADi's matrix product in C, faster than the same SX products)
    F_D = ca.MX.sym("F_D", cell_functions(stages)["kkt_data"].sparsity_out(0))
    T = ca.MX.sym("T", n_D * k)
    return ca.Function("cell_kkt_dtheta", [F_D, T], [ca.mtimes(F_D, ca.reshape(T, k, n_D).T)])
