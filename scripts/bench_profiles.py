#!/usr/bin/env python3
"""Benchmark of profile intervals: one parameter's 20-point profile at one synthetic timepoint.

The ``free`` Volvox fit (13 parameters) of the SYNTHETIC average midline of
``data/synthetic_inversion/<timepoint>`` (made by
scripts/make_synthetic_inversion.py), started from the generating parameters,
by the gradient method at ``--nodes``; then the profile of each of
``--names`` (``morphoshell.fitting.profile``, ``--points`` refits, gradient
method).  Prints the fit's time, each profile's time, refits, interval and
σ² source, and the load average (other processes on the cores slow both).
Target (issue 39): a 20-point profile under 10 s on 2 cores.

Usage: python scripts/bench_profiles.py [--timepoint t05] [--nodes 100 200]
       [--names kappa1 f1] [--points 20] [--method gradient] [--json out/bench_profiles.json]
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

from morphoshell import Problem
from morphoshell.fitting import fit, profile, volvox_spec
from morphoshell.io import Midline

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "data" / "synthetic_inversion"


def start_problem(timepoint: str) -> Problem:
    """The generating parameters of a synthetic timepoint (the fit's start)."""
    truth = json.loads((DATA / "synthetic_inversion.json").read_text(encoding="utf-8"))
    p = dict(next(t for t in truth["timepoints"] if t["timepoint"] == timepoint)["parameters"])
    h, opening = p.pop("h"), p.pop("opening")
    return Problem("volvox", p, h=h, opening=opening)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--timepoint", default="t05")
    parser.add_argument("--nodes", type=int, nargs="+", default=[100, 200])
    parser.add_argument("--names", nargs="+", default=["kappa1", "f1"])
    parser.add_argument("--points", type=int, default=20)
    parser.add_argument("--method", default="gradient", choices=["gradient", "kkt"])
    parser.add_argument("--json", type=Path, default=None)
    args = parser.parse_args(argv)
    data = Midline.from_csv(DATA / args.timepoint / "synthetic_average.csv")
    spec = volvox_spec("free", start_problem(args.timepoint))
    rows = []
    print(f"# SYNTHETIC {args.timepoint} (scripts/bench_profiles.py), free variant, "
          f"{args.points}-point profiles by {args.method}; load average "
          f"{os.getloadavg()[0]:.2f} on {os.cpu_count()} cores")
    for nodes in args.nodes:
        t0 = time.perf_counter()
        result = fit(spec, data, "gradient", nodes=nodes)
        t_fit = time.perf_counter() - t0
        print(f"nodes {nodes}: gradient fit {t_fit:.2f} s ({result.inner_solves} inner solves), "
              f"E_fit {result.E_fit:.4g} R")
        for name in args.names:
            for noise in ("residual", "traces"):
                t0 = time.perf_counter()
                p = profile(spec, data, name, result=result, points=args.points,
                            method=args.method, nodes=nodes, noise=noise)
                seconds = time.perf_counter() - t0
                se = result.standard_errors[name]
                lo, hi = p.interval
                print(f"  {name:7s} {noise:8s} {seconds:6.2f} s, {len(p.values) - 1} refits "
                      f"({int(sum(p.converged)) - 1} converged): [{lo:.5g}, {hi:.5g}] around "
                      f"{p.fitted_value:.5g}; GN +-1.96 SE: +-{1.96 * se:.3g}; sigma^2 "
                      f"{p.sigma2:.3g} R^2{'; ' + p.note if p.note else ''}")
                rows.append({"nodes": nodes, "fit_seconds": t_fit, "name": name, "noise": noise,
                             "seconds": seconds, "refits": len(p.values) - 1,
                             "interval": [lo, hi], "fitted": p.fitted_value, "gn_se": se,
                             "sigma2": p.sigma2, "load": os.getloadavg()[0]})
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps({"label": "SYNTHETIC (scripts/bench_profiles.py)",
                                         "args": {**vars(args), "json": str(args.json)},
                                         "rows": rows}, indent=1) + "\n", encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
