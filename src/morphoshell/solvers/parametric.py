"""The parametric solve as a differentiable map: exact derivatives of direct solutions.

A direct solution (x, λ) of the equality-constrained NLP satisfies the KKT
conditions

    F(x, λ; p) = [∇ₓℒ(x, λ; p), g(x; p)] = 0,     ℒ = f + λᵀg,

so by the implicit function theorem d(x, λ)/dp = −K⁻¹ ∂F/∂p with the KKT
matrix K = ∂F/∂(x, λ), nonsingular at a strict minimum (which every returned
solution is).  p is the physical parameter vector (``Problem.parameter_layout``:
h, Σ, P, the family's parameters); derivatives go through the cell data D(p)
and the parametric mesh, so ∂/∂Σ moves the material points with the cut.

For an observable y(x, p) (:mod:`morphoshell.solvers.observables`)

    dy/dp = ∂y/∂p + ∂y/∂x · dx/dp.

:attr:`Parametric.kkt_residual` exposes F as a CasADi Function, so a caller
can pose the equilibrium as constraints of a larger NLP (a fit in one NLP).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import casadi as ca
import numpy as np

from .._runtime.buffered import Buffered
from .direct import DirectSolver
from .observables import Observable, energy, shape_points
from .results import Equilibrium

__all__ = ["Parametric", "Sensitivities", "SolutionDerivative", "parametric"]


def parametric(solver: DirectSolver) -> "Parametric":
    """The :class:`Parametric` of ``solver``, built once and kept with it."""
    if getattr(solver, "_parametric", None) is None:
        solver._parametric = Parametric(solver)
    return solver._parametric


@dataclass(frozen=True, eq=False)
class SolutionDerivative:
    """dx/dp of one solution, for the parameters ``names`` (columns).

    Attributes
    ----------
    names : tuple of str
        The parameters, in the order of the columns.
    columns : tuple of int
        Their indices in the parameter vector p (``Problem.parameter_vector``).
    dx : ndarray, shape (n, len(names))
        dx/dp of the n unknowns of the NLP.
    """

    names: tuple[str, ...]
    columns: tuple[int, ...]
    dx: np.ndarray


@dataclass(frozen=True, eq=False)
class Sensitivities:
    """Derivatives of a direct solution with respect to the parameters.

    Columns follow ``names`` = (h, cut, opening, family parameters...): k
    parameters; n unknowns of the NLP, N points of the solution.

    Attributes
    ----------
    names : tuple of str
    dx : ndarray, shape (n, k)
        Of the NLP vector x.
    dr, dz, dpsi : ndarray, shape (N, k)
        Of r, z (solver gauge) and ψ at the *material* points (whose s moves
        with Σ and P, see ``ds``); the pole values are fixed (zero derivative).
    ds : ndarray, shape (N, k)
        Of the points' arclength s.
    denergy : ndarray, shape (k,)
        Of the total energy 𝓔 (units of C R²).
    """

    names: tuple[str, ...]
    dx: np.ndarray
    dr: np.ndarray
    dz: np.ndarray
    dpsi: np.ndarray
    ds: np.ndarray
    denergy: np.ndarray

    def column(self, name: str) -> dict[str, np.ndarray]:
        """Derivatives with respect to one parameter, by name.

        Returns
        -------
        dict
            ``r``, ``z``, ``psi``, ``s``: ndarray, shape (N,); ``energy``: float.
        """
        if name not in self.names:
            raise ValueError(f"unknown parameter {name!r}; valid: {list(self.names)}")
        j = self.names.index(name)
        return {"r": self.dr[:, j], "z": self.dz[:, j], "psi": self.dpsi[:, j],
                "s": self.ds[:, j], "energy": float(self.denergy[j])}


class Parametric:
    """Exact parametric derivatives of the solutions of one :class:`DirectSolver`.

    Parameters
    ----------
    solver : DirectSolver

    Attributes
    ----------
    kkt_residual : casadi.Function
        ``(x, lam, p, q) -> F``: the KKT residual of the solver's NLP
        (stationarity of the scaled objective, then the constraints) at
        parameters p and mesh anchors q; zero at every solution.  Anchors are
        held fixed by every derivative here (they place nodes, they are not
        parameters of the physics).
    """

    def __init__(self, solver: DirectSolver):
        self.solver = solver
        d = solver.disc
        x, p, q, D = d.x, d.p, d.q, d.D
        lam = ca.MX.sym("lam", d.g.shape[0])
        g, J = d.jac_g(x, D)
        F_of_D = ca.vertcat(d.grad_f(x, D)[1] + ca.mtimes(J.T, lam), g)
        F = ca.Function("F", [x, D, lam], [F_of_D])
        self.kkt_residual = ca.Function("kkt_residual", [x, lam, p, q], [F(x, d.pre(p, q), lam)],
                                        ["x", "lam", "p", "q"], ["F"])
        # K and ∂F/∂p are assembled from pieces that are cheap to evaluate:
        # the sparse Hessian and constraint Jacobian Ipopt uses, ∂F/∂D (local
        # to each cell) and ∂D/∂p (local to each Gauss point); differentiating
        # the whole graph at once costs many times more.
        self._hess = Buffered(ca.Function("H", [x, D, lam], [d.hess_lag(x, D, 1, lam)]))
        self._jac = Buffered(ca.Function("J", [x, D], [J]))
        self._pattern: tuple | None = None       # K's, built on first use
        self._ordered: tuple | None = None       # and in the LU's column order
        self._D_p = Buffered(d.pre_jacobian)
        self._jacobians: dict[int, ca.Function] = {}
        self._last: tuple | None = None

    def kkt_matrix(self, x: np.ndarray, D: np.ndarray, lam: np.ndarray):
        """The KKT matrix K = [[∇²ℒ, Jᵀ], [J, 0]] at (x, λ) with data D.

        Returns
        -------
        scipy.sparse.csc_matrix, shape (n + m, n + m)
            n unknowns, m constraints.
        """
        if self._pattern is None:
            self._pattern = _kkt_pattern(*self._sparsities())
        return self._assemble(self._pattern, x, D, lam)

    def _sparsities(self) -> tuple[ca.Sparsity, ca.Sparsity]:
        return self._hess.function.sparsity_out(0), self._jac.function.sparsity_out(0)

    def _assemble(self, pattern: tuple, x: np.ndarray, D: np.ndarray, lam: np.ndarray):
        import scipy.sparse

        gather, indices, indptr, shape = pattern
        # the pattern is structural, the same at every (x, λ): only values are gathered
        nz = np.concatenate([self._hess(x, D, lam)[0], self._jac(x, D)[0]])
        return scipy.sparse.csc_matrix((nz[gather], indices, indptr), shape=shape)

    def _factor(self, x: np.ndarray, D: np.ndarray, lam: np.ndarray):
        """``solve(b) -> K⁻¹ b`` by one sparse LU of K at (x, λ)."""
        import scipy.sparse.linalg   # on use: keeps the package's start-up fast

        if self._ordered is None:
            # SuperLU's column order (COLAMD, then its postorder) depends on K's
            # pattern only, which is the same at every (x, λ): kept from the first
            # factorisation, K is assembled in it and SuperLU told not to reorder
            # (same factors, bit for bit, without the ordering's cost)
            lu = scipy.sparse.linalg.splu(self.kkt_matrix(x, D, lam))
            self._ordered = (_kkt_pattern(*self._sparsities(), lu.perm_c), lu.perm_c)
            return lu.solve
        pattern, perm_c = self._ordered
        lu = scipy.sparse.linalg.splu(self._assemble(pattern, x, D, lam), permc_spec="NATURAL")
        return lambda b: lu.solve(b)[perm_c]

    @property
    def names(self) -> tuple[str, ...]:
        """The parameters derivatives are taken with respect to: h, cut, opening, the family's."""
        return self.solver.structure.parameters.names

    def _columns(self, wrt: Sequence[str] | None) -> tuple[tuple[str, ...], tuple[int, ...]]:
        names = self.names if wrt is None else tuple(wrt)
        return names, tuple(self.solver.structure.parameters.indices(names))

    def derivative(self, eq: Equilibrium, wrt: Sequence[str] | None = None) -> SolutionDerivative:
        """dx/dp of the solution ``eq`` (one sparse LU of the KKT matrix, cached per eq).

        Parameters
        ----------
        eq : Equilibrium
            A direct solution on this solver.
        wrt : sequence of str, optional
            The parameters (default: every one, :attr:`names`).

        Returns
        -------
        SolutionDerivative
        """
        self.solver.check(eq.problem)
        if eq.x is None or eq.lam_g is None or len(eq.x) != self.solver.disc.layout.size:
            raise ValueError("eq must be a direct solution on a solver of this mesh")
        names, cols = self._columns(wrt)
        if self._last is None or self._last[0] is not eq:
            p = eq.problem.parameter_vector()
            D = self.solver.disc.cell_data(p, eq.anchors)
            solve = self._factor(eq.x, D, eq.lam_g)
            D_p = self._D_p(p, np.asarray(eq.anchors, dtype=float))[0].reshape(len(D), -1,
                                                                               order="F")
            self._last = (eq, solve, self.solver.disc.kkt_residual_theta_numeric(eq.x, eq.lam_g,
                                                                              D, D_p))
        _, solve, Fp = self._last
        sol = solve(-Fp[:, list(cols)])
        return SolutionDerivative(names, cols, sol[:self.solver.disc.layout.size])

    def jacobian(self, eq: Equilibrium, observable: Observable,
                 wrt: Sequence[str] | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Value and exact Jacobian dy/dp of ``observable`` at the solution ``eq``.

        Returns
        -------
        y : ndarray, shape (len(observable),)
        J : ndarray, shape (len(observable), len(wrt))
            Columns follow ``wrt`` (default: every parameter, in layout order).
        """
        key = id(observable.function)
        if key not in self._jacobians and observable.jacobian is None:
            f = observable.function
            args = [f.mx_in(i) for i in range(f.n_in())]
            y = f(*args)
            self._jacobians[key] = ca.Function(
                "obs_jac", args, [y, ca.jacobian(y, args[0]), ca.jacobian(y, args[1])])
            if len(self._jacobians) > 32:         # bounded: observables are rebuilt rarely
                self._jacobians.pop(next(iter(self._jacobians)))
        dxdp = self.derivative(eq, wrt)
        inputs = observable.inputs(eq.x, eq.problem.parameter_vector(), eq.anchors)
        if observable.jacobian is not None:       # the observable's own, cheaper chain rule
            y, yx, yp = observable.jacobian(*inputs)
        else:
            y, yx, yp = self._jacobians[key](*inputs)
            y, yx, yp = np.asarray(y).ravel(), _csc(yx), np.asarray(ca.densify(yp))
        J = yp[:, list(dxdp.columns)] + yx @ dxdp.dx
        return np.asarray(y).ravel(), J

    def sensitivities(self, eq: Equilibrium) -> Sensitivities:
        """Derivatives of r, z, ψ, s at every point and of the energy, for every parameter.

        Returns
        -------
        Sensitivities
        """
        d = self.solver.disc
        if not hasattr(self, "_shape"):
            self._shape, self._energy = shape_points(d), energy(d)
        _, J = self.jacobian(eq, self._shape)
        _, dE = self.jacobian(eq, self._energy)
        n = d.layout.points
        ds, dr, dz, dpsi = (J[i * n:(i + 1) * n] for i in range(4))
        return Sensitivities(names=self.names, dx=self.derivative(eq).dx, dr=dr, dz=dz,
                             dpsi=dpsi, ds=ds, denergy=dE.ravel())


def _kkt_pattern(hess: ca.Sparsity, jac: ca.Sparsity, column=None) -> tuple:
    """CSC pattern of K = [[H, Jᵀ], [J, 0]] from those of triu(H) and J.

    ``column[j]``, if given, is where K's column j goes (a permutation).
    Returns ``(gather, indices, indptr, shape)``: K's nonzeros in CSC order are
    ``concatenate([nonzeros of triu(H), nonzeros of J])[gather]``.  Built once
    per solver, it replaces SciPy's transposes, sums and ``bmat`` of the same
    pattern at every call, which were most of the cost of a derivative.
    """
    n, m = hess.shape[0], jac.shape[0]
    hr, hc = np.array(hess.get_triplet())
    jr, jc = np.array(jac.get_triplet())
    h, j = np.arange(len(hr)), len(hr) + np.arange(len(jr))
    off = hr != hc                        # the strict upper triangle, mirrored below
    rows = np.concatenate([hr, hc[off], n + jr, jc])
    cols = np.concatenate([hc, hr[off], jc, n + jr])
    src = np.concatenate([h, h[off], j, j])
    if column is not None:
        cols = np.asarray(column)[cols]
    order = np.lexsort((rows, cols))
    indptr = np.concatenate([[0], np.cumsum(np.bincount(cols, minlength=n + m))])
    return src[order], rows[order], indptr, (n + m, n + m)


def _csc(m: ca.DM):
    """A CasADi DM as a SciPy CSC matrix (faster than ``DM.sparse()``)."""
    import scipy.sparse

    sp = m.sparsity()
    return scipy.sparse.csc_matrix((np.array(m.nonzeros()), np.array(sp.row()),
                                    np.array(sp.colind())), shape=sp.shape)
