"""The local solutions of the shell equations at a pole, and what they say about the shape.

The Euler–Lagrange equations are singular at a pole (ρ = 0).  Near it the strains
are affine in w = (r', r/s, ψ', ψ/s) up to O(s²), so the energy is locally the
quadratic form ½ εᵀQε of an Euler-type problem, whose bounded solutions are

    (r, ψ) = c_p s + C₁ c₁ s^β₁ + C₂ c₂ s^β₂,

β₁, β₂ > 0 the positive roots of det M(β) = 0, M(β) = (βP̃ − R̃)ᵀ Q (βP̃ + R̃), and
c_p the solution of M(1) c_p = −(P̃ − R̃)ᵀ Q ε₀ (derivation:
:mod:`morphoshell.solvers.bvp`, which starts its boundary-value problem on these).

The exponents are 1 only for an isotropic quadratic form.  An exponent β₁ < 1
makes the pole *weakly singular*: f_s ~ r' has a term C₁ β₁ s^(β₁ − 1) that grows
without bound at the pole, and with C₁ < 0 the model's own solution crosses the
axis, r = c s + C₁ s^β₁ < 0, for s below s* = (|C₁|/c)^(1/(1 − β₁)) (thick shells:
s* ≈ 9e-8 R at h = 0.8, k = 0.8, 1.5e-6 R at h = 0.95; :func:`weakly_singular`).
Here in a module of its own (no scipy), so that the direct route can ask it.
"""
from __future__ import annotations

from functools import lru_cache

import casadi as ca
import numpy as np

from ..model.energy import Strains, density, intrinsic_function, strains, unpack_intrinsic
from ..model.layouts import INTRINSIC
from ..model.problem import Problem
from ..numerics.status import POLE_ANALYSIS_FAILED, explain
from .results import SolverError

__all__ = ["pole_solutions", "PoleSolution", "weakly_singular"]


@lru_cache(maxsize=1)
def _pole_function() -> ca.Function:
    """``(I, h) -> (Q, G, eps0)`` at a pole from the intrinsic data I.

    ε = G w + eps0 with w = (r', r/s, ψ', ψ/s) and e = ½ εᵀ Q ε.  Family and
    theory enter through I only, so one function serves every structure.
    """
    I, h = ca.SX.sym("I", len(INTRINSIC)), ca.SX.sym("h")
    _, prof, _, coeffs = unpack_intrinsic(I)
    w = ca.SX.sym("w", 4)
    # ρ = 1 with r = r/s, and sin ψ ≈ ψ/s: the strains at the pole, exactly affine in w.
    E = ca.vertcat(*strains(1, w[1], w[3], w[0], w[2], prof))
    G = ca.substitute(ca.jacobian(E, w), w, ca.DM.zeros(4))
    eps0 = ca.substitute(E, w, ca.DM.zeros(4))
    Es = ca.SX.sym("E", 4)
    Q = ca.hessian(density(Strains(*ca.vertsplit(Es)), h, coeffs), Es)[0]
    return ca.Function("pole_data", [I, h], [Q, G, eps0])


def pole_solutions(problem: Problem) -> dict:
    """The local solutions at the poles of ``problem`` (keys "start" and/or "end").

    The bounded solutions of the linearised problem at each pole (module doc,
    "Boundary conditions"), from the quadratic form of the energy density
    (Materials and Methods, Eq. 7) at the pole.

    Returns
    -------
    dict
        A local solution for each end of ``problem`` that is a pole.

    Raises
    ------
    SolverError
        Status ``"Pole_Analysis_Failed"`` when a pole has not two admissible
        exponents.
    """
    st = problem.structure
    p = problem.parameter_vector()
    out = {}
    for where, s_pole in (("start", problem.cut), ("end", problem.end)):
        if getattr(st, where) == "pole":
            I = intrinsic_function(st)(s_pole, p)
            Q, G, eps0 = (np.asarray(v) for v in _pole_function()(I, problem.h))
            out[where] = PoleSolution(Q, G, eps0.ravel())
    return out


class PoleSolution:
    """Bounded local solution of the linearised problem at a pole (see module doc)."""

    def __init__(self, Q: np.ndarray, G: np.ndarray, eps0: np.ndarray):
        P = G[:, [0, 2]]   # coefficients of (r', ψ')
        R = G[:, [1, 3]]   # coefficients of (r/s, ψ/s)
        A, B, C = P.T @ Q @ P, P.T @ Q @ R - R.T @ Q @ P, R.T @ Q @ R

        def M(beta):
            return beta**2 * A + beta * B - C

        # det M(β) as a quartic: exact coefficients from five samples.
        x = np.arange(-2.0, 3.0)
        roots = np.roots(np.polyfit(x, [np.linalg.det(M(v)) for v in x], 4))
        pos = sorted(roots[roots.real > 1e-9], key=lambda z: (z.real, z.imag))
        if len(pos) != 2:
            raise SolverError(f"pole analysis found {len(pos)} admissible exponents "
                              f"({roots}): {explain(POLE_ANALYSIS_FAILED)}", POLE_ANALYSIS_FAILED)
        b1, b2 = pos
        if abs(b1 - b2) < 1e-6 * max(1.0, abs(b1)):
            # Double root (isotropic quadratic form): M(β) vanishes on a plane.
            beta = float(np.real(b1 + b2) / 2)
            _, _, vh = np.linalg.svd(M(beta))
            modes = [(beta, vh[-1], "re"), (beta, vh[-2], "re")]
        elif abs(b1.imag) > 1e-9:   # complex pair: real and imaginary parts of one mode
            c = _null_vector(M(b1))
            modes = [(b1, c, "re"), (b1, c, "im")]
        else:
            modes = [(float(b.real), _null_vector(M(float(b.real))).real, "re") for b in pos]
        self.modes = modes
        self.exponents = [complex(m[0]) for m in modes]
        rhs = -(P - R).T @ Q @ eps0
        self.c_p = np.linalg.lstsq(M(1.0), rhs, rcond=1e-12)[0]

    def fit(self, s: float, r: float, psi: float) -> np.ndarray:
        """Mode amplitudes C that reproduce (r, ψ) at distance s from the pole."""
        basis = np.column_stack([self.evaluate(s, e)[0] - self.c_p * s for e in np.eye(2)])
        return np.linalg.lstsq(basis, np.array([r, psi]) - self.c_p * s, rcond=None)[0]

    def evaluate(self, s: float, C) -> tuple[np.ndarray, np.ndarray]:
        """(r, ψ) and their derivatives at distance s from the pole."""
        v = self.c_p * s
        dv = self.c_p.copy()
        for Cj, (beta, c, part) in zip(C, self.modes):
            term = c * s**beta
            dterm = c * beta * s ** (beta - 1)
            v = v + Cj * (term.real if part == "re" else term.imag)
            dv = dv + Cj * (dterm.real if part == "re" else dterm.imag)
        return np.real(v), np.real(dv)



def _null_vector(M: np.ndarray) -> np.ndarray:
    u, sv, vh = np.linalg.svd(M)
    c = vh[-1].conj()
    return c / np.linalg.norm(c)


def weakly_singular(problem: Problem) -> dict[str, float]:
    """The poles of ``problem`` whose local solution is weakly singular, with their exponent.

    Returns
    -------
    dict
        ``{"start" or "end": β₁}`` for each pole whose smallest exponent has a real part
        below 1 (f_s unbounded there; see the module doc); empty if none.  A pole whose
        analysis fails is left out (it cannot vouch for anything).
    """
    try:
        poles = pole_solutions(problem)
    except SolverError:
        return {}
    out = {}
    for where, pole in poles.items():
        beta = min(e.real for e in pole.exponents)
        if beta < 1:
            out[where] = beta
    return out
