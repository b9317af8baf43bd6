"""Fits of the four hypotheses on one midline, made by hand (no fitting): the E_fit of
audit 25's five-trace average (truth κ₁ = 0.6), for the tests of
morphoshell.fitting.hypotheses, the campaign's summary and ``morphoshell compare``."""
import numpy as np

from morphoshell.fitting import FitResult
from morphoshell.model.problem import Problem

#: The audit's E_fit (R) of each variant's multi-start fit of st2/average.csv.
AUDIT_E_FIT = {"free": 0.003462940019282411, "flat": 0.0034905162190410474,
               "undeformed": 0.003652509068252771, "unstressed": 0.003762149813322323}
#: σ² (R²) of its five traces' spread (profile_noise.noise_variance of the average).
AUDIT_SIGMA2 = 6.477390731512509e-06
#: The Volvox parameters the fits share (the family's names; κ₁ set per variant).
PARAMS = {"f1": 0.85, "f2": 0.9, "f3": 1.33, "f4": 1.0, "f5": 1.32, "kappa1": 0.6,
          "kappa2": -7.3, "kappa3": 1.9, "kappa4": -1.47, "s1": 1.06, "s2": 1.54, "s3": 2.07,
          "s4": 2.31, "sigma": 0.05}
#: κ₁ of each hypothesis (unstressed: 1/f₁).
KAPPA1 = {"flat": 0.0, "undeformed": 1.0, "unstressed": 1 / PARAMS["f1"]}
N = 100


def points(n: int = N) -> np.ndarray:
    """A half circle of radius 1 from the pole, the data the fits share."""
    t = np.linspace(0, np.pi, n)
    return np.column_stack([np.sin(t), 1 - np.cos(t)])


def fit_of(variant: str, E_fit: float, data: np.ndarray | None = None, held=(),
           h: float = 0.15, **params) -> FitResult:
    """A converged fit of ``variant`` at ``E_fit``: free fits all 13 parameters, the others
    all but κ₁ (and the names in ``held``); ``params`` override the shared values."""
    values = {**PARAMS, "kappa1": KAPPA1.get(variant, PARAMS["kappa1"]), **params}
    tied = () if variant == "free" else ("kappa1",)
    fitted = tuple(n for n in values if n != "sigma" and n not in tied and n not in held)
    data = points() if data is None else data
    k = len(fitted)
    problem = Problem(family="volvox", params=values, h=h, opening=0.3)
    residuals = np.full(2 * len(data), E_fit / np.sqrt(2 * len(data)))
    return FitResult("gradient", variant, fitted, {**values, "h": h, "cut": 0.0, "opening": 0.3},
                     {n: 0.01 for n in fitted}, np.eye(k), [], E_fit, residuals, None,
                     data, data + 1e-3, 10, 10, 1.0, True, problem=problem)


def audit_fits(**kwargs) -> dict:
    """The audit's four fits, by variant."""
    return {v: fit_of(v, e, **kwargs) for v, e in AUDIT_E_FIT.items()}


def spread_for(sigma2: float, n_traces: int = 5, n: int = N) -> np.ndarray:
    """A spread (R) whose traces' σ² (mean(spread²)/n_traces off the pole) is ``sigma2``."""
    spread = np.full(n, np.sqrt(sigma2 * n_traces))
    spread[0] = 0.0         # (the pole: the gauge's origin, no spread)
    return spread


def retraced(fit: FitResult, factors: dict) -> FitResult:
    """``fit`` as ``morphoshell fit --pixel-size`` leaves a fit of one image trace: its
    standard errors its re-tracings' (Gauss–Newton ones × √factor per parameter, 1 for the
    others), the Gauss–Newton ones recorded (:class:`~morphoshell.fitting.trace_errors.
    Retracings`)."""
    from dataclasses import replace

    from morphoshell.fitting.trace_errors import Retracings

    gauss_newton = dict(fit.standard_errors)
    sandwich = {n: e * np.sqrt(factors.get(n, 1.0)) for n, e in gauss_newton.items()}
    return replace(fit, standard_errors=sandwich,
                   re_tracings=Retracings(100, 0, 0.004, 0.5, 0, gauss_newton))
