"""The noise variance σ² of a profile's threshold, and the threshold's quantile.

σ² of one coordinate of one point of the data comes from the fit's residual or from the
spread of the traces an averaged midline holds; with σ² from n traces the threshold takes
F(1, n − 1) instead of χ²₁ (:mod:`morphoshell.fitting.profiles`, module docstring, for
why and the coverage each gives).  Split from the profiles so that where σ² came from is
decided, and said, in one place.
"""
from __future__ import annotations

import logging
import math

import numpy as np

from .midline_checks import as_points

__all__ = ["NOISE_SOURCES", "threshold_quantile", "noise_dof", "traces_missing",
           "noise_variance", "log_noise", "parameter_noise", "check_inflation", "RETRACED",
           "traces_and_residual"]

#: The σ² source of a profile whose residual σ² a single trace's re-tracings scaled.
RETRACED = "residual, scaled by the trace's re-tracings"

log = logging.getLogger(__name__)

#: Where σ² comes from; "auto": ``traces`` when the data have them.
NOISE_SOURCES = ("auto", "residual", "traces")


def threshold_quantile(confidence: float, dof: float = math.inf, restrictions: int = 1
                       ) -> float:
    """q of the threshold S_min + σ² q: χ²_d(confidence), or d·F(d, dof) for an estimated σ²
    (d = ``restrictions``; 1 for a profile).

    F(1, ν) is the square of Student's t with ν degrees of freedom: the
    likelihood-ratio statistic with σ² replaced by an estimate of ν degrees
    of freedom (:mod:`morphoshell.fitting.profiles`).  It tends to χ²₁ as ν grows.
    With d ``restrictions`` (a hypothesis that holds d parameters of a fit,
    :mod:`morphoshell.fitting.hypotheses`) χ²_d, or d·F(d, ν): ΔS/σ² is then the sum of d
    such squares.  A profile holds one (d = 1).
    """
    from scipy.stats import chi2, f

    if math.isfinite(dof):
        return float(restrictions * f.ppf(confidence, restrictions, dof))
    return float(chi2.ppf(confidence, restrictions))


def noise_dof(data, source: str) -> float:
    """The degrees of freedom of σ² from ``source`` (:func:`noise_variance`).

    n − 1 for σ² from the spread of n traces (their errors are correlated
    along each trace: :mod:`morphoshell.fitting.profiles`); inf otherwise (χ²₁).
    """
    return float(getattr(data, "n_traces", 1) - 1) if source == "traces" else math.inf


def traces_missing(data) -> str:
    """What keeps σ² from coming from the traces of ``data``, "" when nothing does: "no
    spread (a single trace, or an array of points)", "n_traces = 1, not an average of
    several traces" or "a spread of zero everywhere" (:func:`noise_variance`)."""
    spread = getattr(data, "spread", None)
    if spread is None:
        return "no spread (a single trace, or an array of points)"
    n_traces = getattr(data, "n_traces", 1)
    if n_traces < 2:
        return f"n_traces = {n_traces}, not an average of several traces"
    if not np.any(np.asarray(spread) > 0):
        return "a spread of zero everywhere"
    return ""


def noise_variance(data, S_min: float, k: int, source: str | float = "auto") -> tuple[float, str]:
    """σ², the noise variance of one coordinate of one data point, and where it came from.

    Parameters
    ----------
    data : Midline or array_like (N, 2)
        The fitted midline; a :class:`morphoshell.io.Midline` averaged from
        n > 1 traces carries their spread.
    S_min : float
        The fit's objective E_fit² (units of R²).
    k : int
        The fitted parameters.
    source : {"auto", "residual", "traces"} or float
        ``residual``: S_min/(2N − k); ``traces``: mean(spread²)/n_traces over
        the points off the pole (the pole is the gauge's origin: no spread);
        ``auto``: traces when the data have them, else residual; a number: σ²
        itself (``"given"``).

    Returns
    -------
    sigma2 : float
    source : str

    Raises
    ------
    ValueError
        An unknown source, ``traces`` for data without a spread, or a σ²
        that is not a positive number.
    """
    if not isinstance(source, str):
        if not (np.isfinite(source) and source > 0):
            raise ValueError(f"sigma2 = {source!r} must be a positive number")
        return float(source), "given"
    if source not in NOISE_SOURCES:
        raise ValueError(f"noise = {source!r} must be one of {list(NOISE_SOURCES)} or a number")
    missing = traces_missing(data)
    if source == "traces" and missing:
        raise ValueError(f"noise = 'traces' needs an average of several traces with their "
                         f"spread (a Midline with spread and n_traces > 1); the data hold "
                         f"{missing}")
    if source == "traces" or (source == "auto" and not missing):
        spread = np.asarray(data.spread, dtype=float)
        return float(np.mean(spread[spread > 0] ** 2) / data.n_traces), "traces"
    n = len(as_points(data))
    return float(S_min) / max(2 * n - k, 1), "residual"


def traces_and_residual(data, S_min: float, k: int) -> tuple[float, float, float]:
    """σ² from the traces of ``data``, σ² of the residual of a fit of ``k`` parameters at
    ``S_min`` (the σ² of its Gauss–Newton covariance, S_min/(2N − k)) and the traces'
    degrees of freedom: :func:`noise_variance` both ways, so that a fit's covariance can be
    carried at the σ² its profiles and :mod:`~morphoshell.fitting.hypotheses` take (times
    the first over the second; ValueError where ``data`` hold no traces' spread).
    """
    traces, _ = noise_variance(data, S_min, k, "traces")
    residual, _ = noise_variance(data, S_min, k, "residual")
    return traces, residual, noise_dof(data, "traces")


def log_noise(data, noise) -> None:
    """Log where ``noise="auto"`` takes σ² from: a warning when from the residual, whose
    intervals cover about half as often as the traces' (:mod:`morphoshell.fitting.profiles`),
    since data that
    lost their spread on the way (an array of an average's points) fall back to it
    unseen; the choice is recorded in each :attr:`Profile.sigma2_source` too."""
    if noise != "auto":
        return
    missing = traces_missing(data)
    if missing:
        log.warning("profiles: sigma^2 from the fit's residual with chi2_1 (noise='auto'; the "
                    "data hold %s): such intervals are lower bounds on traced data; fit the "
                    "Midline of an average of traces (morphoshell.io.load_midline of its CSV "
                    "keeps the spread and n_traces), or pass noise='residual' to choose it",
                    missing)
    else:
        log.info("profiles: sigma^2 from the spread of %d traces, F(1, %d)",
                 data.n_traces, data.n_traces - 1)


def check_inflation(inflation, names) -> None:
    """ValueError unless ``inflation`` is None or maps every name of ``names`` it holds to a
    positive number (:func:`parameter_noise`)."""
    if inflation is None:
        return
    for name in names:
        factor = inflation.get(name, 1.0)
        if not (isinstance(factor, (int, float)) and math.isfinite(factor) and factor > 0):
            raise ValueError(f"inflation[{name!r}] = {factor!r} must be a positive number")


def parameter_noise(data, S_min: float, k: int, noise, inflation, name: str
                    ) -> tuple[float, str, float]:
    """σ², its source and degrees of freedom for the profile of ``name``.

    :func:`noise_variance`'s σ², times ``inflation[name]`` where it comes from the residual:
    a single image trace's errors are correlated along the midline, which the residual does
    not show; the factor (SE of the re-tracings / Gauss–Newton SE)² of
    :mod:`morphoshell.fitting.trace_errors` makes a linear model's interval its ±1.96 SE
    (the profiles had stayed 1.3–1.8× narrower than the errors printed beside them).
    """
    sigma2, source = noise_variance(data, S_min, k, noise)
    dof = noise_dof(data, source)
    factor = (inflation or {}).get(name)
    if factor is not None and source == "residual":
        return sigma2 * float(factor), RETRACED, dof
    return sigma2, source, dof
