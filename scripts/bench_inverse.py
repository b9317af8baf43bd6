#!/usr/bin/env python3
"""Timing of the inverse estimates (morphoshell.inverse) on the synthetic ablation table.

Target of the issue: numerical estimates of k for 14 embryos x 3 measures,
bootstrap included, in under 5 s on 2 cores.  Each row is the median of
--repeats runs of :func:`morphoshell.inverse.estimate` (the very first run of
the process, which also imports, is reported separately); every run builds
its own pair of solvers.  Wall time depends on what else the machine runs: the
load average is printed, and the CPU time of all processes (this one and its
workers), which is what an idle machine would need on one core.

Usage: python scripts/bench_inverse.py [--table data/synthetic_ablations.csv] [--repeats 5]
                                       [--json out/bench_inverse.json]
"""
from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

from morphoshell import inverse as I
from morphoshell.solvers.direct import DirectSolver
from morphoshell.io.problem_files import example_path, load_problem, write_json

ROOT = Path(__file__).resolve().parents[1]
#: docs/benchmarks.md's reference (scripts/bench_equilibrium.py): warm re-solve of toy3_anisotropic,
#: 200 nodes, order 4, on an unloaded machine of this kind.
REFERENCE_WARM_S = 5.9e-3

#: (label, methods, workers); None: one per core.
CASES = (("numerical, 2 workers (target < 5 s)", ("numerical",), None),
         ("numerical, 1 process", ("numerical",), 1),
         ("inner problem, 2 workers", ("inner",), None),
         ("leading order + Kelvin, 1 process", ("leading_order", "kelvin"), 1),
         ("all methods (the CLI), 2 workers", I.METHODS, None))


def _cpu() -> float:
    t = os.times()
    return t.user + t.system + t.children_user + t.children_system


def run(table, methods, workers) -> dict:
    t0, c0 = time.perf_counter(), _cpu()
    result = I.estimate(table, methods=methods, workers=workers)
    seconds, cpu = time.perf_counter() - t0, _cpu() - c0
    evals = sum(e.estimates[(m, meth)].evaluations for e in result.embryos
                for m in I.MEASURES for meth in methods)
    estimates = sum(e.estimates[(m, meth)].k is not None for e in result.embryos
                    for m in I.MEASURES for meth in methods)
    return {"seconds": seconds, "cpu": cpu, "builds": result.timing["numerical_solver_builds"],
            "estimates": estimates, "refinement_solves": evals,
            "embryos": len(result.embryos)}


def slowdown(repeats: int = 30) -> tuple[float, float]:
    """(warm re-solve of bench_equilibrium's reference case now, its ratio to the reference's)."""
    problem, _ = load_problem(example_path("toy3_anisotropic"))
    solver = DirectSolver(problem.structure, 200, stages=2)
    base = solver.solve(problem)
    times = []
    for i in range(repeats):
        q = problem.with_updates(f0=problem.params["f0"] + 1e-3 * (i + 1))
        t0 = time.perf_counter()
        solver.solve(q, warm_start=base)
        times.append(time.perf_counter() - t0)
    warm = statistics.median(times)
    return warm, warm / REFERENCE_WARM_S


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--table", default=str(ROOT / "data" / "synthetic_ablations.csv"))
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--json", default=None, help="also write the timings as JSON")
    args = parser.parse_args(argv)
    table = Path(args.table)
    t0 = time.perf_counter()
    load0 = os.getloadavg()
    warm0, factor0 = slowdown()
    first = run(table, ("numerical",), None)
    first_seconds = time.perf_counter() - t0
    rows = []
    for label, methods, workers in CASES:
        runs = [run(table, methods, workers) for _ in range(args.repeats)]
        times = [r["seconds"] for r in runs]
        rows.append({"case": label, "methods": list(methods), "median_s": statistics.median(times),
                     "min_s": min(times), "max_s": max(times),
                     "median_cpu_s": statistics.median(r["cpu"] for r in runs),
                     **{k: runs[0][k] for k in ("builds", "estimates", "refinement_solves",
                                                "embryos")}})
    load = os.getloadavg()
    warm1, factor1 = slowdown()
    print(f"table {table.name}: {first['embryos']} embryos x 3 measures; "
          f"load average (1 min) {load0[0]:.2f} before, {load[0]:.2f} after, on "
          f"{os.cpu_count()} cores (the machine may be shared); median of {args.repeats}")
    print("| methods | wall median | min | max | CPU median (all processes) | estimates | "
          "solver builds | Newton solves beyond the grid |")
    print("|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['case']} | {r['median_s']:.2f} s | {r['min_s']:.2f} s | {r['max_s']:.2f} s "
              f"| {r['median_cpu_s']:.2f} s | {r['estimates']} | {r['builds']} "
              f"| {r['refinement_solves']} |")
    print(f"first run in a fresh process (numerical, imports included): {first_seconds:.2f} s")
    print(f"machine speed now: bench_equilibrium's warm re-solve (toy3, 200 nodes) took "
          f"{warm0 * 1e3:.1f} ms before and {warm1 * 1e3:.1f} ms after, "
          f"{factor0:.1f}x and {factor1:.1f}x the reference's {REFERENCE_WARM_S * 1e3:.1f} ms")
    target = rows[0]["median_s"] < 5.0
    print(f"target (numerical < 5 s): {'met' if target else 'NOT met'} "
          f"({rows[0]['median_s']:.2f} s)")
    if args.json:
        write_json(args.json, {"table": str(table), "repeats": args.repeats,
                               "load_average": {"before": load0, "after": load},
                               "slowdown_vs_readme": [factor0, factor1],
                               "rows": rows, "first_run_s": first_seconds, "target_met": target})
    return 0


if __name__ == "__main__":
    sys.exit(main())
