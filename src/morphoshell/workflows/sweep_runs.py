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
same settings (:func:`settings_record`; ValueError naming the first that differs).

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
from pathlib import Path
from typing import Any, Callable, Iterator, Mapping, Sequence

from .._runtime import interrupts
from .._runtime.console import counter
from .executor import backend_name, open_executor, run
from .sweep_results import NOT_COMPUTED, SweepResult

__all__ = ["run_chunks", "interruptible", "SweepInterrupted", "settings_record", "restored",
           "whole_chunks", "NOT_COMPUTED", "PARTIAL"]

#: The first line of a partial sweep's CSV (after ``"# "``), then how far it got.
PARTIAL = "morphoshell sweep PARTIAL"
#: The second line's start (after ``"# "``): the sweep's settings as JSON.
SETTINGS = "settings: "
#: The message of a row that a partial sweep did not compute.
NOT_COMPUTED_MESSAGE = "not computed: the sweep was interrupted"
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


def restored(path: str | Path, settings: Mapping[str, Any], blank: Mapping[str, Any]
             ) -> dict[int, dict]:
    """The rows a partial sweep file (:meth:`SweepInterrupted.write`) computed, by index.

    Parameters
    ----------
    path : str or Path
        The file, CSV or JSON by its extension; none there: no rows.
    settings : mapping
        This sweep's settings (:func:`settings_record`), which the file's must equal.
    blank : mapping
        A row before its point is solved: the keys and types of a row.

    Raises
    ------
    ValueError
        The file is not a partial sweep (a complete one, say), or was made with other
        settings (the first named, and its option), or lacks a column of a row.
    """
    path = Path(path)
    if not path.exists():
        return {}
    recorded, rows = (_read_json if path.suffix.lower() == ".json" else _read_csv)(path)
    _check_settings(path, recorded, settings)
    keys = {**blank, "seconds": math.nan}
    out = {}
    for i, row in enumerate(rows):
        missing = [k for k in keys if k not in row]
        if missing:
            raise ValueError(f"{path}: row {i + 1} has no column {missing[0]!r}: not a sweep "
                             f"of this version of morphoshell")
        if row["status"] != NOT_COMPUTED:
            out[i] = {k: _typed(row[k], like) for k, like in keys.items()}
    return out


def _not_partial(path: Path) -> ValueError:
    return ValueError(f"{path}: not a partial sweep (a complete one has no "
                      f"'{PARTIAL}' mark): nothing to resume; without --resume the sweep "
                      f"is run again and overwrites it")


def _read_csv(path: Path) -> tuple[dict, list[dict]]:
    """(settings, rows as text) of a partial sweep's CSV."""
    with open(path, newline="") as f:
        head, line = f.readline(), f.readline()
        if not head.startswith(f"# {PARTIAL}:") or not line.startswith(f"# {SETTINGS}"):
            raise _not_partial(path)
        try:
            recorded = json.loads(line[len(f"# {SETTINGS}"):])
        except ValueError:
            raise ValueError(f"{path}: its settings line is not JSON") from None
        return recorded, list(csv.DictReader(f))


def _read_json(path: Path) -> tuple[dict, list[dict]]:
    """(settings, rows) of a partial sweep's JSON."""
    try:
        data = json.loads(path.read_text())
    except ValueError:
        raise ValueError(f"{path}: not JSON") from None
    if not isinstance(data, dict) or data.get("complete") is not False:
        raise _not_partial(path)
    return data.get("settings") or {}, data.get("rows") or []


def _typed(value, like):
    """A row's value as read (CSV text, or JSON) with the type of ``like``; NaN for empty."""
    if isinstance(like, bool):
        return value in (True, "True")
    if isinstance(like, int):
        return int(value)
    if isinstance(like, str):
        return str(value)
    return math.nan if value in ("", None) else float(value)


def _check_settings(path: Path, recorded: Mapping, settings: Mapping) -> None:
    """ValueError naming the first setting of ``recorded`` (the file's) that is not this
    sweep's, and its option."""
    name, theirs, ours = _first_difference(recorded, settings)
    if name:
        option = _OPTIONS.get(name[0], "--" + name[0].replace("_", "-"))
        if name[0] == "axes" and len(name) > 1:
            option = f"--set {name[1]}"
        raise ValueError(f"{path}: a partial sweep with {'.'.join(name)} = {_short(theirs)}, "
                         f"not {_short(ours)} ({option}): resume it with its settings, or run "
                         f"without --resume to start again")


def _short(value) -> str:
    """A setting as a message shows it: a long list by its ends and length."""
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
