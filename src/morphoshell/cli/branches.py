"""``morphoshell continue``: a branch of equilibria with its stability, folds and snap-throughs."""
from __future__ import annotations

import argparse
import sys

from ._args import add_outputs, direct_only, integer, note, problem_and_settings, real
from ._commands import help_of
from ._outputs import Outputs, kept_in

__all__ = ["register", "PARTIAL"]

#: The first line of the CSV of a branch that stopped early (then its points and why).
PARTIAL = "morphoshell continue PARTIAL: the branch stopped early"
#: ... and of one whose switched branches were cut short (the main branch complete).
NOT_DONE = "morphoshell continue PARTIAL: not all done"


def register(sub) -> None:
    """Add ``morphoshell continue`` to the subcommands ``sub``."""
    from ..solvers.arclength import MAX_STEP
    from ..solvers.branches import FOLLOW, MAX_POINTS
    from ..solvers.direct import MAX_NODES

    p = sub.add_parser(
        "continue", help=help_of("continue"),
        description="Follow the equilibria of PROBLEM.toml by pseudo-arclength continuation "
                    "through folds, along the straight path lambda in [0, 1] from the "
                    "family's stress-free parameters to the file's (--from neutral, the "
                    "default), or in one parameter from the file's value to --to. Every point "
                    "carries its stability (the number of negative eigenvalues of the reduced "
                    "Hessian); folds and branch points are located to 1e-8 in lambda. Prints "
                    "the events and the end point. Direct method only. z is in solve's gauge "
                    "(the pole at the origin); lengths in R, energies in C R^2. Ctrl-C (or "
                    "SIGTERM) writes what was followed, the main branch and the switched "
                    "ones, marked partial where something is missing; exit status 130 (143).")
    p.add_argument("problem", metavar="PROBLEM.toml",
                   help="problem file (`morphoshell example NAME` prints one to start from)")
    p.add_argument("--from", dest="source", choices=("neutral",), default=None,
                   help="the path from the family's stress-free parameters (default; not "
                        "with --param)")
    p.add_argument("--param", default=None, metavar="NAME",
                   help="continue in this one parameter instead: h, cut, opening or one of "
                        "the family's (with --to)")
    p.add_argument("--to", type=real(), default=None, metavar="VALUE",
                   help="the value of --param to continue to")
    p.add_argument("--follow", choices=FOLLOW, default="branch",
                   help="branch: the connected branch through its folds and unstable parts "
                        "(the bifurcation diagram, default); stable: what a shell loaded "
                        "quasi-statically does, snapping through at folds")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                   help="override a problem or solver entry before continuing, repeatable "
                        "(as for solve)")
    p.add_argument("--nodes", type=integer(5, MAX_NODES), default=None, metavar="N",
                   help="mesh nodes (default: the file's [solver] nodes, else 200)")
    p.add_argument("--stages", type=int, choices=(1, 2, 3), default=None, metavar="S",
                   help="Gauss points per cell: order 2S (default: the file's, else 2)")
    p.add_argument("--max-step", type=real(0, 1, open_lo=True), default=MAX_STEP, metavar="DS",
                   help=f"largest pseudo-arclength step (default {MAX_STEP})")
    p.add_argument("--max-points", type=integer(2, MAX_POINTS), default=2000, metavar="N",
                   help="give up after this many points (default 2000; exit status 3, the "
                        "points followed written, marked partial)")
    p.add_argument("--switch", type=integer(0, 1000), default=0, metavar="N",
                   help="also follow the branches through the first N branch points, both "
                        "halves of each, to either end of the path (branch switching; "
                        "default 0); the CSV then has a column branch: main, or the branch "
                        "point's number and +/-")
    p.add_argument("--plot-y", choices=("auto", "psi_end", "r_end", "z_end", "energy"),
                   default="auto", help="the observable of the diagram (default auto: the "
                                        "first of psi_end, z_end, r_end, energy that varies "
                                        "along the branch; z_end for a shell with a cut, "
                                        "whose far end is the pole)")
    p.add_argument("--no-plot-shapes", dest="plot_shapes", action="store_false",
                   help="draw the diagram alone, one journal column wide (default: with the "
                        "shapes at the start, the events and the end below it, two columns)")
    add_outputs(p, json="write the branch (problem, path, points, snaps, the end's error "
                        "estimate; with --switch the switched branches) as JSON",
                csv="write one row per point: lambda, the parameter, energy, r_end, z_end, "
                    "psi_end, stable, negative_eigenvalues, event, lambda_error (an event's "
                    "error estimate from the half mesh; inf: not resolved), energy_error, "
                    "r_end_error, z_end_error, psi_end_error (the end's error estimate, as "
                    "solve's: last row only)",
                plot="write the bifurcation diagram with the shapes at the events")
    p.set_defaults(run=_continue)


def _load(args):
    """The problem and mesh, from the file, --set and the options; all checked."""
    from ..solvers.paths import ParameterLine, neutral_problem

    if (args.param is None) != (args.to is None):
        raise ValueError("--param and --to go together (one parameter from the file's value "
                         "to VALUE); without them the path runs from the stress-free parameters")
    if args.source is not None and args.param is not None:     # (it was ignored)
        raise ValueError(f"--from {args.source} and --param {args.param} are two paths: the "
                         f"one from the stress-free parameters, or the one parameter's; "
                         f"give one")
    problem, settings = problem_and_settings(args.problem, args.overrides)
    direct_only(args.problem, settings, "continuations")
    if args.param is not None:
        try:
            ParameterLine.along(problem, args.param, args.to)
        except ValueError as exc:
            raise ValueError(f"--param {args.param} --to {args.to:g}: {exc}") from None
    elif (source := neutral_problem(problem)) is None:
        raise ValueError(f"{args.problem}: the problem is at its family's stress-free "
                         f"parameters already: continue one parameter (--param, --to)")
    else:
        ParameterLine.between(source, problem)      # (refuses another structure)
    nodes = settings.nodes if args.nodes is None else args.nodes
    stages = settings.stages if args.stages is None else args.stages
    return problem, nodes, stages


def _continue(args) -> int:
    from .._runtime.interrupts import interrupted
    from ..solvers.branches import follow_branch
    from ..solvers.results import SolverError

    problem, nodes, stages = _load(args)
    try:
        branch = follow_branch(problem, args.param, args.to, nodes=nodes, stages=stages,
                               follow=args.follow, max_step=args.max_step,
                               max_points=args.max_points)
    except BaseException as exc:
        partial = getattr(exc, "branch", None)
        if partial is None or not (isinstance(exc, SolverError) or interrupted(exc)):
            raise
        return _ended_early(args, problem, exc, partial)
    _report(problem, branch)
    switched, failed, missing = _switched(args, branch)
    written, unwritten = _written(args, branch, switched, missing)
    for path in written:
        print(f"  wrote {path}")
    if missing or unwritten:
        return _cut_short(missing, unwritten, written, switched)
    if branch.ended is not None:
        print(f"morphoshell: the branch ended at lambda = {branch.ended.tau:.10g}, before the "
              f"path's end ({branch.ended.status}: past it the meridian crosses the axis; see "
              f"the warning){'; the points up to there are written' * bool(written)}",
              file=sys.stderr)
        return 3
    if failed:
        print(f"morphoshell: {len(failed)} switch(es) of branches failed: {', '.join(failed)} "
              f"(the branches that were followed are written)", file=sys.stderr)
        return 3
    return 0


def _write(args, branch, switched=(), missing: str | None = None) -> list:
    """Write the --json, --csv and --plot outputs of ``branch`` (and the switched ones); a
    branch that stopped early (:attr:`Branch.ended`) is marked so in each: the JSON's
    ``complete``/``ended``, the CSV's first line, the plot's caption; so is one whose
    switches were cut short (``missing``, what was not done: JSON and CSV)."""
    from ..io.problem_files import write_csv, write_json

    stopped = branch.ended is not None and branch.ended.stopped
    comments = ((f"{PARTIAL}: {branch.ended.why}",) if stopped else
                (f"{NOT_DONE}: {missing}",) if missing else ())
    out = Outputs()
    named = args.switch > 0
    out.add(args.json, lambda path: write_json(path, _document(branch, switched, missing,
                                                                 named), [args.problem]))
    out.add(args.csv, lambda path: write_csv(path, _csv_columns(branch, switched, named),
                                             comments=comments))
    if args.plot:
        from ..plotting import plot_branch, save
        fig = plot_branch(branch, y=args.plot_y, shapes=args.plot_shapes,
                          switched=[b for _, b in switched])
        out.add(args.plot, lambda path: save(fig, path))
    return out.commit()


def _written(args, branch, switched, missing) -> tuple[list, str | None]:
    """:func:`_write`, and where Ctrl-C or SIGTERM cuts it (drawing the plot takes a second),
    the JSON and CSV written again without the plot: (the paths written, what was not
    (None: all)).  The branch is complete; it had been lost whole (audit 17)."""
    from .._runtime import interrupts

    try:
        return _write(args, branch, switched, missing), None
    except BaseException as exc:
        if not interrupts.interrupted(exc):
            raise
        interrupts.swallowed()      # (claimed: the commit would raise it again)
    unwritten = f"the plot {args.plot} not drawn" if args.plot else "the files written again"
    return (_write(argparse.Namespace(**{**vars(args), "plot": None}), branch, switched,
                   missing), f"{interrupts.reason()} while writing: {unwritten}")


def _cut_short(missing, unwritten, written, switched) -> int:
    """The line of a run cut by Ctrl-C or SIGTERM after the main branch's walk (in the
    switches, ``missing``; in the writing, ``unwritten``): what was not done and where
    the rest is; the interruption's exit status (130, 143)."""
    from .._runtime import interrupts

    kept = " and the switched branches followed are" if switched else " is"
    where = kept_in(written, f"the main branch{kept}", ", marked partial" * bool(missing))
    print(f"morphoshell: {'; '.join(filter(None, (missing, unwritten)))}{where}",
          file=sys.stderr)
    return interrupts.exit_status()


def _ended_early(args, problem, exc, branch) -> int:
    """The branch of a walk that stopped early (the SolverError ``exc``: it ended, or the
    points ran out; or Ctrl-C, SIGTERM) written, marked so, and the one-line message
    naming the files; the exit status of the stop (3, or 130/143)."""
    from .._runtime import interrupts
    from ..solvers.results import SolverError

    solver_failed = isinstance(exc, SolverError)
    if not solver_failed:
        interrupts.swallowed()      # (claimed: the outputs' commit would raise it again)
    else:
        _report(problem, branch)
    # (with --switch: the switches' layout, a branch column and not_done, whenever it stops)
    missing = f"{', '.join(_halves(args, branch)) or 'no switch'} not followed" \
        if args.switch else None
    paths = _write(args, branch, missing=missing)
    where = kept_in(paths, f"the {len(branch.points)} points followed to lambda = "
                           f"{branch.end.tau:.6g} are") + f"{'; ' * bool(missing)}{missing or ''}"
    if solver_failed:
        raise SolverError(f"{exc}{where}", exc.status, exc.last_iterate) from exc
    print(f"morphoshell: {branch.ended.why} after {len(branch.points)} points{where}",
          file=sys.stderr)
    return interrupts.exit_status()


def _report(problem, branch) -> None:
    """The branch in a few lines: its size, the events, the snaps and the end."""
    path = (f"{branch.parameter} from {branch.line.a[0]:g} to {branch.line.b[0]:g}"
            if branch.parameter else "lambda from the stress-free parameters (0) to the file's (1)")
    print(f"{problem.name or problem.family}: {len(branch.points)} points along {path} "
          f"({branch.follow}, {branch.seconds:.2f} s)")
    for pt in branch.events:
        where = _where(branch, pt)
        print(f"  {pt.event.replace('_', ' '):13s} at {where}: r_end = {pt.r_end:.6g} R, "
              f"z_end = {pt.z_end:.6g} R, energy = {pt.energy:.6g} C R^2{_error(pt)}")
    for event in (*branch.snaps, *branch.switches):
        print(f"  {event.describe()}")
    if branch.remeshed:
        print(f"  mesh rebuilt for the parameters at lambda = "
              f"{', '.join(f'{t:.6g}' for t in branch.remeshed)} (its knots moved with them)")
    print(f"  {_end_line(branch)}")


def _error(pt) -> str:
    """A fold's or branch point's λ error estimate from the half mesh, for its line ("" for a
    snap's landing, which has none: it is no located event of the branch)."""
    from ..solvers.refinement import COARSE

    if pt.event not in ("fold", "branch_point"):
        return ""
    if pt.lambda_error == float("inf"):
        return "; not resolved (not on the half mesh)"
    if pt.lambda_error > COARSE:
        return f"; not resolved (error in lambda {pt.lambda_error:.2g})"
    if pt.lambda_error >= 0:
        return f"; error in lambda {pt.lambda_error:.2g}"
    return "; no error estimate (the half mesh holds no point before it)"


def _where(branch, pt) -> str:
    """A point's λ, and the continued parameter's value there (``--param``)."""
    return f"lambda = {pt.tau:.10g}" + (f", {branch.parameter} = "
                                        f"{pt.values[branch.parameter]:.10g}"
                                        if branch.parameter else "")


def _end_line(branch) -> str:
    """Where a branch ends: λ (and why, before the path's end), stability, the far end's
    values and their error estimate (as ``solve``'s summary; none where the walk stopped
    before its check)."""
    end = branch.end
    k = end.negative_eigenvalues
    state = "stable" if end.stable else f"unstable ({k} negative eigenvalue{'s' * (k != 1)})"
    early = ("" if branch.ended is None else f" (stopped early: {branch.ended.status})"
             if branch.ended.stopped else f" ({branch.ended.status}: the last physical state)")
    return (f"end at {_where(branch, end)}{early}: {state}, r_end = {end.r_end:.10g} R, "
            f"z_end = {end.z_end:.10g} R, psi_end = {end.psi_end:.10g} rad, energy = "
            f"{end.energy:.10g} C R^2{_end_error(branch.end_error)}")


def _end_error(error) -> str:
    """The end's error estimate for its line: ``solve``'s summary, or why there is none."""
    if error is None:
        return ""
    if error.note:
        return f"; no error estimate: {error.note}"
    return f"; error estimate {error.summary('C R^2')}"


def _switched(args, branch) -> tuple[list[tuple[str, object]], list[str], str | None]:
    """(name, branch) of both halves of the branches through the first ``--switch`` branch
    points, reported as they are followed; the names of those that failed (after the
    main branch's work: named and counted, not taken for bad input); and, where Ctrl-C or
    SIGTERM stops them, what was not followed (None: all were), the part of the one cut
    kept (audit 17: the complete main branch had been lost with it)."""
    from .._runtime import interrupts
    from ..solvers.branches import switch_branch
    from ..solvers.results import SolverError

    count = sum(pt.event == "branch_point" for pt in branch.points)
    if args.switch > count:
        note(f"--switch {args.switch}: the branch has {count} branch point(s)")
    halves = _halves(args, branch)
    out, failed = [], []
    for i, name in enumerate(halves):
        try:
            other = switch_branch(branch, int(name[:-1]) - 1, 1 if name[-1] == "+" else -1,
                                  max_step=args.max_step, max_points=args.max_points)
        except (SolverError, ValueError) as exc:     # (ValueError: not a simple point)
            print(f"  switch at branch point {name} failed: {exc}")
            failed.append(name)
            if getattr(exc, "branch", None) is not None:    # (its part: written, marked)
                out.append((name, exc.branch))
            continue
        except BaseException as exc:
            if not interrupts.interrupted(exc):
                raise
            interrupts.swallowed()      # (claimed: the outputs' commit would raise it again)
            part = getattr(exc, "branch", None)
            if part is not None:
                out.append((name, part))
            rest = halves[i + 1:] if part else halves[i:]
            done = ([f"its {len(part.points)} points followed kept"] if part else []) + \
                ([f"{', '.join(rest)} not followed"] if rest else [])
            return out, failed, (f"{interrupts.reason()} during the switch at branch point "
                                 f"{name}: {'; '.join(done)}")
        print(f"  switched at branch point {name} (lambda = {other.origin:.10g}): "
              f"{len(other.points)} points, {len(other.events) - 1} more event(s), "
              f"{_end_line(other)}")
        out.append((name, other))
    return out, failed, None


def _halves(args, branch) -> list[str]:
    """The names of the branches ``--switch`` follows from ``branch``: both halves (+, −) of
    each of its first N branch points, numbered from 1."""
    count = sum(pt.event == "branch_point" for pt in branch.points)
    return [f"{k + 1}{sign}" for k in range(min(args.switch, count)) for sign in "+-"]


def _csv_columns(branch, switched, named: bool = False) -> dict:
    """The table with ``stable`` as true/false (not Python's True/False); after a switch, the
    switched branches' rows follow, and a first column ``branch`` names each row's (also
    where none was followed, if ``named``: a --switch run's layout)."""
    tables = [("main", branch.columns())] + [(name, b.columns()) for name, b in switched]
    columns = {k: [v for _, t in tables for v in t[k]] for k in tables[0][1]}
    columns["stable"] = ["true" if s else "false" for s in columns["stable"]]
    # (an event that the half mesh does not have: "inf", not the empty cell of "unchecked")
    # (one type in the column: strings, as write_csv writes floats)
    columns["lambda_error"] = ["inf" if e == float("inf") else repr(e) if e >= 0 else ""
                               for e in columns["lambda_error"]]
    if switched or named:
        columns = {"branch": [name for name, t in tables for _ in t["lambda"]], **columns}
    return columns


def _document(branch, switched, missing: str | None = None, named: bool = False) -> dict:
    from .. import __version__

    return {"morphoshell": __version__, **branch.to_dict(),
            **({"switched": [{"name": name, **b.to_dict()} for name, b in switched]}
               if switched or named else {}),
            **({"complete": False, "not_done": missing} if missing else {})}
