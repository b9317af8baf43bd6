"""Running a sweep's chunks: progress, Ctrl-C, the rows kept in a file marked partial, resumed.

:func:`~morphoshell.workflows.sweeps.sweep` sends its chunks to
:mod:`morphoshell.workflows.executor` through :func:`run_chunks`, which puts each row of
the product in place as its chunk finishes.  Ctrl-C (or SIGTERM:
:mod:`morphoshell._runtime.interrupts`) stops the workers at once (the executor kills them)
and, under :func:`interruptible`, raises :class:`SweepInterrupted`: how far the sweep got,
and every row, those of the chunks not finished with the status :data:`NOT_COMPUTED`.
As a campaign keeps its finished fits, the command line keeps these rows: it writes its
``--csv`` and ``--json`` marked partial (:meth:`SweepInterrupted.write`), and
``sweep(..., resume=path)`` (``--resume``) reads such a file back (:func:`restored`) and
computes only the chunks it lacks, once it has checked that the file was made with the
same settings (:func:`settings_record`; ValueError naming the first that differs).  Each
row is restored at the grid point of its coordinates (its axis columns), wherever it is in
the file; a point without a row is computed again, a row off the grid refused.

The unit kept is the chunk: its points are warm-started one from another, so a chunk
computed again from its first point gives the rows of a sweep never interrupted, bit for
bit; the points of a chunk cut short are computed again.  A partial file cannot pass for
a complete one: the CSV's first line is ``# morphoshell sweep PARTIAL: ...`` (without a
comma, so that a reader taking it for the header fails on the next line), the second
``# settings: {...}``, and the rows not computed have the status :data:`NOT_COMPUTED`;
the JSON has ``"complete": false``.
"""
from __future__ import annotations

import csv
import json
import math
import os
from contextlib import ExitStack, contextmanager
from itertools import product
from pathlib import Path
from typing import Any, Callable, Iterator, Mapping, Sequence

from .._runtime import interrupts
from .._runtime.console import counter
from ..io.provenance import check_format
from ..numerics.status import STATUSES
from .executor import backend_name, open_executor, run
from .sweep_results import NOT_COMPUTED, SweepResult, axis_column, point_label

__all__ = ["run_chunks", "interruptible", "SweepInterrupted", "settings_record", "restored",
           "whole_chunks", "NOT_COMPUTED", "PARTIAL"]

#: The first line of a partial sweep's CSV (after ``"# "``), then how far it got.
PARTIAL = "morphoshell sweep PARTIAL"
#: The second line's start (after ``"# "``): the sweep's settings as JSON.
SETTINGS = "settings: "
#: The message of a row that a partial sweep did not compute.
NOT_COMPUTED_MESSAGE = "not computed: the sweep was interrupted"
#: What to do about a row that the sweep did not write so (a refusal says it).
_EDITED = ("the file was edited or made by another sweep; restore the row as the sweep wrote "
           "it, or delete it (a point without a row is computed again)")
#: The command line's option of each setting (a refusal names it).
_OPTIONS = {"ablate": "--ablate", "nodes": "--nodes", "errors": "--errors",
            "chunk_size": "--chunk-size", "stages": "--stages", "linear_solver": "--linear-solver",
            "axes": "--set", "problem": "PROBLEM.toml or --set"}


class SweepInterrupted(KeyboardInterrupt):
    """A sweep stopped by Ctrl-C (or SIGTERM), with the rows of the chunks it finished.

    Attributes
    ----------
    result : SweepResult
        Every row of the product; those not computed have NaN values, the status
        :data:`NOT_COMPUTED` and a message saying so.
    done, total : int
        Points computed (those restored from a partial file included), and all of them.
    settings : dict
        The sweep's settings (:func:`settings_record`), which a partial file records.
    """

    def __init__(self, result: SweepResult, done: int, settings: Mapping[str, Any]):
        super().__init__(f"{interrupts.reason()} after {done} of {len(result)} points")
        self.result, self.done, self.total, self.settings = result, done, len(result), settings

    def write(self, path: str | Path) -> Path:
        """Write the rows as a partial sweep, CSV or JSON by the extension, from which
        ``sweep(..., resume=path)`` computes the rest (the module docstring says how it
        is marked)."""
        from ..io.problem_files import write_csv, write_json

        path = Path(path)
        if path.suffix.lower() == ".json":
            return write_json(path, {**self.result.to_dict(), "complete": False,
                                     "points_done": self.done, "settings": self.settings})
        head = (f"{PARTIAL}: {self.done} of {self.total} points computed (the rows of status "
                f"{NOT_COMPUTED} are not) - the same sweep with --resume computes the rest")
        return write_csv(path, self.result.columns,
                         comments=(head, SETTINGS + json.dumps(self.settings)))


def settings_record(problem, axes: Mapping[str, Sequence], ablate: bool, nodes: int,
                    errors: str, chunk_size: int | None, options: Mapping[str, Any]) -> dict:
    """What a sweep's rows depend on besides the code, JSON-ready: the problem, the axes,
    ``ablate``, ``nodes``, ``errors``, ``chunk_size`` (the chunks) and the solver options.
    Not the workers, which do not change the numbers."""
    from ..io.problem_files import to_jsonable

    record = {"problem": problem.describe(), "axes": dict(axes), "ablate": bool(ablate),
              "nodes": int(nodes), "errors": errors, "chunk_size": chunk_size, **options}
    return json.loads(json.dumps(to_jsonable(record)))     # (as read back: lists, not tuples)


def run_chunks(run_chunk: Callable, tasks: Sequence, results: list, workers: int | None,
               scheduler: str | None, desc: str) -> str:
    """Run every chunk of ``tasks`` (``run_chunk(task)`` → its rows), each row put in
    ``results`` at its index as its chunk finishes; return the executor's back end.

    A scheduler that does not answer is bad input: ValueError naming it.
    """
    with ExitStack() as stack:
        try:
            executor = stack.enter_context(open_executor(workers, scheduler))
        except OSError as exc:     # no scheduler there: bad input, named
            raise ValueError(f"scheduler {scheduler or os.environ.get('DASK_SCHEDULER_ADDRESS')!r}"
                             f": cannot connect ({exc})") from None
        backend = backend_name(executor)
        sizes = [len(t.points) for t in tasks]
        if backend == "serial":   # run() would solve every chunk before showing its bar
            bar = stack.enter_context(counter(total=sum(sizes), desc=desc, unit="point"))
            done = ((i, run_chunk(t, tick=bar.update)) for i, t in enumerate(tasks))
        else:
            done = run(run_chunk, tasks, executor, description=desc, sizes=sizes, unit="point")
        for _, rows in done:
            for index, row in rows:
                results[index] = row
    return backend


@contextmanager
def interruptible(results: list, blank: Mapping[str, Any],
                  finish: Callable[[list[dict]], SweepResult],
                  settings: Mapping[str, Any]) -> Iterator[None]:
    """Ctrl-C in the block (in this process within CasADi: a SystemError caused by it)
    raises :class:`SweepInterrupted` with ``finish(rows)``: the rows of ``results`` there
    are, ``blank`` (a row before its point is solved) marked :data:`NOT_COMPUTED` for
    the others."""
    try:
        yield
    except BaseException as exc:
        if not interrupts.interrupted(exc):
            raise
        missing = {**blank, "status": NOT_COMPUTED, "message": NOT_COMPUTED_MESSAGE,
                   "seconds": math.nan}
        rows = [dict(missing) if row is None else
                {k: v for k, v in row.items() if not k.startswith("_")} for row in results]
        done = sum(row is not None for row in results)
        raise SweepInterrupted(finish(rows), done, settings) from None


def whole_chunks(kept: Mapping[int, dict], chunks: Sequence[Sequence[int]], n: int) -> list:
    """The ``n`` rows of a sweep as far as ``kept`` holds whole chunks (None elsewhere: the
    rows of a chunk are computed together, each warm-started from the one before)."""
    rows: list = [None] * n
    for chunk in chunks:
        if all(i in kept for i in chunk):
            for i in chunk:
                rows[i] = kept[i]
    return rows


def restored(path: str | Path, settings: Mapping[str, Any], blank: Mapping[str, Any],
             axes: Mapping[str, Sequence], ablate: bool,
             values: Sequence[str] = ()) -> dict[int, dict]:
    """The rows a partial sweep file (:meth:`SweepInterrupted.write`) computed, by their
    index in this sweep's grid.

    A row is put at its grid point by its coordinates, the values of its axis columns,
    wherever it is in the file: a file whose rows were deleted (a failed point's, say)
    gives the rows there are, and the points without one are computed again.  The
    coordinates are compared exactly: the sweep writes every float as its ``repr`` (CSV;
    JSON likewise), which reads back to the same float, so a value not equal to the bit
    was edited, and a row meant for another point must not pass for it.

    Parameters
    ----------
    path : str or Path
        The file, CSV or JSON by its extension; none there: no rows.
    settings : mapping
        This sweep's settings (:func:`settings_record`), which the file's must equal.
    blank : mapping
        A row before its point is solved: the keys and types of a row.
    axes : mapping
        This sweep's axes (name → values, the product's order).
    ablate : bool
        Ablation sweep (the axis ``opening`` is the column ``opening_P``).
    values : sequence of str
        The value columns, finite on a row that did not fail (one without a message).

    Raises
    ------
    ValueError
        The file is not UTF-8 text or not a partial sweep (a complete one, say) or lacks
        its settings, was made with other settings (the first named, and its option), or
        has a row that is cut short, lacks a column, has a cell that is not a value of
        its column's type (a status outside :data:`~morphoshell.numerics.status.STATUSES`,
        a non-finite value on a row that did not fail, a ``walls_cross`` neither True nor
        False), is at coordinates that are not a point of the grid or repeats another
        row's (the file, the row and the column named).  A text file may start with a
        UTF-8 byte-order mark (an editor's).
    """
    path = Path(path)
    if not path.exists():
        return {}
    recorded, rows = (_read_json if path.suffix.lower() == ".json" else _read_csv)(path)
    _check_settings(path, recorded, settings)
    grid = _Grid(axes, ablate)
    keys = {**blank, "seconds": math.nan}
    out, rows_at = {}, {}
    for i, row in enumerate(rows):
        where = f"{path}, row {i + 1}"
        missing = [k for k in (*grid.columns, *keys) if k not in row]
        if missing:
            raise ValueError(f"{where} has no column {missing[0]!r}: not a sweep of this "
                             f"version of morphoshell")
        index = grid.index(row, where)
        if index in rows_at:
            raise ValueError(f"{where}: {grid.label(index)} repeats row {rows_at[index] + 1}: "
                             f"delete one of them (a point without a row is computed again)")
        rows_at[index] = i
        if row["status"] != NOT_COMPUTED:
            out[index] = {k: _typed(row[k], like, f"{where}, column {k!r}")
                          for k, like in keys.items()}
            _check_row(out[index], values, where)
    return out


def _check_row(row: Mapping[str, Any], values: Sequence[str], where: str) -> None:
    """ValueError (``where``: the file and the row) where a restored row is not one a sweep
    writes: a status not of the table, a non-finite value on a row that did not fail (audit
    17: both were restored and written back, the row not counted as failed)."""
    if row["status"] not in STATUSES:
        raise ValueError(f"{where}, column 'status': {row['status']!r} is not a status of "
                         f"morphoshell (numerics.status.STATUSES): {_EDITED}")
    if row["message"] == "":
        bad = next((k for k in values if not math.isfinite(row[k])), None)
        if bad is not None:
            raise ValueError(f"{where}, column {bad!r}: {row[bad]!r} on a row that did not "
                             f"fail (status {row['status']}, no message): {_EDITED}")


class _Grid:
    """A sweep's grid points by their coordinates, as a file's axis columns hold them."""

    def __init__(self, axes: Mapping[str, Sequence], ablate: bool):
        self.axes, self.ablate = axes, ablate
        self.columns = [axis_column(name, ablate) for name in axes]
        self.points = list(product(*axes.values()))
        self.at = {point: i for i, point in enumerate(self.points)}

    def label(self, index: int) -> str:
        """Grid point ``index`` in words, as the sweep names its points."""
        return point_label(dict(zip(self.axes, self.points[index])), self.ablate)

    def index(self, row: Mapping[str, Any], where: str) -> int:
        """The index of the grid point at ``row``'s coordinates; ValueError (``where``: the
        file and the row) if they are not a point of the grid."""
        point = tuple(_typed(row[column], values[0], f"{where}, column {column!r}")
                      for column, values in zip(self.columns, self.axes.values()))
        if point in self.at:
            return self.at[point]
        column, value, values = next((c, v, vals) for c, v, vals in
                                     zip(self.columns, point, self.axes.values())
                                     if v not in vals)
        nearest = (f"; nearest {min(values, key=lambda v: abs(v - value))!r}"
                   if isinstance(value, float) and math.isfinite(value) else "")
        label = point_label(dict(zip(self.axes, point)), self.ablate)
        raise ValueError(f"{where}: {label} is not a point of this sweep ({column} = {value!r} "
                         f"is none of its {len(values)} values{nearest}): {_EDITED}")


def _not_partial(path: Path, mark: str = f"'{PARTIAL}' mark") -> ValueError:
    return ValueError(f"{path}: a complete sweep, or none (no {mark}): nothing to "
                      f"resume, and a complete file does not record every setting its rows "
                      f"depend on to be checked against this sweep's; run without --resume "
                      f"to compute it again (it overwrites the file), or write elsewhere")


def _no_settings(path: Path, what: str) -> ValueError:
    return ValueError(f"{path}: a partial sweep {what}: it cannot be checked against this "
                      f"sweep's settings; run without --resume to compute it again (it "
                      f"overwrites the file)")


def _not_utf8(path: Path, exc: UnicodeDecodeError) -> ValueError:
    return ValueError(f"{path}: not UTF-8 text (byte {exc.object[exc.start]:#04x} at "
                      f"{exc.start}): not a file that a sweep wrote")


def _read_csv(path: Path) -> tuple[dict, list[dict]]:
    """(settings, rows as text) of a partial sweep's CSV."""
    try:
        return _read_csv_text(path)
    except UnicodeDecodeError as exc:
        raise _not_utf8(path, exc) from None


def _read_csv_text(path: Path) -> tuple[dict, list[dict]]:
    # (utf-8-sig: an editor's byte-order mark hid the first line's mark, audit 17)
    with open(path, newline="", encoding="utf-8-sig") as f:
        head, line = f.readline(), f.readline()
        if not head.startswith(f"# {PARTIAL}:"):
            raise _not_partial(path)
        if not line.startswith(f"# {SETTINGS}"):
            raise _no_settings(path, f"without its '# {SETTINGS}{{...}}' line (line 2)")
        try:
            recorded = json.loads(line[len(f"# {SETTINGS}"):])
        except ValueError:
            recorded = None
        if not isinstance(recorded, dict) or not recorded:
            raise _no_settings(path, "whose settings line (line 2) is damaged (not a JSON "
                                     "object of settings)")
        return recorded, [_whole(path, i, row) for i, row in enumerate(csv.DictReader(f))]


def _whole(path: Path, i: int, row: dict) -> dict:
    """CSV row ``i`` (from 0), or ValueError naming it if it has fewer cells than the header
    (``csv`` fills them with None: it read as "None is not a number") or more."""
    short = next((k for k, v in row.items() if v is None), None)
    if short is not None:
        raise ValueError(f"{path}, row {i + 1}, column {short!r}: the row is cut short (it "
                         f"ends before this column): {_EDITED}")
    if None in row:
        raise ValueError(f"{path}, row {i + 1}: more cells than the header's columns: "
                         f"{_EDITED}")
    return row


def _read_json(path: Path) -> tuple[dict, list[dict]]:
    """(settings, rows) of a partial sweep's JSON."""
    try:
        data = json.loads(path.read_text(encoding="utf-8-sig"))
    except UnicodeDecodeError as exc:
        raise _not_utf8(path, exc) from None
    except ValueError:
        raise ValueError(f"{path}: not JSON") from None
    check_format(data, str(path))
    if not isinstance(data, dict):
        raise ValueError(f"{path}: not a sweep's JSON (a {type(data).__name__} at the top, "
                         f"not an object): nothing to resume")
    if data.get("complete") is not False:
        raise _not_partial(path, '"complete": false')
    recorded = data.get("settings")
    if not isinstance(recorded, dict) or not recorded:
        raise _no_settings(path, "without its \"settings\" (or with them damaged)")
    rows = data.get("rows")
    if not isinstance(rows, list) or not all(isinstance(row, dict) for row in rows):
        raise ValueError(f"{path}: a partial sweep whose \"rows\" are not a list of rows")
    return recorded, rows


def _typed(value, like, where: str):
    """A row's value as read (CSV text, or JSON) with the type of ``like``; NaN for empty;
    ValueError naming ``where`` (the file, row and column) if it is not one (a JSON
    ``walls_cross`` "yes" read as False, ``iterations`` 1.5 as 1, a status 5 as '5')."""
    if isinstance(like, bool):
        if not (isinstance(value, bool) or value in ("True", "False")):    # (not 0 or 1)
            raise ValueError(f"{where}: {value!r} is not True or False")
        return value in (True, "True")
    if isinstance(like, str):
        if not isinstance(value, str):
            raise ValueError(f"{where}: {value!r} is not text")
        return value
    kind = "a whole number" if isinstance(like, int) else "a number"
    # (JSON's true is an int to Python, and int() cuts 1.5 to 1)
    if isinstance(value, bool) or (isinstance(like, int) and isinstance(value, float)):
        raise ValueError(f"{where}: {value!r} is not {kind}")
    try:
        if isinstance(like, int):
            return int(value)
        return math.nan if value in ("", None) else float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{where}: {value!r} is not {kind}") from None


def _check_settings(path: Path, recorded: Mapping, settings: Mapping) -> None:
    """ValueError naming the first setting of ``recorded`` (the file's) that is not this
    sweep's, and its option."""
    name, theirs, ours = _first_difference(recorded, settings)
    if name:
        option = _OPTIONS.get(name[0], "--" + name[0].replace("_", "-"))
        if name[0] == "axes" and len(name) > 1:
            option = f"--set {name[1]}"
        raise ValueError(f"{path}: a partial sweep with {'.'.join(name)} = "
                         f"{_short(name, theirs)}, not {_short(name, ours)} ({option}): resume "
                         f"it with its settings, or run without --resume to start again")


def _short(name: tuple, value) -> str:
    """A setting as a message shows it: a long list by its ends and length, the automatic
    chunk size as 'automatic' (it read "chunk_size = None")."""
    if name == ("chunk_size",) and value is None:
        return "automatic"
    if isinstance(value, list) and len(value) > 4:
        return f"[{value[0]!r}, ..., {value[-1]!r}] ({len(value)} values)"
    return repr(value)


def _first_difference(a, b, where: tuple = ()) -> tuple[tuple, Any, Any]:
    """(keys, a's value, b's) of the first entry where nested mappings differ; ((), ...) if
    they are equal."""
    if a == b:
        return (), a, b
    if not (isinstance(a, Mapping) and isinstance(b, Mapping)):
        return where, a, b
    for key in dict.fromkeys([*b, *a]):
        if a.get(key) != b.get(key):
            return _first_difference(a.get(key), b.get(key), (*where, key))
    return (), a, b
