"""A fit from several starts: the lowest of the local minima a variant's fit reaches.

E_fit of a Volvox variant has several local minima: a fit ends in the one its
start leads to.  A single fit of the ``unstressed`` variant of a traced
sine-perturbed sphere ended at E_fit 0.041 R from the family's defaults, 0.060
from the free fit's end and 0.021 from the flat fit's, each converged, with
κ₄ on its bound and breakpoints on their constraints in the worse two; ranking
hypotheses by such an E_fit ranks the starts.  :func:`multi_start_fit` fits
from the user's start, the family's defaults and a small deterministic
multi-start (:data:`MULTI_STARTS`), all with the fit's held values, h, opening
and σ, and keeps the lowest.  A campaign's fits start from the same candidates
(:mod:`morphoshell.workflows.start_candidates`), and both continue a fit that
stops unconverged once from its end (:func:`continue_once`).
"""
from __future__ import annotations

import time
from dataclasses import dataclass, replace
from typing import Mapping

from ..model.problem import Problem
from ..solvers.results import SolverError
from .bilevel import METHODS, check_options, fit
from .midline_checks import as_points, check_midline
from .results import FitError, FitResult
from .spec import BOUNDS, VARIANTS, VOLVOX_BREAKPOINTS, FitSpec, check_spec, volvox_spec

__all__ = ["MULTI_STARTS", "FOLD_GAIN", "SAME_MINIMUM", "MultiStartFit", "multi_start_fit",
           "start_specs", "other_starts", "start_from", "continue_once",
           "local_minimum_signs"]

#: The deterministic multi-start: the family's defaults (with the held values) changed so.
#: The bend region's curvature κ₂ and the breakpoints of the model's later stages (the
#: synthetic sequence's mid-inversion keyframe), where chains from early fits stall; the
#: latter with κ₂ = −6, not the defaults' −9, whose |η| reaches 1 when f₁ is held below
#: about 0.8 (the fixed variants after the first timepoint), so that start was left out
#: just where it was needed (the synthetic campaign's unstressed t10-t12).
MULTI_STARTS = ({"kappa2": -3.0}, {"kappa2": -6.0},
                {"kappa2": -6.0, "s1": 0.75, "s2": 1.38, "s3": 1.78, "s4": 2.35})
#: A continuation that ends near a fold replaces the fit it continued only if it lowers E_fit
#: by more than this fraction (:func:`continue_once`).
FOLD_GAIN = 0.1
#: A later start's fit replaces the lowest so far only if its E_fit is lower by more than this
#: fraction: fits from several starts that end in the same minimum differ in E_fit by about the
#: fit's tolerance (1e-10 relative on E_fit²; on the audit's sine data the flat fits from the
#: defaults and from kappa2 = -6 agree to 6 digits), distinct minima by percents (0.041 and
#: 0.018 R), so the earlier start names a shared minimum.
SAME_MINIMUM = 1e-6
#: A fitted value this close to a bound (a fraction of its width) is moved inside it before
#: it starts another fit (:func:`start_from`).
_MARGIN = 1e-6
#: What a start's fit that fails with one of these leaves in the table (the others go on).
_FAILURES = (FitError, SolverError, ValueError)


def start_specs(variant: str, hold: Mapping[str, float], start: Problem | None,
                origin: str) -> list[tuple[str, FitSpec]]:
    """``start`` (the family's defaults if None) and :data:`MULTI_STARTS` from it, each
    with the held values: (label, spec) in that order.

    ``origin`` labels ``start``; the others read e.g. ``"multi-start kappa2 = -3"``.  A
    start that the variant's bounds or the held values do not admit is left out.
    """
    base = start or Problem("volvox", h=0.15, opening=0.3)
    changes = [(origin, {}), *((f"multi-start {', '.join(f'{k} = {v:g}' for k, v in c.items())}",
                                c) for c in MULTI_STARTS)]
    out = []
    for label, change in changes:
        try:
            problem = base.with_updates(**change) if change else start
            out.append((label, volvox_spec(variant, start=problem, hold=hold)))
        except ValueError:
            continue
    return out


def start_from(params: Mapping[str, float]) -> Problem:
    """A start problem from fitted parameters (h, opening too), moved just inside the
    fit's :data:`~morphoshell.fitting.spec.BOUNDS` (a start on a bound can stay there)."""
    p = dict(params)
    h, opening = p.pop("h", 0.15), p.pop("opening", 0.3)
    p.pop("cut", None)
    for n, v in p.items():
        kind = "f" if n.startswith("f") else "kappa" if n.startswith("kappa") else None
        if kind is not None:
            lo, hi = BOUNDS[kind]
            span = (hi - lo) * _MARGIN
            p[n] = float(min(max(v, lo + span), hi - span))
    return Problem("volvox", p, h=h, opening=opening)


def continue_once(first: FitResult, again: FitSpec, data, method: str, nodes: int,
                  max_iterations: int | None = None) -> tuple[FitResult, bool]:
    """``first``, a fit that stopped unconverged, fitted once more from its end (``again``:
    the spec started there), and whether the continuation was kept.

    A least-squares fit that runs out of evaluations in a long, flat valley, or
    stalls where trial points fail, often converges when started again from
    where it stopped, with a fresh trust region.  A continuation that fails is
    dropped and ``first`` kept, saying so; so is one that creeps onto a fold of
    the branch for a small gain (by less than :data:`FOLD_GAIN` of E_fit): where
    the first fit stopped, the shape is stable and its errors mean something.
    One that fits far better is kept even at a fold.  The result counts the
    iterations, solves and seconds of both fits.
    """
    try:
        r = fit(again, data, method, nodes=nodes, start=first.equilibrium,
                max_iterations=max_iterations)
    except _FAILURES as exc:
        return replace(first, message=f"{first.message}; continuing it failed: "
                                      f"{type(exc).__name__}: {exc}"), False
    if r.near_fold and r.E_fit > (1 - FOLD_GAIN) * first.E_fit:
        return replace(first, message=f"{first.message}; continuing it crept onto a fold of "
                                      f"the branch (E_fit {r.E_fit:.6g} R), so it is kept "
                                      f"where it stopped"), False
    return replace(r, outer_iterations=first.outer_iterations + r.outer_iterations,
                   inner_solves=first.inner_solves + r.inner_solves,
                   seconds=first.seconds + r.seconds,
                   message=f"continued once after: {first.message}; then: {r.message}"), True


@dataclass(frozen=True)
class MultiStartFit:
    """The lowest of a variant's fits from several starts, and the table of all.

    Attributes
    ----------
    result : FitResult
        The fit with the lowest E_fit (the first of those within
        :data:`SAME_MINIMUM` of each other).
    winner : str
        Its start's label (a row's ``"from"``).
    starts : tuple of dict
        One row per start, in the order fitted: ``{"from", "E_fit" (R),
        "converged", "constrained" (list of str), "continued" (bool)}``, or
        ``{"from", "E_fit": None, "failed": message}`` for a fit that failed.
    seconds : float
        Wall-clock time of all the starts' fits (``result.seconds`` is the winner's).
    """

    result: FitResult
    winner: str
    starts: tuple[dict, ...]
    seconds: float = 0.0

    def table(self) -> str:
        """The starts as text lines, the winner marked with ``*``."""
        lines, width = [], max(len(row["from"]) for row in self.starts)
        for row in self.starts:
            mark = "*" if row["from"] == self.winner else " "
            if row["E_fit"] is None:
                lines.append(f" {mark} {row['from']:<{width}s} failed: {row['failed']}")
                continue
            state = "converged" if row["converged"] else "not converged"
            state += ", continued once" if row["continued"] else ""
            ends = "; on " + ", ".join(row["constrained"]) if row["constrained"] else ""
            lines.append(f" {mark} {row['from']:<{width}s} E_fit {row['E_fit']:.6g} R ({state})"
                         f"{ends}")
        return "\n".join(lines)

    def to_dict(self) -> dict:
        """JSON-ready: the winner's start and the table (``started_from``, ``starts``)."""
        return {"started_from": self.winner, "starts": [dict(row) for row in self.starts]}


def multi_start_fit(spec: FitSpec, data, method: str = "gradient", *, nodes: int = 200,
                    max_iterations: int | None = None) -> MultiStartFit:
    """Fit a Volvox variant from several starts and keep the lowest E_fit.

    The starts, in order: ``spec``'s own (``"start"``, unless it is the family's
    defaults), the family's defaults (``"family defaults"``) and
    :data:`MULTI_STARTS` from them, each with ``spec``'s variant, held values, h,
    opening and σ; a start its bounds do not admit is left out.  Each is fitted by
    :func:`~morphoshell.fitting.bilevel.fit` and, if it stops unconverged (not near
    a fold), continued once from its end (:func:`continue_once`).  Deterministic; of
    fits within :data:`SAME_MINIMUM` of the lowest E_fit the first wins.

    Parameters
    ----------
    spec : FitSpec
        A Volvox variant's fit (:func:`~morphoshell.fitting.spec.volvox_spec`).
    data, method, nodes, max_iterations
        As for :func:`~morphoshell.fitting.bilevel.fit` (the limit for each run).

    Returns
    -------
    MultiStartFit

    Raises
    ------
    ValueError
        ``spec`` is not one of the Volvox variants (:data:`VARIANTS`), or the
        options or data are refused (before any work).
    SolverError
        Every start's fit failed (the last one's error).
    """
    if check_spec(spec).variant not in VARIANTS or spec.base.family != "volvox":
        raise ValueError(f"multi_start_fit needs a Volvox variant's spec (volvox_spec), "
                         f"got variant {spec.variant!r}")
    if method not in METHODS:
        raise ValueError(f"method = {method!r} must be one of {list(METHODS)}")
    check_options(nodes, 1e-10, max_iterations)
    data = as_points(data)
    check_midline(spec, data)     # (refused before any work, not as every start's failure)
    best, winner, rows, error, t0 = None, "", [], None, time.perf_counter()
    for label, s in _starts(spec):
        try:
            r, continued = _fit_continued(s, data, method, nodes, max_iterations)
        except _FAILURES as exc:
            rows.append({"from": label, "E_fit": None, "failed": f"{type(exc).__name__}: {exc}"})
            error = exc
            continue
        rows.append({"from": label, "E_fit": r.E_fit, "converged": r.converged,
                     "constrained": list(r.constrained), "continued": continued})
        if best is None or r.E_fit < (1 - SAME_MINIMUM) * best.E_fit:
            best, winner = r, label
    if best is None:
        raise error
    return MultiStartFit(best, winner, tuple(rows), time.perf_counter() - t0)


def other_starts(spec: FitSpec, also_hold: Mapping[str, float] = ()
                 ) -> list[tuple[str, FitSpec]]:
    """(label, spec) of the starts other than ``spec``'s own: the family's defaults
    (``"family defaults"``) and :data:`MULTI_STARTS` from them, each with ``spec``'s variant,
    held values and ``also_hold``, h, opening and σ (:func:`start_specs`; a profile's refit
    holds one more parameter: :mod:`morphoshell.fitting.profile_retry`)."""
    base = spec.base
    defaults = Problem("volvox", {"sigma": base.params["sigma"]}, h=base.h,
                       opening=base.opening)
    return start_specs(spec.variant, {**_held(spec), **dict(also_hold)}, defaults,
                       "family defaults")


def _starts(spec: FitSpec) -> list[tuple[str, FitSpec]]:
    """(label, spec) of :func:`multi_start_fit`'s starts: ``spec``, then the defaults' and
    the multi-start's with its held values, h, opening and σ (``spec`` is not fitted twice)."""
    others = other_starts(spec)
    if others and others[0][0] == "family defaults" and _same(others[0][1], spec):
        return others
    return [("start", spec), *others]


def _held(spec: FitSpec) -> dict:
    """The values ``spec`` holds (neither fitted, nor tied, nor σ, which is never fitted)."""
    return {n: v for n, v in spec.base.params.items()
            if n not in spec.fitted and n not in spec.tied and n != "sigma"}


def _same(a: FitSpec, b: FitSpec) -> bool:
    """Whether two specs start at the same values with the same bounds."""
    return a.base.params == b.base.params and dict(a.bounds) == dict(b.bounds)


def _fit_continued(spec: FitSpec, data, method: str, nodes: int,
                   max_iterations: int | None) -> tuple[FitResult, bool]:
    """A start's fit, continued once from its end if it stopped unconverged (not at a fold)."""
    first = fit(spec, data, method, nodes=nodes, max_iterations=max_iterations)
    if first.converged or first.near_fold:
        return first, False
    again = volvox_spec(spec.variant, start=start_from(first.parameters), hold=_held(spec))
    return continue_once(first, again, data, method, nodes, max_iterations)


def local_minimum_signs(result: FitResult) -> tuple[list[str], list[str]]:
    """(fitted stretches and curvatures on a bound, breakpoints on a constraint) of a fit:
    both non-empty in a fixed variant's fit (not ``free``) is the sign of the poor local
    minima that a start leads to (module docstring), ([], []) otherwise."""
    if result.variant not in VARIANTS or result.variant == "free":
        return [], []
    pinned = result.pinned
    bounds = [n for n in pinned if n not in VOLVOX_BREAKPOINTS]
    breakpoints = [n for n in pinned if n in VOLVOX_BREAKPOINTS]
    return (bounds, breakpoints) if bounds and breakpoints else ([], [])
