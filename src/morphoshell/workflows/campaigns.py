"""Fit campaigns across inversion time: every timepoint of a data set, for each variant.

The paper (main text, "The fitted mechanical sequence hints at an adaptive
response to out-of-plane stresses", Fig. 3 D–O; Supplementary, last section)
fits every inversion timepoint in turn, for four hypotheses on the posterior
intrinsic curvature κ₁ = κ_post⁰ (:data:`morphoshell.fitting.spec.VARIANTS`).

:func:`campaign` checks its arguments and the data set (every midline, before
any work), sends one task per variant to :mod:`morphoshell.workflows.executor`
(Dask distributed, a process pool or this process), each of which fits the
timepoints in order (:func:`morphoshell.workflows.timepoint_fits.fit_variant`:
warm starts, held values, resume), and writes the summary table
(:mod:`morphoshell.workflows.campaign_results`).  The data set's table is read
by :func:`morphoshell.io.timepoints.read_timepoints`.  Lengths in units of R,
E_fit in units of R, energies in C R².
"""
from __future__ import annotations

import concurrent.futures as cf
import json
import logging
import os
import time
from contextlib import contextmanager
from dataclasses import replace
from pathlib import Path
from typing import Iterator, Sequence

from .._runtime import interrupts, lifeline
from .._runtime.interrupts import interrupted
from .._runtime.console import NOTE, progress
from .._runtime.validate import name_list
from ..fitting import FIT_NODES, METHODS, VARIANTS, check_midline, volvox_spec
from ..io import Midline
from ..io.timepoints import Timepoint, read_timepoints
from ..solvers.contact import WallContact, warn_of_contact
from .campaign_results import (SETTINGS, SUMMARY, CampaignResult, load_campaign, read_record,
                               read_records, result_path)
from .executor import SerialExecutor, backend_name, check_workers, open_executor
from .timepoint_fits import (CampaignTask, first_start, fit_variant, record_provenance,
                             write_atomic)

__all__ = ["campaign", "CampaignInterrupted", "CAMPAIGN_NODES", "SETTINGS", "SERIAL_BELOW_FITS"]

log = logging.getLogger(__name__)

#: Mesh nodes a campaign accepts (and its --nodes): a fit's (:data:`FIT_NODES`), since its fits
#: are fits.  It was capped at 2000 for the cost, which the user chooses with the timepoints
#: and variants as much as with the nodes; the commands' ranges differed for no other reason.
CAMPAIGN_NODES = FIT_NODES
#: Below this many fits (timepoints x variants, jackknife fits included) ``workers=None``
#: fits in this process: a Dask cluster and each worker's imports and solver builds cost
#: more than a second core saves (docs/benchmarks.md, "Sweeps and campaigns: when workers
#: pay": 4 fits of 200 nodes lost on 2 workers, 8 won in 3 runs of 4 at load 2.6-3.7).
SERIAL_BELOW_FITS = 8


class CampaignInterrupted(KeyboardInterrupt):
    """A campaign stopped by Ctrl-C (a ``KeyboardInterrupt``), with how far it got.

    Its workers were stopped at once (:func:`morphoshell.workflows.executor.open_executor`);
    the fits already written stay, and the same call resumes from them.

    Attributes
    ----------
    done, total : int
        Fits of the campaign stored in ``out`` (earlier runs' included), and all of them.
    out : Path
        The campaign's folder.
    """

    def __init__(self, done: int, total: int, out: Path):
        super().__init__(f"{interrupts.reason()}: {done} of {total} fits done (in {out}), "
                         f"resume with the same command")
        self.done, self.total, self.out = done, total, out


def campaign(data_dir: str | Path, variants: Sequence[str] = VARIANTS, *,
             method: str = "gradient", workers: int | None = None,
             scheduler: str | None = None, out: str | Path = "campaign", resume: bool = True,
             nodes: int = 200, start: dict | None = None,
             timepoints: Sequence[str] | None = None,
             embryo_errors: bool | str | Sequence[str] = False,
             held_from: str | None = None, force: bool = False) -> CampaignResult:
    """Fit every timepoint of a data set for each variant (paper Fig. 3 N, O).

    Parameters
    ----------
    data_dir : str or Path
        The data set: a folder with ``timepoints.csv`` and the midlines it
        names (:mod:`morphoshell.io.timepoints`).
    variants : sequence of str
        Of :data:`morphoshell.fitting.spec.VARIANTS` (default: all four).
    method : {"gradient", "kkt", "nelder-mead"}
        The fit method (:func:`morphoshell.fitting.bilevel.fit`).
    workers : int, optional
        Worker processes (one variant per task: at most ``len(variants)`` are
        started); default: this process for fewer than :data:`SERIAL_BELOW_FITS`
        fits (timepoints × variants, jackknife fits included), else one per
        variant, at most the CPU count; ignored with a scheduler.
    scheduler : str, optional
        Address of a running Dask scheduler (default ``DASK_SCHEDULER_ADDRESS``).
    out : str or Path
        Folder of the results: ``<timepoint>_<variant>.json`` per fit and
        :data:`~morphoshell.workflows.campaign_results.SUMMARY`.
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
        The records of the timepoints and variants run (stored ones
        included), and the timing.

    Raises
    ------
    ValueError
        A bad argument, data file or scheduler address, named, before any
        work (and before any stored result is deleted); a folder that
        holds a campaign with other settings (the setting named), unless
        ``force``.
    CampaignInterrupted
        Ctrl-C (a ``KeyboardInterrupt``) while fitting: the workers are
        stopped at once, the fits written stay, and the same call resumes.
    OSError
        The folder cannot be written (the file named); the results written
        before stay, and a rerun resumes.

    Notes
    -----
    Each record holds the timepoint, pseudotime, variant, method, nodes, the
    data file and its SHA-256, where the fit started from, the held values,
    ``status`` (``ok`` or ``failed`` with ``message``), and for a successful
    fit :meth:`morphoshell.fitting.results.FitResult.to_dict` without its time and
    ``state`` (s, r, ψ, f_s of the fitted equilibrium at its points: the
    next timepoint's warm start), and ``input_check``: null, or ``morphoshell fit``'s
    verdict on an E_fit far above what the model leaves of a traced midline
    (:func:`~morphoshell.workflows.campaign_results.record_input_check`), and
    ``walls_cross`` (in the fit's record): null, or where the fitted shape's walls pass
    through each other (a minimum of the model, which has no self-contact, but not a
    physical shape), each warned of by the fit's name.  A failed fit is
    recorded and the next timepoint starts from the last successful one.
    """
    selected = timepoints
    timepoints, variants, out = _validate(data_dir, variants, method, nodes, workers, out, start)
    if held_from is not None and held_from not in VARIANTS:
        raise ValueError(f"held_from = {held_from!r} must be one of {list(VARIANTS)}")
    jackknifed = _jackknifed(embryo_errors, variants)
    if selected is not None:
        timepoints = _selected(timepoints, selected, data_dir)
    workers = _local_workers(workers, timepoints, variants, jackknifed,
                             _stored(out, timepoints, variants) if resume else frozenset())
    recorded = _check_settings(out, _folder_settings(data_dir, method, nodes, start),
                               force)
    # (recorded, not checked: a folder holds runs of other variants, timepoints and held values)
    recorded = {**recorded, "last_run": {
        "variants": list(variants), "timepoints": [tp.name for tp in timepoints],
        "held_from": held_from, "embryo_errors": [v for v in variants if v in jackknifed]}}
    tasks = [CampaignTask(str(Path(data_dir).resolve()), timepoints, v, method, int(nodes),
                          str(out.resolve()), dict(start) if start else None, v in jackknifed,
                          owner=lifeline.owner())
             for v in variants]
    source = _held_source(tasks, variants, timepoints, held_from)
    t0 = time.perf_counter()
    with _interruptible(out, timepoints, variants), \
            open_executor(workers, scheduler) as executor:
        backend = backend_name(executor)
        tasks, reports, first_report = _run(executor, tasks, source, out, timepoints, variants,
                                            resume, recorded)
    seconds = time.perf_counter() - t0
    # every fit in the folder, not only this run's: a run on a subset had replaced the
    # summary of the whole campaign by its own rows (the folder's settings are one run's);
    # read once, for the summary and this run's result
    stored = load_campaign(out, data_dir)
    records = {key: stored.records[key] for tp in timepoints for v in variants
               if (key := (tp.name, v)) in stored.records}
    fits = _fit_reports(tasks, reports, first_report, held_from)
    done = [r for r in fits if r["computed"]]
    result = CampaignResult(out, timepoints, variants, records, {
        "seconds": seconds, "workers": 1 if backend == "serial" else workers,
        "backend": backend, "computed": len(done),
        "fit_seconds": float(sum(r["seconds"] for r in done)), "fits": fits},
        data_dir=Path(data_dir))
    # (here, not in the workers, whose logs Dask silences: one line per fit, by its name)
    for t, v in result.walls_cross():
        # (read_records checked it against its shell)
        warn_of_contact(WallContact.from_dict(records[(t, v)]["walls_cross"]),
                        f"{t}_{v}, fitted shell")
    unchecked = [f"{t}_{v}" for t, v in result.walls_unchecked()]
    if unchecked:       # (reused from a folder written before the check: say so, audit 24)
        log.log(NOTE, "%d reused fit(s) were written before fitted shapes were checked for walls "
                "that pass through each other (walls_cross empty): %s; resume=False "
                "(--no-resume) refits and checks them", len(unchecked), ", ".join(unchecked))
    write_atomic(out / SUMMARY, stored.to_dataframe().to_csv(index=False))
    return result


@contextmanager
def _interruptible(out: Path, timepoints: tuple[Timepoint, ...],
                   variants: tuple[str, ...]) -> Iterator[None]:
    """Ctrl-C in the block (in this process within CasADi: a SystemError caused by it)
    raises :class:`CampaignInterrupted`, which counts the fits stored in ``out``."""
    try:
        yield
    except BaseException as exc:
        if not interrupted(exc):
            raise
        paths = [result_path(out, tp.name, v) for tp in timepoints for v in variants]
        raise CampaignInterrupted(sum(p.exists() for p in paths), len(paths), out) from None


def _folder_settings(data_dir, method: str, nodes: int, start: dict | None) -> dict:
    """The settings a campaign's folder records (:data:`SETTINGS`) and checks: what all its
    fits share.

    Not ``held_from``, which the ``free`` variant never has: a folder may hold a
    campaign's variants with and without held values (the summary's
    ``held_from`` column says which), and their source's fit is reused.  The file
    also records, unchecked, the last run's variants, timepoints, ``held_from`` and
    ``embryo_errors`` (``last_run``).
    """
    return {"data": str(Path(data_dir).resolve()), "method": method, "nodes": int(nodes),
            "start": dict(start) if start else None}


def _check_settings(out: Path, settings: dict, force: bool) -> dict:
    """``settings``, checked against those recorded in ``out`` (ValueError naming the first
    that differs, unless ``force``)."""
    path = out / SETTINGS
    recorded = read_record(path) if path.is_file() else None
    if recorded is None or force:
        return settings
    _note_versions(path, recorded.get("provenance"))
    if recorded.get("data", settings["data"]) != settings["data"]:
        # (each fit's record holds its files' names within the folder and their sha256:
        # a moved or copied folder's unchanged files reuse their fits, changed ones refit)
        log.warning("%s: the folder's campaign read %s; its fits whose files are the same in "
                    "%s are reused, the others refitted", path, recorded["data"],
                    settings["data"])
    for key, value in settings.items():
        if key != "data" and recorded.get(key, value) != value:
            option = {"data": "DATA_DIR", "start": "start"}.get(key, "--" + key.replace("_", "-"))
            raise ValueError(
                f"{path}: the folder holds a campaign with {key} = {recorded.get(key)!r}, not "
                f"{value!r} ({option}): choose another --out, or --force to record the new "
                f"settings and refit its fits as they come")
    return settings


def _note_versions(path: Path, recorded: dict | None) -> None:
    """Warn when the folder's campaign was run with other package versions or another git
    commit (the version string stays while commits change numbers): its stored fits are
    reused (their records say which versions made them), which may not be wanted."""
    now = record_provenance()
    # (a folder written before commits were recorded has none: not a change to warn of)
    changed = [f"{k} {(recorded or {}).get(k, 'unknown')} -> {v}" for k, v in now.items()
               if k in ("morphoshell", "git_commit", "casadi", "numpy")
               and (recorded or {}).get(k) != v
               and not (k == "git_commit" and (recorded or {}).get(k) is None)]
    if changed:
        log.warning("%s: the folder's fits were made with other versions (%s); they are "
                    "reused as they are (resume=False, --no-resume, refits them)",
                    path, ", ".join(changed))


def _read_data(data_dir, start) -> tuple[Timepoint, ...]:
    """The data set's timepoints, every midline and trace checked before any work.

    Their content too: a bad file fails here, not in a worker.  The free
    variant fits every stretch, so its spec accepts the widest range of lengths.
    """
    timepoints = read_timepoints(data_dir)
    spec = volvox_spec("free", first_start(start))
    for tp in timepoints:
        for path in (tp.midline, *tp.traces):
            check_midline(spec, Midline.from_csv(Path(data_dir) / path), f"{path}: the midline",
                          scale_hint="are its r and z in units of R, the embryo's radius?")
    return timepoints


def _validate(data_dir, variants, method, nodes, workers, out, start) -> tuple:
    """(timepoints, variants, out) of :func:`campaign`'s arguments, checked (ValueError naming
    one)."""
    timepoints = _read_data(data_dir, start)
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
    check_workers(workers)
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise ValueError(f"out = {str(out)!r} is a file, not a folder")
    return timepoints, variants, out


def _stored(out: Path, timepoints: tuple[Timepoint, ...], variants: tuple[str, ...]
            ) -> frozenset:
    """The (timepoint, variant) pairs with a result in ``out`` (a resumed run's likely reuse);
    ValueError naming a record it would reuse that is broken, before any fit
    (:func:`~morphoshell.workflows.campaign_results.read_records`)."""
    read_records(out, [(tp.name, v) for tp in timepoints for v in variants])
    return frozenset((tp.name, v) for tp in timepoints for v in variants
                     if result_path(out, tp.name, v).exists())


def _local_workers(workers: int | None, timepoints: tuple[Timepoint, ...],
                   variants: tuple[str, ...], jackknifed: frozenset,
                   stored: frozenset = frozenset()) -> int:
    """A campaign's workers: ``workers``, by default this process below
    :data:`SERIAL_BELOW_FITS` fits to make and else one per CPU core; at most one per
    variant (a variant is one task).  The fits with a result in the folder (``stored``, when
    resuming) do not count: a rerun with nothing to do started a cluster for 1.1 s (audit
    20); one whose stored results turn out stale is fitted here, as it would be started.
    With every fit stored there are no workers, whatever ``workers`` (``make run`` asks for
    2: its rerun started a cluster for 1.2 s, audit 24).  Ignored with a scheduler."""
    todo = [(tp, v) for tp in timepoints for v in variants if (tp.name, v) not in stored]
    if not todo:
        return 1
    if workers is None:
        fits = len(todo) + sum(len(tp.traces) for tp, v in todo if v in jackknifed)
        workers = 1 if fits < SERIAL_BELOW_FITS else os.cpu_count() or 1
    return max(1, min(workers, len(variants)))


def _jackknifed(embryo_errors, variants: tuple[str, ...]) -> frozenset:
    """The variants that get jackknife errors (``campaign``'s ``embryo_errors``), validated."""
    if isinstance(embryo_errors, bool):
        return frozenset(variants if embryo_errors else ())
    names = name_list(embryo_errors)
    unknown = [v for v in names if v not in variants]
    if unknown or not names:
        raise ValueError(f"embryo_errors {','.join(names)}: {unknown or '(none)'} not among "
                         f"the variants {','.join(variants)}")
    return frozenset(names)


def _selected(timepoints: tuple[Timepoint, ...], selected: str | Sequence[str], data_dir
              ) -> tuple[Timepoint, ...]:
    """The timepoints named in ``selected`` (``campaign``'s ``timepoints``), in the data set's
    order."""
    asked = name_list(selected)
    names = [tp.name for tp in timepoints]
    unknown = [n for n in asked if n not in names]
    if unknown or not asked:
        typed = selected if isinstance(selected, str) else ",".join(asked)
        raise ValueError(f"timepoints {typed!r}: {unknown or '(none)'} not in "
                         f"{Path(data_dir) / 'timepoints.csv'} (it has {','.join(names)})")
    return tuple(tp for tp in timepoints if tp.name in set(asked))


def _held_source(tasks: list[CampaignTask], variants: tuple[str, ...],
                 timepoints: tuple[Timepoint, ...], held_from: str | None) -> CampaignTask | None:
    """The task of ``held_from``'s first fit, or None when no other variant but ``free`` runs.

    Its own task if the variant runs (without jackknife errors otherwise),
    cut to the first timepoint.
    """
    if held_from is None or not any(v not in ("free", held_from) for v in variants):
        return None
    return replace(tasks[variants.index(held_from)] if held_from in variants else
                   replace(tasks[0], variant=held_from, embryo_errors=False),
                   timepoints=timepoints[:1])


def _run(executor, tasks: list[CampaignTask], source: CampaignTask | None, out: Path,
         timepoints: tuple[Timepoint, ...], variants: tuple[str, ...], resume: bool,
         settings: dict) -> tuple[list[CampaignTask], list, list[dict]]:
    """Run the campaign's tasks on ``executor``, with a progress bar of the fits.

    The held values' source fit first, then every variant.  Returns the
    tasks as run (with their ``held_from``), the reports of
    :func:`morphoshell.workflows.timepoint_fits.fit_variant` in their order,
    and that of the source fit.
    """
    # only now: a scheduler that does not answer must leave no folder and delete no results
    out.mkdir(parents=True, exist_ok=True)
    write_atomic(out / SETTINGS, json.dumps({**settings, "provenance": record_provenance()},
                                            indent=1, sort_keys=True) + "\n")
    if not resume:
        for tp in timepoints:
            for v in variants:
                result_path(out, tp.name, v).unlink(missing_ok=True)
    first_report: list = []
    if source is not None:
        if not resume:
            result_path(out, timepoints[0].name, source.variant).unlink(missing_ok=True)
        held, first_report = _held_from(executor, source)
        # (the source itself runs as without held_from, from its stored first fit)
        tasks = [t if t.variant == source.variant else replace(t, held_from=held)
                 for t in tasks]
    reports: list = [None] * len(tasks)
    watched = _watch(executor, tasks, reports, out, timepoints, variants)
    for _ in progress(watched, total=len(tasks) * len(timepoints), desc="fits", unit="fit"):
        pass
    return tasks, reports, first_report


def _held_from(executor, source: CampaignTask) -> tuple[dict, list[dict]]:
    """Fit (or read) the first timepoint of ``source``: the held values of ``held_from``.

    Returns the task's ``held_from`` and the fit's report (:func:`fit_variant`).
    """
    report = executor.submit(fit_variant, source).result()
    tp = source.timepoints[0]
    rec = read_record(result_path(Path(source.out), tp.name, source.variant)) or {}
    held = {"variant": source.variant, "timepoint": tp.name}
    if rec.get("status") != "ok":
        return {**held, "message": rec.get("message", "no result was written")}, report
    return {**held, "parameters": rec["parameters"]}, report


def _watch(executor, tasks, reports, out, timepoints, variants) -> Iterator[None]:
    """Run the tasks; yield once per finished fit (result files appearing), for a progress bar."""
    paths = [result_path(out, tp.name, v) for v in variants for tp in timepoints]

    def count():
        return sum(p.exists() for p in paths)
    seen = 0
    if isinstance(executor, SerialExecutor):    # runs at submission: report per variant
        for i, task in enumerate(tasks):
            reports[i] = fit_variant(task)
            now = count()
            yield from (None for _ in range(now - seen))
            seen = now
        return
    futures = {executor.submit(fit_variant, task): i for i, task in enumerate(tasks)}
    pending = set(futures)
    while pending:
        finished, pending = cf.wait(pending, timeout=0.5, return_when=cf.FIRST_COMPLETED)
        for f in finished:
            reports[futures[f]] = f.result()
        now = count()
        yield from (None for _ in range(now - seen))
        seen = now


def _fit_reports(tasks: list[CampaignTask], reports: list, first_report: list[dict],
                 held_from: str | None) -> list[dict]:
    """Every fit's report (:func:`fit_variant`) with its variant: the timing's ``fits``.

    The source's own task read its first fit back: reported once, as fitted before.
    """
    return [dict(r, variant=held_from) for r in first_report] + [
        dict(r, variant=tasks[i].variant) for i, rep in enumerate(reports) for r in rep
        if not (first_report and tasks[i].variant == held_from and r is rep[0])]
