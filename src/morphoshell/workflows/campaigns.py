"""Fit campaigns across inversion time, and numerical ablations of fitted shapes.

The paper (main text, "The fitted mechanical sequence hints at an adaptive
response to out-of-plane stresses", Fig. 3 D–O; Supplementary, last section)
fits every inversion timepoint in turn, for four hypotheses on the posterior
intrinsic curvature κ₁ = κ_post⁰ (:data:`morphoshell.fitting.core.VARIANTS`), and
ablates the fitted shapes numerically (Materials and Methods: "the value of
Σ was increased from Σ = 0 in these fitted shapes").

:func:`campaign`
    For each variant (one task of :mod:`morphoshell.workflows.executor` per variant:
    Dask distributed, a process pool or this process), the timepoints of a
    data set in order, each fit warm-started from the previous timepoint's
    (its parameters and its equilibrium).  Held/fitted split of the model
    notes ("The Volvox inversion model"): f₁, κ₃, κ₄ are fitted at the first
    timepoint and held after, except in ``free``, which fits them (and κ₁) at
    every timepoint.  One JSON per (timepoint, variant), written atomically
    (a temporary file, then ``os.replace``): an interrupted campaign resumes
    where it stopped, and the resumed results are bit-identical to an
    uninterrupted run's, because every fit starts from what the previous
    timepoint's *file* holds (JSON keeps floats exactly) and the solves are
    deterministic (single-threaded MUMPS).  A summary table (CSV) of E_fit
    and the parameters against pseudotime.
:func:`numerical_ablation`
    Continuation in the cut Σ from 0 (the fitted, intact shell) to the cut
    size, with the adaptive, jump-rejecting steps of
    :func:`morphoshell.solvers.continuation.continue_between`, the observables of
    :func:`morphoshell.mechanics.ablation.ablate`, and a check against a cold solve at
    the final Σ on the same mesh.

A data set is a folder with ``timepoints.csv`` (columns ``timepoint``,
``pseudotime``, ``midline``: a path relative to the folder of an average
midline as :meth:`morphoshell.io.traces.Midline.to_csv` writes it, in units of
R, posterior pole at the origin; optionally ``traces``: the single traces'
midlines that were averaged, in the same form, separated by ``;``, for
``embryo_errors``); ``scripts/make_synthetic_inversion.py`` writes a
synthetic one.  Lengths in units of R, E_fit in units of R,
energies in C R².
"""
from __future__ import annotations

import concurrent.futures as cf
import csv
import hashlib
import io
import json
import os
import tempfile
import time
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Iterator, Sequence

import numpy as np

from ..fitting import (BOUNDS, FIT_NODES, METHODS, VARIANTS, FitError, FitResult, check_midline,
                       fit, volvox_spec)
from ..io import Midline, average
from ..mechanics.ablation import Ablation, edge_state, intact_problem, recoil_jacobian
from ..model.problem import Problem
from ..numerics.mesh import mesh_spec
from ..solvers.continuation import continue_between
from ..solvers.direct import DirectSolver
from ..solvers.observables import RECOIL, recoil
from ..solvers.refinement import solve_from
from ..solvers.results import Equilibrium, SolverError
from ..solvers.routes import solve
from .executor import SerialExecutor, backend_name, open_executor

__all__ = ["Timepoint", "CampaignResult", "NumericalAblation", "campaign", "read_timepoints",
           "load_campaign", "fitted_problem", "fitted_state", "numerical_ablation",
           "ablation_errors", "HELD", "CAMPAIGN_NODES", "CUT", "RESULT_SUFFIX", "SUMMARY"]

#: Parameters fitted at the first timepoint and held after (all variants but ``free``).
HELD = ("f1", "kappa3", "kappa4")
#: A continuation that ends near a fold replaces the fit it continued only if it lowers E_fit
#: by more than this fraction (``_fit_on``).
FOLD_GAIN = 0.1
#: Mesh nodes a campaign accepts (and its --nodes): a fit's lower limit, and a cap on its cost.
CAMPAIGN_NODES = (FIT_NODES[0], 2000)
#: Default cut Σ of numerical ablations (units of R): the experiments removed cells
#: within 3–6 µm of the pole of embryos of posterior radius ≈ 40 µm (Materials and Methods).
CUT = 0.15
#: Result files are ``<timepoint>_<variant>.json``.
RESULT_SUFFIX = ".json"
#: The summary table in the output folder.
SUMMARY = "campaign_summary.csv"
#: A fitted value this close to a bound is moved inside it before it starts the next fit.
_MARGIN = 1e-6
#: First cut of the Σ continuation, as a fraction of the final one (the cap removed
#: from the intact shell in one step; continue_between then grows it adaptively):
#: the smallest of these that the final mesh holds.
_FIRST_CUTS = (0.125, 0.25, 0.5, 0.75)


@dataclass(frozen=True)
class Timepoint:
    """One inversion stage of a data set.

    Attributes
    ----------
    name : str
        Label (``t01``), used in file names.
    pseudotime : float
        Position in the sequence (dimensionless, increasing).
    midline : str
        Path of the average midline (units of R), relative to the data folder.
    traces : tuple of str
        Paths of the single traces' midlines that were averaged (units of R,
        relative to the data folder; optional column ``traces``, separated
        by ``;``): with ``embryo_errors`` the jackknife over them gives
        standard errors.
    """

    name: str
    pseudotime: float
    midline: str
    traces: tuple[str, ...] = ()


def read_timepoints(data_dir: str | Path) -> tuple[Timepoint, ...]:
    """The timepoints of a data set, in order of pseudotime (validated).

    Parameters
    ----------
    data_dir : str or Path
        Folder with ``timepoints.csv`` (see the module docstring).

    Raises
    ------
    ValueError
        One line naming the file, row or value that is wrong.
    """
    data_dir = Path(data_dir)
    table = data_dir / "timepoints.csv"
    if not data_dir.is_dir():
        raise ValueError(f"{str(data_dir)!r} is not a folder")
    if not table.is_file():
        raise ValueError(f"{str(data_dir)!r} has no timepoints.csv (columns timepoint, "
                         f"pseudotime, midline)")
    # errors name the file's line: comment lines are skipped, not forgotten
    numbered = [(k, ln) for k, ln in enumerate(table.read_text(encoding="utf-8").splitlines(), 1)
                if ln.strip() and not ln.lstrip().startswith("#")]
    rows = list(csv.DictReader(io.StringIO("\n".join(ln for _, ln in numbered))))
    if not rows or not {"timepoint", "pseudotime", "midline"} <= set(rows[0]):
        raise ValueError(f"{table}: expected a header timepoint,pseudotime,midline and at "
                         f"least one row")
    out = []
    for (i, _), row in zip(numbered[1:], rows):
        name = (row["timepoint"] or "").strip()
        if not name or not all(c.isalnum() or c in "-_." for c in name):
            raise ValueError(f"{table}, line {i}: timepoint {name!r} must be a non-empty name "
                             f"of letters, digits, '-', '_' or '.'")
        try:
            t = float(row["pseudotime"])
        except (TypeError, ValueError):
            raise ValueError(f"{table}, line {i}: pseudotime {row['pseudotime']!r} is not a "
                             f"number") from None
        if not np.isfinite(t):
            raise ValueError(f"{table}, line {i}: pseudotime {t!r} is not finite")
        path = (row["midline"] or "").strip()
        if not (data_dir / path).is_file():
            raise ValueError(f"{table}, line {i}: midline file {path!r} does not exist")
        traces = tuple(v.strip() for v in (row.get("traces") or "").split(";") if v.strip())
        missing = [v for v in traces if not (data_dir / v).is_file()]
        if missing:
            raise ValueError(f"{table}, line {i}: trace file {missing[0]!r} does not exist")
        out.append(Timepoint(name, t, path, traces))
    names = [tp.name for tp in out]
    if len(set(names)) != len(names):
        raise ValueError(f"{table}: timepoint names repeat")
    times = [tp.pseudotime for tp in out]
    if any(b <= a for a, b in zip(times, times[1:])):
        raise ValueError(f"{table}: pseudotimes must increase down the table")
    return tuple(out)


def fitted_problem(record: dict) -> Problem:
    """The Volvox problem of a campaign result (a record of :func:`campaign`)."""
    p = dict(record["parameters"])
    h, cut, opening = p.pop("h"), p.pop("cut"), p.pop("opening")
    return Problem("volvox", p, h=h, cut=cut, opening=opening,
                   name=f"{record['timepoint']}_{record['variant']}")


def fitted_state(record: dict):
    """The fitted equilibrium's fields s, r, ψ, f_s at its points (units of R, rad).

    Enough to start a solve on any mesh on the fit's branch
    (:func:`~morphoshell.solvers.refinement.solve_from`, ``numerical_ablation(pre=...)``).
    """
    from types import SimpleNamespace

    return SimpleNamespace(**{k: np.asarray(record["state"][k], dtype=float)
                              for k in ("s", "r", "psi", "f_s")})


# --------------------------------------------------------------------------
# the campaign
# --------------------------------------------------------------------------

@dataclass(frozen=True)
class _Task:
    """One variant of a campaign: what a worker needs (small and picklable)."""

    data_dir: str
    timepoints: tuple[Timepoint, ...]
    variant: str
    method: str
    nodes: int
    out: str
    start: dict | None
    embryo_errors: bool = False
    #: ``held_from``: the source variant, its first timepoint and that fit's parameters
    #: (or its failure ``message``)
    held_from: dict | None = None


@dataclass(frozen=True)
class CampaignResult:
    """The results of a campaign, one record per (timepoint, variant).

    Attributes
    ----------
    out : Path
        The folder of the result files and of the summary (:data:`SUMMARY`).
    timepoints : tuple of Timepoint
    variants : tuple of str
    records : dict
        ``{(timepoint, variant): record}``, each record the content of its JSON
        file (see :func:`campaign`).
    timing : dict
        ``seconds`` (wall clock), ``workers``, ``backend``, ``computed`` (fits
        done in this run), ``fit_seconds`` (their summed time).
    """

    out: Path
    timepoints: tuple[Timepoint, ...]
    variants: tuple[str, ...]
    records: dict
    timing: dict = field(default_factory=dict)

    def record(self, timepoint: str, variant: str) -> dict:
        """The record of one fit (KeyError if it is missing)."""
        return self.records[(timepoint, variant)]

    def to_dataframe(self):
        """E_fit (units of R) and the parameters against pseudotime, one row per fit.

        Returns
        -------
        pandas.DataFrame
            Columns ``timepoint``, ``pseudotime``, ``variant``, ``status``,
            ``E_fit``, ``converged``, the 14 Volvox parameters (lengths in R,
            curvatures in 1/R), then ``se_<name>`` (Gauss–Newton standard
            errors; NaN for parameters not fitted at that timepoint), and
            with ``embryo_errors`` ``se_embryo_<name>`` (the jackknife over
            the traces) and ``embryo_t95`` (their 95 % interval is ± this many),
            with ``held_from`` ``held_from`` (the variant whose first fit gave the
            held values; empty where a variant fitted its own).
        """
        import pandas as pd

        rows = []
        held_from = any("held_from" in r for r in self.records.values())
        for tp in self.timepoints:
            for v in self.variants:
                rec = self.records.get((tp.name, v))
                if rec is None:
                    continue
                row = {"timepoint": tp.name, "pseudotime": tp.pseudotime, "variant": v,
                       "status": rec["status"], "E_fit": rec.get("E_fit", float("nan")),
                       "converged": rec.get("converged", False)}
                params = rec.get("parameters", {})
                names = [n for n in params if n not in ("h", "cut", "opening")]
                row.update({n: params[n] for n in names})
                se = rec.get("standard_errors", {})
                # (None: on a constraint, FitResult.constrained)
                row.update({f"se_{n}": _number(se.get(n)) for n in names})
                embryo = rec.get("embryo_standard_errors")
                if embryo is not None:
                    row.update({f"se_embryo_{n}": _number(embryo.get(n)) for n in names})
                    row["embryo_t95"] = rec.get("embryo_t95", float("nan"))   # (none: no errors)
                if held_from:
                    row["held_from"] = rec.get("held_from", {}).get("variant", "")
                rows.append(row)
        return pd.DataFrame(rows)


def _result_path(out: Path, timepoint: str, variant: str) -> Path:
    return out / f"{timepoint}_{variant}{RESULT_SUFFIX}"


def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _write_atomic(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` all or nothing (temporary file in the folder, then rename)."""
    fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            fh.write(text)
        # mkstemp makes the file private: give it the permissions of a new file
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def _settings(task: _Task, tp: Timepoint) -> dict:
    """What makes a stored result reusable: same data, method, mesh and start."""
    settings = {"method": task.method, "nodes": task.nodes,
                "data": {"file": tp.midline,
                         "sha256": _sha256(Path(task.data_dir) / tp.midline)},
                "first_start": task.start}
    if task.held_from is not None and task.variant != "free":
        settings["held_from"] = task.held_from
    if task.embryo_errors:
        settings["traces"] = [{"file": v, "sha256": _sha256(Path(task.data_dir) / v)}
                              for v in tp.traces]
    return settings


def _start_problem(params: dict) -> Problem:
    """A start problem from fitted parameters, moved just inside the fit's bounds."""
    p = dict(params)
    h, opening = p.pop("h", 0.15), p.pop("opening", 0.3)
    p.pop("cut", None)
    for n, v in p.items():
        kind = "f" if n.startswith("f") else "kappa" if n.startswith("kappa") else None
        if kind is not None:
            lo, hi = BOUNDS[kind]
            span = (hi - lo) * _MARGIN
            p[n] = float(min(max(v, lo + span), hi - span))
    return Problem("volvox", p, h=h, opening=opening)


def _first_start(params: dict | None) -> Problem | None:
    """The first timepoint's start: ``params`` (:func:`_start_problem`), else None
    (:func:`morphoshell.fitting.core.volvox_spec`'s default)."""
    return _start_problem(params) if params else None


def _start_state(problem: Problem, state: dict, nodes: int) -> Equilibrium | None:
    """The previous fit's equilibrium carried onto the mesh the next fit builds (None if it fails).

    The mesh follows the breakpoints of the problem it is built for, so the
    previous fit's unknowns belong to another mesh: r, ψ and f_s are
    interpolated from its points (:func:`~morphoshell.solvers.refinement.solve_from`;
    reusing the raw unknowns converged to another equilibrium, 0.5 away,
    measured).
    """
    fields = fitted_state({"state": state})
    try:
        solver = DirectSolver(problem.structure, mesh=mesh_spec(problem, nodes, 2))
        return solve_from(solver, problem, fields)
    except (SolverError, ValueError):
        return None


def _fit_variant(task: _Task) -> list[dict]:
    """Worker: fit the timepoints of one variant in order; write one JSON per fit.

    A stored result with the same settings is read instead of fitted
    (resume).  Returns per fit: timepoint, seconds, computed, status.
    """
    out = Path(task.out)
    report = []
    prev = first = None     # the records the next fit starts from / holds f1, κ3, κ4 of
    for k, tp in enumerate(task.timepoints):
        path = _result_path(out, tp.name, task.variant)
        settings = _settings(task, tp)
        stored = _read_record(path)
        if stored is not None and all(stored.get(key) == value
                                      for key, value in settings.items()):
            rec = stored
            report.append({"timepoint": tp.name, "seconds": 0.0, "computed": False,
                           "status": rec["status"]})
        else:
            t0 = time.perf_counter()
            rec = _fit_one(task, tp, prev, first, settings)
            # sort_keys and full float precision: the same fit writes the same bytes
            _write_atomic(path, json.dumps(rec, indent=1, sort_keys=True) + "\n")
            rec = json.loads(path.read_text(encoding="utf-8"))
            report.append({"timepoint": tp.name, "seconds": time.perf_counter() - t0,
                           "computed": True, "status": rec["status"]})
        if rec["status"] == "ok":
            prev = rec
            first = first or rec
    return report


def _read_record(path: Path) -> dict | None:
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None


def _fit_one(task: _Task, tp: Timepoint, prev: dict | None, first: dict | None,
             settings: dict) -> dict:
    """Fit one timepoint; the record (a failed fit is recorded too, with its message)."""
    data = Midline.from_csv(Path(task.data_dir) / tp.midline)
    source = task.held_from if task.variant != "free" else None
    if prev is not None:
        start, origin = _start_problem(prev["parameters"]), f"fit of {prev['timepoint']}"
    elif source is not None:        # (the start is that fit, below, once it is known to exist)
        start, origin = None, f"the {source['variant']} fit of {source['timepoint']}"
    else:
        start, origin = _first_start(task.start), "start" if task.start else "family defaults"
    # held: the source's values at every timepoint, the first too (paper, SI Fig. S2's
    # test); else, but in free, the first fit's after the first timepoint
    fixed = source.get("parameters") if source is not None else (
        first["parameters"] if prev is not None and task.variant != "free" else None)
    hold = {n: fixed[n] for n in HELD} if fixed else {}
    rec = {"label": "fit of the Volvox model (morphoshell.campaign)",
           "timepoint": tp.name, "pseudotime": tp.pseudotime, "variant": task.variant,
           **settings, "started_from": origin, "held": hold}
    if source is not None and fixed is None:
        return {**rec, "status": "failed",
                "message": f"the held values come from the {source['variant']} fit of "
                           f"{source['timepoint']}, which failed: {source['message']}"}
    if prev is None and source is not None:
        start = _start_problem(fixed)
    try:
        spec = volvox_spec(task.variant, start=start, hold=hold)
    except ValueError as exc:
        return {**rec, "status": "failed", "message": f"{type(exc).__name__}: {exc}"}
    eq0 = None if prev is None else _start_state(spec.base, prev["state"], task.nodes)
    try:
        result, continued = _fit_on(task, hold, spec, data, eq0)
    except (FitError, SolverError, ValueError) as exc:
        # A KKT fit that fails (FitError) has already started again from the
        # reduced optimum (fitting._kkt); on the synthetic campaign (2026-11-23)
        # a refit from the stress-free parameters after one failed all 8 times,
        # for minutes each.
        if eq0 is None or isinstance(exc, FitError):
            return {**rec, "status": "failed", "message": f"{type(exc).__name__}: {exc}"}
        # The previous fit's state can sit near a fold of the branch, where no
        # solve from it converges (measured: unstressed variant, t08 of the
        # synthetic sequence).  Retry once from the physical branch, reached by
        # continuation from the stress-free parameters at the same start values.
        rec["started_from"] += f" (its state failed: {type(exc).__name__}; restarted by " \
                               f"continuation from the stress-free parameters)"
        try:
            result, continued = _fit_on(task, hold, spec, data, None)
        except (FitError, SolverError, ValueError) as exc2:
            return {**rec, "status": "failed", "message": f"{type(exc2).__name__}: {exc2}"}
    d = result.to_dict()
    d.pop("seconds")             # wall-clock time would break bit-identical resumes
    eq = result.equilibrium
    if task.embryo_errors and tp.traces:
        d.update(_embryo_errors(task, tp, hold, d["parameters"], eq, result.constrained,
                                result.pinned))
    return {**rec, **d, "status": "ok", "continued": continued,
            "state": {k: np.asarray(getattr(eq, k), dtype=float).tolist()
                      for k in ("s", "r", "psi", "f_s")}}


def _fit_on(task: _Task, hold: dict, spec, data, start) -> tuple[FitResult, bool]:
    """``fit``, continued once from its own result if it stops unconverged (not at a fold).

    A least-squares fit that runs out of evaluations in a long, flat valley
    often converges when started again from where it stopped, with a fresh
    trust region (synthetic sequence, 2026-11-23: a single trace of t08,
    unconverged after 200 evaluations at κ₁ = 1.058, converged in 34 more
    at 1.048).  Leaving such fits out would bias the jackknife toward the data
    that fit easily.  A continuation that fails or ends near a fold is
    dropped and the first result kept, saying so.  Returns the result, which
    counts the iterations, solves and seconds of both fits, and whether it
    was continued.
    """
    first = fit(spec, data, task.method, nodes=task.nodes, start=start)
    if first.converged or first.near_fold:
        return first, False
    again = volvox_spec(task.variant, start=_start_problem(first.parameters), hold=hold)
    try:
        r = fit(again, data, task.method, nodes=task.nodes, start=first.equilibrium)
    except (FitError, SolverError, ValueError) as exc:
        return replace(first, message=f"{first.message}; continuing it failed: "
                                      f"{type(exc).__name__}: {exc}"), False
    if r.near_fold and r.E_fit > (1 - FOLD_GAIN) * first.E_fit:
        # Synthetic t07, free: the continuation crept onto a fold for a 0.1 % lower E_fit;
        # where the first fit stopped, the shape is stable and its errors mean something.
        # (Not when it fits far better: unstressed t09 stalled at 0.32 R, and its
        # continuation reached 0.038 R at a fold.)
        return replace(first, message=f"{first.message}; continuing it crept onto a fold of "
                                      f"the branch (E_fit {r.E_fit:.6g} R), so it is kept "
                                      f"where it stopped"), False
    return replace(r, outer_iterations=first.outer_iterations + r.outer_iterations,
                   inner_solves=first.inner_solves + r.inner_solves,
                   seconds=first.seconds + r.seconds,
                   message=f"continued once after: {first.message}; then: {r.message}"), True


def _embryo_errors(task: _Task, tp: Timepoint, hold: dict, parameters: dict,
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
    residuals, which are correlated and partly absorbed by the model: on the
    synthetic sequence the free fits reached E_fit 0.0047 R where the
    generating parameters give 0.0101 R (t04), and κ₁ missed the truth by
    5.5 and 6 of those errors at t04 and t08.  Replicate data sets measure
    how often each kind of interval holds the truth
    (``scripts/check_embryo_errors.py``, docs/campaigns.md).  With two
    traces the jackknife is half their fits' difference.
    """
    if len(tp.traces) < 2:
        return {"embryo_fits": [], "embryo_standard_errors": {},
                "embryo_errors_message": "no jackknife errors: they need at least 2 traces"}
    spec = volvox_spec(task.variant, start=_start_problem(parameters), hold=hold)
    traces = [Midline.from_csv(Path(task.data_dir) / path) for path in tp.traces]
    fits = []
    for k, path in enumerate(tp.traces):
        rest = average(traces[:k] + traces[k + 1:])
        try:
            r, continued = _fit_on(task, hold, spec, rest, eq)
        except (FitError, SolverError, ValueError) as exc:
            fits.append({"left_out": path, "status": "failed",
                         "message": f"{type(exc).__name__}: {exc}"})
            continue
        fits.append({"left_out": path, "status": "ok", "converged": r.converged,
                     "E_fit": r.E_fit, "continued": continued,
                     "parameters": {n: r.parameters[n] for n in spec.fitted},
                     "constrained": list(r.constrained), "pinned": list(r.pinned)})
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
    out = {"embryo_fits": fits, "embryo_standard_errors": se, "embryo_t95": _t95(n - 1)}
    # Refits that end on a constraint (s3 - s2 = sigma, ...) are pinned there alike: their
    # spread is not the estimator's (replicate t02 data: jackknife errors of s2 of 0.001-0.002
    # against misses of 0.018).  Those parameters get none.
    # (the fits' own record of it: FitResult.pinned, the parameters without a standard error)
    active = {c for f in fits for c in f["constrained"]} | set(constrained)
    pinned = [p for p in spec.fitted if p in set(pinned).union(*(f["pinned"] for f in fits))]
    if pinned:
        se.update({p: None for p in pinned})
        out["embryo_errors_message"] = (
            f"no jackknife errors of {', '.join(pinned)}: the fit or fits with one trace left "
            f"out end on the constraint {', '.join(sorted(active))}")
    return out


def _number(value) -> float:
    """A record's number, NaN for None (no value: JSON has no NaN)."""
    return float("nan") if value is None else float(value)


def _t95(dof: int) -> float:
    """Half-width, in standard errors, of a 95 % interval when they have ``dof`` degrees of freedom.

    Student's t quantile t₀.₉₇₅(dof): 2.78 for five traces, against 1.96
    for a known error.
    """
    from scipy.stats import t

    return float(t.ppf(0.975, dof))


def _names(value: str | Sequence[str]) -> list[str]:
    """A list of names from a sequence or a comma-separated string."""
    return [v.strip() for v in value.split(",")] if isinstance(value, str) else list(value)


def _jackknifed(embryo_errors, variants: tuple[str, ...]) -> frozenset:
    """The variants that get jackknife errors (``campaign``'s ``embryo_errors``), validated."""
    if isinstance(embryo_errors, bool):
        return frozenset(variants if embryo_errors else ())
    names = _names(embryo_errors)
    unknown = [v for v in names if v not in variants]
    if unknown or not names:
        raise ValueError(f"embryo_errors: variants {unknown or '(none)'} are not among the "
                         f"campaign's {list(variants)}")
    return frozenset(names)


def _validate(data_dir, variants, method, nodes, workers, out, start) -> tuple:
    timepoints = read_timepoints(data_dir)
    # (the free variant fits every stretch: the widest range of lengths)
    spec = volvox_spec("free", _first_start(start))
    for tp in timepoints:       # their content too: a bad file fails here, not in a worker
        for path in (tp.midline, *tp.traces):
            check_midline(spec, Midline.from_csv(Path(data_dir) / path), f"{path}: the midline")
    if isinstance(variants, str):
        variants = (variants,)
    variants = tuple(variants)
    bad = [v for v in variants if v not in VARIANTS]
    if bad or not variants:
        raise ValueError(f"variants {list(bad) or '(none)'}: choose from {list(VARIANTS)}")
    if len(set(variants)) != len(variants):
        raise ValueError(f"variants {list(variants)} repeat")
    if method not in METHODS:
        raise ValueError(f"method = {method!r} must be one of {list(METHODS)}")
    lo, hi = CAMPAIGN_NODES
    if isinstance(nodes, bool) or int(nodes) != nodes or not lo <= nodes <= hi:
        raise ValueError(f"nodes = {nodes!r} must be an integer from {lo} to {hi}")
    if workers is not None and (isinstance(workers, bool) or int(workers) != workers
                                or workers < 1):
        raise ValueError(f"workers = {workers!r} must be a positive integer")
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise ValueError(f"out = {str(out)!r} is a file, not a folder")
    return timepoints, variants, out


def campaign(data_dir: str | Path, variants: Sequence[str] = VARIANTS, *,
             method: str = "gradient", workers: int | None = None,
             scheduler: str | None = None, out: str | Path = "campaign", resume: bool = True,
             nodes: int = 200, start: dict | None = None,
             timepoints: Sequence[str] | None = None,
             embryo_errors: bool | str | Sequence[str] = False,
             held_from: str | None = None) -> CampaignResult:
    """Fit every timepoint of a data set for each variant (paper Fig. 3 N, O).

    Parameters
    ----------
    data_dir : str or Path
        The data set (see the module docstring).
    variants : sequence of str
        Of :data:`morphoshell.fitting.core.VARIANTS` (default: all four).
    method : {"gradient", "kkt", "nelder-mead"}
        The fit method (:func:`morphoshell.fitting.core.fit`).
    workers : int, optional
        Worker processes (one variant per task, so more than ``len(variants)``
        do not help; default: one per variant, at most the CPU count);
        ignored with a scheduler.
    scheduler : str, optional
        Address of a running Dask scheduler (default ``DASK_SCHEDULER_ADDRESS``).
    out : str or Path
        Folder of the results: ``<timepoint>_<variant>.json`` per fit and
        :data:`SUMMARY`.
    resume : bool
        Keep stored results made with the same data file, method, nodes and
        start, and fit only the missing ones; ``False`` refits everything.
    nodes : int
        Mesh nodes of the inner solves.
    start : dict, optional
        Parameters the first timepoint starts from (default: the Volvox
        family's illustrative defaults).
    timepoints : sequence of str, optional
        Fit only these timepoints (names, in the data set's order; a short
        campaign); default all.
    embryo_errors : bool, str or sequence of str
        Also fit, for each of the n traces of a timepoint (its ``traces``),
        the average of the others, from the average's fit, and record the
        jackknife standard errors of the average's parameters
        (``embryo_standard_errors``, only when all n fits converge, else
        ``embryo_errors_message`` says why; ``embryo_fits``;
        a fit that stops unconverged is continued once from where it
        stopped).  They include what the Gauss–Newton errors of one fit
        cannot see (its residuals' correlation, the model absorbing them);
        with n traces they are themselves uncertain (n − 1 degrees of
        freedom): a 95 % interval is ± ``embryo_t95`` of them (Student's t,
        2.78 for n = 5).  Costs n more fits.  ``True`` for every variant, or
        the variants (names, or a comma-separated string) that get them.
    held_from : str, optional
        A variant whose fit of the first timepoint gives f₁, κ₃, κ₄ to every
        other variant but ``free``, held from the first timepoint on (and
        that fit's parameters their first start), instead of each fitting
        its own at the first timepoint: the paper's test of the held values
        (Supplementary, Fig. S2); ``"free"``, whose fit fits κ₁ as well,
        assumes no hypothesis.  That fit runs first (stored in ``out``
        like the others, whether or not the variant is in ``variants``;
        not at all when no other variant but ``free`` runs).  With its
        values the variants differ in κ₁ alone.

    Returns
    -------
    CampaignResult

    Notes
    -----
    Each record holds the timepoint, pseudotime, variant, method, nodes, the
    data file and its SHA-256, where the fit started from, the held values,
    ``status`` (``ok`` or ``failed`` with ``message``), and for a successful
    fit :meth:`morphoshell.fitting.core.FitResult.to_dict` without its time and
    ``state`` (s, r, ψ, f_s of the fitted equilibrium at its points: the
    next timepoint's warm start).  A failed fit is recorded and the next timepoint
    starts from the last successful one.
    """
    selected = timepoints
    timepoints, variants, out = _validate(data_dir, variants, method, nodes, workers, out, start)
    if held_from is not None and held_from not in VARIANTS:
        raise ValueError(f"held_from = {held_from!r} must be one of {list(VARIANTS)}")
    jackknifed = _jackknifed(embryo_errors, variants)
    if selected is not None:
        selected = _names(selected)
        names = [tp.name for tp in timepoints]
        unknown = [n for n in selected if n not in names]
        if unknown or not selected:
            raise ValueError(f"timepoints {unknown or '(none)'}: the data set has {names}")
        timepoints = tuple(tp for tp in timepoints if tp.name in set(selected))
    if workers is None:
        workers = min(len(variants), os.cpu_count() or 1)
    tasks = [_Task(str(Path(data_dir).resolve()), timepoints, v, method, int(nodes),
                   str(out.resolve()), dict(start) if start else None, v in jackknifed)
             for v in variants]
    source, first_report = None, []
    if held_from is not None and any(v not in ("free", held_from) for v in variants):
        source = replace(tasks[variants.index(held_from)] if held_from in variants else
                         replace(tasks[0], variant=held_from, embryo_errors=False),
                         timepoints=timepoints[:1])
    total = len(tasks) * len(timepoints)
    t0 = time.perf_counter()
    reports: list = [None] * len(tasks)
    from .._runtime.console import progress
    with open_executor(workers, scheduler) as executor:
        # only now: a scheduler that does not answer must leave no folder and delete no results
        out.mkdir(parents=True, exist_ok=True)
        if not resume:
            for tp in timepoints:
                for v in variants:
                    _result_path(out, tp.name, v).unlink(missing_ok=True)
        backend = backend_name(executor)
        if source is not None:
            if not resume:
                _result_path(out, timepoints[0].name, held_from).unlink(missing_ok=True)
            held, first_report = _held_from(executor, source)
            # (the source itself runs as without held_from, from its stored first fit)
            tasks = [t if t.variant == held_from else replace(t, held_from=held)
                     for t in tasks]
        watched = _watch(executor, tasks, reports, out, timepoints, variants)
        for _ in progress(watched, total=total, desc="fits", unit="fit"):
            pass
    seconds = time.perf_counter() - t0
    records = {}
    for tp in timepoints:
        for v in variants:
            rec = _read_record(_result_path(out, tp.name, v))
            if rec is not None:
                records[(tp.name, v)] = rec
    # (the source's own task read its first fit back: reported once, as fitted before)
    fits = [dict(r, variant=held_from) for r in first_report] + [
        dict(r, variant=tasks[i].variant) for i, rep in enumerate(reports) for r in rep
        if not (first_report and tasks[i].variant == held_from and r is rep[0])]
    done = [r for r in fits if r["computed"]]
    result = CampaignResult(out, timepoints, variants, records, {
        "seconds": seconds, "workers": 1 if backend == "serial" else workers,
        "backend": backend, "computed": len(done),
        "fit_seconds": float(sum(r["seconds"] for r in done)), "fits": fits})
    _write_atomic(out / SUMMARY, result.to_dataframe().to_csv(index=False))
    return result


def _held_from(executor, source: _Task) -> tuple[dict, list[dict]]:
    """Fit (or read) the first timepoint of ``source``: the held values of ``held_from``.

    Returns the task's ``held_from`` and the fit's report (:func:`_fit_variant`).
    """
    report = executor.submit(_fit_variant, source).result()
    tp = source.timepoints[0]
    rec = _read_record(_result_path(Path(source.out), tp.name, source.variant)) or {}
    held = {"variant": source.variant, "timepoint": tp.name}
    if rec.get("status") != "ok":
        return {**held, "message": rec.get("message", "no result was written")}, report
    return {**held, "parameters": rec["parameters"]}, report


def _watch(executor, tasks, reports, out, timepoints, variants) -> Iterator[None]:
    """Run the tasks; yield once per finished fit (result files appearing), for a progress bar."""
    paths = [_result_path(out, tp.name, v) for v in variants for tp in timepoints]

    def count():
        return sum(p.exists() for p in paths)
    seen = 0
    if isinstance(executor, SerialExecutor):    # runs at submission: report per variant
        for i, task in enumerate(tasks):
            reports[i] = _fit_variant(task)
            now = count()
            yield from (None for _ in range(now - seen))
            seen = now
        return
    futures = {executor.submit(_fit_variant, task): i for i, task in enumerate(tasks)}
    pending = set(futures)
    while pending:
        finished, pending = cf.wait(pending, timeout=0.5, return_when=cf.FIRST_COMPLETED)
        for f in finished:
            reports[futures[f]] = f.result()
        now = count()
        yield from (None for _ in range(now - seen))
        seen = now


def load_campaign(out: str | Path, data_dir: str | Path) -> CampaignResult:
    """The stored results of a campaign (no fitting): for figures and reports."""
    timepoints = read_timepoints(data_dir)
    out = Path(out)
    records, variants = {}, []
    for v in VARIANTS:
        for tp in timepoints:
            rec = _read_record(_result_path(out, tp.name, v))
            if rec is not None:
                records[(tp.name, v)] = rec
                if v not in variants:
                    variants.append(v)
    return CampaignResult(out, timepoints, tuple(variants), records)


# --------------------------------------------------------------------------
# numerical ablation of a fitted shape
# --------------------------------------------------------------------------

@dataclass(frozen=True, eq=False)
class NumericalAblation:
    """A numerical ablation reached by continuation in Σ, and its check.

    Attributes
    ----------
    ablation : Ablation
        Pre-ablation (the intact, fitted shell), post-ablation (at the final
        Σ) and the observables of :func:`morphoshell.mechanics.ablation.ablate`.
    steps, rejected : int
        Accepted and retried steps of the continuation in Σ (after the first
        cut, the smallest of :data:`_FIRST_CUTS` of the final one that its mesh holds).
    cold : Equilibrium or None
        A cold solve at the final Σ on the same mesh (None if it failed).
    cold_difference : float
        max |x_continuation − x_cold| over the unknowns (NaN without a cold
        solution): a few 1e-8 when both reach the same equilibrium.
    """

    ablation: Ablation
    steps: int
    rejected: int
    cold: Equilibrium | None
    cold_difference: float

    def observables(self) -> dict[str, float]:
        """The recoil observables (units: :data:`morphoshell.mechanics.ablation.UNITS`)."""
        return self.ablation.observables()


def numerical_ablation(problem: Problem, cut: float = CUT, *, nodes: int = 200,
                       pre: Equilibrium | None = None, cold: bool = True) -> NumericalAblation:
    """Ablate a (fitted) shell by continuation in Σ from 0 to ``cut``.

    Materials and Methods ("For numerical ablations, the value of Σ was
    increased from Σ = 0 in these fitted shapes"): the intact shell (Σ = 0)
    is solved on a mesh with a node at s = Σ; its state starts the cut shell
    at Σ₀ = Σ/8 (or Σ/4, Σ/2, 3Σ/4 where the mesh needs it; interpolated,
    :func:`~morphoshell.solvers.refinement.solve_from`), which
    :func:`~morphoshell.solvers.continuation.continue_between` grows to Σ with
    adaptive steps that are retried smaller when they fail or jump.

    Parameters
    ----------
    problem : Problem
        The fitted shell (its cut is ignored: Σ = 0 before, ``cut`` after).
    cut : float
        The final Σ (units of R).
    nodes : int
        Mesh nodes of both states.
    pre : Equilibrium or fields, optional
        The intact shell to carry onto the anchored mesh (an Equilibrium, or
        :func:`fitted_state` of a campaign record: the fit's branch); by
        default solved by continuation from the stress-free parameters.
    cold : bool
        Also solve the final Σ cold (from the solver's initial guess) on the
        same mesh, for :attr:`NumericalAblation.cold_difference`.

    Returns
    -------
    NumericalAblation
    """
    if not 0 < cut < problem.end:
        raise ValueError(f"cut = {cut!r} must lie inside the shell (0, {problem.end:.6g})")
    target = problem.with_updates(cut=float(cut))
    intact = intact_problem(target)
    if pre is None:
        pre = solve(intact, nodes=nodes, anchors=(cut,))
    else:
        anchored = DirectSolver(intact.structure, mesh=mesh_spec(intact, nodes, 2, (cut,)))
        pre = solve_from(anchored, intact, pre, anchors=(cut,))
    solver = DirectSolver(target.structure, mesh=mesh_spec(target, nodes, 2))
    # The mesh's knots follow the breakpoints at fixed fractions of [Σ, π − P]:
    # far below the final Σ the map to s can fold (measured: Σ/8 for a fitted
    # undeformed shell), so the first cut is the smallest of these that the
    # final mesh holds.
    post = None
    for fraction in _FIRST_CUTS:
        try:
            post = solve_from(solver, target.with_updates(cut=fraction * cut), pre)
            break
        except ValueError:
            continue
    if post is None:
        raise ValueError(f"the mesh of the cut shell at Σ = {cut:g} cannot hold a first cut "
                         f"of {_FIRST_CUTS[-1]:g} Σ")
    post = continue_between(solver, post, target, first_step=0.25)
    steps = int(post.solver.details.get("continuation_steps", 0))
    rejected = _rejected(post)
    cold_eq, diff = None, float("nan")
    if cold:
        try:
            cold_eq = solver.solve(target)
            diff = float(np.max(np.abs(cold_eq.x - post.x)))
        except SolverError:
            cold_eq = None
    obs = recoil(edge_state(pre, cut), edge_state(post, cut))
    removed = pre.energy_between(pre.s[0], cut)
    ab = Ablation(problem=target, pre=pre, post=post, **{k: float(obs[k]) for k in RECOIL},
                  energy_released=post.energy - (pre.energy - removed), energy_removed=removed)
    return NumericalAblation(ab, steps, rejected, cold_eq, diff)


def _rejected(eq: Equilibrium) -> int:
    path = str(eq.solver.details.get("path", ""))
    try:
        return int(path.split("(")[1].split(" retried")[0])
    except (IndexError, ValueError):
        return 0


def ablation_errors(record: dict, ablation: Ablation) -> dict[str, float]:
    """Standard errors of the recoil observables of a fitted shape's ablation.

    The fit's Gauss–Newton covariance C of the fitted parameters θ (a lower
    bound: the residuals of a traced midline are correlated) propagated
    linearly, σ_y² = (J C Jᵀ)_yy, with J = dy/dθ the exact derivatives of the
    observables (:func:`~morphoshell.mechanics.ablation.recoil_jacobian`, through both
    equilibria) and the ``unstressed`` tie κ₁ = 1/f₁ (dκ₁/df₁ = −1/f₁²).

    Parameters
    ----------
    record : dict
        A successful campaign record (``fitted``, ``standard_errors``,
        ``correlation``, ``parameters``, ``variant``).
    ablation : Ablation
        Its numerical ablation (direct method, e.g. :func:`numerical_ablation`).

    Returns
    -------
    dict
        Observable name (:data:`morphoshell.solvers.observables.RECOIL`) → standard
        error (units of :data:`morphoshell.mechanics.ablation.UNITS`).
    """
    names = list(record["fitted"])
    se = np.array([record["standard_errors"][n] for n in names], dtype=float)
    corr = np.nan_to_num(np.array(record["correlation"], dtype=float))
    np.fill_diagonal(corr, 1.0)
    cov = corr * np.outer(se, se)
    tied = record["variant"] == "unstressed"
    wrt = names + (["kappa1"] if tied else [])
    _, J = recoil_jacobian(ablation, wrt)
    if tied:
        f1 = record["parameters"]["f1"]
        J = J[:, :-1] + np.outer(J[:, -1], [(-1 / f1 ** 2) if n == "f1" else 0.0 for n in names])
    var = np.einsum("ij,jk,ik->i", J, cov, J)
    return {k: float(np.sqrt(max(v, 0.0))) for k, v in zip(RECOIL, var)}
