"""The timepoints of an inversion data set: the table ``timepoints.csv``.

A data set is a folder with ``timepoints.csv``, one row per inversion stage
(paper, main text, Fig. 3 D–O: the sequence a campaign fits), with columns
named in lower case and cells separated by commas (``;`` separates the
traces within a cell; a header of other separators or case is refused,
saying so)

``timepoint``
    A name (``t01``) of letters, digits, ``-``, ``_`` or ``.``, used in file
    names; unique.
``pseudotime``
    The stage's position in the sequence: a finite number, increasing down
    the table.
``midline``
    Path, relative to the folder, of the stage's average midline as
    :meth:`morphoshell.io.traces.Midline.to_csv` writes it (units of R,
    posterior pole at the origin).
``traces`` (optional)
    The single traces' midlines that were averaged, in the same form,
    separated by ``;`` (the jackknife of a campaign's ``embryo_errors``).

Blank lines and lines starting with ``#`` are skipped; an error names the
file's line.  ``scripts/make_synthetic_inversion.py`` writes a synthetic data
set.
"""
from __future__ import annotations

import csv
import io
from dataclasses import dataclass
from pathlib import Path

import numpy as np

__all__ = ["Timepoint", "read_timepoints"]

#: The table of a data set's folder.
_TABLE = "timepoints.csv"
#: Columns every table has (``traces`` is optional).
_COLUMNS = ("timepoint", "pseudotime", "midline")


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

    Returns
    -------
    timepoints : tuple of Timepoint, shape (T,)
        One per row of the table, in its order (pseudotime increasing).

    Raises
    ------
    ValueError
        One line naming the file, row or value that is wrong.
    """
    data_dir = Path(data_dir)
    table = data_dir / _TABLE
    _check_folder(data_dir, table)
    numbered, rows = _rows(table)
    out = [_timepoint(data_dir, table, i, row) for (i, _), row in zip(numbered[1:], rows)]
    _check_sequence(table, out)
    return tuple(out)


def _check_folder(data_dir: Path, table: Path) -> None:
    """The data set is a folder that holds the table."""
    if not data_dir.is_dir():
        raise ValueError(f"{str(data_dir)!r} is not a folder")
    if not table.is_file():
        raise ValueError(f"{str(data_dir)!r} has no timepoints.csv (columns timepoint, "
                         f"pseudotime, midline)")


def _rows(table: Path) -> tuple[list[tuple[int, str]], list[dict]]:
    """(file line number, text) of the lines that count, and the rows they make.

    Comment lines are skipped but not forgotten: errors name the file's line.
    """
    try:
        text = table.read_text(encoding="utf-8-sig")
    except UnicodeDecodeError as exc:
        raise ValueError(f"{table}: not a UTF-8 text (CSV) file (byte {exc.start}); expected "
                         f"a header timepoint,pseudotime,midline") from None
    numbered = [(k, ln) for k, ln in enumerate(text.splitlines(), 1)
                if ln.strip() and not ln.lstrip().startswith("#")]
    rows = list(csv.DictReader(io.StringIO("\n".join(ln for _, ln in numbered))))
    if not rows or not set(_COLUMNS) <= set(rows[0]):
        raise ValueError(f"{table}: {_header_problem(numbered, rows)}; expected a header "
                         f"timepoint,pseudotime,midline (cells separated by ',') and at least "
                         f"one row")
    return numbered, rows


def _header_problem(numbered: list[tuple[int, str]], rows: list[dict]) -> str:
    """What is wrong with the header (line, text) of a table that has not the columns or no
    row: its cells' separator, the case of its names, the columns missing, or no row.  (The
    message had been the same for all: audit 26, F6.)"""
    if not numbered:
        return "no header (the file is empty or all comments)"
    k, header = numbered[0]
    read = f"line {k}, the header, reads {header.strip()!r}"
    if "," not in header:
        for sep, name in ((";", "';'"), ("\t", "tabs")):
            if sep in header:
                return f"{read}: cells separated by {name}, not ','"
    names = [c.strip() for c in next(csv.reader([header]))]
    missing = [c for c in _COLUMNS if c not in names]
    if not missing:
        return f"{read} but no row follows it"
    if all(c in [n.lower() for n in names] for c in missing):
        return f"{read}: column names are lower case"
    return f"{read}: no column {', '.join(missing)}"


def _timepoint(data_dir: Path, table: Path, i: int, row: dict) -> Timepoint:
    """The row on line ``i`` of the table, each value checked in the order of the columns."""
    name = (row["timepoint"] or "").strip()
    if not name or not all(c.isalnum() or c in "-_." for c in name):
        raise ValueError(f"{table}, line {i}: timepoint {name!r} must be a non-empty name "
                         f"of letters, digits, '-', '_' or '.'")
    t = _pseudotime(table, i, row["pseudotime"])
    path = (row["midline"] or "").strip()
    if not (data_dir / path).is_file():
        raise ValueError(f"{table}, line {i}: midline file {path!r} "
                         f"{_why_not_a_file(data_dir / path)}")
    traces = tuple(v.strip() for v in (row.get("traces") or "").split(";") if v.strip())
    missing = [v for v in traces if not (data_dir / v).is_file()]
    if missing:
        raise ValueError(f"{table}, line {i}: trace file {missing[0]!r} "
                         f"{_why_not_a_file(data_dir / missing[0])}")
    return Timepoint(name, t, path, traces)


def _why_not_a_file(path: Path) -> str:
    """Why ``path`` is no file to read: it is a folder, or it does not exist."""
    return "is a folder, not a file" if path.is_dir() else "does not exist"


def _pseudotime(table: Path, i: int, text: str | None) -> float:
    """The pseudotime of line ``i``: a finite number."""
    try:
        t = float(text)
    except (TypeError, ValueError):
        raise ValueError(f"{table}, line {i}: pseudotime {text!r} is not a number") from None
    if not np.isfinite(t):
        raise ValueError(f"{table}, line {i}: pseudotime {t!r} is not finite")
    return t


def _check_sequence(table: Path, timepoints: list[Timepoint]) -> None:
    """Names are unique and pseudotimes increase down the table."""
    names = [tp.name for tp in timepoints]
    if len(set(names)) != len(names):
        raise ValueError(f"{table}: timepoint names repeat")
    times = [tp.pseudotime for tp in timepoints]
    if any(b <= a for a, b in zip(times, times[1:])):
        raise ValueError(f"{table}: pseudotimes must increase down the table")
