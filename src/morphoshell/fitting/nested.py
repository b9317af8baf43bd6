"""The nested fits: an outer optimiser around warm-started inner solves.

``nelder-mead``  the paper's baseline (Supplementary, "Fitting of the
                 morphoelastic theory to the average cell sheet midlines of
                 Volvox inversion", "Fitting methods and details"): an
                 ``fminsearch``-like adaptive Nelder–Mead (scipy, Gao & Han
                 coefficients), restarted around its best point;
``gradient``     bounded least squares (``scipy.optimize.least_squares``, trust
                 region) with the exact Jacobian of the residuals through the
                 parametric inner solve (implicit function theorem,
                 :mod:`morphoshell.solvers.parametric`).

Each returns (θ, outer iterations, converged, message, stop), ``stop`` naming
how it ended (a key of :data:`morphoshell.numerics.status.STATUSES`); a trial
point whose inner solve fails is rejected like a bad step, not fatal.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from .._runtime.console import counter
from ..numerics.status import (FIT_CONVERGED, FIT_NOT_STATIONARY, FIT_STALLED,
                               MAXIMUM_EVALUATIONS_EXCEEDED)
from ..solvers.results import SolverError

if TYPE_CHECKING:
    from .inner import InnerProblem
    from .spec import FitSpec

__all__ = ["nelder_mead_fit", "gradient_fit", "MAX_FAILED_TRIALS", "MAX_REMESHES", "STATIONARY",
           "RESIDUAL_FLOOR", "NM_RESTARTS", "NM_EVALUATIONS", "GRADIENT_EVALUATIONS"]

#: Nelder–Mead's function evaluations in all (its restarts included), by default: the
#: paper's fminsearch budget.
NM_EVALUATIONS = 20000
#: The gradient fit's residual evaluations (least_squares' max_nfev), by default.
GRADIENT_EVALUATIONS = 200

#: Nelder–Mead runs at most this many simplices (restarts around the best point).
NM_RESTARTS = 8
#: The gradient fit stops (not converged, at its best point) after this many
#: consecutive trial points whose inner solve failed (each is one failed warm
#: solve: the trust region has shrunk 4⁸-fold by then; tuned on fits stuck at a fold).
MAX_FAILED_TRIALS = 8
#: The gradient fit's least_squares starts again from its end at most this many times when
#: a solve moved the inner problem to another mesh during its run (:func:`gradient_fit`).
MAX_REMESHES = 8
#: A trial point that moved the inner problem to another mesh with E_fit more than this
#: factor above the best point's has jumped to another branch of equilibria
#: (:class:`_Trials`): least-squares trials near a minimum lie within percents of it,
#: the jumps seen (synthetic campaign, unstressed t08, flat t09) 20-160 times above.
REMESH_JUMP = 2.0
#: Largest gradient, relative to the residual's norm, at which the gradient method's end is
#: a stationary point (first-order optimality over ‖r‖, scaled variables; see
#: :func:`gradient_fit`; tuned on the synthetic campaign's least-squares ends).
STATIONARY = 1e-2
#: Residual norm (units of R) below which a fit is exact and its gradient is compared with
#: this instead (noiseless data: E_fit ~ 1e-14 R).
RESIDUAL_FLOOR = 1e-8


def _feasible(spec, theta) -> bool:
    """Whether θ lies within its bounds and gives a valid problem."""
    lo, hi = spec.box()
    if np.any(theta < lo) or np.any(theta > hi):
        return False
    try:
        spec.problem(theta)
    except ValueError:
        return False
    return True


def nelder_mead_fit(spec: FitSpec, inner: InnerProblem, tol: float,
                    max_iterations: int | None) -> tuple[np.ndarray, int, bool, str, str]:
    """The paper's fit: adaptive Nelder–Mead on E_fit(θ), restarted around its best point.

    The paper's modified ``fminsearch`` (Supplementary, "Fitting of the
    morphoelastic theory to the average cell sheet midlines of Volvox
    inversion", "Fitting methods and details"): scipy's Nelder–Mead with
    the adaptive (Gao & Han) coefficients, within the bounds.  Points whose
    inner solve fails, or that are infeasible, get 10 times the worst E_fit
    seen.  A simplex can collapse before the minimum: the search restarts
    around its best point (at most :data:`NM_RESTARTS` simplices) while a
    restart improves E_fit by 1 % and E_fit is above 10⁻⁶ of the start's.
    On a terminal a progress bar counts the evaluations against the limit
    (thousands of them, minutes at 200 nodes: :func:`morphoshell._runtime.console.counter`).

    Parameters
    ----------
    spec : FitSpec
        What is fitted.
    inner : InnerProblem
        The inner solves and residuals.
    tol : float
        Relative tolerance on E_fit (scipy's ``fatol`` times the start's E_fit).
    max_iterations : int or None
        Function evaluations in all, restarts included (default :data:`NM_EVALUATIONS`).

    Returns
    -------
    theta : ndarray, shape (k,)
        The best point, in ``spec.fitted`` order.
    evaluations : int
        Function evaluations.
    converged : bool
        Whether the last simplex met its tolerances.
    message : str
        scipy's.
    stop : str
        ``"Fit_Converged"``, or ``"Maximum_Evaluations_Exceeded"`` when the
        evaluations ran out.
    """
    budget = max_iterations or NM_EVALUATIONS
    with counter(budget, desc="Nelder-Mead", unit="evaluation") as bar:
        worst = [1.0]

        def E(theta):
            bar.update()
            if not _feasible(spec, theta):
                return 10 * worst[0]
            try:
                res = inner.residuals(inner.solve(theta))
            except SolverError:
                return 10 * worst[0]
            value = float(np.sqrt(res @ res))
            worst[0] = max(worst[0], value)
            return value

        theta, evaluations, out = _restarted_simplices(E, spec, tol, budget)
    # (scipy's Nelder-Mead fails only by running out of evaluations or iterations)
    stop = FIT_CONVERGED if out.success else MAXIMUM_EVALUATIONS_EXCEEDED
    return theta, evaluations, bool(out.success), str(out.message), stop


def _restarted_simplices(E, spec: FitSpec, tol: float, budget: int) -> tuple:
    """Nelder–Mead on ``E`` from ``spec.theta0``, restarted around its best point (see
    :func:`nelder_mead_fit`): the best θ, the evaluations, the last simplex's result."""
    from scipy.optimize import minimize

    lo, hi = spec.box()
    bounds = list(zip(np.where(np.isfinite(lo), lo, None), np.where(np.isfinite(hi), hi, None)))
    theta, evaluations, best = spec.theta0, 0, np.inf
    start = E(theta)
    # A simplex can collapse before the minimum: restart around the best point,
    # as careful fminsearch users do, while a restart still improves E_fit by
    # 1 % and E_fit is not negligible (1e-6 of the start's).
    for _ in range(NM_RESTARTS):
        out = minimize(E, theta, method="Nelder-Mead", bounds=bounds,
                       options={"adaptive": True, "xatol": 1e-8,
                                "fatol": tol * max(start, 1e-12),
                                "maxfev": budget - evaluations})
        evaluations += int(out.nfev)
        improved = out.fun < 0.99 * best
        theta, best = out.x, min(best, float(out.fun))
        if not improved or best < 1e-6 * start or evaluations >= budget:
            break
    return theta, evaluations, out


class _Stalled(Exception):
    """Raised inside the gradient fit's residuals when trial points keep failing."""


def _mesh_of(inner) -> object:
    """The mesh of the inner problem's solves (None for a stand-in without one)."""
    return getattr(getattr(inner, "solver", None), "mesh", None)


class _Trials:
    """The residuals and Jacobian that the gradient fit gives ``least_squares``, the best
    point they have seen (θ, cost, state), and whether a solve moved the inner problem to
    another mesh (``moved``)."""

    def __init__(self, inner: InnerProblem, theta):
        self.inner, self.failures, self.evaluations = inner, 0, 0
        self.best = [np.array(theta, dtype=float), np.inf, None]
        self.mesh, self.moved = _mesh_of(inner), False

    def fun(self, theta):
        # A trial point whose inner solve fails (the continuation cannot reach
        # it) or that is infeasible (|eta| >= 1) is rejected like a bad step:
        # the trust region shrinks on non-finite residuals instead of the fit
        # aborting.  When every trial fails (a state at a fold of the branch,
        # where the trust region would shrink for many minutes), the fit stops
        # at its best point, not converged.
        self.evaluations += 1
        mesh = _mesh_of(self.inner)
        try:
            # a trial whose warm solve fails is rejected without continuation, which
            # would cost more than the rest of the fit
            eq = self.inner.solve(theta, trial=True)
            self._watch()
            res = self.inner.residuals(eq)
        except (SolverError, ValueError):
            self.failures += 1
            if self.failures >= MAX_FAILED_TRIALS:
                raise _Stalled from None
            return np.full(2 * self.inner.n, np.inf)
        self.failures = 0
        cost = float(res @ res)
        if cost < self.best[1]:
            self.best[:] = [np.array(theta, dtype=float), cost, eq]
        elif cost > REMESH_JUMP ** 2 * self.best[1] and _mesh_of(self.inner) != mesh:
            # A trial that moved the mesh leaves the inner problem only its own state
            # there (InnerProblem.solve); where that jumped to another branch, every
            # trial after it went on from that branch (the synthetic campaign's
            # unstressed t08: E_fit 0.042 -> 0.67 R, and the fit ended at 0.755 R;
            # the next four timepoints' fits failed).  Such a trial, which
            # least_squares rejects, leaves no trace: back to the best point's state
            # and mesh.
            self.inner.keep(self.best[0], self.best[2])
        return res

    def jac(self, theta):
        eq = self.inner.solve(theta)
        self._watch()
        return self.inner.jacobian(eq, theta)

    def _watch(self) -> None:
        """Note whether the last solve moved the inner problem to another mesh."""
        mesh = _mesh_of(self.inner)
        if mesh != self.mesh:
            self.mesh, self.moved = mesh, True


def gradient_fit(spec: FitSpec, inner: InnerProblem, tol: float, max_iterations: int | None,
                 theta0: np.ndarray | None = None) -> tuple[np.ndarray, int, bool, str, str]:
    """Bounded least squares of the residuals with their exact Jacobian (trust region).

    ``scipy.optimize.least_squares`` (``trf``, ``x_scale="jac"``) on the
    residuals r(θ) of :meth:`InnerProblem.residuals`, with the Jacobian of
    :meth:`InnerProblem.jacobian` (implicit function theorem).  A trial point
    whose warm inner solve fails, or that is infeasible, gets non-finite
    residuals and is rejected like a bad step; after
    :data:`MAX_FAILED_TRIALS` such trials in a row the fit stops at its best
    point, not converged.  An end by ``ftol`` or ``xtol`` whose gradient
    exceeds :data:`STATIONARY` of the residual's norm is a stall, not a
    minimum, and is reported as not converged.

    A solve that moves the inner problem to another mesh (the breakpoints far
    from its knots, or a continuation that refined it) changes E_fit under
    the iteration, which compares the costs of both meshes: where the new
    mesh's E_fit lies higher every trial is rejected, and least_squares stops
    there by xtol or ftol (the synthetic t02 embryo's free fit at 60 nodes,
    "converged" at E_fit 0.0124 R for 0.0122 R).  Such an end starts
    least_squares again from there, on the mesh it reached, at most
    :data:`MAX_REMESHES` times.

    Parameters
    ----------
    spec : FitSpec
        What is fitted.
    inner : InnerProblem
        The inner solves, residuals and Jacobian.
    tol : float
        Relative tolerance on E_fit² (scipy's ``ftol``).
    max_iterations : int or None
        Residual evaluations in all, least_squares' ``max_nfev`` (default
        :data:`GRADIENT_EVALUATIONS`).
    theta0 : ndarray, shape (k,), optional
        The start (default ``spec.theta0``).

    Returns
    -------
    theta : ndarray, shape (k,)
        The end point, in ``spec.fitted`` order.
    evaluations : int
        Residual evaluations.
    converged : bool
        Whether it ended at a stationary point.
    message : str
        scipy's, or why it is not converged.
    stop : str
        ``"Fit_Converged"``, ``"Maximum_Evaluations_Exceeded"``,
        ``"Fit_Stalled"`` (the failed trials) or ``"Fit_Not_Stationary"``.
    """
    budget = max_iterations or GRADIENT_EVALUATIONS
    theta, spent = spec.theta0 if theta0 is None else theta0, 0
    for again in range(MAX_REMESHES + 1):
        trials = _Trials(inner, theta)
        try:
            theta, spent, ok, message, stop = _least_squares(spec, trials, theta, tol,
                                                             budget, spent)
        except _Stalled:
            if trials.best[2] is not None:
                # (its state may have left the archive, and a solve from another one there
                # can fail, and with it the whole fit)
                inner.keep(trials.best[0], trials.best[2])
            return (trials.best[0], spent + trials.evaluations, False,
                    f"stopped at the best point reached, after {MAX_FAILED_TRIALS} consecutive "
                    f"trial points whose inner solve failed (a fold of the branch?)", FIT_STALLED)
        if not (trials.moved and stop in (FIT_CONVERGED, FIT_NOT_STATIONARY)) or \
                spent >= budget or again == MAX_REMESHES:
            break
        try:
            inner.solve(theta)     # (the next start, on the mesh reached: ready for a trial)
        except (SolverError, ValueError):
            break
    return theta, spent, ok, message, stop


def _least_squares(spec: FitSpec, trials: _Trials, theta, tol: float, budget: int,
                   spent: int) -> tuple[np.ndarray, int, bool, str, str]:
    """:func:`gradient_fit`'s least_squares run from θ, ``spent`` of its ``budget`` of
    evaluations gone: (θ, evaluations in all, converged, message, stop); raises _Stalled."""
    from scipy.optimize import least_squares

    lo, hi = spec.box()
    out = least_squares(trials.fun, theta, jac=trials.jac, bounds=(lo, hi), method="trf",
                        x_scale="jac", ftol=tol, xtol=1e-12, gtol=1e-12,
                        max_nfev=budget - spent)
    stall = _not_stationary(out)
    if stall:
        return out.x, spent + int(out.nfev), False, stall, FIT_NOT_STATIONARY
    # (status 0: max_nfev ran out; -1, bad input, raises before)
    stop = FIT_CONVERGED if out.status > 0 else MAXIMUM_EVALUATIONS_EXCEEDED
    return out.x, spent + int(out.nfev), bool(out.status > 0), str(out.message), stop


def _not_stationary(out) -> str | None:
    """Why the end of ``least_squares`` (its result ``out``) is a stall, or None.

    least_squares also stops when its trust region has shrunk below xtol or
    its cost no longer falls (ftol), which a stall does too: near a fold
    trial points jump between states of the inner branch and are all
    rejected, whatever the Jacobian promises.  Such an end has a gradient
    (the cosine of r with J's scaled columns, ``x_scale="jac"``) above
    :data:`STATIONARY`; gtol (status 1) is stationarity itself, and a misfit
    below :data:`RESIDUAL_FLOOR` is exact data's.
    """
    cos = float(out.optimality) / max(np.sqrt(2 * float(out.cost)), RESIDUAL_FLOOR)
    if out.status > 1 and cos > STATIONARY:
        return (f"{out.message} But it is not a stationary point: the gradient there is "
                f"{cos:.2g} of the residual's norm (STATIONARY = {STATIONARY:g}), so trial "
                f"points near it were rejected for a reason the Jacobian does not see (the "
                f"inner state jumping between branches near a fold?)")
    return None
