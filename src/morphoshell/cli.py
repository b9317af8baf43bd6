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
    p.add_argument("--method", choices=METHODS, default=None,
                   help="direct energy minimisation (default) or the boundary-value reference")
    p.add_argument("--nodes", type=int, default=None, metavar="N",
                   help="mesh nodes (default: the file's [solver] nodes, else 200)")
    p.add_argument("--stages", type=int, choices=(1, 2, 3), default=None, metavar="S",
                   help="Gauss points per cell of the direct solver: order 2S (default: the "
                        "file's [solver] stages, else 2)")
    p.add_argument("--linear-solver", default="mumps", metavar="NAME",
                   help="Ipopt's linear solver for the direct method: mumps (default, bundled) "
                        "or an HSL solver such as ma27/ma57 if libhsl.so is installed")
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
    p.set_defaults(run=_solve)

    p = sub.add_parser("ablate", help="laser ablation: pre- and post-ablation equilibria",
                       description="Solve PROBLEM.toml before (cut = 0) and after the cut "
                                   "Sigma = cut > 0 and report the recoil observables opening, "
                                   "rotation, displacement and energy_released (Supplementary, "
                                   "toy problem 2; see morphoshell.observables).")
    _common(p)
    p.set_defaults(run=_ablate)

    p = sub.add_parser("asymptotics", help="the paper's asymptotic predictions for toy problem 2",
                       description="Leading-order and small-cut (Kelvin function) predictions "
                                   "of the Supplementary for a cut of half-angle SIGMA in a "
                                   "sphere of thickness H and intrinsic curvature K.")
    p.add_argument("--h", type=float, required=True, metavar="H", help="relative thickness h")
    p.add_argument("--k", type=float, required=True, metavar="K", help="intrinsic curvature k")
    p.add_argument("--cut-angle", type=float, required=True, metavar="SIGMA",
                   help="Sigma, half-angle of the ablation (radians, 0 < Sigma < pi)")
    p.add_argument("--json", metavar="OUT.json", help="write the predictions as JSON")
    p.set_defaults(run=_asymptotics)

    p = sub.add_parser("sphere", help="toy problem 1: radius of a sphere with intrinsic curvature",
                       description="Toy problem 1: deformed radius f of a complete sphere with "
                                   "intrinsic curvature K: the minimiser of the main text's shell "
                                   "energy, the exact bulk-elasticity minimiser (Mooney-Rivlin "
                                   "C10, C01) and the Supplementary's asymptotic formula.")
    p.add_argument("--h", type=float, required=True, metavar="H", help="relative thickness h")
    p.add_argument("--k", type=float, required=True, metavar="K", help="intrinsic curvature k")
    p.add_argument("--c10", type=float, default=1.0, metavar="A", help="C10 (default 1)")
    p.add_argument("--c01", type=float, default=0.0, metavar="B", help="C01 (default 0)")
    p.add_argument("--json", metavar="OUT.json", help="write the results as JSON")
    p.set_defaults(run=_sphere)
    return parser


def _load(args):
    problem, settings = load_problem(args.problem)
    problem = apply_overrides(problem, parse_overrides(args.overrides))
    nodes = settings.nodes if args.nodes is None else args.nodes
    if nodes < 5:
        raise ProblemFileError(f"--nodes {nodes}: need at least 5 nodes")
    stages = settings.stages if args.stages is None else args.stages
    return problem, settings, nodes, stages


def _direct_options(args, method: str, stages: int) -> dict:
    if method != "direct":
        return {}
    return {"stages": stages, "linear_solver": args.linear_solver}


def _solve(args) -> int:
    from .equilibrium import solve

    problem, settings, nodes, stages = _load(args)
    method = args.method or settings.method
    eq = solve(problem, nodes=nodes, method=method, **_direct_options(args, method, stages))
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


def _ablate(args) -> int:
    from .ablation import ablate

    problem, settings, nodes, stages = _load(args)
    method = args.method or settings.method
    ab = ablate(problem, nodes=nodes, method=method, **_direct_options(args, method, stages))
    print(f"{problem.name or problem.family}: ablation of Sigma = {problem.cut:g} "
          f"({method}, {len(ab.post.s)} points)")
    for key, value in ab.observables().items():
        print(f"  {key:20s} = {value:.10g}")
    if args.json:
        write_json(args.json, ab.to_dict())
        print(f"  wrote {args.json}")
    if args.plot:
        from .plotting import plot_ablation, save
        save(plot_ablation(ab, title=f"{problem.name or problem.family}: cut {problem.cut:g}"),
             args.plot)
        print(f"  wrote {args.plot}")
    return 0


def _asymptotics(args) -> int:
    from .asymptotics import predictions

    out = predictions(args.h, args.k, args.cut_angle)
    print(f"toy problem 2 asymptotics, h = {args.h:g}, k = {args.k:g}, Sigma = {args.cut_angle:g}")
    for key, value in out.items():
        print(f"  {key:22s} = {value:.10g}")
    if args.json:
        write_json(args.json, {"h": args.h, "k": args.k, "cut_angle": args.cut_angle, **out})
        print(f"  wrote {args.json}")
    return 0


def _sphere(args) -> int:
    from .asymptotics import f_bulk_asymptotic, f_shell_asymptotic, f_shell_exact, k_star
    from .bulk import f_bulk

    out = {"f_shell": f_shell_exact(args.h, args.k),
           "f_shell_asymptotic": f_shell_asymptotic(args.h, args.k),
           "f_bulk": f_bulk(args.h, args.k, args.c10, args.c01),
           "f_asymptotic": f_bulk_asymptotic(args.h, args.k, args.c10, args.c01)}
    try:
        out["k_star"] = k_star(args.c10, args.c01)
    except ValueError as exc:   # 5 C10 + C01 = 0: no second sign change
        out["k_star"] = None
        print(f"  (k_star: {exc})")
    print(f"toy problem 1, h = {args.h:g}, k = {args.k:g}, C10 = {args.c10:g}, C01 = {args.c01:g}")
    for key, value in out.items():
        print(f"  {key:18s} = {value if value is None else format(value, '.15g')}")
    if args.json:
        write_json(args.json, {"h": args.h, "k": args.k, "c10": args.c10, "c01": args.c01, **out})
        print(f"  wrote {args.json}")
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    from .results import SolverError

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
