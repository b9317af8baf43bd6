#!/usr/bin/env python3
"""Timing of the full synthetic fit campaign (≥ 10 timepoints × 4 variants) on 1 and 2 workers.

Target of the issue: the whole synthetic campaign (data/synthetic_inversion:
12 timepoints × 4 variants = 48 fits) with the KKT method in under 5 minutes
on 2 cores.  Each row runs the campaign from scratch (``resume=False``) into
its own folder and reports the wall time (workers' start-up included), the
mean time per fit (summed fit times / fits: what one fit costs in a worker),
the failed fits, the speed-up over the first row's worker count, and the
achieved parallelism (summed fit time / wall time).  A campaign has one task per
variant, so more workers than variants do not help; with 4 variants on 2
workers the slowest pair of variants sets the wall time.  The machine's
load average is printed: the wall time depends on what else runs.

Usage: python scripts/bench_campaign.py [--method kkt] [--workers 1,2] [--nodes 200]
                                        [--data data/synthetic_inversion] [--out out/bench_campaign]
"""
from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from morphoshell.workflows import campaign
from morphoshell.fitting import METHODS

ROOT = Path(__file__).resolve().parents[1]


def main(argv=None) -> int:
    """Run the campaign once per worker count and print the table."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--method", choices=METHODS, default="kkt")
    p.add_argument("--workers", default="1,2", help="comma-separated worker counts")
    p.add_argument("--nodes", type=int, default=200)
    p.add_argument("--data", type=Path, default=ROOT / "data" / "synthetic_inversion")
    p.add_argument("--out", type=Path, default=Path("out/bench_campaign"))
    p.add_argument("--timepoints", default=None,
                   help="comma-separated timepoint names (default: all; a shorter benchmark)")
    args = p.parse_args(argv)
    rows = []
    for w in (int(v) for v in args.workers.split(",")):
        result = campaign(args.data, method=args.method, workers=w, nodes=args.nodes,
                          out=args.out / f"{args.method}_{w}", resume=False,
                          timepoints=args.timepoints)
        t = result.timing
        failed = sum(r["status"] != "ok" for r in result.records.values())
        rows.append((w, t["backend"], t["computed"], failed, t["fit_seconds"] / t["computed"],
                     t["seconds"]))
    base = rows[0][5]
    print(f"campaign of {len(result.timepoints)} timepoints x {len(result.variants)} variants, "
          f"method {args.method}, {args.nodes} nodes; load average "
          f"{', '.join(f'{v:.2f}' for v in os.getloadavg())}")
    # parallelism: summed fit time / wall time (what the workers achieved
    # against running the same fits one after the other in one process)
    print(f"{'workers':>7} {'backend':>8} {'fits':>5} {'failed':>6} {'s/fit':>7} "
          f"{'total s':>8} {'speed-up':>8} {'fit-s/wall':>10}")
    for w, backend, n, failed, per, total in rows:
        print(f"{w:7d} {backend:>8} {n:5d} {failed:6d} {per:7.2f} {total:8.1f} "
              f"{base / total:8.2f} {per * n / total:10.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
