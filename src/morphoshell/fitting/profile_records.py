"""Profiles read back from a fit's JSON: replot or rethreshold them without refitting.

``morphoshell fit --profile NAMES --json FILE`` (or :meth:`Profile.to_dict`) writes
each profile's grid, objective and threshold under ``profiles``;
:func:`load_profiles` reads them back as :class:`~morphoshell.fitting.profiles.Profile`
objects, every entry checked and a bad one named in one line (the file and the
entry), as :func:`morphoshell.fitting.load_fit` does for the fit itself.

The grid, objective, interval, threshold and σ² come back to the bit.  Two things
are not stored and come back as what they stand for: how a side whose interval
closes was walked (read as ``"grid"``; only an open side's reason is kept, and
only it enters :meth:`Profile.open_sides` and :meth:`Profile.verdict`), and a
retry's objectives, stored as E_fit (R) and read as E_fit² (to round-off).  The entries
derived from others (S_min, threshold, interval, flat) must agree with the objective, σ²
and confidence they come from: an edit of one is refused, by name.
"""
from __future__ import annotations

import logging
import math
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from .._runtime.validate import choice, flag, real, short, text, within
from ..io.problem_files import read_json
from .bilevel import METHODS
from .profile_noise import NOISE_SOURCES, threshold_quantile
from .profile_retry import Retry, crossings
from .profiles import LOWER, Profile, is_flat

log = logging.getLogger(__name__)

__all__ = ["load_profiles", "profile_from_dict"]

#: How an open side of a profile ended (:attr:`Profile.side_ends`).
SIDE_ENDS = ("grid", "bound", "failed")
#: How far (relative) a record's threshold and interval may lie from those recomputed from
#: its objective, S_min, σ² and confidence (:func:`_check_derived`).  They are the same
#: formulas on the same numbers (JSON gives floats back to the bit): an unedited record's
#: agree exactly (47 profiles of recent fits' JSON, and audit 23's).  The slack is for another
#: SciPy's χ²/F quantile (accurate to ~1e-14 relative), which the interval's interpolation in
#: √(S − S_min) amplifies by threshold/(threshold − S_min) (~20 for a 95 % profile of a fit to
#: traces): 1e-9 leaves five orders of magnitude and still refuses any edit a reader would notice.
DERIVED_RTOL = 1e-9


def load_profiles(path: str | Path) -> dict[str, Profile]:
    """The profiles saved in a fit's JSON (``morphoshell fit --profile … --json``).

    Parameters
    ----------
    path : str or Path
        The fit's JSON file.

    Returns
    -------
    dict of str to Profile
        By parameter name, in the file's order (empty when the fit was not profiled).
        Of a run cut short (``"complete": false``) the finished ones, with a warning
        naming those not done.

    Raises
    ------
    ValueError
        An unreadable file, not JSON, or an entry of ``profiles`` that is not what
        :meth:`Profile.to_dict` writes (the file and the entry named).

    Examples
    --------
    >>> from morphoshell.fitting.profile_records import load_profiles
    >>> from morphoshell.plotting import plot_profiles
    >>> profiles = load_profiles("fit.json")                    # doctest: +SKIP
    >>> plot_profiles({n: p.rethreshold(1e-5) for n, p in profiles.items()})  # doctest: +SKIP
    """
    record = read_json(path)
    profiles = record.get("profiles", {}) if isinstance(record, dict) else None
    if not isinstance(profiles, dict):
        raise ValueError(f"{path}: expected the JSON object of morphoshell fit --json, its "
                         f"'profiles' an object of profiles by parameter name")
    if record.get("complete") is False:
        # (audit 27 F11: a partial file read back as if its profiles were all asked for)
        log.warning("%s: a run cut short (complete: false): %s; read the profiles it "
                    "finished: %s", path, record.get("not_done") or "some not done",
                    ", ".join(profiles) or "none")
    return {name: profile_from_dict(entry, f"{path}: profiles.{name}", name)
            for name, entry in profiles.items()}


def profile_from_dict(record: Any, where: str = "profile", name: str | None = None) -> Profile:
    """The :class:`Profile` of its record (:meth:`Profile.to_dict`), every entry checked.

    Parameters
    ----------
    record : dict
        The record.
    where : str
        What the messages call it (a file and the entry's place in it).
    name : str, optional
        The parameter the record must be of (its key in a fit's JSON).

    Raises
    ------
    ValueError
        The record is not such a record: one line naming ``where`` and the entry.
    """
    if not isinstance(record, Mapping):
        raise ValueError(f"{where}: expected an object (a profile's record)")
    try:
        return _profile(record, name)
    except KeyError as exc:
        raise ValueError(f"{where}: the entry {exc.args[0]!r} is missing") from None
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{where}: {exc}") from None


def _profile(r: Mapping, name: str | None) -> Profile:
    """The checks of :func:`profile_from_dict` (KeyError for a missing entry)."""
    if not isinstance(r["name"], str) or name is not None and r["name"] != name:
        raise ValueError(f"name = {r['name']!r} must be {name!r}, the profile's key")
    values = np.array([real(f"values[{i}]", v) for i, v in enumerate(_list(r, "values"))])
    m = len(values)
    if m < 1 or np.any(np.diff(values) <= 0):
        raise ValueError("values must be a non-empty list of increasing numbers")
    objective = np.array([math.nan if v is None else within(f"objective[{i}]", v, 0, math.inf)
                          for i, v in enumerate(_list(r, "objective", m, "values"))])
    converged = np.array([flag(f"converged[{i}]", c)
                          for i, c in enumerate(_list(r, "converged", m, "values"))], dtype=bool)
    interval = tuple(bound if v is None else real(f"interval[{i}]", v)
                     for i, (v, bound) in enumerate(zip(_list(r, "interval", 2),
                                                        (-math.inf, math.inf))))
    fitted = real("fitted_value", r["fitted_value"])
    if fitted not in values:
        raise ValueError(f"fitted_value = {fitted!r} must be one of the grid's values")
    return _check_derived(Profile(
        name=r["name"], fitted_value=fitted, values=values, objective=objective,
        converged=converged, interval=interval,
        threshold=within("threshold", r["threshold"], 0, math.inf),
        S_min=within("S_min", r["S_min"], 0, math.inf),
        sigma2=within("sigma2", r["sigma2"], 0, math.inf, open_lo=True),
        sigma2_source=choice("sigma2_source", r["sigma2_source"],
                             (*NOISE_SOURCES[1:], "given")),
        confidence=within("confidence", r["confidence"], 0, 1, open_lo=True),
        flat=flag("flat", r["flat"]), method=choice("method", r["method"], METHODS),
        note=text("note", r["note"]),
        dof=math.inf if r.get("sigma2_dof") is None else within(
            "sigma2_dof", r["sigma2_dof"], 1, math.inf),
        side_ends=tuple(choice(f"open_sides[{i}]", end, SIDE_ENDS, nullable=True) or "grid"
                       for i, end in enumerate(_list(r, "open_sides", 2))),
        retries=tuple(_retry(row, f"retries[{i}]")
                      for i, row in enumerate(_list(r, "retries") if "retries" in r else []))))


def _check_derived(p: Profile) -> Profile:
    """``p``, or ValueError naming the entry that disagrees with what it is derived from:
    ``S_min`` the least objective, ``threshold`` S_min + σ² q (or, as the profile sets it
    where no refit lies lower than the fit by :data:`LOWER`, the fit's objective + σ² q),
    ``interval`` the crossings of the threshold (:func:`crossings`), ``flat`` whether a side
    is open up to the grid's end or a bound.  An edit of one of them (an audit: a reversed
    interval, one without the fitted value, S_min 1, which rethreshold then made
    (-inf, inf)) would otherwise be printed and replotted as the profile's."""
    if not p.confidence < 1:
        raise ValueError(f"confidence = {p.confidence!r} must lie in (0, 1): at 1 the "
                         f"threshold's quantile is infinite")
    least = float(np.nanmin(p.objective)) if np.any(np.isfinite(p.objective)) else math.nan
    if p.S_min != least:       # (the least of the stored numbers is one of them: exact)
        raise ValueError(f"S_min = {p.S_min!r} must be the least objective of the profile "
                         f"({least!r})")
    q = threshold_quantile(p.confidence, p.dof)
    at_fit = float(p.objective[int(np.searchsorted(p.values, p.fitted_value))])
    bases = (p.S_min,) + ((at_fit,) if p.S_min >= (1 - LOWER) * at_fit else ())
    if not any(math.isclose(p.threshold, base + p.sigma2 * q, rel_tol=DERIVED_RTOL)
               for base in bases):
        raise ValueError(f"threshold = {p.threshold!r} must be S_min + sigma2 * q = "
                         f"{p.S_min + p.sigma2 * q!r} (q = {q:.6g}: confidence "
                         f"{p.confidence:g}, sigma2_dof {p.dof:g})")
    interval = crossings(p.values, p.objective, p.fitted_value, p.threshold, p.S_min)
    slack = DERIVED_RTOL * (p.values[-1] - p.values[0])
    if not all(a == b or math.isclose(a, b, rel_tol=DERIVED_RTOL, abs_tol=slack)
               for a, b in zip(p.interval, interval)):
        raise ValueError(f"interval = {_bounds(p.interval)} must be where the objective "
                         f"crosses the threshold, {_bounds(interval)}")
    if p.flat != is_flat(p.interval, p.side_ends):
        raise ValueError(f"flat = {p.flat} disagrees with the interval {_bounds(p.interval)} "
                         f"and open_sides")
    return p


def _bounds(interval: tuple[float, float]) -> str:
    """An interval as the record writes it (null for an open side)."""
    return "[" + ", ".join("null" if math.isinf(v) else repr(v) for v in interval) + "]"


def _retry(r: Any, key: str) -> Retry:
    """A :class:`Retry` of its record (``Retry.to_dict``)."""
    if not isinstance(r, Mapping):
        raise ValueError(f"{key} must be an object (a retried refit's record)")
    starts = _list(r, "starts")
    if not all(isinstance(row, Mapping) for row in starts):
        raise ValueError(f"{key}.starts must be a list of objects")
    return Retry(value=real(f"{key}.value", r["value"]),
                 S_before=within(f"{key}.E_fit_before", r["E_fit_before"], 0, math.inf) ** 2,
                 winner=text(f"{key}.kept", r["kept"], nullable=True),
                 S=within(f"{key}.E_fit", r["E_fit"], 0, math.inf) ** 2,
                 converged=flag(f"{key}.converged", r["converged"]),
                 starts=tuple(dict(row) for row in starts),
                 seconds=within(f"{key}.seconds", r.get("seconds", 0.0), 0, math.inf),
                 reason=text(f"{key}.reason", r.get("reason"), nullable=True))


def _list(r: Mapping, key: str, length: int | None = None, like: str = "") -> list:
    """``r[key]``, a list (of ``length`` items if given: as many as ``like`` has, if given,
    whose length the message names too, since either may be the one edited)."""
    value = r[key]
    if not isinstance(value, list):
        raise ValueError(f"{key} = {short(value)} must be a list")
    if length is not None and len(value) != length:
        raise ValueError(f"{key} has {len(value)} items, {like} {length}: one for each of "
                         f"{like}" if like else f"{key} = {short(value)} must be a list of "
                         f"{length} items")
    return value
