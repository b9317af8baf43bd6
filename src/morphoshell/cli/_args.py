"""Argument types and options shared by the commands (checked at parse time)."""
from __future__ import annotations

import argparse
import logging
import math
import re
from contextlib import contextmanager
from typing import Callable, Iterator, Mapping

from ._outputs import output_path

__all__ = ["integer", "real", "micrometres", "add_outputs", "TRACE_OPTIONS", "SOLVER_OPTIONS",
           "FORMAT_HELP",
           "SECTION_HELP", "OUTLIER_POINTS_HELP", "problem_and_settings", "reworded",
           "reader_notes", "linear_solver", "family_keys", "scale_hint", "micrometre_list"]


#: The Python arguments that the messages of morphoshell.io name, as the command line spells
#: them (a new user typed "pixel_size_um" into the shell).
TRACE_OPTIONS = {r"\bpixel_size_um\b": "--pixel-size", r"\bradius_um\b": "--radius-um",
                 r"\bsection='(\w+)'": r"--section \1", r"\broi='([^']*)'": r"--roi \1",
                 r"\broi=": "--roi ",
                 r"\bdrop_outlier_points=True\b": "--drop-outlier-points",
                 r"\bwith format '(\w+)' or none": r"with --format \1 or none",
                 r"\bthe pixel size and the radius R\b": "--pixel-size and --radius-um",
                 # (the command line has no option for it)
                 r"\(max_asymmetry = ([0-9.e+-]+)\)": r"(at most \1 R)"}

#: The Python arguments and objects that the solvers' failures name (their advice in
#: morphoshell.numerics.status.STATUSES), as the command line spells them, or marked as
#: Python's where it has none: after `solve --method bvp`, "raise max_nodes ... the last
#: iterate is attached (.last_iterate)" named neither an option nor an object it has (audit 26).
SOLVER_OPTIONS = {r"[;.] (?:the|The) [\w' ]+ is attached \(\.last_iterate\)": "",
                  r"\bmax_nodes \(--max-nodes on the command line\)": "--max-nodes",
                  r"\bloosen rtol\b": "loosen --rtol", r"\bmore stages\b": "more --stages",
                  r"(\buse|\bor|;) the direct method\b": r"\1 the direct method (--method direct)",
                  r"\bthe direct or bvp route\b":
                      "the direct or bvp route (--method direct or bvp)",
                  # (the reference routes' options, and Ipopt's iterations: Python's only)
                  r"(\b(?:raise|more|loosen) )(max_nodes|max_iter|max_segments|max_seconds|"
                  r"homotopy_steps|bc_tol|segments)\b(?! \(solve\()":
                      r"\1\2 (Python's solve() only)"}


#: What --section means, and its caveats (io.midlines), for the help of fit and average.
SECTION_HELP = ("whole: rim to rim through the posterior pole, mirror-averaged into a half; the "
                "pole is taken at half the trace's length, so trace both rims to their ends. "
                "half: from the pole (the first point) to a rim; its axis rests on the points "
                "within 0.4 R of the pole only, so noise tilts it: a half section whose axis's "
                "standard error moves the midline by more than 0.01 R rms is refused (from "
                "0.1-0.2 px of noise on an embryo of R = 140 px): trace whole sections where "
                "you can. Default (auto): whole for image traces, half for r,z CSVs")
#: What --drop-outlier-points does (io.trace_outliers), for the help of fit and average.
OUTLIER_POINTS_HELP = ("leave out an image trace's isolated outlier points (mis-clicks: points "
                       "more than 10 times the trace's noise off the curve of their neighbours, "
                       "named in a note); without it they are kept and named in a warning")
#: What the --format names mean (io.traces, io.trace_text), for the help of fit and average.
FORMAT_HELP = ("csv: a midline in units of R, header r,z (pole first); xy: image pixels x, y "
               "(y down), a header x,y or none, cells separated by commas, tabs or spaces, "
               "after a row-number column if any (a Fiji Results table); fiji-xy: Fiji's "
               "File > Save As > XY Coordinates (no header, x<TAB>y), read as xy; roi: an "
               "ImageJ .roi file or a ROI Manager set RoiSet.zip")


def family_keys() -> str:
    """Each packaged family's parameters for a --set help: ``"uniform: k; …; volvox: f1..f5,
    kappa1..kappa4, s1..s4, sigma; …"`` (numbered runs shortened), from the registry, so
    that a new family is listed (the blister's G, w had not been)."""
    from ..model.profiles import FAMILIES

    def runs(names):
        out, groups = [], {}
        for name in names:
            m = re.fullmatch(r"([a-z_]+)(\d+)", name)
            if m:
                groups.setdefault(m[1], []).append(int(m[2]))
                if len(groups[m[1]]) == 1:
                    out.append(m[1])
            else:
                out.append(name)
        return [f"{n}{min(groups[n])}..{n}{max(groups[n])}" if len(groups.get(n, ())) > 1
                else f"{n}{groups[n][0]}" if n in groups else n for n in out]
    return "; ".join(f"{f.name}: {', '.join(runs(f.parameters))}" for f in FAMILIES.values())


def reworded(message: str, options: Mapping[str, str]) -> str:
    """``message`` with the library's argument names spelt as the command line's options.

    The library's messages name its Python arguments (``pixel_size_um``); on the
    command line they must name the options (``--pixel-size``) that the user types.

    Parameters
    ----------
    message : str
        A library's message.
    options : mapping of str to str
        Regular expressions of the argument names (``\\b`` at their ends: a file
        name that contains one stays as it is) and their replacements.

    Returns
    -------
    str
    """
    for pattern, option in options.items():
        message = re.sub(pattern, option, message)
    return message


@contextmanager
def reader_notes() -> Iterator[list[str]]:
    """The notes of the trace readers (INFO of ``morphoshell.io``), collected, not shown.

    What alignment did to a trace (bins, a spline through sparse points, a half
    section's axis and its error) is a note at INFO, which the terminal shows
    only with ``-v``; a command that reads traces prints these notes itself,
    once its checks have passed, so that a refused trace still gets its one
    line.  Records above INFO (outlier points) pass on, reworded.

    Yields
    ------
    list of str
        The notes, reworded for the command line, filled as they come.
    """
    logger, notes = logging.getLogger("morphoshell.io"), []

    class Collect(logging.Handler):
        def emit(self, record: logging.LogRecord) -> None:
            if record.levelno == logging.INFO:
                notes.append(reworded(record.getMessage(), TRACE_OPTIONS))
            else:           # (a warning names the command line's options too)
                record.msg, record.args = reworded(record.getMessage(), TRACE_OPTIONS), ()
                logging.getLogger("morphoshell").handle(record)

    handler, saved = Collect(logging.DEBUG), (logger.level, logger.propagate)
    logger.addHandler(handler)
    logger.setLevel(logging.INFO)
    logger.propagate = False
    try:
        yield notes
    finally:
        logger.removeHandler(handler)
        logger.setLevel(saved[0])
        logger.propagate = saved[1]


def scale_hint(path, fmt: str | None, pixel_size: float, radius: float | list[float],
               whose: str = "the embryo's") -> Callable[[float, tuple[float, float]], str]:
    """What the message of a midline too long or short for the model asks of an image trace
    (``fitting.check_midline``'s ``scale_hint``): the options that set its scale, or the
    likely mistake where the length names it.

    A Fiji XY export of a spatially calibrated image is in µm, with decimals (docs/fitting.md:
    pass ``--pixel-size 1``); read with the pixel size it is that factor off, and the user,
    asked whether the pixel size is right, answers yes (audit 25: 0.676 R long, "4.2×
    shorter", at --pixel-size 0.25).  So where the length at ``--pixel-size 1`` lies within
    the lengths the check allows, the message says so, and whether the file's coordinates
    have decimals (a trace in pixels from Fiji's line tools has none; a ROI is in pixels
    whatever the calibration, and is not asked about).

    Parameters
    ----------
    path : str or Path
        The trace file.
    fmt : str or None
        ``--format``.
    pixel_size : float
        ``--pixel-size``.
    radius : float or list of float
        ``--radius-um`` of this trace, or the radii of a set's line ROIs averaged into it.
    whose : str
        Whose radius, for the question.
    """
    question = (f"is --pixel-size {pixel_size:g} the size of a pixel in µm (Fiji: Image › "
                f"Properties), and --radius-um {_radii_text(radius)} {whose} radius R in µm?")

    def hint(length: float, allowed: tuple[float, float]) -> str:
        at_one = length / pixel_size                # (the length scales with the pixel size)
        if pixel_size == 1 or not allowed[0] <= at_one <= allowed[1]:
            return question
        import numpy as np

        from ..io.traces import text_coordinates
        values = text_coordinates(path, fmt)
        if values is None:
            return question
        off = (f"1/{pixel_size:g} = {1 / pixel_size:.3g}× too short" if pixel_size < 1
               else f"{pixel_size:g}× too long")
        how = f"{off}: {at_one:.3g} R long at --pixel-size 1"
        if np.any(values != np.round(values)):
            return (f"the coordinates look like µm already (non-integer, and the midline is "
                    f"{how}): pass --pixel-size 1 (Fiji writes the XY coordinates of a "
                    f"calibrated image in µm)")
        return (f"the coordinates may be in µm already (the midline is {how}): if Fiji "
                f"exported them from a calibrated image, pass --pixel-size 1; else {question}")
    return hint


def note(text: str) -> None:
    """Print ``note: text`` on standard output, unless ``-q`` (the ``morphoshell`` logger
    shows errors only): a note is a remark on the work, not its result."""
    if logging.getLogger("morphoshell").isEnabledFor(logging.WARNING):
        print(f"note: {text}")


def integer(lo: int, hi: int) -> Callable[[str], int]:
    """An integer in [lo, hi]."""
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not an integer") from None
        if not lo <= value <= hi:
            raise argparse.ArgumentTypeError(f"{value} must lie in [{lo}, {hi}]")
        return value
    parse.__name__ = "integer"
    return parse


def real(lo: float = -math.inf, hi: float = math.inf, *, open_lo: bool = False,
         open_hi: bool = False, unit: str = "") -> Callable[[str], float]:
    """A finite real number in [lo, hi] (bounds excluded where ``open_*``)."""
    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
        low_ok = value > lo if open_lo else value >= lo
        high_ok = value < hi if open_hi else value <= hi
        if not math.isfinite(value) or not (low_ok and high_ok):
            raise argparse.ArgumentTypeError(f"{text} must be a finite number{bounds}{unit}")
        return value

    # (no bound is none to name: "--to nan must be a finite number in [-inf, inf]", audit 26 F7)
    bounds = ("" if math.isinf(lo) and math.isinf(hi) else
              f" in {'(' if open_lo else '['}{lo:g}, {hi:g}{')' if open_hi else ']'}")
    parse.__name__ = "number"
    return parse


def linear_solver(text: str) -> str:
    """One of Ipopt's linear solvers that Ipopt can load here (the HSL ones only with the
    user's libhsl.so): refused at parse time, before the problem file is read."""
    from ..numerics.ipopt_options import check_ipopt_options

    try:
        check_ipopt_options(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc).replace("linear_solver = ", "", 1)) from None
    return text


linear_solver.__name__ = "linear solver"


def _radii_text(radius: float | list[float]) -> str:
    """A radius, or a set's radii, as ``--radius-um`` takes them (comma-separated)."""
    return ",".join(f"{r:g}" for r in (radius if isinstance(radius, list) else [radius]))


def micrometres(text: str) -> float:
    """A length in µm of an image's scale (a pixel's size, an embryo's radius): in (0, 10⁶]."""
    return real(0, 1e6, open_lo=True, unit=" um")(text)


micrometres.__name__ = "number"


def micrometre_list(text: str) -> list[float]:
    """``--radius-um`` of the commands that read several traces (average; fit of a ROI set's
    ``--roi all``): one radius in µm, or several separated by commas."""
    return [micrometres(part.strip()) for part in text.split(",")]


micrometre_list.__name__ = "number"


def add_executor(p: argparse.ArgumentParser, default_workers: str) -> None:
    """``--workers`` and ``--scheduler``: where the tasks of a sweep or campaign run
    (:mod:`morphoshell.workflows.executor`); ``default_workers`` says what no ``--workers``
    means."""
    p.add_argument("--workers", type=integer(1, 4096), default=None, metavar="N",
                   help=f"worker processes (default: {default_workers}); ignored with "
                        f"--scheduler")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="a running Dask scheduler, e.g. tcp://host:8786 (default: "
                        "$DASK_SCHEDULER_ADDRESS, else a local cluster or process pool)")


def add_outputs(p: argparse.ArgumentParser, json: str, csv: str | None = None,
                plot: str | None = None) -> None:
    """--json / --csv / --plot, each validated before any work (see ``_outputs``)."""
    p.add_argument("--json", type=output_path("json"), metavar="OUT.json", help=json)
    if csv:
        p.add_argument("--csv", type=output_path("csv"), metavar="OUT.csv", help=csv)
    if plot:
        p.add_argument("--plot", type=output_path("plot"), metavar="OUT.png",
                       help=plot + " (.png, .pdf or .svg)")


def problem_and_settings(path, overrides):
    """The problem and solver settings of a problem file with ``--set`` overrides applied.

    Raises ``ProblemFileError`` naming the file, or the ``--set`` item, that is bad.
    """
    from ..io.problem_files import (ProblemFileError, apply_overrides, load_problem,
                                    parse_overrides, settings_from, split_overrides)

    problem, settings = load_problem(path)
    problem_over, solver_over = split_overrides(parse_overrides(overrides))
    problem = apply_overrides(problem, problem_over, str(path))
    try:
        settings = settings_from(solver_over, settings)
    except ValueError as exc:
        raise ProblemFileError(f"--set: {exc}") from None
    return problem, settings


def direct_only(path, settings, command: str) -> None:
    """``ProblemFileError`` where the file or ``--set`` asks a command that has only the direct
    method (``sweep``, ``continue``; plural) for a reference route: ``continue`` ran the direct
    one with a note where ``sweep`` refused (audit 26, F5)."""
    if settings.method != "direct":
        from ..io.problem_files import ProblemFileError
        raise ProblemFileError(f"{path}: method = {settings.method!r}: {command} use the "
                               f"direct method")
