"""Statistics of the estimates over embryos: mean, spread and a 95 % interval of the mean.

Paper, main text "Quantitative estimates of the curvature mismatch during
*Volvox* invagination…", Fig. 2 J: the mean k over embryos with its spread.
Each summary is a :class:`Spread`: the mean, the standard deviation (n − 1),
Student's t interval of the mean, x̄ ± t₀.₉₇₅(n − 1) s/√n (Student 1908,
Biometrika 6, 1–25; exact for normally scattered estimates, and near it for
others by the central limit theorem), the percentile bootstrap interval beside
it for comparison, and the inverse-variance weighted mean and its standard
error over the estimates that have an error.

Why not the bootstrap's interval: resampling n values draws means from at most n
distinct values, and the percentile interval then reaches only as far as they
scatter (s√((n − 1)/n)/√n against the t interval's t₀.₉₇₅ s/√n).  For two
embryos it is [min, max] of their two estimates, which holds the truth half the
time.  Coverage of the two over 1000 simulated tables each (k ~ N(0.05, 0.13);
``scripts/check_interval_coverage.py``; documentation: "Inverse estimates",
"Summaries"):

==========  =====  =====  =====  =====  =====
n             2      3      5      8      14
==========  =====  =====  =====  =====  =====
bootstrap   0.521  0.770  0.822  0.887  0.915
Student t   0.954  0.954  0.944  0.952  0.949
==========  =====  =====  =====  =====  =====
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Iterator, Sequence

import numpy as np

__all__ = ["BOOTSTRAP", "SEED", "MIN_BOOTSTRAP", "Spread", "summarise", "resamples",
           "t_quantile", "check_bootstrap"]

#: Default bootstrap resamples and seed.
BOOTSTRAP, SEED = 2000, 0
#: Fewest resamples of a bootstrap interval: its 2.5 % and 97.5 % quantiles rest on
#: 0.025 × resamples of them each, at least one (one resample gave "95 %" intervals of zero
#: width).
MIN_BOOTSTRAP = 40
#: Most indices drawn at once (32 MB): memory stays bounded for any resamples × embryos.
RESAMPLE_CHUNK = 2**22


def resamples(rng: np.random.Generator, n: int, bootstrap: int) -> Iterator[np.ndarray]:
    """The bootstrap's resamples of n indices, in chunks of rows of at most RESAMPLE_CHUNK indices.

    The rows are those of ``rng.integers(0, n, size=(bootstrap, n))`` in the same order
    (the generator draws them one after another), so that results do not depend on the
    chunking; only the memory does (``--bootstrap 1000000`` of 1000 embryos held 16 GB).

    Yields
    ------
    ndarray of int, shape (m, n)
        The next m ≥ 1 resamples.
    """
    rows = max(1, RESAMPLE_CHUNK // max(n, 1))
    for start in range(0, int(bootstrap), rows):
        yield rng.integers(0, n, size=(min(rows, int(bootstrap) - start), n))


def check_bootstrap(bootstrap) -> int:
    """``bootstrap``: 0 (none) or at least :data:`MIN_BOOTSTRAP` resamples (ValueError)."""
    if isinstance(bootstrap, bool) or not isinstance(bootstrap, (int, np.integer)) \
            or bootstrap < 0:
        raise ValueError(f"bootstrap = {bootstrap!r} must be a non-negative integer")
    if 0 < bootstrap < MIN_BOOTSTRAP:
        raise ValueError(f"bootstrap = {bootstrap}: too few resamples to estimate the 2.5 % and "
                         f"97.5 % quantiles (at least {MIN_BOOTSTRAP}; 0 for none)")
    return int(bootstrap)


def t_quantile(n: int) -> float:
    """t₀.₉₇₅(n − 1): Student's 97.5 % quantile of n − 1 degrees of freedom (n ≥ 2)."""
    # scipy.special's inverse of Student's distribution function, which scipy.stats' t.ppf
    # calls: the same number without importing scipy.stats (a third of a second and more)
    from scipy.special import stdtrit

    return float(stdtrit(n - 1, 0.975))


@dataclass(frozen=True)
class Spread:
    """Mean, standard deviation and Student's t 95 % interval of the mean over embryos.

    ``bootstrap_interval``: the percentile bootstrap's, for comparison (it
    covers less with few embryos: module docstring).  ``weighted_mean`` and
    ``weighted_error``: inverse-variance weighted mean and its standard error
    over the ``weighted_n`` values that have an error (None when none has).
    """

    n: int
    mean: float | None
    std: float | None
    interval: tuple[float, float] | None
    weighted_mean: float | None = None
    weighted_error: float | None = None
    bootstrap_interval: tuple[float, float] | None = None
    weighted_n: int = 0

    def __str__(self) -> str:
        if not self.n:
            return "no estimates"
        iv = f" [{self.interval[0]:.3f}, {self.interval[1]:.3f}]" if self.interval else ""
        std = "" if self.std is None else f" +- {self.std:.3f}"
        return f"{self.mean:.3f}{std}{iv} (n = {self.n})"

    def to_dict(self) -> dict:
        """JSON-ready: n, mean, std, the 95 % intervals and the weighted mean (units of the
        estimates; null where there is none)."""
        def pair(iv):
            return None if iv is None else list(iv)
        return {"n": self.n, "mean": self.mean, "std": self.std,
                "interval_95": pair(self.interval), "interval_method": "student_t",
                "bootstrap_interval_95": pair(self.bootstrap_interval),
                "weighted_mean": self.weighted_mean, "weighted_error": self.weighted_error,
                "weighted_n": self.weighted_n}


def summarise(values: Sequence[float], errors: Sequence[float | None] | None = None,
              bootstrap: int = BOOTSTRAP, rng: np.random.Generator | None = None) -> Spread:
    """:class:`Spread` of ``values`` (std with n − 1; Student's t interval of the mean).

    Parameters
    ----------
    values : sequence of float, length n
        The estimates, finite.
    errors : sequence of float or None, length n, optional
        Their errors: the weighted mean is over those with one (not None, non-zero).
    bootstrap : int
        Resamples of the percentile bootstrap interval beside (0: none, else at least
        :data:`MIN_BOOTSTRAP`); no interval for n < 2.
    rng : numpy.random.Generator, optional
        Draws the resamples (default: seeded with :data:`SEED`).

    Returns
    -------
    Spread

    Raises
    ------
    ValueError
        For a value that is not finite (it would turn every statistic into NaN),
        or a bad ``bootstrap`` (:func:`check_bootstrap`).
    """
    bootstrap = check_bootstrap(bootstrap)
    x = np.asarray(values, dtype=float)
    n = x.size
    if n == 0:
        return Spread(0, None, None, None)
    if not np.all(np.isfinite(x)):        # a NaN would make every statistic NaN, silently
        i = int(np.flatnonzero(~np.isfinite(x))[0])
        raise ValueError(f"summarise: value {i} is {float(x[i])!r}, not a finite number")
    mean = float(x.mean())
    std = float(x.std(ddof=1)) if n >= 2 else None
    interval = boot = None
    if n >= 2:
        half = t_quantile(n) * std / math.sqrt(n)
        interval = (mean - half, mean + half)
    if bootstrap and n >= 2:
        rng = rng or np.random.default_rng(SEED)
        means = np.concatenate([x[idx].mean(axis=1) for idx in resamples(rng, n, bootstrap)])
        boot = tuple(float(v) for v in np.percentile(means, [2.5, 97.5]))
    wm = we = None
    errors = list(errors) if errors is not None and len(errors) == n else [None] * n
    has = [i for i, e in enumerate(errors) if e]
    if has:
        w = 1 / np.asarray([errors[i] for i in has], dtype=float) ** 2
        wm, we = float(np.dot(w, x[has]) / w.sum()), float(1 / math.sqrt(w.sum()))
    return Spread(n, mean, std, interval, wm, we, boot, len(has))
