#!/usr/bin/env python3
"""The main job of `make run`: solve every example problem and write results to out/.

The examples ship in the package (src/morphoshell/examples, also reachable as
problems/; `morphoshell example --list`).  For each NAME.toml: out/NAME.json (the equilibrium) and out/NAME.png
(cross-section); out/summary.json collects energies, edge values and solver
statistics of all problems.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import matplotlib

from morphoshell._runtime.console import run_script, progress
from morphoshell.solvers.routes import solve
from morphoshell.io.problem_files import EXAMPLES_DIR, load_problem, write_json
from morphoshell.plotting import plot_cross_section, save



def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="out", help="output folder (default: out)")
    parser.add_argument("--problems", default=str(EXAMPLES_DIR),
                        help="problem folder (default: the packaged examples, also problems/)")
    return run_script(parser, argv, _run)


def _run(args) -> int:
    matplotlib.use("Agg")   # files only: no display needed
    out = Path(args.out)
    summary = {}
    for path in progress(sorted(Path(args.problems).glob("*.toml")), desc="problems",
                         unit="problem"):
        problem, settings = load_problem(path)
        extra = {"stages": settings.stages} if settings.method == "direct" else {}
        eq = solve(problem, nodes=settings.nodes, method=settings.method, **extra)
        write_json(out / f"{path.stem}.json", eq.to_dict())
        # title: the problem; caption: its parameters, method and mesh
        save(plot_cross_section(eq), out / f"{path.stem}.png", close=True)
        summary[path.stem] = eq.to_dict(arrays=False)
        print(f"{path.stem:20s} energy {eq.energy:.10g}  {eq.solver.iterations} iterations  "
              f"{eq.solver.seconds * 1e3:7.1f} ms")
    write_json(out / "summary.json", {"problems": summary})
    print(f"wrote {out}/summary.json and {len(summary)} problems' JSON and PNG files")
    return 0


if __name__ == "__main__":
    sys.exit(main())
