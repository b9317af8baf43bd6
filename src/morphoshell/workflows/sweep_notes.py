"""What a sweep says about its rows: each caveat once, counting and naming the points.

``solve()`` says of one shell what is wrong with it: walls that pass through each
other (:func:`morphoshell.solvers.contact.warn_if_walls_overlap`), an error estimate
above :data:`~morphoshell.solvers.refinement.COARSE` (the mesh does not resolve the
shell), an estimate it could not make; its continuation notes where it snapped
through a fold or switched branches.  A sweep of hundreds of points would repeat
each hundreds of times, or, as it did, say nothing.  :func:`summary` says each once
after the sweep, with the number of points and their values
(:meth:`~morphoshell.workflows.sweep_results.SweepResult.points`); the rows keep the
flags (``walls_cross``, ``event``, the ``*_error`` columns, ``status``).
"""
from __future__ import annotations

import logging
from typing import Mapping, Sequence

import numpy as np

from ..solvers.refinement import COARSE
from .sweep_results import SweepResult

__all__ = ["summary", "log_summary"]

log = logging.getLogger("morphoshell.workflows.sweeps")


def summary(result: SweepResult, coarse: Mapping[int, tuple[str, float]],
            unestimated: Mapping[int, str], jumped: Sequence[int] = ()
            ) -> list[tuple[int, str]]:
    """The lines a sweep logs about its rows: (logging level, line), warnings first.

    Parameters
    ----------
    result : SweepResult
    coarse : mapping
        Row → (the quantity, its error) of its worst estimate above ``COARSE``
        (:func:`~morphoshell.solvers.refinement.too_coarse`).
    unestimated : mapping
        Row → why the estimate asked for there could not be made.
    jumped : sequence of int
        Rows whose warm path from the point before left its branch (past a fold or
        branch point: :mod:`~morphoshell.workflows.sweep_steps`), solved by ``solve()``'s
        route instead.

    Returns
    -------
    list of (int, str)
        Failed points, walls that cross, coarse meshes, missing estimates
        (warnings), then snaps and switches and the warm path's jumps (notes), each
        where there is one.
    """
    c, n = result.columns, len(result)
    lines = []
    failed = c["message"] != ""
    if failed.any():
        statuses = ", ".join(sorted(set(c["status"][failed])))
        lines.append((logging.WARNING, f"sweep: {failed.sum()} of {n} points failed "
                      f"({result.points(failed)}: {statuses}); their rows keep the status "
                      f"and the message"))
    walls = c["walls_cross"]
    if walls.any():
        lines.append((logging.WARNING, f"sweep: the shell's walls pass through each other at "
                      f"{walls.sum()} of {n} points ({result.points(walls)}; column "
                      f"walls_cross): the model has no self-contact, so these shapes are "
                      f"minima of the model but not physical ones"))
    if coarse:
        rows = sorted(coarse)
        key, worst = max((coarse[i] for i in rows), key=lambda kv: kv[1])
        scale = ("relative to the observables" if result.ablate else
                 "R or rad; the energy relative")
        lines.append((logging.WARNING, f"sweep: the error estimates exceed {COARSE:g} ({scale}) "
                      f"at {len(rows)} of {n} points "
                      f"({result.points(rows)}; the largest: {key} {worst:.2g}): the mesh is "
                      f"too coarse for these shells; refine it (nodes=, --nodes)"))
    if unestimated:
        rows = sorted(unestimated)
        why = "; ".join(sorted(set(unestimated.values())))
        lines.append((logging.WARNING, f"sweep: no error estimate at {len(rows)} of "
                      f"{int(np.sum(~failed))} points where one was asked for "
                      f"({result.points(rows)}): {why}; their *_error columns are empty"))
    for word, what in (("snapped", "snapped through a fold"),
                       ("switched", "switched branches at a branch point")):
        rows = np.array([word in e for e in c["event"]])
        if rows.any():
            lines.append((logging.INFO, f"sweep: the continuation to {rows.sum()} of {n} "
                          f"points {what} ({result.points(rows)}; column event)"))
    if len(jumped):
        lines.append((logging.INFO, f"sweep: the warm path from the point before left its "
                      f"branch at {len(jumped)} of {n} points ({result.points(sorted(jumped))}: "
                      f"a fold or branch point between the two), which are solved by solve()'s "
                      f"route (column path: continuation; event: what that route crossed)"))
    return lines


def log_summary(result: SweepResult, coarse: Mapping[int, tuple[str, float]],
                unestimated: Mapping[int, str], jumped: Sequence[int] = ()) -> None:
    """Log the lines of :func:`summary`."""
    for level, line in summary(result, coarse, unestimated, jumped):
        log.log(level, line)
