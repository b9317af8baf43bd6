"""Saved equilibria read back: the JSON of ``solve --json`` (:meth:`Equilibrium.to_dict`),
and either state of ``ablate --json`` (``which="pre"`` or ``"post"``).

A saved result holds its problem, its energy, how it was solved and every field at
its points, but not the unknowns and multipliers of its mesh: read back, it is like
another route's result (a BVP solution).  It plots, tabulates and gives its
observables as it did, and as a ``warm_start`` it is carried onto the solver's mesh
(interpolated in s: Newton then converges on its branch in a few iterations).  Its
error estimate is restored as written (the estimated values are the result's own).
"""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from ..solvers.refinement import error_estimate
from ..solvers.results import FIELDS, Equilibrium, ErrorEstimate, SolverStats
from .problem_files import problem_of_record, read_json
from .provenance import note_unknown

__all__ = ["load_equilibrium", "equilibrium_of_record"]

#: The entries of a saved equilibrium (:meth:`Equilibrium.to_dict`, and what ``solve
#: --json`` adds): others are not read, and :func:`load_equilibrium` warns of them.
KNOWN = ("problem", "converged", "energy", "units", "solver", "error_estimate", "edge_start",
         "edge_end", *FIELDS, "settings", "provenance")
#: Entries of a saved solver block that are :class:`SolverStats` fields (the rest are details).
_STATS = ("method", "iterations", "seconds", "status", "nodes", "build_seconds")
#: Other results' JSON, told by their keys: (keys, what it is, what to use instead).  A sweep's
#: or a branch's has no fields either, but it is not an equilibrium saved without them.
_OTHERS = (
    (("parameters", "E_fit"), "a fit's record",
     "read it with morphoshell.fitting.load_fit, or its shell with "
     "morphoshell.workflows.fitted_problem"),
    (("axes", "rows"), "a sweep's JSON",
     "its rows hold values at the grid's points, not shapes: save a point's shape with "
     "morphoshell solve PROBLEM --set KEY=VALUE --json (a sweep keeps none)"),
    (("pre", "post"), "an ablation's JSON",
     "it holds two equilibria: read one with load_equilibrium(path, which='pre') (the intact "
     "shell) or which='post' (after the cut), or equilibrium_of_record(record['pre'])"),
    (("parameter", "points"), "a branch's JSON",
     "its points hold values along the branch, not shapes: in Python a point's shape is "
     "follow_branch(...).points[i].equilibrium (its to_dict() reads back here)"),
)


def equilibrium_of_record(record: Mapping[str, Any], where: str = "the record") -> Equilibrium:
    """The :class:`Equilibrium` of a saved result's record (:meth:`Equilibrium.to_dict`).

    Parameters
    ----------
    record : mapping
        With ``problem``, ``energy``, ``solver`` and the arrays of :data:`FIELDS`
        (written by ``solve --json`` or ``to_dict(arrays=True)``).
    where : str
        The file or record, for messages.

    Returns
    -------
    Equilibrium
        Without mesh unknowns (``x`` None); with its error estimate if it was saved.

    Raises
    ------
    ValueError
        A fit's record, a sweep's, an ablation's or a branch's JSON, no problem, a missing
        or non-numeric
        field, fields of different lengths, or points s not increasing (the entry named).
    """
    for keys, what, instead in _OTHERS:
        if all(k in record for k in keys):
            raise ValueError(f"{where} is {what} (keys {', '.join(keys)}), not an "
                             f"equilibrium's: {instead}")
    problem = problem_of_record(record, where)
    missing = [k for k in (*FIELDS, "energy") if k not in record]
    if missing:
        raise ValueError(f"{where}: no {', '.join(missing)}: a result saved without its "
                         f"arrays (to_dict(arrays=False)) cannot be read back")
    fields = {}
    for key in FIELDS:
        try:
            fields[key] = np.asarray(record[key], dtype=float)
        except (TypeError, ValueError):
            raise ValueError(f"{where}: {key} is not a list of numbers") from None
    lengths = {len(v) for v in fields.values()}
    if len(lengths) != 1 or not all(v.ndim == 1 for v in fields.values()):
        raise ValueError(f"{where}: the fields have different lengths {sorted(lengths)}")
    if not np.all(np.diff(fields["s"]) > 0):
        raise ValueError(f"{where}: s must increase")
    solver = dict(record.get("solver") or {})
    stats = SolverStats(str(solver.get("method", "direct")), int(solver.get("iterations", 0)),
                        float(solver.get("seconds", 0.0)), str(solver.get("status", "unknown")),
                        int(solver.get("nodes", len(fields["s"]))),
                        float(solver.get("build_seconds", 0.0)),
                        {k: v for k, v in solver.items() if k not in _STATS})
    eq = Equilibrium(problem=problem, **fields, energy=float(record["energy"]), solver=stats,
                     converged=bool(record.get("converged", True)))
    error = record.get("error_estimate")
    return eq if error is None else replace(eq, error=_error_estimate(error, eq, where))


def _error_estimate(record: Mapping[str, Any], eq: Equilibrium, where: str) -> ErrorEstimate:
    """The :class:`ErrorEstimate` of a saved ``error_estimate`` (:meth:`ErrorEstimate.to_dict`):
    the errors as written (None, JSON's NaN, back to NaN), the estimated values those of
    ``eq`` and the energy's floor of its problem, by :func:`~morphoshell.solvers.refinement.
    error_estimate` as ``solve()``'s."""
    try:
        errors = {k: float("nan") if v is None else float(v)
                  for k, v in dict(record["errors"]).items()}
        est = error_estimate(eq, errors, int(record["reference_nodes"]), int(record["order"]),
                             str(record.get("note", "")))
        return replace(est, nodes=int(record["nodes"]))
    except (KeyError, TypeError, ValueError):
        raise ValueError(f"{where}: error_estimate is not the record of an error estimate "
                         f"(errors, nodes, reference_nodes, order)") from None


#: The states of an ablation's JSON (``ablate --json``, :meth:`Ablation.to_dict`).
_STATES = ("pre", "post")


def load_equilibrium(path: str | Path, which: str | None = None) -> Equilibrium:
    """The equilibrium saved by ``solve --json`` (or :meth:`Equilibrium.to_dict`) at ``path``,
    or one state of an ablation saved by ``ablate --json``.

    Parameters
    ----------
    path : str or Path
        The JSON file.
    which : {"pre", "post"}, optional
        For an ablation's JSON (keys ``pre`` and ``post``), which state: the intact shell
        (``"pre"``) or the shell after the cut (``"post"``); required there, refused for
        a file of one equilibrium.

    Raises
    ------
    ValueError
        An unreadable file, not JSON, an ablation's JSON without ``which`` (or ``which``
        for another file), or a record :func:`equilibrium_of_record` refuses (the file
        named).
    """
    data = read_json(path)
    if not isinstance(data, dict):
        raise ValueError(f"{path}: expected the JSON object written by morphoshell solve --json")
    if which is None:
        eq = equilibrium_of_record(data, str(path))
        note_unknown(data, KNOWN, str(path), "load_equilibrium")
        return eq
    if which not in _STATES:
        raise ValueError(f"which={which!r}: the state of an ablation's JSON is one of "
                         f"{', '.join(map(repr, _STATES))}")
    if not all(isinstance(data.get(k), dict) for k in _STATES):
        raise ValueError(f"{path}: which={which!r} reads a state of an ablation's JSON (keys "
                         f"pre and post, ablate --json); this file has none: leave which out")
    eq = equilibrium_of_record(data[which], f"{path} ({which})")
    note_unknown(data[which], KNOWN, f"{path} ({which})", "load_equilibrium")
    return eq
