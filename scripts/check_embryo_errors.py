#!/usr/bin/env python3
"""Are the free fit's standard errors right?  Coverage over replicate synthetic data sets.

A standard error is right when intervals built from it contain the truth as
often as they claim.  For each chosen timepoint of the synthetic inversion
sequence this script makes ``--replicates`` new data sets with the generator
of ``data/synthetic_inversion`` (``scripts/make_synthetic_inversion.py``, the
same trajectory, microscope and noise; seeds ``--seed`` + 0, 1, ...), each of
``--embryos`` traces and their average, and fits each with the campaign
(``morphoshell.workflows.campaign``, variant ``free``, ``embryo_errors=True``,
starting from the generating parameters).  For every fitted parameter it
reports

* the spread of the estimates over the replicates (the error the standard
  errors should estimate) against the root mean square of each kind of
  standard error: Gauss–Newton from the fit to the average (``GN``) and the
  jackknife over the traces (``embryo``: the average fitted with each trace
  left out in turn);
* the coverage: the fraction of replicates whose interval contains the
  generating value, ±1.96 GN errors and ±t₀.₉₇₅(n − 1) embryo errors (95 %
  nominal; with 20 replicates a coverage below 0.85 is wrong at the 2 %
  level), over the replicates that have such an error: a parameter of a fit
  that ends on a constraint has none (``no error``: how many, per parameter).

Everything is synthetic; nothing is written outside ``--work``.

Usage: python scripts/check_embryo_errors.py [--timepoints t02,t05,t08] [--replicates 20]
       [--embryos 5] [--seed 1000] [--method gradient] [--workers 2]
       [--work out/check_embryo_errors]
"""
from __future__ import annotations

import argparse
import json
import shutil
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "scripts"))

import make_synthetic_inversion as synthetic  # noqa: E402
from morphoshell.workflows.executor import open_executor, run  # noqa: E402
from morphoshell.fitting import METHODS  # noqa: E402


def replicate(task: tuple) -> dict:
    """One data set of one timepoint, made and fitted; the estimates, errors and truth."""
    from morphoshell.workflows import campaign

    pseudotime, seed, embryos, method, nodes, folder = task
    folder = Path(folder)
    shutil.rmtree(folder, ignore_errors=True)
    truth = synthetic.make(folder / "data", pseudotimes=[pseudotime], embryos=embryos,
                           seed=seed, quiet=True)["timepoints"][0]["parameters"]
    result = campaign(folder / "data", ("free",), method=method, nodes=nodes, workers=1,
                      out=folder / "fits", resume=False, embryo_errors=True, start=truth)
    rec = next(iter(result.records.values()))
    if rec["status"] != "ok":
        return {"seed": seed, "status": rec["status"], "message": rec.get("message", "")}
    fits = rec.get("embryo_fits", [])
    return {"seed": seed, "status": "ok", "converged": rec["converged"], "truth": truth,
            "estimate": {n: rec["parameters"][n] for n in rec["standard_errors"]},
            "gn": rec["standard_errors"], "embryo": rec.get("embryo_standard_errors", {}),
            "t95": rec.get("embryo_t95", float("nan")),
            "traces_used": sum(f["status"] == "ok" and f["converged"] for f in fits),
            "continued": sum(bool(f.get("continued")) for f in fits)}


def _table(name: str, runs: list[dict], names: list[str]) -> list[str]:
    ok = [r for r in runs if r["status"] == "ok" and r["converged"] and r["embryo"]]
    lines = [f"{name}: {len(ok)} of {len(runs)} replicates fitted "
             f"({sum(r['continued'] for r in ok)} jackknife fits continued once)",
             f"{'parameter':>10} {'truth':>8} {'mean':>8} {'sd':>7} {'rms GN':>7} "
             f"{'rms emb':>7} {'cover GN':>8} {'cover emb':>9} {'no error':>8}"]
    for n in names:
        est = np.array([r["estimate"][n] for r in ok])
        truth = ok[0]["truth"][n]
        # (None: a fit pinned on a constraint has no error; coverage over those that have)
        gn = np.array([r["gn"][n] for r in ok], dtype=float)
        emb = np.array([r["embryo"][n] for r in ok], dtype=float)
        t95 = np.array([r["t95"] for r in ok])
        g, e = np.isfinite(gn), np.isfinite(emb)
        lines.append(f"{n:>10} {truth:8.4f} {est.mean():8.4f} {est.std(ddof=1):7.4f} "
                     f"{np.sqrt(np.mean(gn[g] ** 2)):7.4f} {np.sqrt(np.mean(emb[e] ** 2)):7.4f} "
                     f"{np.mean(np.abs(est - truth)[g] <= 1.96 * gn[g]):8.2f} "
                     f"{np.mean(np.abs(est - truth)[e] <= t95[e] * emb[e]):9.2f} "
                     f"{int(np.sum(~e)):8d}")
    return lines


def main(argv=None) -> int:
    """Make and fit the replicates, print one table per timepoint, save the raw numbers."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--timepoints", default="t02,t05,t08",
                   help="names in data/synthetic_inversion (default t02,t05,t08)")
    p.add_argument("--replicates", type=int, default=20)
    p.add_argument("--embryos", type=int, default=5)
    p.add_argument("--seed", type=int, default=1000)
    p.add_argument("--method", choices=METHODS, default="gradient")
    p.add_argument("--nodes", type=int, default=200)
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--work", type=Path, default=Path("out/check_embryo_errors"))
    args = p.parse_args(argv)
    times = synthetic.shipped_pseudotimes()
    names = args.timepoints.split(",")
    unknown = [n for n in names if n not in times]
    if unknown or args.replicates < 2 or args.embryos < 2:
        print(f"check_embryo_errors: timepoints {unknown} not in {sorted(times)}" if unknown else
              "check_embryo_errors: need at least 2 replicates and 2 embryos", file=sys.stderr)
        return 2
    tasks = [(times[n], args.seed + k, args.embryos, args.method, args.nodes,
              str((args.work / f"{n}_{k:03d}").resolve()))
             for n in names for k in range(args.replicates)]
    results: list = [None] * len(tasks)
    with open_executor(args.workers) as executor:
        for i, r in run(replicate, tasks, executor, description="replicates"):
            results[i] = r
    (args.work / "replicates.json").write_text(json.dumps(
        {"label": "SYNTHETIC replicates (scripts/check_embryo_errors.py)", "args": vars(args) |
         {"work": str(args.work)}, "timepoints": names, "results": results}, indent=1) + "\n",
        encoding="utf-8")
    print(f"# {args.replicates} replicate data sets per timepoint, {args.embryos} embryos each, "
          f"seeds {args.seed}..{args.seed + args.replicates - 1}, method {args.method}, "
          f"{args.nodes} nodes; coverage of 95 % intervals")
    for j, n in enumerate(names):
        runs = results[j * args.replicates:(j + 1) * args.replicates]
        fitted = next((r for r in runs if r["status"] == "ok"), None)
        params = ["kappa1", "f1", "kappa2", "s1", "s2"] if fitted else []
        print("\n".join(_table(f"{n} (t = {times[n]:g})", runs, params)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
