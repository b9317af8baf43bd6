#!/usr/bin/env python3
"""Benchmark of the KKT fit against the gradient fit, timed in the same run, fit by fit.

The 13-parameter ``free`` Volvox fit at 200 mesh nodes (``--nodes``) of

* the synthetic inversion's averages (``data/synthetic_inversion/tNN/synthetic_average.csv``,
  residuals of a few 1e-3 R), cold (from the family's defaults) and warm (a campaign
  step: from the previous timepoint's gradient fit, its parameters and its state carried
  onto the new mesh, as ``morphoshell campaign`` starts them);
* a pixel trace: the forward model's midline at the synthetic sequence's first keyframe
  (400 points), scaled to 160 px/R, rounded to whole pixels (a Fiji XY export's
  quantisation) and read back through the trace reader (header ``x,y``); residuals of
  ~1e-4 R.  Cold, and warm from the first timepoint's fit.

Each case is fitted ``--repeats`` times by both methods, alternating, after one untimed
fit of each (the compiled kernels load once per process).  The table gives medians of the
seconds, the median of the per-repeat ratios kkt/gradient (the two fits of a repeat run
back to back, under the same load), the E_fit of both and their relative difference.

Usage: python scripts/bench_kkt.py [--repeats 3] [--nodes 200] [--timepoints t01 t02 t03 t04]
       [--no-pixel] [--json out/bench_kkt.json]
"""
from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from morphoshell import Problem
from morphoshell.fitting import fit, synthetic_midline, volvox_spec
from morphoshell.io.midlines import load_midline
from morphoshell.io.problem_files import write_json
from morphoshell.io.traces import to_image
from morphoshell.numerics.mesh import mesh_spec
from morphoshell.solvers.direct import DirectSolver
from morphoshell.solvers.refinement import solve_from
from morphoshell.workflows.timepoint_fits import first_start

ROOT = Path(__file__).resolve().parent.parent
DATA = ROOT / "data" / "synthetic_inversion"
#: The synthetic sequence's first keyframe (data/synthetic_inversion/synthetic_inversion.json).
KEYFRAME = Problem("volvox", {"f1": 0.8, "kappa3": 1.0, "kappa4": 1.0, "f2": 1.0, "f3": 1.1,
                              "f4": 1.0, "f5": 1.15, "kappa2": -7.0, "s1": 1.3, "s2": 1.65,
                              "s3": 1.95, "s4": 2.35}, h=0.15, opening=0.3)
#: Pixels per R of the pixel trace (the issue's Fiji export).
PIXELS_PER_R = 160.0


def pixel_trace(folder: Path) -> np.ndarray:
    """The keyframe's midline as a whole-section trace in whole pixels, read back (100 points)."""
    points = synthetic_midline(KEYFRAME, nodes=400, n=400)
    pixels = np.round(to_image(points, radius_px=PIXELS_PER_R, offset_px=(400.0, 400.0)))
    path = folder / "keyframe_160px.csv"
    path.write_text("x,y\n" + "".join(f"{x:.0f},{y:.0f}\n" for x, y in pixels), encoding="utf-8")
    return load_midline(path, pixel_size_um=1.0, radius_um=PIXELS_PER_R).points


def warm_start(previous, nodes: int) -> tuple:
    """(spec, start state) of a campaign step from the fit ``previous``."""
    spec = volvox_spec("free", start=first_start(previous.parameters))
    solver = DirectSolver(spec.base.structure, mesh=mesh_spec(spec.base, nodes, 2))
    return spec, solve_from(solver, spec.base, previous.equilibrium)


def cases(args, folder: Path) -> list[tuple[str, np.ndarray, object, object]]:
    """(name, data, spec, start) of every case; warm starts from gradient fits (untimed)."""
    out, previous = [], None
    for tp in args.timepoints:
        data = load_midline(DATA / tp / "synthetic_average.csv").points
        out.append((f"{tp} cold", data, volvox_spec("free"), None))
        if previous is not None:
            out.append((f"{tp} warm", data, *warm_start(previous, args.nodes)))
        previous = fit(volvox_spec("free"), data, "gradient", nodes=args.nodes)
        if tp == args.timepoints[0]:
            first = previous
    if args.pixel:
        data = pixel_trace(folder)
        out.append(("160 px/R cold", data, volvox_spec("free"), None))
        out.append((f"160 px/R warm from {args.timepoints[0]}", data,
                    *warm_start(first, args.nodes)))
    return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--nodes", type=int, default=200)
    parser.add_argument("--timepoints", nargs="+", default=["t01", "t02", "t03", "t04"])
    parser.add_argument("--no-pixel", dest="pixel", action="store_false",
                        help="leave out the pixel-trace case")
    parser.add_argument("--json", default=None, help="also write the table as JSON")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        todo = cases(args, Path(tmp))
    first = todo[0]
    for method in ("gradient", "kkt"):           # untimed: kernels load once per process
        fit(first[2], first[1], method, nodes=args.nodes, start=first[3])
    rows = []
    for name, data, spec, start in todo:
        runs = {"gradient": [], "kkt": []}
        for _ in range(args.repeats):
            for method in runs:
                t0 = time.perf_counter()
                try:
                    r = fit(spec, data, method, nodes=args.nodes, start=start)
                    runs[method].append((time.perf_counter() - t0, r.E_fit, r.converged,
                                         r.outer_iterations))
                except Exception as exc:          # a failed fit is a row, not the end
                    runs[method].append((time.perf_counter() - t0, float("nan"), False,
                                         f"{type(exc).__name__}: {exc}"[:80]))
        g, k = runs["gradient"], runs["kkt"]
        row = {"case": name, "load": os.getloadavg()[0],
               "gradient_s": statistics.median(s for s, *_ in g),
               "kkt_s": statistics.median(s for s, *_ in k),
               "ratio": statistics.median(b[0] / a[0] for a, b in zip(g, k)),
               "E_gradient": g[-1][1], "E_kkt": k[-1][1],
               "converged": all(r[2] for r in g + k), "iterations": [g[-1][3], k[-1][3]]}
        row["rel"] = (row["E_kkt"] - row["E_gradient"]) / row["E_gradient"]
        rows.append(row)
        print(f"{name:28s} gradient {row['gradient_s']:.2f} s  kkt {row['kkt_s']:.2f} s  "
              f"ratio {row['ratio']:.2f}  E_fit {row['E_gradient']:.9g} / {row['E_kkt']:.9g}",
              flush=True)
    print(f"\nbench_kkt: free variant, 13 parameters, {args.nodes} nodes, 100 points; medians of "
          f"{args.repeats}; {os.cpu_count()} cores, load average "
          f"{min(r['load'] for r in rows):.1f}-{max(r['load'] for r in rows):.1f}")
    print("| case | gradient s | kkt s | kkt/gradient | E_fit gradient (R) | E_fit kkt (R) "
          "| relative difference |")
    print("|---|---|---|---|---|---|---|")
    for r in rows:
        flag = "" if r["converged"] else " (not converged)"
        print(f"| {r['case']} | {r['gradient_s']:.2f} | {r['kkt_s']:.2f} | {r['ratio']:.2f}"
              f" | {r['E_gradient']:.6g} | {r['E_kkt']:.6g} | {r['rel']:+.1e}{flag} |")
    if args.json:
        write_json(args.json, {"rows": rows, "nodes": args.nodes, "repeats": args.repeats})
    return 0


if __name__ == "__main__":
    sys.exit(main())
