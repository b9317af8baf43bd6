"""Input checks shared by the modules: one message format for bad values."""
from __future__ import annotations

import math
import os
from typing import Any, Iterable, Mapping, Sequence, TypeVar

import numpy as np

__all__ = ["real", "lookup", "within", "integer", "flag", "text", "choice", "short", "instance",
           "name_list"]

T = TypeVar("T")


def real(name: str, value: Any) -> float:
    """``value`` as a finite float, or ValueError naming it (bools are not numbers)."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ValueError(f"{name} = {short(value)} must be a real number")
    value = float(value)
    if not math.isfinite(value):
        raise ValueError(f"{name} = {value!r} must be finite")
    return value


def within(name: str, value: Any, lo: float, hi: float, *, open_lo: bool = False,
           why: str = "") -> float:
    """``value`` as a finite float in [lo, hi] ((lo, hi] with ``open_lo``), or ValueError
    naming it, the interval and (``why``) the reason for it."""
    number = real(name, value)
    if not (lo < number if open_lo else lo <= number) or not number <= hi:
        interval = f"{'(' if open_lo else '['}{lo:g}, {hi:g}]"
        raise ValueError(f"{name} = {short(value)} must lie in {interval}"
                         + (f": {why}" if why else ""))
    return number


def integer(name: str, value: Any, lo: int, hi: int | None = None) -> int:
    """``value`` as an int in [lo, hi] (no upper bound without ``hi``), or ValueError naming it
    (bools and floats are not integers)."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < lo \
            or hi is not None and value > hi:
        bound = f"in [{lo}, {hi}]" if hi is not None else f">= {lo}"
        raise ValueError(f"{name} = {short(value)} must be an integer {bound}")
    return int(value)


def flag(name: str, value: Any) -> bool:
    """``value`` as a bool, or TypeError naming it: a string such as "no" is true and
    would silently mean the opposite (a user audit: ``continuation="no"`` continued)."""
    if not isinstance(value, (bool, np.bool_)):
        raise TypeError(f"{name} = {short(value)} must be True or False")
    return bool(value)


def lookup(registry: Mapping[str, T], name: str, what: str) -> T:
    """``registry[name]``, or ValueError listing the valid names."""
    try:
        return registry[name]
    except (KeyError, TypeError):
        raise ValueError(f"unknown {what} {short(name)}; choose one of {sorted(registry)}"
                         ) from None


def short(value: Any) -> str:
    """``repr(value)`` on one line, cut to 80 characters (a message names the value, not a
    screenful of it: an array's repr spans lines); a string or path whole up to 300 (its
    repr is one line, and a path cut short does not name the file)."""
    if isinstance(value, (str, os.PathLike)):
        text, limit = repr(value), 300
    else:
        text, limit = " ".join(repr(value).split()), 80
    return text if len(text) <= limit else text[:limit - 3] + "..."


def instance(name: str, value: Any, kind: type | tuple[type, ...], what: str) -> Any:
    """``value``, or TypeError naming it unless it is a ``kind``; ``what`` says what it must be
    and where one comes from (an audit: ``fit(Problem(...), data)`` raised "'Problem' object
    has no attribute 'base'" three calls deep)."""
    if not isinstance(value, kind):
        raise TypeError(f"{name} = {short(value)} must be {what}, not {type(value).__name__}")
    return value


def name_list(value: str | Sequence[str], name: str = "names") -> list[str]:
    """A list of names from a sequence or a comma-separated string (as the command line's
    options take them): a single string is not split into its letters; TypeError naming
    ``name`` for anything else (an audit: ``methods=3`` raised "'int' object is not
    iterable")."""
    if isinstance(value, str):
        return [v.strip() for v in value.split(",") if v.strip()]
    if isinstance(value, (bytes, Mapping)) or not isinstance(value, Iterable):
        raise TypeError(f"{name} = {short(value)} must be a name, names separated by commas "
                        f"or a sequence of names, not {type(value).__name__}")
    return list(value)


def text(name: str, value: Any, nullable: bool = False) -> str:
    """``value``, a string ("" for None when ``nullable``), or ValueError naming it (a
    record's entry read back: a note, a message)."""
    if nullable and value is None:
        return ""
    if not isinstance(value, str):
        raise ValueError(f"{name} = {short(value)} must be a string"
                         + (" or null" if nullable else ""))
    return value


def choice(name: str, value: Any, choices: Iterable[str], nullable: bool = False) -> str | None:
    """``value``, one of ``choices`` (or None when ``nullable``), or ValueError naming it and
    listing them (a record's entry read back: a method, a variant)."""
    if not (nullable and value is None or isinstance(value, str) and value in choices):
        raise ValueError(f"{name} = {short(value)} must be one of {list(choices)}"
                         + (" or null" if nullable else ""))
    return value
