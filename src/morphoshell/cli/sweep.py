"""``morphoshell sweep``: equilibria or ablations on the Cartesian product of ``--set`` axes."""
from __future__ import annotations

import math

from ._args import add_executor, add_outputs, direct_only, family_keys, integer, linear_solver
from ._commands import help_of
from ._outputs import Outputs, kept_in

__all__ = ["register", "parse_axes"]



def register(sub) -> None:
    """Add ``morphoshell sweep`` to the subcommands ``sub``."""
    from ..solvers.direct import MAX_NODES
    from ..workflows.sweeps import ERRORS

    p = sub.add_parser(
        "sweep", help=help_of("sweep"),
        description="Solve PROBLEM.toml (or, with --ablate, ablate it) at every point of the "
                    "Cartesian product of the --set axes and write one row per point: the "
                    "axis values, then the energy (C R^2) and edge values (R, rad), or with "
                    "--ablate the recoil observables (opening R, rotation rad, displacement R, "
                    "energy released C R^2); each with its estimated error where estimated "
                    "(--errors), the solver's status, the Newton iterations, the path, what "
                    "its continuation crossed (event: snapped, switched) and whether the "
                    "shell's walls pass through each other (walls_cross). Failed points keep "
                    "their row (NaN values and the status); the exit status is then 3 "
                    "(--allow-failures for 0). The points are "
                    "solved in chunks along the axis with the most values, each point warm-"
                    "started from the previous one (continuation from the stress-free "
                    "parameters at a chunk's first point), on the mesh `solve` and `ablate` "
                    "would use; chunks run in parallel (Dask if installed, else a process "
                    "pool) and the numbers do not depend on the number of workers. Ctrl-C "
                    "(or SIGTERM) writes the points of the chunks finished, marked partial, "
                    "and exits 130 (143); --resume computes the rest.")
    p.add_argument("problem", metavar="PROBLEM.toml",
                   help="problem file (`morphoshell example NAME` prints one to start from)")
    p.add_argument("--set", dest="overrides", action="append", default=[],
                   metavar="KEY=VALUES",
                   help=f"KEY=VALUE overrides a problem entry; KEY=a,b,c (a list) or "
                        f"KEY=start:stop:num (num values from start to stop, both included) "
                        f"makes KEY an axis of the sweep. Repeatable. Keys: h, theory, cut "
                        f"(Sigma), opening (P), a parameter of the problem's family "
                        f"({family_keys()}), and as plain overrides family, nodes, stages")
    p.add_argument("--ablate", action="store_true",
                   help="ablate at every point (cut > 0) and report the recoil observables "
                        "instead of the equilibrium")
    p.add_argument("--nodes", type=integer(5, MAX_NODES), default=None, metavar="N",
                   help=f"mesh nodes, 5..{MAX_NODES} (default: the file's [solver] nodes, else "
                        f"200)")
    p.add_argument("--stages", type=int, choices=(1, 2, 3), default=None, metavar="S",
                   help="Gauss points per cell: order 2S (default: the file's, else 2)")
    p.add_argument("--linear-solver", default="mumps", type=linear_solver, metavar="NAME",
                   help="Ipopt's linear solver (default mumps, bundled)")
    p.add_argument("--errors", choices=ERRORS, default="ends",
                   help="where to estimate discretisation errors (two coarser meshes per "
                        "estimate): at both ends of the chunk axis for every value of the "
                        "others (default), at every point, or nowhere")
    add_executor(p, "this process for small sweeps, else one per CPU core; at most one per "
                    "chunk")
    p.add_argument("--chunk-size", dest="chunk_size", type=integer(1, 10**9), default=None,
                   metavar="N", help="most points per task (default: automatic, at least 12 "
                                     "tasks where the grid allows)")
    p.add_argument("--max-points", dest="max_points", type=integer(1, 10**12),
                   default=MAX_GRID, metavar="N",
                   help=f"refuse a grid of more points (default {MAX_GRID:,}: a grid's rows "
                        f"and its runtime grow with it); raise it to insist")
    p.add_argument("--allow-failures", action="store_true",
                   help="exit 0 even when points failed (default: exit status 3, naming them "
                        "on the last line; their rows are written either way)")
    add_outputs(p, json="write the sweep (problem, axes, units, timing, rows) as JSON",
                csv="write one row per point as CSV (units: docs, 'Sweeps')")
    p.add_argument("--resume", action="store_true",
                   help="complete an interrupted sweep: keep the points of the --json file "
                        "(else --csv) that it wrote, marked partial, and compute only the "
                        "others (refused if made with other settings; no file: all points)")
    p.set_defaults(run=_sweep)


#: Most grid points a sweep accepts unless told otherwise (``--max-points``).
MAX_GRID = 100_000


def parse_axes(items, max_points: int = MAX_GRID) -> tuple[dict, dict]:
    """``--set`` items → (axes: key → list of values, scalar overrides: key → value).

    ``KEY=a,b,c`` is a list, ``KEY=start:stop:num`` ``num`` values from
    ``start`` to ``stop`` inclusive; anything else a scalar override
    (:func:`morphoshell.io.problem_files.parse_overrides`).  Raises ``ProblemFileError``
    naming the item, or the grid's size when it has more than ``max_points``
    points (before any list of values is made).
    """
    from ..io.problem_files import ProblemFileError, parse_overrides

    # the whole grid's size before any list is made, so that the advice is the number that
    # works (one long axis had been refused alone, advising a --max-points that the grid
    # then exceeded: audit 17 F2)
    counts = _axis_counts(items)
    size = math.prod(counts.values())
    if size > max_points:
        spans = " x ".join(f"{item} ({n:,})" for item, n in counts.items())
        raise ProblemFileError(f"--set: the grid {spans} has {size:,} points, more than "
                               f"{max_points:,}: give fewer values, or --max-points {size} to "
                               f"insist")
    axes: dict = {}
    scalars: dict = {}
    for item in items:
        key, value = _split(item)
        if _is_axis(value):
            name, values = _axis(item, key, value)
            target = axes
        else:
            parsed = parse_overrides([item])
            name = next(iter(parsed))
            values = parsed[name]
            target = scalars
        if name in axes or name in scalars:
            raise ProblemFileError(f"--set {item!r}: {name} is set more than once")
        target[name] = values
    return axes, scalars


def _axis_counts(items) -> dict[str, int]:
    """How many values each axis item of ``--set`` gives (:func:`_count`), by item."""
    values = [(item, _split(item)[1]) for item in items]
    return {item: _count(item, value) for item, value in values if _is_axis(value)}


def _split(item: str) -> tuple[str, str]:
    """(key, value) of a ``--set`` item, or ``ProblemFileError`` naming it."""
    from ..io.problem_files import ProblemFileError

    key, sep, value = item.partition("=")
    key, value = key.strip(), value.strip()
    if not sep or not key or not value:
        raise ProblemFileError(f"--set {item!r}: expected KEY=VALUE, KEY=a,b,c or "
                               f"KEY=start:stop:num")
    return key, value


def _is_axis(value: str) -> bool:
    return "," in value or ":" in value


def _count(item: str, value: str) -> int:
    """How many values an axis item gives (``KEY=a,b,c`` or ``KEY=start:stop:num``),
    without making them; ``ProblemFileError`` naming a malformed range."""
    from ..io.problem_files import ProblemFileError

    if ":" not in value:
        return len(value.split(","))
    parts = [v.strip() for v in value.split(":")]
    if len(parts) != 3 or "," in value:
        raise ProblemFileError(f"--set {item!r}: a range is start:stop:num "
                               f"(num values, both ends included)")
    try:
        num = int(parts[2])
    except ValueError:
        raise ProblemFileError(f"--set {item!r}: the number of values "
                               f"{parts[2]!r} is not an integer") from None
    if num < 1:
        raise ProblemFileError(f"--set {item!r}: the number of values must be "
                               f"at least 1, got {num}")
    return num


def _axis(item: str, key: str, value: str) -> tuple[str, list]:
    """(name, values) of an axis item: ``KEY=a,b,c`` or ``KEY=start:stop:num``."""
    from ..io.problem_files import SOLVER_KEYS, ProblemFileError, parse_overrides

    if ":" in value:
        name, values = _range(item, key, value)
    else:
        items = [v.strip() for v in value.split(",")]
        if "" in items:
            raise ProblemFileError(f"--set {item!r}: an empty value in the list {value!r}")
        # (the first value resolves a deprecated alias, and warns of it, once for all)
        name = next(iter(parse_overrides([f"{key}={items[0]}"])))
        values = [parse_overrides([f"{name}={v}"])[name] for v in items]
    if name in SOLVER_KEYS or name in ("family", "geometry", "name"):
        raise ProblemFileError(f"--set {item!r}: {name} cannot be a sweep axis")
    return name, values


def _range(item: str, key: str, value: str) -> tuple[str, list]:
    """(name, values) of ``KEY=start:stop:num``: ``num`` numbers, both ends included."""
    import numpy as np

    from ..io.problem_files import ProblemFileError, parse_overrides

    num = _count(item, value)
    parts = [v.strip() for v in value.split(":")]
    ends = [parse_overrides([f"{key}={v}"]) for v in parts[:2]]
    name = next(iter(ends[0]))
    if not all(isinstance(e[name], float) for e in ends):
        raise ProblemFileError(f"--set {item!r}: a range needs numbers")
    return name, np.linspace(ends[0][name], ends[1][name], num).tolist()


def _sweep(args) -> int:
    from ..io.problem_files import (ProblemFileError, apply_overrides, load_problem, settings_from,
                                    split_overrides, write_csv, write_json)
    from ..workflows.sweeps import SweepInterrupted, sweep

    problem, settings = load_problem(args.problem)
    axes, scalars = parse_axes(args.overrides, args.max_points)
    if not axes:
        raise ProblemFileError("--set: no axis to sweep; give a list (KEY=a,b,c) or a range "
                               "(KEY=start:stop:num)")
    problem_over, solver_over = split_overrides(scalars)
    problem = apply_overrides(problem, problem_over)
    try:
        settings = settings_from(solver_over, settings)
    except ValueError as exc:
        raise ProblemFileError(f"--set: {exc}") from None
    direct_only(args.problem, settings, "sweeps")
    nodes = settings.nodes if args.nodes is None else args.nodes
    stages = settings.stages if args.stages is None else args.stages
    # every point is validated before any work (ValueError naming it: exit status 2)
    try:
        result = sweep(problem, axes, ablate=args.ablate, nodes=nodes, workers=args.workers,
                       scheduler=args.scheduler, errors=args.errors, chunk_size=args.chunk_size,
                       stages=stages, linear_solver=args.linear_solver,
                       resume=_resume_file(args))
    except SweepInterrupted as exc:         # Ctrl-C or SIGTERM: how far it got, on one line
        return _interrupted(exc, args)
    _print_table(result, problem, nodes, args)
    out = Outputs()
    out.add(args.csv, lambda path: write_csv(path, result.columns))
    out.add(args.json, lambda path: write_json(path, result.to_dict(), [args.problem]))
    for path in out.commit():
        print(f"  wrote {path}")
    if result.failed:
        print(_verdict(result, args.allow_failures))
    return 3 if result.failed and not args.allow_failures else 0


def _resume_file(args):
    """The file --resume reads: the --json file if there is one, else the --csv file (None
    without --resume); ValueError without either option."""
    if not args.resume:
        return None
    given = [path for path in (args.json, args.csv) if path is not None]
    if not given:
        raise ValueError("--resume needs the --csv or --json file of the interrupted sweep")
    return next((path for path in given if path.exists()), given[0])


def _interrupted(exc, args) -> int:
    """Write the points of an interrupted sweep, marked partial, and say so on one line
    (as campaign's); the exit status of an interruption (130, 143 after SIGTERM)."""
    import sys

    from .._runtime import interrupts

    interrupts.swallowed()      # (claimed: the outputs' commit would raise it again)
    out = Outputs()
    if exc.done:        # (nothing computed: an earlier file stays as it was)
        out.add(args.csv, exc.write)
        out.add(args.json, exc.write)
    paths = out.commit()
    where = kept_in(paths, mark=", marked partial: the same command with --resume computes "
                    "the rest", unkept="; not kept: no --csv or --json" if exc.done else
                    "; no chunk finished: no file written")
    print(f"morphoshell: {exc}{where}", file=sys.stderr)
    return interrupts.exit_status()


#: A flag column's value where a row has nothing to flag.
_UNSET = {"event": "", "walls_cross": False}


def _print_table(result, problem, nodes: int, args) -> None:
    """The summary line and the table: the axes, the main values, the status and the flags
    some row has (units in the headers)."""
    import numpy as np

    t = result.timing
    what = "ablations" if args.ablate else "equilibria"
    shape = " x ".join(f"{len(v)} {k}" for k, v in result.axes.items())
    computed = len(result) - t["restored"]
    per = t["seconds"] / max(computed, 1)
    workers = "a Dask scheduler" if args.scheduler else \
        f"{t['workers']} {'worker' if t['workers'] == 1 else 'workers'} ({t['backend']})"
    kept = f", {t['restored']} restored by --resume" if t["restored"] else ""
    print(f"{problem.name or problem.family}: sweep of {len(result)} {what} ({shape}), "
          f"{nodes} nodes, in {t['chunks']} chunks along {t['chunk_axis']} on {workers}: "
          f"{t['seconds']:.3g} s, {per * 1e3:.3g} ms per point{kept}; {result.failed} failed")
    df = result.to_dataframe()
    values = ["opening", "rotation", "displacement", "energy_released"] if args.ablate else \
        ["energy", "r_start", "psi_start", "r_end", "psi_end", "z_end"]
    # (the flags where a row has one: solve() would have warned of it)
    flags = [k for k in ("event", "walls_cross") if np.any(result.columns[k] != _UNSET[k])]
    show = [*result.dims(), *values, "status", *flags]
    units = result.units
    df = df[show].rename(columns={c: f"{c} [{units[c]}]" for c in show if c in units
                                  and c not in ("iterations",)})
    print(df.to_string(max_rows=20, float_format=lambda v: f"{v:.6g}" if math.isfinite(v)
                       else "nan"))


def _verdict(result, allowed: bool) -> str:
    """The last line of a sweep with failed points: how many, which (as campaign's)."""
    tail = ("(--allow-failures: exit status 0)" if allowed else
            "(their rows say why; exit status 3, --allow-failures for 0)")
    return (f"of {len(result)} points, {result.failed} failed: "
            f"{result.points(result.columns['message'] != '')} {tail}")
