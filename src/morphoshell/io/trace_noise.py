"""The noise of traced points: its estimate, and bins that keep it from lengthening the curve.

Noise σ on points at spacing h lengthens a curve through them by a fraction
~(σ/h)² (80 % for half-pixel noise on a one-pixel freehand trace), and
unevenly, which moves equally spaced points along the curve.  So alignment
(:func:`morphoshell.io.midlines.align`) first estimates σ (fourth differences
across the curve) and, if σ/h exceeds 1/20, averages the interior points in
bins of k consecutive ones, the least k that brings the ratio below 1/20
(noise σ/√k at spacing kh); the end points are kept.  A bin's mean lies inside
a curved line, by ½κ(k² − 1)h²/12, so each mean is moved back out by that
amount, with the curvature from its neighbouring means.  Clean traces are
left as they are.

Sparse points
-------------
The estimate of σ assumes that the points resolve the curve: that its own
fourth differences, O(h⁴) for a smooth curve, are small beside the noise's.
The vertices of a segmented line (a Fiji *Segmented Line* saved as XY
coordinates: 15-50 clicked points, 0.1-0.35 R apart) do not: at the folds of a
Volvox midline (radii 0.035-0.08 R on the synthetic inversion data) the
corners between them read as noise, and bins of their neighbours cut the
folds off.  Whatever the estimate, bins are therefore never longer than
:data:`MAX_BIN` (k h ≤ 0.15 R), and points more than half of it apart are
not binned at all: the midline between them is the cubic spline through
them, vertices kept.  On subsampled synthetic traces, bins made sparse
traces' midlines worse and noisy dense ones' better; with the bound, sparse
traces are read without bins and dense ones as before (docs/benchmarks.md,
"Traced midlines").
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["MAX_BIN", "NOISE_PER_STEP", "Binning", "bin_noisy", "noise_estimate"]

#: Largest ratio of point noise to point spacing that alignment leaves as it is.
NOISE_PER_STEP = 0.05
#: Longest bin, units of R: bins k points long span k h ≤ MAX_BIN (module docstring).
MAX_BIN = 0.15


@dataclass(frozen=True, eq=False)
class Binning:
    """Points as alignment takes them (:func:`bin_noisy`), and what was done to them.

    Attributes
    ----------
    points : ndarray, shape (m, 2)
        The points binned, or as given (m = n).
    n : int
        The number of points given.
    sigma : float
        Estimated noise per coordinate, units of the points (nan for fewer than
        12 points).
    spacing : float
        Spacing of the points along the curve: a quarter of the median chord
        of 4 steps (noise lengthens single steps), or the median step for
        fewer than 12 points.
    k : int
        Points per bin; 1 if not binned.
    wanted : int
        Points per bin that the noise alone asks for (k is less when bins of
        ``wanted`` would be longer than :data:`MAX_BIN`).
    """

    points: np.ndarray
    n: int
    sigma: float
    spacing: float
    k: int
    wanted: int

    @property
    def sparse(self) -> bool:
        """Points too far apart to bin (more than MAX_BIN/2): the curve is the spline through
        them."""
        return 2 * self.spacing > MAX_BIN

    def note(self, source: str) -> str | None:
        """What was done to the points, in one line naming ``source``; None if nothing."""
        if self.sparse:
            mean_step = float(np.sum(np.hypot(*np.diff(self.points, axis=0).T))) / (self.n - 1)
            return (f"{source}: {self.n} points {mean_step:.2g} R apart (vertices of a segmented "
                    f"line?): the midline between them is the cubic spline through them, "
                    f"not averaged in bins, which would cut the folds")
        if self.k <= 1:
            return None
        line = (f"{source}: noise ≈ {self.sigma:.2g} R at a point spacing of {self.spacing:.2g} R: "
                f"the {self.n - 2} points between the ends averaged in bins of {self.k} "
                f"({len(self.points)} points, each moved back onto the curve)")
        if self.wanted > self.k:
            line += (f"; bins of {self.wanted}, longer than {MAX_BIN:g} R, would cut the folds: "
                     f"noise ≈ {self.sigma / math.sqrt(self.k):.2g} R at a spacing of "
                     f"{self.k * self.spacing:.2g} R remains")
        return line


def bin_noisy(points: np.ndarray) -> Binning:
    """The points, or, if noisy for their spacing, their interior averaged in bins of k.

    σ is estimated (:func:`noise_estimate`) from the fourth differences across the curve (their
    median; Gaussian noise gives them variance 70 σ², a smooth curve O(h⁴));
    k is the least making σ/√k ≤ NOISE_PER_STEP·k·h (h the median step), and at most
    MAX_BIN over the spacing along the curve.
    The means are moved out by the curvature bias of averaging along a curve.

    Parameters
    ----------
    points : ndarray, shape (n, 2)
        A trace's points, units of R, consecutive ones distinct.

    Returns
    -------
    Binning
        ``points`` of shape (m, 2), m ≤ n.
    """
    n = len(points)
    step = float(np.median(np.hypot(*np.diff(points, axis=0).T))) if n > 1 else math.nan
    if n < 12:
        return Binning(points, n, math.nan, step, 1, 1)
    sigma, h = noise_estimate(points)
    wanted = math.ceil((sigma / (NOISE_PER_STEP * step)) ** (2 / 3))
    k = min(wanted, math.floor(MAX_BIN / h))
    bins = (n - 2) // max(k, 1)
    if k <= 1 or bins < 4:
        return Binning(points, n, sigma, h, 1, wanted)
    groups = np.array_split(points[1:-1], bins)
    out = np.vstack([points[:1], [b.mean(axis=0) for b in groups], points[-1:]])
    # A bin's mean lies inside the curve: by ½ c''(s̄) (k² − 1) h²/12, c'' = κ n the
    # curvature vector (Taylor: the positions s̄ + (i − (k − 1)/2) h average c(s̄) and
    # half the variance times c'').  At the folds of a Volvox midline that is as large as the
    # noise of an average of a few traces, and the same in every data set, so it would bias
    # the fitted curvatures (κ₁).  It is removed, with c'' from the three-point difference of
    # the means (which adds a little to their noise).
    c2 = _second_derivative(out)
    var = (np.array([len(b) for b in groups]) ** 2 - 1) * h ** 2 / 12
    out[1:-1] -= 0.5 * var[:, None] * c2
    return Binning(out, n, sigma, h, k, wanted)


def noise_estimate(points: np.ndarray) -> tuple[float, float]:
    """σ, the noise per coordinate, and h, the spacing along the curve, of at least 12 points.

    σ from the median of the fourth differences across the curve (Gaussian
    noise gives them variance 70 σ², a smooth curve O(h⁴)); h a quarter of the
    median chord of 4 steps (noise lengthens single steps, and with them the
    bins' lengths and their curvature correction).  In the points' units.
    """
    chord = points[4:] - points[:-4]
    length = np.linalg.norm(chord, axis=1)
    h = float(np.median(length)) / 4
    # A chord of 4 steps can vanish (a trace that retraces itself, a loop of 4 pixels): it has
    # no direction across, and its NaN made σ and the bins NaN ("cannot convert float NaN to
    # integer", audit 13 F5); the fourth differences there are left out.
    full = length > 0
    if not np.any(full):
        return 0.0, h
    across = chord[full, ::-1] * [1.0, -1.0] / length[full, None]
    wiggle = np.abs(np.sum(np.diff(points, n=4, axis=0)[full] * across, axis=1))
    return float(np.median(wiggle)) / (0.6745 * math.sqrt(70.0)), h


def _second_derivative(points: np.ndarray) -> np.ndarray:
    """c'' with respect to arclength at the interior points (m − 2, 2), from chords to their
    neighbours."""
    a, b = points[1:-1] - points[:-2], points[2:] - points[1:-1]
    d1, d2 = np.linalg.norm(a, axis=1)[:, None], np.linalg.norm(b, axis=1)[:, None]
    return 2 * (b / d2 - a / d1) / (d1 + d2)
