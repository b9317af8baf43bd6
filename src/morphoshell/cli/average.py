"""``morphoshell average``: the traces of one stage as the average midline a campaign fits.

From image traces (Fiji XY, .roi, RoiSet.zip, x,y CSV; each embryo at its own
radius) or midline CSVs to the files of a campaign's data folder
(docs/campaigns.md, "Data"): the average midline with its pointwise spread
and, with ``--traces``, each trace's midline beside it (the jackknife's
inputs).  Each trace is checked as a fit would check it, and a trace far from
the others (:data:`OUTLIER_RATIO`) is named: the check to make before a campaign.
"""
from __future__ import annotations

import re
from pathlib import Path

from ._args import (FORMAT_HELP, OUTLIER_POINTS_HELP, SECTION_HELP, TRACE_OPTIONS, add_outputs,
                    micrometre_list, micrometres, note, reader_notes, reworded, scale_hint)
from ._commands import help_of
from ._outputs import Outputs

__all__ = ["register", "OUTLIER_RATIO"]

#: A trace whose rms distance from the traces' pointwise median exceeds this many times the
#: median of all traces' is named as an outlier (a wrong scale, a flipped or retraced path):
#: on the shipped synthetic stages (12 × 5 traces) every trace lies within 2.4 times the
#: median, and one read 5 % off in scale at 13-37 times (io.midlines.trace_distances).
OUTLIER_RATIO = 5.0


def register(sub) -> None:
    """Add ``morphoshell average`` to the subcommands ``sub``."""
    from ..io.midlines import SECTIONS
    from ..io.traces import FORMATS

    p = sub.add_parser(
        "average", help=help_of("average"),
        description="Read, align and resample each trace (the same steps as `fit`), check "
                    "it, and write their average midline (units of R, 100 points equally "
                    "spaced in arclength, with the pointwise spread and the number of traces) "
                    "as a campaign's data folder lists it in timepoints.csv. A ROI Manager "
                    "set (RoiSet.zip) adds every line ROI as a trace (or the one --roi "
                    "names). Each trace's rms distance from the traces' pointwise median is "
                    "printed; one over 5 times the median of these is named as an outlier.")
    p.add_argument("traces", nargs="+", metavar="TRACE",
                   help="trace files of one stage: image traces (Fiji XY, .roi, RoiSet.zip, "
                        "x,y CSV; need --pixel-size and --radius-um) or midline CSVs of r,z "
                        "(units of R)")
    p.add_argument("--format", choices=FORMATS, default=None,
                   help=f"file format of every TRACE (default: from each file's content). "
                        f"{FORMAT_HELP}")
    p.add_argument("--pixel-size", dest="pixel_size", type=micrometres, default=None,
                   metavar="UM", help="image traces: micrometres per pixel "
                   "(Fiji: Image > Properties > Pixel width); required with --radius-um")
    p.add_argument("--radius-um", dest="radius_um", type=micrometre_list, default=None,
                   metavar="R[,R...]",
                   help="image traces: the embryo's radius R in micrometres, the unit of "
                        "lengths: one for every TRACE, one per TRACE in their order (the "
                        "ROIs of a set share its file's), or one per trace, each line ROI of "
                        "a set in the set's order (comma-separated)")
    p.add_argument("--roi", default=None, metavar="NAME|INDEX|all",
                   help="in a ROI Manager set: the line ROI to take, by name or position "
                        "(from 1), or all (default): every line ROI is a trace")
    p.add_argument("--section", choices=SECTIONS, default="auto",
                   help=f"what an image trace covers. {SECTION_HELP}")
    p.add_argument("--drop-outlier-points", dest="drop_outlier_points", action="store_true",
                   help=OUTLIER_POINTS_HELP)
    p.add_argument("--traces", dest="write_traces", action="store_true",
                   help="also write each trace's midline beside the --csv file, named "
                        "<average>_<trace>.csv (the timepoints.csv column traces, for "
                        "the campaign's jackknife errors)")
    p.add_argument("--drop-outliers", dest="drop_outliers", action="store_true",
                   help="leave the traces named outliers out of the average (their names "
                        "go into its # comments); without it they are averaged in and named")
    add_outputs(p, json="write the average, the traces' midlines and their distances as JSON",
                csv="write the average midline (r, z, spread; n_traces, sources, --section, "
                    "--pixel-size, --radius-um and the version as # comments), as a "
                    "campaign's timepoints.csv lists it",
                plot="draw the traces over their average, and their distances along it")
    p.set_defaults(run=_average)


def _check_options(args) -> list:
    """The radius of each TRACE: a float, a list of one per line ROI of a set, or None (not an
    image trace); one line naming a bad option."""
    if (args.pixel_size is None) != (args.radius_um is None):
        raise ValueError("--pixel-size and --radius-um go together: image traces need both")
    if args.write_traces and args.csv is None:
        raise ValueError("--traces writes the traces' midlines beside the --csv file: give --csv")
    radii = args.radius_um or [None]
    if len(radii) in (1, len(args.traces)):
        return radii * len(args.traces) if len(radii) == 1 else radii
    sizes = _set_sizes(args)
    counts = [k or 1 for k in sizes]
    if len(radii) != sum(counts):
        raise ValueError(f"--radius-um has {len(radii)} radii for {len(args.traces)} TRACE files "
                         f"holding {sum(counts)} traces: give one for all, one per TRACE (the "
                         f"line ROIs of a set share its file's), or one per trace, a set's line "
                         f"ROIs in its order")
    per_file, at = [], 0
    for size, k in zip(sizes, counts):
        per_file.append(radii[at] if size is None else radii[at:at + k])
        at += k
    return per_file


def _roi_choice(args, path):
    """--roi for the file ``path``: as given, or for a set without it every line ROI."""
    from ..io.roi_sets import is_roi_set

    if args.roi is None and args.format in (None, "roi") and is_roi_set(path):
        return "all"
    return args.roi


def _set_sizes(args) -> list[int | None]:
    """How many traces each TRACE holds: a set's line ROIs chosen, None for another file (read
    before any work, to match one radius to each trace)."""
    from ..io import MidlineError
    from ..io.roi_sets import is_roi_set, line_roi_names

    sizes = []
    for path in args.traces:
        if args.format not in (None, "roi") or not is_roi_set(path):
            sizes.append(None)
            continue
        try:
            sizes.append(len(line_roi_names(path, _roi_choice(args, path))))
        except MidlineError as exc:
            raise MidlineError(reworded(str(exc), TRACE_OPTIONS)) from None
    return sizes


def _load(args, radii) -> list:
    """Every trace's midline (N_FIT points), checked as `fit` checks a midline; the readers'
    notes printed once all are accepted."""
    from ..fitting import N_FIT, check_midline, volvox_spec
    from ..io import MidlineError, load_midlines

    spec, midlines, notes = volvox_spec("free"), [], []
    for path, radius in zip(args.traces, radii):
        try:
            with reader_notes() as found_notes:
                found = load_midlines(path, args.format, n=N_FIT, section=args.section,
                                      pixel_size_um=args.pixel_size, radius_um=radius,
                                      roi=_roi_choice(args, path),
                                      drop_outlier_points=args.drop_outlier_points)
        except MidlineError as exc:
            raise MidlineError(reworded(str(exc), TRACE_OPTIONS)) from None
        notes += found_notes
        for m, r in zip(found, radius if isinstance(radius, list) else [radius] * len(found),
                        strict=True):
            hint = (scale_hint(path, args.format, args.pixel_size, r, "this embryo's")
                    if r is not None else
                    "are its r and z in units of R (µm divided by the embryo's radius in µm; a "
                    "trace in pixels needs --pixel-size and --radius-um)?")
            check_midline(spec, m, f"{m.source[0]}: the midline", scale_hint=hint)
        midlines += found
    if len(midlines) < 2:
        raise ValueError(f"{len(midlines)} trace in {', '.join(map(str, args.traces))}: an "
                         f"average needs at least 2 (fit a single trace with `morphoshell fit`)")
    for text in notes:
        note(text)
    return midlines


def _trace_names(midlines) -> list[str]:
    """Short, file-safe names of the traces: file stems, a set's ROI names after its stem."""
    names = []
    for m in midlines:
        path, _, roi = m.source[0].partition(", ROI ")
        name = Path(path).stem + (f"_{roi.strip(chr(39))}" if roi else "")
        names.append(re.sub(r"[^A-Za-z0-9_.-]+", "_", name))
    repeated = sorted({n for n in names if names.count(n) > 1})
    if repeated:
        raise ValueError(f"two traces have the same name {repeated[0]!r} (files of one name in "
                         f"different folders?): rename one")
    return names


def _how_made(args, radii: list) -> list[str]:
    """The ``key = value`` comments of the written midlines that say how they were made: the
    scale of each TRACE file (an average could not be reproduced from its file) and the
    package version (and git commit, from a checkout)."""
    from .. import __version__
    from ..io.provenance import code_commit

    # (audit 27 F11: the columns' unit was said nowhere in the file, as the shipped averages say)
    lines = ["units = R (r, z and spread in units of R, the embryo's radius)",
             f"morphoshell = {__version__}",
             *(f"{k} = {str(v).lower()}" for k, v in code_commit().items()),
             f"section = {args.section}"]
    if args.drop_outlier_points:        # (only when given: the shipped averages stay as they are)
        lines.append("drop_outlier_points = true")
    if args.pixel_size is not None:
        lines.append(f"pixel_size_um = {args.pixel_size:.10g}")
        lines += [f"radius_um = {path}: {_micrometres(radius)}"
                  for path, radius in zip(args.traces, radii)]
    return lines


def _micrometres(radius) -> str:
    """A radius, or a set's radii (one per line ROI) separated by commas, as written."""
    return ", ".join(f"{r:.10g}" for r in (radius if isinstance(radius, list) else [radius]))


def _average(args) -> int:
    import numpy as np

    from ..io import average, trace_distances

    radii = _check_options(args)
    midlines = _load(args, radii)
    names = _trace_names(midlines)
    mean = average(midlines)
    rms = np.sqrt((trace_distances(midlines) ** 2).mean(axis=1))
    median = float(np.median(rms))
    print(f"{len(midlines)} traces, {len(mean.r)} points each; mean spread "
          f"{float(np.mean(mean.spread)):.3g} R")
    print("  trace                          rms distance from the traces' median (R)")
    outliers = [n for n, d in zip(names, rms) if len(rms) > 2 and d > OUTLIER_RATIO * median]
    for name, d in zip(names, rms):
        flag = "  <- an outlier: check its scale and path" if name in outliers else ""
        print(f"  {name:30s} {d:.3g}{flag}")
    made, kept = _how_made(args, radii), midlines
    if outliers and args.drop_outliers:
        kept = [m for m, n in zip(midlines, names) if n not in outliers]
        mean = average(kept)
        made.append(f"dropped_outliers = {', '.join(outliers)}")
        print(f"  left out of the average: {', '.join(outliers)} ({len(kept)} traces kept)")
    if not outliers or args.drop_outliers:      # (outliers averaged in are named below)
        _warn_of_spread(mean, kept, args.traces)
    out = Outputs()
    out.add(args.csv, lambda path: mean.to_csv(path, made))
    written = {}
    if args.write_traces:
        for name, m in zip(names, midlines):
            path = args.csv.with_name(f"{args.csv.stem}_{name}.csv")
            written[name] = path
            out.add(path, lambda path, m=m: m.to_csv(path, made))
    out.add(args.json, lambda path: _write_json(path, mean, midlines, names, rms, written,
                                                      args.traces))
    out.add(args.plot, lambda path: _plot(path, mean, midlines, names))
    for path in out.commit():
        print(f"  wrote {path}")
    if args.csv is not None:
        _row_hint(args.csv, list(written.values()))
    if outliers and not args.drop_outliers:
        print(f"morphoshell average: {len(outliers)} outlier{'s' * (len(outliers) > 1)} "
              f"({', '.join(outliers)}): more than {OUTLIER_RATIO:g} times the median "
              f"distance {median:.3g} R from the traces' median; the average includes "
              f"{'them' if len(outliers) > 1 else 'it'}: check the scale (--radius-um, "
              f"--pixel-size) and path, then rerun, leaving out a trace that does not belong "
              f"(--drop-outliers)")
    return 0


def _warn_of_spread(mean, midlines, files) -> None:
    """Warn where the traces differ far more than their noise and no outlier says why: all
    scaled wrong alike (one radius for several embryos) is no outlier (audit 25)."""
    import logging

    import numpy as np

    from ..io.trace_checks import spread_warning

    warning = spread_warning(float(np.mean(mean.spread)), [m.noise for m in midlines],
                             f"the {len(midlines)} traces of {', '.join(map(str, files))}")
    if warning:
        logging.getLogger("morphoshell").warning(reworded(warning, TRACE_OPTIONS))


def _row_hint(csv: Path, traces: list[Path]) -> None:
    """The files' entries of a timepoints.csv row, relative to the data folder DATA, taken to
    be the --csv file's grandparent (the layout DATA/t01/average.csv)."""
    data = csv.resolve().parent.parent

    def rel(path: Path) -> str:
        return path.resolve().relative_to(data).as_posix()
    print(f"for timepoints.csv in {data}: midline {rel(csv)}"
          + (f", traces {';'.join(rel(p) for p in traces)}" if traces else ""))


def _write_json(path, mean, midlines, names, rms, written, files) -> None:
    from ..io.problem_files import write_json

    write_json(path, {"average": {"r": mean.r, "z": mean.z, "spread": mean.spread,
                                  "n_traces": mean.n_traces},
                      "traces": [{"name": n, "source": m.source[0], "r": m.r, "z": m.z,
                                  "rms_distance": float(d), "file": str(written.get(n, ""))
                                  or None} for n, m, d in zip(names, midlines, rms)],
                      "units": "R"}, files)


def _plot(path, mean, midlines, names) -> None:
    from ..plotting import plot_traces, save

    save(plot_traces(mean, midlines, names, pyplot=False), path)
