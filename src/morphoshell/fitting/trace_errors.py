"""Standard errors of a fit to one image trace: its pixel noise carried through the reader.

The Gauss–Newton errors σ²(JᵀJ)⁻¹ (:func:`morphoshell.fitting.results.fit_result`) take
the 2N residuals of the fitted midline as independent.  A single image trace's midline is
not N independent noisy points: the reader (:func:`morphoshell.io.midlines.align`,
:func:`~morphoshell.io.midlines.resample`) averages the pixel noise in bins, draws a spline
through the bins, averages the two halves of a whole section, fits the axis and the pole's
height and resamples in its own, noisy, arclength.  Its errors are correlated along the
midline, short-range (neighbouring points share bins: lag-1 autocorrelation of the residuals
0.45) and long-range (the axis, the pole's height and the arclength move whole stretches
together, autocorrelation 0.3–0.5 at lags of 4–10 points).  The fit absorbs the long-range
part into its parameters, so the residuals neither show it (their autocorrelation beyond lag
3 is 0; a Newey–West covariance from them covered κ₁ 0.62–0.72 where 0.95 was nominal) nor
give σ² (2.8× smaller than the midline's error variance).  The Gauss–Newton errors were
1.3–1.8× too small; their ±1.96 SE covered 0.59–0.78 (docs/benchmarks.md, "Standard errors of
a fit to one trace").

What is done instead: the trace's pixel noise σ is estimated from its own points
(:func:`morphoshell.io.trace_noise.noise_estimate`), and the reader is run on ``replicates``
synthetic re-tracings of the fitted data midline (placed as the trace was, whole or half
section, at the trace's number of points, each with Gaussian noise σ per coordinate).  Their
midlines' differences from the clean template's e_b give the covariance of the data's error,
and the sandwich (JᵀJ)⁻¹Jᵀ Σ J(JᵀJ)⁻¹ the parameters' (computed as the spread of the linear
responses (JᵀJ)⁻¹Jᵀe_b).  On 39 replicate traces it matched the covariance of the reader's
true errors (200 seeds) within 1–7 %; on 76, ±1.96 SE covered f₁ 0.93 and the others
0.93–1.00, but κ₁ 0.83 and κ₂ 0.86 (κ₁'s estimate is skewed: a linearised error cannot
cover it).  A single trace's profile thresholds take the residual's σ² times each parameter's
(SE here / Gauss–Newton SE)² (:func:`morphoshell.fitting.profile_noise.parameter_noise`).

A re-tracing that the reader refuses (its noise made the halves differ beyond ``max_asymmetry``,
or a half section's axis uncertain) is left out: the trace itself was read, and a 20-vertex
segmented line, whose σ the corners between its vertices inflate, had been refused for one of
its re-tracings (audit 15, F7).  More than :data:`MAX_REFUSED` of them refused and the errors of
the rest would miss the worst: :attr:`ReaderErrors.usable` is then false and the Gauss–Newton
errors stand.

A fit with them says so (audit 27 F1: its record said "Gauss-Newton lower bounds" of either):
:func:`with_trace_errors` records how they were made (:class:`Retracings`: count, refused, σ,
seed, the Gauss–Newton errors replaced) and the result's ``standard_errors_source`` which
errors it holds.  :func:`with_trace_file_errors` gives a fit of a trace file the errors
``morphoshell fit`` gives it, in one call; the command line takes its steps
(:func:`single_trace`, :func:`trace_retracings`, :func:`with_trace_errors`) to reuse the
re-tracings for a refit.
"""
from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from .._runtime.validate import integer, within
from ..io.midlines import align, resample
from ..io.trace_checks import MidlineError
from ..io.trace_noise import noise_estimate
from ..io.traces import Trace, to_image

__all__ = ["TRACE_REPLICATES", "MAX_REFUSED", "ReaderErrors", "Retracings", "reader_errors",
           "sandwich_errors", "with_trace_errors", "single_trace", "trace_retracings",
           "with_trace_file_errors", "profile_inflation", "fit_inflation"]

#: Synthetic re-tracings per fit: the standard errors' own relative error is about 1/√(2B),
#: 7 % (about 1.5 s on the 470 points of a whole section at 133 px per R).
TRACE_REPLICATES = 100
#: Largest fraction of the re-tracings that the reader may refuse for their errors to stand
#: (the refused are the worst read; leaving out a few narrows the ± a little, more would not).
MAX_REFUSED = 0.1


@dataclass(frozen=True, eq=False)
class ReaderErrors:
    """The reader's errors on re-tracings of a fitted midline (:func:`reader_errors`).

    Attributes
    ----------
    errors : ndarray, shape (B, 2N)
        Each re-tracing read: its midline minus the clean template's, r then z (as the
        residuals); B the re-tracings not refused.
    sigma : float
        The trace's estimated noise per coordinate, units of R.
    refused : tuple of str
        Why the reader refused each of the others (its MidlineError's message).
    """

    errors: np.ndarray
    sigma: float
    refused: tuple[str, ...] = ()
    seed: int = 0
    sigma_px: float = math.nan

    @property
    def usable(self) -> bool:
        """At most :data:`MAX_REFUSED` of the re-tracings refused (and at least two read)."""
        return _usable(len(self.errors), len(self.refused))


def _usable(read: int, refused: int) -> bool:
    """Whether the errors of ``read`` re-tracings stand with ``refused`` others left out: at
    least two read, at most :data:`MAX_REFUSED` of all refused."""
    return read >= 2 and refused <= MAX_REFUSED * (read + refused)


@dataclass(frozen=True)
class Retracings:
    """What a fit's record says of the re-tracings of its image trace (its ``re_tracings``).

    Attributes
    ----------
    replicates : int
        Re-tracings made.
    refused : int
        Those the reader refused (left out).
    sigma : float
        The trace's estimated pixel noise per coordinate, units of R.
    sigma_px : float
        The same in pixels (NaN where the trace's scale is not known).
    seed : int
        Of their noise: the same seed, trace and fit give the same errors.
    gauss_newton : dict
        The fit's own Gauss–Newton standard errors (NaN on a constraint), which the
        re-tracings' replaced where :attr:`used`.
    """

    replicates: int
    refused: int
    sigma: float
    sigma_px: float
    seed: int
    gauss_newton: Mapping[str, float] = field(default_factory=dict)

    @property
    def used(self) -> bool:
        """Whether the fit's standard errors are the re-tracings' (few enough refused:
        :attr:`ReaderErrors.usable`); if not, the Gauss–Newton errors stand."""
        return _usable(self.replicates - self.refused, self.refused)

    def describe(self) -> str:
        """The re-tracings in a few words: ``"100 re-tracings (σ = 0.0038 R = 0.51 px per
        coordinate, seed 0)"``, with how many the reader refused."""
        px = f" = {self.sigma_px:.2g} px" if math.isfinite(self.sigma_px) else ""
        refused = f"; {self.refused} refused by the reader" if self.refused else ""
        return (f"{self.replicates} re-tracings (pixel noise {self.sigma:.2g} R{px} per "
                f"coordinate, seed {self.seed}{refused})")

    def to_dict(self) -> dict:
        """JSON-ready (a fit's ``re_tracings``; null for an unknown ``sigma_px`` or error)."""
        return {"replicates": self.replicates, "refused": self.refused,
                "sigma": self.sigma, "sigma_units": "R",
                "sigma_px": self.sigma_px if math.isfinite(self.sigma_px) else None,
                "seed": self.seed,
                "gauss_newton_errors": {n: (e if math.isfinite(e) else None)
                                        for n, e in self.gauss_newton.items()}}

    @classmethod
    def from_dict(cls, key: str, value: Any, fitted: tuple[str, ...]) -> "Retracings":
        """The record ``value`` (:meth:`to_dict`) of the entry ``key`` of a fit whose fitted
        parameters are ``fitted``; ValueError naming the entry and what it must be."""
        if not isinstance(value, Mapping) or not {"replicates", "refused", "sigma", "seed",
                                                   "gauss_newton_errors"} <= set(value):
            raise ValueError(f"{key} must map replicates, refused, sigma, seed and "
                             f"gauss_newton_errors to their values")
        errors = value["gauss_newton_errors"]
        if not isinstance(errors, Mapping) or set(errors) != set(fitted):
            raise ValueError(f"{key}.gauss_newton_errors must map each fitted parameter "
                             f"({', '.join(fitted)}) to a number, or null on a constraint")
        replicates = integer(f"{key}.replicates", value["replicates"], 0)
        px = value.get("sigma_px")
        return cls(replicates, integer(f"{key}.refused", value["refused"], 0, replicates),
                   within(f"{key}.sigma", value["sigma"], 0.0, math.inf),
                   math.nan if px is None else within(f"{key}.sigma_px", px, 0.0, math.inf),
                   integer(f"{key}.seed", value["seed"], 0),
                   {n: math.nan if e is None else
                    within(f"{key}.gauss_newton_errors.{n}", e, 0.0, math.inf)
                    for n, e in errors.items()})


def reader_errors(data: np.ndarray, trace: Trace, section: str,
                  replicates: int = TRACE_REPLICATES, seed: int = 0) -> ReaderErrors:
    """The reader's errors on re-tracings of ``data`` with the noise of ``trace``.

    Parameters
    ----------
    data : ndarray, shape (N, 2)
        The fitted midline (r, z), model gauge, units of R: the template.
    trace : Trace
        The image trace it was read from (its points, in units of R, give σ and their count;
        its scale σ in pixels).
    section : {"whole", "half"}
        How it was aligned (:attr:`morphoshell.io.midlines.Alignment.section`).
    replicates : int
        Re-tracings.
    seed : int
        Of the noise (so that a fit's errors are reproducible).

    Returns
    -------
    ReaderErrors
        The re-tracings read, and the reader's messages for those it refused (left out).

    Raises
    ------
    MidlineError
        The clean template itself refused (not expected: the trace it was read from passed).
    """
    sigma, _ = noise_estimate(trace.points)
    template = to_image(data, radius_px=1.0, section=section) * [1.0, -1.0]     # y up
    dense = resample(template, len(trace.points))
    n = len(data)
    clean = _read(dense, section, n)
    rng = np.random.default_rng(seed)
    errors, refused = [], []
    for _ in range(replicates):
        try:
            errors.append((_read(dense + rng.normal(0.0, sigma, dense.shape), section, n)
                           - clean).T.ravel())
        except MidlineError as exc:
            refused.append(str(exc).removeprefix("re-tracing: "))
    return ReaderErrors(np.reshape(errors, (len(errors), 2 * n)), sigma, tuple(refused), seed,
                        sigma / trace.scale)


def _read(points: np.ndarray, section: str, n: int) -> np.ndarray:
    """The ``n`` point midline the reader makes of image points (units of R, y up); its notes
    and warnings (a re-tracing's bins, its asymmetry) are the simulation's, not the user's,
    and are not logged."""
    trace = Trace(points, "re-tracing", "xy", tuple(f"point {i}" for i in range(len(points))))
    logger = logging.getLogger(align.__module__)
    disabled, logger.disabled = logger.disabled, True
    try:
        return resample(align(trace, section).points, n)
    finally:
        logger.disabled = disabled


def sandwich_errors(J: np.ndarray, errors: np.ndarray) -> np.ndarray:
    """The parameters' covariance (JᵀJ)⁺Jᵀ Σ J(JᵀJ)⁺, Σ the covariance of the rows of ``errors``.

    Parameters
    ----------
    J : ndarray, shape (2N, k)
        The residuals' Jacobian at the fit.
    errors : ndarray, shape (B, 2N)
        Samples of the data's error.

    Returns
    -------
    ndarray, shape (k, k)
    """
    responses = errors @ (np.linalg.pinv(J.T @ J) @ J.T).T
    return np.atleast_2d(np.cov(responses, rowvar=False))


def with_trace_errors(result, retraced: ReaderErrors):
    """``result`` with the standard errors and correlation of its data's errors ``retraced``
    (:func:`reader_errors`: its trace's re-tracings), by the sandwich at its Jacobian.

    The re-tracings depend on the data and the trace only, so one set serves the fit and a
    refit of the same data (the profiles' lower fit).  Parameters that the Gauss–Newton
    errors left NaN (on a constraint) stay NaN.  With more than :data:`MAX_REFUSED` of the
    re-tracings refused (:attr:`ReaderErrors.usable` false) the Gauss–Newton errors stand.
    Either way :attr:`~morphoshell.fitting.results.FitResult.re_tracings` records them
    (count, refused, σ, seed and the Gauss–Newton errors) and
    :attr:`~morphoshell.fitting.results.FitResult.standard_errors_source` says which
    errors the result holds.

    Returns
    -------
    FitResult

    Raises
    ------
    ValueError
        A result without a Jacobian (read back from its record: refit it) or whose errors
        are already a trace's re-tracings'.
    """
    if result.jacobian is None:
        raise ValueError("the fit has no Jacobian (a fit read back from its record): the "
                         "re-tracings' errors need the fit itself, as fit() returns it")
    if result.re_tracings is not None:
        raise ValueError("the fit's standard errors already come from re-tracings of its "
                         "trace (re_tracings): apply them to the fit as fit() returns it")
    record = Retracings(len(retraced.errors) + len(retraced.refused), len(retraced.refused),
                        retraced.sigma, retraced.sigma_px, retraced.seed,
                        dict(result.standard_errors))
    if not retraced.usable:
        return replace(result, re_tracings=record)
    cov = sandwich_errors(result.jacobian, retraced.errors)
    se = np.sqrt(np.maximum(np.diag(cov), 0.0))
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = cov / np.outer(se, se)
    keep = {n: float("nan") for n, e in result.standard_errors.items() if not np.isfinite(e)}
    return replace(result, standard_errors={**dict(zip(result.fitted, se.tolist())), **keep},
                   correlation=corr, re_tracings=record)


def single_trace(path: str | Path, format: str | None = None, *, pixel_size_um: float,
                 radius_um: float, roi: str | int | None = None) -> Trace | None:
    """The one image trace that the midline of ``path`` is read from
    (:func:`morphoshell.io.load_midline`'s arguments), or None where it is an average of
    several (a ROI set's ``roi="all"``), whose errors the Gauss–Newton ones or the traces'
    spread give."""
    from ..io.roi_sets import is_roi_set, read_set_traces
    from ..io.traces import read_trace

    scale = {"pixel_size_um": pixel_size_um, "radius_um": radius_um}
    if format in (None, "roi") and is_roi_set(path):
        traces = read_set_traces(path, roi, **scale)
    else:
        traces = [read_trace(path, format, **scale)]
    return traces[0] if len(traces) == 1 else None


def trace_retracings(result, trace: Trace, section: str = "auto",
                     replicates: int = TRACE_REPLICATES, seed: int = 0) -> ReaderErrors:
    """:func:`reader_errors` of the fitted data midline of ``result`` (read from ``trace``,
    aligned as ``section`` said: :func:`morphoshell.io.load_midline`'s ``section``, "auto"
    for an image trace meaning a whole one)."""
    return reader_errors(result.data, trace, "half" if section == "half" else "whole",
                         replicates, seed)


def with_trace_file_errors(result, path: str | Path, *, pixel_size_um: float,
                           radius_um: float, section: str = "auto", roi: str | int | None = None,
                           format: str | None = None, replicates: int = TRACE_REPLICATES,
                           seed: int = 0):
    """``result``, a fit of the midline of one image trace, with the standard errors that
    ``morphoshell fit`` of that file gives: the sandwich of ``replicates`` re-tracings
    (:func:`trace_retracings`, :func:`with_trace_errors`).

    Parameters
    ----------
    result : FitResult
        The fit, as :func:`morphoshell.fitting.fit` returns it (with its Jacobian).
    path, pixel_size_um, radius_um, section, roi, format
        As given to :func:`morphoshell.io.load_midline` for the fitted midline.
    replicates, seed
        The re-tracings (the command line's: 100, seed 0).

    Returns
    -------
    FitResult
        Its :attr:`~morphoshell.fitting.results.FitResult.standard_errors_source`
        ``"re-tracings"``, or ``"gauss-newton"`` where the reader refused too many of them
        (:attr:`~morphoshell.fitting.results.FitResult.re_tracings` says how many).

    Raises
    ------
    ValueError
        ``path`` is not one image trace (an average of a ROI set's traces), or ``result``
        has no Jacobian (:func:`with_trace_errors`).
    """
    trace = single_trace(path, format, pixel_size_um=pixel_size_um, radius_um=radius_um,
                         roi=roi)
    if trace is None:
        raise ValueError(f"{path}: roi={roi!r} reads several traces, not one: an average's "
                         f"errors are the Gauss-Newton ones or its traces' spread")
    return with_trace_errors(result, trace_retracings(result, trace, section, replicates, seed))


def profile_inflation(gauss_newton: Mapping[str, float],
                      sandwich: Mapping[str, float]) -> dict[str, float]:
    """Per parameter, (sandwich SE / Gauss–Newton SE)²: the factor on the residual's σ² that
    puts a single trace's profile intervals on the errors printed beside them
    (:func:`morphoshell.fitting.profile_noise.parameter_noise`); parameters without both
    errors (on a constraint) are left out."""
    return {name: (se / gauss_newton[name]) ** 2 for name, se in sandwich.items()
            if np.isfinite(se) and np.isfinite(gauss_newton.get(name, np.nan))
            and gauss_newton[name] > 0}


def fit_inflation(result) -> dict[str, float] | None:
    """:func:`profile_inflation` of a fit (a result or one read from its record) whose
    standard errors are its trace's re-tracings' (``standard_errors_source``
    ``"re-tracings"``); None for any other (its σ² needs no factor: an average's, or the
    Gauss–Newton errors stand).  The factors of its profiles and of the test of hypotheses
    against it (:mod:`morphoshell.fitting.hypotheses`)."""
    if result.standard_errors_source != "re-tracings":
        return None
    return profile_inflation(result.re_tracings.gauss_newton, result.standard_errors)
