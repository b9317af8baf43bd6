"""Ipopt back end: solves a transcribed, equality-constrained parametric NLP.

The transcription (:class:`morphoshell.numerics.discretisation.Discretisation`) declares
the NLP: unknowns ``x``, parameters ``D``, objective, constraints g(x; D) = 0
and exact derivative functions.  This module hands it to Ipopt (bundled with
CasADi, MUMPS linear solver), decides whether Ipopt's answer is a solution,
and certifies that it is a local *minimum* by the inertia of the KKT matrix.
It knows nothing about shells: another back end only has to provide
:meth:`IpoptBackend.solve` and :meth:`IpoptBackend.inertia_correction`.
"""
from __future__ import annotations

import os
import time
from dataclasses import dataclass, field
from typing import Any, Mapping

import casadi as ca
import numpy as np

from .._runtime.buffered import Buffered
from .._runtime.interrupts import swallowed
from .status import (INVALID_OPTION, IPOPT_UNKNOWN, SEARCH_DIRECTION_BECOMES_TOO_SMALL,
                     SOLVE_SUCCEEDED, SOLVED_TO_ACCEPTABLE_LEVEL, STABILITY_CHECK_FAILED, STATUSES,
                     SolverError, explain)

__all__ = ["IpoptBackend", "BackendResult", "IPOPT_DEFAULTS", "converged", "load_ipopt",
           "ipopt_status"]

#: Ipopt's options for every solve (``ipopt_options`` overrides them).
IPOPT_DEFAULTS = {
    "print_level": 0, "sb": "yes", "print_timing_statistics": "no",
    "hessian_approximation": "exact",
    # Warm starts hand over the multipliers of the previous solution; for a
    # purely equality-constrained problem a cold start with lam_g = 0 is a
    # plain Newton start, so one setting serves both.
    "warm_start_init_point": "yes",
    # The NLP is scaled already, so MUMPS' automatic (permuting) scaling only
    # costs time, most of a solve's on fine meshes; AMD ordering suits the
    # banded KKT matrix.
    "mumps_scaling": 0, "mumps_permuting_scaling": 0, "mumps_pivot_order": 0,
}


_PLUGIN = {"loaded": False}


def load_ipopt() -> None:
    """Load CasADi's Ipopt plugin with its bundled OpenBLAS single-threaded.

    Call before any ``nlpsol(..., "ipopt", ...)``: the first creation of an
    Ipopt solver would otherwise load the plugin with OpenBLAS's default
    threads (and a later call here would load it twice).

    MUMPS factorises our banded KKT systems in small dense blocks, where BLAS
    threads do not help, and on a busy machine their spin-waiting slows warm
    re-solves several times over (scripts/bench_equilibrium.py).  OpenBLAS
    reads its thread count when it is loaded, i.e. with the plugin, so the
    variables are set only around that (NumPy's own BLAS, loaded earlier, is
    untouched); a value the user set is kept.
    """
    if _PLUGIN["loaded"]:
        return
    saved = {k: os.environ.get(k) for k in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS")}
    try:
        for k, v in saved.items():
            if v is None:
                os.environ[k] = "1"
        ca.load_nlpsol("ipopt")
    finally:
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
    _PLUGIN["loaded"] = True


def ipopt_status(stats: Mapping[str, Any]) -> str:
    """Ipopt's return status from the solver's ``stats()``, as a key of the status table.

    Parameters
    ----------
    stats : mapping
        ``casadi.Function.stats()`` of an Ipopt solver.

    Returns
    -------
    str
        ``stats["return_status"]`` if :data:`morphoshell.numerics.status.STATUSES`
        has it (every status CasADi names), else ``"Unknown"``.

    Raises
    ------
    KeyboardInterrupt
        The solve ended because of a Ctrl-C (CasADi returns it as
        ``NonIpopt_Exception_Thrown``; :mod:`morphoshell._runtime.interrupts`).
    """
    status = stats.get("return_status", IPOPT_UNKNOWN)
    if status == "NonIpopt_Exception_Thrown" and swallowed():
        raise KeyboardInterrupt
    return status if status in STATUSES else IPOPT_UNKNOWN


def converged(status: str, stats: Mapping[str, Any]) -> bool:
    """Whether Ipopt's result is a solution (see :class:`IpoptBackend`, ``tol``).

    Parameters
    ----------
    status : str
        Ipopt's return status (:func:`ipopt_status`).
    stats : mapping
        The solver's ``stats()``: its last iterations' scaled infeasibilities
        decide ``Search_Direction_Becomes_Too_Small``.

    Returns
    -------
    bool
    """
    if status in (SOLVE_SUCCEEDED, SOLVED_TO_ACCEPTABLE_LEVEL):
        return True
    if status == SEARCH_DIRECTION_BECOMES_TOO_SMALL:
        it = stats.get("iterations", {})
        if it.get("inf_pr") and it.get("inf_du"):
            return it["inf_pr"][-1] < 1e-9 and it["inf_du"][-1] < 1e-6
    return False


@dataclass(frozen=True)
class BackendResult:
    """Ipopt's answer: iterate, multipliers, status and the minimum certificate.

    Attributes
    ----------
    x : ndarray, shape (n,)
        The last iterate (the unknowns of the transcription).
    lam_g : ndarray, shape (m,)
        Multipliers of the m equality constraints.
    status : str
        Ipopt's return status (a key of :data:`morphoshell.numerics.status.STATUSES`).
    iterations : int
    seconds : float
        Wall time of the call (s).
    converged : bool
        Whether the status counts as a solution (:func:`converged`).
    details : mapping
        How the minimum was certified: ``stability`` (``"ipopt_last_step"``,
        ``"penalised_ldl"`` or ``"ipopt_refactorisation"``) and
        ``inertia_correction`` (0 for a strict minimum).
    """

    x: np.ndarray
    lam_g: np.ndarray
    status: str
    iterations: int
    seconds: float
    converged: bool
    details: Mapping[str, Any] = field(default_factory=dict)

    @property
    def is_minimum(self) -> bool:
        """Whether the solution is a certified minimum (no inertia correction was needed)."""
        return self.details.get("inertia_correction", 0.0) == 0


class IpoptBackend:
    """Ipopt for one transcribed NLP, built once and called many times.

    Parameters
    ----------
    nlp : object
        With CasADi attributes ``x``, ``D`` (parameters), ``objective``,
        ``g`` and the derivative Functions ``grad_f``, ``jac_g``,
        ``hess_lag`` (signatures of ``nlpsol``'s options), and the number of
        ``constraints``.  Ipopt is set up on the first :meth:`solve`.
    tol : float
        Ipopt's convergence tolerance (on the scaled KKT error).
        Ipopt's ``Search_Direction_Becomes_Too_Small`` (Newton steps at
        machine precision) counts as converged when the final scaled primal
        and dual infeasibilities are below 1e-9 and 1e-6, and so does
        ``Solved_To_Acceptable_Level`` (three iterations in a row within
        max(1e-6, 100 tol) and constraint violation below 1e-10: the round-off
        floor of thin shells).
    max_iter : int
    linear_solver : str
        ``"mumps"`` (bundled) or an HSL solver such as ``"ma27"`` if the user
        provides ``libhsl.so``.
    stability : {"auto", "exact", "off"}
        How to verify that a solution is a local minimum.  ``"exact"``
        refactorises the KKT matrix at the solution and checks its inertia
        (see :meth:`inertia_correction`).  ``"auto"`` accepts Ipopt's own
        certificate when its last Newton step needed no inertia correction
        (MUMPS then found the KKT inertia correct) *and* was negligible
        (‖d‖ < 1e-6), so that the factorised iterate is the solution;
        otherwise (every warm re-solve: two Newton steps, the last not
        negligible) it factorises a penalised Hessian once
        (:meth:`penalised_certificate`, one sparse LDLᵀ), and only if that does not
        certify a minimum falls back to ``"exact"``.  (A one-step convergence from
        a stress-free start is factorised only where the compressive stress
        has not built up yet, and can end on a saddle: the exact check
        catches it.)
    ipopt_options : mapping
        Extra Ipopt options, overriding the defaults.
    """

    def __init__(self, nlp, *, tol: float, max_iter: int = 500, linear_solver: str = "mumps",
                 stability: str = "auto", ipopt_options: Mapping[str, Any] | None = None):
        if stability not in ("auto", "exact", "off"):
            raise ValueError(f"stability = {stability!r} must be 'auto', 'exact' or 'off'")
        self.nlp = nlp
        self.tol = float(tol)
        self.linear_solver = linear_solver
        self.stability = stability
        # Newton converges quadratically: once within 1e-6 the next step lands
        # far below, so three iterations in a row there mean the round-off
        # floor is reached.  Thin shells raise that floor like 1/h² (stretching
        # stiffness relative to bending).
        self.acceptable_tol = max(1e-6, 100 * self.tol)
        self.options = dict(IPOPT_DEFAULTS, tol=self.tol, max_iter=int(max_iter),
                            linear_solver=linear_solver, acceptable_tol=self.acceptable_tol,
                            acceptable_iter=3, acceptable_constr_viol_tol=1e-10)
        self.options.update(ipopt_options or {})
        # built on first use: a solve that Newton certifies needs no Ipopt
        self._solver = self._refactor = self._certifier = None
        n, m = nlp.x.shape[0], nlp.constraints
        self._bounds = (np.full(n, -np.inf), np.full(n, np.inf), np.zeros(m), np.zeros(m),
                        np.zeros(n))

    @property
    def _solve(self) -> Buffered:
        if self._solver is None:
            self._solver = Buffered(self._nlpsol("shell", self.options))
        return self._solver

    def _nlpsol(self, name: str, ipopt: Mapping[str, Any]) -> ca.Function:
        load_ipopt()
        d = self.nlp
        # ``numeric``: the same NLP on faster (compiled, not differentiable) kernels
        f = getattr(d, "numeric", None) or {k: getattr(d, k) for k in
                                            ("objective", "g", "grad_f", "jac_g", "hess_lag")}
        return ca.nlpsol(name, "ipopt", {"x": d.x, "p": d.D, "f": f["objective"], "g": f["g"]}, {
            "ipopt": dict(ipopt), "print_time": False, "error_on_fail": False,
            # a NaN at a trial point is Ipopt's to handle (a shorter step) or to report
            # (Invalid_Number_Detected, named): not a raw C++ warning on the user's terminal
            "show_eval_warnings": False,
            "grad_f": f["grad_f"], "jac_g": f["jac_g"], "hess_lag": f["hess_lag"],
            # Multipliers of bounds and parameters are not needed (there are
            # no bounds; parametric derivatives come from the KKT system).
            "calc_lam_p": False, "calc_lam_x": False, "bound_consistency": False,
            "calc_f": False, "calc_g": False})

    def solve(self, x0: np.ndarray, D: np.ndarray, lam_g0: np.ndarray,
              data=None) -> BackendResult:
        """Run Ipopt from (x0, λ0) with parameters D and certify the result.

        Parameters
        ----------
        x0 : ndarray, shape (n,)
            Initial iterate.
        D : ndarray
            The NLP's parameters (the transcription's cell data).
        lam_g0 : ndarray, shape (m,)
            Initial multipliers (zeros: a cold start).
        data : callable, optional
            Returns D as a ``casadi.DM`` (cheaper than converting the NumPy
            array when the certificate needs it).

        Returns
        -------
        BackendResult
            Converged or not; a converged one says in ``details`` how it was
            certified a minimum (unless ``stability="off"``).
        """
        lbx, ubx, lbg, ubg, lam_x0 = self._bounds
        t0 = time.perf_counter()
        x, _, _, _, lam, _ = self._solve(x0, D, lbx, ubx, lbg, ubg, lam_x0, lam_g0)
        seconds = time.perf_counter() - t0
        st = self._solve.stats()
        status = ipopt_status(st)
        iters = int(st.get("iter_count", -1))
        ok = converged(status, st)
        details: dict[str, Any] = {}
        if ok and self.stability != "off":
            it = st.get("iterations", {})
            reg, step = it.get("regularization_size", []), it.get("d_norm", [])
            # Ipopt's last factorisation was at the previous iterate: it
            # certifies the solution only if the last step was negligible.
            if (self.stability == "auto" and iters >= 2 and len(reg) and reg[-1] == 0
                    and step[-1] < 1e-6):
                details["stability"] = "ipopt_last_step"
                details["inertia_correction"] = 0.0
            elif self.stability == "auto" and self.penalised_certificate(x, D, lam, data):
                details["stability"] = "penalised_ldl"
                details["inertia_correction"] = 0.0
            else:
                details["stability"] = "ipopt_refactorisation"
                details["inertia_correction"] = self.inertia_correction(x, D, lam)
        return BackendResult(x, lam, status, iters, seconds, ok, details)

    def penalised_certificate(self, x: np.ndarray, D: np.ndarray, lam_g: np.ndarray,
                              data=None) -> bool:
        """True if (x, λ) is certified a strict local minimum by one sparse LDLᵀ; False: undecided.

        For any weights W ≥ 0, vᵀ(∇²ℒ + Jᵀ W J)v = vᵀ∇²ℒ v on the tangent space
        Jv = 0, so if M = ∇²ℒ + Jᵀ W J is positive definite the reduced Hessian
        is too (the converse holds for W large enough: Finsler's lemma).  M is
        positive definite iff its unpivoted LDLᵀ factorisation has positive
        pivots (Sylvester); we factorise M − 10⁻⁸ diag|M|, a margin against
        round-off, with W_i = ρ Σ_j |∇²ℒ_jj| / ‖J_i‖² over the unknowns j of
        constraint i (a penalty on the scale of the Hessian; ρ = 1, then 100).
        A saddle can never pass; a minimum that does not (weights too small,
        a nearly singular reduced Hessian) goes to :meth:`inertia_correction`.
        The factorisation is CasADi's sparse LDLᵀ of M (SPD, banded), far
        cheaper than the extra Ipopt call of :meth:`inertia_correction`.

        Parameters
        ----------
        x : ndarray, shape (n,)
        D : ndarray
            The NLP's parameters.
        lam_g : ndarray, shape (m,)
        data : callable, optional
            Returns D as a ``casadi.DM``.

        Returns
        -------
        bool
            True: a strict local minimum; False: undecided.
        """
        try:
            if self._certifier is None:
                self._certifier = self._build_certifier()
            F, solver = self._certifier
            Ddm = data() if data is not None else ca.DM(np.asarray(D).tolist())
            # lists convert to DM faster than NumPy arrays do
            xdm, ldm = ca.DM(np.asarray(x).tolist()), ca.DM(np.asarray(lam_g).tolist())
            n = F.size1_out(0)
            for rho in (1.0, 100.0):
                M = F(xdm, Ddm, ldm, rho)
                solver.nfact(M)
                if solver.neig(M) == 0 and solver.rank(M) == n:
                    return True
        except Exception:        # undecided: the exact check decides
            return False
        return False

    def _build_certifier(self):
        d = self.nlp
        f = getattr(d, "numeric", None) or {k: getattr(d, k) for k in ("jac_g", "hess_lag")}
        lam, rho = ca.MX.sym("lam", self._bounds[2].shape[0]), ca.MX.sym("rho")
        Ht = f["hess_lag"](d.x, d.D, 1.0, lam)
        J = f["jac_g"](d.x, d.D)[1]
        H = Ht + ca.triu(Ht, False).T
        pattern = ca.DM(J.sparsity(), 1.0)
        w = rho * ca.mtimes(pattern, ca.fabs(ca.diag(H))) / ca.fmax(ca.sum2(J * J), 1e-300)
        M = H + ca.mtimes(J.T, ca.mtimes(ca.diag(w), J))
        M = M - 1e-8 * ca.diag(ca.fabs(ca.diag(M)))
        F = ca.Function("certificate", [d.x, d.D, lam, rho], [M])
        solver = ca.Linsol("certificate", "ldl", M.sparsity())
        return F, solver

    def inertia_correction(self, x: np.ndarray, D: np.ndarray, lam_g: np.ndarray) -> float:
        """Hessian regularisation δ_w that Ipopt needs at (x, λ); 0 iff it is a strict minimum.

        By Sylvester's law of inertia the KKT matrix [[∇²ℒ, Jᵀ], [J, 0]] has
        exactly m negative eigenvalues (m constraints) and none zero iff the
        Hessian of the Lagrangian is positive definite on the tangent space of
        the constraints.  Ipopt factorises it with MUMPS (symmetric indefinite
        LDLᵀ with pivoting, which reports the inertia) and adds δ_w I to the
        Hessian until the inertia is right.  Restarting Ipopt at (x, λ) for
        one iteration, with a tolerance it cannot meet so that it does not stop
        before factorising, therefore tells whether (x, λ) is a minimum.

        Parameters
        ----------
        x : ndarray, shape (n,)
        D : ndarray
            The NLP's parameters.
        lam_g : ndarray, shape (m,)

        Returns
        -------
        float
            δ_w ≥ 0; 0 iff (x, λ) is a strict local minimum.

        Raises
        ------
        SolverError
            Status ``"Stability_Check_Failed"`` when Ipopt did not factorise.
        """
        if self._refactor is None:
            self._refactor = Buffered(self._nlpsol(
                "shell_inertia", dict(self.options, tol=1e-300, max_iter=1, acceptable_iter=0)))
        lbx, ubx, lbg, ubg, lam_x0 = self._bounds
        self._refactor(x, D, lbx, ubx, lbg, ubg, lam_x0, lam_g)
        reg = self._refactor.stats().get("iterations", {}).get("regularization_size", [])
        if len(reg) < 2:
            raise SolverError(f"stability check: Ipopt did not factorise the KKT matrix: "
                              f"{explain(STABILITY_CHECK_FAILED)}", STABILITY_CHECK_FAILED)
        return float(reg[1])

    def failure_message(self, label: str, result: BackendResult) -> str:
        """A one-paragraph explanation of a failed solve, naming Ipopt's status.

        Parameters
        ----------
        label : str
            The problem's name.
        result : BackendResult
            The failed solve.

        Returns
        -------
        str
            The status, the iterations and the status's line of the table
            (:func:`morphoshell.numerics.status.explain`).
        """
        if result.status == INVALID_OPTION:
            return (f"Ipopt rejected its options (status 'Invalid_Option'): with linear_solver = "
                    f"{self.linear_solver!r}, note that the HSL solvers (ma27, ma57, ...) load "
                    f"only if libhsl.so is on the library path; 'mumps' is bundled")
        return (f"Ipopt failed on {label!r} with status {result.status!r} after "
                f"{result.iterations} iterations: {explain(result.status)}; the last iterate is "
                f"attached (.last_iterate)")
