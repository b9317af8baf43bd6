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
retry's objectives, stored as E_fit (R) and read as E_fit² (to round-off).
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from .._runtime.validate import flag, real, within
from ..io.problem_files import read_json
from .bilevel import METHODS
from .profile_noise import NOISE_SOURCES
from .profile_retry import Retry
from .profiles import Profile

__all__ = ["load_profiles", "profile_from_dict"]

#: How an open side of a profile ended (:attr:`Profile.side_ends`).
SIDE_ENDS = ("grid", "bound", "failed")


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
                          for i, v in enumerate(_list(r, "objective", m))])
    converged = np.array([flag(f"converged[{i}]", c)
                          for i, c in enumerate(_list(r, "converged", m))], dtype=bool)
    interval = tuple(bound if v is None else real(f"interval[{i}]", v)
                     for i, (v, bound) in enumerate(zip(_list(r, "interval", 2),
                                                        (-math.inf, math.inf))))
    fitted = real("fitted_value", r["fitted_value"])
    if fitted not in values:
        raise ValueError(f"fitted_value = {fitted!r} must be one of the grid's values")
    return Profile(
        name=r["name"], fitted_value=fitted, values=values, objective=objective,
        converged=converged, interval=interval,
        threshold=within("threshold", r["threshold"], 0, math.inf),
        S_min=within("S_min", r["S_min"], 0, math.inf),
        sigma2=within("sigma2", r["sigma2"], 0, math.inf),
        sigma2_source=_choice("sigma2_source", r["sigma2_source"],
                              (*NOISE_SOURCES[1:], "given")),
        confidence=within("confidence", r["confidence"], 0, 1, open_lo=True),
        flat=flag("flat", r["flat"]), method=_choice("method", r["method"], METHODS),
        note=_text("note", r["note"]),
        dof=math.inf if r.get("sigma2_dof") is None else within(
            "sigma2_dof", r["sigma2_dof"], 1, math.inf),
        side_ends=tuple(_choice(f"open_sides[{i}]", end, SIDE_ENDS, nullable=True) or "grid"
                        for i, end in enumerate(_list(r, "open_sides", 2))),
        retries=tuple(_retry(row, f"retries[{i}]")
                      for i, row in enumerate(_list(r, "retries") if "retries" in r else [])))


def _retry(r: Any, key: str) -> Retry:
    """A :class:`Retry` of its record (``Retry.to_dict``)."""
    if not isinstance(r, Mapping):
        raise ValueError(f"{key} must be an object (a retried refit's record)")
    starts = _list(r, "starts")
    if not all(isinstance(row, Mapping) for row in starts):
        raise ValueError(f"{key}.starts must be a list of objects")
    return Retry(value=real(f"{key}.value", r["value"]),
                 S_before=within(f"{key}.E_fit_before", r["E_fit_before"], 0, math.inf) ** 2,
                 winner=_text(f"{key}.kept", r["kept"], nullable=True),
                 S=within(f"{key}.E_fit", r["E_fit"], 0, math.inf) ** 2,
                 converged=flag(f"{key}.converged", r["converged"]),
                 starts=tuple(dict(row) for row in starts),
                 seconds=within(f"{key}.seconds", r.get("seconds", 0.0), 0, math.inf),
                 reason=_text(f"{key}.reason", r.get("reason"), nullable=True))


def _list(r: Mapping, key: str, length: int | None = None) -> list:
    """``r[key]``, a list (of ``length`` items if given)."""
    value = r[key]
    if not isinstance(value, list) or length is not None and len(value) != length:
        size = "" if length is None else f" of {length} items"
        raise ValueError(f"{key} = {value!r} must be a list{size}")
    return value


def _choice(key: str, value: Any, choices, nullable: bool = False) -> str | None:
    """``value``, one of ``choices`` (or None when ``nullable``)."""
    if not (nullable and value is None or isinstance(value, str) and value in choices):
        raise ValueError(f"{key} = {value!r} must be one of {list(choices)}"
                         + (" or null" if nullable else ""))
    return value


def _text(key: str, value: Any, nullable: bool = False) -> str:
    """``value``, a string ("" for None when ``nullable``)."""
    if nullable and value is None:
        return ""
    if not isinstance(value, str):
        raise ValueError(f"{key} = {value!r} must be a string" + (" or null" if nullable else ""))
    return value
