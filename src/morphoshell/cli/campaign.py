"""``morphoshell campaign``: the Volvox fits of every timepoint and variant (paper Fig. 3 N, O)."""
from __future__ import annotations

import argparse
from pathlib import Path

from ._args import add_executor, integer, reworded
from ._commands import help_of

__all__ = ["register"]


def _variants(text: str) -> tuple[str, ...]:
    """A comma-separated list of Volvox variants (checked at parse time)."""
    from ..fitting import VARIANTS

    names = tuple(v.strip() for v in text.split(",") if v.strip())
    bad = [v for v in names if v not in VARIANTS]
    if not names or bad:
        raise argparse.ArgumentTypeError(f"{text!r}: choose from {','.join(VARIANTS)}")
    if len(set(names)) != len(names):
        raise argparse.ArgumentTypeError(f"{text!r}: a variant is named twice")
    return names


def _out_dir(text: str) -> Path:
    """An output folder: may exist (a folder, writable) or be created in an existing folder."""
    import os

    path = Path(text)
    if not text.strip():
        raise argparse.ArgumentTypeError("the output folder is empty")
    if path.exists() and not path.is_dir():
        raise argparse.ArgumentTypeError(f"{text!r} is a file, not a folder")
    probe = path if path.exists() else path.parent if str(path.parent) else Path(".")
    if not probe.is_dir() or not os.access(probe, os.W_OK | os.X_OK):
        raise argparse.ArgumentTypeError(f"{text!r}: {str(probe)!r} is not a writable folder")
    return path


def register(sub) -> None:
    """Add ``morphoshell campaign`` to the subcommands ``sub``."""
    from ..workflows import CAMPAIGN_NODES
    from ..fitting import METHODS, VARIANTS

    p = sub.add_parser(
        "campaign", help=help_of("campaign"),
        description="Fit the Volvox model to the average midline of every timepoint listed in "
                    "DATA_DIR/timepoints.csv (columns timepoint, pseudotime, midline; units of "
                    "R), in order, each fit warm-started from the previous timepoint's, for "
                    "each variant of the posterior intrinsic curvature kappa1 (flat 0, "
                    "undeformed 1, unstressed 1/f1, free). f1, kappa3, kappa4 are fitted at the "
                    "first timepoint and held after, except in the free variant. Variants run "
                    "in parallel worker processes (Dask if installed, else a process pool). "
                    "Writes OUT/<timepoint>_<variant>.json per fit (atomically: an interrupted "
                    "campaign resumes where it stopped, with identical results) and "
                    "OUT/campaign_summary.csv (E_fit in R and the parameters against "
                    "pseudotime; units: docs, 'Results as tables'), and the settings in "
                    "OUT/campaign_settings.json.")
    p.add_argument("data_dir", metavar="DATA_DIR",
                   help="folder with timepoints.csv (data/synthetic_inversion is a synthetic one)")
    p.add_argument("--variants", type=_variants, default=VARIANTS, metavar="V1,V2",
                   help=f"comma-separated variants (default: {','.join(VARIANTS)})")
    p.add_argument("--method", choices=METHODS, default="gradient",
                   help="fit method: gradient (exact Jacobian, default), kkt (one NLP with the "
                        "equilibrium as constraints), nelder-mead (the paper's baseline)")
    p.add_argument("--timepoints", default=None, metavar="T1,T2",
                   help="fit only these timepoints (names from timepoints.csv, e.g. "
                        "t01,t02,t03: a short campaign); default all")
    p.add_argument("--nodes", type=integer(*CAMPAIGN_NODES), default=200, metavar="N",
                   help=f"mesh nodes of the inner solves, {CAMPAIGN_NODES[0]} to "
                        f"{CAMPAIGN_NODES[1]} as for morphoshell fit (default 200)")
    p.add_argument("--embryo-errors", nargs="?", type=_variants, const=True, default=False,
                   metavar="V1,V2",
                   help="also fit the average of a timepoint's traces (the optional 'traces' "
                        "column of timepoints.csv) with each left out in turn, and record the "
                        "jackknife standard errors (one more fit per trace); for every variant, "
                        "or only those listed (e.g. --embryo-errors free)")
    p.add_argument("--held-from", choices=VARIANTS, default=None, metavar="VARIANT",
                   help="hold f1, kappa3, kappa4 in every variant but free at the values of "
                        "this variant's fit of the first timepoint, from the first timepoint on "
                        "(the paper's test of the held values, SI Fig. S2: the variants then "
                        "differ in kappa1 alone; free's fit assumes no hypothesis); default: "
                        "each variant fits its own at the first timepoint")
    add_executor(p, "this process for a short campaign, else one per variant, at most one "
                    "per CPU core")
    p.add_argument("--out", type=_out_dir, default=Path("campaign"), metavar="DIR",
                   help="output folder (default: ./campaign)")
    p.add_argument("--force", action="store_true",
                   help="run into a folder that holds a campaign with other settings (data, "
                        "method, nodes): record the new ones and refit its fits as "
                        "they come (default: refused, naming the setting)")
    p.add_argument("--allow-failures", action="store_true",
                   help="exit 0 even when fits failed or did not converge, or the best fit "
                        "of a timepoint is far above what the model leaves of a traced midline "
                        "(default: exit status 3, naming them on the last line)")
    resume = p.add_mutually_exclusive_group()
    resume.add_argument("--resume", dest="resume", action="store_true", default=True,
                        help="keep results already in DIR made with the same data, method and "
                             "nodes, and fit only the missing ones (default)")
    resume.add_argument("--no-resume", dest="resume", action="store_false",
                        help="refit everything")
    p.set_defaults(run=_campaign)


#: The arguments of workflows.campaign that its messages name, as the command line spells them.
_OPTIONS = {r"^embryo_errors\b": "--embryo-errors", r"^held_from\b": "--held-from",
            r"^timepoints\b": "--timepoints", r"^variants\b": "--variants",
            r"\bnot among the variants\b": "not among --variants"}


def _campaign(args) -> int:
    import sys

    from .._runtime.interrupts import exit_status
    from ..workflows import SUMMARY, CampaignInterrupted, campaign

    try:
        result = campaign(args.data_dir, args.variants, method=args.method,
                          workers=args.workers, scheduler=args.scheduler, out=args.out,
                          resume=args.resume, nodes=args.nodes, timepoints=args.timepoints,
                          embryo_errors=args.embryo_errors, held_from=args.held_from,
                          force=args.force)
    except CampaignInterrupted as exc:      # Ctrl-C or SIGTERM: how far it got, on one line
        print(f"morphoshell: {exc}", file=sys.stderr)
        return exit_status()
    except ValueError as exc:               # (refused before any work: name the options)
        raise ValueError(reworded(str(exc), _OPTIONS)) from None
    t = result.timing
    unfinished = result.unfinished()
    failed = sum(why == "failed" for *_, why in unfinished)
    per = f" ({t['fit_seconds'] / t['computed']:.3g} s per fit)" if t["computed"] else ""
    print(f"campaign of {_count(len(result.timepoints), 'timepoint')} x "
          f"{_count(len(result.variants), 'variant')} ({args.method}, {args.nodes} nodes) on "
          f"{t['workers']} worker(s) ({t['backend']}): {_count(t['computed'], 'fit')} in "
          f"{t['seconds']:.3g} s{per}, {sum(not f['computed'] for f in t['fits'])} reused, "
          f"{failed} failed")
    df = result.to_dataframe()
    if len(df):
        table = df.pivot(index=["timepoint", "pseudotime"], columns="variant", values="E_fit")
        print("E_fit [R]:")
        print(table.to_string(float_format=lambda v: f"{v:.4g}"))
    for line in _hypothesis_lines(result):
        print(line)
    print(f"  wrote {_written(result)} and {result.out / SUMMARY}")
    far, best = result.far_above(), result.best_far_above()
    print(_verdict(unfinished, len(result.records), args.allow_failures, far, best,
                   result.walls_cross()))
    return 3 if (unfinished or best) and not args.allow_failures else 0


def _hypothesis_lines(result) -> list[str]:
    """Per timepoint, which hypotheses its free fit rejects and which the data cannot tell
    apart (:meth:`~morphoshell.workflows.CampaignResult.hypothesis_tests`), with each
    Delta S/sigma^2 and threshold: the lowest E_fit alone does not decide (audit 25 F1)."""
    from ..fitting.hypotheses import TESTED

    if "free" not in result.variants:
        if len(result.variants) < 2:
            return []
        return ["hypotheses: not tested (the test of each against the data needs the free "
                "fit, which nests them: add free to --variants); the lowest E_fit alone does "
                "not decide"]
    lines = ["hypotheses against free (Delta S/sigma^2 against the 95% threshold; "
             "campaign_summary.csv: hypothesis_test):"]
    for name, (test, why) in result.hypothesis_tests().items():
        if test is None:
            if any(key[0] == name for key in result.records):
                lines.append(f"  {name}: not tested ({why})")
            continue
        ratios = ", ".join(f"{h.variant} {h.ratio:.3g}/{h.threshold:.3g}"
                           for h in test.hypotheses
                           if h.verdict in TESTED)
        lines.append(f"  {name}: {test.summary()} [{ratios}; sigma^2 from the "
                     f"{test.sigma2_source}]")
    return lines if len(lines) > 1 else []


def _written(result) -> str:
    """The fits' files, by name (the first and last of more than 3), in their folder."""
    from ..workflows.campaign_results import result_path

    names = [result_path(result.out, tp.name, v).name for tp in result.timepoints
             for v in result.variants if (tp.name, v) in result.records]
    shown = ", ".join(names) if len(names) <= 3 else f"{names[0]}, ..., {names[-1]}"
    return f"{_count(len(names), 'fit file')} in {result.out} ({shown})"


def _count(n: int, noun: str) -> str:
    return f"{n} {noun}{'s' * (n != 1)}"


def _verdict(unfinished: list, fits: int, allowed: bool, far: list | None = None,
             best: list | None = None, walls: list | None = None) -> str:
    """The last line: all converged, or how many failed and did not converge, by name; then
    the fits far above what the model leaves of a traced midline (their ``input_check``), and
    the timepoints whose best fit is one of them (exit status 3, as a failure); then the fits
    whose walls pass through each other (``walls_cross``: a note, not exit status 3: such a
    fit is a true minimum of the model, which has no self-contact, so the fit did its job
    and the shape, not the fit, is in doubt; a hypothesis that needs it is itself a result)."""
    failed = [f"{t}_{v}" for t, v, why in unfinished if why == "failed"]
    stopped = [f"{t}_{v}" for t, v, why in unfinished if why != "failed"]
    parts = [f"{len(names)} {what}: {', '.join(names)}"
             for names, what in ((failed, "failed"), (stopped, "did not converge")) if names]
    head = f"of {fits} fits, {'; '.join(parts)}" if parts else f"all {fits} fits converged"
    if far:
        head += (f"; {len(far)} fit far above what the model leaves of a traced midline "
                 f"(check the input or the hypothesis): {', '.join(f'{t}_{v}' for t, v in far)}")
    if best:
        head += (f"; {len(best)} of them the best fit of a timepoint (no variant describes "
                 f"its data: check the input): {', '.join(f'{t}_{v}' for t, v in best)}")
    if walls:
        one = len(walls) == 1
        head += (f"; {len(walls)} fitted shape{'' if one else 's'} whose walls pass through each "
                 f"other (the model has no self-contact: "
                 f"{'not a physical shape' if one else 'not physical shapes'}): "
                 f"{', '.join(f'{t}_{v}' for t, v in walls)}")
    if not (parts or best):
        return head
    tail = ("(--allow-failures: exit status 0)" if allowed else
            "(their JSON files say why; exit status 3, --allow-failures for 0)")
    return f"{head} {tail}"
