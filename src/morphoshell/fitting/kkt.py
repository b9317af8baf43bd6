"""The KKT fit: how the one-NLP method gets to its optimum and checks it.

The bilevel fit as one NLP in (θ, shape, multipliers), the inner equilibrium's
KKT conditions as constraints (:class:`morphoshell.fitting.kkt_problem.KKTProblem`).
The KKT conditions hold at saddles too: the fitted state is checked to be a
minimum of the inner energy (the inertia of its KKT matrix) and to be what the
inner solve gives at the fitted parameters, and is rejected otherwise.  Where
the NLP starts decides whether it converges: :func:`kkt_fit` gets there by
Gauss–Newton steps of the reduced problem
(:func:`morphoshell.fitting.nested.gradient_fit`).
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ..numerics.status import FIT_NOT_REPRODUCED, FIT_SADDLE, GAUSS_NEWTON_STOPPED
from ..solvers.observables import midline_cells
from ..solvers.results import SolverError
from .inner import InnerProblem
from .kkt_problem import WINDOW, KKTProblem
from .nested import gradient_fit
from .results import FitError

if TYPE_CHECKING:
    from .spec import FitSpec

__all__ = ["kkt_fit", "KKT_GN_TOL", "KKT_GN_ITERATIONS"]

#: Tolerance (relative on E_fit²) of the Gauss-Newton steps that start every KKT fit
#: (:func:`kkt_fit`: they bring the NLP near its optimum; tuned by scripts/bench_kkt.py).
KKT_GN_TOL = 1e-6
#: Residual evaluations of those Gauss-Newton steps, at most (the gradient fit's default).
KKT_GN_ITERATIONS = 200


def kkt_fit(spec: FitSpec, inner: InnerProblem, tol: float,
            max_iterations: int | None) -> tuple[np.ndarray, int, bool, str, str]:
    """The fit as one NLP in (θ, x, λ), the inner KKT conditions as constraints.

    Route A: Gauss–Newton steps of the reduced problem from the start
    (``inner.eq``: a previous fit's state, or the start parameters' branch)
    to :data:`KKT_GN_TOL`, at most :data:`KKT_GN_ITERATIONS` evaluations,
    then the NLP from their end, its multipliers the reduced problem's
    adjoints.  From farther starts (the family's defaults, a previous
    fit's state, a coarse mesh's optimum) the NLP's Newton steps crawl
    through the curved valleys of the poorly identified directions, move
    fit points out of their windows or cross nearly singular stretches of
    the branch, and fail; its iterations cost several Gauss–Newton steps
    each.  Route B, when A fails (its NLP, or its end is a saddle or not
    reproduced): Gauss–Newton steps to the fit's tolerance, then the NLP
    from their end.  Each NLP stops after
    :data:`morphoshell.fitting.kkt_problem.KKT_ITERATIONS`.

    Parameters
    ----------
    spec : FitSpec
        What is fitted.
    inner : InnerProblem
        The inner problem; its state becomes the fitted one.
    tol : float
        Ipopt's tolerance (and the Gauss–Newton steps' of route B).
    max_iterations : int or None
        Ipopt iterations of each NLP (default
        :data:`morphoshell.fitting.kkt_problem.KKT_ITERATIONS`), and residual
        evaluations of route B's Gauss–Newton steps (default
        :data:`KKT_GN_ITERATIONS`).

    Returns
    -------
    theta : ndarray, shape (k,)
        The fitted parameters, in ``spec.fitted`` order.
    iterations : int
        Ipopt iterations and Gauss–Newton evaluations in all.
    converged : bool
        True (a failure raises).
    message : str
        Ipopt's status.
    stop : str
        Ipopt's status again (a key of :data:`morphoshell.numerics.status.STATUSES`).

    Raises
    ------
    FitError
        Both routes failed: the first failure's status, with the second's
        reason.
    """
    theta0, eq, spent, its = spec.theta0, inner.eq, 0, 0
    try:
        theta0, eq, spent = _gauss_newton_steps(spec, inner, KKT_GN_TOL, KKT_GN_ITERATIONS,
                                                theta0, eq)
        theta, x, lam, its, status = _kkt_nlp(spec, inner, tol, max_iterations, theta0, eq)
        return _kkt_checked(inner, theta, x, lam, spent + its, status)
    except FitError as exc:
        # Route B: from the reduced optimum the NLP converges where from
        # another start it failed or ended on a saddle (and a homotopy in the
        # data that shortened its steps cost far more, mostly to fail).
        spent += its or int(getattr(exc, "iterations", 0) or 0)
        first = exc
    try:
        theta0, eq, steps = _gauss_newton_steps(spec, inner, tol, max_iterations, theta0, eq,
                                                required=True)
    except FitError as exc:         # what failed first, and why it was not tried again
        raise FitError(f"{first}; {exc}", first.status, first.last_iterate) from None
    theta, x, lam, its, status = _kkt_nlp(spec, inner, tol, max_iterations, theta0, eq)
    return _kkt_checked(inner, theta, x, lam, spent + steps + its, status)


def _gauss_newton_steps(spec, inner, ftol, max_evaluations, theta0, eq,
                        required: bool = False) -> tuple:
    """(θ, its inner state, evaluations): Gauss–Newton steps from θ₀ and its state ``eq``.

    The reduced problem's (:func:`gradient_fit`).  From a start that no solve
    reproduces (a saddle: rejected after the NLP) there are none.  When
    ``required``, steps that stop short of ``ftol`` raise FitError: they
    stopped at a fold of the branch, say, and an NLP from there goes wild.
    """
    evaluations = 0
    try:
        theta, evaluations, converged, message, _ = gradient_fit(spec, inner, ftol,
                                                                 max_evaluations, theta0)
        if converged or not required:
            return theta, inner.solve(theta), evaluations
    except SolverError as exc:
        if not required:
            return theta0, eq, 0
        message = str(exc)
    exc = FitError(f"the Gauss-Newton steps to start again from stopped short: {message}",
                   GAUSS_NEWTON_STOPPED, eq)
    exc.iterations = evaluations
    raise exc


def _kkt_nlp(spec, inner, tol, max_iterations, theta0, eq) -> tuple:
    """(θ, x, λ, iterations, status) of the KKT NLP from θ₀ and its inner state ``eq``.

    θ₀ is close to the optimum (Gauss–Newton steps' end): the NLP starts from
    the reduced problem's adjoints as multipliers (from zero ones the exact
    Hessian lacks the constraints' curvature and the NLP stalls in line
    searches; Ipopt's least-squares estimate fails now and then) and with a
    tiny initial barrier (a larger one has the NLP wander while mu falls).
    """
    inner.eq = eq         # (the NLP's objective is scaled by the misfit there)
    nlp = KKTProblem(spec, inner, tol, max_iterations, mu_init=1e-9, adjoint_duals=True)
    return _kkt_cells(nlp, inner, theta0, eq.x, eq.lam_g, inner.data)


def _kkt_checked(inner, theta, x, lam, iterations, status) -> tuple:
    """:func:`kkt_fit`'s result at the NLP's end, after checking that it is the inner minimum.

    Raises FitError at a saddle of the inner energy, or when the inner solve
    at the fitted θ does not stay at x.
    """
    spec = inner.spec
    problem = spec.problem(theta)
    p = problem.parameter_vector()
    d = inner.solver.disc
    D = d.cell_data(p)
    fitted = inner.solver.equilibrium(problem, x, lam, p, np.zeros(0), D, inner.eq.solver, True)
    if inner.solver.backend.inertia_correction(x, D, lam) > 0:
        raise FitError(
            "the KKT fit ended on a stationary state of the inner energy that is not a "
            "minimum (a saddle: the reduced Hessian is not positive definite); start from "
            "another point or use the gradient method", FIT_SADDLE, fitted)
    # the fitted state must be what the inner problem gives there: re-solve from it
    check = inner.solver.solve(problem, warm_start=fitted)
    inner.solves += 1
    if np.max(np.abs(check.x - x)) > 1e-6:
        raise FitError("the KKT fit's state is not reproduced by the inner solve at the "
                       "fitted parameters", FIT_NOT_REPRODUCED, fitted)
    inner.reset(theta, check)
    return theta, iterations, True, status, status


def _kkt_cells(nlp, inner, theta, x, lam, data) -> tuple:
    """NLPs to ``data`` from (θ, x, λ), rebuilt while the fit points leave their cells' windows."""
    iterations, status = 0, ""
    spec, d = inner.spec, inner.solver.disc
    for _ in range(8):
        cells = midline_cells(d, x, spec.problem(theta).parameter_vector(), inner.n)
        try:
            theta, x, lam, its, status = nlp.solve(cells, theta, x, lam, data)
        except FitError as exc:
            exc.iterations = iterations + int(nlp.nlp.stats().get("iter_count", 0))
            raise
        iterations += its
        # the NLP chose each point's cell within a window around the assigned
        # one: exact as long as every point stayed inside its window
        now = midline_cells(d, x, spec.problem(theta).parameter_vector(), inner.n)
        if max(abs(a - b) for a, b in zip(now, cells)) <= WINDOW:
            break
    return theta, x, lam, iterations, status
