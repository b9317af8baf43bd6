"""Where a profile's interval ends: its crossing, made sure where a refit stalled or the grid is
coarse.

A profile (:mod:`morphoshell.fitting.profiles`) refits the other parameters at each step
of θⱼ from the neighbouring step's end; every refit's objective bounds the profile from
above, so a refit that stops short of its minimum (not converged: out of evaluations, or
stalled where its trial points fail) lies too high, and where it is the step that decides
a crossing the interval comes out too narrow.  An audit's κ₁ (the ``free`` fit of a noisy
forward solution, 100 nodes) read [−0.009, 1.03]: the refits at both neighbours of the
optimum stalled above the threshold, where a fit with κ₁ held at 1.2 from the family's
defaults converged below it and the right end lies near 1.6.

Two remedies, both only where they are needed (an ordinary profile's refits all converge
and its crossing lies several steps out: its numbers stay the same to the bit):

* **Other starts** (:func:`retried`): a refit beyond the threshold that did not converge
  is fitted again, with θⱼ held, from the starts a fit from several starts tries
  (:func:`morphoshell.fitting.multistart.other_starts`: the family's defaults, κ₂ = −3
  and −6, the late-stage start; those a campaign's fit also tries), in turn until the
  lowest converges; the lowest objective is kept.  A retry that lands below the threshold
  lets the walk go on outward from there, so the interval widens.  Each retry is recorded
  (:class:`Retry`: which start won) in the profile's note and JSON.
* **A coarse crossing refined** (:func:`refine_crossing`): where a side crosses the
  threshold within its first two steps (a profile far narrower than the Gauss–Newton error
  that set the step, or a grid asked for with few points), the crossing interpolated
  across one step rests on two refits; one or two refits at the interpolated crossing
  (false position) bracket it within a fraction of a step, and a coarse grid's crossing
  refit in a worse minimum, the walk's last, no longer decides the end alone.
* **Neighbours' ends** (:func:`settle_side`): a profile rises outward on either side of its
  minimum, so a converged refit above one farther out (by :data:`MONOTONE_TOL`) ended in a
  worse local minimum.  It is fitted again from its outer neighbour's end, then its inner
  one's, keeping the lower, until the side is monotone or no untried start is left; and the
  two refits the crossing is interpolated between (the first above the threshold and the last
  below) are tried from their outer neighbour's end too where they lie above their
  neighbours' chord in √(S − S_min), where the profile bends the wrong way.  An
  audit's f₁ (the synthetic t05, ``free``): the refit at 0.77851 converged at 2.965e-5 R²,
  above the threshold 2.9196e-5 and above the refit at 0.77579 (2.942e-5); from that one's
  end it gives 2.913e-5, and the lower end moved from 0.77997 to 0.7779.  Audit 27's κ₁
  (the synthetic t02, 6 points, 60 nodes): the first step on either side converged in a worse
  minimum (−0.0219: 0.66 threshold heights, 0.26 from the crossing refit's end), both sides
  monotone, the crossing's refit the walk's last; the interval [−0.097, 0.932] became
  [−0.157, 0.954], and [−0.1725, 0.954] with the lower crossing, at the first step, refined
  (20 points: [−0.172, 0.960]).  A side still not
  monotone after them is named in a warning and the profile's note
  (:func:`not_monotone_note`).

Lengths in units of R.
"""
from __future__ import annotations

import logging
import time
from dataclasses import dataclass, replace
from typing import Callable

import numpy as np

from ..solvers.results import SolverError
from .bilevel import fit
from .multistart import other_starts
from .results import FitError
from .spec import VARIANTS, FitSpec

__all__ = ["Retry", "RETRY_METHOD", "REFINEMENTS", "MONOTONE_TOL",
           "NEIGHBOUR_REFITS", "ABOVE_FARTHER", "CROSSING", "BEFORE_CROSSING", "crossing",
           "crossings", "retried",
           "needs_retry", "refine_crossing", "started_at", "non_monotone", "settle_side",
           "not_monotone_note"]

log = logging.getLogger(__name__)

#: The retries' method whatever the profile's: a KKT fit from a far start fails or falls back
#: to the gradient fit (as a campaign's fits from its other starts, which run by it too).
RETRY_METHOD = "gradient"
#: At most this many refits at the interpolated crossing on a side (:func:`refine_crossing`).
REFINEMENTS = 2
#: A side (outward) is monotone where no refit lies above one farther out by more than this
#: fraction of the threshold's height (threshold − S_min).  Near its crossing a 20-point
#: grid's profile rises by about 0.4 heights a step (a parabola reaching the threshold at the
#: fifth step), so a bump this small moves the interpolated crossing by 2.5 % of a step at
#: most; and it is thousands of times what two ends of one minimum differ by (the refits stop
#: at 10⁻⁸ of S, the height is ≥ 0.2 % of S_min for up to 1000 points), so the round-off of a
#: flat side asks for no refits.  The audit's f₁ bump was 7 % of a height.
MONOTONE_TOL = 0.01
#: At most this many refits from neighbours' ends on a side (:func:`settle_side`): the audit's
#: f₁ took two (the bump, then the new crossing from beyond it), an ordinary side one.
NEIGHBOUR_REFITS = 6
#: :attr:`Retry.reason` of a refit above one farther out, of the crossing's refit (the first
#: above the threshold), and of the refit before it (the last below).
ABOVE_FARTHER = "above a refit farther out"
CROSSING = "the crossing"
BEFORE_CROSSING = "the step before the crossing"
#: What a retry's fit that fails with one of these leaves in its table (the others go on).
_FAILURES = (FitError, SolverError, ValueError)


@dataclass(frozen=True)
class Retry:
    """A profile's refit fitted again from other starts: one beyond the threshold that did not
    converge (from the starts of a fit from several starts, :func:`retried`), or one that lies
    above a refit farther out or decides a crossing (from its neighbours' ends,
    :func:`settle_side`).

    Attributes
    ----------
    value : float
        θⱼ, held.
    S_before : float
        The stalled refit's objective (units of R²).
    winner : str
        The start whose fit is kept (a row's ``"from"``), or ``""``: none lay lower, the
        stalled refit stands.
    S : float
        The kept objective (units of R²).
    converged : bool
        Whether the kept refit converged.
    starts : tuple of dict
        One row per start fitted, in order: ``{"from", "E_fit" (R), "converged"}`` or
        ``{"from", "E_fit": None, "failed": message}``.
    seconds : float
        Wall-clock time of the retry's fits.
    reason : str
        Why a refit was fitted again from its neighbours' ends (:data:`ABOVE_FARTHER`,
        :data:`CROSSING`, :data:`BEFORE_CROSSING`); "" for a stalled refit's retry from other
        starts.
    """

    value: float
    S_before: float
    winner: str
    S: float
    converged: bool
    starts: tuple[dict, ...]
    seconds: float = 0.0
    reason: str = ""

    def note(self, name: str) -> str:
        """One clause for the profile's note: where, from which start, what it gave ("" for a
        refit from a neighbour's end that lay no lower: the JSON keeps it)."""
        if self.reason and not self.winner:
            return ""
        why = f", {self.reason}" if self.reason else ""
        head = (f"the refit at {name} = {self.value:.6g} (E_fit {np.sqrt(self.S_before):.6g} "
                f"R{why}) fitted again from {len(self.starts)} other "
                f"start{'s' * (len(self.starts) != 1)}")
        if not self.winner:
            return f"{head}: none lay lower"
        state = "converged" if self.converged else "not converged"
        return f"{head}: lowest {np.sqrt(self.S):.6g} R, from the {self.winner} ({state})"

    def to_dict(self) -> dict:
        """JSON-ready (E_fit in R)."""
        return {"value": self.value, "E_fit_before": float(np.sqrt(self.S_before)),
                "kept": self.winner or None, "E_fit": float(np.sqrt(self.S)),
                "converged": self.converged, "starts": [dict(row) for row in self.starts],
                "seconds": self.seconds, "reason": self.reason or None}


def started_at(spec: FitSpec, theta) -> FitSpec:
    """``spec`` started at θ (its breakpoints' boxes moved around θ where it orders them)."""
    return spec.recentred(theta) if spec.ordered else replace(spec, base=spec.problem(theta))


def needs_retry(out: tuple | None, threshold: float, objective: list) -> bool:
    """Whether a profile's refit (:func:`morphoshell.fitting.profiles`' tuple: spec, θ,
    state, objective, converged) decides its side's crossing without having converged: it
    lies beyond the threshold, and no refit before it on the side (``objective``, outward)
    does.  A converged refit there would move the crossing outward; one after the first
    beyond cannot move it (:func:`crossing` takes the first)."""
    return (out is not None and not out[4] and out[3] > threshold
            and not any(S > threshold for S in objective))


def retried(spec: FitSpec, name: str, value: float, out: tuple, threshold: float, data,
            nodes: int, tol: float) -> tuple[tuple, Retry | None]:
    """A stalled refit with ``name`` held at ``value`` fitted again from other starts: the
    lowest of it and theirs, and the :class:`Retry` (None for a spec that is not a Volvox
    variant's: the starts are the Volvox family's).

    The starts (:func:`morphoshell.fitting.multistart.other_starts`, with ``spec``'s held
    values and ``name`` = ``value``) are fitted in turn (:data:`RETRY_METHOD`, on
    ``nodes`` nodes to ``tol``) until the lowest so far converged, as a campaign fits its
    other starts, or lies below ``threshold``: the point is inside the interval then, and
    a lower objective would move its crossing by a fraction of a step at most.  ``out`` is
    the stalled refit's tuple (spec, θ, state, objective, converged); so is the one
    returned, its spec ``spec`` started at its θ.
    """
    if spec.variant not in VARIANTS or spec.base.family != "volvox":
        return out, None
    j, before = spec.fitted.index(name), out[3]
    t0, best, winner, rows = time.perf_counter(), None, "", []
    for label, start in other_starts(spec, {name: value}):
        try:
            r = fit(start, data, RETRY_METHOD, nodes=nodes, tol=tol)
        except _FAILURES as exc:
            rows.append({"from": label, "E_fit": None, "failed": f"{type(exc).__name__}: {exc}"})
            continue
        rows.append({"from": label, "E_fit": float(r.E_fit), "converged": bool(r.converged)})
        if float(r.E_fit) ** 2 < (before if best is None else float(best.E_fit) ** 2):
            best, winner = r, label
        if best is not None and (best.converged or float(best.E_fit) ** 2 <= threshold):
            break
    if best is not None:
        theta = np.insert([best.parameters[n] for n in spec.fitted if n != name], j, value)
        out = (started_at(spec, theta), theta, best.equilibrium, float(best.E_fit) ** 2,
               bool(best.converged))
    return out, Retry(float(value), before, winner, out[3], out[4], tuple(rows),
                      time.perf_counter() - t0)


def crossing(values: list, objective: list, start: tuple[float, float], direction: float,
             threshold: float, S_min: float) -> float:
    """Where the profile first crosses ``threshold`` walking out from ``start`` (θ̂ and its
    objective; ``values`` outward); ±inf (``direction``) if it never does.

    Interpolated linearly in √(S − S_min), S_min the profile's least objective,
    between the last step below and the first above: exact for a quadratic
    profile (a linear problem), whatever the grid's step, where interpolating S
    itself put the crossing inside by up to a step.  Where θ̂ itself lies above
    the threshold (a refit found an objective lower than the fit's by more than
    the threshold's height: rethresholded with a small σ²), the crossing is the
    first outward from the steps below it, and a side without any ends at θ̂
    (at θ̂ the interpolation divided 0 by 0).
    """
    last_v, S_start = start
    below = S_start <= threshold
    last_r, target = (np.sqrt(max(S - S_min, 0.0)) for S in (S_start, threshold))
    for v, s in zip(values, objective):
        if not np.isfinite(s):
            break
        r = np.sqrt(max(s - S_min, 0.0))
        if s > threshold and below:
            return float(last_v + (v - last_v) * (target - last_r) / (r - last_r))
        below = below or s <= threshold
        last_v, last_r = v, r
    return direction * np.inf if below else float(start[0])


def crossings(values, objective, fitted_value: float, threshold: float,
              S_min: float) -> tuple[float, float]:
    """The interval of a profile (its grid ``values``, increasing, ``fitted_value`` among
    them, and ``objective``) at ``threshold``: :func:`crossing` below and above the fitted
    value (:meth:`~morphoshell.fitting.profiles.Profile.rethreshold`, and the check of a
    record's interval, :mod:`morphoshell.fitting.profile_records`)."""
    values, objective = np.asarray(values, dtype=float), np.asarray(objective, dtype=float)
    j = int(np.searchsorted(values, fitted_value))
    below = (values[:j][::-1].tolist(), objective[:j][::-1].tolist())
    above = (values[j + 1:].tolist(), objective[j + 1:].tolist())
    start = (fitted_value, float(objective[j]))
    return (crossing(*below, start, -1.0, threshold, S_min),
            crossing(*above, start, 1.0, threshold, S_min))


def _first_above(objective: list, threshold: float) -> int | None:
    """The index of a side's first objective above ``threshold`` (None: none before the
    side's end or a failed refit)."""
    for i, s in enumerate(objective):
        if not np.isfinite(s):
            return None
        if s > threshold:
            return i
    return None


def refine_crossing(side: tuple[list, list, list, list], start: tuple, threshold: float,
                    refit: Callable) -> int:
    """Refits at the interpolated crossing of a side that crosses within its first two
    steps: at most :data:`REFINEMENTS`, each inserted into ``side`` where it belongs, each
    in the bracket the last left (false position: for a smooth profile closer than the
    midpoint).

    Whatever the steps the grid planned: a 20-point grid's side (10 steps, reaching twice
    the linear half-width) crosses near its fifth step and is not refined, but a grid asked
    for with few points (4 to 7: two or three steps a side) crosses within two, and there
    the crossing's refit is often the walk's last, in a worse minimum no neighbour's end
    reaches (audit: the synthetic t05's κ₁ on 6 points, its upper end 0.974 against the
    20-point 1.069; refined, 1.002).

    They are not retried from other starts (:func:`retried`: seconds each, for a fraction
    of a step); a refit that fails, or did not converge and lies above the step beyond it,
    is left out and ends the refinement.

    Parameters
    ----------
    side : (values, objectives, converged, ends)
        The side's walk, outward (lists, changed in place); ``ends[i]`` the state a refit
        at ``values[i]`` ended in (spec, θ, state), the next refit's start.
    start : (float, float, tuple)
        θ̂, S_min and the optimum's state (spec, θ, state).
    threshold : float
    refit : callable
        ``refit(end, value)``: the profile's refit at ``value`` from the state ``end``,
        its tuple (spec, θ, state, objective, converged) or None if it failed.

    Returns
    -------
    int
        The refits made.
    """
    values, objective, converged, ends = side
    i = _first_above(objective, threshold)
    if i is None or i > 1:
        return 0
    made = 0
    while made < REFINEMENTS:
        i = _first_above(objective, threshold)
        prev = (start[0], start[1]) if i == 0 else (values[i - 1], objective[i - 1])
        v = crossing([values[i]], [objective[i]], prev, 1.0, threshold, start[1])
        if not min(prev[0], values[i]) < v < max(prev[0], values[i]):
            break                   # (at an end of its step: a refit there adds nothing)
        out = refit(start[2] if i == 0 else ends[i - 1], v)
        made += 1
        if out is None or (not out[4] and out[3] > objective[i]):
            # (failed, or stalled above the step beyond it: above the profile, which rises
            # outward to its crossing; the audit's κ₁ at 1.62, 0.0030916 R² where the
            # retried 1.64 lies at 0.0030735, would have put the end at 1.599, not 1.620)
            break
        for items, item in zip(side, (v, out[3], out[4], out[:3])):
            items.insert(i, item)
    return made


def non_monotone(objective: list, tol: float) -> list[int]:
    """The refits of a side (``objective`` outward) that lie above one farther out by more
    than ``tol``, outermost first (a failed refit's NaN compares with none)."""
    out, low = [], np.inf
    for i in range(len(objective) - 1, -1, -1):
        if np.isfinite(objective[i]):
            if objective[i] > low + tol:
                out.append(i)
            low = min(low, objective[i])
    return out


def _above_chord(side: tuple, start: tuple, i: int, tol: float) -> bool:
    """Whether refit ``i`` lies above the chord of its neighbours (the optimum inside the
    first) in √(S − S_min) by more than ``tol`` in S: near its optimum a profile's
    √(S − S_min) is linear in θⱼ, and where it rises less further out it bends down, so a
    refit above the chord may have ended in a worse local minimum (an interval's end that
    a monotone side leaves unchecked).  False without an outer neighbour."""
    values, objective = side[:2]
    if i + 1 >= len(values) or not np.isfinite(objective[i + 1]):
        return False
    root = [np.sqrt(max(S - start[1], 0.0)) for S in (objective[i - 1] if i else start[1],
                                                       objective[i + 1])]
    inner = values[i - 1] if i else start[0]
    chord = root[0] + (root[1] - root[0]) * (values[i] - inner) / (values[i + 1] - inner)
    return objective[i] > start[1] + chord ** 2 + tol


def _untried(side: tuple, start: tuple, threshold: float, tol: float, tried: set,
             version: dict) -> tuple[int, int, str] | None:
    """The next refit of :func:`settle_side` and its neighbour (−1: the optimum) not tried from
    that neighbour's present end: a refit above one farther out from its outer neighbour,
    then its inner one; then the crossing's refit, and the one before it, from its outer
    neighbour, where it lies above their chord (:func:`_above_chord`)."""
    _, objective, _, ends = side
    pairs = [(i, k, ABOVE_FARTHER) for i in non_monotone(objective, tol) for k in (i + 1, i - 1)]
    first = _first_above(objective, threshold)
    if first is not None:
        # (the two refits the interpolated end rests on: the crossing's, then the last one
        # below the threshold, whose outer neighbour is the crossing's refit)
        pairs += [(i, i + 1, why) for i, why in ((first, CROSSING), (first - 1, BEFORE_CROSSING))
                  if i >= 0 and _above_chord(side, start, i, tol)]
    for i, k, why in pairs:
        if k < len(ends) and (k < 0 or ends[k] is not None) and (i, k, version[k]) not in tried:
            return i, k, why
    return None


def _from_neighbours(side: tuple, start: tuple, threshold: float, refit: Callable, name: str,
                     records: dict, budget: int) -> int:
    """Refits of a side from its neighbours' ends (:func:`settle_side`) until none is left
    untried or ``budget`` are made; each written into ``side`` where it lies lower, and into
    ``records`` (by value: the objective before, why, the table of starts, the winner, the
    time).  Returns the refits made."""
    values, objective, converged, ends = side
    tol = MONOTONE_TOL * (threshold - start[1])
    version = {k: 0 for k in range(-1, len(values))}  # (a neighbour refitted lower: a new start)
    tried = {(i, i - 1, 0) for i in range(len(values))}          # (the walk's own starts)
    for made in range(budget):
        pair = _untried(side, start, threshold, tol, tried, version)
        if pair is None:
            return made
        i, k, why = pair
        tried.add((i, k, version[k]))
        t0 = time.perf_counter()
        out, failure = refit(start[2] if k < 0 else ends[k], values[i])
        label = "optimum" if k < 0 else f"refit at {name} = {values[k]:.6g}"
        rec = records.setdefault(values[i], {"S_before": objective[i], "reason": why,
                                             "starts": [], "winner": "", "seconds": 0.0})
        rec["starts"].append({"from": label, "E_fit": None, "failed": failure} if out is None
                             else {"from": label, "E_fit": float(np.sqrt(out[3])),
                                   "converged": bool(out[4])})
        # (lower by the tolerance, as for monotonicity: less moves a crossing by < 2.5 % of
        # a step, and a profile whose refits agree so stays the same to the bit)
        if out is not None and out[3] < objective[i] - tol:
            objective[i], converged[i], ends[i], rec["winner"] = out[3], out[4], out[:3], label
            version[i] += 1
        rec["seconds"] += time.perf_counter() - t0
    return budget


def settle_side(side: tuple[list, list, list, list], start: tuple, threshold: float,
                refit: Callable, name: str) -> list[Retry]:
    """A side's walk made monotone from its neighbours' ends and its crossing refined.

    A profile is a minimum over the other parameters and rises outward from its minimum, so a
    refit above one farther out (by :data:`MONOTONE_TOL` of the threshold's height) ended in
    a worse local minimum than the profile's, although it may have converged.  Such refits
    are fitted again from the end of their outer neighbour (the farther one first), then
    their inner one (the optimum for the first step), outermost first, the lower kept, until
    the side is monotone or none is left untried from its neighbours' present ends; the
    refit that first exceeds the threshold and the one before it (the interval's end is
    interpolated between them) are also tried from their outer neighbour's end where they
    lie above their neighbours' chord in √(S − S_min) (:func:`_above_chord`: a profile
    there bends the wrong way).  A refit from a neighbour is kept
    where it lies lower by more than that tolerance.  At most :data:`NEIGHBOUR_REFITS`
    refits; then the crossing is refined (:func:`refine_crossing`), and its refinements
    are tried the same way.  A monotone side that bends upward costs nothing.

    Parameters
    ----------
    side, start, threshold
        As :func:`refine_crossing`.
    refit : callable
        ``refit(end, value)``: the profile's refit at ``value`` from the state ``end``, its
        tuple (spec, θ, state, objective, converged) or None if it failed, and the failure's
        message.
    name : str
        θⱼ's name (the records' labels).

    Returns
    -------
    list of Retry
        One per value refitted from a neighbour (:attr:`Retry.reason` says why; ``winner``
        "" where none lay lower).
    """
    records: dict = {}
    made = _from_neighbours(side, start, threshold, refit, name, records, NEIGHBOUR_REFITS)
    if refine_crossing(side, start, threshold, lambda end, value: refit(end, value)[0]):
        _from_neighbours(side, start, threshold, refit, name, records, NEIGHBOUR_REFITS - made)
    return [Retry(float(v), r["S_before"], r["winner"],
                  float(side[1][side[0].index(v)]), bool(side[2][side[0].index(v)]),
                  tuple(r["starts"]), r["seconds"], r["reason"]) for v, r in records.items()]


def not_monotone_note(name: str, side: tuple[list, list], threshold: float, S_min: float,
                      where: str) -> str:
    """A warning (logged, and returned for the profile's note) where a side (values and
    objectives, outward; ``where``: "below" or "above") is still not monotone after
    :func:`settle_side`: its interval's end may lie further out.  "" where it is."""
    values, objective = side
    bad = non_monotone(objective, MONOTONE_TOL * (threshold - S_min))
    if not bad:
        return ""
    pairs = []
    for i in sorted(bad):
        k = i + 1 + int(np.nanargmin(objective[i + 1:]))
        pairs.append(f"E_fit^2 {objective[i]:.6g} R^2 at {name} = {values[i]:.6g} above "
                     f"{objective[k]:.6g} at {values[k]:.6g}")
    text = (f"the profile of {name} is not monotone {where} the fit after refits from the "
            f"neighbours' ends ({'; '.join(pairs)}): the interval's end there may lie "
            f"further out")
    log.warning("profiles: %s", text)
    return text
