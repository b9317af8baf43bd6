#!/usr/bin/env python3
"""Benchmark: a branch of about 200 points through the folds of a 400-node Volvox shell.

The shell is the fold shell of issue 38 (``tests/data/volvox_fold.toml``): its path from
the stress-free parameters to λ = 1 has six folds.  ``follow_branch`` (pseudo-arclength
steps, the inertia of every point, the folds located by Brent's method) with a largest
step that gives about 200 points; target of the issue: under 5 s on 2 cores.

Reference, in the same run: as many natural-parameter warm solves (``DirectSolver.solve``
from the previous solution, minimum certificate included) along the same path before
its first fold (λ from 0 to 0.85 in equal steps), on the same solver.  The ratio says
what a point of the branch costs against a warm solve.

Timings are medians of ``--repeats`` runs in this process with the solver built (its
build, done once, is printed apart); the machine's load average is printed with the
table (the machine may be shared: compare ratios within one run).

Usage: python scripts/bench_branches.py [--repeats 5] [--nodes 400] [--max-step 0.017]
                                        [--profile]
"""
from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

import numpy as np

from morphoshell.io.problem_files import load_problem
from morphoshell.solvers.branches import follow_branch
from morphoshell.solvers.paths import ParameterLine, neutral_problem
from morphoshell.solvers.routes import direct_solver

FIXTURE = Path(__file__).resolve().parents[1] / "tests" / "data" / "volvox_fold.toml"


def load() -> str:
    one, five, _ = os.getloadavg()
    return f"load average {one:.2f} (1 min), {five:.2f} (5 min) on {os.cpu_count()} cores"


def branch(problem, nodes: int, max_step: float):
    return follow_branch(problem, nodes=nodes, max_step=max_step, max_points=5000)


def natural(problem, nodes: int, count: int) -> float:
    """Seconds of ``count`` warm solves along the path before its first fold."""
    solver = direct_solver(problem, nodes, ())
    line = ParameterLine.between(neutral_problem(problem), problem)
    eq = solver.solve(line.source)
    t0 = time.perf_counter()
    for tau in np.linspace(0.0, 0.85, count + 1)[1:]:
        eq = solver.solve(line.at(float(tau)), warm_start=eq)
    return time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--nodes", type=int, default=400)
    ap.add_argument("--max-step", type=float, default=0.017)
    ap.add_argument("--profile", action="store_true",
                    help="one more branch under pyinstrument (pip install pyinstrument)")
    args = ap.parse_args()
    problem = load_problem(FIXTURE)[0]
    t0 = time.perf_counter()
    first = branch(problem, args.nodes, args.max_step)
    print(f"first branch, solver build included: {time.perf_counter() - t0:.2f} s")
    points = len(first.points)
    folds = [round(pt.tau, 7) for pt in first.events if pt.event == "fold"]
    rows = []
    for _ in range(args.repeats):
        t0 = time.perf_counter()
        b = branch(problem, args.nodes, args.max_step)
        t_branch = time.perf_counter() - t0
        assert len(b.points) == points
        rows.append((t_branch, natural(problem, args.nodes, points)))
    t_branch, t_natural = np.median(np.array(rows), axis=0)
    ratio = np.median([a / b for a, b in rows])
    print(f"{load()}")
    print(f"fold shell, {args.nodes} nodes, max_step {args.max_step}: {points} points, "
          f"folds at {folds}, end at lambda = {first.end.tau} (stable: {first.end.stable})")
    print("| case | median s | points | ms per point | ratio to warm solves |")
    print("|---|---|---|---|---|")
    print(f"| follow_branch | {t_branch:.2f} | {points} | {1e3 * t_branch / points:.1f} | "
          f"{ratio:.2f} |")
    print(f"| {points} natural warm solves | {t_natural:.2f} | {points} | "
          f"{1e3 * t_natural / points:.1f} | 1 |")
    print(f"target < 5 s: {'met' if t_branch < 5 else 'missed'} "
          f"(median of {args.repeats}; the rounds: "
          f"{', '.join(f'{a:.2f}/{b:.2f}' for a, b in rows)} s)")
    if args.profile:
        from pyinstrument import Profiler

        profiler = Profiler()
        profiler.start()
        branch(problem, args.nodes, args.max_step)
        profiler.stop()
        print(profiler.output_text(unicode=False, color=False, show_all=False))


if __name__ == "__main__":
    main()
