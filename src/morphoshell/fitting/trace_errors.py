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
"""
from __future__ import annotations

import logging
from dataclasses import dataclass, replace
from typing import Mapping

import numpy as np

from ..io.midlines import align, resample
from ..io.trace_checks import MidlineError
from ..io.trace_noise import noise_estimate
from ..io.traces import Trace, to_image

__all__ = ["TRACE_REPLICATES", "MAX_REFUSED", "ReaderErrors", "reader_errors", "sandwich_errors",
           "with_trace_errors", "profile_inflation"]

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

    @property
    def usable(self) -> bool:
        """At most :data:`MAX_REFUSED` of the re-tracings refused (and at least two read)."""
        made = len(self.errors) + len(self.refused)
        return len(self.errors) >= 2 and len(self.refused) <= MAX_REFUSED * made


def reader_errors(data: np.ndarray, trace: Trace, section: str,
                  replicates: int = TRACE_REPLICATES, seed: int = 0) -> ReaderErrors:
    """The reader's errors on re-tracings of ``data`` with the noise of ``trace``.

    Parameters
    ----------
    data : ndarray, shape (N, 2)
        The fitted midline (r, z), model gauge, units of R: the template.
    trace : Trace
        The image trace it was read from (its points, in units of R, give σ and their count).
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
    return ReaderErrors(np.reshape(errors, (len(errors), 2 * n)), sigma, tuple(refused))


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


def with_trace_errors(result, errors: np.ndarray):
    """``result`` with its standard errors and correlation from the data's ``errors``
    (:func:`reader_errors`: its trace's re-tracings) by the sandwich at its Jacobian.

    The re-tracings depend on the data and the trace only, so one set serves the fit and a
    refit of the same data (the profiles' lower fit).  Parameters that the Gauss–Newton
    errors left NaN (on a constraint) stay NaN.

    Returns
    -------
    FitResult
        ``standard_errors`` and ``correlation`` replaced.
    """
    cov = sandwich_errors(result.jacobian, errors)
    se = np.sqrt(np.maximum(np.diag(cov), 0.0))
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = cov / np.outer(se, se)
    keep = {n: float("nan") for n, e in result.standard_errors.items() if not np.isfinite(e)}
    return replace(result, standard_errors={**dict(zip(result.fitted, se.tolist())), **keep},
                   correlation=corr)


def profile_inflation(gauss_newton: Mapping[str, float],
                      sandwich: Mapping[str, float]) -> dict[str, float]:
    """Per parameter, (sandwich SE / Gauss–Newton SE)²: the factor on the residual's σ² that
    puts a single trace's profile intervals on the errors printed beside them
    (:func:`morphoshell.fitting.profile_noise.parameter_noise`); parameters without both
    errors (on a constraint) are left out."""
    return {name: (se / gauss_newton[name]) ** 2 for name, se in sandwich.items()
            if np.isfinite(se) and np.isfinite(gauss_newton.get(name, np.nan))
            and gauss_newton[name] > 0}
