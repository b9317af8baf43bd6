#!/usr/bin/env python3
"""Do 95 % profile intervals cover the truth 95 % of the time?  Coverage on SYNTHETIC replicates.

For one timepoint of the synthetic inversion sequence this script makes
``--replicates`` new data sets with the generator of ``data/synthetic_inversion``
(``scripts/make_synthetic_inversion.py``: the same trajectory and microscope,
``--embryos`` whole-section image traces with Gaussian pixel noise of
NOISE_PX = 0.5 px, each aligned and resampled, then averaged; seeds
``--seed`` + 0, 1, ...), fits each average (variant ``free``, gradient method,
``--nodes``, from the generating parameters) and profiles κ₁ and f₁
(``morphoshell.fitting.profile_intervals``, ``--points`` refits each).  Each
profile is thresholded with σ² from the traces' spread and, on the same
objective (:meth:`Profile.rethreshold`), from the fit's residual.  It reports
the fraction of replicates whose interval contains the generating value, with
a Clopper–Pearson 95 % interval of that fraction, for

* the profile interval, σ² from the traces (``profile/traces``: the threshold's
  quantile F(1, n − 1), the library's default for σ² from n traces);
* the same profile with the χ²₁ quantile, as if σ² were known
  (``profile/traces, chi2``: what the library did before);
* the profile interval, σ² from the residual (``profile/residual``);
* the Gauss–Newton interval ±1.96 SE (``GN``);

and the median width of each.  Everything is synthetic; the data sets and
``coverage.json`` (the options, the seeds and every interval) go under
``--work``.

Usage: python scripts/check_profile_coverage.py [--timepoint t05] [--replicates 40]
       [--embryos 5] [--seed 3000] [--nodes 100] [--points 20] [--workers 2]
       [--work out/check_profile_coverage]
"""
from __future__ import annotations

import argparse
import json
import shutil
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "scripts"))

import make_synthetic_inversion as synthetic  # noqa: E402
from morphoshell.workflows.executor import open_executor, run  # noqa: E402

NAMES = ("kappa1", "f1")
LABEL = "SYNTHETIC replicates (scripts/check_profile_coverage.py)"


def replicate(task: tuple) -> dict:
    """One data set made, fitted and profiled: every interval and the truth."""
    from morphoshell import Problem
    from morphoshell.fitting import fit, profile_intervals, volvox_spec
    from morphoshell.io import Midline

    pseudotime, seed, embryos, nodes, points, folder = task
    folder = Path(folder)
    shutil.rmtree(folder, ignore_errors=True)
    made = synthetic.make(folder, pseudotimes=[pseudotime], embryos=embryos, seed=seed,
                          quiet=True)["timepoints"][0]
    truth = dict(made["parameters"])
    data = Midline.from_csv(folder / made["average"])
    h, opening = truth.pop("h"), truth.pop("opening")
    spec = volvox_spec("free", Problem("volvox", truth, h=h, opening=opening))
    t0 = time.perf_counter()
    try:
        result = fit(spec, data, "gradient", nodes=nodes)
        profiles = profile_intervals(spec, data, NAMES, result=result, points=points,
                                     nodes=nodes, noise="traces")
    except Exception as exc:          # (a replicate that fails is counted, not fatal)
        return {"seed": seed, "status": "failed", "message": f"{type(exc).__name__}: {exc}"}
    n, k = len(data.r), len(spec.fitted)
    residual = result.E_fit ** 2 / (2 * n - k)
    out = {"seed": seed, "status": "ok", "converged": result.converged,
           "E_fit": result.E_fit, "seconds": time.perf_counter() - t0,
           "sigma2_traces": next(iter(profiles.values())).sigma2, "sigma2_residual": residual,
           "constrained": list(result.constrained), "parameters": {}}
    for name, p in profiles.items():
        se = result.standard_errors[name]
        value = result.parameters[name]
        out["parameters"][name] = {
            "truth": truth[name], "estimate": value, "gn_se": se,
            "GN": [value - 1.96 * se, value + 1.96 * se],
            "profile/traces": list(p.interval),
            "profile/traces, chi2": list(p.rethreshold(p.sigma2, "traces").interval),
            "profile/residual": list(p.rethreshold(residual, "residual").interval),
            "refits_converged": int(p.converged.sum()) - 1, "refits": len(p.values) - 1,
            "note": p.note}
    return out


def clopper_pearson(k: int, n: int, level: float = 0.95) -> tuple[float, float]:
    """The exact binomial interval of a proportion k/n."""
    from scipy.stats import beta
    a = (1 - level) / 2
    lo = 0.0 if k == 0 else float(beta.ppf(a, k, n - k + 1))
    hi = 1.0 if k == n else float(beta.ppf(1 - a, k + 1, n - k))
    return lo, hi


def table(runs: list[dict]) -> list[str]:
    """The coverage table (markdown) over the replicates that fitted."""
    ok = [r for r in runs if r["status"] == "ok"]
    lines = ["| parameter | interval | coverage | 95 % CI of the coverage | median width | open |",
             "|---|---|---|---|---|---|"]
    for name in NAMES:
        for kind in ("profile/traces", "profile/traces, chi2", "profile/residual", "GN"):
            hits, widths, open_ = 0, [], 0
            for r in ok:
                par = r["parameters"][name]
                lo, hi = par[kind]
                lo = -np.inf if lo is None or not np.isfinite(lo) else lo
                hi = np.inf if hi is None or not np.isfinite(hi) else hi
                hits += bool(lo <= par["truth"] <= hi)
                open_ += not (np.isfinite(lo) and np.isfinite(hi))
                widths.append(hi - lo)
            c_lo, c_hi = clopper_pearson(hits, len(ok))
            lines.append(f"| {name} | {kind} | {hits}/{len(ok)} = {hits / len(ok):.2f} | "
                         f"{c_lo:.2f}–{c_hi:.2f} | {np.median(widths):.3g} | {open_} |")
    return lines


def main(argv=None) -> int:
    """Make, fit and profile the replicates; print and save the table."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--timepoint", default="t05")
    p.add_argument("--replicates", type=int, default=40)
    p.add_argument("--embryos", type=int, default=5)
    p.add_argument("--seed", type=int, default=3000)
    p.add_argument("--nodes", type=int, default=100)
    p.add_argument("--points", type=int, default=20)
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--work", type=Path, default=Path("out/check_profile_coverage"))
    args = p.parse_args(argv)
    times = synthetic.shipped_pseudotimes()
    if args.timepoint not in times or args.replicates < 2:
        print(f"check_profile_coverage: timepoint {args.timepoint!r} not in {sorted(times)}, "
              f"or fewer than 2 replicates", file=sys.stderr)
        return 2
    args.work.mkdir(parents=True, exist_ok=True)
    tasks = [(times[args.timepoint], args.seed + k, args.embryos, args.nodes, args.points,
              str((args.work / f"{args.timepoint}_{k:03d}").resolve()))
             for k in range(args.replicates)]
    runs: list = [None] * len(tasks)
    t0 = time.perf_counter()
    with open_executor(args.workers) as executor:     # (single-threaded workers: MUMPS)
        for i, r in run(replicate, tasks, executor, description="replicates"):
            runs[i] = r
    ok = [r for r in runs if r["status"] == "ok"]
    header = (f"# {LABEL}: {args.timepoint} (t = {times[args.timepoint]:.4g}), "
              f"{len(ok)} of {args.replicates} replicates fitted, {args.embryos} traces each "
              f"(0.5 px noise), seeds {args.seed}..{args.seed + args.replicates - 1}, free "
              f"variant, gradient, {args.nodes} nodes, {args.points}-point profiles; "
              f"{time.perf_counter() - t0:.0f} s on {args.workers} workers")
    ratio = np.median([r["sigma2_traces"] / r["sigma2_residual"] for r in ok])
    lines = [header, "", *table(runs), "",
             f"median sigma^2 from the traces / from the residual: {ratio:.2f}; "
             f"converged fits: {sum(r['converged'] for r in ok)}/{len(ok)}; fits on a "
             f"constraint: {sum(bool(r['constrained']) for r in ok)}"]
    print("\n".join(lines))
    (args.work / "coverage.json").write_text(json.dumps(
        {"label": LABEL, "args": {**vars(args), "work": str(args.work)}, "table": lines,
         "replicates": runs}, indent=1) + "\n", encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
