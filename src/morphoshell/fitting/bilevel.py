"""Fits of the morphoelastic model to traced midlines: a bilevel problem, three ways.

The paper (Supplementary, "Fitting of the morphoelastic theory to the average
cell sheet midlines of Volvox inversion") fits the 13-parameter Volvox model
(documentation: "Problems and families") to the average midline of an
inversion stage by minimising the fit energy E_fit
(:mod:`morphoshell.fitting.inner`) over its parameters
(:mod:`morphoshell.fitting.spec`).  The model midline is an *equilibrium*: the
outer least-squares problem has the inner energy minimisation as a
constraint.  Three methods, one interface, :func:`fit`:

``nelder-mead``  the paper's baseline, adaptive Nelder–Mead around
                 warm-started inner solves (:mod:`morphoshell.fitting.nested`);
``gradient``     bounded least squares with the exact Jacobian of the
                 residuals (:mod:`morphoshell.fitting.nested`);
``kkt``          one NLP in (parameters, shape, multipliers) with the inner
                 KKT conditions as constraints (:mod:`morphoshell.fitting.kkt`).

:func:`fit` checks its options and the data, runs the method, moves the
breakpoints' boxes while the fit ends on one of their edges, goes on from the
end's own mesh while it ends on another (:meth:`InnerProblem.own_mesh`), and
returns a :class:`morphoshell.fitting.results.FitResult`.
"""
from __future__ import annotations

import time
from typing import Callable

import numpy as np

from .._runtime.validate import real
from ..numerics.status import (FIT_MOVED_BOXES_FAILED, FIT_ON_BOX_EDGES,
                               MAXIMUM_EVALUATIONS_EXCEEDED)
from ..solvers.results import Equilibrium, SolverError
from .inner import InnerProblem
from .kkt import kkt_fit
from .kkt_problem import KKT_ITERATIONS
from .midline_checks import as_points, check_midline
from .nested import GRADIENT_EVALUATIONS, NM_EVALUATIONS, gradient_fit, nelder_mead_fit
from .results import FitError, FitResult, fit_result
from .spec import VARIANTS, FitSpec

__all__ = ["fit", "fit_moving_boxes", "check_options", "METHODS", "method_run", "FIT_NODES",
           "MAX_RECENTRES", "EVALUATION_LIMITS", "more_evaluations"]

#: Fit methods (see the module docstring).
METHODS = ("nelder-mead", "gradient", "kkt")
#: Mesh nodes a fit accepts (the command line's --nodes too): fewer cells cannot hold the
#: Volvox model's breakpoints and steps.
FIT_NODES = (20, 3200)
#: :func:`fit` moves the breakpoints' boxes, or goes on from the end's own mesh, at most
#: this many times in all.  Each move lets a breakpoint go PUSH_SHARE of the way to its
#: neighbour or halfway (a bound on the work: each move is a fit of its own).
MAX_RECENTRES = 12
#: What ``max_iterations`` counts for each method, and its default: Nelder–Mead's function
#: evaluations in all; the gradient fit's residual evaluations (least_squares' max_nfev);
#: the Ipopt iterations of each of the KKT fit's NLPs (and the residual evaluations of its
#: fallback Gauss–Newton steps, whose default is KKT_GN_ITERATIONS).  A fit that goes on
#: from moved boxes gets the limit anew for each run.
EVALUATION_LIMITS = {"nelder-mead": ("function evaluations", NM_EVALUATIONS),
                     "gradient": ("residual evaluations", GRADIENT_EVALUATIONS),
                     "kkt": ("Ipopt iterations per NLP", KKT_ITERATIONS)}


def more_evaluations(method: str, limit: int, option: str, start: str, go_on: str) -> str:
    """What to try when a fit ran out of evaluations (``"Maximum_Evaluations_Exceeded"``):
    the words of a :class:`FitResult`'s message and of ``morphoshell fit``'s last line.

    Parameters
    ----------
    method : str
        The fit's method: a Nelder–Mead fit is better started from a gradient fit.
    limit : int
        The limit it ran with.
    option : str
        What sets the limit: ``"max_iterations"`` (:func:`fit`), ``"--max-evaluations"``.
    start, go_on : str
        How to start a gradient fit from this one's end (after a Nelder–Mead fit), and how
        to go on from it by the same method (after the others).

    Returns
    -------
    str
        E.g. "raise max_iterations above 200, or go on from this fit with ...".
    """
    after = (f"start from a gradient fit with {start}" if method == "nelder-mead"
             else f"go on from this fit with {go_on}")
    return f"raise {option} above {limit}, or {after}"


def _out_of_evaluations(message: str, method: str, spec: FitSpec, limit: int,
                        nodes: int) -> str:
    """``message`` of a fit that ran out of evaluations, with the limit (``max_iterations``)
    and what to try (:func:`more_evaluations`, in the Python words: ``start=`` the fit's
    equilibrium, on its ``nodes``, of a spec started at its parameters, ``result.problem``)."""
    if spec.variant in VARIANTS and spec.base.family == "volvox":
        held = [n for n, v in spec.base.params.items()      # (beyond the variant's own κ₁)
                if n not in spec.fitted and n not in spec.tied and n != "sigma"
                and not (n == "kappa1" and spec.variant in ("flat", "undeformed"))]
        again = (f"volvox_spec({spec.variant!r}, result.problem"
                 + (f", hold={{n: result.parameters[n] for n in {tuple(held)!r}}}" if held
                    else "") + ")")
    else:
        again = "<the spec started at result.problem>"
    unit = EVALUATION_LIMITS[method][0]
    return (f"{message.rstrip('. ')} (max_iterations = {limit} {unit}): " + more_evaluations(
        method, limit, "max_iterations",
        f"fit({again}, data, 'gradient', nodes={nodes}, start=result.equilibrium)",
        f"fit({again}, data, {method!r}, nodes={nodes}, start=result.equilibrium)"))


def fit(spec: FitSpec, data, method: str = "gradient", *, nodes: int = 200,
        tol: float = 1e-10, max_iterations: int | None = None,
        start: Equilibrium | None = None) -> FitResult:
    """Fit ``spec`` to a midline: minimise E_fit over θ, the model's midline an equilibrium.

    The paper's fit (Supplementary, "Fitting of the morphoelastic theory to
    the average cell sheet midlines of Volvox inversion", "Fitting methods and
    details") by one of three methods (module docstring).  The options and
    the data are checked first (:func:`morphoshell.fitting.midline_checks.check_midline`);
    a fit that ends with a breakpoint on an edge of its box (not a constraint
    of the fit: :meth:`morphoshell.fitting.spec.FitSpec.on_box_edges`) goes on
    from boxes moved around its end, and one that converged on a mesh built for
    other breakpoints goes on from its end's own (the one a refit from the
    result builds: :meth:`morphoshell.fitting.inner.InnerProblem.own_mesh`;
    not Nelder–Mead, whose every run is a new simplex), at most
    :data:`MAX_RECENTRES` times in all (:func:`fit_moving_boxes`).

    Parameters
    ----------
    spec : FitSpec
        What is fitted (:func:`morphoshell.fitting.spec.volvox_spec` for the
        paper's variants).
    data : array_like (N, 2) or Midline
        The target midline (r, z) in the model gauge, N points equally spaced
        in arclength (:func:`morphoshell.io.midlines.resample`); N = 100 in the
        paper.
    method : {"nelder-mead", "gradient", "kkt"}
    nodes : int
        Mesh nodes of the inner solves, from 20 to 3200 (:data:`FIT_NODES`).
    tol : float
        Relative tolerance on E_fit² of the outer iteration, in [1e-15, 1).
    max_iterations : int, optional
        The limit of the outer iteration, for each run (:data:`EVALUATION_LIMITS`):
        function evaluations for Nelder–Mead (default 20000), residual
        evaluations for the gradient fit (default 200), Ipopt iterations of
        each NLP for KKT (default
        :data:`morphoshell.fitting.kkt_problem.KKT_ITERATIONS`).  A fit
        that reaches it returns ``converged=False``, ``stop =
        "Maximum_Evaluations_Exceeded"`` and a message that names the limit and
        how to go on from the fit (``start=result.equilibrium``) (KKT: raises FitError).
    start : Equilibrium, optional
        The inner state to start from (a direct solution of ``spec.base`` on
        the fit's mesh, e.g. a previous fit's); by default the physical branch
        by continuation from the stress-free parameters.

    Returns
    -------
    FitResult
        The fitted parameters with their Gauss–Newton standard errors, E_fit,
        the fitted equilibrium and midline, and whether and how the fit
        converged (a fit near a fold of the inner branch is not converged;
        :attr:`FitResult.stop` names how it ended), and where the fitted shape's
        walls pass through each other (:attr:`FitResult.contact`, checked by
        :func:`~morphoshell.solvers.contact.wall_contact`; the model has no
        self-contact).  Not warned of here (multi-starts, campaigns and profiles
        fit many times on the way to their result; ``morphoshell fit`` and
        campaigns warn of their result's, naming it:
        :func:`~morphoshell.solvers.contact.warn_of_contact`).

    Raises
    ------
    TypeError
        ``spec`` not a FitSpec, ``start`` not an Equilibrium, ``data`` not
        points (a file's path: read it with
        :func:`morphoshell.io.midlines.load_midline`), before any work.
    ValueError
        An option out of range, data that are not N >= 3 finite points, or
        a midline that does not start at the pole, turns back on itself or,
        of a Volvox fit, is far too short or long for the model
        (:func:`morphoshell.fitting.midline_checks.check_midline`), before
        any work.
    FitError
        KKT only: status ``"Fit_Saddle"`` when the fit ends on a state that is
        not a minimum of the inner energy, ``"Fit_Not_Reproduced"`` when the
        inner solve at the fitted parameters leaves that state, else Ipopt's
        status of the failed NLP; the last iterate is attached.  The other
        methods return ``converged=False`` and a message when their outer
        iteration stops short.
    """
    if method not in METHODS:
        raise ValueError(f"method = {method!r} must be one of {list(METHODS)}")
    check_options(nodes, tol, max_iterations)
    data = as_points(data)
    check_midline(spec, data)
    t0 = time.perf_counter()
    inner = InnerProblem(spec, data, nodes, start)
    # (Nelder-Mead does not go on from its end's own mesh: each run from there is a new
    # simplex, thousands of evaluations; the golden set's fit, 5 s, ran for over 20 minutes)
    spec, theta, iterations, ok, msg, stop = fit_moving_boxes(
        method_run(method), spec, inner, tol, max_iterations, own_mesh=method != "nelder-mead")
    if stop == MAXIMUM_EVALUATIONS_EXCEEDED:
        msg = _out_of_evaluations(msg, method, spec,
                                  max_iterations or EVALUATION_LIMITS[method][1], nodes)
    return fit_result(method, spec, inner, theta, iterations, time.perf_counter() - t0, ok, msg,
                      stop)


def method_run(method: str) -> Callable:
    """The outer iteration of ``method``, ``run(spec, inner, tol, max_iterations)`` returning
    (θ, iterations, converged, message, stop): what :func:`fit_moving_boxes` runs (looked up at
    each call, so that a test can replace a method)."""
    return {"nelder-mead": nelder_mead_fit, "gradient": gradient_fit, "kkt": kkt_fit}[method]


def fit_moving_boxes(run: Callable, spec: FitSpec, inner: InnerProblem, tol: float,
                     max_iterations: int | None, own_mesh: bool = True
                     ) -> tuple[FitSpec, np.ndarray, int, bool, str, str]:
    """``run`` (a method), again from moved boxes while it ends on a breakpoint's box edge,
    and on θ's own mesh while it ends on another one.

    The breakpoints' boxes order them for methods that take bounds, not
    constraints; their edges are not the fit's: a fit that ends on one goes
    on from boxes moved around its end (:meth:`FitSpec.recentred`), from
    the state it reached.  The inner solves' mesh has its knots at the
    breakpoints but their places in the mesh of the problem it was built for
    (:meth:`InnerProblem.own_mesh`); a fit started at θ, a refit from the
    result, builds θ's own, and on a coarse mesh the two E_fit differ by more
    than the fit's tolerance (a minimum of the one is not of the other): a fit
    that converged on another mesh goes on from θ's own.  Where the fits on two or
    more meshes each end where another is θ's own (a knot's place jumps where
    they end), the lowest of those ends stands.  Not with ``own_mesh=False``.

    Returns the last spec, θ, the outer iterations in all, whether it
    converged, its message and how it ended (``stop``); a failure (FitError)
    after a move leaves the fit within the last boxes standing, unconverged
    (``"Fit_Moved_Boxes_Failed"``), and a breakpoint still on an edge, or a
    mesh not θ's own, after :data:`MAX_RECENTRES` moves ends it unconverged
    (``"Fit_On_Box_Edges"``).
    """
    iterations, moved, remeshed, last = 0, [], 0, spec   # (last: the spec before the last move)
    why = ""            # why the fit went on the last time
    ends: list = []     # the ends inside their boxes on another mesh: (mesh, E_fit², state, end)
    while True:
        try:
            theta, its, ok, msg, stop = run(spec, inner, tol, max_iterations)
        except FitError as exc:
            if not (moved or remeshed):
                raise
            # the fit within the last boxes stands, reported as unconverged (an
            # NLP from moved boxes can run out of iterations where the last did not)
            iterations += int(getattr(exc, "iterations", 0) or 0)
            spec = inner.spec = last
            ok, stop, msg = False, FIT_MOVED_BOXES_FAILED, (
                f"{msg}; but {why}, and the fit from moved boxes failed: {exc}")
            break
        iterations += its
        # (a run that did not converge stops there, whatever its mesh)
        edges, own = spec.on_box_edges(theta), not (ok and own_mesh) or inner.on_own_mesh(theta)
        if not edges and own:
            break
        if not edges:
            lowest = _lowest_of_cycle(ends, inner, (spec, theta, ok, msg, stop))
            if lowest is not None:
                spec, theta, ok, msg, stop = lowest
                break
        why = (f"{', '.join(edges)} rested on the edge of their boxes" if edges else
               "it ended on another problem's mesh")
        if len(moved) + remeshed == MAX_RECENTRES:
            ok, stop, msg = False, FIT_ON_BOX_EDGES, (
                f"{msg}; but {why} still after {MAX_RECENTRES} moves of its boxes or mesh "
                f"(FitSpec.on_box_edges, InnerProblem.own_mesh): the optimum may lie beyond")
            break
        if edges:
            moved.append(", ".join(edges))
        else:
            remeshed += 1
        try:
            inner.eq, last = inner.solve(theta) if own else inner.remesh(theta), spec
        except SolverError as exc:       # (the end stands, on the mesh it reached)
            msg = f"{msg}; its end's own mesh failed to solve it ({exc})"
            break
        spec = inner.spec = spec.recentred(theta)
        inner.warm = True            # (the KKT fit goes on from this state)
    went = ([f"moving the breakpoints' boxes {len(moved)} times: {'; '.join(moved)}"] * bool(moved)
            + [f"going on from its end's own mesh {remeshed} times"] * bool(remeshed))
    if went:
        msg = f"{msg} (after {', and '.join(went)})"
    return spec, theta, iterations, ok, msg, stop


def _lowest_of_cycle(ends: list, inner: InnerProblem, end: tuple) -> tuple | None:
    """The lowest end of a cycle of meshes, or None (and ``end`` recorded in ``ends``).

    ``end`` = (spec, θ, converged, message, stop) of a run that ended inside
    its boxes on a mesh that is not θ's own.  When a run has already ended on
    θ's own mesh, the runs since went round meshes whose fits each end where
    another is θ's own: the lowest of their ends, made current again (its
    mesh, spec and state), ends the fit.
    """
    spec, theta = end[:2]
    eq = inner.solve(theta)
    res = inner.residuals(eq)
    ends.append((inner.solver.mesh, float(res @ res), eq, end))
    own = inner.own_mesh(theta)
    first = next((i for i, item in enumerate(ends) if item[0] == own), None)
    if first is None:
        return None
    _, _, eq, (spec, theta, ok, msg, stop) = min(ends[first:], key=lambda item: item[1])
    inner.spec = spec
    inner.keep(theta, eq)
    return spec, theta, ok, (f"{msg}; the fits on {len(ends) - first} meshes each end where "
                             f"another is its end's own (a knot's place jumps there): the "
                             f"lowest end stands"), stop


def check_options(nodes, tol, max_iterations) -> None:
    """ValueError naming the first of :func:`fit`'s options that is out of range (profiles too)."""
    def integer(value) -> bool:
        return isinstance(value, (int, np.integer)) and not isinstance(value, bool)

    lo, hi = FIT_NODES
    if not (integer(nodes) and lo <= nodes <= hi):     # (5 nodes: too few for the Volvox knots)
        raise ValueError(f"nodes = {nodes!r} must be an integer from {lo} to {hi}")
    if real("tol", tol) < 1e-15 or tol >= 1:     # (scipy: below eps ends no iteration)
        raise ValueError(f"tol = {tol!r} must lie in [1e-15, 1)")
    if max_iterations is not None and not (integer(max_iterations) and max_iterations >= 1):
        raise ValueError(f"max_iterations = {max_iterations!r} must be a positive integer")
