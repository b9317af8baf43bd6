"""What the data determine: profile-likelihood intervals of fitted parameters.

A fit's Gauss–Newton errors (:mod:`morphoshell.fitting.results`) are those of the linearised
problem at the optimum.  A *profile* (Venzon & Moolgavkar 1988; Raue et al. 2009) asks the
nonlinear question instead: step one parameter θⱼ over a grid around its fitted value, fit
all the others again at each step (warm-started from the neighbouring step's result; a refit
far above the profile, or failed, again from the optimum; one that decides a crossing
without having converged from other starts, :mod:`morphoshell.fitting.profile_retry`, which
also fits one above a refit farther out, and a crossing's, again from its neighbours' ends
and refines a crossing within a side's first steps), and record the least-squares objective
S(θⱼ) = E_fit²(θⱼ) (units of R²; the fit energy of the paper, Supplementary, "Fitting of the
morphoelastic theory to the average cell sheet midlines of Volvox inversion").  With
Gaussian residuals of variance σ² the likelihood-ratio statistic [S(θⱼ) − S_min]/σ² is
χ²₁-distributed at the true θⱼ, so the interval at confidence c is

    { θⱼ : S(θⱼ) − S_min ≤ σ² χ²₁(c) }          (χ²₁(0.95) = 3.841).

For a problem linear in θ it is the Gauss–Newton interval ±√χ²₁(c) SE; where the midline
depends nonlinearly on θⱼ (folds of the branch, curvatures near the pole) it is asymmetric,
and where the data do not determine θⱼ at all it does not close: the objective stays below
the threshold up to the grid's end or the parameter's bound, and that side is reported
unbounded (±inf; ``None`` in JSON) and the parameter *not determined by the data*
(:attr:`Profile.flat`).

σ², the noise variance of one coordinate of one point of the data, comes from
(:func:`noise_variance`)

``residual``  S_min/(2N − k) (N points, two coordinates, k fitted parameters):
              the Gauss–Newton errors' estimate.  It contains the model error
              (a model that does not fit the shape exactly leaves residuals that
              are not noise), which widens the intervals;
``traces``    when the data are an average of n traces with a per-point spread
              (:class:`morphoshell.io.Midline`, ``spread`` and ``n_traces``),
              mean(spread²)/n over the points off the pole: the noise of the
              average alone, free of model error.

``auto`` (the default) takes the traces when the data have them, else the residual, and
logs which (a warning for the residual: data that lost an average's spread on the way fall
back to it); each :class:`Profile` records it (``sigma2_source``, ``dof``).  The noise is
:mod:`morphoshell.fitting.profile_noise`'s.

The errors of a traced midline are correlated along it: each trace is aligned, scaled and
drawn as a whole, so most of its error moves many points at once.  The 2N residuals are then
far from 2N independent pieces of information.  With σ² from the traces, the threshold
counts what the spread of n traces does hold, n − 1 degrees of freedom (one per trace beyond
the mean), and takes the quantile of F(1, n − 1) (Student's t²ₙ₋₁, as the jackknife errors
do) instead of χ²₁: 7.71 instead of 3.84 for five traces (:func:`threshold_quantile`).  On
40 synthetic replicates of five traces it covers the generating κ₁ in 95 % and f₁ in 90 % of
them, where χ²₁ covered 90 % and 75 % (documentation: "Fitting", "Profile intervals").  σ²
from the residual keeps χ²₁ and covers far less (55 %, 50 %): the 13-parameter model absorbs
part of the correlated noise, so the residual underestimates it.

Lengths in units of R.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, replace
from typing import Mapping, Sequence

import numpy as np

from .._runtime.console import counter
from ..numerics.status import FIT_NOT_MINIMUM
from ..solvers.direct import solver_of
from ..solvers.results import Equilibrium, SolverError
from .bilevel import check_options, fit, fit_moving_boxes, method_run
from .inner import InnerProblem
from .midline_checks import as_points, check_midline
from .profile_noise import (NOISE_SOURCES, check_inflation, log_noise, noise_dof,
                            noise_variance, parameter_noise, threshold_quantile, traces_missing)
from .profile_retry import (Retry, crossings, needs_retry, not_monotone_note, retried,
                            settle_side, started_at)
from .profile_runs import each_profile
from .results import FitResult, fit_result
from .spec import FitSpec, check_spec

__all__ = ["Profile", "profile", "profile_intervals", "profiled_fit", "noise_variance",
           "traces_missing", "noise_dof", "threshold_quantile", "STOP_MARGIN", "JUMP_MARGIN",
           "PROFILE_METHODS", "NOISE_SOURCES", "SPAN_FACTOR", "EXTEND_STEPS", "LOWER",
           "MAX_RECENTRINGS"]

#: Methods of a profile's refits (Nelder–Mead is far too slow for 20 refits).
PROFILE_METHODS = ("gradient", "kkt")
#: The default grid reaches this many times the linear interval's half-width
#: (√(χ²₁ σ²/σ²_GN) Gauss–Newton errors) on either side: room for a profile twice as
#: wide as the linearisation says before the grid is extended.
SPAN_FACTOR = 2.0
#: A side whose objective is still below the threshold at the grid's end goes on by at most
#: this many steps, each twice the last (to 8 half-widths in all), before it is called open.
EXTEND_STEPS = 4
#: A side's walk ends at the first refit whose objective lies beyond S_min + STOP_MARGIN
#: (threshold − S_min): its interval ends before that refit, and the refits further out
#: cannot move it (:func:`~morphoshell.fitting.profile_retry.crossing` takes the first
#: crossing) while they are the slowest and fail most (far from the data; 8 of the 13 s of a
#: 20-point κ₁ profile of the synthetic t05).
#: The profile stays long enough to rethreshold with up to STOP_MARGIN times the σ².
STOP_MARGIN = 1.5
#: A refit whose objective lies beyond S_min + JUMP_MARGIN (threshold − S_min), or that
#: failed, is tried again from the optimum (:func:`_refit_checked`): one step of the grid
#: from below STOP_MARGIN does not get there on a smooth profile.  On the synthetic t05's
#: κ₁ and f₁ profiles (scripts/bench_profiles.py) the refits that the retry lowered lay at
#: 3.2–15 threshold heights (to 1.1–1.7), those it left alone at 1.6–2.1.
JUMP_MARGIN = 2.5
#: A refit whose objective lies below the fit's by more than this fraction of it found a lower
#: minimum: the fit had not reached its own.  The refits stop at a relative change of E_fit²
#: of ``tol`` (10⁻⁸) and a fit at 10⁻¹⁰, so two ends of one minimum agree to about 10⁻⁸; this
#: is a hundred times that, and still far below anything the intervals see (the threshold's
#: height is 2 % of S_min with σ² from the residual of 100 points).
LOWER = 1e-6
#: A profile whose refit lies lower than the optimum (by :data:`LOWER`) moves the optimum
#: there (a fit of all the parameters from that refit's end) and the profiles are computed
#: again about it, at most this many times; a profile still lower then keeps its note.
MAX_RECENTRINGS = 2


@dataclass(frozen=True, eq=False)
class Profile:
    """The profile of one fitted parameter: the objective with the others refitted.

    Attributes
    ----------
    name : str
        The profiled parameter.
    fitted_value : float
        Its value at the optimum (of the profile's own refit of the fit).
    values : ndarray, shape (m,)
        The grid, increasing, the fitted value included.
    objective : ndarray, shape (m,)
        S = E_fit² with the others refitted (units of R²); NaN where the
        refit failed.
    converged : ndarray of bool, shape (m,)
        Whether each refit converged (the fitted value's: the fit's).
    interval : (float, float)
        Where S − S_min ≤ σ² q (q: :func:`threshold_quantile`), interpolated between grid
        points; −inf / +inf on a side where the profile does not cross the
        threshold before the grid's end, the parameter's bound or a failed
        refit.
    threshold : float
        S_min + σ² q (units of R²).
    S_min : float
        The least objective of the profile (units of R²).
    sigma2 : float
        The noise variance per coordinate and point (units of R²).
    sigma2_source : str
        ``"residual"``, ``"traces"`` or ``"given"`` (:func:`noise_variance`).
    confidence : float
    flat : bool
        The profile stays below the threshold on a side up to the parameter's
        bound or the grid's end: the data do not determine the parameter (there).
    method : str
        The refits' method.
    dof : float
        The degrees of freedom of σ² (n − 1 for σ² from n traces; inf for
        the others, whose threshold takes χ²₁).
    note : str
        What else a reader should know (a refit that failed, a lower
        objective than the fit's).
    side_ends : (str, str)
        How the walk below and above the fitted value ended: ``"failed"`` (a
        refit failed: a side open there is open because the profile could not
        be computed beyond, e.g. at the model's |η| < 1 limit, not because
        the data do not determine it), ``"bound"`` (the parameter's bound) or
        ``"grid"`` (the grid's end, or the threshold crossed).
    retries : tuple of Retry
        The refits fitted again (:mod:`morphoshell.fitting.profile_retry`: which start won):
        from other starts where one beyond the threshold did not converge, from their
        neighbours' ends where one lay above a refit farther out or decided a crossing.
    """

    name: str
    fitted_value: float
    values: np.ndarray
    objective: np.ndarray
    converged: np.ndarray
    interval: tuple[float, float]
    threshold: float
    S_min: float
    sigma2: float
    sigma2_source: str
    confidence: float
    flat: bool
    method: str
    note: str = ""
    dof: float = math.inf
    side_ends: tuple[str, str] = ("grid", "grid")
    retries: tuple[Retry, ...] = ()

    def open_sides(self) -> tuple[str, str]:
        """Why each side of the interval is open (:attr:`side_ends`), "" where it closes."""
        return tuple("" if np.isfinite(v) else end
                     for v, end in zip(self.interval, self.side_ends))

    def uncertain_sides(self) -> tuple[bool, bool]:
        """Whether the refit where each side first exceeds the threshold did not converge:
        its objective bounds the profile's from above there, so the interval may reach
        further on that side (an audit's κ₁: [−0.01, 1.03] where a cold refit put the
        right end near 1.6)."""
        return tuple(v is not None for v in self._unconverged_crossings())

    def _unconverged_crossings(self) -> tuple[float | None, float | None]:
        """Below and above: the value of the refit where the side first exceeds the
        threshold, if it did not converge (:meth:`uncertain_sides`), else None."""
        j = int(np.searchsorted(self.values, self.fitted_value))
        out = []
        for side in (range(j - 1, -1, -1), range(j + 1, len(self.values))):
            above = [i for i in side if self.objective[i] > self.threshold]
            out.append(float(self.values[above[0]]) if above and not self.converged[above[0]]
                       else None)
        return tuple(out)

    def verdict(self) -> str:
        """What the interval's ends say: "not determined by the data" (:attr:`flat`),
        "open where a refit failed" (the note says why), "may reach further below/above"
        (:meth:`uncertain_sides`), or "" (closed by converged refits)."""
        sides = self.open_sides()
        if self.flat:
            return "not determined by the data" + (" within its bounds" if "bound" in sides
                                                   else "")
        words = ["open where a refit failed"] if "failed" in sides else []
        further = [(w, v) for w, v in zip(("below", "above"), self._unconverged_crossings())
                   if v is not None]
        if further:
            at = " and ".join(f"{v:.6g}" for _, v in further)
            words.append(f"may reach further {' and '.join(w for w, _ in further)} (the "
                         f"refit{'s' * (len(further) > 1)} beyond the threshold at {self.name} "
                         f"= {at} did not converge)")
        return "; ".join(words)

    @property
    def determined(self) -> bool:
        """Whether the data determine the parameter (the interval is closed)."""
        return not self.flat

    @property
    def below_fit(self) -> bool:
        """Whether a refit lies lower than the fit at :attr:`fitted_value` (by :data:`LOWER`):
        that fit is not the minimum (:attr:`note` says where)."""
        at = self.objective[int(np.searchsorted(self.values, self.fitted_value))]
        return bool(self.S_min < (1 - LOWER) * at)

    def summary(self) -> str:
        """One line: the parameter, its interval and whether the data determine it."""
        lo, hi = self.interval
        text = (f"  {self.name:8s} = {self.fitted_value: .6g}  "
                f"[{lo: .6g}, {hi: .6g}] ({100 * self.confidence:g} % profile)")
        if self.verdict():
            text += f": {self.verdict()}"
        return text + (f" ({self.note})" if self.note else "")

    def rethreshold(self, sigma2: float, source: str = "given",
                    dof: float = math.inf) -> "Profile":
        """This profile with the threshold of another σ² with ``dof`` degrees of freedom.

        The objective does not depend on σ²; the grid stays: an interval
        wider than it reaches its end and is open there.  Used to compare σ²
        sources on one profile (scripts/check_profile_coverage.py).
        """
        threshold = self.S_min + sigma2 * threshold_quantile(self.confidence, dof)
        interval = crossings(self.values, self.objective, self.fitted_value, threshold,
                             self.S_min)
        return replace(self, interval=interval, threshold=float(threshold), sigma2=float(sigma2),
                       sigma2_source=source, flat=is_flat(interval, self.side_ends), dof=dof)

    def to_dict(self) -> dict:
        """JSON-ready (an open side of the interval is ``None``: JSON has no infinity)."""
        def number(v):
            return float(v) if np.isfinite(v) else None
        return {"name": self.name, "fitted_value": self.fitted_value,
                "values": self.values.tolist(), "objective": [number(v) for v in self.objective],
                "converged": [bool(c) for c in self.converged],
                "interval": [number(v) for v in self.interval], "threshold": self.threshold,
                "S_min": self.S_min, "sigma2": self.sigma2, "sigma2_source": self.sigma2_source,
                "sigma2_dof": number(self.dof), "confidence": self.confidence, "flat": self.flat,
                "method": self.method, "open_sides": [end or None for end in self.open_sides()],
                "note": self.note, "retries": [r.to_dict() for r in self.retries],
                "objective_units": "R^2"}

    def to_dataframe(self):
        """The profile as a table: value, objective, converged (pandas)."""
        import pandas as pd
        return pd.DataFrame({"value": self.values, "objective": self.objective,
                             "converged": self.converged}).rename_axis(self.name)


@dataclass
class _Optimum:
    """The profile's own refit of the fit: spec (boxes around θ̂), θ̂, S_min, its state, and
    the fit the profiles are about (the given one, or the refit where it lies lower)."""

    spec: FitSpec
    theta: np.ndarray
    S: float
    eq: Equilibrium
    inner: InnerProblem
    fit: FitResult

    @property
    def errors(self) -> Mapping[str, float]:
        """The fit's Gauss–Newton standard errors (the grid's span)."""
        return self.fit.standard_errors

    @property
    def sigma2_gn(self) -> float:
        """The fit's Gauss–Newton σ², E_fit²/(2N − k)."""
        return float(self.fit.E_fit) ** 2 / max(len(self.fit.residuals) - len(self.theta), 1)


def _optimum(spec: FitSpec, data: np.ndarray, result: FitResult | None, method: str,
             nodes: int, tol: float) -> _Optimum:
    """The fit (``result``, or a new one) refitted on the profile's own inner problem.

    Refitting from the result (a few evaluations) makes θ̂ and S_min those of
    the mesh and tolerance every step of the profile uses, so that the profile's
    minimum sits at θ̂ whatever method or mesh gave the result.  Where the refit
    lies lower than the result (by :data:`LOWER`) the result had not reached its
    minimum, and the refit is the fit the profiles are about (:func:`_refitted`).
    """
    if result is None:
        result = fit(spec, data, method, nodes=nodes, tol=tol)
    theta = np.array([result.parameters[n] for n in spec.fitted], dtype=float)
    start = started_at(spec, theta)
    same = _nodes_of(result.equilibrium) == nodes      # (else a new mesh, continued to)
    inner = InnerProblem(start, data, nodes, result.equilibrium if same else None,
                         solver_of(result.equilibrium) if same else None)
    inner.warm = True
    # A refit stays on the branch of its neighbour: a trial point beyond a fold is
    # rejected, not snapped through (a failed snap costs far more than a rejected trial,
    # and a stalled refit eight of them: docs/benchmarks.md, "Profile intervals");
    # another branch is tried by the retry from the optimum (_refit_checked).
    inner.snap_trials = False
    return _refitted(inner, start, result, method, tol)


def _refitted(inner: InnerProblem, start: FitSpec, before: FitResult, method: str,
              tol: float) -> _Optimum:
    """Every fitted parameter refitted from ``start`` (the inner problem restarted there): the
    optimum, whose fit is ``before`` unless the refit lies lower (by :data:`LOWER`).

    A lower refit is a new :class:`FitResult` (its parameters, E_fit and Gauss–Newton
    errors), its message saying which fit it went on from.
    """
    t0 = time.perf_counter()
    end, theta, its, ok, msg, stop = fit_moving_boxes(method_run(method), start, inner, tol, None)
    eq = inner.solve(theta)
    res = inner.residuals(eq)
    S = float(res @ res)
    found = before
    if S < (1 - LOWER) * float(before.E_fit) ** 2:
        msg = (f"the profiles' {method} refit of a {before.method} fit that had not reached its "
               f"minimum (E_fit {before.E_fit:.6g} R, lowered to {np.sqrt(S):.6g} R): {msg}")
        found = fit_result(method, end, inner, theta, its,
                           before.seconds + time.perf_counter() - t0, ok, msg, stop)
    return _Optimum(end, theta, S, eq, inner, found)


def _nodes_of(eq: Equilibrium | None) -> int | None:
    """The mesh nodes of a direct solution (None for another route's, or for none: a fit
    read back from its JSON holds no equilibrium, and the profile's solves start afresh)."""
    return None if eq is None or eq.source is None else int(eq.source[1].nodes)


def _held(spec: FitSpec, name: str, theta: np.ndarray, value: float) -> FitSpec:
    """``spec`` with ``name`` held at ``value`` and the others starting at θ (full, spec's order).

    A generic spec's way of holding a parameter: out of ``fitted`` and its
    bounds, its value (and the others' starts) in ``base``.
    """
    full = np.array(theta, dtype=float)
    full[spec.fitted.index(name)] = value
    base = spec.problem(full)
    return replace(spec, base=base, fitted=tuple(n for n in spec.fitted if n != name),
                   bounds={n: b for n, b in spec.bounds.items() if n != name})


def _grid(opt: _Optimum, name: str, points: int, span, q: float,
          sigma2: float) -> tuple[list[float], list[float], float]:
    """The steps below and above the fitted value (each outward) and the grid's step."""
    j = opt.spec.fitted.index(name)
    value = float(opt.theta[j])
    lo, hi = opt.spec.bounds.get(name, (-np.inf, np.inf))
    if span is None:
        se = opt.errors.get(name, np.nan)
        if np.isfinite(se) and se > 0:
            # the linear interval's half-width, √(q σ²/σ²_GN) Gauss-Newton errors
            span = SPAN_FACTOR * se * np.sqrt(q * sigma2 / max(opt.sigma2_gn, 1e-300))
        else:              # no error (on a constraint): a tenth of the bounds' width
            width = hi - lo if np.isfinite(hi - lo) else max(abs(value), 1.0)
            span = 0.1 * width
    span = float(span)
    if not (np.isfinite(span) and span > 0):
        raise ValueError(f"span = {span!r} must be a positive number")
    half = max(points // 2, 1)
    step = span / half
    below = [max(value - i * step, lo) for i in range(1, half + 1)]
    above = [min(value + i * step, hi) for i in range(1, points - half + 1)]
    # (steps clipped onto a bound repeat it: walk to the bound once)
    return _unique(value, below), _unique(value, above), step


def _unique(start: float, values: list[float]) -> list[float]:
    """``values`` without repeats of their predecessor (or of ``start``, the first's)."""
    out: list[float] = []
    for v in values:
        if v != (out[-1] if out else start):
            out.append(v)
    return out


def _refit(opt: _Optimum, name: str, spec: FitSpec, theta: np.ndarray, eq: Equilibrium,
           value: float, method: str, tol: float) -> tuple:
    """One refit with ``name`` held at ``value``, the others from θ and the state ``eq``.

    Returns the next step's spec (this one's boxes, moved if the refit moved
    them, θⱼ fitted again), the full θ, the state, the objective and whether
    the refit converged.  Raises SolverError or ValueError when it fails.
    """
    j = opt.spec.fitted.index(name)
    held = _held(spec, name, theta, value)
    opt.inner.restart(held, eq)
    held, others, _, ok, _, _ = fit_moving_boxes(method_run(method), held, opt.inner, tol, None)
    eq = opt.inner.solve(others)
    res = opt.inner.residuals(eq)
    bounds = dict(held.bounds)
    if name in opt.spec.bounds:
        bounds[name] = opt.spec.bounds[name]
    return (replace(held, fitted=opt.spec.fitted, bounds=bounds), np.insert(others, j, value),
            eq, float(res @ res), bool(ok))


def _refit_checked(opt: _Optimum, name: str, walked: tuple, value: float, method: str,
                   tol: float, jump: float) -> tuple:
    """:func:`_refit` from the walk's last end ``walked`` (spec, θ, state), and again from the
    optimum where that one failed or lies above ``jump`` (:data:`JUMP_MARGIN`): the lower.

    The profile is a minimum over the other parameters, so every refit's objective bounds it
    from above and the lower one is the better estimate.  A refit continued from the last
    step can end on another local minimum, on the branch of the inner problem the walk
    followed up to its fold (the synthetic t05's κ₁ at 200 nodes: at κ₁ = 1.09, 13.8
    threshold heights above S_min, where the refit from the optimum gives 1.12): the side's
    crossing, decided at such a step, would depend on the walk's history.  Returns
    :func:`_refit`'s tuple and the first failure's message (empty when either refit worked).
    """
    out, failure = None, ""
    try:
        out = _refit(opt, name, *walked, value, method, tol)
    except (SolverError, ValueError) as exc:
        failure = str(exc)
    if out is None or out[3] > jump:
        try:
            again = _refit(opt, name, opt.spec, opt.theta, opt.eq, value, method, tol)
        except (SolverError, ValueError) as exc:
            again, failure = None, failure or str(exc)
        if again is not None and (out is None or again[3] < out[3]):
            out = again
    return out, ("" if out is not None else failure)


def _refit_retried(opt: _Optimum, name: str, walked: tuple, value: float, method: str,
                   tol: float, margins: tuple[float, float], retries: list | None, bar,
                   before: list = ()) -> tuple:
    """:func:`_refit_checked` (``margins``: its jump and the threshold), and a refit that
    decides the crossing without having converged (``before``: the side's objectives so
    far; :func:`~morphoshell.fitting.profile_retry.needs_retry`) fitted again from other
    starts (:func:`~morphoshell.fitting.profile_retry.retried`), recorded in ``retries``
    (None: no retry); one count on the progress bar ``bar``."""
    jump, threshold = margins
    out, failure = _refit_checked(opt, name, walked, value, method, tol, jump)
    bar.update()
    if retries is not None and needs_retry(out, threshold, before):
        out, retry = retried(opt.spec, name, value, out, threshold, opt.inner.data,
                             opt.inner.nodes, tol)
        retries.extend([retry] if retry is not None else [])
    return out, failure


def _walk(opt: _Optimum, name: str, steps: list[float], direction: float, step: float,
          threshold: float, method: str, tol: float, bar, retries: list
          ) -> tuple[list, list, list, str, tuple]:
    """Refit at each of ``steps`` outward from θ̂, each from the last one's end
    (:func:`_refit_retried`).

    Goes on beyond the planned steps (each twice the last, at most
    :data:`EXTEND_STEPS`) while the objective stays below ``threshold`` and
    the bound is not reached; stops at a refit that fails (its objective
    NaN) or lies beyond :data:`STOP_MARGIN` times the threshold's height; then refits
    from neighbours' ends where the side is not monotone and at its crossing, and refines
    a crossing within the first two steps
    (:func:`~morphoshell.fitting.profile_retry.settle_side`).  Each refit counts one on
    the progress bar ``bar``; the retries are added to ``retries``.
    Returns values, objectives, converged flags, a note and the lowest refit
    (objective, spec, θ, state; None without one), where a lower optimum may lie.
    """
    lo, hi = opt.spec.bounds.get(name, (-np.inf, np.inf))
    walked = (opt.spec, opt.theta.copy(), opt.eq)
    values, objective, converged, ends, note = [], [], [], [], ""
    plan, extra = list(steps), 0
    beyond, jump = (opt.S + margin * (threshold - opt.S) for margin in (STOP_MARGIN, JUMP_MARGIN))

    def refit(end, value, retry=None):
        return _refit_retried(opt, name, end, value, method, tol, (jump, threshold), retry,
                              bar, objective)
    while plan and not (objective and objective[-1] > beyond):
        value = plan.pop(0)
        out, failure = refit(walked, value, retries)
        values.append(value)
        if out is None:
            # (the next step would start from a state no refit reached: stop here)
            objective.append(np.nan)
            converged.append(False)
            ends.append(None)
            note = f"the refit at {name} = {value:.6g} failed: {failure}"
            break
        walked = out[:3]
        ends.append(walked)
        objective.append(out[3])
        converged.append(out[4])
        bound = lo if direction < 0 else hi
        if not plan and objective[-1] < threshold and value != bound and extra < EXTEND_STEPS:
            extra += 1
            nxt = value + direction * step * 2 ** extra
            plan.append(max(nxt, lo) if direction < 0 else min(nxt, hi))
    retries.extend(settle_side((values, objective, converged, ends),
                               (float(opt.theta[opt.spec.fitted.index(name)]), opt.S,
                                (opt.spec, opt.theta.copy(), opt.eq)),
                               threshold, refit, name))
    lowest = min(((S, *end) for S, end in zip(objective, ends) if end is not None),
                 key=lambda low: low[0], default=None)
    return values, objective, converged, note, lowest


def _profile(opt: _Optimum, data, name: str, points: int, span, method: str, tol: float,
             confidence: float, noise, bar, inflation=None) -> tuple[Profile, tuple | None]:
    """The profile of ``name`` about the optimum ``opt`` (see :func:`profile`), and its
    lowest refit (:func:`_walk`; its refits counted on the progress bar ``bar``)."""
    bar.set_description(f"profile of {name}")
    sigma2, source, dof = parameter_noise(data, opt.S, len(opt.theta), noise, inflation, name)
    q = threshold_quantile(confidence, dof)
    below, above, step = _grid(opt, name, points, span, q, sigma2)
    threshold = opt.S + sigma2 * q
    j = opt.spec.fitted.index(name)
    value = float(opt.theta[j])
    retries: list[Retry] = []
    vb, sb, cb, note_b, low_b = _walk(opt, name, below, -1.0, step, threshold, method, tol, bar,
                                      retries)
    va, sa, ca, note_a, low_a = _walk(opt, name, above, 1.0, step, threshold, method, tol, bar,
                                      retries)
    values = np.array([*vb[::-1], value, *va])
    objective = np.array([*sb[::-1], opt.S, *sa])
    # (an unconverged crossing is the verdict's: Profile.uncertain_sides)
    notes = [n for n in (note_b, note_a, *(r.note(name) for r in retries), *(
        not_monotone_note(name, (v, s), threshold, opt.S, w)
        for v, s, w in ((vb, sb, "below"), (va, sa, "above")))) if n]
    S_min = float(np.nanmin(objective))
    if S_min < opt.S * (1 - LOWER):
        # (the fit was not at the minimum: the threshold from the profile's own)
        where = float(values[int(np.nanargmin(objective))])
        notes.append(f"a refit at {name} = {where:.6g} found a lower objective (E_fit "
                     f"{np.sqrt(S_min):.6g} R) than the fit's ({np.sqrt(opt.S):.6g} R): the fit "
                     f"is not the minimum")
        threshold = S_min + sigma2 * q
    interval = crossings(values, objective, value, threshold, S_min)
    lowest = min((low for low in (low_b, low_a) if low is not None), key=lambda low: low[0],
                 default=None)
    ends = tuple(_side_end(opt, name, v, note, d)
                 for v, note, d in ((vb, note_b, -1.0), (va, note_a, 1.0)))
    return Profile(name, value, values, objective, np.array([*cb[::-1], True, *ca]),
                   interval, float(threshold), S_min, sigma2, source, confidence,
                   is_flat(interval, ends), method, "; ".join(notes), dof, ends,
                   tuple(retries)), lowest


def _side_end(opt: _Optimum, name: str, values: list, failure: str, direction: float) -> str:
    """How a side's walk (:func:`_walk`) ended: "failed", "bound" or "grid"."""
    lo, hi = opt.spec.bounds.get(name, (-np.inf, np.inf))
    if failure:
        return "failed"
    return "bound" if values and values[-1] == (lo if direction < 0 else hi) else "grid"


def is_flat(interval: tuple[float, float], ends: tuple[str, str]) -> bool:
    """Whether a side is open where the profile ran to a bound or the grid's end below the
    threshold: the data do not determine the parameter (a side open at a failed refit
    says nothing either way, :meth:`Profile.verdict`)."""
    return any(not np.isfinite(v) and end != "failed" for v, end in zip(interval, ends))


def _check(spec: FitSpec, names: Sequence[str], points: int, method: str,
           confidence: float, nodes: int, tol: float) -> None:
    """ValueError naming the first bad option of a profile, before any work."""
    if method not in PROFILE_METHODS:
        raise ValueError(f"method = {method!r} must be one of {list(PROFILE_METHODS)}")
    not_fitted = [n for n in names if n not in spec.fitted]
    if not_fitted:
        raise ValueError(f"cannot profile {not_fitted}: not fitted in the {spec.variant} "
                         f"variant (fitted: {list(spec.fitted)})")
    if not names:
        raise ValueError("no parameter to profile")
    if not (isinstance(points, (int, np.integer)) and not isinstance(points, bool)
            and 2 <= points <= 1000):
        raise ValueError(f"points = {points!r} must be an integer from 2 to 1000")
    if not (isinstance(confidence, float) and 0 < confidence < 1):
        raise ValueError(f"confidence = {confidence!r} must lie in (0, 1)")
    check_options(nodes, tol, None)


def profiled_fit(spec: FitSpec, data, names: Sequence[str] | None = None, *,
                 result: FitResult | None = None, points: int = 20, span=None,
                 method: str = "gradient", nodes: int | None = None,
                 confidence: float = 0.95, noise: str | float = "auto",
                 tol: float = 1e-8, inflation: Mapping[str, float] | None = None
                 ) -> tuple[FitResult, dict[str, Profile]]:
    """Profiles of several fitted parameters, and the fit they are about.

    The fit is refitted once on the profiles' inner problem (by ``method``, from
    its end); each profile starts from there.  Where that refit lies lower than
    ``result`` (by :data:`LOWER`), ``result`` had not reached its minimum: the
    refit is the fit, a new :class:`FitResult` whose message says so.  Where a
    profile's refit lies lower than the fit, all the parameters are fitted again
    from there and the profiles computed again about that fit (at most
    :data:`MAX_RECENTRINGS` times; a profile lower still keeps a note and
    :attr:`Profile.below_fit`).  So the profiles' minimum is the returned fit's
    parameters and E_fit, and the intervals are about it.

    Parameters
    ----------
    spec, data, names, result, points, span, method, nodes, confidence, noise, tol
        As :func:`profile_intervals`.
    inflation : mapping, optional
        Name → factor on the residual's σ² (a single trace's, :func:`parameter_noise`).

    Returns
    -------
    fit : FitResult
        ``result`` (or, without one, the fit by ``method``), or the lower refit
        the profiles found: ``fit is result`` tells which.
    profiles : dict
        :class:`Profile` by name, in the order of ``names``.

    Raises
    ------
    ProfilesInterrupted
        Ctrl-C or SIGTERM in the profiles: the fit and those finished (its attributes).
    """
    names = list(check_spec(spec).fitted if names is None else names)
    if nodes is None:
        nodes = (_nodes_of(result.equilibrium) if result is not None else None) or 200
    _check(spec, names, points, method, confidence, nodes, tol)
    if result is not None and tuple(result.fitted) != tuple(spec.fitted):
        raise ValueError(f"the result fitted {list(result.fitted)}, the spec "
                         f"{list(spec.fitted)}: not a fit of this spec")
    noise_variance(data, 1.0, len(spec.fitted), noise)      # (checks it before any work)
    check_inflation(inflation, names)
    log_noise(data, noise)
    points_ = as_points(data)
    check_midline(spec, points_)
    spans = span if isinstance(span, Mapping) else {n: span for n in names}
    # (a bar of the planned refits, on a terminal: a profile of all 13 parameters takes
    # minutes, and its refits are many small gradient fits that show nothing)
    with counter(len(names) * points, desc="profiles: the fit refitted", unit="refit") as bar:
        opt = _optimum(spec, points_, result, method, nodes, tol)
        return _about_minimum(opt, method, tol, bar, lambda opt: each_profile(names, opt.fit, (
            lambda n: _profile(opt, data, n, points, spans.get(n), method, tol, confidence,
                               noise, bar, inflation))))


def _about_minimum(opt: _Optimum, method: str, tol: float, bar, run) -> tuple:
    """``run(opt)``'s profiles (each with its lowest refit), again about the fit from the
    lowest refit while one lies lower than the optimum (at most :data:`MAX_RECENTRINGS`
    times; the progress bar ``bar`` plans their refits again): the fit and the profiles
    of :func:`profiled_fit`."""
    planned = bar.total
    for recentrings in range(MAX_RECENTRINGS + 1):
        if recentrings:
            bar.total += planned
            bar.refresh()
        out = run(opt)
        profiles = {n: p for n, (p, _) in out.items()}
        lowest = min((low for _, low in out.values() if low is not None),
                     key=lambda low: low[0], default=None)
        if lowest is None or lowest[0] >= (1 - LOWER) * opt.S:
            return opt.fit, profiles
        if recentrings == MAX_RECENTRINGS:
            return _not_minimum(opt.fit, lowest[0], profiles), profiles
        # a lower minimum than the fit's: fit everything again from there, and profile
        # about that fit (the intervals of a profile about a point that is not its
        # minimum are neither the fit's nor the minimum's)
        _, lower, theta, eq = lowest
        start = started_at(lower, theta)
        opt.inner.restart(start, eq)
        opt = _refitted(opt.inner, start, opt.fit, method, tol)


def _not_minimum(found: FitResult, S: float, profiles: dict[str, Profile]) -> FitResult:
    """``found``, not converged: a profile's refit lies at ``S``, lower still after
    :data:`MAX_RECENTRINGS` fits from the lowest refits."""
    where = ", ".join(n for n, p in profiles.items() if p.below_fit)
    return replace(found, converged=False, stop=FIT_NOT_MINIMUM, message=(
        f"{found.message}; but the profile of {where} found a lower objective (E_fit "
        f"{np.sqrt(S):.6g} R) than the fit's: it is not the minimum (refitted from the "
        f"lowest refit at most MAX_RECENTRINGS = {MAX_RECENTRINGS} times)").lstrip("; "))


def profile_intervals(spec: FitSpec, data, names: Sequence[str] | None = None, *,
                      result: FitResult | None = None, points: int = 20, span=None,
                      method: str = "gradient", nodes: int | None = None,
                      confidence: float = 0.95, noise: str | float = "auto",
                      tol: float = 1e-8) -> dict[str, Profile]:
    """Profiles of several fitted parameters about one fit (see :func:`profile`).

    The fit is refitted once on the profiles' inner problem; each profile
    starts from there.  Where a refit lies lower than ``result``, the profiles
    are about the lower fit (:func:`profiled_fit`, which returns it too).

    Parameters
    ----------
    spec : FitSpec
        What was fitted.
    data : array_like (N, 2) or Midline
        The fitted midline.
    names : sequence of str, optional
        Fitted parameters (default: all of ``spec.fitted``).
    result, points, span, method, nodes, confidence, noise, tol
        As :func:`profile` (``span``: one value for all, or a mapping by name).

    Returns
    -------
    dict
        :class:`Profile` by name, in the order of ``names``.
    """
    return profiled_fit(spec, data, names, result=result, points=points, span=span,
                        method=method, nodes=nodes, confidence=confidence, noise=noise,
                        tol=tol)[1]


def profile(spec: FitSpec, data, name: str, *, result: FitResult | None = None,
            points: int = 20, span: float | None = None, method: str = "gradient",
            nodes: int | None = None, confidence: float = 0.95, noise: str | float = "auto",
            tol: float = 1e-8) -> Profile:
    """The profile of one fitted parameter and its interval (module docstring).

    θⱼ steps over ``points`` values around its fitted value, half on either
    side, each outward from the last; at each the other parameters are fitted
    again (``method``), starting from the neighbouring step's parameters and
    equilibrium (one branch of equilibria), with θⱼ held: ``spec`` with θⱼ
    moved from ``fitted`` into ``base``.  Where the objective is still below
    the threshold at the grid's end the side goes on by steps twice as long
    (at most :data:`EXTEND_STEPS`); a side that reaches θⱼ's bound, a failed
    refit or the last step below the threshold is open.

    Parameters
    ----------
    spec : FitSpec
        What was fitted (:func:`morphoshell.fitting.spec.volvox_spec`).
    data : array_like (N, 2) or Midline
        The fitted midline (a Midline averaged from traces carries the
        spread that ``noise="traces"`` uses).
    name : str
        A parameter of ``spec.fitted``.
    result : FitResult, optional
        The fit of ``spec`` to ``data`` (default: fitted here, by ``method``).
    points : int
        Refits on the grid (2 to 1000; 20 by default).
    span : float, optional
        The grid's half-width (units of θⱼ); default :data:`SPAN_FACTOR` times
        the linear interval's half-width from the Gauss–Newton error, or a
        tenth of θⱼ's bounds for a parameter on a constraint.  Clipped to the
        bounds.
    method : {"gradient", "kkt"}
        The refits' method.
    nodes : int, optional
        Mesh nodes (default: the result's, else 200).
    confidence : float
        Of the interval (the threshold's quantile: :func:`threshold_quantile`).
    noise : {"auto", "residual", "traces"} or float
        Where σ² comes from (:func:`noise_variance`), or σ² itself.
    tol : float
        The refits' tolerance (relative on E_fit²).

    Returns
    -------
    Profile

    Raises
    ------
    ValueError
        A name not fitted by ``spec``, another bad option, or data that
        :func:`morphoshell.fitting.midline_checks.check_midline` refuses,
        before any work.
    """
    return profile_intervals(spec, data, [name], result=result, points=points, span=span,
                             method=method, nodes=nodes, confidence=confidence, noise=noise,
                             tol=tol)[name]

