"""Statistics of the estimates over embryos: mean, spread and a bootstrap interval.

Paper, main text "Quantitative estimates of the curvature mismatch during
*Volvox* invagination…", Fig. 2 J: the mean k over embryos with its spread.
Each summary is a :class:`Spread`: the mean, the standard deviation (n − 1),
the percentile bootstrap 95 % interval of the mean and, when every estimate
has an error, the inverse-variance weighted mean and its standard error.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Iterator, Sequence

import numpy as np

__all__ = ["BOOTSTRAP", "SEED", "Spread", "summarise", "resamples"]

#: Default bootstrap resamples and seed.
BOOTSTRAP, SEED = 2000, 0
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


@dataclass(frozen=True)
class Spread:
    """Mean, standard deviation and bootstrap 95 % interval of the mean over embryos.

    ``weighted_mean`` and ``weighted_error``: inverse-variance weighted mean
    and its standard error, when every value has an error.
    """

    n: int
    mean: float | None
    std: float | None
    interval: tuple[float, float] | None
    weighted_mean: float | None = None
    weighted_error: float | None = None

    def __str__(self) -> str:
        if not self.n:
            return "no estimates"
        iv = f" [{self.interval[0]:.3f}, {self.interval[1]:.3f}]" if self.interval else ""
        std = "" if self.std is None else f" +- {self.std:.3f}"
        return f"{self.mean:.3f}{std}{iv} (n = {self.n})"

    def to_dict(self) -> dict:
        """JSON-ready: n, mean, std and the 95 % interval (units of the estimates)."""
        out = {"n": self.n, "mean": self.mean, "std": self.std,
               "interval_95": None if self.interval is None else list(self.interval)}
        if self.weighted_mean is not None:
            out |= {"weighted_mean": self.weighted_mean, "weighted_error": self.weighted_error}
        return out


def summarise(values: Sequence[float], errors: Sequence[float | None] | None = None,
              bootstrap: int = BOOTSTRAP, rng: np.random.Generator | None = None) -> Spread:
    """:class:`Spread` of ``values`` (std with n − 1; percentile bootstrap of the mean).

    Parameters
    ----------
    values : sequence of float, length n
        The estimates, finite.
    errors : sequence of float, length n, optional
        Their errors: the weighted mean needs all of them, non-zero.
    bootstrap : int
        Resamples of the interval (0: none; none either for n < 2).
    rng : numpy.random.Generator, optional
        Draws the resamples (default: seeded with :data:`SEED`).

    Returns
    -------
    Spread

    Raises
    ------
    ValueError
        For a value that is not finite (it would turn every statistic into NaN).
    """
    x = np.asarray(values, dtype=float)
    n = x.size
    if n == 0:
        return Spread(0, None, None, None)
    if not np.all(np.isfinite(x)):        # a NaN would make every statistic NaN, silently
        i = int(np.flatnonzero(~np.isfinite(x))[0])
        raise ValueError(f"summarise: value {i} is {float(x[i])!r}, not a finite number")
    interval = None
    if bootstrap and n >= 2:
        rng = rng or np.random.default_rng(SEED)
        means = np.concatenate([x[idx].mean(axis=1) for idx in resamples(rng, n, bootstrap)])
        interval = tuple(float(v) for v in np.percentile(means, [2.5, 97.5]))
    wm = we = None
    if errors is not None and len(errors) == n and all(e for e in errors):
        w = 1 / np.asarray(errors, dtype=float) ** 2
        wm, we = float(np.dot(w, x) / w.sum()), float(1 / math.sqrt(w.sum()))
    return Spread(n, float(x.mean()), float(x.std(ddof=1)) if n >= 2 else None, interval, wm, we)
