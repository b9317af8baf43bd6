#!/usr/bin/env python3
"""Benchmark: direct minimisation (cold and warm) against the BVP reference.

Problem: the example toy3_anisotropic (anisotropic contraction, h = 0.3,
Sigma = 0.3, f0 = 0.1: a free edge with a boundary layer and a weakly
singular pole).  All timings are medians of several runs in this process.

* cold: build the NLP (DirectSolver) and solve from the undeformed shell;
* warm: parametric re-solve after a small change (f0 + 1e-3 i) from the
  previous solution, on the NLP built once;
* BVP: scipy's solve_bvp on the Pontryagin equations, cold (undeformed guess)
  and warm (previous BVP solution as guess and initial mesh).

Accuracy is the largest relative error of the edge values r(Sigma), psi(Sigma)
against the Richardson limit of the fourth-order direct scheme on 1600/3200
nodes (it agrees with the BVP at tol 1e-8 to ~1e-10).  "Matched accuracy"
compares the cheapest configuration of each method whose error is at most
1e-6.

Usage: python scripts/bench_equilibrium.py [--quick]
"""
from __future__ import annotations

import argparse
import resource
import sys
import time
from pathlib import Path

import numpy as np

from morphoshell.equilibrium import DirectSolver, solve
from morphoshell.io import example_path, load_problem

ROOT = Path(__file__).resolve().parents[1]
TARGET = 1e-6


def edge(eq) -> np.ndarray:
    return np.array([eq.r[0], eq.psi[0]])


def median_time(fn, repeats: int) -> tuple[float, object]:
    times, out = [], None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return float(np.median(times)), out


def bench_direct(problem, nodes, stages, repeats_cold, repeats_warm, ref):
    variants = [problem.with_updates(f0=problem.params["f0"] + 1e-3 * (i + 1))
                for i in range(repeats_warm)]

    def cold():
        solver = DirectSolver(problem.structure, nodes, stages=stages)
        return solver, solver.solve(problem)

    t_cold, (solver, base) = median_time(cold, repeats_cold)
    warm_times, iters = [], []
    for q in variants:
        t0 = time.perf_counter()
        eq = solver.solve(q, warm_start=base)
        warm_times.append(time.perf_counter() - t0)
        iters.append(eq.solver.iterations)
    return {"cold": t_cold, "build": solver.build_seconds, "warm": float(np.median(warm_times)),
            "iters": int(np.median(iters)), "error": float(np.max(np.abs(edge(base) / ref - 1))),
            "unknowns": solver.disc.layout.size}


def bench_bvp(problem, tol, repeats, ref):
    variants = [problem.with_updates(f0=problem.params["f0"] + 1e-3 * (i + 1))
                for i in range(repeats)]
    t_cold, base = median_time(lambda: solve(problem, method="bvp", tol=tol, nodes=50), repeats)
    warm = []
    for q in variants:
        t0 = time.perf_counter()
        solve(q, method="bvp", tol=tol, warm_start=base)
        warm.append(time.perf_counter() - t0)
    return {"cold": t_cold, "warm": float(np.median(warm)), "nodes": len(base.s),
            "error": float(np.max(np.abs(edge(base) / ref - 1)))}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer repeats, no N = 12800")
    args = parser.parse_args(argv)
    problem, _ = load_problem(example_path("toy3_anisotropic"))
    rc, rw = (2, 5) if args.quick else (5, 15)
    meshes = (200, 800, 3200) if args.quick else (200, 800, 3200, 12800)

    # The first build in a process also creates the symbolic energy and cell
    # functions (cached per structure); report it, then time with warm caches.
    t0 = time.perf_counter()
    DirectSolver(problem.structure, 50).solve(problem)
    first_direct = time.perf_counter() - t0
    t0 = time.perf_counter()
    solve(problem, method="bvp", nodes=50, tol=1e-3)
    first_bvp = time.perf_counter() - t0
    print(f"first solve in this process (symbolic set-up included): direct N = 50 "
          f"{1e3 * first_direct:.0f} ms, BVP tol 1e-3 {1e3 * first_bvp:.0f} ms\n")

    a, b = solve(problem, nodes=1600), solve(problem, nodes=3200)
    ref = edge(b) + (edge(b) - edge(a)) / 15
    check = solve(problem, method="bvp", tol=1e-8)
    print(f"reference edge values r = {ref[0]:.12f}, psi = {ref[1]:.12f} "
          f"(BVP tol 1e-8 differs by {np.max(np.abs(edge(check) / ref - 1)):.1e})\n")


    print("Direct minimisation (Ipopt + MUMPS), toy3_anisotropic, medians")
    print(f"{'scheme':>10} {'N':>6} {'unknowns':>9} {'cold ms':>9} {'build ms':>9} "
          f"{'warm ms':>9} {'iters':>5} {'warm us/unknown':>15} {'edge error':>11}")
    rows = {}
    for stages, name in ((1, "order 2"), (2, "order 4")):
        for n in meshes:
            r = bench_direct(problem, n, stages, rc if n < 12800 else 2, rw if n < 12800 else 5, ref)
            rows[(stages, n)] = r
            print(f"{name:>10} {n:6d} {r['unknowns']:9d} {1e3 * r['cold']:9.1f} "
                  f"{1e3 * r['build']:9.1f} {1e3 * r['warm']:9.2f} {r['iters']:5d} "
                  f"{1e6 * r['warm'] / r['unknowns']:15.2f} {r['error']:11.1e}")
    for stages in (1, 2):
        ns = np.array(meshes, float)
        for key in ("cold", "warm"):
            slope = np.polyfit(np.log(ns[1:]), np.log([rows[(stages, n)][key] for n in meshes[1:]]), 1)[0]
            print(f"  order {2 * stages}: {key} time grows like N^{slope:.2f} (N = {meshes[1]}..{meshes[-1]})")

    print("\nBVP reference (scipy solve_bvp, Pontryagin equations), medians")
    print(f"{'tol':>8} {'final nodes':>11} {'cold ms':>9} {'warm ms':>9} {'edge error':>11}")
    bvp = {}
    for tol in (1e-3, 1e-4, 1e-6, 1e-8):
        r = bench_bvp(problem, tol, max(3, rc), ref)
        bvp[tol] = r
        print(f"{tol:8.0e} {r['nodes']:11d} {1e3 * r['cold']:9.1f} {1e3 * r['warm']:9.1f} "
              f"{r['error']:11.1e}")

    print(f"\nMatched accuracy (edge error <= {TARGET:.0e}): cheapest configuration of each method")
    cands = []
    for stages in (1, 2):
        for n in ((25, 50, 100, 200, 400) if stages == 2 else (400, 800, 1600, 3200)):
            r = rows.get((stages, n)) or bench_direct(problem, n, stages, rc, rw, ref)
            if r["error"] <= TARGET:
                cands.append((f"direct order {2 * stages}, N = {n}", r))
                break
    b_ok = [(tol, r) for tol, r in bvp.items() if r["error"] <= TARGET]
    tol, rb = max(b_ok, key=lambda t: t[0])
    print(f"  BVP tol {tol:.0e}: cold {1e3 * rb['cold']:.1f} ms, warm {1e3 * rb['warm']:.1f} ms, "
          f"error {rb['error']:.1e}")
    for label, r in cands:
        print(f"  {label}: cold {1e3 * r['cold']:.1f} ms (build {1e3 * r['build']:.1f}), "
              f"warm {1e3 * r['warm']:.2f} ms, error {r['error']:.1e}  ->  "
              f"BVP/direct: cold {rb['cold'] / r['cold']:.1f}x, warm {rb['warm'] / r['warm']:.1f}x")
    w800 = rows[(1, 800)]["warm"], rows[(2, 800)]["warm"]
    print(f"\nwarm re-solve at N = 800: {1e3 * w800[0]:.2f} ms (order 2), {1e3 * w800[1]:.2f} ms "
          f"(order 4); target < 10 ms")
    print(f"peak resident memory: {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f} MiB")
    return 0


if __name__ == "__main__":
    sys.exit(main())
