"""Input checks shared by the modules: one message format for bad values."""
from __future__ import annotations

import math
from typing import Any, Mapping, TypeVar

import numpy as np

__all__ = ["real", "lookup"]

T = TypeVar("T")


def real(name: str, value: Any) -> float:
    """``value`` as a finite float, or ValueError naming it (bools are not numbers)."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ValueError(f"{name} = {value!r} must be a real number")
    value = float(value)
    if not math.isfinite(value):
        raise ValueError(f"{name} = {value!r} must be finite")
    return value


def lookup(registry: Mapping[str, T], name: str, what: str) -> T:
    """``registry[name]``, or ValueError listing the valid names."""
    try:
        return registry[name]
    except (KeyError, TypeError):
        raise ValueError(f"unknown {what} {name!r}; choose one of {sorted(registry)}") from None
