"""``morphoshell compare``: which hypotheses on κ₁ the data tell apart.

The fits' JSON files (``morphoshell fit --json``) of one midline, tested against the
free fit by :func:`morphoshell.fitting.hypotheses.compare_hypotheses`; σ² from the spread
of the traces of the averaged midline they were fitted to, read again from their
``midline_file`` with the options that read it for the fits, or from the free fit's residual
(for one image trace scaled by its re-tracings, as κ₁'s profile).
"""
from __future__ import annotations

import argparse
from pathlib import Path

from ._args import add_outputs, note
from ._commands import help_of
from ._outputs import Outputs

__all__ = ["register"]

_DESCRIPTION = """\
Compare fits of the hypotheses on the posterior intrinsic curvature kappa1 (variants flat,
undeformed, unstressed: free with kappa1 tied) to one midline. Each is tested against the
free fit, which nests it: Delta S = E_fit^2 - E_free^2 (units of R^2) over the noise
variance sigma^2 is chi2_d at a true hypothesis of d restrictions, or d*F(d, n - 1) with
sigma^2 from the spread of n traces (the threshold of the profile intervals, fit --profile).
On one image trace (fit --pixel-size) sigma^2 is the free fit's residual's times kappa1's
(SE of the re-tracings / Gauss-Newton SE)^2, as kappa1's profile takes it (the residuals of
a trace are correlated). A hypothesis above its threshold is rejected, else consistent with
the data; the E_fit ranking of consistent ones is noise. Without a free fit the others are
compared with the best, without a test. The fits must be of the same midline points, shell
and mesh. A fit that did not converge leaves a verdict open ("not established": a stopped
hypothesis fit cannot be rejected, a stopped free fit cannot call one consistent); the exit
status is then 3, as fit's for an unconverged fit."""


def _noise(text: str) -> str | float:
    """--noise: auto, residual, traces, or sigma^2 itself (a positive number, R^2)."""
    if text in ("auto", "residual", "traces"):
        return text
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not value > 0 or value == float("inf"):
        raise argparse.ArgumentTypeError(f"{text!r}: choose auto, residual, traces or a "
                                         f"positive sigma^2 in R^2")
    return value


def register(sub) -> None:
    """Add ``morphoshell compare`` to the subcommands ``sub``."""
    p = sub.add_parser("compare", help=help_of("compare"), description=_DESCRIPTION,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("fits", nargs="+", metavar="FIT.json",
                   help="fits of one midline (morphoshell fit --json), each variant once, "
                        "free included for the test")
    p.add_argument("--midline", default=None, metavar="AVERAGE.csv",
                   help="the averaged midline the fits were made to, for sigma^2 from its "
                        "traces' spread (default: the fits' midline_file, relative to the "
                        "current folder), read with the fits' reading options")
    p.add_argument("--noise", type=_noise, default="auto", metavar="SOURCE",
                   help="where sigma^2 comes from: traces (the averaged midline's spread of n "
                        "traces; threshold d*F(d, n-1)), residual (the free fit's; chi2_d; "
                        "on one image trace times kappa1's re-tracing factor, as its profile; "
                        "else smaller than a traced midline's noise: rejects too readily), or a "
                        "number (sigma^2 in R^2); auto (default): traces when the midline "
                        "has them, else residual")
    add_outputs(p, json="write the comparison as JSON (sigma^2, each fit's Delta S, "
                        "Delta S/sigma^2, threshold and verdict, the summary)",
                csv="write the comparison as CSV, one row per fit")
    p.set_defaults(run=_compare)


def _records(paths: list[str]) -> dict[str, dict]:
    """Each file's record, by its path (ValueError naming a file that is not one)."""
    from ..io.problem_files import read_json

    records, seen = {}, {}
    for path in paths:
        same = seen.setdefault(Path(path).resolve(), path)      # (a.json and ./a.json: one)
        if path in records or same != path:
            raise ValueError(f"{path} is named twice{'' if same == path else f' (as {same})'}: "
                             f"compare one fit of each hypothesis")
        record = read_json(path)
        if not isinstance(record, dict):
            raise ValueError(f"{path}: expected the JSON object written by morphoshell fit --json")
        records[path] = record
    return records


def _midline(args, records: dict[str, dict]):
    """The midline for σ² from its traces, or None (σ² from the residual: no file to read,
    or --noise that needs none).  Read as the first record's settings read it."""
    from ..io.problem_files import record_midline

    if args.noise not in ("auto", "traces"):
        return None
    first = next(iter(records.values()))
    path = args.midline or first.get("midline_file")
    if args.midline and not Path(path).is_file():
        raise ValueError(f"--midline {path}: not a file")
    data = record_midline(first, args.midline)
    if data is None:
        missing = ("the fits' records name no midline file" if path is None else
                   f"{path} (the fits' midline_file) is not a file here")
        if args.noise == "traces":
            raise ValueError(f"--noise traces: {missing}: give the averaged midline with "
                             f"--midline AVERAGE.csv")
        note(f"{missing}: sigma^2 from the free fit's residual (--midline AVERAGE.csv for the "
             f"traces' spread)")
    return data


def _compare(args) -> int:
    from ..fitting.hypotheses import NOT_ESTABLISHED, compare_hypotheses
    from ..io.problem_files import write_csv, write_json

    records = _records(args.fits)
    data = _midline(args, records)
    test = compare_hypotheses(records, data, noise=args.noise)
    print(test.noise_line())
    print(test.table())
    print(test.summary())
    out = Outputs()
    out.add(args.json, lambda path: write_json(path, {"fits": list(args.fits), **test.to_dict()}))
    out.add(args.csv, lambda path: write_csv(path, test.columns()))
    for path in out.commit():
        print(f"  wrote {path}")
    # a verdict that a fit which stopped short leaves open is a fit not converged: exit 3, as
    # fit's and campaign's (the comparison is still written, its rows marked)
    return 3 if test.of(NOT_ESTABLISHED) else 0
