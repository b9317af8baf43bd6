"""Command line: ``morphoshell COMMAND ...``.

Exit status: 0 on success, 2 for bad input (named in the message), 3 when a
solver fails (Ipopt or solve_bvp status in the message).
"""
from __future__ import annotations

import argparse
import sys
from typing import Sequence

from . import __version__
from .io import METHODS, ProblemFileError, apply_overrides, load_problem, parse_overrides, write_json

__all__ = ["main", "build_parser"]

_SET_HELP = ("override a problem entry, repeatable: h, theory, cut (Sigma), opening (P) or a "
             "parameter of the problem's family (uniform: k; anisotropic: f0; local_relaxation: "
             "F0, s0; volvox: f1..f5, kappa1..kappa4, s1..s4, sigma)")


def _common(p: argparse.ArgumentParser) -> None:
    p.add_argument("problem", metavar="PROBLEM.toml", help="problem file (see problems/)")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                   help=_SET_HELP)
    p.add_argument("--nodes", type=int, default=None, metavar="N",
                   help="mesh nodes (default: the file's [solver] nodes, else 200)")
    p.add_argument("--stages", type=int, choices=(1, 2, 3), default=None, metavar="S",
                   help="Gauss points per cell of the direct solver: order 2S (default: the "
                        "file's [solver] stages, else 2)")
    p.add_argument("--json", metavar="OUT.json", help="write results as JSON")
    p.add_argument("--plot", metavar="OUT.png", help="write a cross-section plot")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="morphoshell",
        description="Equilibria of axisymmetric morphoelastic shells by direct energy "
                    "minimisation (CasADi + Ipopt), with a boundary-value reference. Lengths "
                    "are in units of the undeformed radius R, energies in units of C R^2.")
    parser.add_argument("--version", action="version", version=f"morphoshell {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    p = sub.add_parser("solve", help="equilibrium of a problem file",
                       description="Solve for the equilibrium shape of PROBLEM.toml and print a "
                                   "summary (energy, edge values, solver statistics).")
    _common(p)
    p.add_argument("--method", choices=METHODS, default=None,
                   help="direct energy minimisation (default) or the boundary-value reference")
    p.set_defaults(run=_solve)
    return parser


def _load(args):
    problem, settings = load_problem(args.problem)
    problem = apply_overrides(problem, parse_overrides(args.overrides))
    nodes = settings.nodes if args.nodes is None else args.nodes
    if nodes < 5:
        raise ProblemFileError(f"--nodes {nodes}: need at least 5 nodes")
    stages = settings.stages if args.stages is None else args.stages
    return problem, settings, nodes, stages


def _solve(args) -> int:
    from .equilibrium import solve

    problem, settings, nodes, stages = _load(args)
    method = args.method or settings.method
    eq = solve(problem, nodes=nodes, method=method, **({"stages": stages} if method == "direct" else {}))
    edge = "start" if problem.structure.start == "free" else "end"
    e = eq.edge(edge)
    print(f"{problem.name or problem.family}: {method} solution, {len(eq.s)} points, "
          f"{eq.solver.iterations} iterations, {eq.solver.seconds * 1e3:.1f} ms "
          f"({eq.solver.status})")
    print(f"  energy          = {eq.energy:.12g}  (units of C R^2)")
    print(f"  {edge} edge s = {e['s']:.6g}: r = {e['r']:.10g}, z = {e['z']:.10g}, "
          f"psi = {e['psi']:.10g}")
    print(f"  max |eta|       = {abs(eq.eta).max():.4g}")
    if args.json:
        write_json(args.json, eq.to_dict())
        print(f"  wrote {args.json}")
    if args.plot:
        from .plotting import plot_cross_section, save
        ax = plot_cross_section([eq], title=f"{problem.name or problem.family} ({method})")
        save(ax, args.plot)
        print(f"  wrote {args.plot}")
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    from .equilibrium import SolverError

    try:
        return args.run(args)
    except ProblemFileError as exc:
        print(f"morphoshell: error: {exc}", file=sys.stderr)
        return 2
    except SolverError as exc:
        print(f"morphoshell: solver failed: {exc}", file=sys.stderr)
        return 3
    except ValueError as exc:
        print(f"morphoshell: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
