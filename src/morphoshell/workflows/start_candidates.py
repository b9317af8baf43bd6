"""Where a campaign's fit starts: the best of a few candidates, not only the previous fit.

A chain of fits warm-started each from the previous timepoint's follows one
branch of local optima: a fit that stalls or takes a poor optimum passes its
start on, and which timepoints are fitted decides where the later ones end
(a subset's fit of t05 started from t02's, the full chain's from t04's).  So
each fit starts from the candidate with the lowest E_fit at its start
(:func:`best_start`): the previous fit (its parameters and its equilibrium:
its branch), the campaign's start or the family's defaults with the held
values, and a small deterministic multi-start
(:data:`morphoshell.fitting.multistart.MULTI_STARTS`, which ``morphoshell fit
--multi-start`` fits from too).  The
candidates are ranked by E_fit of their starting shape, on the previous
fit's branch for the previous fit and on the physical branch (continuation
from the stress-free parameters, crossing snap-throughs) on a coarse mesh
(:data:`RANK_NODES`) for the others: a ranking, not a fit.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping, Sequence

import numpy as np

from ..fitting.inner import InnerProblem
from ..fitting.midline_checks import as_points
from ..fitting.multistart import MULTI_STARTS, start_specs
from ..model.problem import Problem
from ..solvers.results import Equilibrium, SolverError

__all__ = ["Candidate", "best_start", "other_candidates", "MULTI_STARTS", "RANK_NODES"]

#: Mesh nodes of the solves that rank the candidates without a state: their E_fit differ by
#: far more than a coarse mesh's error (a candidate that wins is then fitted on the fit's mesh).
RANK_NODES = 60
@dataclass(frozen=True)
class Candidate:
    """A start of a fit: where from (``started_from``), its spec and its state (or None).

    ``state`` is an equilibrium of ``spec.base`` on the fit's mesh (the
    previous fit's, carried onto it); None: the physical branch.
    """

    origin: str
    spec: object
    state: Equilibrium | None = None


def other_candidates(variant: str, hold: Mapping[str, float], start: Problem | None,
                     origin: str) -> list[Candidate]:
    """The candidates besides the previous fit: ``start`` (the campaign's, or the family's
    defaults if None) with the held values, and :data:`MULTI_STARTS` from the defaults.

    ``origin`` names ``start`` (``"start"`` or ``"family defaults"``).  A start that the
    variant's bounds or the held values do not admit is left out.
    """
    return [Candidate(label, spec) for label, spec in start_specs(variant, hold, start, origin)]


def best_start(candidates: Sequence[Candidate], data, nodes: int
               ) -> tuple[Candidate, list[dict]]:
    """The candidate with the lowest E_fit at its start, and the table of all.

    Parameters
    ----------
    candidates : sequence of Candidate
        The first wins ties (the previous fit: the chain as before).
    data : Midline or ndarray, shape (N, 2)
        The timepoint's midline.
    nodes : int
        The fit's mesh nodes (a candidate with a state is on it).

    Returns
    -------
    Candidate
    list of dict
        ``{"from": origin, "E_fit": E_fit at the start (R; None if its
        solve failed)}`` per candidate, in order: the record's
        ``start_candidates``.
    """
    points = as_points(data)
    scores = [_start_misfit(c, points, nodes) for c in candidates]
    best = int(np.argmin(scores))          # (the first of equals)
    table = [{"from": c.origin, "E_fit": (float(e) if np.isfinite(e) else None)}
             for c, e in zip(candidates, scores)]
    return candidates[best], table


def _start_misfit(candidate: Candidate, points: np.ndarray, nodes: int) -> float:
    """E_fit (R) of a candidate's starting shape, inf if it cannot be solved."""
    try:
        if candidate.state is not None:
            inner = InnerProblem(candidate.spec, points, nodes, start=candidate.state)
        else:
            inner = InnerProblem(candidate.spec, points, RANK_NODES)
        return float(np.linalg.norm(inner.residuals(inner.eq)))
    except (SolverError, ValueError):
        return float("inf")
