"""E/μ from the initial recoil velocities, and the bounds on E and E H³ it gives.

Paper, main text "Recoil velocity measurements yield a bound on the elastic
modulus…", Fig. 2 K; Supplementary, "Recoil velocity: scaling argument".  The
initial recoil velocity scales as V ~ (E/μ) H^{5/2} R^{−3/2} |1 − k|
(:func:`morphoshell.mechanics.asymptotics.recoil_velocity`): with each
embryo's k from its recoil, E/μ is the least-squares slope through the origin
of V against X = H^{5/2} R^{−3/2} |1 − k| (:func:`fit_velocity`), and a lower
bound μ_min of the effective viscosity bounds E ≥ (E/μ) μ_min and the bending
modulus E H³ (:func:`elastic_bounds`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from ..mechanics import asymptotics
from .summaries import BOOTSTRAP, SEED, check_bootstrap, resamples, t_quantile

__all__ = ["MU_MIN", "velocity_scale", "elastic_bounds", "VelocityFit", "fit_velocity"]

#: Default lower bound of the effective viscosity: algal growth medium (Pa s).
MU_MIN = 0.8e-3

_MICRON = 1e-6  # m


def velocity_scale(H_um, R_um, k):
    """H^{5/2} R^{−3/2} |1 − k| (µm): the recoil velocity per unit E/μ (main text, Fig. 2 K).

    Parameters
    ----------
    H_um, R_um : float or array_like
        Sheet thickness and posterior radius (µm).
    k : float or array_like
        Intrinsic curvature (units of 1/R).

    Returns
    -------
    float or ndarray, the broadcast shape of the inputs
        X in µm: V = (E/μ) X with V in µm/s and E/μ in 1/s.
    """
    return asymptotics.recoil_velocity(1.0, H_um, R_um, k)


def elastic_bounds(E_over_mu: float, mu_min: float = MU_MIN, H_um: float = 11.0) -> dict:
    """E ≥ (E/μ) μ_min (Pa) and the bending modulus E H³ ≥ … (J), H in µm.

    Main text, "Recoil velocity measurements yield a bound on the elastic
    modulus…": with E/μ = 0.6 1/s, μ ≥ 0.8 mPa s and H = 11 µm, E ≥ 0.5 mPa
    and E H³ ≥ 7 × 10⁻¹⁹ J.

    Returns
    -------
    dict
        ``E_lower_bound_Pa`` and ``bending_modulus_lower_bound_J``.
    """
    E = float(E_over_mu) * float(mu_min)
    return {"E_lower_bound_Pa": E, "bending_modulus_lower_bound_J": E * (H_um * _MICRON) ** 3}


@dataclass(frozen=True)
class VelocityFit:
    """Least squares through the origin of V against its scaling X = H^{5/2}R^{−3/2}|1 − k|.

    E/μ = ΣXV/ΣX² (1/s), standard error SE = √(Σr²/(n − 1)/ΣX²), 95 % interval
    E/μ ± t₀.₉₇₅(n − 1) SE: the least-squares slope's t interval (a regression
    through the origin has n − 1 residual degrees of freedom; e.g. Draper & Smith,
    *Applied Regression Analysis*, 3rd ed. 1998, §3.13); the percentile bootstrap
    over embryos beside it (``bootstrap_interval``), which covers less with few
    embryos (documentation: "Inverse estimates", "Summaries"); the bounds
    E ≥ (E/μ) μ_min and E H³ with the mean H of the table.
    """

    E_over_mu: float
    standard_error: float | None
    interval: tuple[float, float] | None
    embryos: tuple[str, ...]
    X_um: tuple[float, ...]
    V_um_per_s: tuple[float, ...]
    mu_min_Pa_s: float
    H_mean_um: float
    E_lower_bound_Pa: float
    bending_modulus_lower_bound_J: float
    excluded: tuple[str, ...] = ()
    bootstrap_interval: tuple[float, float] | None = None

    def __str__(self) -> str:
        se = "" if self.standard_error is None else f" +- {self.standard_error:.3f}"
        return (f"E/mu = {self.E_over_mu:.3f}{se} 1/s ({len(self.embryos)} embryos) => "
                f"E >= {self.E_lower_bound_Pa * 1e3:.3g} mPa (mu >= {self.mu_min_Pa_s * 1e3:g} "
                f"mPa s), E H^3 >= {self.bending_modulus_lower_bound_J:.3g} J "
                f"(H = {self.H_mean_um:.3g} um)")

    def to_dict(self) -> dict:
        """JSON-ready: E/μ (1/s) with its error and interval, the bounds on E (Pa) and E H³ (J)."""
        return {"E_over_mu": self.E_over_mu, "E_over_mu_standard_error": self.standard_error,
                "E_over_mu_interval_95": None if self.interval is None else list(self.interval),
                "E_over_mu_interval_method": "student_t",
                "E_over_mu_bootstrap_interval_95":
                    None if self.bootstrap_interval is None else list(self.bootstrap_interval),
                "E_lower_bound_Pa": self.E_lower_bound_Pa,
                "bending_modulus_lower_bound_J": self.bending_modulus_lower_bound_J,
                "mu_min_Pa_s": self.mu_min_Pa_s, "H_mean_um": self.H_mean_um,
                "embryos": list(self.embryos), "X_um": list(self.X_um),
                "V_um_per_s": list(self.V_um_per_s), "excluded": list(self.excluded)}


def _check_finite(V: np.ndarray, X: np.ndarray, embryos: Sequence[str] | None) -> None:
    """ValueError naming the first embryo whose velocity or scale is not finite."""
    for name, values in (("velocity", V), ("velocity scale", X)):
        bad = np.flatnonzero(~np.isfinite(values))
        if len(bad):         # a NaN would give E/mu = nan, silently
            who = embryos[bad[0]] if embryos is not None else int(bad[0])
            raise ValueError(f"fit_velocity: the {name} of embryo {who!r} is "
                             f"{float(values[bad[0]])!r}, not a finite number")


def _bootstrap_slopes(V: np.ndarray, X: np.ndarray, bootstrap: int,
                      rng: np.random.Generator | None) -> tuple[float, float]:
    """Percentile bootstrap 95 % interval of the slope (resamples with ΣX² = 0 dropped)."""
    n = V.size
    rng = rng or np.random.default_rng(SEED)
    slopes = np.concatenate([_slopes(V[idx], X[idx]) for idx in resamples(rng, n, bootstrap)])
    return tuple(float(v) for v in np.percentile(slopes, [2.5, 97.5]))


def _slopes(V: np.ndarray, X: np.ndarray) -> np.ndarray:
    """ΣXV/ΣX² of each row of resampled V and X, shape (m, n) → (≤ m,): rows with ΣX² = 0
    dropped."""
    den = np.einsum("ij,ij->i", X, X)
    ok = den > 0
    return np.einsum("ij,ij->i", X, V)[ok] / den[ok]


def fit_velocity(V: Sequence[float], X: Sequence[float], *, mu_min: float = MU_MIN,
                 H_mean_um: float = 11.0, embryos: Sequence[str] | None = None,
                 bootstrap: int = BOOTSTRAP, rng: np.random.Generator | None = None,
                 excluded: Sequence[str] = ()) -> VelocityFit:
    """Fit V = (E/μ) X through the origin (V in µm/s, X in µm; see :class:`VelocityFit`).

    Parameters
    ----------
    V, X : sequence of float, length n
        Initial recoil velocities (µm/s) and their scales (:func:`velocity_scale`, µm).
    mu_min : float
        Lower bound of the effective viscosity (Pa s).
    H_mean_um : float
        Sheet thickness of the bound on E H³ (µm).
    embryos : sequence of str, length n, optional
        Labels (default: 0, 1, …).
    bootstrap : int
        Resamples of the bootstrap interval beside the t interval (0: none, else at least
        :data:`morphoshell.inverse.summaries.MIN_BOOTSTRAP`); no interval for n < 2.
    rng : numpy.random.Generator, optional
        Draws the resamples (default: seeded with :data:`morphoshell.inverse.summaries.SEED`).
    excluded : sequence of str
        Embryos with a velocity but no k, recorded in the result.

    Returns
    -------
    VelocityFit

    Raises
    ------
    ValueError
        For unequal lengths, all-zero X, a value that is not finite (named
        by its embryo), or a bad ``bootstrap``.
    """
    bootstrap = check_bootstrap(bootstrap)
    V, X = np.asarray(V, dtype=float), np.asarray(X, dtype=float)
    if V.size == 0 or V.size != X.size or not np.any(X):
        raise ValueError("fit_velocity needs equally many velocities and scales, not all zero")
    _check_finite(V, X, embryos)
    sxx = float(X @ X)
    slope = float(X @ V / sxx)
    n = V.size
    se = float(math.sqrt(np.sum((V - slope * X) ** 2) / (n - 1) / sxx)) if n >= 2 else None
    interval = None if se is None else (slope - t_quantile(n) * se, slope + t_quantile(n) * se)
    boot = _bootstrap_slopes(V, X, bootstrap, rng) if bootstrap and n >= 2 else None
    bounds = elastic_bounds(slope, mu_min, H_mean_um)
    return VelocityFit(slope, se, interval, tuple(embryos or [str(i) for i in range(n)]),
                       tuple(map(float, X)), tuple(map(float, V)), float(mu_min),
                       float(H_mean_um), **bounds, excluded=tuple(excluded),
                       bootstrap_interval=boot)
