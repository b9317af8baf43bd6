"""Problem files (TOML), ``KEY=VALUE`` overrides, the packaged examples, JSON and CSV output.

A problem file has a ``[problem]`` table, a ``[parameters]`` table with the
profile family's parameters and an optional ``[solver]`` table::

    [problem]
    family = "uniform"          # uniform | anisotropic | local_relaxation | volvox | a plugin's
    theory = "large_bending"    # or "classical"
    h = 0.3                     # relative thickness H/R
    cut = 0.3                   # Sigma (units of R = radians on the unit sphere): ablation
                                # around the pole s = 0 (0: closed pole)
    opening = 0.0               # P (units of R): opening around s = pi (0: closed pole)

    [parameters]
    k = 0.0

    [solver]
    nodes = 200                 # mesh nodes
    stages = 2                  # Gauss points per cell: order 2 * stages
    method = "direct"           # or "bvp" or "shooting"

Unknown tables or keys, wrong types and bad values are errors that name
the file and the offending entry; nothing is silently ignored.  Parameters
missing from ``[parameters]`` take the family's defaults, and the defaults
used are reported (a warning on the ``morphoshell.io.problem_files`` logger when the whole
table is missing, an info message otherwise), never silently.

The cut Σ is called ``cut`` everywhere (problem files, ``--set``, the API);
``Sigma`` is still accepted as a deprecated alias, with a warning.

The example problems ship inside the package (:mod:`.example_problems`, whose
``examples``, ``example_path``, ``example_text`` and ``EXAMPLES_DIR`` are importable from
here too; ``morphoshell example NAME`` prints one).
"""
from __future__ import annotations

import logging
import math
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Iterable, Mapping, Sequence

import numpy as np

from ..model.problem import BASE_KEYS, Problem
from ..solvers.direct import check_nodes
from ..solvers.routes import METHODS
from .example_problems import EXAMPLES_DIR, example_path, example_text, examples  # noqa: F401
from .provenance import check_format, provenance

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - exercised on Python 3.10 only
    import tomli as tomllib

__all__ = ["ProblemFileError", "Settings", "load_problem", "parse_overrides", "apply_overrides",
           "split_overrides", "settings_from", "to_jsonable", "write_json", "write_csv", "METHODS",
           "write_problem", "problem_toml",
           "SOLVER_KEYS", "ALIASES", "problem_of_record", "fit_source",
           "record_midline"]

log = logging.getLogger(__name__)

#: Deprecated names of keys (problem files and ``--set``) and their one name.
ALIASES = {"Sigma": "cut"}


_PROBLEM_KEYS = {"family", "theory", "h", "cut", "opening", "geometry", "name"}
#: Keys of the [solver] table (also accepted by ``--set``).
SOLVER_KEYS = ("nodes", "method", "stages")
#: ``--set`` keys whose values are words, not numbers.
_WORDS = ("theory", "family", "geometry", "name", "method")
_INTEGERS = ("nodes", "stages")


class ProblemFileError(ValueError):
    """A problem file or override that cannot be used (names file and entry)."""


@dataclass(frozen=True)
class Settings:
    """Solver settings from a problem file (defaults when absent)."""

    nodes: int = 200
    method: str = "direct"
    stages: int = 2


def load_problem(path: str | Path) -> tuple[Problem, Settings]:
    """Read a problem file.

    Returns
    -------
    problem : Problem
    settings : Settings

    Raises
    ------
    ProblemFileError
        Missing file, TOML syntax error, unknown or missing entries, or a
        value that :class:`~morphoshell.model.problem.Problem` rejects.
    """
    path = Path(path)
    if path.suffix.lower() == ".json":
        return _problem_from_json(path)
    try:
        # utf-8-sig: a byte-order mark, as some Windows editors write, is not an error
        text = path.read_text(encoding="utf-8-sig")
    except UnicodeDecodeError as exc:
        raise ProblemFileError(f"{path}: not a text file in UTF-8 (byte {exc.start}: "
                               f"{exc.reason})") from None
    except OSError as exc:
        raise ProblemFileError(f"{path}: cannot read problem file ({exc.strerror})") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ProblemFileError(f"{path}: not valid TOML: {exc}") from None
    _check_tables(path, data)
    prob = _dealias(dict(data["problem"]), f"{path}: [problem]")
    unknown = sorted(set(prob) - _PROBLEM_KEYS)
    if unknown:
        raise ProblemFileError(f"{path}: unknown key(s) {unknown} in [problem]; "
                               f"valid: {sorted(_PROBLEM_KEYS)}")
    for key in ("family", "h"):
        if key not in prob:
            raise ProblemFileError(f"{path}: [problem] needs '{key}'")
    for key in ("family", "theory", "geometry", "name"):
        if key in prob and not isinstance(prob[key], str):
            raise ProblemFileError(f"{path}: [problem] {key} = {prob[key]!r} must be a string")
    solver = dict(data.get("solver", {}))
    unknown = sorted(set(solver) - set(SOLVER_KEYS))
    if unknown:
        raise ProblemFileError(f"{path}: unknown key(s) {unknown} in [solver]; "
                               f"valid: {sorted(SOLVER_KEYS)}")
    try:
        settings = settings_from(solver)
        problem = Problem(params=dict(data.get("parameters", {})),
                          **{"name": path.stem, **prob})
    except ValueError as exc:
        raise ProblemFileError(f"{path}: {exc}") from None
    _note_defaults(path, problem, data.get("parameters"))
    return problem, settings


def read_json(path: Path) -> Any:
    """The content of the JSON file ``path`` (a BOM allowed); ValueError naming the file
    when it cannot be read, is not JSON or is of a newer format than this package reads
    (:func:`morphoshell.io.provenance.check_format`)."""
    import json

    try:
        data = json.loads(Path(path).read_text(encoding="utf-8-sig"))
    except OSError as exc:
        raise ValueError(f"{path}: cannot read the file ({exc.strerror})") from None
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ValueError(f"{path}: not valid JSON ({exc})") from None
    check_format(data, str(path))
    return data


def _problem_from_json(path: Path) -> tuple[Problem, Settings]:
    """The problem of a result JSON (``solve --json``, ``fit --json``): its "problem" entry,
    and the solver settings it records (:func:`_recorded_settings`)."""
    try:
        data = read_json(path)
    except ValueError as exc:
        raise ProblemFileError(str(exc)) from None
    if not isinstance(data, dict) or not isinstance(data.get("problem"), dict):
        raise ProblemFileError(f"{path}: no 'problem' entry: expected the JSON written by "
                               f"morphoshell solve/ablate/fit --json")
    try:
        return problem_of_record(data, str(path)), _recorded_settings(path, data)
    except ValueError as exc:
        raise ProblemFileError(str(exc)) from None


def recorded_solver(data: Mapping[str, Any]) -> dict[str, Any]:
    """The [solver] entries (:data:`SOLVER_KEYS`) a result's JSON records of how it was solved:
    a fit's ``solver`` table of its inner solves (nodes, stages, method) or a campaign
    record's ``nodes``; a solve's or an ablation's ``settings`` (``solve``/``ablate --json``;
    its other entries, rtol and the linear solver, are not a problem file's); ``{}`` for
    other results, whose ``solver`` reports a solve, and for files written before these
    were recorded."""
    if "fitted" in data:
        table = data.get("solver")
        if not isinstance(table, Mapping):
            table = {"nodes": data["nodes"]} if "nodes" in data else {}
        return dict(table)
    table = data.get("settings")
    return {k: table[k] for k in SOLVER_KEYS if k in table} if isinstance(table, Mapping) else {}


def _recorded_settings(path: Path, data: Mapping[str, Any]) -> Settings:
    """The [solver] settings a result records (:func:`recorded_solver`), so that re-solving
    it solves it as it was solved or fitted (it was solved at 200 nodes whatever the
    record's), defaults where it records none."""
    table = recorded_solver(data)
    unknown = sorted(set(table) - set(SOLVER_KEYS))
    if unknown:
        raise ValueError(f"{path}: unknown key(s) {unknown} in 'solver'; valid: "
                         f"{sorted(SOLVER_KEYS)}")
    try:
        return settings_from(table)
    except ValueError as exc:
        raise ValueError(f"{path}: solver: {exc}") from None




def problem_of_record(record: Mapping[str, Any], where: str = "the record") -> Problem:
    """The problem of a result (``solve``/``ablate``/``fit --json``, or a campaign's record).

    A fit's record holds its parameters twice: ``parameters`` (what a reader
    looks at and may edit) and ``problem.params`` with h, cut and opening
    (what rebuilds the problem).  Both are read and must agree, so that an
    edit of one is never silently ignored; a family parameter that neither
    holds is refused rather than taken from the family's defaults.

    Parameters
    ----------
    record : mapping
        With a ``problem`` entry (:meth:`Problem.describe`) and, for a fit,
        ``parameters``.
    where : str
        The file or record, for messages.

    Returns
    -------
    Problem

    Raises
    ------
    ValueError
        No ``problem`` entry, the two copies disagree (the entry named), a
        fit's parameter missing from both, or an invalid problem.
    """
    desc = record.get("problem")
    if not isinstance(desc, Mapping):
        raise ValueError(f"{where}: no 'problem' entry: expected the JSON written by "
                         f"morphoshell solve/ablate/fit --json or a campaign")
    # (a result's "problem" is Problem.describe(): the file's keys and the parameters)
    desc = {k: v for k, v in desc.items() if k in _PROBLEM_KEYS | {"params"}}
    params = desc.get("params") or {}
    if not isinstance(params, Mapping):
        raise ValueError(f"{where}: problem.params = {params!r} must map names to numbers")
    params = dict(params)
    fitted = record.get("parameters")
    if isinstance(fitted, Mapping):
        for name, value in fitted.items():
            here = desc if name in ("h", "cut", "opening") else params
            if name in here and here[name] != value:
                entry = name if here is desc else f"params.{name}"
                raise ValueError(f"{where}: parameters.{name} = {value!r} but problem.{entry} = "
                                 f"{here[name]!r}: the fit's two copies of its parameters "
                                 f"disagree; make them equal (or delete one)")
            here.setdefault(name, value)
    try:
        problem = Problem(**{**desc, "params": params})
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{where}: {exc}") from None
    missing = [n for n in problem.family_obj.parameters if n not in params]
    if isinstance(fitted, Mapping) and missing:
        raise ValueError(f"{where}: the fit gives no value of {', '.join(missing)} (neither in "
                         f"'parameters' nor in 'problem.params'): refusing the family's "
                         f"default for a fitted shell")
    return problem


def fit_source(record: Mapping[str, Any], where: str = "the fit's record"
               ) -> dict[str, Any] | None:
    """Where a fitted shape comes from, with a warning when its fit did not converge.

    A fit that stopped short (out of evaluations, near a fold) still has a
    shell, but not the fitted one: ablating it as if it were was silent.

    Parameters
    ----------
    record : mapping
        A result's JSON or a campaign's record.
    where : str
        The file, for the warning and the source.

    Returns
    -------
    dict or None
        ``file``, ``E_fit`` (units of R), ``converged`` and ``message`` of a
        fit's record (it has ``fitted``); None for other results.
    """
    if "fitted" not in record:
        return None
    source = {"file": where, "E_fit": record.get("E_fit"),
              "converged": bool(record.get("converged", False)),
              "message": record.get("message", "")}
    if not source["converged"]:
        e_fit = source["E_fit"]
        log.warning("%s: the fit did not converge (E_fit = %s R: %s): its shell is where the "
                    "fit stopped, not the fitted one", where,
                    f"{e_fit:.4g}" if isinstance(e_fit, (int, float)) else e_fit,
                    source["message"] or "no message")
    return source


def record_midline(record: Mapping[str, Any], path: str | Path | None = None):
    """The midline a fit's record was fitted to, read again as its settings read it.

    For σ² from the spread of its traces (``compare``, ``ablate FIT.json``): a record keeps
    the points, not the spread, so the file they came from is read with the options that
    read it for the fit (format, section, pixel size, radius, ROI, outlier points).

    Parameters
    ----------
    record : mapping
        A fit's record (``morphoshell fit --json``): ``midline_file``, ``settings``,
        ``data_midline``.
    path : str or Path, optional
        The file instead of the record's ``midline_file`` (relative to the current folder).

    Returns
    -------
    Midline or None
        None where the record names no file or it is not a file here.
    """
    from .midlines import load_midline

    settings = record.get("settings") or {}
    path = path or record.get("midline_file")
    if path is None or not Path(path).is_file():
        return None
    n = len((record.get("data_midline") or {}).get("r", [])) or None
    return load_midline(path, settings.get("format"), n=n,
                        section=settings.get("section", "auto"),
                        pixel_size_um=settings.get("pixel_size_um"),
                        radius_um=settings.get("radius_um"), roi=settings.get("roi"),
                        drop_outlier_points=bool(settings.get("drop_outlier_points")))


def _dealias(table: dict, where: str) -> dict:
    """``table`` with deprecated key names (:data:`ALIASES`) renamed, with a warning each."""
    for old, new in ALIASES.items():
        if old in table:
            if new in table:
                raise ProblemFileError(f"{where} gives both {new!r} and its deprecated alias "
                                       f"{old!r}; keep {new!r}")
            log.warning("%s: %r is deprecated, call it %r (the same value: the cut Sigma, "
                        "units of R)", where, old, new)
            table = {(new if k == old else k): v for k, v in table.items()}
    return table


def _note_defaults(path: Path, problem: Problem, given: Mapping | None) -> None:
    """Say which of the family's parameters a problem file leaves at their defaults."""
    missing = [n for n in problem.family_obj.parameters if n not in (given or {})]
    if not missing:
        return
    values = ", ".join(f"{n} = {problem.params[n]:g}" for n in missing)
    if given is None:
        log.warning("%s has no [parameters] table: using the defaults of family %r: %s",
                    path, problem.family, values)
    else:
        log.info("%s: [parameters] leaves %s at the defaults of family %r: %s", path,
                 "it" if len(missing) == 1 else "them", problem.family, values)


def settings_from(values: Mapping[str, Any], base: Settings = Settings()) -> Settings:
    """``base`` with the [solver] ``values`` applied and checked (ValueError naming the key)."""
    def get(key):
        return values.get(key, getattr(base, key))
    return Settings(nodes=check_nodes(get("nodes")), method=_method(get("method")),
                    stages=_stages(get("stages")))


def _stages(value: Any) -> int:
    # only integers, like nodes: 2.0 is as wrong as 200.0
    if isinstance(value, bool) or not isinstance(value, int) or value not in (1, 2, 3):
        raise ValueError(f"stages = {value!r} must be the integer 1, 2 or 3 (order 2, 4 or 6)")
    return value


def _method(value: Any) -> str:
    if value not in METHODS:
        raise ValueError(f"method = {value!r} must be one of {list(METHODS)}")
    return value


def _check_tables(path: Path, data: dict) -> None:
    """A problem file's tables: [problem], optionally [parameters] and [solver], no other."""
    unknown = sorted(set(data) - {"problem", "parameters", "solver"})
    loose = [k for k in unknown if not isinstance(data[k], dict)]
    if loose:       # keys before any table: its header line is missing, not a table unknown
        raise ProblemFileError(f"{path}: key(s) {loose} outside any table; is the [problem] "
                               f"line above them missing?")
    if unknown:
        raise ProblemFileError(f"{path}: unknown table(s) {unknown}; "
                               f"expected [problem], [parameters], [solver]")
    for table in ("problem", "parameters", "solver"):
        if table in data and not isinstance(data[table], dict):
            raise ProblemFileError(f"{path}: '{table}' must be a table ([{table}])")
    if "problem" not in data:
        raise ProblemFileError(f"{path}: missing the [problem] table")


def parse_overrides(items: Iterable[str]) -> dict[str, Any]:
    """``["k=0.5", "theory=classical"]`` → ``{"k": 0.5, "theory": "classical"}``.

    theory, family, geometry, name and method take words, nodes and stages
    integers, everything else numbers.
    """
    out: dict[str, Any] = {}
    for item in items:
        key, sep, value = item.partition("=")
        key, value = key.strip(), value.strip()
        if not sep or not key or not value:
            raise ProblemFileError(f"--set {item!r}: expected KEY=VALUE")
        if key in ALIASES:
            log.warning("--set %s: %r is deprecated, call it %r", item, key, ALIASES[key])
            key = ALIASES[key]
        if key in out:      # (the last had won, silently; a sweep refused it)
            raise ProblemFileError(f"--set {item!r}: {key} is set more than once")
        if key in _WORDS:
            out[key] = value
            continue
        if key in _INTEGERS:
            try:
                out[key] = int(value)
            except ValueError:
                raise ProblemFileError(f"--set {item!r}: {key} needs an integer, "
                                       f"got {value!r}") from None
            continue
        try:
            number = float(value)
        except ValueError:
            raise ProblemFileError(f"--set {item!r}: {key} needs a number, got {value!r}") from None
        if not math.isfinite(number):
            raise ProblemFileError(f"--set {item!r}: {key} = {value} must be finite")
        out[key] = number
    return out


def split_overrides(overrides: Mapping[str, Any]) -> tuple[dict, dict]:
    """(problem overrides, [solver] overrides)."""
    solver = {k: v for k, v in overrides.items() if k in SOLVER_KEYS}
    return {k: v for k, v in overrides.items() if k not in SOLVER_KEYS}, solver


def apply_overrides(problem: Problem, overrides: Mapping[str, Any],
                    where: str | None = None) -> Problem:
    """Problem with ``--set`` overrides applied; unknown keys name the valid ones.

    A new ``family`` starts from its defaults; the other overrides may then
    set its parameters.  ``where`` is the problem's file: a problem the
    overrides make invalid is named by it and them (the fault may be the
    file's values as much as the new ones).
    """
    from ..model.profiles import get_family

    try:
        family = get_family(overrides.get("family", problem.family))
    except ValueError as exc:
        raise ProblemFileError(f"--set: {exc}") from None
    valid = set(BASE_KEYS) | {"family", "geometry", "name"} | set(family.parameters)
    unknown = sorted(set(overrides) - valid)
    if unknown:
        raise ProblemFileError(f"--set: unknown key(s) {unknown} for family {family.name!r}; "
                               f"valid: {sorted(valid)}, and the solver's {list(SOLVER_KEYS)}")
    try:
        return problem.with_updates(**overrides)
    except ValueError as exc:
        # (the file's values with the new ones: e.g. a fit's curvature with a cut)
        given = " ".join(f"{k}={v}" for k, v in overrides.items())
        raise ProblemFileError(f"{where} with --set {given}: {exc}" if where else
                               f"--set: {exc}") from None


def to_jsonable(obj: Any) -> Any:
    """NumPy arrays and scalars to lists and floats (non-finite → None)."""
    if isinstance(obj, Mapping):
        return {str(k): to_jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [to_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return to_jsonable(obj.tolist())
    if isinstance(obj, (np.floating, float)):
        return float(obj) if math.isfinite(obj) else None
    if isinstance(obj, (np.integer,)):
        return int(obj)
    if isinstance(obj, np.bool_):
        return bool(obj)
    return obj


def problem_toml(problem: Problem, settings: Settings | None = None) -> str:
    """The text of a problem file of ``problem`` and its [solver] ``settings`` (defaults if
    None), which :func:`load_problem` reads back to an equal problem and settings.

    Every parameter of the family is written (none left to its default), floats as their
    shortest repr (the same double read back), strings as TOML basic strings: the grammar
    of a problem file is three flat tables of numbers and words, written by hand rather
    than with a TOML library.
    """
    from .. import __version__

    settings = Settings() if settings is None else settings
    head = {k: v for k, v in problem.describe().items() if k != "params"}
    lines = [f"# written by morphoshell {__version__} (morphoshell.io.write_problem)",
             "[problem]", *(f"{k} = {_toml_value(v)}" for k, v in head.items()),
             "", "[parameters]",
             *(f"{_toml_key(k)} = {_toml_value(v)}" for k, v in problem.params.items()),
             "", "[solver]", f"nodes = {int(settings.nodes)}",
             f"method = {_toml_value(settings.method)}", f"stages = {int(settings.stages)}"]
    return "\n".join(lines) + "\n"


def write_problem(path: str | Path, problem: Problem, settings: Settings | None = None
                  ) -> Path:
    """Write ``problem`` (and ``settings``) as a problem file (:func:`problem_toml`),
    creating parent folders; ``load_problem(path)`` gives them back."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(problem_toml(problem, settings), encoding="utf-8")
    return path


def _toml_key(key: str) -> str:
    """A bare TOML key, or a quoted one where it has other characters."""
    return key if key and all(c.isascii() and (c.isalnum() or c in "_-") for c in key) \
        else _toml_value(key)


def _toml_value(value: Any) -> str:
    """A number or word as TOML: floats by repr (inf and nan as TOML spells them), strings
    with JSON's escapes (TOML's basic strings share them)."""
    import json

    if isinstance(value, str):
        return json.dumps(value)        # (ASCII: control characters and DEL escaped)
    value = float(value)
    return repr(value) if math.isfinite(value) else ("nan" if value != value else
                                                      "inf" if value > 0 else "-inf")


def write_json(path: str | Path, data: Mapping[str, Any], inputs: Sequence[str | Path] = ()
               ) -> Path:
    """Write ``data`` (plus ``provenance``, naming the ``inputs`` files read with their
    SHA-256: :func:`morphoshell.io.provenance.provenance`) as JSON, creating parent
    folders."""
    import json

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    payload = {**to_jsonable(data), "provenance": provenance(inputs)}
    path.write_text(json.dumps(payload, indent=1) + "\n")
    return path


def write_csv(path: str | Path, columns: Mapping[str, Any], comments: Sequence[str] = ()
              ) -> Path:
    """Write equal-length columns (scalars repeat) as CSV with a header row.

    Non-finite values are written as empty cells; ``comments`` are lines written before
    the header, each after ``"# "``.
    """
    import csv

    path = Path(path)
    arrays = {k: np.atleast_1d(np.asarray(v)) for k, v in columns.items()}
    n = max(len(a) for a in arrays.values())
    for k, a in arrays.items():
        if len(a) not in (1, n):
            raise ValueError(f"column {k!r} has {len(a)} rows, expected {n}")
    with path.open("w", newline="") as f:
        f.writelines(f"# {line}\n" for line in comments)
        w = csv.writer(f)
        w.writerow(list(arrays))
        for i in range(n):
            w.writerow([_cell(a[i] if len(a) == n else a[0]) for a in arrays.values()])
    return path


def _cell(v: Any) -> Any:
    if isinstance(v, (float, np.floating)):
        return repr(float(v)) if math.isfinite(v) else ""
    return v
