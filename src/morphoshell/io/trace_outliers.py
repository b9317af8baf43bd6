"""Isolated outlier points of a trace (mis-clicks), found before alignment bins them.

A point clicked 0.3 R off a trace of ½-px noise (audit 13, F6) vanished in the
bins of :func:`morphoshell.io.trace_noise.bin_noisy`, so a plot showed nothing,
yet it lengthened the curve, shifted every resampled point along it and raised
a fit's E_fit fivefold.  :func:`find_outliers` names such points from the trace
alone:

* each point is compared with a quadratic fitted, across the curve, to its
  :data:`WINDOW` neighbours on either side (itself left out), in the frame of
  their principal axis (pointing the way their indices grow); its distance is
  the distance from the quadratic at the nearest place between its two nearest
  neighbours along the curve (a point in its place lies between them; an end
  point within a mean step beyond its neighbour);
* each distance is divided by the standard error of the prediction (the
  quadratic's own error at that point: larger at the ends, where it
  extrapolates) and by the trace's noise σ, the MAD of these ratios over all
  its points (1.4826 × median, Gaussian-consistent);
* points beyond :data:`OUTLIER_SIGMAS` σ are outliers; they are left out of
  their neighbours' fits and the test repeated until the set stops changing,
  so that a few outliers close together do not hide one another.

The threshold was measured (docs/benchmarks.md, "Traced midlines"): on the 60
shipped synthetic traces (½ px noise at 1.5 px spacing) no point lay beyond 4.0
σ, on 1440 noisy or pixel-rounded traces of the 12 generating midlines none
beyond 5.0; the audit's mis-clicks lie 55-63 σ off.  Traces too sparse to bin
(vertices of a segmented line, :attr:`~morphoshell.io.trace_noise.Binning.sparse`)
or of fewer than :data:`MIN_POINTS` points are not tested: their corners are not
noise; nor is a point found within half a step of where its neighbours put it
(:data:`_FLOOR`).  :func:`morphoshell.io.midlines.align` names the outliers of
an image trace in a warning, or leaves them out (``drop_outlier_points``).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["OUTLIER_SIGMAS", "WINDOW", "MIN_POINTS", "Outliers", "find_outliers"]

#: A point farther than this many noise σ from its neighbours' quadratic is an outlier.
OUTLIER_SIGMAS = 10.0
#: Neighbours on either side of a point that its quadratic is fitted to.
WINDOW = 3
#: Fewest points tested (fewer cannot tell a point's noise from the curve's shape).
MIN_POINTS = 12
#: Nor is a point within this many median steps of its neighbours' curve: the noise of a
#: noise-free trace is the quadratic's error, whose σ means nothing (clean traces of the
#: generating midlines lie within 0.03 steps).
_FLOOR = 0.5
#: Rounds of the test: outliers are left out of their neighbours' fits and it is repeated.
_ROUNDS = 5


@dataclass(frozen=True, eq=False)
class Outliers:
    """The outlier points of a trace (:func:`find_outliers`).

    Attributes
    ----------
    index : ndarray of int
        Positions of the outliers among the trace's points, increasing.
    distance : ndarray
        Each outlier's distance from its neighbours' curve, units of the points.
    sigma : float
        The trace's noise, from the scatter of all its points about their
        neighbours' curves (units of the points; nan when not tested).
    """

    index: np.ndarray
    distance: np.ndarray
    sigma: float

    def __len__(self) -> int:
        return len(self.index)


def find_outliers(points: np.ndarray, sigmas: float = OUTLIER_SIGMAS) -> Outliers:
    """Points farther than ``sigmas`` noise σ from the curve of their neighbours.

    Parameters
    ----------
    points : ndarray, shape (n, 2)
        A dense trace, consecutive points distinct (rules in the module docstring).
    sigmas : float
        The threshold in units of the trace's noise σ.

    Returns
    -------
    Outliers
        None found (and sigma nan) for fewer than :data:`MIN_POINTS` points.
    """
    points = np.asarray(points, dtype=float)
    none = np.zeros(0, dtype=int)
    if len(points) < max(MIN_POINTS, 2 * WINDOW + 1):
        return Outliers(none, np.zeros(0), float("nan"))
    floor = _FLOOR * float(np.median(np.hypot(*np.diff(points, axis=0).T)))
    out = np.zeros(len(points), dtype=bool)
    for _ in range(_ROUNDS):
        distance, error = _distances(points, out)
        ratio = distance / error
        sigma = 1.4826 * float(np.median(ratio[~out]))
        found = (ratio > sigmas * sigma) & (distance > floor)
        if np.array_equal(found, out):
            break
        out = found
    index = np.flatnonzero(out)
    return Outliers(index, distance[index], sigma)


def _windows(n: int) -> np.ndarray:
    """Indices (n, 2 WINDOW) of each point's neighbours, itself left out; shifted inward at
    the ends so that every point has 2 WINDOW of them."""
    offsets = np.r_[np.arange(-WINDOW, 0), np.arange(1, WINDOW + 1)]
    centre = np.clip(np.arange(n), WINDOW, n - 1 - WINDOW)
    idx = centre[:, None] + offsets
    # at the ends the point itself falls in its shifted window: put the centre there instead
    return np.where(idx == np.arange(n)[:, None], centre[:, None], idx)


def _distances(points: np.ndarray, out: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each point's distance from its neighbours' quadratic (the ``out`` ones left out of the
    fits) and the standard error of that prediction in units of the noise."""
    n = len(points)
    idx = _windows(n)
    weight = (~out[idx]).astype(float)
    weight[weight.sum(axis=1) < 3] = 1.0        # (too few kept to fit a quadratic: keep all)
    q = points[idx]                                                 # (n, 2W, 2)
    later = idx > np.arange(n)[:, None]
    # the direction along the curve: the neighbours' principal axis (their chord can vanish:
    # pixel-rounded points repeat), pointing the way their indices grow
    centre = _weighted_mean(q, weight)
    spread = np.einsum("nk,nki,nkj->nij", weight, q - centre[:, None], q - centre[:, None])
    along = np.linalg.eigh(spread)[1][..., -1]
    order = np.einsum("nk,nk,nkj,nj->n", weight, idx - idx.mean(axis=1, keepdims=True),
                      q - centre[:, None], along)
    along *= np.where(order < 0, -1.0, 1.0)[:, None]
    across = along[:, ::-1] * [-1.0, 1.0]
    x, y = (np.einsum("nkj,nj->nk", q - centre[:, None], e) for e in (along, across))
    x0, y0 = (np.einsum("nj,nj->n", points - centre, e) for e in (along, across))
    # where the point should lie along the curve: between its nearest kept neighbours before
    # and after (an end point within a mean spacing of the window beyond its nearest one)
    kept = np.where(weight > 0, x, np.nan)
    spacing = (np.nanmax(kept, axis=1) - np.nanmin(kept, axis=1)) / (2 * WINDOW - 1)
    before = np.where(weight * ~later > 0, x, -np.inf).max(axis=1)
    after = np.where(weight * later > 0, x, np.inf).min(axis=1)
    before = np.where(np.isfinite(before), before, after - spacing)
    after = np.where(np.isfinite(after), after, before + spacing)
    place = np.clip(x0, np.minimum(before, after), np.maximum(before, after))
    design = np.stack([np.ones_like(x), x, x * x], axis=-1)        # (n, 2W, 3)
    normal = np.einsum("nk,nki,nkj->nij", weight, design, design)
    # (pinv: the neighbours of pixel-rounded traces can repeat, leaving 2 distinct x)
    inverse = np.linalg.pinv(normal)
    coef = inverse @ np.einsum("nk,nki,nk->ni", weight, design, y)[..., None]
    at = np.stack([np.ones_like(place), place, place * place], axis=-1)
    offset = y0 - np.einsum("ni,ni->n", at, coef[..., 0])
    leverage = np.einsum("ni,nij,nj->n", at, inverse, at)
    return np.hypot(offset, x0 - place), np.sqrt(1.0 + leverage)


def _weighted_mean(q: np.ndarray, weight: np.ndarray) -> np.ndarray:
    """Weighted mean over axis 1 of q (n, k, 2); nan where the weights are all 0."""
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.einsum("nk,nkj->nj", weight, q) / weight.sum(axis=1)[:, None]
