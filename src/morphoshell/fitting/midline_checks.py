"""Checks of a data midline before a fit: points, pole, retraced lines and length.

A midline that cannot be one of the model's (listed rim first, retracing its
way, in the wrong units) used to "converge" to a fit energy of several R with
the model's midline nowhere near it: :func:`check_midline` refuses it before
any work, naming what is wrong.  :func:`intrinsic_lengths` bounds the lengths
the Volvox model's midline can have.
"""
from __future__ import annotations

import numpy as np

from .spec import FitSpec

__all__ = ["check_midline", "intrinsic_lengths", "as_points", "LENGTH_SLACK", "MAX_TURN",
           "TURN_LENGTH", "POLE_SLACK"]

#: A data midline whose length lies further than this factor outside the Volvox model's
#: intrinsic lengths (:func:`intrinsic_lengths`) is refused before a fit: its units or scale
#: are wrong (a factor 2 means elastic strains of 100 %, far beyond the theory's).
LENGTH_SLACK = 2.0
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


def check_midline(spec: FitSpec, data, name: str = "the data midline") -> None:
    """ValueError if the midline ``data`` (N, 2) cannot be a midline of ``spec``'s shell.

    It does not start at the posterior pole of an intact shell (further than
    :data:`POLE_SLACK` from the origin of the model gauge: listed rim first?),
    it turns back on itself (more than :data:`MAX_TURN` within
    :data:`TURN_LENGTH`: a retraced line), or its polygon length lies outside
    :func:`intrinsic_lengths` by more than :data:`LENGTH_SLACK` either way
    (the wrong units or scale).

    Parameters
    ----------
    spec : FitSpec
        The fit the midline is meant for.
    data : array_like, shape (N, 2), or Midline
        The midline (r, z) in the model gauge (:func:`as_points`).
    name : str
        What the messages call the midline.

    Raises
    ------
    ValueError
        Naming what is wrong and what to check.
    """
    try:
        points = as_points(data)
    except ValueError as exc:
        raise ValueError(f"{name}: {exc}") from None
    off = float(np.hypot(*points[0]))
    if spec.base.cut == 0 and off > POLE_SLACK:
        raise ValueError(
            f"{name} starts at (r, z) = ({points[0, 0]:.3g}, {points[0, 1]:.3g}), {off:.3g} R "
            f"from the posterior pole at the origin of the model gauge, where a midline "
            f"starts: is it listed rim first (reverse it), or not in the model gauge?")
    step = np.diff(points, axis=0)
    step = step[np.any(step != 0, axis=1)]       # (a repeated point has no direction)
    seg = np.hypot(*step.T)
    length = float(seg.sum())
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
    lengths = intrinsic_lengths(spec)
    if lengths is None:
        return
    shortest, longest = lengths
    if not shortest / LENGTH_SLACK <= length <= longest * LENGTH_SLACK:
        raise ValueError(
            f"{name} is {length:.3g} R long, but the model's midlines are about "
            f"{shortest:.3g}-{longest:.3g} R long (stretches f1-f3 within their bounds over "
            f"the shell's {spec.base.end:.3g} R): are its units R and its scale right?")


def as_points(data) -> np.ndarray:
    """The points (r, z) of a midline, checked.

    Parameters
    ----------
    data : array_like, shape (N, 2), or Midline
        Points (r, z), or anything with arrays ``r`` and ``z`` (a
        :class:`morphoshell.io.traces.Midline`).

    Returns
    -------
    points : ndarray, shape (N, 2)
        As floats.

    Raises
    ------
    ValueError
        Unless N >= 3 and every coordinate is finite.
    """
    if hasattr(data, "r") and hasattr(data, "z"):
        data = np.column_stack([data.r, data.z])
    data = np.asarray(data, dtype=float)
    if data.ndim != 2 or data.shape[1] != 2 or len(data) < 3 or not np.all(np.isfinite(data)):
        raise ValueError(f"the data must be N >= 3 finite points (r, z), got shape {data.shape}")
    return data
