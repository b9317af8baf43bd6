"""Ipopt's options checked before a solver is built: a linear solver or an option that Ipopt
would refuse is named in a ValueError, instead of a raw CasADi ``RuntimeError`` with
Ipopt's option table dumped on standard output, after the transcription is built.

Ipopt checks its options when CasADi creates the solver and loads a linear solver's
library only when it first solves.  :func:`check_ipopt_options` therefore creates and
solves a one-unknown problem with the options (a few milliseconds), with standard
output redirected, since Ipopt prints its refusals there; a refusal is
re-raised naming the option, its value and what Ipopt accepts.  An option set
that passed is remembered (per process); the defaults are never probed.

A solver whose library cannot be loaded at all is refused before the probe: Ipopt's
ma97 without ``libhsl.so`` crashes the process (a segmentation fault) instead of
returning ``Invalid_Option`` as the other HSL solvers do.
"""
from __future__ import annotations

import contextlib
import ctypes
import io
import re
from typing import Any, Mapping

import casadi as ca

from .ipopt import IPOPT_DEFAULTS, load_ipopt

__all__ = ["LINEAR_SOLVERS", "BUNDLED_SOLVERS", "check_ipopt_options"]

#: Ipopt's linear solvers (its option ``linear_solver``; Ipopt 3.14 as CasADi bundles it,
#: less ``custom``, which needs a solver object).  MUMPS and SPRAL are built in; the HSL
#: ones load at run time from ``libhsl.so`` (Ipopt's option ``hsllib``), Pardiso from
#: ``libpardiso.so`` (``pardisolib``).
LINEAR_SOLVERS = ("mumps", "ma27", "ma57", "ma77", "ma86", "ma97", "spral", "pardiso")
#: The linear solvers that need no library of the user's.
BUNDLED_SOLVERS = ("mumps", "spral")
#: Ipopt's option naming the library a solver loads at run time, and the names it tries by
#: default (Ipopt 3.14: ``libhsl.so``, then ``libcoinhsl.so``).
_LIBRARIES = {"hsllib": ("libhsl.so", "libcoinhsl.so"), "pardisolib": ("libpardiso.so",)}

#: Option sets (linear solver, options) that passed :func:`check_ipopt_options`.
_PASSED: set = set()

#: What CasADi's type assertions mean, for its "type mismatch" of an option's value.
_KINDS = {"is_int": "an integer", "is_double": "a number", "is_string": "a string",
          "is_bool": "a boolean"}


def check_ipopt_options(linear_solver: Any = "mumps",
                        ipopt_options: Mapping[str, Any] | None = None) -> None:
    """Raise unless Ipopt accepts ``linear_solver`` and ``ipopt_options``.

    Parameters
    ----------
    linear_solver : str
        One of :data:`LINEAR_SOLVERS`, whose library Ipopt can load.
    ipopt_options : mapping of str, optional
        Ipopt's options (names and values as Ipopt's documentation gives them).

    Raises
    ------
    ValueError
        A linear solver Ipopt does not know or cannot load, or an option
        Ipopt refuses (unknown, of the wrong type, or out of its range),
        named with its value and what Ipopt accepts.
    TypeError
        ``ipopt_options`` not a mapping with string keys.
    """
    if not isinstance(linear_solver, str) or linear_solver not in LINEAR_SOLVERS:
        raise ValueError(f"linear_solver = {linear_solver!r}: choose one of "
                         f"{list(LINEAR_SOLVERS)}")
    if ipopt_options is None:
        ipopt_options = {}
    if not isinstance(ipopt_options, Mapping):
        raise TypeError(f"ipopt_options = {ipopt_options!r} must be a mapping of Ipopt's "
                        f"option names to values")
    for name in ipopt_options:
        if not isinstance(name, str):
            raise TypeError(f"ipopt_options: the key {name!r} must be the name of an Ipopt "
                            f"option (a string)")
    if linear_solver == "mumps" and not ipopt_options:
        return                                   # the defaults: every solver uses them
    key = (linear_solver, tuple(sorted((k, repr(v)) for k, v in ipopt_options.items())))
    if key in _PASSED:
        return
    # one option at a time first, so that a refusal names the option refused
    for name, value in ipopt_options.items():
        said = _refusal({name: value})
        if said:
            raise ValueError(f"ipopt_options: {name} = {value!r} is refused by Ipopt: {said}")
    said = (_missing_library(linear_solver, ipopt_options)
            or _refusal({"linear_solver": linear_solver, **ipopt_options}))
    if said and linear_solver not in BUNDLED_SOLVERS:
        raise ValueError(
            f"linear_solver = {linear_solver!r}: Ipopt cannot load it ({said}): the HSL solvers "
            f"(ma27, ma57, ...) load only from libhsl.so on the library path (or Ipopt's option "
            f"hsllib), pardiso from libpardiso.so (pardisolib); 'mumps' is bundled")
    if said:
        raise ValueError(f"ipopt_options = {dict(ipopt_options)!r} are refused by Ipopt "
                         f"together: {said}")
    _PASSED.add(key)


def _missing_library(linear_solver: str, options: Mapping[str, Any]) -> str:
    """Why the library of a solver that Ipopt loads at run time cannot be loaded, or ""
    (bundled, or loadable: the probe then decides)."""
    if linear_solver in BUNDLED_SOLVERS:
        return ""
    option = "pardisolib" if linear_solver == "pardiso" else "hsllib"
    names = (options[option],) if option in options else _LIBRARIES[option]
    reasons = []
    for name in names:
        try:
            ctypes.CDLL(str(name))
            return ""
        except OSError as exc:
            reasons.append(str(exc))
    return "; ".join(reasons)


def _refusal(options: Mapping[str, Any]) -> str:
    """Why Ipopt refuses ``options`` (over :data:`IPOPT_DEFAULTS`) on a one-unknown problem,
    or "" if it solves it."""
    load_ipopt()
    x = ca.MX.sym("x")
    with _stdout_captured() as printed:
        try:
            probe = ca.nlpsol("ipopt_options", "ipopt", {"x": x, "f": (x - 1) ** 2}, {
                "ipopt": {**IPOPT_DEFAULTS, **options}, "print_time": False,
                "error_on_fail": False})
            probe(x0=0.0)
            status = probe.stats().get("return_status", "")
            error = "" if status != "Invalid_Option" else "status 'Invalid_Option'"
        except RuntimeError as exc:
            error = str(exc)
    return _reason(error, printed[0]) if error else ""


def _reason(error: str, printed: str) -> str:
    """Ipopt's reason for a refusal in one line, from what it printed (its "Setting: ..."
    line and the valid range or settings) or else from CasADi's message."""
    lines = [line.strip() for line in printed.splitlines() if line.strip()]
    setting = next((line for line in lines if line.startswith("Setting:")), "")
    if setting:
        ranges = [line for line in lines if "<" in line and "(" in line]
        valid = [line.split()[0] for line in printed.splitlines() if line.startswith("\t")]
        reason = setting.split(". Check")[0]
        if ranges:
            return f"{reason} (valid: {ranges[0]}, the default in parentheses)"
        return f"{reason} (valid: {', '.join(valid)})" if valid else reason
    kind = re.search(r'Assertion "(\w+)\(\)" failed', error)
    if kind and "type mismatch" in error:
        return f"it must be {_KINDS.get(kind.group(1), 'of another type')}"
    last = error.strip().splitlines()[-1] if error.strip() else error
    return re.sub(r"^\.\.\./\S+:\d+: ", "", last)


@contextlib.contextmanager
def _stdout_captured():
    """Yield a list whose item receives what is printed meanwhile through Python's
    ``sys.stdout``, where CasADi's Python module sends Ipopt's messages."""
    printed = [""]
    text = io.StringIO()
    try:
        with contextlib.redirect_stdout(text):
            yield printed
    finally:
        printed[0] = text.getvalue()
