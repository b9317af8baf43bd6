"""Newton back end for warm starts: Newton's method on the KKT conditions, certified by its own LDLᵀ.

A warm re-solve (continuation, fitting, sweeps) starts next to the solution:
Newton's method on the KKT conditions ∇f + Jᵀλ = 0, g = 0 converges in two or
three full steps, and Ipopt's fixed cost per call (set-up, MUMPS' analysis, a
separate factorisation for the minimum certificate) was most of a warm solve
(measured 10 of 15 ms at N = 200).  This back end takes those steps itself
with one sparse LDLᵀ per iterate (CasADi's ``ldl``, symbolic analysis once),
and reads the minimum certificate off the factorisation *at the returned
point*.  It returns None whenever it cannot certify a converged minimum (no
convergence within a few steps, a growing residual, the wrong inertia), and
the caller falls back to Ipopt: it can only make a warm solve faster, never
change what is accepted.

The linear system.  With weights W > 0 per constraint (as in
:meth:`morphoshell.ipopt.IpoptBackend.penalised_certificate`) and
M = ∇²ℒ + Jᵀ W J, the Newton step (dx, dλ) solves

    [ M   Jᵀ ] [dx]     [ ∇f + Jᵀλ + Jᵀ W g ]
    [ J  −Δ  ] [dλ] = − [ g                  ],     Δ = ε W⁻¹

(assembled per cell by the transcription), which for Δ = 0 is exactly
Newton's KKT system (J dx = −g turns Jᵀ W J dx into −Jᵀ W g); ε = 1e-8
perturbs the step by a relative 1e-8, invisible in Newton's convergence.  The matrix is quasi-definite when M is positive
definite, so an LDLᵀ factorisation without pivoting exists in any ordering
and is stable (Vanderbei 1995).  By Sylvester's law its inertia is that of
M + Jᵀ Δ⁻¹ J plus m negative pivots: exactly m negative pivots and full rank
mean vᵀ ∇²ℒ v > 0 for every v ≠ 0 with Jv = 0, a strict local minimum
(Nocedal & Wright, Thm 12.6).  A saddle can never pass this test.
"""
from __future__ import annotations

import time

import casadi as ca
import numpy as np

from .ipopt import BackendResult

__all__ = ["NewtonBackend", "S_MAX"]

#: Ipopt's ``s_max``: the dual infeasibility is scaled down by ‖λ‖₁/(n + m)/s_max when larger.
S_MAX = 100.0


class NewtonBackend:
    """Certified Newton iterations on the KKT conditions of ``nlp`` (see the module docstring).

    Parameters
    ----------
    nlp : object
        With the CasADi symbol ``x`` and a method ``newton_system()`` returning
        the Function ``(x, D, λ, ρ) -> (K, rhs, ‖∇f + Jᵀλ‖∞, ‖g‖∞, ‖λ‖₁)`` of
        the system above (:meth:`morphoshell.discretisation.Discretisation.newton_system`).
    tol : float
        Converged when max(‖∇f + Jᵀλ‖∞ / s_d, ‖g‖∞) ≤ tol, Ipopt's
        unscaled KKT error (s_d as in Ipopt: max(1, ‖λ‖₁/((n + m) s_max))).
    acceptable_tol : float
        Also converged when the error is below this, ‖g‖∞ ≤ 1e-10 and a step
        no longer reduced it tenfold (Newton at its round-off floor: Ipopt's
        "acceptable" exit, which thin shells need).
    max_iter : int
        Newton steps before giving up (warm starts need 2–3).
    """

    def __init__(self, nlp, *, tol: float, acceptable_tol: float, max_iter: int = 8):
        self.tol, self.acceptable_tol, self.max_iter = float(tol), float(acceptable_tol), max_iter
        self._system = nlp.newton_system()
        self.n, self.m = nlp.x.shape[0], self._system.size1_in(2)
        self._linsol = ca.Linsol("newton", "ldl", self._system.sparsity_out(0))

    def solve(self, x0: np.ndarray, D, lam_g0: np.ndarray) -> BackendResult | None:
        """Newton from (x0, λ0) at parameters D (a ``casadi.DM``); None if not certified.

        None: no converged, certified minimum within ``max_iter`` steps (the
        caller then runs Ipopt).  The result's ``details["stability"]`` names
        the certificate: ``"newton_ldl"``, or ``"newton_ldl_rho100"`` when the
        weights W had to be raised.
        """
        t0 = time.perf_counter()
        # lists convert to DM three times faster than NumPy arrays
        xk, lk = ca.DM(np.asarray(x0).tolist()), ca.DM(np.asarray(lam_g0).tolist())
        n, m = self.n, self.m
        lin, last = self._linsol, np.inf
        for it in range(self.max_iter + 1):
            K, rhs, dual, primal, l1 = self._system(xk, D, lk, 1.0)
            dual, primal = float(dual), float(primal)
            err = max(dual / max(1.0, float(l1) / ((n + m) * S_MAX)), primal)
            done = err <= self.tol or (err <= self.acceptable_tol and primal <= 1e-10
                                       and err > 0.1 * last)
            if not done and (not np.isfinite(err) or (it >= 2 and err > last)
                             or it == self.max_iter):
                return None       # not converging: Ipopt's globalisation is needed
            lin.nfact(K)
            if done:
                how = self._certify(K, xk, D, lk)
                if how is None:
                    return None
                return BackendResult(np.array(xk).ravel(), np.array(lk).ravel(),
                                     "Newton_Converged", it, time.perf_counter() - t0, True,
                                     {"stability": how, "inertia_correction": 0.0,
                                      "route": "newton"})
            step = lin.solve(K, rhs)
            xk, lk = xk + step[:n], lk + step[n:]
            last = err
        return None

    def _certify(self, K, x, D, lam) -> str | None:
        """The certificate of the factorised K at the returned point, trying ρ = 100 if ρ = 1 fails."""
        lin = self._linsol
        if lin.neig(K) == self.m and lin.rank(K) == self.n + self.m:
            return "newton_ldl"
        K = self._system(x, D, lam, 100.0)[0]
        lin.nfact(K)
        if lin.neig(K) == self.m and lin.rank(K) == self.n + self.m:
            return "newton_ldl_rho100"
        return None
