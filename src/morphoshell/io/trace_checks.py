"""Checks of traced curves and of the options that read them.

The trace readers (:mod:`morphoshell.io.traces`, :mod:`morphoshell.io.roi_sets`)
and the alignment (:mod:`morphoshell.io.midlines`) refuse what cannot be a
midline with :class:`MidlineError`, one line naming the file and the line,
point or option: an option that is not a choice or not positive, a scale
missing, points that are not one simple curve, that reach farther than a
midline can from its pole, or a midline that crosses the axis.  What passes
but may mislead a fit gets one line that :func:`morphoshell.io.midlines.align`
logs: halves of a whole section further apart than its noise leaves
(:func:`asymmetry_warning`), a gap in a dense trace bridged by the spline
(:func:`bridged_gap`).
"""
from __future__ import annotations

from typing import Sequence

import numpy as np

from .._runtime.validate import real
from .trace_noise import Binning, noise_estimate

__all__ = ["MidlineError", "image_scale", "check_choice", "check_positive", "one_curve",
           "check_count", "check_extent", "check_axis", "noise_hint", "asymmetry_warning",
           "bridged_gap", "check_scale", "check_not_short", "check_average", "check_open",
           "spread_warning", "SPREAD_RATIO", "HALF_LENGTHS", "MIN_HALF_LENGTH"]

#: Lengths (units of R) of a half midline beyond which a trace refused for its shape is refused
#: for its scale instead (:func:`check_scale`): a Volvox midline's half is about 2-4 R
#: (fitting.intrinsic_lengths).
HALF_LENGTHS = (1.0, 6.0)
#: A half midline shorter than this (units of R) is refused for its scale whatever its shape
#: (:func:`check_not_short`): noise only lengthens a polyline, so a trace this short is at the
#: wrong scale (an audit's radius R 10 times too large gave 0.26 R, which passed the shape's
#: tests and which a fit then refused as turning back on itself, by its noise).  A quarter of
#: a midline's 2 R at least: a trace 2-4 times too short is left to the fit's check, whose
#: message gives the factor (``fitting.check_midline``; 4 times: 0.64 R, "4.5× shorter").
#: Not for long traces: noise larger than the point spacing lengthens a right trace too.
MIN_HALF_LENGTH = 0.5

#: A step longer than _GAP_STEPS median steps and _GAP_FRACTION of the trace joins two curves.
_GAP_STEPS, _GAP_FRACTION = 10.0, 0.05
#: A crossing of two segments closes a loop; one that stays within _JITTER σ of where it
#: starts (σ the trace's noise, trace_noise.noise_estimate) is the noise's, not the curve's.
#: Loops of noise stay within about 10 σ whatever the point spacing, a curve that crosses
#: itself closes a loop as large as the curve: 20 σ lies between with room on both sides
#: (docs/benchmarks.md, "Traced midlines"; tests/io/test_traces.py).
_JITTER = 20.0
#: A trace doubles back at point k when the points J steps before and after it lie closer
#: than _REVERSAL times the path from one to the other through k: a hairpin of radius ρ with
#: arms of length λ gives about ρ/λ, a path retraced with noise σ about σ/λ.  J steps span
#: _REVERSAL_NOISE σ (at least 3 steps, at most 1/_REVERSAL_SPAN of the points).  On the
#: shipped synthetic traces and on 1200 traces of their generating midlines (whole and half,
#: 0-1 px of noise or pixel-rounded, points 0.2-40 px apart at R = 100-200 px) the least ratio
#: was 0.6 for dense traces and 0.14 for points 0.2-0.4 R apart (docs/benchmarks.md).
_REVERSAL, _REVERSAL_NOISE, _REVERSAL_SPAN = 0.05, 40.0, 20
#: How far (units of R) an aligned midline may stray to r < 0: noise near the pole, no more.
_AXIS_SLACK = 0.05
#: A whole section's halves are named in a warning when they lie farther from their mirror
#: average than _ASYMMETRY_SIGMAS times the noise of its binned points (σ/√k) and than
#: _ASYMMETRY_FLOOR (R); a segmented line's vertices (their σ the corners inflate), farther than
#: _ASYMMETRY_SPARSE h² (h their mean spacing, R) and the floor.  Clean traces lay within 0.6-2.5
#: times that noise (the 60 shipped ones; 384 of 6 shapes at 100-300 px per R, 0-1 % R noise,
#: rounded or not, at most 5.0: 3 px of noise at 300 px per R), 15-40 vertices of the shipped
#: traces within 0.35 h² (1080 placements); a rim traced 0.05 R short gives 0.012-0.032 R, one
#: 0.1 R short 0.022-0.05 R (docs/benchmarks.md, "Traced midlines").
_ASYMMETRY_SIGMAS, _ASYMMETRY_FLOOR, _ASYMMETRY_SPARSE = 5.0, 0.01, 0.5
#: A step of a dense trace longer than _BRIDGED_STEPS median steps is named in a note: those of
#: clean traces reach 2.7 (the shipped ones) to 4.0 (pixel-rounded, 0-3 px of noise); the
#: audit's gaps of 0.1 and 0.28 R, 9 and 26.
_BRIDGED_STEPS = 5.0
#: How far (units of R) a trace may reach from its first point: a Volvox midline lies within
#: about 2 R of its pole; farther is a trace in other units (at 1e300 the spline overflowed).
_MAX_EXTENT = 20.0

#: A whole section refused for its halves is named a closed trace (an outline) when its ends
#: lie within _CLOSED_STEPS median steps (a closed selection's XY coordinates), or when its
#: point at each arclength s < _FOLD_SPAN·L from one end lies within _FOLD_FRACTION·L of the
#: point at s from the other (L its length): an outline of the wall, outer and inner, comes
#: back along itself about a wall's thickness away (audit 25's, h = 0.15 R: at most 0.06·L,
#: the inner wall being shorter), the halves of a midline are mirror images, 2r apart (the 60
#: shipped traces and the audit's 5: at least 0.40·L); their ends lie 14 median steps apart
#: or more (of the binned points), a closed polygon's one step.
_CLOSED_STEPS, _FOLD_SPAN, _FOLD_FRACTION = 2.0, 0.4, 0.2

#: An average of image traces whose mean spread exceeds SPREAD_RATIO times its traces' noise
#: (the median of their estimates) is named in a warning (:func:`spread_warning`).  The spread
#: over the noise was 0.29-0.51 on the 12 shipped synthetic stages (white noise), 1.8 on
#: audit 25's 5 hand-like traces (1 px of slow wiggle besides), 4.7 and 12 with their radii
#: 2 % and 5 % off by turns, 19 with one radius for embryos of R = 35-42 µm, which no outlier
#: rule names (all traces are off).  Embryos of one stage differ, which the synthetic traces
#: do not: the warning asks, it does not refuse.
SPREAD_RATIO = 10.0


class MidlineError(ValueError):
    """A trace file or option that cannot be used; the message names the file and line or option."""


def image_scale(path, fmt: str, pixel_size_um, radius_um) -> float:
    """Units of R per pixel, from the two scale options (MidlineError naming a missing one).

    Parameters
    ----------
    path : str or Path
        The file, for messages.
    fmt : str
        Its format, for messages.
    pixel_size_um, radius_um : float or None
        µm per pixel and the embryo radius R in µm.

    Returns
    -------
    float
    """
    options = {"pixel_size_um": (pixel_size_um, "µm per pixel"),
               "radius_um": (radius_um, "the embryo radius R in µm")}
    missing = [f"{name} ({meaning})" for name, (value, meaning) in options.items() if value is None]
    if missing:
        raise MidlineError(f"{path}: {fmt} coordinates are in pixels: pass "
                           f"{' and '.join(missing)} to convert them to units of R")
    pixel_size, radius = (check_positive(name, value, f"{path}: ")
                          for name, (value, _) in options.items())
    return pixel_size / radius


def check_choice(value, choices: Sequence[str], what: str) -> str:
    """``value`` if it is one of ``choices``.

    Parameters
    ----------
    value
        The option given.
    choices : sequence of str
        The options allowed (:data:`FORMATS`, the sections, ...).
    what : str
        The option's name, for the message.

    Returns
    -------
    str
        ``value``.

    Raises
    ------
    MidlineError
        "unknown {what} ...; choose one of [...]".
    """
    if value not in choices:
        raise MidlineError(f"unknown {what} {value!r}; choose one of {list(choices)}")
    return value


def check_positive(name: str, value, prefix: str = "") -> float:
    """``value`` as a float if it is a finite positive real number.

    Parameters
    ----------
    name : str
        The option's name, for the message.
    value
        The option given.
    prefix : str
        Put before the message (the file, ``"{path}: "``), or nothing.

    Returns
    -------
    float

    Raises
    ------
    MidlineError
        Not a real number, not finite, or not positive.
    """
    try:
        value = real(name, value)
    except ValueError as exc:
        raise MidlineError(f"{prefix}{exc}") from None
    if value <= 0:
        raise MidlineError(f"{prefix}{name} = {value!r} must be positive")
    return value


def check_count(name: str, value, minimum: int) -> int:
    """``value`` as an int if it is an integer (not a bool) of at least ``minimum``.

    Raises
    ------
    MidlineError
        "{name} = {value!r} must be an integer >= {minimum}".
    """
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < minimum:
        raise MidlineError(f"{name} = {value!r} must be an integer >= {minimum}")
    return int(value)


def one_curve(path, points: np.ndarray, where: list[str], unit: str):
    """Points without repeats and their labels; MidlineError unless they make one simple curve."""
    with np.errstate(over="ignore"):     # (coordinates near 1e308: _refuse_overflow below)
        keep = np.r_[True, np.any(np.diff(points, axis=0) != 0, axis=1)][:len(points)]
    points, where = points[keep], [w for w, k in zip(where, keep) if k]
    if len(points) < 4:
        count = "1 distinct point" if len(points) == 1 else f"{len(points)} distinct points"
        raise MidlineError(f"{path}: {count}; a midline needs at least 4")
    with np.errstate(over="ignore"):
        steps = np.hypot(*np.diff(points, axis=0).T)
        length = float(steps.sum())
    if not np.isfinite(length):
        _refuse_overflow(path, points, where, steps, unit)
    median = float(np.median(steps))
    gaps = np.flatnonzero(steps > max(_GAP_STEPS * median, _GAP_FRACTION * length))
    if len(gaps):
        i = gaps[0]
        raise MidlineError(f"{path}: {where[i]} to {where[i + 1]}: a step of {steps[i]:.4g} {unit} "
                           f"({steps[i] / median:.0f} median steps): the trace is not one curve "
                           f"(two pieces, or points out of order)")
    with np.errstate(over="ignore", invalid="ignore"):     # (coordinates near 1e300)
        sigma, h = noise_estimate(points) if len(points) >= 12 else (0.0, median)
        turn = _first_reversal(points, sigma, h)
    if turn is not None:
        along = float(np.sum(steps[:turn]))
        raise MidlineError(f"{path}: the trace doubles back on itself at {where[turn]} "
                           f"(arclength {along:.4g} {unit} of {length:.4g}): trace the "
                           f"midline once, from pole to rim (or rim to rim through the pole)")
    with np.errstate(over="ignore", invalid="ignore"):
        crossing = _first_crossing(points, _GAP_STEPS * median, _JITTER * np.nan_to_num(sigma))
    if crossing is not None:
        i, j = crossing
        raise MidlineError(f"{path}: the segment {where[i]} to {where[i + 1]} crosses the segment "
                           f"{where[j]} to {where[j + 1]}: the trace intersects itself"
                           f"{noise_hint(sigma, h, unit)}")
    return points, where


def _refuse_overflow(path, points: np.ndarray, where: list[str], steps: np.ndarray,
                     unit: str) -> None:
    """MidlineError naming the point of the longest step farther from the others: the trace's
    length overflows (a coordinate near 1e308 left the doubling-back check to say so, with
    numpy's overflow warnings)."""
    i = int(np.argmax(steps))
    k = i + int(np.max(np.abs(points[i + 1])) > np.max(np.abs(points[i])))
    raise MidlineError(f"{path}: {where[k]}: ({points[k, 0]:.4g}, {points[k, 1]:.4g}) {unit}, a "
                       f"coordinate so far out that the trace's length overflows: a value out "
                       f"of place")


def noise_hint(sigma: float, spacing: float, unit: str) -> str:
    """A clause naming noise larger than the point spacing (it lengthens a trace, makes loops),
    to end the message of a trace refused for its length or loops; "" for less noise."""
    if not sigma > spacing:
        return ""
    return (f" (noise larger than the point spacing: ≈ {sigma:.2g} {unit} at {spacing:.2g} "
            f"{unit}: subsample or smooth the trace)")


def check_scale(source: str, binning: Binning, halves: int, also: str = "") -> None:
    """Before refusing a trace for its shape: MidlineError naming the scale instead if its
    halves are far longer or shorter than a Volvox midline's (:data:`HALF_LENGTHS`).

    At a wrong scale the shape's tests mislead (points of a trace 10 times too large lie
    0.1 R apart, too sparse to bin, and their noise makes the halves differ); a fit names a
    scale 1.5-2 times off precisely (``fitting.check_midline``), after alignment.  The length
    is that of the binned points: noise larger than the point spacing lengthens the raw
    polyline (0.3 px of noise at 0.19 px spacing tripled a 2.9 R half to 8.3 R), and where
    the bins leave such noise the message of a long trace names it rather than the scale.
    ``also`` names the refusal of its shape.
    """
    half = _half_length(binning, halves)
    if HALF_LENGTHS[0] <= half <= HALF_LENGTHS[1]:
        return
    k = binning.k
    noise = half > HALF_LENGTHS[1] and noise_hint(binning.sigma / np.sqrt(k), k * binning.spacing,
                                                  "R")
    raise MidlineError(f"{source}: {'its halves are' if halves == 2 else 'it is'} {half:.3g} R "
                       f"long, where a midline's half is about 2-4 R" + f" ({also})" * bool(also)
                       + (noise or ": check the pixel size and the radius R"))


def check_open(source: str, points: np.ndarray) -> None:
    """Before refusing a whole section for its halves: MidlineError naming a closed trace
    (rules at :data:`_CLOSED_STEPS`), whose halves are not those of a midline.

    Parameters
    ----------
    source : str
        The file, for the message.
    points : ndarray, shape (n, 2)
        The trace's points (binned, :func:`morphoshell.io.trace_noise.bin_noisy`), units of R.
    """
    steps = np.hypot(*np.diff(points, axis=0).T)
    along = np.r_[0.0, np.cumsum(steps)]
    length = along[-1]
    gap = float(np.hypot(*(points[-1] - points[0])))
    if gap <= _CLOSED_STEPS * np.median(steps):
        how = "its first and last points coincide"
    else:
        s = np.linspace(0.0, _FOLD_SPAN, 41) * length

        def at(arclength):
            return np.column_stack([np.interp(arclength, along, p) for p in points.T])
        fold = float(np.max(np.hypot(*(at(s) - at(length - s)).T)))
        if fold > _FOLD_FRACTION * length:
            return
        how = (f"its first and last points lie {gap:.2g} R apart and it comes back along "
               f"itself, within {fold:.2g} R")
    raise MidlineError(f"{source}: the trace is closed ({how}): trace the midline of the wall, "
                       f"from rim to rim, not the outline")


def check_not_short(source: str, binning: Binning, halves: int) -> None:
    """MidlineError naming the scale if the trace's halves are shorter than
    :data:`MIN_HALF_LENGTH`, whatever its shape."""
    if _half_length(binning, halves) < MIN_HALF_LENGTH:
        check_scale(source, binning, halves, "too short for any shell of the model")


def _half_length(binning: Binning, halves: int) -> float:
    """The length (units of R) of the binned points' polyline over the number of its halves."""
    return float(np.sum(np.hypot(*np.diff(binning.points, axis=0).T))) / halves


def _first_reversal(points: np.ndarray, sigma: float, h: float) -> int | None:
    """The point where the polyline turns back along itself (the deepest turn of the first run
    of them, rules at :data:`_REVERSAL`), or None."""
    n = len(points)
    span = _REVERSAL_NOISE * np.nan_to_num(sigma) / h if h > 0 else 0.0
    j = min(max(3, int(np.ceil(span))), max(n // _REVERSAL_SPAN, 3), (n - 1) // 2)
    if j < 1:
        return None
    a, c, b = points[:-2 * j], points[j:-j], points[2 * j:]
    path = np.hypot(*(c - a).T) + np.hypot(*(b - c).T)
    chord = np.hypot(*(b - a).T)
    back = chord < _REVERSAL * path
    if not np.any(back):
        return None
    first = int(np.argmax(back))
    run = first + int(np.argmin(back[first:])) if not np.all(back[first:]) else len(back)
    return j + first + int(np.argmin(chord[first:run] / path[first:run]))


def _first_crossing(points: np.ndarray, apart: float, loop: float,
                    chunk: int = 32) -> tuple[int, int] | None:
    """(i, j), i < j, of two segments of the polyline that cross, ``apart`` along it and closing
    a loop that reaches farther than ``loop`` from point i; i smallest.

    Segments closer than ``apart`` along the polyline may cross, and so may
    segments whose loop stays within ``loop``: noise at the scale of the point
    spacing makes such small loops.  Only chunks of consecutive segments
    whose bounding boxes overlap are compared, which makes the check about
    linear in the number of points for a curve.
    """
    a, d = points[:-1], np.diff(points, axis=0)
    along = np.r_[0.0, np.cumsum(np.hypot(*d.T))]             # polyline length at each point
    starts = np.arange(0, len(a), chunk)
    lo = np.minimum.reduceat(np.minimum(a, a + d), starts)
    hi = np.maximum.reduceat(np.maximum(a, a + d), starts)
    boxes_meet = np.all((lo[:, None] <= hi[None]) & (lo[None] <= hi[:, None]), axis=-1)

    def cross(u, v):
        return u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0]

    found = []
    for p, q in np.argwhere(np.triu(boxes_meet)):
        i = np.arange(starts[p], min(starts[p] + chunk, len(a)))[:, None]
        j = np.arange(starts[q], min(starts[q] + chunk, len(a)))[None, :]
        # ends of segment j on opposite sides of segment i, and vice versa (touching is not
        # crossing)
        hit = ((cross(d[i], a[j] - a[i]) * cross(d[i], a[j] + d[j] - a[i]) < 0)
               & (cross(d[j], a[i] - a[j]) * cross(d[j], a[i] + d[i] - a[j]) < 0)
               & (along[j] - along[i + 1] >= apart))
        found += [(int(i[k, 0]), int(j[0, m])) for k, m in np.argwhere(hit)]
    for i, j in sorted(found):
        if np.max(np.hypot(*(points[i:j + 2] - points[i]).T)) > loop:
            return i, j
    return None


def check_extent(source: str, points: np.ndarray, where, hint: str) -> None:
    """MidlineError if a point lies more than _MAX_EXTENT R from the first (wrong units); a
    reach beyond floats (coordinates of opposite signs near 1e308) is inf, refused too."""
    if not len(points):         # (nothing to measure; the count is one_curve's to refuse)
        return
    with np.errstate(over="ignore"):
        reach = np.hypot(*(points - points[0]).T)
    if reach.max() > _MAX_EXTENT:
        i = int(np.argmax(reach > _MAX_EXTENT))
        raise MidlineError(f"{source}: {where[i]}: {reach[i]:.4g} R from the first point; a "
                           f"midline lies within {_MAX_EXTENT:g} R of its pole ({hint})")


def check_average(source: str, n_traces: int, sources: Sequence[str], spread, where) -> None:
    """MidlineError unless a csv average's ``# n_traces`` (an integer) and ``spread`` column
    can be those of an average (:meth:`morphoshell.io.traces.Midline.to_csv`).

    n_traces at least 1 and, where the file lists more than one ``# source``, their number
    (to_csv writes one per trace averaged; one source with more traces is a loaded average
    written again, which names its own file); each spread (an rms distance of the traces'
    points from their mean, R) in [0, _MAX_EXTENT], as far as a midline reaches.  The profile
    intervals of a fit take σ² = mean(spread²)/n_traces: an audit's n_traces = 1e9 shrank
    them to zero width, a spread of 1e6 made them (-inf, inf), silently.
    """
    if n_traces < 1:
        raise MidlineError(f"{source}: comment 'n_traces = {n_traces}' must be at least 1 "
                           f"(the traces averaged)")
    if len(sources) > 1 and n_traces != len(sources):
        raise MidlineError(f"{source}: comment 'n_traces = {n_traces}' disagrees with its "
                           f"{len(sources)} 'source' comments, one per trace averaged")
    if spread is None:
        return
    bad = np.flatnonzero(~((spread >= 0) & (spread <= _MAX_EXTENT)))
    if len(bad):
        i = int(bad[0])
        raise MidlineError(f"{source}: {where[i]} (spread): {float(spread[i])!r} must lie in "
                           f"[0, {_MAX_EXTENT:g}] R: the traces' rms distance from their mean "
                           f"is not negative, nor farther than a midline reaches")


def check_axis(source: str, points: np.ndarray, where, hint: str = "") -> None:
    """Refuse a model-gauge midline that goes to r < 0 by more than noise.

    Parameters
    ----------
    source : str
        The file, for the message.
    points : ndarray, shape (n, 2)
        (r, z) in units of R.
    where : sequence of str, length n
        Where each point is in the file ("line 7"), for the message.
    hint : str
        Appended to the message: the likely cause.

    Raises
    ------
    MidlineError
        At the first point with r below −0.05 R (noise near the pole, no more).
    """
    bad = np.flatnonzero(points[:, 0] < -_AXIS_SLACK)
    if len(bad):
        raise MidlineError(f"{source}: {where[bad[0]]}: r = {points[bad[0], 0]:.4g} < 0: the "
                           f"midline crosses the axis (the model gauge has r >= 0){hint}")


def asymmetry_warning(source: str, asymmetry: float, binning: Binning) -> str | None:
    """One line naming a whole section whose halves lie farther apart than its noise leaves.

    Parameters
    ----------
    source : str
        The file, for the message.
    asymmetry : float
        Rms distance of the halves from their mirror average, units of R
        (:attr:`morphoshell.io.midlines.Alignment.asymmetry`).
    binning : Binning
        The points aligned (:func:`morphoshell.io.trace_noise.bin_noisy`), for their noise or,
        a segmented line's vertices, their spacing.

    Returns
    -------
    str or None
        The warning, or None within the limit (rules at :data:`_ASYMMETRY_SIGMAS`).
    """
    if binning.sparse:
        spacing = float(np.sum(np.hypot(*np.diff(binning.points, axis=0).T))) / (binning.n - 1)
        limit, what = _ASYMMETRY_SPARSE * spacing ** 2, "the spline between its vertices"
    else:
        limit, what = _ASYMMETRY_SIGMAS * binning.sigma / np.sqrt(binning.k), "its noise"
    limit = max(limit, _ASYMMETRY_FLOOR)
    if not asymmetry > limit:
        return None
    # (audit 15 F3: rims 0.05-0.3 R short gave 0.017-0.047 R here, midlines 0.013-0.087 R off)
    return (f"{source}: the halves of this whole section differ by {asymmetry:.2g} R rms from "
            f"their mirror average, more than {what} leaves ({limit:.2g} R): a rim traced short "
            f"moves the pole along the curve and the midline, their average, by 1-2 times that "
            f"(a rim 0.1 R short: 0.03 R), which a fit cannot tell; check that both rims are "
            f"traced to their ends")


def bridged_gap(source: str, points: np.ndarray, where, scale: float,
                skip=()) -> str | None:
    """One line naming the longest step of a dense trace if it is a gap the spline bridges.

    Parameters
    ----------
    source : str
        The file, for the message.
    points : ndarray, shape (n, 2)
        The trace's points, units of R.
    where : sequence of str, length n
        Where each point is in the file ("line 7").
    scale : float
        Units of R per pixel.
    skip : sequence of int
        Points whose steps are not gaps (outliers named already).

    Returns
    -------
    str or None
        The note, or None when no step exceeds :data:`_BRIDGED_STEPS` median steps (a
        step beyond :func:`one_curve`'s limit was refused when the trace was read).
    """
    steps = np.hypot(*np.diff(points, axis=0).T)
    median = float(np.median(steps))
    ratio = steps / median
    for i in skip:                       # (the steps to and from the point)
        ratio[max(i - 1, 0):i + 1] = 0.0
    i = int(np.argmax(ratio))
    if not ratio[i] > _BRIDGED_STEPS:
        return None
    return (f"{source}: {where[i]} to {where[i + 1]}: a gap of {steps[i]:.2g} R "
            f"({steps[i] / scale:.3g} px, {ratio[i]:.0f} median steps) bridged by the spline "
            f"through the points: the midline there is the spline's, not the trace's")


def spread_warning(spread: float, noises, what: str = "the traces") -> str | None:
    """One line naming an average whose traces differ far more than their noise
    (:data:`SPREAD_RATIO`): radii or pixel sizes off, or traces of different stages.

    Parameters
    ----------
    spread : float
        The average's mean spread, units of R (:attr:`morphoshell.io.traces.Midline.spread`).
    noises : sequence of float
        Each trace's noise, units of R (:attr:`morphoshell.io.traces.Midline.noise`); nan
        where unknown.
    what : str
        The traces, for the message.

    Returns
    -------
    str or None
        The warning, or None within the limit or without two noise estimates.
    """
    known = [float(s) for s in noises if np.isfinite(s) and s > 0]
    if len(known) < 2:
        return None
    noise = float(np.median(known))
    ratio = spread / noise
    if not ratio > SPREAD_RATIO:
        return None
    return (f"{what} differ by more than tracing does: their mean spread {spread:.2g} R is "
            f"{ratio:.0f} times their noise ({noise:.2g} R, the median of their estimates); "
            f"check each trace's radius_um and pixel_size_um (radii 5 % off by turns gave 12 "
            f"times, one radius for embryos of R = 35-42 µm 19) and that they are of one stage")
