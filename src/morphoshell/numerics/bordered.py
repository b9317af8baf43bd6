"""The KKT system bordered by a parameter: Newton steps along a branch of equilibria.

A branch of equilibria of the transcribed energy is the curve of solutions
(x, λ, τ) of the KKT conditions F(x, λ; p(τ)) = 0 for parameters p(τ) on a
line.  Pseudo-arclength continuation (Keller 1977; Allgower & Georg 2003, §2)
follows it through folds, where τ turns back and the KKT matrix K = ∂F/∂(x, λ)
is singular, by adding one equation that fixes the distance along the branch:
the bordered system

    [ K    F_τ ] [du]   [ −F ]
    [ cᵀ   c_τ ] [dτ] = [ −N ],

nonsingular at a simple fold.  Here u = (x, λ) in the cell order of the Newton
back end (:mod:`morphoshell.numerics.cell_order`), and K is that back end's
quasi-definite system (:meth:`Discretisation.newton_system`): its solution is
Newton's step on the KKT conditions, and its LDLᵀ gives the inertia.  The
system is solved by block elimination (two right-hand sides for one
factorisation): a point close to a fold makes K ill-conditioned, but Newton's
iteration recomputes the residual exactly, and a fold is located without
solving at it (:mod:`morphoshell.solvers.arclength`).  A corrector's iteration
is one call (:meth:`BorderedKKT.iterate`: the cell data, K, its LDLᵀ and both
solves inside CasADi, read into NumPy memory); from Python the conversions
between CasADi and NumPy had cost more than the arithmetic.

The stability of an equilibrium is the inertia of the reduced Hessian (the
Hessian of the Lagrangian on the tangent space of the constraints): by
Sylvester's law the LDLᵀ of K has m negative pivots more than the reduced
Hessian has negative eigenvalues (see :mod:`morphoshell.numerics.newton`).
"""
from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from .._runtime.buffered import Buffered
from .newton import S_MAX

__all__ = ["BorderedKKT", "KKTState", "Inertia"]


@dataclass(frozen=True)
class Inertia:
    """Of the reduced Hessian at an equilibrium: its negative and zero eigenvalues.

    Attributes
    ----------
    negative : int
        Negative eigenvalues: 0 at a stable equilibrium (a strict minimum when
        ``zero`` is 0 too), the number of independent directions in which the
        energy decreases otherwise.
    zero : int
        The KKT matrix's rank deficiency (0 but at a fold or branch point).
    """

    negative: int
    zero: int

    @property
    def stable(self) -> bool:
        """A strict local minimum of the energy."""
        return self.negative == 0 and self.zero == 0


@dataclass(frozen=True)
class KKTState:
    """The bordered system at one point (u, τ): what a Newton step or a tangent needs.

    Attributes
    ----------
    K : casadi.DM
        The Newton system's matrix (cell order), shape (k, k) with k the
        system's unknowns u[lo:hi].
    rhs : ndarray, shape (k,)
        −F (as the Newton back end's right-hand side).
    F_tau : ndarray, shape (k,), or None
        ∂F/∂τ, transformed as ``rhs`` is (the weights W held).
    error : float
        The KKT error (Ipopt's unscaled measure, as the Newton back end's).
    w : casadi.DM
        The weights W of the system, shape (m,).
    """

    K: ca.DM
    rhs: np.ndarray
    F_tau: np.ndarray | None
    error: float
    w: ca.DM


class BorderedKKT:
    """The KKT system of one transcription, bordered by a parameter direction.

    Parameters
    ----------
    disc : Discretisation
        The transcription (:class:`morphoshell.numerics.discretisation.Discretisation`).
    """

    def __init__(self, disc):
        self.disc = disc
        self.order = disc.cell_order
        self.n, self.m = disc.layout.size, disc.constraints
        self._system = disc.newton_system()
        self._rhs = disc.newton_rhs()
        self._linsol = ca.Linsol("bordered", "ldl", self._system.sparsity_out(0))
        self.x_mask = np.asarray(disc.cell_assembly.x_mask, dtype=float).ravel() > 0.5
        self._iterate = self._iterate_around = None       # (built on first use)

    # -- conversions -----------------------------------------------------------
    def pack(self, x: np.ndarray, lam: np.ndarray) -> np.ndarray:
        """u (cell order, all entries) of (x, λ).

        Returns
        -------
        ndarray, shape (order.size,)
        """
        return self.disc.kkt_pack(np.asarray(x, dtype=float), np.asarray(lam, dtype=float))

    def unpack(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(x, λ) of u: shapes (n,) and (m,)."""
        return self.order.unpack(np.asarray(u, dtype=float))

    def free(self, u: np.ndarray) -> np.ndarray:
        """The system's unknowns u[lo:hi] of u."""
        return u[self.order.lo:self.order.hi]

    def moved(self, u: np.ndarray, du: np.ndarray) -> np.ndarray:
        """u + du with du over the system's unknowns (the poles' fixed values kept)."""
        out = u.copy()
        out[self.order.lo:self.order.hi] += du
        return out

    # -- the system ------------------------------------------------------------
    def state(self, u: np.ndarray, D, around: tuple | None = None) -> KKTState:
        """The bordered system at u with cell data D.

        Parameters
        ----------
        u : ndarray, shape (order.size,)
        D : array_like, shape (n_D,)
            Cell data at p(τ).
        around : tuple, optional
            ``(D_plus, D_minus, h)``: the cell data at p(τ ± h), for the bordering
            column F_τ by a central difference (error O(h²) relative, about 1e-10
            for h = 1e-5; the compiled kernels have no derivatives, and F_τ only
            steers Newton's steps and the tangent, never the solution).  Without
            it ``F_tau`` is None.

        Returns
        -------
        KKTState
        """
        uk = ca.DM(u.tolist())
        K, rhs, dual, primal, l1, w = self._system(uk, D, 1.0)
        F_tau = None
        if around is not None:
            plus, minus, h = around
            F_tau = (np.asarray(self._rhs(uk, minus, w)[0]).ravel()
                     - np.asarray(self._rhs(uk, plus, w)[0]).ravel()) / (2 * h)
        return KKTState(K, np.asarray(rhs).ravel(), F_tau, self._error(dual, primal, l1), w)

    def solve(self, state: KKTState, b: np.ndarray, c: np.ndarray, c_tau: float,
              beta: float, column: np.ndarray | None = None) -> tuple[np.ndarray, float]:
        """(du, dτ) solving ``[K F_τ; cᵀ c_τ] [du; dτ] = [b; β]`` by block elimination.

        Parameters
        ----------
        state : KKTState
        b : ndarray, shape (k,)
        c : ndarray, shape (k,)
            The border row over the system's unknowns.
        c_tau : float
        beta : float
        column : ndarray, shape (k,), optional
            The bordering column if not ``state.F_tau`` (a chord: one kept from
            another point).

        Returns
        -------
        du : ndarray, shape (k,)
        dtau : float
        """
        column = state.F_tau if column is None else column
        Z = np.asarray(self._linsol.solve(state.K, ca.DM(np.column_stack([b, column])))
                       ).reshape(len(b), 2)
        return self.eliminate(Z, c, c_tau, beta)

    def solve_columns(self, state: KKTState, B: np.ndarray) -> np.ndarray:
        """K⁻¹ B for a block of right-hand sides B, shape (k, c)."""
        return np.asarray(self._linsol.solve(state.K, ca.DM(B))).reshape(B.shape)

    @staticmethod
    def times(state: KKTState, B: np.ndarray) -> np.ndarray:
        """K B for a block B, shape (k, c)."""
        return np.asarray(ca.mtimes(state.K, ca.DM(B))).reshape(B.shape)

    @staticmethod
    def eliminate(Z: np.ndarray, c: np.ndarray, c_tau: float,
                  beta: float) -> tuple[np.ndarray, float]:
        """(du, dτ) of the bordered system from Z = K⁻¹ [b, F_τ], shape (k, 2)."""
        dtau = (beta - c @ Z[:, 0]) / (c_tau - c @ Z[:, 1])
        return Z[:, 0] - Z[:, 1] * dtau, float(dtau)

    # -- fused: a corrector's iterations in one call each -------------------------------
    def iterate(self, u: np.ndarray, p: np.ndarray, q: np.ndarray,
                column: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
        """The system at u for parameters p (anchors q) and its solves, in one call:
        (Z = K⁻¹ [rhs, ``column``], rhs, the KKT error), as :meth:`state` and :meth:`solve`
        give them, to the bit.  From Python, converting u, K and the solutions between
        NumPy and CasADi cost more than the factorisation (docs/benchmarks.md, "The
        fused corrector").

        Returns
        -------
        Z : ndarray, shape (k, 2)
            As :meth:`solve` holds it (the same layout: the same bits in
            :meth:`eliminate`).
        rhs : ndarray, shape (k,)
        error : float
        """
        if self._iterate is None:
            self._iterate = Buffered(self._fused_iterate())
        Z, rhs, dual, primal, l1 = self._iterate(u, p, q, column)
        return self._columns(Z), rhs, self._error(dual[0], primal[0], l1[0])

    def iterate_around(self, u: np.ndarray, p: np.ndarray, q: np.ndarray,
                       around: tuple) -> tuple[np.ndarray, np.ndarray, float, np.ndarray]:
        """:meth:`iterate` with the bordering column F_τ at u by :meth:`state`'s central
        difference, ``around`` = (p(τ + h), p(τ − h), h): (Z, rhs, error, F_τ), one call."""
        if self._iterate_around is None:
            self._iterate_around = Buffered(self._fused_iterate(around=True))
        plus, minus, h = around
        Z, rhs, dual, primal, l1, F_tau = self._iterate_around(u, p, q, plus, minus, 2 * h)
        return self._columns(Z), rhs, self._error(dual[0], primal[0], l1[0]), F_tau

    @staticmethod
    def _columns(Z: np.ndarray) -> np.ndarray:
        """CasADi's column-major (k, 2) Z as :meth:`solve` holds it (the same bits in
        :meth:`eliminate`)."""
        return np.ascontiguousarray(Z.reshape(2, -1).T)

    def _fused_iterate(self, around: bool = False) -> ca.Function:
        pre = self.disc.pre_numeric
        u, p, q = (ca.MX.sym(name, sp) for name, sp in (
            ("u", self._system.sparsity_in(0)), ("p", pre.sparsity_in(0)),
            ("q", pre.sparsity_in(1))))
        K, rhs, dual, primal, l1, w = self._system(u, pre(p, q), 1.0)
        if around:       # (state's central difference: the same operations, the same bits)
            plus, minus = (ca.MX.sym(name, p.sparsity()) for name in ("plus", "minus"))
            two_h = ca.MX.sym("two_h")
            column = (self._rhs(u, pre(minus, q), w)[0] - self._rhs(u, pre(plus, q), w)[0]) \
                / two_h
            ins, extra = [u, p, q, plus, minus, two_h], [column]
        else:
            column = ca.MX.sym("column", self._system.sparsity_out(1))
            ins, extra = [u, p, q, column], []
        Z = self._linsol.solve(K, ca.horzcat(rhs, column), False)
        return ca.Function("bordered_iterate", ins, [Z, rhs, dual, primal, l1, *extra])

    def _error(self, dual: float, primal: float, l1: float) -> float:
        """The KKT error (Ipopt's unscaled measure) from the system's three norms."""
        return max(float(dual) / max(1.0, float(l1) / ((self.n + self.m) * S_MAX)),
                   float(primal))

    def inertia(self, state: KKTState) -> Inertia:
        """The inertia of the reduced Hessian from the LDLᵀ of K (module docstring)."""
        self._linsol.nfact(state.K)
        k = state.K.size1()
        return Inertia(int(self._linsol.neig(state.K)) - self.m,
                       k - int(self._linsol.rank(state.K)))
