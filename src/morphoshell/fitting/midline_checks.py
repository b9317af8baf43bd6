"""Checks of a data midline before a fit (points, pole, retraced lines, length and scale),
and the verdict on one after it.

A midline that cannot be one of the model's (listed rim first, retracing its
way, in the wrong units or scale, its columns r and z swapped) used to
"converge" to a fit energy of several R with the model's midline nowhere near
it: :func:`check_midline` refuses it before any work, naming what is wrong
and what is probably the cause.  :func:`intrinsic_lengths` bounds the lengths
the Volvox model's midline can have.  What passes these checks and still ends
far above what the model leaves of a traced midline gets :func:`input_check`'s
verdict: ``morphoshell fit``'s last line and JSON, and every campaign record, hold it.
"""
from __future__ import annotations

from pathlib import PurePath
from typing import Callable

import numpy as np

from .._runtime.validate import short
from .spec import FitSpec, check_spec

__all__ = ["check_midline", "intrinsic_lengths", "as_points", "LENGTH_SLACK", "MAX_TURN",
           "TURN_LENGTH", "POLE_SLACK", "MAX_MEAN_STRETCH", "POLE_ANGLE", "POLE_ARC",
           "SCALE_HINT", "input_check", "far_above", "IMPLAUSIBLE_E_FIT", "INPUT_CHECK",
           "MISFIT"]

#: A data midline whose length lies further than this factor outside the Volvox model's
#: intrinsic lengths (:func:`intrinsic_lengths`) is refused before a fit: its units or scale
#: are wrong (a factor 2 means elastic strains of 100 %, far beyond the theory's).
LENGTH_SLACK = 2.0
#: A data midline longer than MAX_MEAN_STRETCH times the undeformed shell's length
#: (π − P − Σ, units of R), or shorter than that divided by it, is refused before a fit: its
#: scale is wrong.  Its length over the undeformed one is the shell's mean meridional stretch;
#: an image trace at the right scale gives 0.89-0.98 (the shipped synthetic inversion), the
#: same trace with its pixel size 1.5× too large still fits (E_fit 0.034 R, f2 on its bound
#: 2), 2× too large ends at E_fit 0.83 R with f2 and f4 on their bound, 0.5× and 0.67× at
#: 4.9 R and 3.1 R (issue 41): a mean stretch beyond 1.5 either way leaves the fit nothing to
#: find but its bounds.
MAX_MEAN_STRETCH = 1.5
#: A data midline of an intact shell that rises more than POLE_ANGLE (radians) from the r
#: axis over its first POLE_ARC·h of arclength is refused before a fit (its columns r and z
#: swapped?).  A regular pole of an axisymmetric shell has its tangent perpendicular to the
#: axis; turning from there needs curvature, and a sheet of deformed thickness h/(f_s f_φ)
#: bends to a radius no smaller than half of it: curvature at most 2 f²/h with f ≤ 2, the
#: stretches' bound, so the chord over h/4 rises by at most f²/4 ≤ 1 rad (57 degrees).  A
#: swapped trace starts along the axis, at ~90 degrees.
POLE_ANGLE, POLE_ARC = np.radians(60.0), 0.25
#: A data midline that turns by more than MAX_TURN (radians) within TURN_LENGTH (units of R)
#: of its arclength is refused before a fit: a line that retraces its way.  That is a mean
#: radius of curvature below 0.042 R, a fraction of the cell sheet's thickness (h = 0.15 R
#: in the paper's fits); tuned between the shipped synthetic midlines (at most 0.73 rad
#: within 0.1 R) and traced hairpins (tests/fitting/test_midline_checks.py).
MAX_TURN, TURN_LENGTH = 0.75 * np.pi, 0.1
#: A data midline of an intact shell (no cut) starts at the posterior pole, the origin of the
#: model gauge, within this distance (units of R) or is refused before a fit (listed rim
#: first?).  Image traces are aligned with their pole there exactly; a CSV of r, z is taken
#: as it is.
POLE_SLACK = 0.1

#: E_fit (R) above which a fit's last line points at the input before the fit.  E_fit is the
#: root of the sum of 100 squared distances: 0.1 R is 0.01 R rms a point, 0.4 µm at R = 40 µm,
#: more than a pixel.  Fits of traced midlines end at 0.005-0.02 R (the synthetic averages
#: 0.0046-0.012, single noisy image traces 0.012, 24-point sparse traces 0.02), the worst
#: variant of a late stage at 0.031 (flat, t06); wrong input ends at 0.2-16 R (z flipped 10.2,
#: a half section tilted by rounding 6.6, the radius 10 % off 0.69, f1 held at 5 16.5).  Stalls
#: at a fold from far starts on right data reach 0.24-0.67 R too (t06 from the defaults, t08
#: with t01's held values): above the threshold the line names both, the input first.
IMPLAUSIBLE_E_FIT = 0.1
#: What to check of an input whose fit ends above IMPLAUSIBLE_E_FIT.
INPUT_CHECK = ("check the input: its orientation (pole first? z flipped?), its scale "
               "(--pixel-size and --radius-um; a CSV's r, z in units of R), its axis "
               "(--section) and any --set values")
#: What a converged fit far above traced midlines may mean when its input is right.
MISFIT = ("if it is right, the model may not describe this shape (see the parameters on "
          "bounds and constraints)")


def intrinsic_lengths(spec: FitSpec) -> tuple[float, float] | None:
    """(shortest, longest) intrinsic length ∫ f_s0 ds of the fitted Volvox shell, in R.

    f_s0 blends f₁, f₂ and f₃ with smoothed steps (documentation: "Problems
    and families"), so over the shell's length L − P the intrinsic midline is
    about as long as the smallest of their lower bounds (held values for held
    stretches) times L − P, at least, and the largest of their upper bounds
    times L − P, at most.

    Parameters
    ----------
    spec : FitSpec
        The fit (its bounds and held values of f₁ … f₃).

    Returns
    -------
    (float, float) or None
        The shortest and longest length, in units of R; ``None`` for other
        families than ``volvox``.
    """
    if spec.base.family != "volvox":
        return None
    lo, hi = spec.box()
    lows, highs = [], []
    for name in ("f1", "f2", "f3"):
        if name in spec.fitted:
            i = spec.fitted.index(name)
            lows.append(lo[i]), highs.append(hi[i])
        else:
            lows.append(spec.base.params[name]), highs.append(spec.base.params[name])
    return min(lows) * spec.base.end, max(highs) * spec.base.end


#: What the messages of a wrong length suggest checking, unless the caller says better (the
#: command line names its options).
SCALE_HINT = ("are its units R (divided by the embryo's radius), and for an image trace the "
              "pixel size in µm per pixel and the radius R in µm?")


def check_midline(spec: FitSpec, data, name: str = "the data midline", *,
                  scale_hint: str | Callable[[float, tuple[float, float]], str] = SCALE_HINT
                  ) -> None:
    """ValueError if the midline ``data`` (N, 2) cannot be a midline of ``spec``'s shell.

    In this order: it does not start at the posterior pole of an intact shell
    (further than :data:`POLE_SLACK` from the origin of the model gauge:
    listed rim first?); it is too short (below); it turns back on itself
    (more than :data:`MAX_TURN` within :data:`TURN_LENGTH`: a retraced line,
    or the noise of a trace far too short); it is too long: its polygon
    length lies outside :func:`intrinsic_lengths` by more than
    :data:`LENGTH_SLACK`, or its mean stretch (length over the undeformed
    shell's) beyond :data:`MAX_MEAN_STRETCH` (the wrong units or scale: the
    message gives the factor); it leaves the pole of an intact shell along
    the axis rather than across it (:data:`POLE_ANGLE`: columns r and z
    swapped?).

    Parameters
    ----------
    spec : FitSpec
        The fit the midline is meant for.
    data : array_like, shape (N, 2), or Midline
        The midline (r, z) in the model gauge (:func:`as_points`).
    name : str
        What the messages call the midline.
    scale_hint : str or callable
        What the message of a wrong length asks the user to check (the
        command line names its options --pixel-size and --radius-um), or a
        function ``hint(length, (lo, hi))`` of the midline's length and the
        lengths the check allows (units of R) that says it: the command line
        names the likely mistake where the length says which (a Fiji export
        already in µm read with the pixel size, :func:`morphoshell.cli._args.scale_hint`).

    Raises
    ------
    ValueError
        Naming what is wrong and what to check.
    TypeError
        ``spec`` is not a :class:`FitSpec`, or ``data`` not points (:func:`as_points`).
    """
    check_spec(spec)
    points = as_points(data, name)
    off = float(np.hypot(*points[0]))
    if spec.base.cut == 0 and off > POLE_SLACK:
        raise ValueError(
            f"{name} starts at (r, z) = ({points[0, 0]:.3g}, {points[0, 1]:.3g}), {off:.3g} R "
            f"from the posterior pole at the origin of the model gauge, where a midline "
            f"starts: is it listed rim first (reverse it), or not in the model gauge?")
    step = np.diff(points, axis=0)
    step = step[np.any(step != 0, axis=1)]       # (a repeated point has no direction)
    seg = np.hypot(*step.T)
    # a midline too short is refused for its scale before its shape: the noise of a trace
    # read at a tenth of its scale turns it back on itself (an audit's 0.26 R trace, by 200
    # degrees); one too long after it, since retracing a line lengthens it
    _check_length(spec, float(seg.sum()), name, scale_hint, longer=False)
    _check_turns(step, seg, name)
    _check_length(spec, float(seg.sum()), name, scale_hint)
    if spec.base.cut == 0:
        _check_pole_tangent(spec, points[0], step, seg, name)


def _check_turns(step: np.ndarray, seg: np.ndarray, name: str) -> None:
    """Refuse a midline that turns by more than MAX_TURN within TURN_LENGTH (retraced)."""
    middle = np.cumsum(seg) - seg / 2
    # the tangent's angle, unwrapped: a U-turn adds up to pi however many segments it spans
    angle = np.unwrap(np.arctan2(step[:, 1], step[:, 0]))
    for i in range(len(step)):
        j = np.searchsorted(middle, middle[i] + TURN_LENGTH, side="right")
        turn = np.abs(angle[i:j] - angle[i])
        if turn.max() > MAX_TURN:
            raise ValueError(
                f"{name} turns back on itself {middle[i]:.3g} R along it (by "
                f"{np.degrees(turn.max()):.0f} degrees within {TURN_LENGTH:g} R): a traced "
                f"line that retraces its way?")


def _check_length(spec: FitSpec, length: float, name: str, hint, longer: bool = True
                  ) -> None:
    """Refuse a Volvox midline too long or short for the stretches and scale (module constants;
    only too short without ``longer``).

    The factor named is the length over the undeformed shell's, the mean
    stretch: about 1 at the right scale, so about the factor the scale is off.
    """
    lengths = intrinsic_lengths(spec)
    if lengths is None:
        return
    shortest, longest = lengths
    undeformed = spec.base.end - spec.base.cut
    lo = max(shortest / LENGTH_SLACK, undeformed / MAX_MEAN_STRETCH)
    hi = min(longest * LENGTH_SLACK, undeformed * MAX_MEAN_STRETCH)
    if lo <= length and (length <= hi or not longer):
        return
    factor = length / undeformed
    ratio = f"{factor:.2g}× longer" if factor > 1 else f"{1 / factor:.2g}× shorter"
    raise ValueError(
        f"{name} is {length:.3g} R long, {ratio} than the undeformed shell ({undeformed:.3g} "
        f"R); the model's midlines are about {lo:.3g}-{hi:.3g} R long: "
        f"{hint(length, (lo, hi)) if callable(hint) else hint}")


def _check_pole_tangent(spec: FitSpec, pole: np.ndarray, step: np.ndarray, seg: np.ndarray,
                        name: str) -> None:
    """Refuse a midline of an intact shell that leaves its pole along the axis (POLE_ANGLE)."""
    arc = POLE_ARC * spec.base.h
    along = np.r_[0.0, np.cumsum(seg)]
    if along[-1] <= arc:
        return
    k = int(np.searchsorted(along, arc))          # the point at arc lies on step k - 1
    end = pole + step[:k - 1].sum(axis=0) + (arc - along[k - 1]) / seg[k - 1] * step[k - 1]
    rise = float(np.arctan2(abs(end[1] - pole[1]), end[0] - pole[0]))
    if rise > POLE_ANGLE:
        raise ValueError(
            f"{name} leaves the pole at {np.degrees(rise):.0f} degrees from the r axis (over "
            f"its first {arc:.2g} R): a shell's midline leaves its pole perpendicular to the "
            f"axis, and a sheet of thickness h = {spec.base.h:g} cannot bend by more than "
            f"{np.degrees(POLE_ANGLE):.0f} degrees that soon: are its columns r and z "
            f"swapped?")


def as_points(data, name: str = "data") -> np.ndarray:
    """The points (r, z) of a midline, checked.

    Parameters
    ----------
    data : array_like, shape (N, 2), or Midline
        Points (r, z), or anything with arrays ``r`` and ``z`` (a
        :class:`morphoshell.io.traces.Midline`).
    name : str
        What the messages call ``data``.

    Returns
    -------
    points : ndarray, shape (N, 2)
        As floats.

    Raises
    ------
    TypeError
        ``data`` is a file's path (read it with
        :func:`morphoshell.io.midlines.load_midline`) or not numbers.
    ValueError
        Unless N >= 3 and every coordinate is finite (the first point that
        is not is named, counting from 0).
    """
    if isinstance(data, (str, bytes, PurePath)):
        raise TypeError(f"{name} = {short(data)} must be a Midline or (N, 2) points (r, z), not a "
                        f"path: read a file with morphoshell.io.load_midline")
    if hasattr(data, "r") and hasattr(data, "z"):
        data = np.column_stack([data.r, data.z])
    try:
        points = np.asarray(data, dtype=float)
    except (TypeError, ValueError):
        raise TypeError(f"{name} = {short(data)} must be a Midline or (N, 2) points (r, z)") \
            from None
    if points.ndim != 2 or points.shape[1] != 2 or len(points) < 3:
        raise ValueError(f"{name} must be N >= 3 points (r, z), got shape {points.shape}")
    bad = np.flatnonzero(~np.all(np.isfinite(points), axis=1))
    if len(bad):
        i = int(bad[0])
        raise ValueError(f"{name}: point {i} (r, z) = ({points[i, 0]:.6g}, {points[i, 1]:.6g}) "
                         f"is not finite" + (f" ({len(bad)} points are not)" * (len(bad) > 1)))
    return points


def far_above(E_fit: float) -> str:
    """What a fit's last line says of an E_fit above :data:`IMPLAUSIBLE_E_FIT` ("" below it).

    Right input can end there too: a stall at a fold, or a shape the model does
    not describe (:data:`MISFIT`: an audit's hand-made bowl, three stretches on
    their bounds).
    """
    if not E_fit > IMPLAUSIBLE_E_FIT:
        return ""
    return (f"E_fit is far above what the model leaves of a traced midline (0.005-0.03 R): "
            f"{INPUT_CHECK}")


def input_check(E_fit: float) -> str | None:
    """The verdict on a fit that ends far above what the model leaves of a traced midline.

    The ``input_check`` of ``morphoshell fit``'s JSON and of every campaign
    record, so that a script does not take such a fit for a good one.

    Parameters
    ----------
    E_fit : float
        The fit's E_fit, units of R.

    Returns
    -------
    str or None
        None at or below :data:`IMPLAUSIBLE_E_FIT`; above it, what to check of
        the input and, if the input is right, that the model may not describe
        the shape (:data:`MISFIT`).
    """
    far = far_above(E_fit)
    return f"{far}; {MISFIT}" if far else None
