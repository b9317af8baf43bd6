"""The work of a campaign's worker: the timepoints of one variant, fitted in order.

One :class:`CampaignTask` per variant (:func:`fit_variant`, run by
:mod:`morphoshell.workflows.executor`) fits the timepoints of a data set in
order, each fit warm-started from the previous timepoint's: its parameters,
moved just inside the fit's bounds, and its equilibrium, carried onto the
next fit's mesh.  Held/fitted split of the model notes ("The Volvox inversion
model"; paper, Supplementary, last section): f₁, κ₃, κ₄ are fitted at the
first timepoint and held after (:data:`HELD`), except in ``free``, which fits
them (and κ₁) at every timepoint; with ``held_from`` they are held from the
first timepoint on at another variant's values (Supplementary, Fig. S2).

Resume.  One JSON per fit, written atomically (:func:`write_atomic`); a
stored record made with the same settings (data files and their SHA-256,
method, nodes, start, held values) is read instead of fitted.  The resumed
results are bit-identical to an uninterrupted run's, because every fit
starts from what the previous timepoint's *file* holds (JSON keeps floats
exactly) and the solves are deterministic (single-threaded MUMPS).

Errors of a timepoint's fit: the Gauss–Newton ones of
:func:`morphoshell.fitting.bilevel.fit`, and with ``embryo_errors`` the jackknife
over the traces that were averaged (:func:`_embryo_errors`).
"""
from __future__ import annotations

import hashlib
import json
import os
import tempfile
import time
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Sequence

import numpy as np

from .._runtime import interrupts, lifeline
from .._runtime.files import as_new_file, replace_named
from ..fitting import FitError, FitResult, fit, volvox_spec
from ..fitting.multistart import FOLD_GAIN, continue_once, start_from
from ..inverse.summaries import t_quantile
from ..io import Midline, average
from ..io.provenance import sha256_of
from ..io.timepoints import Timepoint
from ..model.problem import Problem
from ..numerics.mesh import mesh_spec
from ..solvers.direct import DirectSolver
from ..solvers.refinement import solve_from
from ..solvers.results import Equilibrium, SolverError
from .campaign_results import read_record, record_input_check, result_path
from .fitted_shapes import fitted_state
from .start_candidates import Candidate, best_start, other_candidates

__all__ = ["CampaignTask", "fit_variant", "first_start", "write_atomic", "record_provenance",
           "HELD", "FOLD_GAIN"]

#: Parameters fitted at the first timepoint and held after (all variants but ``free``).
HELD = ("f1", "kappa3", "kappa4")
#: What a fit that fails with one of these records as its message (the campaign goes on).
_FIT_FAILURES = (FitError, SolverError, ValueError)


@dataclass(frozen=True)
class CampaignTask:
    """One variant of a campaign: what a worker needs (small and picklable).

    Attributes
    ----------
    data_dir : str
        The data set's folder (absolute).
    timepoints : tuple of Timepoint
        The timepoints to fit, in order.
    variant, method : str
        The variant (:data:`morphoshell.fitting.spec.VARIANTS`) and fit method.
    nodes : int
        Mesh nodes of the inner solves.
    out : str
        The output folder (absolute).
    start : dict or None
        Parameters the first timepoint starts from (None: the family's defaults).
    embryo_errors : bool
        Whether the fits get jackknife errors over their traces.
    held_from : dict or None
        The source variant, its first timepoint and that fit's ``parameters``
        (or its failure ``message``): the values held by every variant but ``free``.
    owner : tuple or None
        The process that runs the campaign (:func:`morphoshell._runtime.lifeline.owner`):
        a worker on its machine stops when it has gone.
    """

    data_dir: str
    timepoints: tuple[Timepoint, ...]
    variant: str
    method: str
    nodes: int
    out: str
    start: dict | None
    embryo_errors: bool = False
    held_from: dict | None = None
    owner: tuple | None = None


#: Entries of a record that label its fit but do not change it: left out of the digest that
#: chains a fit to the previous one (``previous``), so that a corrected pseudotime or another
#: package version updates the labels of stored fits instead of refitting every later one.
#: ``input_check`` is the verdict on the fit's E_fit (:func:`record_input_check`), added to
#: the records of folders written before it without refitting them.  ``walls_cross``, the
#: check of the fitted shape (:attr:`morphoshell.fitting.results.FitResult.contact`), is a
#: verdict on the fit as well, not an input of the next (and absent from older folders).
_LABELS = ("pseudotime", "provenance", "input_check", "walls_cross")


def _digest(record: dict, labels: Sequence[str] = _LABELS) -> str:
    """SHA-256 of a record as JSON without its ``labels`` (sorted keys: the same record, the
    same digest).  ``labels=()`` gives the digest of folders written before :data:`_LABELS`."""
    kept = {k: v for k, v in record.items() if k not in labels}
    return hashlib.sha256(json.dumps(kept, sort_keys=True).encode()).hexdigest()


def record_provenance() -> dict[str, object]:
    """The versions and git commit a campaign's fit was made with (no date: a resumed
    campaign writes the same bytes as an uninterrupted one of the same code)."""
    from ..io.provenance import provenance

    return {k: v for k, v in provenance().items() if k != "written"}


def write_atomic(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` all or nothing (temporary file in the folder, then rename).

    An interrupted campaign leaves whole records or none, never a part of
    one: it resumes where it stopped.
    """
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=".tmp", dir=path.parent)
    except OSError as exc:      # (named: not the temporary file's name)
        raise OSError(exc.errno, f"cannot write {path}: {exc.strerror}") from None
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            fh.write(text)
        as_new_file(tmp)
        replace_named(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def _settings(task: CampaignTask, tp: Timepoint, prev: dict | None) -> dict:
    """What makes a stored result reusable: same data, method, mesh and start.

    The start of a fit after the first is the previous fit's record: its
    digest (``previous``) makes a changed fit upstream redo every fit
    downstream of it, not only its own.
    """
    settings = {"method": task.method, "nodes": task.nodes,
                "data": {"file": tp.midline,
                         "sha256": sha256_of(Path(task.data_dir) / tp.midline)},
                "first_start": task.start,
                "previous": None if prev is None else _digest(prev)}
    if task.held_from is not None and task.variant != "free":
        settings["held_from"] = task.held_from
    if task.embryo_errors:
        settings["traces"] = [{"file": v, "sha256": sha256_of(Path(task.data_dir) / v)}
                              for v in tp.traces]
    return settings


def _reusable(stored: dict | None, settings: dict) -> bool:
    """Whether a stored record was made with ``settings``: every entry the same, and held
    values from the same source or from none (``held_from`` is in ``settings`` only when
    set: a record held from another fit is not reusable by a run that holds nothing)."""
    return stored is not None and stored.get("held_from") == settings.get("held_from") \
        and all(stored.get(key) == value for key, value in settings.items())


def _start_problem(params: dict) -> Problem:
    """A start problem from fitted parameters, moved just inside the fit's bounds."""
    return start_from(params)


def first_start(params: dict | None) -> Problem | None:
    """The first timepoint's start problem.

    Parameters
    ----------
    params : dict or None
        Parameters (a campaign's ``start``), moved just inside the fit's bounds.

    Returns
    -------
    Problem or None
        None without ``params``: :func:`morphoshell.fitting.spec.volvox_spec`'s default.
    """
    return _start_problem(params) if params else None


def _start_state(problem: Problem, state: dict, nodes: int) -> Equilibrium | None:
    """The previous fit's equilibrium carried onto the mesh the next fit builds (None if it fails).

    The mesh follows the breakpoints of the problem it is built for, so the
    previous fit's unknowns belong to another mesh: r, ψ and f_s are
    interpolated from its points (:func:`~morphoshell.solvers.refinement.solve_from`),
    because the raw unknowns, read on another mesh, can converge to another
    equilibrium.
    """
    fields = fitted_state({"state": state})
    try:
        solver = DirectSolver(problem.structure, mesh=mesh_spec(problem, nodes, 2))
        return solve_from(solver, problem, fields)
    except (SolverError, ValueError):
        return None


def fit_variant(task: CampaignTask) -> list[dict]:
    """Worker: fit the timepoints of one variant in order; write one JSON per fit.

    A stored result with the same settings is read instead of fitted
    (resume).  A failed fit is recorded and the next timepoint starts from
    the last successful one.

    Parameters
    ----------
    task : CampaignTask

    Returns
    -------
    list of dict
        Per timepoint: ``timepoint``, ``seconds`` (of its fit; 0 when read),
        ``computed`` (fitted in this run) and ``status``.
    """
    out = Path(task.out)
    report = []
    prev = first = None     # the records the next fit starts from / holds f1, κ3, κ4 of
    legacy = None           # the digest of ``prev`` as a folder before _LABELS chained it
    lifeline.watch(task.owner)
    for tp in task.timepoints:
        path = result_path(out, tp.name, task.variant)
        settings = _settings(task, tp, prev)
        stored = read_record(path)
        relabelled = _relabelled(stored, tp, settings, legacy)
        if _reusable(relabelled, settings):
            rec = relabelled
            if rec != stored:   # a record never disagrees with timepoints.csv (the summary)
                write_atomic(path, json.dumps(rec, indent=1, sort_keys=True) + "\n")
            report.append({"timepoint": tp.name, "seconds": 0.0, "computed": False,
                           "status": rec["status"]})
        else:
            t0 = time.perf_counter()
            rec = _fit_one(task, tp, prev, first, settings)
            rec["input_check"] = record_input_check(rec)
            # a Ctrl-C that CasADi dropped (_runtime.interrupts) stops the campaign here: the
            # fit it may have cut is not stored
            interrupts.check()
            # sort_keys and full float precision: the same fit writes the same bytes
            write_atomic(path, json.dumps(rec, indent=1, sort_keys=True) + "\n")
            rec = stored = json.loads(path.read_text(encoding="utf-8"))
            report.append({"timepoint": tp.name, "seconds": time.perf_counter() - t0,
                           "computed": True, "status": rec["status"]})
        if rec["status"] == "ok":
            prev, legacy = rec, _digest(stored, ())
            first = first or rec
    return report


def _relabelled(stored: dict | None, tp: Timepoint, settings: dict, legacy: str | None
                ) -> dict | None:
    """A stored record with its labels brought up to date: the pseudotime of ``tp`` (an
    input of no fit: timepoints.csv may correct it), its ``input_check`` (a folder written
    before it has none), and a ``previous`` digest of the format before :data:`_LABELS`
    (``legacy``) replaced by the current one."""
    if stored is None:
        return None
    rec = dict(stored, pseudotime=tp.pseudotime, input_check=record_input_check(stored))
    if legacy is not None and rec.get("previous") == legacy:
        rec["previous"] = settings["previous"]
    return rec


def _failed(rec: dict, exc: BaseException) -> dict:
    """The record of a fit that failed with ``exc``."""
    return {**rec, "status": "failed", "message": f"{type(exc).__name__}: {exc}"}


def _start(task: CampaignTask, prev: dict | None, source: dict | None
           ) -> tuple[Problem | None, str]:
    """Where a fit starts, and the record's ``started_from``.

    From the previous timepoint's fit; else, with held values, from their
    source fit (set by the caller once that fit is known to exist); else from
    the campaign's start or the family's defaults.
    """
    if prev is not None:
        return _start_problem(prev["parameters"]), f"fit of {prev['timepoint']}"
    if source is not None:
        return None, f"the {source['variant']} fit of {source['timepoint']}"
    return first_start(task.start), "start" if task.start else "family defaults"


def _fixed(task: CampaignTask, prev: dict | None, first: dict | None,
           source: dict | None) -> dict | None:
    """The parameters whose :data:`HELD` values a fit holds, or None (it fits them).

    With ``held_from``: the source's values at every timepoint, the first too
    (paper, SI Fig. S2's test); else, but in ``free``, the first fit's after
    the first timepoint.
    """
    if source is not None:
        return source.get("parameters")
    return first["parameters"] if prev is not None and task.variant != "free" else None


def _fit_one(task: CampaignTask, tp: Timepoint, prev: dict | None, first: dict | None,
             settings: dict) -> dict:
    """Fit one timepoint; the record (a failed fit is recorded too, with its message)."""
    data = Midline.from_csv(Path(task.data_dir) / tp.midline)
    source = task.held_from if task.variant != "free" else None
    start, origin = _start(task, prev, source)
    fixed = _fixed(task, prev, first, source)
    hold = {n: fixed[n] for n in HELD} if fixed else {}
    rec = {"label": "fit of the Volvox model (morphoshell.campaign)",
           "timepoint": tp.name, "pseudotime": tp.pseudotime, "variant": task.variant,
           "provenance": record_provenance(), **settings, "started_from": origin, "held": hold}
    if source is not None and fixed is None:
        return {**rec, "status": "failed",
                "message": f"the held values come from the {source['variant']} fit of "
                           f"{source['timepoint']}, which failed: {source['message']}"}
    if prev is None and source is not None:
        start = _start_problem(fixed)
    try:
        spec = volvox_spec(task.variant, start=start, hold=hold)
    except ValueError as exc:
        return _failed(rec, exc)
    eq0 = None if prev is None else _start_state(spec.base, prev["state"], task.nodes)
    ranked = _ranked_starts(task, hold, data, Candidate(origin, spec, eq0), rec)
    try:
        result, continued = _fit_or_restart(task, hold, ranked[0].spec, data, ranked[0].state,
                                            rec)
    except _FIT_FAILURES as exc:
        result, continued, first = None, False, exc
    if result is None or not result.converged:
        result, continued = _fit_from_others(task, hold, data, ranked[1:], result, continued,
                                             rec)
    if result is None:
        return _failed(rec, first)
    d = result.to_dict()
    d.pop("seconds")             # wall-clock time would break bit-identical resumes
    fitted_by = d.pop("method")  # (the record's "method" is the campaign's setting)
    if fitted_by != task.method:
        d["fitted_by"] = fitted_by
    eq = result.equilibrium
    if task.embryo_errors and tp.traces:
        d.update(_embryo_errors(task, tp, hold, d["parameters"], eq, result.constrained,
                                result.pinned))
    return {**rec, **d, "status": "ok", "continued": continued,
            "state": {k: np.asarray(getattr(eq, k), dtype=float).tolist()
                      for k in ("s", "r", "psi", "f_s")}}


def _ranked_starts(task: CampaignTask, hold: dict, data, first: Candidate,
                   rec: dict) -> list[Candidate]:
    """The starts of a fit (:mod:`morphoshell.workflows.start_candidates`): ``first`` (the
    previous fit, or the chain's first start) and the others, best (lowest E_fit at the
    start) first; those whose start cannot be solved are left out, but the best.

    Records ``started_from`` (the best) and ``start_candidates`` in ``rec``.
    """
    others = other_candidates(task.variant, hold, first_start(task.start),
                              "start" if task.start else "family defaults")
    candidates = [first, *(c for c in others if c.origin != first.origin)]
    best, rec["start_candidates"] = best_start(candidates, data, task.nodes)
    rec["started_from"] = best.origin
    score = {row["from"]: row["E_fit"] for row in rec["start_candidates"]}
    rest = sorted((c for c in candidates if c is not best and score[c.origin] is not None),
                  key=lambda c: score[c.origin])
    return [best, *rest]


def _fit_from_others(task: CampaignTask, hold: dict, data, others: list[Candidate],
                     result: FitResult | None, continued: bool, rec: dict) -> tuple:
    """(the lowest fit, whether it was continued): a fit from the best start that failed or
    did not converge, then fits from the other starts in turn until one converges.

    The start's E_fit ranks starts only roughly: the synthetic campaign's unstressed
    t10 from the previous fit (E_fit 0.39 R at the start) stalled at a fold of the
    branch, while from the late-stage multi-start (7.6 R at the start) it converged at
    0.032 R.  The other starts are fitted by the gradient method whatever the
    campaign's: a KKT fit from a far start fails or falls back to it (the KKT fit's
    routes), and a hopeless hypothesis tried from every start by KKT doubled a
    campaign's time (docs/benchmarks.md, "Campaigns").
    Each fit tried is recorded in ``rec["other_starts"]``; ``started_from`` names the
    winner's start (a winner of another method says so: ``fitted_by``).
    """
    tried, gradient = [], replace(task, method="gradient")
    for c in others:
        scratch = {"started_from": c.origin}
        try:
            r, cont = _fit_or_restart(gradient, hold, c.spec, data, c.state, scratch)
        except _FIT_FAILURES as exc:
            tried.append({"from": c.origin, "status": "failed",
                          "message": f"{type(exc).__name__}: {exc}"})
            continue
        tried.append({"from": c.origin, "status": "ok", "E_fit": r.E_fit,
                      "converged": r.converged})
        if result is None or r.E_fit < result.E_fit:
            result, continued, rec["started_from"] = r, cont, scratch["started_from"]
        if result.converged:
            break
    rec["other_starts"] = tried
    return result, continued


def _fit_or_restart(task: CampaignTask, hold: dict, spec, data, eq0: Equilibrium | None,
                    rec: dict) -> tuple[FitResult, bool]:
    """:func:`_fit_on` from the previous fit's state, else once more from the physical branch.

    The previous fit's state can sit near a fold of the branch, where no
    solve from it converges: the fit is retried once from the physical
    branch, reached by continuation from the stress-free parameters at the
    same start values, and ``rec["started_from"]`` says so.  Not after a KKT
    fit that failed (FitError): it has already started again from the
    reduced optimum (:mod:`morphoshell.fitting`), and a refit from the
    stress-free parameters after one costs minutes and does not succeed
    where that failed.  Raises the last fit's error.
    """
    try:
        return _fit_on(task, hold, spec, data, eq0)
    except _FIT_FAILURES as exc:
        if eq0 is None or isinstance(exc, FitError):
            raise
        rec["started_from"] += f" (its state failed: {type(exc).__name__}; restarted by " \
                               f"continuation from the stress-free parameters)"
    return _fit_on(task, hold, spec, data, None)


def _fit_on(task: CampaignTask, hold: dict, spec, data, start) -> tuple[FitResult, bool]:
    """``fit``, continued once from its own result if it stops unconverged (not at a fold).

    A least-squares fit that runs out of evaluations in a long, flat valley
    often converges when started again from where it stopped, with a fresh
    trust region.  Leaving such fits out would bias the jackknife toward the
    data that fit easily.  A continuation that fails is dropped and the first
    result kept, saying so; so is one that creeps onto a fold of the branch
    for a small gain (by less than :data:`FOLD_GAIN` of E_fit): where the
    first fit stopped, the shape is stable and its errors mean something.
    One that fits far better is kept even at a fold.  Returns the result,
    which counts the iterations, solves and seconds of both fits, and
    whether it was continued.
    """
    first = _fit_falling_back(task, spec, data, start)
    if first.converged or first.near_fold:
        return first, False
    again = volvox_spec(task.variant, start=_start_problem(first.parameters), hold=hold)
    return continue_once(first, again, data, task.method, task.nodes)


def _fit_falling_back(task: CampaignTask, spec, data, start) -> FitResult:
    """``fit`` by the task's method; a KKT fit that fails (a saddle of the inner energy, its
    NLP or its restart stopping short: FitError) is done by the gradient method instead,
    and its message says so.

    Near folds of the inner branch the KKT fit's NLP can end on a saddle where the
    reduced problem's steps still find a minimum (the synthetic campaign's ``flat`` and
    ``free`` fits at t07-t10): a campaign gets a fit, not a failure, and the record's
    ``fitted_by`` names the method that made it.
    """
    try:
        return fit(spec, data, task.method, nodes=task.nodes, start=start)
    except FitError as exc:
        if task.method != "kkt":
            raise
        result = fit(spec, data, "gradient", nodes=task.nodes, start=start)
        return replace(result, message=f"the KKT fit failed ({exc.status}: {exc}); fitted by "
                                       f"the gradient method: {result.message}")


def _embryo_errors(task: CampaignTask, tp: Timepoint, hold: dict, parameters: dict,
                   eq: Equilibrium, constrained: Sequence[str] = (),
                   pinned: Sequence[str] = ()) -> dict:
    """Jackknife standard errors of the average's fit over its traces.

    The average of the n traces with trace k left out is fitted from the
    average's fit, for k = 1 … n; the standard error of a parameter θ is
    √((n − 1)/n · Σₖ (θ₍ₖ₎ − θ̄)²) (Efron & Tibshirani, *An Introduction to
    the Bootstrap*, 1993, ch. 11).  It estimates
    the error of the estimator actually used, the fit of an average, with
    its nonlinearity.  It needs every one of the n fits: when one fails or
    stops unconverged there are no errors, and ``embryo_errors_message``
    says why.  The Gauss–Newton errors of that one fit see only its
    residuals, which are correlated and partly absorbed by the model, and
    on the synthetic sequence they miss the generating parameters by
    several of themselves.  Replicate data sets show how often each kind of
    interval holds the truth (``scripts/check_embryo_errors.py``,
    docs/campaigns.md).  With two traces the jackknife is half their fits'
    difference.
    """
    if len(tp.traces) < 2:
        return {"embryo_fits": [], "embryo_standard_errors": {},
                "embryo_errors_message": "no jackknife errors: they need at least 2 traces"}
    spec = volvox_spec(task.variant, start=_start_problem(parameters), hold=hold)
    fits = _left_out_fits(task, tp, hold, spec, eq)
    good = [f["parameters"] for f in fits if f["status"] == "ok" and f["converged"]]
    if len(good) < len(fits):
        # A spread over the fits that converged is not the jackknife of the estimator:
        # the traces whose absence breaks a fit are not left out at random.
        return {"embryo_fits": fits, "embryo_standard_errors": {},
                "embryo_errors_message": f"no jackknife errors: {len(fits) - len(good)} of "
                                         f"the {len(fits)} fits with one trace left out did "
                                         f"not converge (embryo_fits), and the jackknife "
                                         f"needs all of them"}
    theta = np.array([[g[name] for name in spec.fitted] for g in good])    # (n, parameters)
    n = len(good)
    se = dict(zip(spec.fitted, np.sqrt((n - 1) / n * np.sum((theta - theta.mean(axis=0)) ** 2,
                                                           axis=0)).tolist()))
    out = {"embryo_fits": fits, "embryo_standard_errors": se, "embryo_t95": t_quantile(n)}
    # Refits that end on a constraint (s3 - s2 = sigma, ...) are pinned there alike: their
    # spread is not the estimator's (on replicate data it is far smaller than the misses),
    # so those parameters get none.
    # (the fits' own record of it: FitResult.pinned, the parameters without a standard error)
    active = {c for f in fits for c in f["constrained"]} | set(constrained)
    pinned = [p for p in spec.fitted if p in set(pinned).union(*(f["pinned"] for f in fits))]
    if pinned:
        se.update({p: None for p in pinned})
        out["embryo_errors_message"] = (
            f"no jackknife errors of {', '.join(pinned)}: the fit or fits with one trace left "
            f"out end on the constraint {', '.join(sorted(active))}")
    return out


def _left_out_fits(task: CampaignTask, tp: Timepoint, hold: dict, spec,
                   eq: Equilibrium) -> list[dict]:
    """The fit of the average of the traces with each left out in turn, from ``eq``."""
    traces = [Midline.from_csv(Path(task.data_dir) / path) for path in tp.traces]
    fits = []
    for k, path in enumerate(tp.traces):
        rest = average(traces[:k] + traces[k + 1:])
        try:
            r, continued = _fit_on(task, hold, spec, rest, eq)
        except _FIT_FAILURES as exc:
            fits.append({"left_out": path, "status": "failed",
                         "message": f"{type(exc).__name__}: {exc}"})
            continue
        fits.append({"left_out": path, "status": "ok", "converged": r.converged,
                     "E_fit": r.E_fit, "continued": continued,
                     "parameters": {n: r.parameters[n] for n in spec.fitted},
                     "constrained": list(r.constrained), "pinned": list(r.pinned)})
    return fits
