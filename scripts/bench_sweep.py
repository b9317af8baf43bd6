#!/usr/bin/env python3
"""Timing of a sweep of 1000 ablations (toy problem 2: 3 k x 333 cuts) on 1 and 2 workers.

Target of the issue: a sweep of 1000 ablations runs at the solver's warm
speed, not at process start-up speed.  The cost of one warm solve (the cut
shell of toy problem 2 at 200 nodes, re-solved after a small change of the
cut: the median of --warm-repeats) is measured in the same run, so that the
per-ablation cost (wall time / 1000; an ablation is two solves, the intact and
the cut shell) can be compared with it on a machine in any state of load.
Each sweep row is the median of --repeats runs; the wall time includes
starting the workers (a Dask LocalCluster), which is also timed on its own;
the CPU time (this process and its workers) does not depend on what else
the machine runs, the wall time does (the load average is printed).

Usage: python scripts/bench_sweep.py [--workers 1,2] [--repeats 1] [--errors ends]
                                     [--json out/bench_sweep.json]
"""
from __future__ import annotations

import argparse
import os
import statistics
import time

import numpy as np

from morphoshell.solvers.continuation import continue_to
from morphoshell.solvers.direct import DirectSolver
from morphoshell.workflows.executor import open_executor, run
from morphoshell.io.problem_files import example_path, load_problem, write_json
from morphoshell.numerics.mesh import mesh_spec
from morphoshell.workflows.sweeps import sweep

KS = (0.0, 0.5, 2.0)
CUTS = np.linspace(0.05, 1.4, 333)


def warm_solve(problem, nodes: int, repeats: int) -> float:
    """Median wall time (s) of one warm re-solve of the cut shell, cut changed by 1e-3 R."""
    solver = DirectSolver(problem.structure, stages=2, mesh=mesh_spec(problem, nodes, 2))
    eq = continue_to(solver, problem)
    times = []
    for i in range(repeats):
        q = problem.with_updates(cut=problem.cut + 1e-3 * (i % 2 + 1))
        t0 = time.perf_counter()
        solver.solve(q, warm_start=eq)
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def startup(workers: int) -> float:
    """Wall time (s) to start ``workers`` workers, run a trivial task on each and stop them."""
    t0 = time.perf_counter()
    with open_executor(workers) as ex:
        list(run(abs, range(workers), ex))
    return time.perf_counter() - t0


def _cpu() -> float:
    """CPU seconds of this process and its finished children (the workers, once stopped)."""
    t = os.times()
    return t.user + t.system + t.children_user + t.children_system


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workers", default="1,2", help="worker counts, comma-separated")
    parser.add_argument("--repeats", type=int, default=1, help="runs of each sweep (median)")
    parser.add_argument("--warm-repeats", type=int, default=40)
    parser.add_argument("--errors", default="ends", choices=("ends", "all", "none"))
    parser.add_argument("--json", default=None, help="also write the timings as JSON")
    args = parser.parse_args(argv)
    base, settings = load_problem(example_path("toy2_ablation"))
    nodes = settings.nodes
    n = len(KS) * len(CUTS)
    print(f"toy problem 2 (h = {base.h}), {nodes} nodes, order 4: {n} ablations "
          f"({len(KS)} k x {len(CUTS)} cuts in [{CUTS[0]}, {CUTS[-1]}] R), errors={args.errors}; "
          f"{os.cpu_count()} CPU cores, load average {os.getloadavg()[0]:.2f}")
    warm = warm_solve(base, nodes, args.warm_repeats)
    rows = {"warm_solve_s": warm, "ablations": n, "nodes": nodes, "errors": args.errors,
            "load_average": os.getloadavg()[0], "sweeps": {}}
    reference = None
    for w in (int(v) for v in args.workers.split(",")):
        runs = []
        for _ in range(args.repeats):
            load = os.getloadavg()[0]
            t0, c0 = time.perf_counter(), _cpu()
            res = sweep(base, {"k": list(KS), "cut": CUTS}, ablate=True, nodes=nodes,
                        workers=w, errors=args.errors)
            wall, cpu = time.perf_counter() - t0, _cpu() - c0
            runs.append((wall, cpu, load, res))
        wall, cpu, load, res = sorted(runs, key=lambda r: r[0])[len(runs) // 2]
        cols = res.columns
        if reference is None:
            reference = cols
        same = all(np.array_equal(reference[k], cols[k], equal_nan=True)
                   for k in ("opening", "rotation", "displacement", "energy_released"))
        rows["sweeps"][w] = {
            "wall_s": wall, "per_ablation_s": wall / n, "work_s": float(np.sum(cols["seconds"])),
            "cpu_s": cpu, "cpu_per_ablation_s": cpu / n, "load_before": load,
            "startup_s": startup(w) if w > 1 else 0.0, "backend": res.timing["backend"],
            "chunks": res.timing["chunks"], "failed": res.failed,
            "iterations_per_ablation": float(np.mean(cols["iterations"])),
            "same_numbers_as_first": bool(same)}
    print(f"\none warm solve (cut shell, {nodes} nodes): {warm * 1e3:.1f} ms "
          f"(median of {args.warm_repeats})\n")
    head = (f"{'workers':>7}  {'backend':>7}  {'load':>4}  {'wall s':>6}  {'start-up s':>10}  "
            f"{'CPU s':>6}  {'ms/ablation':>11}  {'CPU ms/abl.':>11}  {'/ warm solve':>12}  "
            f"{'Newton it.':>10}  {'failed':>6}  same numbers")
    print(head)
    print("-" * len(head))
    for w, r in rows["sweeps"].items():
        print(f"{w:>7}  {r['backend']:>7}  {r['load_before']:>4.1f}  {r['wall_s']:>6.1f}  "
              f"{r['startup_s']:>10.1f}  {r['cpu_s']:>6.1f}  {r['per_ablation_s'] * 1e3:>11.1f}  "
              f"{r['cpu_per_ablation_s'] * 1e3:>11.1f}  {r['per_ablation_s'] / warm:>12.2f}  "
              f"{r['iterations_per_ablation']:>10.1f}  {r['failed']:>6}  "
              f"{'yes' if r['same_numbers_as_first'] else 'NO'}")
    print("\nload: the 1-minute load average before the sweep (other processes share the "
          "cores); wall: the whole sweep, workers' start-up included (start-up: timed alone); "
          "CPU: this process and its workers; / warm solve: wall ms per ablation over one warm "
          "solve (an ablation is two solves, the intact and the cut shell); Newton it.: both "
          "shells, continuation at each chunk's first point included")
    if args.json:
        write_json(args.json, rows)
    return 0


if __name__ == "__main__":      # the guard: Dask's workers re-import this module
    raise SystemExit(main())
