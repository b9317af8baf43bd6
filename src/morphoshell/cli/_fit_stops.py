"""The last line of ``morphoshell fit``: why the fit stopped, and what to try next.

A fit's JSON holds the method's message, but a user at a terminal reads the
last line: it names the method, how the fit ended (:attr:`FitResult.stop`, a
key of :data:`morphoshell.numerics.status.STATUSES`), after how many
evaluations, at which E_fit, and, when it did not converge, the options that
may help (``--max-evaluations``, ``--start``, ``--set``, ``--method``).
A fit that fails (the KKT fit raises) ends with the error line instead:
:func:`failure_hint` is what that line says to try.  A fit that ends far above what
the model gives any traced midline (:data:`IMPLAUSIBLE_E_FIT`) points at the input
first: its orientation, scale and axis (the verdict of
:func:`morphoshell.fitting.midline_checks.input_check`, which the JSON holds).
"""
from __future__ import annotations

from typing import TYPE_CHECKING

from ..numerics.status import (FIT_CONVERGED, FIT_MOVED_BOXES_FAILED, FIT_NEAR_FOLD,
                               FIT_NOT_MINIMUM, FIT_NOT_STATIONARY, FIT_ON_BOX_EDGES, FIT_STALLED,
                               MAXIMUM_EVALUATIONS_EXCEEDED, MAXIMUM_ITERATIONS_EXCEEDED,
                               SOLVE_SUCCEEDED, SOLVED_TO_ACCEPTABLE_LEVEL, explain)
from ..fitting.bilevel import more_evaluations
from ..fitting.midline_checks import (IMPLAUSIBLE_E_FIT, INPUT_CHECK, MISFIT, far_above,
                                      input_check)

if TYPE_CHECKING:
    from ..fitting import FitResult

__all__ = ["stop_line", "failure_hint", "far_above", "NAMES", "IMPLAUSIBLE_E_FIT",
           "INPUT_CHECK", "MISFIT"]

#: How the last line names each method, and what its iteration count counts.
NAMES = {"nelder-mead": ("Nelder-Mead", "evaluations"),
         "gradient": ("Gradient fit", "evaluations"),
         "kkt": ("KKT fit", "iterations")}

_START = "--start FIT.json"
#: Where a stalled fit (near a fold of the branch) may do better.
_ELSEWHERE = f"start nearer the data with {_START} (a fit of a neighbouring stage)"


def stop_line(result: FitResult, limit: int, refit_of: FitResult | None = None) -> str:
    """One line: how ``result`` ended and, unless it converged, what to try.

    Parameters
    ----------
    result : FitResult
        The fit.
    limit : int
        The evaluation limit it ran with (``--max-evaluations`` or the
        method's default, :data:`morphoshell.fitting.bilevel.EVALUATION_LIMITS`).
    refit_of : FitResult, optional
        The fit whose end ``result`` went on from (``--profile``'s refit, where it
        found a lower E_fit): the line says so.

    Returns
    -------
    str
        E.g. "Nelder-Mead stopped after 20000 evaluations (the limit) at E_fit
        0.0123 R, not converged: raise --max-evaluations above 20000, or start
        from a gradient fit with --start FIT.json".
    """
    name, unit = NAMES.get(result.method, (result.method, "iterations"))
    if refit_of is not None:
        name += f" (the profiles' refit from the fit's end at E_fit {refit_of.E_fit:.4g} R)"
    its = f"{result.outer_iterations} {unit}"
    at = f"at E_fit {result.E_fit:.4g} R"
    far = far_above(result.E_fit)
    if result.converged:
        ipopt = result.stop in (SOLVE_SUCCEEDED, SOLVED_TO_ACCEPTABLE_LEVEL)
        check = input_check(result.E_fit)       # (the JSON's: one verdict)
        return f"{name} converged after {its} {at}" + (f" (Ipopt: {result.stop})" if ipopt
                                                       else "") + (f"; {check}" if check
                                                                   else "")
    what, why, remedy = _not_converged(result, its, limit)
    tail = f"{why}; {remedy}" if why else remedy
    return f"{name} {what} {at}, not converged: " + (f"{far} first; if it is right, {tail}"
                                                     if far else tail)


def _not_converged(result: FitResult, its: str, limit: int) -> tuple[str, str, str]:
    """(what happened, why, what to try) for a fit that did not converge, by its stop."""
    stop = result.stop
    if stop == MAXIMUM_EVALUATIONS_EXCEEDED:
        # (a fit that moved its boxes ran several times, each with the limit)
        which = ("the limit" if result.outer_iterations == limit
                 else f"the limit of {limit} in its last run")
        return f"stopped after {its} ({which})", "", more_evaluations(
            result.method, limit, "--max-evaluations", _START, f"{_START} (its --json output)")
    table = {
        FIT_STALLED: (f"stopped at its best point after {its}",
                      "trial points in a row failed their inner solve (a fold of the branch?)",
                      f"{_ELSEWHERE}, or --method nelder-mead"),
        FIT_NOT_STATIONARY: (f"stalled short of a stationary point after {its}",
                             "trial points near it were rejected (a fold of the branch?)",
                             f"{_ELSEWHERE}, or --method nelder-mead"),
        FIT_NEAR_FOLD: (f"ended near a fold of the equilibrium branch after {its}",
                        "the shape is nearly unstable, its standard errors meaningless",
                        f"start from another point with {_START}, or hold a poorly identified "
                        f"parameter with --set NAME=VALUE"),
        FIT_ON_BOX_EDGES: (f"ended with a breakpoint on the edge of its box after {its}",
                           "the optimum may lie beyond the boxes' last move",
                           f"hold it with --set NAME=VALUE, or {_ELSEWHERE}"),
        FIT_MOVED_BOXES_FAILED: (f"failed from moved boxes after {its}",
                                 "the fit within the last boxes stands",
                                 f"go on from it with {_START} (its --json output), or another "
                                 f"--method"),
        FIT_NOT_MINIMUM: (f"ended short of its minimum after {its}",
                          "a profile's refit lies lower (the profiles' notes say where)",
                          f"fit again from it with {_START} (its --json output), or another "
                          f"--method"),
    }
    return table.get(stop, (f"stopped after {its}", stop,
                            explain(stop) if stop != FIT_CONVERGED else "see its message"))


def failure_hint(status: str, limit: int, unit: str, started: bool) -> str:
    """What the error line of a failed fit (exit status 3) says to try.

    Parameters
    ----------
    status : str
        The failure's status (:attr:`morphoshell.numerics.status.SolverError.status`).
    limit : int
        The evaluation limit the fit ran with.
    unit : str
        What the limit counts (:data:`morphoshell.fitting.bilevel.EVALUATION_LIMITS`).
    started : bool
        Whether the fit started from ``--start``.
    """
    where = "a --start nearer the data" if started else \
        f"{_START} (a fit of a neighbouring stage)"
    if status == MAXIMUM_ITERATIONS_EXCEEDED:
        return (f"The iterations ran out: raise --max-evaluations above {limit} ({unit}), or "
                f"try {where}")
    # the usual cause: a mid-inversion stage fitted from the family's defaults
    return f"A fit from far away can cross folds of the branch: try {where}, or another --method"
