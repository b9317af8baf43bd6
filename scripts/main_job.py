#!/usr/bin/env python3
"""The main job of `make run`: solve every problem in problems/ and write results to out/.

For each problems/NAME.toml: out/NAME.json (the equilibrium) and out/NAME.png
(cross-section); out/summary.json collects energies, edge values and solver
statistics of all problems.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import matplotlib

from morphoshell.equilibrium import solve
from morphoshell.io import load_problem, write_json
from morphoshell.plotting import plot_cross_section, problem_label, save

ROOT = Path(__file__).resolve().parents[1]


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="out", help="output folder (default: out)")
    parser.add_argument("--problems", default=str(ROOT / "problems"), help="problem folder")
    args = parser.parse_args(argv)
    matplotlib.use("Agg")   # files only: no display needed
    out = Path(args.out)
    summary = {}
    for path in sorted(Path(args.problems).glob("*.toml")):
        problem, settings = load_problem(path)
        extra = {"stages": settings.stages} if settings.method == "direct" else {}
        eq = solve(problem, nodes=settings.nodes, method=settings.method, **extra)
        write_json(out / f"{path.stem}.json", eq.to_dict())
        title = f"{problem_label(problem)}\n({settings.method}, {settings.nodes} nodes)"
        save(plot_cross_section(eq, title=title), out / f"{path.stem}.png", close=True)
        summary[path.stem] = eq.to_dict(arrays=False)
        print(f"{path.stem:20s} energy {eq.energy:.10g}  {eq.solver.iterations} iterations  "
              f"{eq.solver.seconds * 1e3:7.1f} ms")
    write_json(out / "summary.json", {"problems": summary})
    print(f"wrote {out}/summary.json and {len(summary)} problems' JSON and PNG files")
    return 0


if __name__ == "__main__":
    sys.exit(main())
