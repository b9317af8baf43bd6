#!/usr/bin/env python3
"""Reproduce Fig. 3 D–O of the paper from the results of a fit campaign.

Panels (paper, main text "The fitted mechanical sequence hints at an adaptive
response to out-of-plane stresses", Fig. 3 caption; Materials and Methods
"Fitting the morphoelastic model"):

D–L  fits of the three fixed-κ₁ variants (columns: flat κ₁ = 0, undeformed
     κ₁ = 1, unstressed κ₁ = 1/f₁) at an early, a mid and a late timepoint
     (rows), each with its numerical ablation (pre-ablation light, post-
     ablation dark: continuation in Σ from 0 to :data:`CUT`) and an inset of
     the fitted midline (line) over the data (dots);
M    overlay of the pre- (red) and post-ablation (cyan) sheets of the early
     flat fit, their union white (as the micrographs of Fig. 1);
N    E_fit against pseudotime for the four variants;
O    fitted κ₁ of the free variant (95 % intervals) and 1/f₁ against
     pseudotime, with the generating κ₁(t) of a synthetic data set; inset f₁.

S2   with ``--held DIR`` (repeatable), campaigns run with ``--held-from
     VARIANT`` (paper, Supplementary Fig. S2, the test of the held values):
     E_fit against pseudotime of the fixed-κ₁ variants with their own f₁, κ₃,
     κ₄ (solid) and with each VARIANT's (dashed, dotted).

Writes fig3_D-L, fig3_M, fig3_N, fig3_O (and figS2_held) (PNG at 300 dpi and
PDF) and fig3_ablations.json (the observables of the numerical ablations) to
--out.

Usage: python scripts/fig3_fits.py --campaign out/campaign [--data data/synthetic_inversion]
       [--out out/figures] [--nodes 200] [--held out/campaign_held_flat ...]
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import matplotlib
import numpy as np
import scipy.stats

ROOT = Path(__file__).resolve().parents[1]
#: Cut Σ of the numerical ablations (units of R).
CUT = 0.15
FIXED = ("flat", "undeformed", "unstressed")
LABELS = {"flat": "κ₁ = 0", "undeformed": "κ₁ = 1", "unstressed": "κ₁ = 1/f₁",
          "free": "κ₁ fitted"}
COLORS = {"flat": "C0", "undeformed": "C1", "unstressed": "C2", "free": "k"}


def _stages(result) -> list:
    """Early, mid and late timepoints: first, middle and last of those fitted (a campaign
    of a few timepoints of a long sequence draws its own, not empty panels)."""
    fitted = {tp for tp, _ in result.records}
    tps = [tp for tp in result.timepoints if tp.name in fitted] or result.timepoints
    picked = [tps[0], tps[len(tps) // 2], tps[-1]]
    # (two fitted timepoints drew the last one twice, as a third "stage": one row each)
    return [tp for i, tp in enumerate(picked) if tp not in picked[:i]]


def _inset(ax, rec: dict, variant: str) -> None:
    """The inset of a Fig. 3 D–L panel: the data (grey points) and the fitted midline."""
    inset = ax.inset_axes(_free_box(ax))
    d, m = rec["data_midline"], rec["fitted_midline"]
    inset.plot(d["r"], d["z"], ".", ms=1.5, color="0.4")
    inset.plot(m["r"], m["z"], "-", lw=0.8, color=COLORS[variant])
    inset.set_aspect("equal")
    inset.set_xticks([])
    inset.set_yticks([])


#: Places of a D-L panel's inset (axes fractions): the four corners and the cavity between
#: the rims; the one the drawn shell crosses least is taken (one place covered the shell at
#: early stages, another the cut at late ones).
INSET_BOXES = ([0.68, 0.02, 0.3, 0.36], [0.02, 0.02, 0.3, 0.36], [0.38, 0.42, 0.24, 0.4],
               [0.68, 0.62, 0.3, 0.36], [0.02, 0.62, 0.3, 0.36])
#: A marker (the cut's rims) counts as this many of a line's points: never cover the cut.
MARKER_WEIGHT = 50


def _free_box(ax) -> list:
    """Of :data:`INSET_BOXES`, the box with the fewest points of ``ax``'s lines in it."""
    ax.get_xlim()       # (the pending autoscale applied: transLimits maps the drawn limits)
    parts = [(ax.transLimits.transform(line.get_xydata()),
              MARKER_WEIGHT if line.get_marker() not in ("None", "", None) else 1)
             for line in ax.get_lines()]

    def covered(box):
        x0, y0, w, h = box
        pad = 0.03
        return sum(weight * int(np.sum((p[:, 0] > x0 - pad) & (p[:, 0] < x0 + w + pad)
                                       & (p[:, 1] > y0 - pad) & (p[:, 1] < y0 + h + pad)))
                   for p, weight in parts)
    return min(INSET_BOXES, key=covered)


def _panels_DL(result, stages, nodes: int, out: Path):
    """Fig. 3 D–L: the fixed variants' fits at three stages, numerically ablated.

    Returns the ablations' observables by ``<timepoint>_<variant>`` and the first
    flat fit's (timepoint, ablation) for panel M (None if none).
    """
    import matplotlib.pyplot as plt

    from morphoshell.plotting import DOUBLE_COLUMN, label_panel, plot_ablation, save
    from morphoshell.workflows import (ablation_errors, fitted_problem, fitted_state,
                                       numerical_ablation)

    rows = len(stages)
    if rows < 3:
        print(f"fig3_D-L: {rows} fitted timepoint{'s' * (rows > 1)}, so {rows} row"
              f"{'s' * (rows > 1)} of the figure's 3 stages", file=sys.stderr)
    fig, axes = plt.subplots(rows, 3, figsize=(DOUBLE_COLUMN, DOUBLE_COLUMN * rows / 3),
                             layout="constrained", squeeze=False)
    letters = iter("DEFGHIJKL")
    ablations, first_flat = {}, None
    for i, tp in enumerate(stages):
        for j, v in enumerate(FIXED):
            ax = axes[i, j]
            label_panel(ax, next(letters))
            rec = result.records.get((tp.name, v))
            if rec is None or rec["status"] != "ok":
                ax.text(0.5, 0.5, "no fit", ha="center", transform=ax.transAxes)
                ax.set_axis_off()
                continue
            try:
                num = numerical_ablation(fitted_problem(rec), CUT, nodes=nodes,
                                         pre=fitted_state(rec))
            except Exception as exc:     # a figure with a gap beats no figure
                # (synthetic t07, flat: a 0.19 R misfit whose cut's continuation stops
                # at 18 % of Σ): the intact fit's midline, and the reason in the JSON
                ablations[f"{tp.name}_{v}"] = {"error": str(exc)}
                _intact(ax, tp, rec, v)
                continue
            if first_flat is None and v == "flat":
                first_flat = (tp, num)
            errors = ablation_errors(rec, num.ablation)
            ablations[f"{tp.name}_{v}"] = {**num.observables(), "steps": num.steps,
                                           "cold_difference": num.cold_difference,
                                           **{f"se_{k}": e for k, e in errors.items()}}
            plot_ablation(num.ablation, ax, title=None, legend=False)
            ax.set_title(f"{tp.name} (t = {tp.pseudotime:.2f}), {LABELS[v]}\n"
                         f"E_fit = {rec['E_fit']:.3g} R, o = {num.ablation.opening:.3g} R",
                         fontsize=7)
            _inset(ax, rec, v)
    save(fig, out / "fig3_D-L.png", ("png", "pdf"), close=True)
    return ablations, first_flat


def _intact(ax, tp, rec: dict, v: str) -> None:
    """A D–L panel whose numerical ablation failed: the intact fit's midline."""
    m = rec["fitted_midline"]
    for sign in (1, -1):
        ax.plot(sign * np.asarray(m["r"]), m["z"], "-", lw=1.2, color=COLORS[v])
    ax.set_aspect("equal")
    ax.set_xlabel("r/R")
    ax.set_ylabel("z/R")
    ax.set_title(f"{tp.name} (t = {tp.pseudotime:.2f}), {LABELS[v]}\n"
                 f"E_fit = {rec['E_fit']:.3g} R, numerical ablation failed", fontsize=7)
    _inset(ax, rec, v)


def _panel_M(first_flat, out: Path) -> None:
    """Fig. 3 M: the early flat fit's pre- and post-ablation sheets overlaid."""
    import matplotlib.pyplot as plt

    from morphoshell.plotting import SINGLE_COLUMN, label_panel, plot_ablation_overlay, save

    fig, ax = plt.subplots(figsize=(SINGLE_COLUMN, SINGLE_COLUMN), layout="constrained")
    tp, num = first_flat
    plot_ablation_overlay(num.ablation, ax, title=f"{tp.name}, κ₁ = 0: pre (red), "
                                                  f"post (cyan), union (white)")
    label_panel(ax, "M")
    save(fig, out / "fig3_M.png", ("png", "pdf"), close=True)


def _panel_N(df, variants, out: Path) -> None:
    """Fig. 3 N: E_fit against pseudotime for every variant."""
    import matplotlib.pyplot as plt

    from morphoshell.plotting import SINGLE_COLUMN, label_panel, save

    fig, ax = plt.subplots(figsize=(SINGLE_COLUMN, 0.75 * SINGLE_COLUMN), layout="constrained")
    for v in variants:
        sub = df[(df.variant == v) & (df.status == "ok")]
        ax.plot(sub.pseudotime, sub.E_fit, "o-", ms=3, color=COLORS[v], label=LABELS[v])
    ax.set_xlabel("pseudotime")
    ax.set_ylabel("E_fit / R")
    ax.set_yscale("log")
    ax.legend(fontsize=7)
    label_panel(ax, "N")
    save(fig, out / "fig3_N.png", ("png", "pdf"), close=True)


def _panel_O(df, truth: dict | None, out: Path) -> None:
    """Fig. 3 O: the free fit's κ₁ (95 % intervals) and 1/f₁, f₁ inset, the truth if known."""
    import matplotlib.pyplot as plt

    from morphoshell.plotting import SINGLE_COLUMN, label_panel, save

    fig, ax = plt.subplots(figsize=(SINGLE_COLUMN, 0.95 * SINGLE_COLUMN), layout="constrained")
    free = df[(df.variant == "free") & (df.status == "ok")]
    if len(free):
        _free_kappa1(ax, free)
    if truth is not None:       # over the fitted pseudotimes (a short campaign: not the rest)
        span = (free.pseudotime.min(), free.pseudotime.max()) if len(free) else (-np.inf, np.inf)
        points = [tp for tp in truth["timepoints"] if span[0] <= tp["pseudotime"] <= span[1]]
        ax.plot([tp["pseudotime"] for tp in points],
                [tp["parameters"]["kappa1"] for tp in points], ":", color="C3",
                label="generating κ₁ (synthetic)")
    ax.set_xlabel("pseudotime")
    ax.set_ylabel("κ₁ · R")
    # one column below the axes: two columns of these labels are wider than a column of a
    # journal page, and constrained layout then collapses the axes
    ax.legend(fontsize=6, loc="upper center", bbox_to_anchor=(0.5, -0.22), ncol=1, frameon=False)
    if len(free):
        inset = ax.inset_axes([0.62, 0.12, 0.35, 0.35])
        inset.plot(free.pseudotime, free.f1, "o-", ms=2, color="k")
        inset.set_title("f₁", fontsize=7)
        inset.tick_params(labelsize=6)
    label_panel(ax, "O")
    save(fig, out / "fig3_O.png", ("png", "pdf"), close=True)


def _free_kappa1(ax, free) -> None:
    """The free fits' κ₁ with 95 % intervals, the unconverged ones open, and 1/f₁."""
    # jackknife errors where the campaign computed them (--embryo-errors); the
    # Gauss-Newton ones are up to 4x too small (docs/campaigns.md, Standard errors)
    # bars: 95 % intervals, so that a miss of the generating kappa1 shows as one
    jack = "se_embryo_kappa1" in free and free.se_embryo_kappa1.notna().any()
    half = (free.se_embryo_kappa1 * free.embryo_t95 if jack
            else free.se_kappa1 * scipy.stats.norm.ppf(0.975))
    ok = free.converged.astype(bool)
    ax.plot(free.pseudotime, free.kappa1, "-", color="k", lw=0.8)
    ax.errorbar(free.pseudotime[ok], free.kappa1[ok], yerr=half[ok], fmt="o", ms=3,
                color="k", capsize=2, label="fitted κ₁ (free), 95 % interval "
                + ("(jackknife, Student's t)" if jack else "(Gauss–Newton, too narrow)"))
    if (~ok).any():
        ax.plot(free.pseudotime[~ok], free.kappa1[~ok], "o", ms=4, mfc="none",
                color="k", label="not converged")
    ax.plot(free.pseudotime, 1 / free.f1, "s--", ms=3, color="C2", label="1/f₁ (free)")


def _figure_S2(df, held: list, sources: list, out: Path) -> None:
    """Fig. S2: the fixed variants' E_fit with their own and others' held f₁, κ₃, κ₄."""
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D

    from morphoshell.plotting import SINGLE_COLUMN, save

    fig, ax = plt.subplots(figsize=(SINGLE_COLUMN, 0.95 * SINGLE_COLUMN), layout="constrained")
    # (data, marker, line style, whose f₁, κ₃, κ₄)
    runs = [(df, "o", "-", "own")] + [
        (h.to_dataframe(), marker, ls, source) for h, (marker, ls), source
        in zip(held, (("s", "--"), ("^", ":"), ("v", "-.")), sources)]
    for v in FIXED:
        for frame, marker, ls, what in runs:
            sub = frame[(frame.variant == v) & (frame.status == "ok")]
            if len(sub) and (what == "own" or v != what):
                ax.plot(sub.pseudotime, sub.E_fit, marker=marker, ls=ls, ms=3, color=COLORS[v])
    ax.set_xlabel("pseudotime")
    ax.set_ylabel("E_fit / R")
    ax.set_yscale("log")
    # two legends, outside the data: colour = hypothesis, line = whose f₁, κ₃, κ₄
    hypotheses = [Line2D([], [], color=COLORS[v], lw=2, label=LABELS[v]) for v in FIXED]
    held_by = [Line2D([], [], color="k", ls=ls, marker=marker, ms=3,
                      label="its own first fit" if what == "own" else f"{what}'s first fit")
               for _, marker, ls, what in runs]
    fig.legend(handles=hypotheses + held_by, loc="outside lower center", ncols=2,
               fontsize=6, title="hypothesis;  f₁, κ₃, κ₄ held from", title_fontsize=6)
    save(fig, out / "figS2_held.png", ("png", "pdf"), close=True)


def _campaigns(args):
    """The campaign, the held campaigns and whose first fit each held from (None: exit 2)."""
    from morphoshell.workflows import load_campaign

    result = load_campaign(args.campaign, args.data)
    held = [load_campaign(folder, args.data) for folder in args.held]
    for folder, res in ((args.campaign, result), *zip(args.held, held)):
        if not res.records:
            print(f"no campaign results in {folder}", file=sys.stderr)
            return None
    sources = [next((r["held_from"]["variant"] for r in h.records.values() if "held_from" in r),
                    None) for h in held]
    for folder, source in zip(args.held, sources):
        if source is None:
            print(f"{folder}: not a campaign run with --held-from", file=sys.stderr)
            return None
    return result, held, sources


def main(argv=None) -> int:
    """Draw the panels (see the module docstring); returns the exit status."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--campaign", type=Path, required=True, help="output folder of a campaign")
    p.add_argument("--data", type=Path, default=ROOT / "data" / "synthetic_inversion",
                   help="its data folder (default: data/synthetic_inversion)")
    p.add_argument("--out", type=Path, default=Path("out/figures"), help="output folder")
    p.add_argument("--nodes", type=int, default=200, help="mesh nodes of the ablations")
    p.add_argument("--held", type=Path, action="append", default=[],
                   help="output folder of a campaign run with --held-from (Fig. S2); "
                        "repeat for several")
    args = p.parse_args(argv)
    matplotlib.use("Agg")
    from morphoshell.plotting import paper_style

    loaded = _campaigns(args)
    if loaded is None:
        return 2
    result, held, sources = loaded
    truth_file = args.data / "synthetic_inversion.json"
    truth = json.loads(truth_file.read_text()) if truth_file.exists() else None
    args.out.mkdir(parents=True, exist_ok=True)
    df = result.to_dataframe()
    with paper_style():
        ablations, first_flat = _panels_DL(result, _stages(result), args.nodes, args.out)
        if first_flat is not None:
            _panel_M(first_flat, args.out)
        _panel_N(df, result.variants, args.out)
        _panel_O(df, truth, args.out)
        if held:
            _figure_S2(df, held, sources, args.out)
    (args.out / "fig3_ablations.json").write_text(json.dumps(ablations, indent=1) + "\n")
    print(f"wrote fig3_D-L, fig3_M, fig3_N, fig3_O{', figS2_held' if held else ''} (.png, "
          f".pdf) and fig3_ablations.json to {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
