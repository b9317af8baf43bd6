"""Midline geometry: traces brought to the model gauge, resampled and averaged.

A traced curve read from a file (:func:`morphoshell.io.traces.read_trace`,
formats in :mod:`morphoshell.io.traces`) has an arbitrary rotation and
offset, points unevenly spaced along it and pixel noise.  A fit needs a
*half midline in the model gauge*: points (r_i, z_i) equally spaced in
arclength from the posterior pole, at the origin, to the rim; the axis of
symmetry along z, z growing toward the anterior, r ≥ 0; lengths in units of
the embryo radius R.  The paper fits the average midline of each stage at
N_fit = 100 such points (SI Appendix, "Fitting methods and details").  Three
functions get there:

``align``         a trace → :class:`Alignment` (half midline in the model gauge);
``resample``      points → N points equally spaced in arclength, ends included
                  (:mod:`morphoshell.io.resampling`);
``average``       midlines of one stage → a
                  :class:`~morphoshell.io.traces.Midline` with a pointwise spread.

:func:`load_midline` chains :func:`morphoshell.io.traces.read_trace`,
:func:`align` and :func:`resample`, except for a midline the package wrote
(:meth:`~morphoshell.io.traces.Midline.to_csv`, recognised by its
``# n_traces`` comment): its rows are already equally spaced in arclength and
are read at their fractions of it (:func:`~morphoshell.io.resampling.at_fractions`),
so that it reads back as written.  This module lives in ``io``, not with the
fits, because :func:`load_midline` reads a file; it imports the file side
(:mod:`morphoshell.io.traces`), never the reverse.  Bad traces and options raise
:class:`~morphoshell.io.traces.MidlineError`, as the file side does.

Alignment
---------
*csv* traces are already in the model gauge and are taken as they are (not
re-aligned; a midline's rows not resampled either, :func:`load_midline`).
Image traces have an arbitrary rotation and offset; ``section`` says what was
traced:

``"whole"``  rim to rim through the posterior pole.  The pole is taken at
             mid-arclength (a section traced from rim to rim has halves of
             equal length: both rims must be traced to their ends, or the
             pole moves), and the axis is the line that best maps the point
             at arclength L/2 + σ onto the mirror image of the one at L/2 − σ,
             0 < σ ≤ L/2: least squares of the mismatch across the curve,
             with the mismatch along it weighted 1/100 (noise makes the
             arclengths of the halves fluctuate, shifting partners along the
             curve, which says nothing about the axis; the small weight keeps
             a circular arc, symmetric about any diameter, determined by where
             its rims are); then again with a soft-L1 loss scaled to the
             residuals, so that a few stray points do not pull the axis.
             The pole is where the axis crosses the curve; the two halves,
             each from the pole to its rim, are mirrored onto r ≥ 0 and
             averaged at equal fractions of their lengths.  The pole's height
             along the axis is then that of a least-squares fit
             z = z₀ + a s² + b s⁴ of the average within 0.3 R of arclength s
             from it, not that of the one noisy point where the axis crosses
             the trace: that point's error would shift the whole midline
             along z.  A section whose halves lie farther than
             ``max_asymmetry`` (rms, units of R) from their mirror average is
             refused; farther than its noise leaves, named in a warning
             (:func:`~morphoshell.io.trace_checks.asymmetry_warning`).
``"half"``   pole to rim, the pole first.  A regular pole of an axisymmetric
             surface has its tangent perpendicular to the axis, and the
             midline is even about it: in the frame of the axis,
             z = t + a r² + b r⁴ near the pole.  That is fitted, by least
             squares across the curve, to the points within 0.4 R of
             arclength of the first (inside the posterior region, which
             reaches s₁ ≈ 0.5-0.75 R; at least 6 points), for the axis's
             direction and the pole's height t; the pole's place along the
             curve is the first point (an error δ there tilts the axis by
             only δκ, κ ≈ 1/R).  The spline's tangent at the first point,
             the estimate before, rested on the first few points: noise σ at
             point spacing h tilted it by ~σ/h (the midline 0.05-0.17 R rms
             off for 0.05-0.5 px of noise).  The fit's error is still that of
             one side of the pole only: its standard error (from the
             residuals, their noise at least the trace's) moves the midline
             by that angle times the points' rms distance from the pole, and
             a half section where that exceeds 0.01 R is refused, naming the
             error (on synthetic half sections from 0.1-0.2 px of noise at
             R = 140-200 px); of 420 seeded ones (0.02-1 px of noise), the
             195 accepted lay within 0.021 R rms of the truth, 13 beyond
             0.01 R.  Clean, the fit's model errs by 1.5e-4 R
             rms on the Volvox example's equilibrium and 2.4e-3 R on the
             tests' bulged reference shape.  Trace whole sections where you
             can: their axis rests on both halves (0.15° for ½ px of noise).
             A half section traced rim first is aligned from its last point
             when, aligned from its first, it crosses the axis and from its
             last it does not (a note says so); otherwise its ends cannot be
             told apart by shape (a circular arc reads the same from either
             end; the local shape near an end, its fit's residual or its
             curvature's slope, told a rim from a pole on clean traces only,
             and not on the bulged reference shape) and it is taken as given
             (its note says that the first point was taken as the pole).
``"auto"``   csv → half; image formats → whole.  Shape alone cannot tell: a
             circular arc traced from pole to rim is mirror-symmetric about
             its middle exactly as a whole section of a cup is, so a half
             image trace must be declared (a non-symmetric one passed as
             whole fails the asymmetry check with a message that says so).

The axis points toward the anterior, taken to be the side of the pole where
the rims are (z_rim > 0, true until late inversion); ``flip=True`` reverses it.

Noise and sparse points
-----------------------
Alignment works on the points of :func:`morphoshell.io.trace_noise.bin_noisy`:
noisy dense points averaged in bins (noise lengthens a curve through them,
unevenly), points of a segmented line (more than 0.075 R apart) taken as
they are, the curve between them the spline through them.  What alignment
did to a trace's points is logged at INFO on this module's logger (the
command line prints it as a note).  A trace of fewer points than a midline
needs to hold its shape is refused: a whole section needs
:data:`MIN_POINTS` ``["whole"]`` = 15, a half section 8: with fewer vertices a
midline lies several times farther from the dense trace's and many are refused
as asymmetric (docs/benchmarks.md, "Traced midlines").  What noise still leaves along the curve,
:func:`average` removes by resampling the mean of the traces in its own
arclength.
"""
from __future__ import annotations

import logging
import math
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Sequence

import numpy as np

from .._runtime.validate import short
from .resampling import Curve, at_fractions, resample
from .roi_sets import is_roi_set, read_set_traces
from .trace_checks import (MidlineError, asymmetry_warning, bridged_gap, check_axis, check_choice,
                           check_count, check_not_short, check_open, check_positive, check_scale)
from .trace_noise import Binning, bin_noisy
from .trace_outliers import OUTLIER_SIGMAS, find_outliers
from .traces import Midline, Trace, read_trace

__all__ = ["SECTIONS", "MIN_POINTS", "Alignment", "align", "resample", "load_midline",
           "load_midlines", "resample_spread", "average", "trace_distances"]

#: What a trace covers (see the module docstring).
SECTIONS = ("auto", "whole", "half")
#: Samples of σ in the mirror fit of a whole section, and the weight of the mismatch along the
#: curve relative to across it (module docstring).
_MIRROR_SAMPLES, _ALONG_WEIGHT = 200, 0.01
#: Arclength (units of R) from the pole of a whole section over which its height is fitted,
#: and the even powers of arclength fitted there: 1, s², s⁴ (:func:`_pole_height`).
_POLE_WINDOW, _POLE_TERMS = 0.3, 3
#: Fewest distinct points of a trace that can hold a midline's shape, by section (module
#: docstring).
MIN_POINTS = {"whole": 15, "half": 8}
#: A half section's axis is fitted to its points within _HALF_WINDOW (units of R) of the pole,
#: inside the posterior region (to s₁ ≈ 0.5-0.75 R), at least _HALF_POINTS of them; it is
#: refused when one standard error of the axis's direction moves the midline by more than
#: _MAX_AXIS_ERROR rms (module docstring).
_HALF_WINDOW, _HALF_POINTS, _MAX_AXIS_ERROR = 0.4, 6, 0.01

log = logging.getLogger(__name__)


@dataclass(frozen=True, eq=False)
class Alignment:
    """A trace brought to the model gauge (:func:`align`).

    Attributes
    ----------
    points : ndarray, shape (m, 2)
        The half midline (r, z), units of R, pole first at the origin; for a
        whole section the mirror average of its halves.
    section : str
        "whole" or "half".
    axis_angle : float
        Direction of +z (anterior) in the trace's frame (y up), radians
        counter-clockwise from +y; nan for csv.
    pole : ndarray, shape (2,)
        The pole in the trace's frame (units of R).
    asymmetry : float
        Rms distance of each half from the mirror average (units of R); 0
        for a half section.
    noise : float
        An image trace's noise per coordinate (units of R,
        :func:`~morphoshell.io.trace_noise.noise_estimate`); nan for csv, for
        fewer than 12 points, and for the vertices of a segmented line, whose
        corners the estimate reads as noise.
    """

    points: np.ndarray
    section: str
    axis_angle: float
    pole: np.ndarray
    asymmetry: float
    noise: float = math.nan



# --------------------------------------------------------------------------- alignment

def align(trace: Trace, section: str = "auto", *, flip: bool = False,
          max_asymmetry: float = 0.05, drop_outlier_points: bool = False) -> Alignment:
    """Bring a trace to the model gauge (rules in the module docstring).

    Parameters
    ----------
    trace : Trace
    section : {"auto", "whole", "half"}
    flip : bool
        Point +z the other way (when the rims are posterior of the pole).
    max_asymmetry : float
        Largest rms distance (units of R) of the halves of a whole section
        from their mirror average.
    drop_outlier_points : bool
        Leave out an image trace's isolated outlier points
        (:mod:`morphoshell.io.trace_outliers`; a note names them); without it
        they are kept and a warning names them.

    Returns
    -------
    Alignment
        ``points`` of shape (m, 2): the trace's own points for a half
        section (binned if noisy, :mod:`morphoshell.io.trace_noise`), the
        first moved onto the fitted pole; max(1024, 2n) mirror-averaged
        points for a whole one.

    Raises
    ------
    MidlineError
        Fewer points than :data:`MIN_POINTS`; a whole section whose halves
        differ by more than ``max_asymmetry``; a half section whose axis is
        uncertain (or with fewer than 6 points within 0.4 R of its pole);
        either named for its scale instead when its halves are far from a
        midline's 2-4 R, and a midline far shorter refused for its scale
        whatever its shape (:func:`~morphoshell.io.trace_checks.check_not_short`);
        a midline that crosses the axis (a half section:
        from either end; from its first only, it is taken from its last,
        traced rim first).
    """
    section = check_choice(section, SECTIONS, "section")
    max_asymmetry = check_positive("max_asymmetry", max_asymmetry)
    if trace.format == "csv":
        if section == "whole" or flip:
            raise MidlineError(f"{trace.source}: csv traces are half midlines in the model gauge: "
                               f"section='whole' and flip do not apply")
        _check_count(trace, "half")
        return Alignment(trace.points, "half", math.nan, trace.points[0], 0.0)
    kind = "half" if section == "half" else "whole"
    _check_count(trace, kind)
    binning, outliers = bin_noisy(trace.points), ()
    if not binning.sparse:
        trace, outliers = _outlier_points(trace, drop_outlier_points)
        if len(trace.points) < binning.n:
            _check_count(trace, kind)
            binning = bin_noisy(trace.points)
    check_not_short(trace.source, binning, 1 if kind == "half" else 2)
    warning = None
    if kind == "half":
        pole, e_r, e_z, points, axis_note = _half_section(trace, binning, flip)
        asymmetry = 0.0
    else:
        pole, e_r, e_z, points, asymmetry = _whole(Curve.through(binning.points),
                                                   len(binning.points), flip)
        if asymmetry > max_asymmetry:
            check_open(trace.source, binning.points)
            check_scale(trace.source, binning, 2, f"its halves differ by {asymmetry:.3g} R rms")
            raise MidlineError(f"{trace.source}: the halves of this whole section differ by "
                               f"{asymmetry:.3g} R rms from their mirror average (max_asymmetry = "
                               f"{max_asymmetry:g}): the pole is taken at half the trace's "
                               f"length, so both rims must be traced to their ends (one traced "
                               f"short moves the pole); only a trace that starts at the pole is a "
                               f"half section (section='half')")
        where = [f"{f:.0%} of the way from the pole" for f in np.linspace(0, 1, len(points))]
        axis_note = None
        check_axis(trace.source, points, where)
        warning = asymmetry_warning(trace.source, asymmetry, binning)
    gap = None if binning.sparse else bridged_gap(trace.source, trace.points, trace.where,
                                                  trace.scale, outliers)
    for note in (binning.note(trace.source), gap, axis_note):
        if note:
            log.info(note)
    if warning:
        log.warning(warning)
    return Alignment(points, kind, math.atan2(-e_z[0], e_z[1]), pole, asymmetry,
                     math.nan if binning.sparse else binning.sigma)


def _outlier_points(trace: Trace, drop: bool) -> tuple[Trace, np.ndarray]:
    """The trace, its outlier points named in a warning, or left out (``drop``) with a note;
    and the positions of those kept."""
    found = find_outliers(trace.points)
    if not len(found):
        return trace, found.index
    listed = ", ".join(f"{trace.where[i]} ({d:.2g} R = {d / trace.scale:.3g} px)"
                       for i, d in zip(found.index, found.distance))
    what = (f"{trace.source}: {len(found)} point{'s' * (len(found) > 1)} far off the curve of "
            f"{'their' if len(found) > 1 else 'its'} neighbours (beyond {OUTLIER_SIGMAS:g} times "
            f"the trace's noise {found.sigma:.2g} R; mis-clicks?): {listed}")
    if not drop:
        log.warning(f"{what}; kept: they lengthen the midline and bias a fit; leave them out "
                    f"with drop_outlier_points=True, or correct the trace")
        return trace, found.index
    log.info(f"{what}; left out (drop_outlier_points=True)")
    keep = np.ones(len(trace.points), dtype=bool)
    keep[found.index] = False
    return replace(trace, points=trace.points[keep],
                   where=tuple(w for w, k in zip(trace.where, keep) if k)), found.index[:0]


def _check_count(trace: Trace, kind: str) -> None:
    """MidlineError if the trace has fewer points than :data:`MIN_POINTS` asks for its section."""
    if len(trace.points) < MIN_POINTS[kind]:
        raise MidlineError(f"{trace.source}: {len(trace.points)} distinct points; a {kind} "
                           f"section needs at least {MIN_POINTS[kind]} to hold the shape of a "
                           f"midline (a half section {MIN_POINTS['half']}, a whole one "
                           f"{MIN_POINTS['whole']}): trace it with more points, one at every fold")


def _half_section(trace: Trace, binning: Binning, flip: bool):
    """Pole, e_r, e_z, the points in the model gauge and a note (the end taken as the pole) of a
    half section, taken from its last point if it was traced rim first.

    A half section runs from the pole, on the axis, to a free rim.  Aligned
    from its first point, a trace that starts at the rim can cross the axis
    fitted there; if it does and, aligned from its last point, it does not,
    the last point is its pole (a note says so), as a whole section is read
    in either direction.  Where neither end crosses, the ends cannot be told
    apart by the trace (a circular arc is the same from either end) and it
    is taken as given.
    """
    crossing = _half_checked(trace, binning, flip)
    if not isinstance(crossing, MidlineError):
        pole, e_r, e_z, points, what = crossing
        return pole, e_r, e_z, points, (
            f"{trace.source}: a half section, its first point taken as the pole (the midline "
            f"does not cross the axis from it, and the ends cannot be told apart by shape: one "
            f"listed rim first is read upside down): {what}")
    back = replace(trace, points=trace.points[::-1], where=trace.where[::-1])
    other = _half_checked(back, replace(binning, points=binning.points[::-1]), flip)
    if isinstance(other, MidlineError):
        why = str(other).removeprefix(f"{trace.source}: ")
        raise MidlineError(f"{crossing}; traced rim first? reversed, it is refused too: "
                           f"{why}") from None
    pole, e_r, e_z, points, what = other
    where = str(crossing).removeprefix(f"{trace.source}: ").partition(": the midline")[0]
    return pole, e_r, e_z, points, (
        f"{trace.source}: traced rim first? from its first point the midline crosses the axis "
        f"({where}), from its last it does not: the last point taken as the pole; a half "
        f"section: {what}")


def _half_checked(trace: Trace, binning: Binning, flip: bool):
    """:func:`_half` of the trace as it runs, or the MidlineError of a midline that crosses the
    axis from its first point (other refusals raised, named for the scale if it is off)."""
    try:
        pole, e_r, e_z, points, axis_note = _half(trace.source, binning, flip)
    except MidlineError as exc:
        check_scale(trace.source, binning, 1, "its axis is uncertain")
        raise exc from None
    where = trace.where if binning.k == 1 else [
        f"point {k + 1} after binning" for k in range(len(points))]
    try:
        check_axis(trace.source, points, where)
    except MidlineError as exc:
        return exc
    return pole, e_r, e_z, points, axis_note


def _half(source: str, binning: Binning, flip: bool):
    """Pole, e_r, e_z, the points in the model gauge and its axis's error in words, of a half
    section (refused if its axis is uncertain beyond :data:`_MAX_AXIS_ERROR`)."""
    points = binning.points
    # the noise of the points fitted is at least the trace's (a median over all its points, a
    # steadier estimate than the residuals of the few near the pole), unless the points are
    # too sparse for that estimate (trace_noise)
    floor = 0.0 if binning.sparse or binning.n < 12 else binning.sigma / math.sqrt(binning.k)
    pole, e_r, e_z, error, noise, used = _half_axis(source, points, floor)
    e_z = _anterior(e_z, pole, [points[-1]], flip)
    gauge = _gauge(points, pole, e_r, e_z)
    gauge[0] = 0.0                  # the first point, a noisy pole, at the fitted one
    moved = error * float(np.sqrt(np.mean(np.sum(gauge ** 2, axis=1))))
    what = (f"fitted to its {used} points within {_HALF_WINDOW:g} R of the pole (noise ≈ "
            f"{noise:.2g} R), the axis's direction has a standard error of "
            f"{math.degrees(error):.2g}°, which moves the midline by {moved:.2g} R rms")
    if moved > _MAX_AXIS_ERROR:
        raise MidlineError(f"{source}: the axis of this half section is uncertain: {what} (more "
                           f"than {_MAX_AXIS_ERROR:g} R): trace the whole section, rim to rim "
                           f"through the pole (section='whole'), whose axis rests on both halves")
    return pole, e_r, e_z, gauge, what


def _half_axis(source: str, points: np.ndarray, floor: float):
    """Pole, e_r, e_z (sign free), standard error of the axis's direction (radians), noise and
    points used, from a least-squares fit z = t + a r² + b r⁴ near the first point; the noise
    is that of the fit's residuals, at least ``floor``.

    The pole is the first point moved by t along the axis: its position along
    the curve rests on where the trace starts (an error δ there tilts the axis
    by δκ, κ ≈ 1/R near the pole), its height on the fit (module docstring).
    """
    s = np.r_[0.0, np.cumsum(np.hypot(*np.diff(points, axis=0).T))]
    near = points[s <= _HALF_WINDOW] - points[0]
    if len(near) < _HALF_POINTS:
        raise MidlineError(f"{source}: {len(near)} points within {_HALF_WINDOW:g} R of the pole; "
                           f"the axis of a half section is fitted to the points there and needs "
                           f"{_HALF_POINTS}: trace more points near the pole, or the whole section "
                           f"(section='whole')")
    # start: the principal direction of the points, toward the last of them
    direction = np.linalg.svd(near - near.mean(axis=0))[2][0]
    direction *= 1.0 if direction @ near[-1] >= 0 else -1.0

    def misfit(p):
        e_r = np.array([math.cos(p[0]), math.sin(p[0])])
        r, z = near @ e_r, near @ [-e_r[1], e_r[0]]
        return z - (p[1] + p[2] * r ** 2 + p[3] * r ** 4)

    from scipy.optimize import least_squares
    fit = least_squares(misfit, [math.atan2(direction[1], direction[0]), 0.0, 0.0, 0.0],
                        xtol=1e-15, ftol=1e-15, gtol=1e-15)
    noise = max(math.sqrt(2 * fit.cost / max(len(near) - 4, 1)), floor)
    covariance = np.linalg.pinv(fit.jac.T @ fit.jac) * noise ** 2
    angle, t = fit.x[:2]
    e_r = np.array([math.cos(angle), math.sin(angle)])
    e_z = np.array([-e_r[1], e_r[0]])
    return (points[0] + t * e_z, e_r, e_z, math.sqrt(covariance[0, 0]), noise, len(near))


def _gauge(points, pole, e_r, e_z) -> np.ndarray:
    """(r, z) of points of the trace's frame, for the pole and axes given."""
    return (points - pole) @ np.column_stack([e_r, e_z])


def _anterior(e_z, pole, rims, flip: bool) -> np.ndarray:
    """±e_z, pointing to the side of the pole where the rims are (or away, if ``flip``)."""
    sign = 1.0 if np.mean([(rim - pole) @ e_z for rim in rims]) >= 0 else -1.0
    return -sign * e_z if flip else sign * e_z


def _whole(curve: Curve, n_points: int, flip: bool):
    """Pole, e_r, e_z, mirror-averaged half (m, 2) and asymmetry of a whole section."""
    length = curve.length
    sigma = length / 2 * np.arange(1, _MIRROR_SAMPLES + 1) / _MIRROR_SAMPLES
    right, left = curve(length / 2 + sigma), curve(length / 2 - sigma)
    # directions along and across the left half, from chords long enough to average noise out
    chord = curve(length / 2 - sigma + length / 30) - curve(length / 2 - sigma - length / 30)
    along = chord / np.linalg.norm(chord, axis=1, keepdims=True)
    across = along @ [[0.0, 1.0], [-1.0, 0.0]]

    def mismatch(p):      # reflection of the right half in the line n·X = c, minus the left half
        normal = np.array([math.cos(p[0]), math.sin(p[0])])
        d = right - 2 * (right @ normal - p[1])[:, None] * normal - left
        return np.r_[np.sum(d * across, axis=1),
                     _ALONG_WEIGHT * np.sum(d * along, axis=1)]

    from scipy.optimize import least_squares
    t = curve(length / 2, tangent=True)       # the axis is normal to the curve at the pole
    fit = least_squares(mismatch, [math.atan2(t[1], t[0]), t @ curve(length / 2)],
                        xtol=1e-15, ftol=1e-15, gtol=1e-15)
    scale = 1.4826 * float(np.median(np.abs(fit.fun)))      # MAD: the noise of the points
    if scale > 1e-9 * length:
        fit = least_squares(mismatch, fit.x, loss="soft_l1", f_scale=scale,
                            xtol=1e-15, ftol=1e-15, gtol=1e-15)
    normal, c = np.array([math.cos(fit.x[0]), math.sin(fit.x[0])]), fit.x[1]
    s_pole = _crossing(curve, normal, c)
    pole = curve(s_pole)
    fraction = np.linspace(0.0, 1.0, max(1024, 2 * n_points))
    right, left = curve(s_pole + fraction * (length - s_pole)), curve(s_pole - fraction * s_pole)
    e_r = normal if np.mean((right - pole) @ normal) >= 0 else -normal
    e_z = _anterior(np.array([-normal[1], normal[0]]), pole, [right[-1], left[-1]], flip)
    right, left = _gauge(right, pole, e_r, e_z), _gauge(left, pole, -e_r, e_z)    # left mirrored
    asymmetry = float(np.sqrt(np.mean(np.sum((right - left) ** 2, axis=1)))) / 2
    half = (right + left) / 2
    z0 = _pole_height(half)
    half[:, 1] -= z0
    half[0] = 0.0
    return pole + z0 * e_z, e_r, e_z, half, asymmetry


def _pole_height(half: np.ndarray) -> float:
    """Height z₀ of the pole of a mirror-averaged half (m, 2): least squares of
    z = z₀ + a s² + b s⁴.

    Over the points within :data:`_POLE_WINDOW` of arclength s from the pole
    (z is even in s through a regular pole).  The crossing of the axis with
    the trace is one point of the noisy curve, and its height error shifts
    the whole midline along z, which a fit, its pole pinned at the origin,
    can only absorb by bending the posterior (the free fit's κ₁ is sensitive
    to it).  The fitted height scatters less from trace to trace than
    the crossing's; the series truncated after s⁴ errs a little on clean
    data, and a term s⁶ would halve that error but scatter more with noise.
    """
    s = np.r_[0.0, np.cumsum(np.hypot(*np.diff(half, axis=0).T))]
    near = s <= _POLE_WINDOW
    if np.count_nonzero(near) < 6:
        return 0.0
    A = np.column_stack([s[near] ** (2 * j) for j in range(_POLE_TERMS)])
    return float(np.linalg.lstsq(A, half[near, 1], rcond=None)[0][0])


def _crossing(curve: Curve, normal: np.ndarray, c: float) -> float:
    """Arclength, nearest mid-length, where the curve crosses the line normal·X = c."""
    s = np.linspace(0.0, curve.length, 4 * len(curve.knots) + 1)
    side = curve(s) @ normal - c
    changes = np.flatnonzero(np.sign(side[:-1]) != np.sign(side[1:]))
    if not len(changes):
        raise MidlineError("the fitted axis of symmetry does not cross the trace")
    k = changes[np.argmin(np.abs(s[changes] - curve.length / 2))]
    if side[k] == 0:
        return float(s[k])
    from scipy.optimize import brentq
    return brentq(lambda x: float(curve(x) @ normal) - c, s[k], s[k + 1], xtol=1e-15)


# --------------------------------------------------------------------------- midlines

def load_midline(path: str | Path, format: str | None = None, *, n: int = 100,
                 section: str = "auto", flip: bool = False, pixel_size_um: float | None = None,
                 radius_um: float | None = None, max_asymmetry: float = 0.05,
                 roi: str | int | None = None, drop_outlier_points: bool = False) -> Midline:
    """Read, align and resample one trace, or the chosen traces of a ROI Manager set.

    :func:`load_midlines`; several traces of a set are averaged
    (:func:`average`).  The options are checked before the file is read.

    What is done to the points depends on what the file is, never on its
    numbers.  A *midline* the package wrote (:meth:`Midline.to_csv`,
    ``morphoshell average --csv``, the shipped ``*_midline.csv`` and
    ``synthetic_average.csv``: a csv with a ``# n_traces`` comment, no row
    repeated) holds rows already aligned and equally spaced in arclength,
    row i at the fraction i/(N − 1): they are read at those fractions
    (:func:`~morphoshell.io.resampling.at_fractions`), so ``n = N`` returns
    the rows bit for bit and another n the spline through them at the
    fractions j/(n − 1), as the spread is moved (:func:`resample_spread`).
    Any other trace (an image trace, a csv of ``r,z`` without that comment,
    as :func:`~morphoshell.io.traces.write_trace` writes an array) is aligned
    (:func:`align`; a csv as it is) and resampled along the spline through
    its points (:func:`resample`).  Resampling a midline's rows so had
    moved them on every reading (by up to 2.3e-3 R along the curve on the
    shipped single-trace midlines).

    Parameters
    ----------
    path : str or Path
    format : str, optional
        One of :data:`morphoshell.io.traces.FORMATS`; inferred from the
        content when None (a zip file is a ROI Manager set).
    n : int
        Points of the midline, at least 2.
    section : {"auto", "whole", "half"}
    flip : bool
        Point +z the other way (when the rims are posterior of the pole).
    pixel_size_um, radius_um : float
        µm per pixel and the embryo radius R in µm (image formats); for a ROI
        Manager set radius_um may list one per line ROI chosen, in its order.
    max_asymmetry : float
        Largest rms distance (units of R) of the halves of a whole section
        from their mirror average.
    roi : str, int or None
        ROI Manager sets only: the line ROI by name or position (from 1), or
        ``"all"`` to average every line ROI; None: the set's only line ROI
        (:mod:`morphoshell.io.roi_sets`).
    drop_outlier_points : bool
        Leave out image traces' isolated outlier points (:func:`align`).

    Returns
    -------
    Midline
        n points (r, z each of shape (n,)); for one trace spread None and
        n_traces 1, for several their :func:`average`; for a csv average
        (``r,z,spread`` and ``# n_traces``, as :meth:`Midline.to_csv` and
        ``morphoshell average --csv`` write it) its n_traces and its spread
        resampled onto the n points (:func:`resample_spread`), so that a fit's
        profiles take their noise from the traces as the command line's do.

    Raises
    ------
    MidlineError
        A bad option, file or trace (:func:`morphoshell.io.traces.read_trace`,
        :func:`align`, :func:`morphoshell.io.roi_sets.choose_rois`).
    """
    midlines = load_midlines(path, format, n=n, section=section, flip=flip,
                             pixel_size_um=pixel_size_um, radius_um=radius_um,
                             max_asymmetry=max_asymmetry, roi=roi,
                             drop_outlier_points=drop_outlier_points)
    return midlines[0] if len(midlines) == 1 else average(midlines)


def load_midlines(path: str | Path, format: str | None = None, *, n: int = 100,
                  section: str = "auto", flip: bool = False, pixel_size_um: float | None = None,
                  radius_um: float | None = None, max_asymmetry: float = 0.05,
                  roi: str | int | None = None,
                  drop_outlier_points: bool = False) -> list[Midline]:
    """The single-trace midlines of a file, each read, aligned and resampled, not averaged.

    :func:`morphoshell.io.traces.read_trace` (or, for an ImageJ ROI Manager
    set, :func:`morphoshell.io.roi_sets.read_set_traces`), then :func:`align`,
    then :func:`resample`, or for a midline's rows
    :func:`~morphoshell.io.resampling.at_fractions` (the rule:
    :func:`load_midline`).  Parameters as :func:`load_midline`'s.

    Returns
    -------
    list of Midline
        One per trace (one for a trace file, the chosen line ROIs' for a
        set), each of n points, spread None, n_traces 1, its source the
        trace's (for a set's ROI ``"PATH, ROI 'NAME'"``); a csv average keeps
        its n_traces and its spread (:func:`load_midline`).
    """
    n = check_count("n", n, 2)
    check_choice(section, SECTIONS, "section")
    check_positive("max_asymmetry", max_asymmetry)
    if format in (None, "roi") and is_roi_set(path):
        traces = read_set_traces(path, roi, pixel_size_um=pixel_size_um, radius_um=radius_um)
    elif roi is not None:
        raise MidlineError(f"{path}: roi={roi!r} applies to an ImageJ ROI Manager set (zip), "
                           f"not to this file")
    elif radius_um is not None and np.ndim(radius_um) > 0:
        raise MidlineError(f"{path}: radius_um lists radii, one per line ROI of a ROI Manager "
                           f"set: this file holds one trace")
    else:
        traces = [read_trace(path, format, pixel_size_um=pixel_size_um, radius_um=radius_um)]
    midlines = []
    for trace in traces:
        aligned = align(trace, section, flip=flip, max_asymmetry=max_asymmetry,
                        drop_outlier_points=drop_outlier_points)
        r, z = _at_n(trace, aligned.points, n).T
        midlines.append(Midline(r, z, resample_spread(trace.spread, n), trace.n_traces,
                                (trace.source,), aligned.noise))
    return midlines


def _at_n(trace: Trace, half: np.ndarray, n: int) -> np.ndarray:
    """n points of an aligned trace equally spaced in arclength: a midline's rows
    (:attr:`Trace.written`) at their fractions of arclength (:func:`at_fractions`; the rows
    themselves at n = rows), any other trace's along the spline through its points
    (:func:`resample`)."""
    return at_fractions(half, n) if trace.written else resample(half, n)


def resample_spread(spread, n: int) -> np.ndarray | None:
    """An average's spread at its N rows, at n points equally spaced in arclength.

    Row i of an average lies at the fraction i/(N − 1) of its arclength (:func:`average`),
    as point j of the resampled midline at j/(n − 1), so the spread goes across by that
    fraction, interpolated linearly (exact near the pole, where it grows linearly from 0).

    Parameters
    ----------
    spread : array_like, shape (N,), or None
        Units of R.
    n : int
        Points wanted.

    Returns
    -------
    ndarray, shape (n,), or None
        The spread itself when N = n; None for None.
    """
    if spread is None:
        return None
    spread = np.asarray(spread, dtype=float)
    if len(spread) == n:
        return spread
    return np.interp(np.linspace(0.0, 1.0, n), np.linspace(0.0, 1.0, len(spread)), spread)


def average(midlines: Sequence[Midline]) -> Midline:
    """Mean and spread of single-trace midlines of one stage, point by point.

    The mean of the points i, resampled equally spaced in its own arclength
    (:func:`resample`); the spread is that of the points i.  Without the
    resampling the mean keeps a bias along the curve: pixel noise lengthens
    each trace's arclength unevenly (most where the noise is large for the
    point spacing), so a fraction of the length falls at a slightly other
    material point in every trace alike, and averaging more traces does not
    shrink it.  Resampled (and with the bins of :func:`align` moved back
    onto the curve), the mean is unbiased within its standard error, with
    the same spread.

    Parameters
    ----------
    midlines : sequence of Midline
        Single-trace midlines (n_traces 1), all of N points.

    Returns
    -------
    Midline
        r, z of shape (N,); spread of shape (N,) (None for a single
        midline); n_traces the number averaged; source their files.

    Raises
    ------
    MidlineError
        No midlines, different numbers of points, or an input that is
        itself an average.
    TypeError
        ``midlines`` is not a sequence of Midline objects (of arrays, of paths).
    """
    midlines = _midlines("average", midlines)
    if not midlines:
        raise MidlineError("average: no midlines given")
    sizes = sorted({len(m.r) for m in midlines})
    if len(sizes) > 1:
        raise MidlineError(f"average: the midlines have different numbers of points {sizes}; "
                           f"resample them to one n")
    for m in midlines:
        if m.n_traces != 1:
            raise MidlineError(f"average: {', '.join(m.source) or 'a midline'} is already an "
                               f"average of {m.n_traces} traces; average the single traces")
    points = np.stack([m.points for m in midlines])            # (traces, N, 2)
    mean = points.mean(axis=0)
    if len(midlines) > 1 and len(mean) >= 4:
        mean = resample(mean, len(mean))
    spread = np.sqrt(points.var(axis=0, ddof=1).mean(axis=1)) if len(midlines) > 1 else None
    return Midline(mean[:, 0], mean[:, 1], spread, len(midlines),
                   tuple(s for m in midlines for s in m.source))


def trace_distances(midlines: Sequence[Midline]) -> np.ndarray:
    """Each trace's distance from the traces' pointwise median, point by point (units of R).

    A median (of r and of z at each point), not a mean: a trace at the wrong
    scale or orientation would drag a mean toward itself, and among three
    to five traces even a mean of the others is dragged so far that the
    outlier stands out by only about the number of traces less one.  From the
    median it stands out by far more: on the shipped synthetic stages every
    trace's rms distance lies within 2.4 times the median of the five, and
    one read 5 % off in scale lies 13–37 times as far.

    Parameters
    ----------
    midlines : sequence of Midline
        At least two single-trace midlines of one number of points N.

    Returns
    -------
    ndarray, shape (n_traces, N)
        |p_k,i − median_j p_j,i| for trace k at point i; their rms over i
        (the square root of the mean of the squares) is the trace's summary.
    """
    points = np.stack([m.points for m in _midlines("trace_distances", midlines)])
    if len(points) < 2:
        raise MidlineError(f"trace_distances: {len(points)} midline; it needs at least 2")
    return np.hypot(*np.moveaxis(points - np.median(points, axis=0), 2, 0))


def _midlines(what: str, midlines) -> list[Midline]:
    """``midlines`` as a list, or TypeError naming the first that is not a Midline (arrays and
    paths raised "no attribute 'r'")."""
    if isinstance(midlines, (Midline, str, Path)):
        raise TypeError(f"{what}: midlines = {short(midlines)} must be a sequence of Midline "
                        f"objects, not one {type(midlines).__name__} (load_midlines(path) reads "
                        f"a file's)")
    listed = list(midlines)
    for i, m in enumerate(listed):
        if not isinstance(m, Midline):
            raise TypeError(f"{what}: midlines[{i}] = {short(m)} must be a Midline, not "
                            f"{type(m).__name__} (load_midline(path) reads a file's)")
    return listed
