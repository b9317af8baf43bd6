"""Which hypotheses on κ₁ the data tell apart: each tested against the free fit.

``flat``, ``undeformed`` and ``unstressed`` (:mod:`morphoshell.fitting.spec`) each tie
κ₁ (to 0, 1 and 1/f₁) and are otherwise the ``free`` model: each is ``free`` under d
restrictions (d = 1 for fits of one midline; d = 4 at a campaign's later timepoints, where
the three also hold f₁, κ₃ and κ₄).  Their E_fit can only lie above the free fit's, and
how far above is noise unless it exceeds what the noise makes.  With S = E_fit² (units of
R²: the sum of squares over the N points, the objective of the profiles; no factor N) and
Gaussian noise of variance σ² per coordinate of a point, the likelihood-ratio statistic of
a true hypothesis

    ΔS/σ² = (E_V² − E_free²)/σ²

is χ²_d-distributed, or d·F(d, n − 1) with σ² from the spread of n traces: the profiles'
threshold (:func:`~morphoshell.fitting.profile_noise.threshold_quantile`), σ² chosen as
they choose it (:func:`~morphoshell.fitting.profile_noise.noise_variance`: the traces
when the data carry their spread, else the free fit's residual, whose σ² underestimates
a traced midline's noise, so that hypotheses are rejected too readily).  A hypothesis whose
ΔS/σ² exceeds its threshold is *rejected*, else *consistent* with the data; the E_fit
ranking of consistent hypotheses is noise.

On one image trace whose free fit carries its re-tracings' errors
(:mod:`morphoshell.fitting.trace_errors`: ``morphoshell fit --pixel-size``), the residual's
σ² is scaled as κ₁'s profile scales it
(:func:`~morphoshell.fitting.profile_noise.parameter_noise`): times κ₁'s (SE of the
re-tracings / Gauss–Newton SE)².  The residuals of such a trace are correlated along the
midline, so a true hypothesis's ΔS/σ²_residual is c·χ²₁, c the ratio of the restricted
direction's sandwich and Gauss–Newton variances; for ``flat`` and ``undeformed`` (κ₁ held)
it is κ₁'s factor exactly, for ``unstressed`` (κ₁ − 1/f₁ held) κ₁'s up to f₁'s part of
that direction, which the records do not keep (its Gauss–Newton covariance is not
written).  On the docs' embryo 1 (made with κ₁ = 0) the unscaled test rejected ``flat`` at
ΔS/σ² = 32.8 (χ²₁: 3.84); docs/benchmarks.md gives the rates of false rejections before and
after on the shipped traces.  With d > 1 restrictions (a campaign's later timepoints) ΔS/σ²
is a sum of d such terms whose weights need the restricted parameters' covariances under
both errors: no single factor calibrates it, and σ² stays the residual's (the summary's
caveat says a rejection may be the trace's correlated noise).

It is the κ₁ profile interval's question (:mod:`morphoshell.fitting.profiles`) at single
values: the profile's refit at κ₁ = 0 is the ``flat`` fit, so ``flat`` is consistent
exactly when 0 lies within the profile interval (both at their minima); ``unstressed``
ties κ₁ to 1/f₁, a restriction the profile does not step along.

A verdict needs the E_fit of both fits at their minima.  An E_fit that did not converge
only bounds its minimum from above (as a profile's refit that stops short): a hypothesis
whose own fit stopped has a ΔS that is an upper bound, so it may be called *consistent*
(its minimum lies lower still) but not *rejected*; a free fit that stopped has a ΔS that
is a lower bound on every hypothesis's (and with σ² from its residual a σ² that is an
upper bound), so a hypothesis may be *rejected* but not called *consistent*, nor rejected
where σ² is the residual's scaled by the stopped fit's own re-tracings.  The verdict that
the stop leaves open is *not established* (:data:`NOT_ESTABLISHED`), and the summary names
the fit and how it stopped (audit 28 F1: an undeformed fit stopped after 3 evaluations at
E_fit 0.082 R, against 0.0051 R converged, was "rejected" at ΔS/σ² = 9.8·10³).

Without a free fit nothing nests the hypotheses: each is compared with the best (lowest
E_fit) by ΔS/σ², without a threshold (no χ² law holds between non-nested fits).

Lengths in units of R.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from ..numerics.status import FIT_CONVERGED
from .midline_checks import as_points
from .profile_noise import RETRACED, parameter_noise, threshold_quantile
from .results import FitResult
from .trace_errors import fit_inflation

__all__ = ["Hypothesis", "HypothesisTest", "compare_hypotheses", "REFERENCE",
           "CONSISTENT", "REJECTED", "NOT_ESTABLISHED", "TESTED"]

#: The variant that nests the others: the test's reference.
REFERENCE = "free"
#: The verdicts of a tested hypothesis.
CONSISTENT, REJECTED = "consistent", "rejected"
#: The verdict a fit that did not converge leaves open (module docstring).
NOT_ESTABLISHED = "not established"
#: The verdicts of a test (with a threshold), established or not.
TESTED = (CONSISTENT, REJECTED, NOT_ESTABLISHED)
#: A hypothesis that is not ``free`` under restrictions (fitted or held otherwise).
NOT_NESTED = "not nested"
#: What the problem of every fit compared must share (beside the data and the mesh).
_SHELL = ("family", "theory", "geometry", "h", "cut", "opening")


@dataclass(frozen=True)
class Hypothesis:
    """One fit of the comparison.

    Attributes
    ----------
    name : str
        Where it comes from (a file, ``t01_flat``).
    variant : str
    E_fit : float
        Units of R.
    fitted : int
        Its fitted parameters.
    restrictions : int or None
        d, the free fit's fitted parameters less its own; None where it is not nested in
        a free fit (or there is none).
    delta_S : float
        E_fit² − E_ref² against the reference (free, or the best), units of R².
    ratio : float
        ΔS/σ².
    threshold : float
        q of the test (d·F(d, ν) or χ²_d); NaN without a test.
    verdict : str
        ``"reference"`` (the free fit), ``"consistent"``, ``"rejected"``, ``"not
        established"`` (a fit that did not converge leaves the verdict open: module
        docstring), ``"not nested"``; without a free fit ``"best"`` (the lowest E_fit) or
        ``""`` (no test).
    converged : bool
        Whether its fit converged (:attr:`FitResult.converged`).
    stop : str
        How its fit ended (:attr:`FitResult.stop`).
    """

    name: str
    variant: str
    E_fit: float
    fitted: int
    restrictions: int | None
    delta_S: float
    ratio: float
    threshold: float
    verdict: str
    converged: bool = True
    stop: str = FIT_CONVERGED

    def to_dict(self) -> dict:
        """JSON-ready (NaN as None)."""
        return {"name": self.name, "variant": self.variant, "E_fit": self.E_fit,
                "fitted": self.fitted, "restrictions": self.restrictions,
                "delta_S": self.delta_S, "delta_S_over_sigma2": self.ratio,
                "threshold": None if math.isnan(self.threshold) else self.threshold,
                "verdict": self.verdict, "converged": self.converged, "stop": self.stop}


@dataclass(frozen=True)
class HypothesisTest:
    """The hypotheses on one midline compared (:func:`compare_hypotheses`).

    Attributes
    ----------
    hypotheses : tuple of Hypothesis
        In the order given.
    reference : str
        The name of the fit the ΔS are against: the free fit, or the best.
    nested : bool
        Whether the reference is a free fit (then the hypotheses are tested).
    sigma2 : float
        σ² (units of R²).
    sigma2_source : str
        ``"traces"``, ``"residual"`` or ``"given"``.
    dof : float
        Degrees of freedom of σ² (inf: χ²).
    confidence : float
    inflation : tuple of (str, float) or None
        With ``sigma2_source`` :data:`~morphoshell.fitting.profile_noise.RETRACED`: the
        parameter the hypotheses restrict and its factor on the residual's σ², (SE of the
        free fit's re-tracings / Gauss–Newton SE)²; None otherwise.
    """

    hypotheses: tuple[Hypothesis, ...]
    reference: str
    nested: bool
    sigma2: float
    sigma2_source: str
    dof: float
    confidence: float
    inflation: tuple[str, float] | None = None

    def of(self, verdict: str) -> list[str]:
        """The variants with ``verdict``, in order."""
        return [h.variant for h in self.hypotheses if h.verdict == verdict]

    def verdict(self, variant: str) -> str:
        """The verdict of ``variant`` (KeyError if it was not compared)."""
        return {h.variant: h.verdict for h in self.hypotheses}[variant]

    def noise_line(self) -> str:
        """Where σ² comes from and the law of the threshold."""
        where = {"traces": f"from the spread of {self.dof + 1:g} traces",
                 "residual": "from the free fit's residual" if self.nested else
                             "from the best fit's residual",
                 "given": "given"}.get(self.sigma2_source, self.sigma2_source)
        if self.inflation is not None:
            name, factor = self.inflation
            where = (f"from the free fit's residual times {factor:.3g}, {name}'s (SE of its "
                     f"trace's re-tracings / Gauss-Newton SE)^2, as {name}'s profile")
        line = f"sigma^2 = {self.sigma2:.3g} R^2 {where}"
        laws = sorted({_law(h.restrictions, self.dof) for h in self.hypotheses
                       if h.verdict in TESTED})
        if laws:
            line += f"; threshold: the {self.confidence:.0%} quantile of {' or '.join(laws)}"
        if self.sigma2_source == "residual":
            line += (" (a traced midline's noise is larger than its residual's: an average of "
                     "traces, morphoshell average --csv, gives the calibrated test)")
        return line

    def summary(self) -> str:
        """The verdict in one line: which hypotheses the data cannot tell apart, or the one
        consistent, or none; without a free fit, that the test needs one."""
        if not self.nested:
            return (f"no test: no free fit to test the hypotheses against (each is free with "
                    f"kappa1 tied); Delta S/sigma^2 against the best, {self.reference}, is "
                    f"only a guide: fit --variant free to the same midline and compare again")
        ok, out, left = self.of(CONSISTENT), self.of(REJECTED), self.of(NOT_ESTABLISHED)
        rejected = f"; rejected: {', '.join(out)}" if out else ""
        if len(ok) > 1:
            head = (f"the data do not tell {', '.join(ok)} apart (each within its threshold "
                    f"of free): their E_fit ranking is noise")
        elif ok:
            head = f"{'only ' if out and not left else ''}{ok[0]} is consistent with the data"
        elif out and not left:
            head = "every hypothesis is rejected: kappa1 is none of them (read free's)"
        elif out or left:
            head = "no hypothesis is established as consistent with the data"
        else:
            head = "no hypothesis tested: none is free under restrictions (not nested)"
        return head + rejected + self._unconverged() + self._caveats(out)

    def _unconverged(self) -> str:
        """The verdicts a fit that did not converge leaves open, and the fits that did not
        converge whose verdicts stand (module docstring), with how each stopped."""
        ref = next(h for h in self.hypotheses if h.name == self.reference)
        left = [h for h in self.hypotheses if h.verdict == NOT_ESTABLISHED]
        why = []
        if not ref.converged and self.nested:
            why.append(f"free's fit did not converge (stop {ref.stop}): its E_fit lies above "
                       f"its minimum, so each Delta S/sigma^2 may be larger")
        why += [f"{h.variant}'s fit did not converge (stop {h.stop}): its Delta S/sigma^2 "
                f"may be smaller" for h in left if not h.converged]
        text = (f"; not established: {', '.join(h.variant for h in left)} "
                f"({'; '.join(why)}; refit to convergence, --start FIT.json)" if left else "")
        stand = [h for h in self.hypotheses if not h.converged and h not in left
                 and (h is not ref or not left)]
        if stand:
            text += (f"; {', '.join(h.variant for h in stand)} did not converge "
                     f"({', '.join(f'stop {h.stop}' for h in stand)})"
                     + ("; the verdicts shown stand: a stop only moves Delta S/sigma^2 "
                        "away from them" if self.nested else ""))
        return text

    def _caveats(self, out: list[str]) -> str:
        """A free fit above a hypothesis, and the residual's σ² of a traced midline."""
        lower = [h.variant for h in self.hypotheses if h.verdict in TESTED
                 and h.delta_S < 0]
        note = (f"; free's E_fit lies above {', '.join(lower)}'s: the free fit is not at its "
                f"minimum (refit free from there, --start FIT.json)" if lower else "")
        caveat = ("; sigma^2 from the residual, smaller than a traced midline's correlated "
                  "noise: a rejection may be that noise (compare fits of an average of traces)"
                  if self.sigma2_source == "residual" and out else
                  # (the truth was still rejected on 3 of 18 synthetic traces: benchmarks)
                  "; sigma^2 holds the trace's pixel noise only, not a hand's slow wiggles "
                  "(compare fits of an average of traces)"
                  if self.sigma2_source == RETRACED and out else "")
        return note + caveat

    def columns(self) -> dict[str, list]:
        """The comparison as columns: name, variant, E_fit (R), fitted, restrictions,
        delta_S (R²), delta_S_over_sigma2, threshold, verdict, converged, stop
        (:meth:`to_dict`'s rows)."""
        rows = [h.to_dict() for h in self.hypotheses]
        return {key: [row[key] for row in rows] for key in rows[0]}

    def table(self) -> str:
        """The comparison as text lines, one per hypothesis."""
        lines = [f"  {'variant':<11}{'E_fit [R]':>12}{'k':>4}{'dS [R^2]':>12}"
                 f"{'dS/sigma^2':>12}{'threshold':>11}  verdict"]
        for h in self.hypotheses:
            q = "" if math.isnan(h.threshold) else f"{h.threshold:.3g}"
            stopped = "" if h.converged else f" (fit not converged: {h.stop})"
            lines.append(f"  {h.variant:<11}{h.E_fit:>12.6g}{h.fitted:>4}{h.delta_S:>12.3g}"
                         f"{h.ratio:>12.3g}{q:>11}  {h.verdict}{stopped}")
        return "\n".join(lines)

    def to_dict(self) -> dict:
        """JSON-ready: the noise, the reference, the rows and the summary."""
        return {"reference": self.reference, "nested": self.nested, "sigma2": self.sigma2,
                "sigma2_units": "R^2", "sigma2_source": self.sigma2_source,
                "dof": None if math.isinf(self.dof) else self.dof,
                "sigma2_inflation": None if self.inflation is None else
                                    dict(zip(("parameter", "factor"), self.inflation)),
                "confidence": self.confidence,
                "hypotheses": [h.to_dict() for h in self.hypotheses],
                "summary": self.summary()}


def compare_hypotheses(fits: Mapping[str, Any], data=None, *, noise: str | float = "auto",
                       confidence: float = 0.95) -> HypothesisTest:
    """Test each hypothesis on κ₁ against the free fit of the same midline (module docstring).

    Parameters
    ----------
    fits : mapping
        Name (a file, a label) → :class:`FitResult` or a fit's record (the JSON of
        ``morphoshell fit --json``, a campaign's), at least two, each variant once, all
        fitted to the same points on the same shell (and, where the records say, mesh).
    data : Midline or array_like (N, 2), optional
        The midline they were fitted to, for σ² from its traces' spread; default: the fits'
        points (σ² from the residual).
    noise : {"auto", "residual", "traces"} or float
        As the profiles' (:func:`~morphoshell.fitting.profile_noise.noise_variance`).
    confidence : float
        Of the test (0.95: rejected at the 5 % level).

    Returns
    -------
    HypothesisTest

    Raises
    ------
    ValueError
        Fewer than two fits, a variant twice, fits of other data, meshes or shells than the
        first's, ``data`` that are not the fits' data, or a bad ``noise``: one line naming
        the fits.
    """
    if not 0 < confidence < 1:
        raise ValueError(f"confidence = {confidence!r} must lie between 0 and 1")
    results = {name: _as_fit(fit, name) for name, fit in fits.items()}
    _check_same(fits, results, data)
    by_variant = {r.variant: name for name, r in results.items()}
    nested = REFERENCE in by_variant
    ref_name = by_variant[REFERENCE] if nested else min(results, key=lambda n: results[n].E_fit)
    ref = results[ref_name]
    source = data if data is not None else ref.data
    restricted = _restricted(results, ref) if nested else None
    inflation = fit_inflation(ref) if restricted else None
    sigma2, where, dof = parameter_noise(source, ref.E_fit ** 2, len(ref.fitted), noise,
                                         inflation, restricted or "")
    rows = tuple(_row(name, r, ref, ref_name == name, nested, (sigma2, where), confidence,
                      dof) for name, r in results.items())
    factor = (restricted, inflation[restricted]) if where == RETRACED else None
    return HypothesisTest(rows, ref_name, nested, sigma2, where, dof, confidence, factor)


def _restricted(results: Mapping[str, FitResult], free: FitResult) -> str | None:
    """The one parameter that every hypothesis nested in ``free`` restricts (``kappa1``),
    whose re-tracing factor scales a single trace's σ² (module docstring); None where some
    restrict more or others (their ΔS/σ² has no single factor)."""
    removed = {frozenset(free.fitted) - frozenset(fit.fitted) for fit in results.values()
               if fit is not free and _restrictions(fit, free) is not None}
    if len(removed) != 1:
        return None
    (names,) = removed
    return next(iter(names)) if len(names) == 1 else None


def _row(name: str, fit: FitResult, ref: FitResult, is_ref: bool, nested: bool,
         noise: tuple[float, str], confidence: float, dof: float) -> Hypothesis:
    """One fit's ΔS, ΔS/σ², threshold and verdict against ``ref`` (``noise``: σ² and
    where it comes from)."""
    sigma2, where = noise
    delta = float(fit.E_fit) ** 2 - float(ref.E_fit) ** 2
    d = _restrictions(fit, ref) if nested and not is_ref else None
    q = threshold_quantile(confidence, dof, d) if d else math.nan
    if is_ref:
        verdict = "reference" if nested else "best"
    elif not nested:
        verdict = ""
    elif d is None:
        verdict = NOT_NESTED
    else:
        verdict = _established(REJECTED if delta / sigma2 > q else CONSISTENT, fit, ref,
                               where == RETRACED)
    return Hypothesis(name, fit.variant, float(fit.E_fit), len(fit.fitted), d, delta,
                      delta / sigma2, q, verdict, bool(fit.converged), fit.stop)


def _established(verdict: str, fit: FitResult, free: FitResult, retraced: bool) -> str:
    """``verdict``, or :data:`NOT_ESTABLISHED` where a fit that did not converge leaves it
    open (module docstring): a rejection needs ``fit``'s E_fit at its minimum (a stop
    leaves ΔS an upper bound) and σ² no larger than a stopped free fit leaves it (its
    residual's is larger still; a re-traced factor of its own may be either); consistency
    needs ``free``'s (a stop leaves every ΔS a lower bound)."""
    if verdict == REJECTED:
        settled = fit.converged and (free.converged or not retraced)
    else:
        settled = free.converged
    return verdict if settled else NOT_ESTABLISHED


def _law(d: int, dof: float) -> str:
    """The law of ΔS/σ² at a true hypothesis of d restrictions, in words."""
    if math.isinf(dof):
        return f"chi2_{d}"
    return f"F(1, {dof:g})" if d == 1 else f"{d}*F({d}, {dof:g})"


def _restrictions(fit: FitResult, free: FitResult) -> int | None:
    """d, how many more parameters ``free`` fits than ``fit``, when ``fit`` is ``free`` under
    restrictions: every parameter it fits fitted by ``free`` too, every one ``free`` holds
    held by it at the same value; else None."""
    mine, theirs = set(fit.fitted), set(free.fitted)
    held = [n for n in free.parameters if n not in theirs]
    if not mine < theirs or any(fit.parameters.get(n) != free.parameters[n] for n in held):
        return None
    return len(theirs) - len(mine)


def _as_fit(fit, name: str) -> FitResult:
    """A :class:`FitResult` of a result or of a record (checked, ``name`` in its messages)."""
    if isinstance(fit, FitResult):
        return fit
    if isinstance(fit, Mapping):
        return FitResult.from_dict(fit, name)
    raise ValueError(f"{name}: {type(fit).__name__} is neither a FitResult nor a fit's record")


def _nodes(fit) -> int | None:
    """The mesh of a fit's record (``morphoshell fit``'s [solver] table, a campaign's
    ``nodes``), None where it does not say (a FitResult)."""
    if not isinstance(fit, Mapping):
        return None
    solver = fit.get("solver")
    return solver.get("nodes") if isinstance(solver, Mapping) else fit.get("nodes")


def _check_same(fits: Mapping[str, Any], results: Mapping[str, FitResult], data) -> None:
    """ValueError unless there are two fits or more, each variant once, all of the first's
    data, mesh and shell (and ``data``, if given, is theirs)."""
    if len(results) < 2:
        raise ValueError(f"{len(results)} fit(s) given: comparing hypotheses needs two or more "
                         f"fits of one midline (free and the hypotheses on kappa1)")
    names = list(results)
    first, fit0 = names[0], results[names[0]]
    seen: dict[str, str] = {}
    for name in names:
        fit = results[name]
        if fit.variant in seen:
            raise ValueError(f"{seen[fit.variant]} and {name} are both fits of the variant "
                             f"{fit.variant}: compare one fit of each hypothesis")
        seen[fit.variant] = name
        _same_points(fit0.data, fit.data, f"{name} was fitted to other data than {first}")
        _same_mesh(_nodes(fits[first]), _nodes(fits[name]), first, name)
        _same_shell(fit0, fit, first, name)
    if data is not None:
        _same_points(fit0.data, as_points(data),
                     f"the data given are not those the fits were made to ({first})")


#: Points of one midline agree to this (R): a record holds its points to the bit (JSON keeps
#: every digit) and the reader resamples a file the same way each time (0 on audit 25's
#: average), but another version's resampling may move them by round-off; another average
#: of traces moves them by its noise, 10⁻⁴–10⁻² R.
SAME_POINTS = 1e-9


def _same_points(a: np.ndarray, b: np.ndarray, what: str) -> None:
    """ValueError ``what`` unless the midlines ``a`` and ``b`` are the same points (to
    :data:`SAME_POINTS`)."""
    if a.shape != b.shape:
        raise ValueError(f"{what} ({len(b)} points against {len(a)}): compare fits of one "
                         f"midline")
    if not np.max(np.abs(a - b)) <= SAME_POINTS:
        raise ValueError(f"{what} (points up to {np.max(np.abs(a - b)):.3g} R apart): compare "
                         f"fits of one midline")


def _same_mesh(a: int | None, b: int | None, first: str, name: str) -> None:
    """ValueError unless the meshes ``a`` and ``b`` agree (where both are known): E_fit on
    another mesh differs by the discretisation, which the test would read as data."""
    if a is not None and b is not None and a != b:
        raise ValueError(f"{name} was fitted on {b} nodes, {first} on {a}: compare fits on "
                         f"one mesh")


def _same_shell(a: FitResult, b: FitResult, first: str, name: str) -> None:
    """ValueError unless the fits' shells share family, theory, geometry, h, cut, opening."""
    for key in _SHELL:
        va, vb = getattr(a.problem, key, None), getattr(b.problem, key, None)
        if va != vb:
            raise ValueError(f"{name} is a fit of another shell than {first} ({key} {vb} "
                             f"against {va}): compare fits of one shell")
