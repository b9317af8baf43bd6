"""Brent's bracketing root finder, without importing ``scipy.optimize``.

Importing ``scipy.optimize`` takes about a third of a second (it pulls in
scipy.linalg, scipy.sparse and more), a large part of a command that meets one
fold or evaluates one closed form.  :func:`brentq` takes the steps of
``scipy.optimize.brentq`` (R. P. Brent, *Algorithms for Minimization without
Derivatives*, 1973, ch. 4: inverse quadratic or secant steps while they shrink
the bracket fast enough, bisection otherwise) in the same floating-point
operations, so that it returns the same root to the bit (tests/numerics/test_roots.py
compares them); its arguments and errors are scipy's.
"""
from __future__ import annotations

import math
import sys
from typing import Callable

__all__ = ["brentq", "XTOL", "RTOL", "MAX_ITERATIONS"]

#: scipy's defaults: absolute and relative tolerance of the root, iterations.
XTOL, RTOL, MAX_ITERATIONS = 2e-12, 4 * sys.float_info.epsilon, 100


def _value(f: Callable[[float], float], x: float) -> float:
    """f(x) as a float; NaN is an error (no bracket can be kept with it), as scipy's."""
    value = float(f(x))
    if math.isnan(value):
        raise ValueError(f"the function value at x={x} is NaN; solver cannot continue")
    return value


def _opposite(fa: float, fb: float) -> bool:
    """Whether the two values are nonzero with opposite signs (by sign bit: no underflow)."""
    return fa != 0 and fb != 0 and math.copysign(1.0, fa) != math.copysign(1.0, fb)


def _step(x: tuple[float, float, float], fx: tuple[float, float, float]) -> float:
    """The interpolation step from the current point: secant if the previous point is the
    bracket's other end, else inverse quadratic through the three points."""
    cur, prev, far = x
    fcur, fprev, ffar = fx
    if prev == far:
        return -fcur * (cur - prev) / (fcur - fprev)
    dprev = (fprev - fcur) / (prev - cur)
    dfar = (ffar - fcur) / (far - cur)
    return -fcur * (ffar * dfar - fprev * dprev) / (dfar * dprev * (ffar - fprev))


def brentq(f: Callable[[float], float], a: float, b: float, xtol: float = XTOL,
           rtol: float = RTOL, maxiter: int = MAX_ITERATIONS) -> float:
    """A root of ``f`` in the bracket [a, b] (f(a) and f(b) of opposite signs).

    Parameters
    ----------
    f : callable
        A continuous function of one float.
    a, b : float
        The bracket's ends.
    xtol, rtol : float
        The root is within ``xtol + rtol * |root|`` of a sign change of f
        (``xtol`` > 0, ``rtol`` ≥ 4 ε, as scipy's).
    maxiter : int
        Most iterations.

    Returns
    -------
    float
        The root: ``scipy.optimize.brentq(f, a, b, xtol, rtol, maxiter)`` to the bit.

    Raises
    ------
    ValueError
        f(a) and f(b) of the same sign, a NaN value of f, or a bad tolerance.
    RuntimeError
        Not converged in ``maxiter`` iterations.
    """
    if not xtol > 0:
        raise ValueError(f"xtol too small ({xtol:g} <= 0)")
    if not rtol >= RTOL:
        raise ValueError(f"rtol too small ({rtol:g} < {RTOL:g})")
    prev, cur = float(a), float(b)
    fprev, fcur = _value(f, prev), _value(f, cur)
    if fprev == 0:
        return prev
    if fcur == 0:
        return cur
    if not _opposite(fprev, fcur):
        raise ValueError("f(a) and f(b) must have different signs")
    far = ffar = step = last = 0.0       # the bracket's other end; this and the last step
    for _ in range(maxiter):
        if _opposite(fprev, fcur):       # the sign changed: prev is the other end
            far, ffar = prev, fprev
            step = last = cur - prev
        if abs(ffar) < abs(fcur):        # keep the smaller value at cur
            prev, cur, far = cur, far, cur
            fprev, fcur, ffar = fcur, ffar, fcur
        delta = (xtol + rtol * abs(cur)) / 2    # half the tolerance
        half = (far - cur) / 2                  # the bisection step
        if fcur == 0 or abs(half) < delta:
            return cur
        if abs(last) > delta and abs(fcur) < abs(fprev):
            trial = _step((cur, prev, far), (fcur, fprev, ffar))
            bound = 3 * abs(half) - delta
            # a short step that the last ones vouch for, else bisection
            last, step = (step, trial) if 2 * abs(trial) < (abs(last) if abs(last) < bound
                                                           else bound) else (half, half)
        else:
            last = step = half
        prev, fprev = cur, fcur
        cur += step if abs(step) > delta else (delta if half > 0 else -delta)
        fcur = _value(f, cur)
    raise RuntimeError(f"failed to converge after {maxiter} iterations, value is {cur}")
