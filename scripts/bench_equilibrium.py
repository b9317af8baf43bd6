#!/usr/bin/env python3
"""Benchmark: direct minimisation against the BVP reference at matched accuracy (issue 11).

Eight rows: toy 3 (h 0.3, Sigma 0.3, f0 0.1), toy 2 (k 0), the classical
theory at h 1e-3 and 1e-4 (Sigma 0.5, k 0), each at edge-value error targets
1e-6 and 1e-8.  For each method the cheapest setting (least cold + warm time)
whose edge values r(Sigma), psi(Sigma) meet the target both cold *and* after a
warm re-solve is chosen:

* direct: order 4 (stages 2) and order 6 (stages 3) on N nodes of the mesh
  ``solve()`` uses (graded for the problem's boundary layer, ``mesh_spec``);
  cold = choose the mesh, build the NLP and solve from the undeformed shell,
  with no solver of that size alive (the ratio's; and again with one alive,
  as in a session that solved that size before: "cold, size alive"),
  warm = re-solve after a 1 % parameter change (f0 for toy 3, h otherwise)
  from the previous solution, minimum certificate included;
* BVP: scipy's solve_bvp at tol 1e-3 .. 1e-8 from 50 or 200 initial nodes;
  warm = the previous BVP solution as guess and initial mesh.

Errors are relative to the Richardson limit of the order-4 direct scheme on
1600/3200 nodes (for the base and the perturbed problem), cross-checked with
solve_bvp at tol 1e-8.  Timings are medians of repeated runs in this process,
all ratios from the same run; the machine's load average is printed with every
table (the machine may be shared).  The targets are judged on paired ratios: the
two chosen settings of a row timed back to back in rounds (the medians above are
timed minutes apart, and the machine's speed drifts by 10-50 % in that time).  Then: the warm re-solve with certificate
at N = 200 and 3200, the build time against N, and the first solve in a fresh
process (``morphoshell solve problems/toy2_ablation.toml``), and what single CasADi
operations cost to build from Python (the fixed cost of every build).

With ``--large`` (or ``--only large``), also one build and solve each on
12 800 to 102 400 nodes, with the log-log slopes of the times against N,
with the default allocator and with large blocks kept in the heap.

Usage: python scripts/bench_equilibrium.py [--quick] [--large] [--only PART]
"""
from __future__ import annotations

import argparse
import datetime
import gc
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from morphoshell import Problem
from morphoshell.solvers.direct import DirectSolver
from morphoshell.solvers.routes import clear_cache, solve
from morphoshell.io.problem_files import example_path, load_problem
from morphoshell.numerics.mesh import mesh_spec
from morphoshell.solvers.results import SolverError

ROOT = Path(__file__).resolve().parents[1]
TARGETS = (1e-6, 1e-8)
# nodes in steps of 2^(1/4): the cheapest N meeting a target is within 19 % of the least
LADDER = tuple(int(round(25 * 2 ** (k / 4))) for k in range(25))   # 25 .. 1600
BVP_TOLS = (1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8)
BVP_NODES = (50, 200)


def load() -> str:
    one, five, _ = os.getloadavg()
    return f"load average {one:.2f} (1 min), {five:.2f} (5 min) on {os.cpu_count()} cores"


def edge(eq) -> np.ndarray:
    return np.array([eq.r[0], eq.psi[0]])


def error(eq, ref) -> float:
    return float(np.max(np.abs(edge(eq) / ref - 1)))


def median_time(fn, repeats: int, fresh: bool = False):
    """(median seconds, last result) of ``repeats`` calls of ``fn``.

    ``fresh``: drop each result (and collect it, untimed) before the next
    call.  For builds: CasADi keeps a kernel's map over N cells while a
    solver that uses it is alive, and a second build of the same size
    reuses it (measured: 0.9 ms of a 12.6 ms cold solve at 25 nodes, and
    180 -> 110 ms for a build at 3200).
    """
    times, out = [], None
    for _ in range(repeats):
        if fresh:
            out = None
            gc.collect()
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return float(np.median(times)), out


def rows():
    toy3, _ = load_problem(example_path("toy3_anisotropic"))
    toy2, _ = load_problem(example_path("toy2_ablation"))
    out = [("toy 3", toy3, toy3.with_updates(f0=1.01 * toy3.params["f0"])),
           ("toy 2 (k 0)", toy2, toy2.with_updates(h=1.01 * toy2.h))]
    for h in (1e-3, 1e-4):
        p = Problem("uniform", {"k": 0.0}, h=h, cut=0.5, theory="classical")
        out.append((f"classical h {h:.0e}", p, p.with_updates(h=1.01 * h)))
    return out


def reference(problem) -> tuple[np.ndarray, float]:
    a, b = solve(problem, nodes=1600), solve(problem, nodes=3200)
    ref = edge(b) + (edge(b) - edge(a)) / 15
    return ref, error(solve(problem, method="bvp", tol=1e-8), ref)


def direct_setting(problem, changed, stages, nodes, refs, repeats):
    """(cold s, warm s, cold error, warm error) of one direct setting, or None if it fails."""
    def cold():
        solver = DirectSolver(problem.structure, stages=stages,
                              mesh=mesh_spec(problem, nodes, stages))
        return solver, solver.solve(problem)
    try:
        t_cold, (solver, base) = median_time(cold, repeats, fresh=True)
        t_warm, warm = median_time(lambda: solver.solve(changed, warm_start=base), repeats)
    except SolverError:
        return None
    return t_cold, t_warm, error(base, refs[0]), error(warm, refs[1])


def cold_with_size_alive(problem, other, stages, nodes, repeats) -> float:
    """Seconds of a cold solve of ``problem`` while a solver of the same size and order (built
    for ``other``) lives: the two share what is assembled from the cell kernels alone
    (``discretisation._Shared``), as in a session that solved that size before."""
    alive = DirectSolver(other.structure, stages=stages, mesh=mesh_spec(other, nodes, stages))
    alive.solve(other)
    t, _ = median_time(lambda: DirectSolver(problem.structure, stages=stages, mesh=mesh_spec(
        problem, nodes, stages)).solve(problem), repeats, fresh=True)
    return t


def bvp_setting(problem, changed, tol, nodes, refs, repeats):
    try:
        t_cold, base = median_time(lambda: solve(problem, method="bvp", tol=tol, nodes=nodes),
                                   repeats)
        t_warm, warm = median_time(lambda: solve(changed, method="bvp", tol=tol, warm_start=base),
                                   repeats)
    except SolverError:
        return None
    return t_cold, t_warm, error(base, refs[0]), error(warm, refs[1])


def interleaved(problem, changed, direct: tuple, bvp: tuple, rounds: int) -> tuple[float, float]:
    """Medians over ``rounds`` of solve_bvp's time over the direct one's, cold and warm, each
    round timing both methods back to back (medians of 3 solves each).

    The chosen settings' medians are timed minutes apart, and the machine's speed
    drifts by 10-50 % in that time (measured); a round's timings share the drift.
    Each method's solves run in a block of their own, as in the medians (single
    solves in strict alternation put every direct warm solve right after a
    solve_bvp call: its warm ratios read 0.65-0.76 of the medians' in the same run),
    and cold direct solves with no solver of their size alive, as in the ratio's
    column (with one alive they read like "cold, size alive").
    """
    stages, nodes = direct
    tol, n0 = bvp

    def direct_cold():
        solver = DirectSolver(problem.structure, stages=stages,
                              mesh=mesh_spec(problem, nodes, stages))
        return solver, solver.solve(problem)

    bvp_base = solve(problem, method="bvp", tol=tol, nodes=n0)
    cold, warm = [], []
    for _ in range(rounds):
        t_direct, _ = median_time(direct_cold, 3, fresh=True)
        t_bvp, _ = median_time(lambda: solve(problem, method="bvp", tol=tol, nodes=n0), 3)
        cold.append(t_bvp / t_direct)
        solver, base = direct_cold()
        t_direct, _ = median_time(lambda: solver.solve(changed, warm_start=base), 3)
        t_bvp, _ = median_time(lambda: solve(changed, method="bvp", tol=tol,
                                             warm_start=bvp_base), 3)
        warm.append(t_bvp / t_direct)
        del solver, base
    return float(np.median(cold)), float(np.median(warm))


def cheapest(results: dict, target: float):
    ok = [(k, v) for k, v in results.items()
          if v is not None and v[2] <= target and v[3] <= target]
    return min(ok, key=lambda kv: kv[1][0] + kv[1][1]) if ok else (None, None)


def matched_accuracy(quick: bool) -> None:
    repeats = 3 if quick else 7
    print(f"Matched accuracy: cheapest setting meeting the edge-value target cold AND warm "
          f"(medians of {repeats}); {load()}")
    print(f"{'problem, target':>28} | {'direct':>12} {'cold ms':>8} {'warm ms':>8} | "
          f"{'solve_bvp':>16} {'cold ms':>8} {'warm ms':>8} | {'ratio cold':>10} {'warm':>6} | "
          f"{'paired cold':>11} {'warm':>6} | {'cold, size alive':>16}")
    misses = []
    for label, problem, changed in rows():
        refs = [reference(p) for p in (problem, changed)]
        clear_cache()      # (solve()'s cache would keep the references' solvers alive)
        direct, bvp = {}, {}
        for stages in (2, 3):
            for n in LADDER:
                r = direct_setting(problem, changed, stages, n, [refs[0][0], refs[1][0]], repeats)
                direct[(stages, n)] = r
                if r is not None and max(r[2], r[3]) <= min(TARGETS) / 2:
                    break
        # (as many repeats as the direct settings: with 3, the cheapest BVP setting of a row
        # changed from run to run by noise alone, and with it the row's ratio)
        for tol in BVP_TOLS:
            for n in BVP_NODES:
                bvp[(tol, n)] = bvp_setting(problem, changed, tol, n, [refs[0][0], refs[1][0]],
                                            repeats)
        for target in TARGETS:
            (dk, dv), (bk, bv) = cheapest(direct, target), cheapest(bvp, target)
            name = f"{label}, {target:.0e}"
            if dv is None or bv is None:
                print(f"{name:>28} | no setting met the target "
                      f"({'direct' if dv is None else 'BVP'})")
                continue
            rc, rw = bv[0] / dv[0], bv[1] / dv[1]
            pc, pw = interleaved(problem, changed, dk, bk, repeats)
            if pc < 3 or pw < 10:
                misses.append((name, pc, pw))
            shared = cold_with_size_alive(problem, changed, *dk, repeats)
            print(f"{name:>28} | {f'o{2 * dk[0]} N {dk[1]}':>12} {1e3 * dv[0]:8.2f} "
                  f"{1e3 * dv[1]:8.2f} | {f'tol {bk[0]:.0e} N0 {bk[1]}':>16} {1e3 * bv[0]:8.2f} "
                  f"{1e3 * bv[1]:8.2f} | {rc:10.1f} {rw:6.1f} | {pc:11.1f} {pw:6.1f} | "
                  f"{1e3 * shared:8.2f} ({bv[0] / shared:.1f}x)")
        print(f"{'':>28}   (reference cross-check: BVP tol 1e-8 differs by "
              f"{refs[0][1]:.1e} / {refs[1][1]:.1e})")
    print(f"targets (cold >= 3x, warm >= 10x faster than solve_bvp, paired ratios: the chosen "
          f"settings timed back to back, medians of {repeats} rounds): "
          f"{'all met' if not misses else 'missed on ' + str(len(misses)) + ' rows'}\n")


def warm_with_certificate(quick: bool) -> None:
    problem, _ = load_problem(example_path("toy3_anisotropic"))
    repeats = 5 if quick else 15
    print(f"Warm re-solve with the minimum certificate, toy 3, order 4 (medians of {repeats}, "
          f"after 2 untimed warm solves: the steady state of a fit or a continuation); {load()}")
    print(f"{'N':>6} {'unknowns':>9} {'whole ms':>9} {'CPU ms':>7} {'solver ms':>9} {'rest ms':>8} "
          f"{'iters':>5} {'certificate':>30} {'target ms':>9}")
    # "solver ms": the back end's own time (Newton's steps and factorisations,
    # or the Ipopt call); "rest": parameter data and the Equilibrium's fields
    for n, target in ((200, 2.0), (3200, 30.0)):
        solver = DirectSolver(problem.structure, n)
        base = solver.solve(problem)
        # The first warm solve has no factorisation to take a chord step with,
        # and the first calls of each function fill its work memory (measured
        # at 3200: 33-34 ms for the first two, 26-28 ms after)
        for f in (0.995, 0.997):
            solver.solve(problem.with_updates(f0=problem.params["f0"] * f), warm_start=base)
        times, cpu, ipopt, iters, how = [], [], [], [], set()
        for i in range(repeats):
            changed = problem.with_updates(f0=problem.params["f0"] * (1 + 0.01 * (i + 1) / repeats))
            t0, c0 = time.perf_counter(), time.process_time()
            eq = solver.solve(changed, warm_start=base)
            times.append(time.perf_counter() - t0)
            cpu.append(time.process_time() - c0)
            ipopt.append(eq.solver.seconds)
            iters.append(eq.solver.iterations)
            how.add(eq.solver.details.get("stability"))
        w, ip = 1e3 * np.median(times), 1e3 * np.median(ipopt)
        print(f"{n:6d} {solver.disc.layout.size:9d} {w:9.2f} {1e3 * np.median(cpu):7.2f} "
              f"{ip:9.2f} {w - ip:8.2f} {int(np.median(iters)):5d} {','.join(sorted(how)):>30} "
              f"{target:9.1f}"
              f"{'' if w <= target else f'  missed by {w / target:.1f}x'}")
    print()


def build_scaling(quick: bool) -> None:
    problem, _ = load_problem(example_path("toy3_anisotropic"))
    meshes = (200, 800, 3200) if quick else (200, 800, 3200, 12800)
    print(f"Build and solve against N, toy 3, order 4 (median of 3 builds, each with no solver of "
          f"that size alive); {load()}")
    print(f"{'N':>6} {'unknowns':>9} {'build ms':>9} {'build CPU':>9} {'cold solve ms':>13} "
          f"{'warm ms':>8} {'warm us/unknown':>15}")
    builds = []
    for n in meshes:
        cpu = []

        def build():
            c0 = time.process_time()
            solver = DirectSolver(problem.structure, n)
            cpu.append(time.process_time() - c0)
            return solver
        t_build, solver = median_time(build, 3, fresh=True)
        c_build = float(np.median(cpu))
        t_cold, base = median_time(lambda: solver.solve(problem), 1)
        t_warm, _ = median_time(lambda: solver.solve(problem.with_updates(
            f0=1.01 * problem.params["f0"]), warm_start=base), 3)
        builds.append(t_build)
        print(f"{n:6d} {solver.disc.layout.size:9d} {1e3 * t_build:9.1f} {1e3 * c_build:9.1f} "
              f"{1e3 * t_cold:13.1f} "
              f"{1e3 * t_warm:8.2f} {1e6 * t_warm / solver.disc.layout.size:15.2f}")
    print(f"build N = {meshes[-1]} / N = {meshes[0]}: {builds[-1] / builds[0]:.1f}x "
          f"(target <= 2x); kernels: {solver.disc.kernels}\n")


def large_meshes(quick: bool) -> None:
    """Time against N up to 10^5 nodes (issue 11: linear in N): one build and solve each,
    with the C library's default allocator, then with large blocks kept in the heap
    (:func:`morphoshell.keep_large_blocks`, as the command line does)."""
    from morphoshell import keep_large_blocks

    _large_meshes(quick, "default allocator")
    if keep_large_blocks():
        _large_meshes(quick, "keep_large_blocks() (as the command line)")
    print("  target: time linear in N up to 10^5 nodes\n")


def _large_meshes(quick: bool, allocator: str) -> None:
    import resource

    problem, _ = load_problem(example_path("toy3_anisotropic"))
    changed = problem.with_updates(f0=1.01 * problem.params["f0"])
    meshes = (12800, 25600, 51200) if quick else (12800, 25600, 51200, 102400)
    print(f"Large meshes, toy 3, order 4, {allocator} (one run each; the slope is "
          f"d log t / d log N against the row above, 1 = linear); {load()}")
    print(f"{'N':>7} {'unknowns':>9} {'build s':>8} {'slope':>5} {'cold s':>7} {'slope':>5} "
          f"{'warm s':>7} {'slope':>5} {'warm us/unknown':>15} {'peak RSS GB':>11}")
    prev = None
    for n in meshes:
        t0 = time.perf_counter()
        solver = DirectSolver(problem.structure, n)
        t_build = time.perf_counter() - t0
        t_cold, base = median_time(lambda: solver.solve(problem), 1)
        solver.solve(changed, warm_start=base)          # builds the Newton back end
        t_warm, _ = median_time(lambda: solver.solve(changed, warm_start=base), 3)
        row = np.array([t_build, t_cold, t_warm])
        slopes = (np.log(row / prev[1]) / np.log(n / prev[0]) if prev is not None
                  else np.full(3, np.nan))
        rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e6     # kB on Linux
        print(f"{n:7d} {solver.disc.layout.size:9d} {t_build:8.2f} {slopes[0]:5.2f} "
              f"{t_cold:7.2f} {slopes[1]:5.2f} {t_warm:7.3f} {slopes[2]:5.2f} "
              f"{1e6 * t_warm / solver.disc.layout.size:15.2f} {rss:11.1f}")
        prev = (n, row)
        del solver, base


def fresh_process(quick: bool) -> None:
    repeats = 3 if quick else 5
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT / "src"), env.get("PYTHONPATH", "")])
    # Bytecode cached as on an installed package (pip compiles it; an
    # environment with PYTHONDONTWRITEBYTECODE set would recompile every
    # module in every process: 60-100 ms), kept out of the source tree.
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    cases = {"python -c pass": [sys.executable, "-c", "pass"],
             # the floor of any solve: the two libraries every direct solve needs
             "import numpy, casadi": [sys.executable, "-c", "import numpy, casadi"],
             "import morphoshell.cli": [sys.executable, "-c", "import morphoshell.cli"],
             "morphoshell solve toy2_ablation.toml": [
                 sys.executable, "-m", "morphoshell.cli", "solve",
                 str(ROOT / "problems" / "toy2_ablation.toml")]}
    print(f"Fresh process (median of {repeats}, compiled kernels and bytecode cached); {load()}")
    with tempfile.TemporaryDirectory(prefix="morphoshell-pycache-") as pycache:
        env["PYTHONPYCACHEPREFIX"] = pycache
        for label, cmd in cases.items():
            subprocess.run(cmd, env=env, check=True, stdout=subprocess.DEVNULL)  # writes bytecode
            t, _ = median_time(lambda: subprocess.run(cmd, env=env, check=True,
                                                      stdout=subprocess.DEVNULL), repeats)
            print(f"  {label:40s} {1e3 * t:8.0f} ms")
    print("  target: first solve <= 200 ms\n")


def binding_costs(quick: bool) -> None:
    """What a build's CasADi operations cost in Python, whatever their size (issue 11's
    flat build and cold 3x: a cold solve at 25 nodes makes about a hundred of them)."""
    import casadi as ca
    repeats = 500 if quick else 3000
    p = ca.MX.sym("p", 5)
    h, b = p[1], p[2]
    v, M = ca.MX.sym("v", 300), ca.MX.sym("M", 10, 30)
    idx = list(range(0, 300, 2))
    f = ca.Function("f", [v], [2 * v])
    x, y = ca.SX.sym("x"), ca.SX.sym("y")
    d = ca.DM(2.0)
    dense = np.random.default_rng(0).random(10000)
    cases = {
        "h * b (MX, generic operator)": lambda: h * b,
        "ca.MX.binary(OP_MUL, h, b) (typed)": lambda: ca.MX.binary(ca.OP_MUL, h, b),
        "x * y (SX, generic)": lambda: x * y,
        "d * d (DM, generic)": lambda: d * d,
        "ca.sin(h) (generic)": lambda: ca.sin(h),
        "ca.MX.unary(OP_SIN, h) (typed)": lambda: ca.MX.unary(ca.OP_SIN, h),
        "ca.vec(M)": lambda: ca.vec(M),
        "ca.vertcat(v, v)": lambda: ca.vertcat(v, v),
        "v[list of 150]": lambda: v[idx],
        "v[0:300:2] (slice)": lambda: v[0:300:2],
        "f(v) (symbolic call)": lambda: f(v),
        "ca.DM(ndarray of 10 000) / 10 000": lambda: ca.DM(dense),
        "ca.DM(list of 10 000) / 10 000": lambda: ca.DM(dense.tolist()),
    }
    print(f"CasADi's Python binding: microseconds per operation built (median of 5 runs of "
          f"{repeats}); {load()}")
    for label, fn in cases.items():
        runs = []
        for _ in range(5):
            t0 = time.perf_counter()
            for _ in range(repeats):
                fn()
            runs.append((time.perf_counter() - t0) / repeats)
        per = 1e6 * float(np.median(runs))
        if label.endswith("/ 10 000"):
            print(f"  {label[:-9]:44s} {1e3 * per / 10000:8.1f} ns an entry")
        else:
            print(f"  {label:44s} {per:8.1f} us")
    print()


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true",
                        help="fewer repeats, no N = 12800 build")
    parser.add_argument("--only", choices=("matched", "warm", "build", "fresh", "binding",
                                           "large"),
                        default=None)
    parser.add_argument("--large", action="store_true",
                        help="also time meshes of 12 800 to 102 400 nodes, with the default "
                             "allocator and with large blocks kept (about 3 minutes, 5 GB)")
    args = parser.parse_args(argv)
    print(f"{datetime.date.today()}, {platform.node()}, {platform.processor() or platform.machine()}"
          f", Python {platform.python_version()}\n")
    parts = {"fresh": fresh_process, "warm": warm_with_certificate, "build": build_scaling,
             "binding": binding_costs, "matched": matched_accuracy, "large": large_meshes}
    for name, fn in parts.items():
        if args.only == name or args.only is None and (name != "large" or args.large):
            fn(args.quick)
    return 0


if __name__ == "__main__":
    sys.exit(main())
