#!/usr/bin/env python3
"""Reproduce Fig. 2 J–K of the paper: k and E/μ estimated from ablation recoils.

J  the intrinsic curvature k of each embryo estimated from its cut opening o,
   rotation ϱ and displacement d: the paper's asymptotic formulas (open
   markers: leading order for o, the small-cut Kelvin forms for ϱ and d) and
   numerical inversion of toy problem 2 in the large-bending theory at the
   embryo's own h and Σ (filled); mean ± standard deviation of each (large
   markers), off-scale values and measures no k in [−1, 1] produces as arrows
   at the axis; the combined ⟨k⟩ from ϱ and d (dashed).  The paper plots
   K⟨R⟩ = k⟨R⟩/R; here k is in units of each embryo's own 1/R.
K  the initial recoil velocity V against its scaling H^{5/2}R^{−3/2}|1 − k|
   (main text, "Recoil velocity measurements…"), with the least-squares line
   through the origin, whose slope is ⟨E/μ⟩.

The default input is the SYNTHETIC table data/synthetic_ablations.csv (made by
scripts/make_synthetic_ablations.py; no measurement table is public); its
ground truth (sidecar JSON) is drawn as grey ticks.  Writes fig2_J, fig2_K and
fig2_JK (PNG and PDF), fig2jk_estimates.json and fig2jk_estimates.csv to --out.

Usage: python scripts/fig2jk_estimates.py [--input TABLE.csv] [--out out/figures] [-v | -q]

A progress bar over the embryos shows on a terminal; -q/--quiet hides it and
warnings, -v/--verbose adds notes.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from morphoshell._runtime.console import run_script
from morphoshell.plotting import (DOUBLE_COLUMN, SINGLE_COLUMN, figure_JK, new_axes,
                                  plot_k_estimates, plot_recoil_velocity, save)
from morphoshell.inverse import estimate
from morphoshell.io.problem_files import write_csv, write_json

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = Path(__file__).name
DEFAULT_INPUT = ROOT / "data" / "synthetic_ablations.csv"
FORMATS = ("png", "pdf")
#: Sizes (inches) of the single-panel files: J two journal columns wide, K one.
SIZES = {"J": (DOUBLE_COLUMN, 3.1), "K": (SINGLE_COLUMN, 3.0)}


def ground_truth(table: Path) -> dict[str, float] | None:
    """True k per embryo from a synthetic table's sidecar (``<stem>.json``), if any."""
    sidecar = table.with_suffix(".json")
    if not sidecar.exists():
        return None
    data = json.loads(sidecar.read_text())
    return {e["embryo"]: e["k"] for e in data.get("ground_truth", {}).get("embryos", [])} or None


def _save(fig, stem: Path) -> list[Path]:
    """300 dpi PNG and PDF (text editable: the paper style's TrueType fonts)."""
    return save(fig, stem, FORMATS, close=True)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--input", default=str(DEFAULT_INPUT),
                        help="measurement table (default: the SYNTHETIC "
                             "data/synthetic_ablations.csv)")
    parser.add_argument("--out", default="out/figures", help="output folder (default out/figures)")
    return run_script(parser, argv, _run)


def _run(args) -> int:
    table, out = Path(args.input), Path(args.out)
    t0 = time.perf_counter()
    result = estimate(table)
    t1 = time.perf_counter()
    print(result)
    truth = ground_truth(table)
    written = []
    for name, draw in (("J", lambda ax: plot_k_estimates(ax, result, truth)),
                       ("K", lambda ax: plot_recoil_velocity(ax, result))):
        ax = new_axes(SIZES[name])        # in the paper style: fonts >= 7 pt
        draw(ax)
        written += _save(ax.figure, out / f"fig2_{name}")
    written += _save(figure_JK(result, truth), out / "fig2_JK")
    written.append(write_json(out / "fig2jk_estimates.json",
                              {"script": SCRIPT, "input": str(table),
                               "synthetic": truth is not None, "true_k": truth,
                               **result.to_dict()}))
    written.append(write_csv(out / "fig2jk_estimates.csv", result.table()))
    for path in written:
        print(f"wrote {path}")
    print(f"{SCRIPT}: estimated in {t1 - t0:.1f} s, plotted in {time.perf_counter() - t1:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
