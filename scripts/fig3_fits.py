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

The panels write the paper's symbols: κ⁰_post for κ₁/R (κ₁ = κ⁰_post R) and r_post for
f₁ R.  A fit that did not converge is drawn as such: open markers in N, O and S2
(morphoshell.plotting.plot_fit_series), and in D–L a hatched panel whose title says
"not converged"; a numerical ablation whose shell's walls pass through each other
(before or after the cut) is hatched with a note in its title, warned of naming the fit,
and its contact is in fig3_ablations.json (``walls_cross``).

S2   with ``--held DIR`` (repeatable), campaigns run with ``--held-from
     VARIANT`` (paper, Supplementary Fig. S2, the test of the held values):
     E_fit against pseudotime of the fixed-κ₁ variants, one panel each (A–C, in
     its colour and N's marker), with their own f₁, κ₃, κ₄ (solid) and with each
     VARIANT's first fit's (dashed, dotted); the stages of D–L marked on the
     pseudotime axis.

Writes fig3_D-L, fig3_M, fig3_N, fig3_O (and figS2_held) (PNG at 300 dpi and
PDF) and fig3_ablations.json to --out: under ``ablations`` the observables of the
numerical ablations by ``<timepoint>_<variant>``, their numerical error estimates
(``<observable>_error``) and the fit's errors carried into them (``se_<observable>``,
and where the data folder's average has its traces' spread ``se_traces_<observable>`` at
their σ² with ``t95_traces``, t₀.₉₇₅(n − 1): a 95 % interval is ± t95_traces of them);
beside it the ``units``, the ``cut`` and ``nodes`` of the ablations, the ``campaign``
and ``data`` folders (absolute) and the ``provenance`` of every package JSON.

Usage: python scripts/fig3_fits.py --campaign out/campaign [--data DATA_DIR]
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

from morphoshell.plotting import MIN_FONT_SIZE, NOT_CONVERGED

ROOT = Path(__file__).resolve().parents[1]
#: Cut Σ of the numerical ablations (units of R).
CUT = 0.15
FIXED = ("flat", "undeformed", "unstressed")
#: The paper's symbols (Fig. 3 caption): the package's κ₁ is κ⁰_post R, its f₁ is r_post/R.
KAPPA, RPOST = r"\kappa^0_\mathrm{post}", r"r_\mathrm{post}"
LABELS = {"flat": f"${KAPPA} = 0$", "undeformed": f"${KAPPA} = R^{{-1}}$",
          "unstressed": f"${KAPPA} = {RPOST}^{{-1}}$", "free": f"${KAPPA}$, ${RPOST}$ fitted"}
E_FIT = r"$E_\mathrm{fit}$"
#: The E_fit axes' label (N, S2): units of R, in the symbols' italics.
E_FIT_AXIS = r"$E_\mathrm{fit}/R$"
#: One colour and marker per hypothesis, the colours of distinct greys (luminance 0.23,
#: 0.64, 0.44 and 0 in print without colour: tests/workflows/test_fig3.py).
COLORS = {"flat": "#1b3f8b", "undeformed": "#e69f00", "unstressed": "#2ca02c", "free": "k"}
MARKERS = {"flat": "o", "undeformed": "s", "unstressed": "^", "free": "D"}


def _stages(result) -> list:
    """Early, mid and late timepoints: first, middle and last of those fitted (a campaign
    of a few timepoints of a long sequence draws its own, not empty panels)."""
    fitted = {tp for tp, _ in result.records}
    tps = [tp for tp in result.timepoints if tp.name in fitted] or result.timepoints
    picked = [tps[0], tps[len(tps) // 2], tps[-1]]
    # (two fitted timepoints drew the last one twice, as a third "stage": one row each)
    return [tp for i, tp in enumerate(picked) if tp not in picked[:i]]


def _inset(ax, rec: dict, variant: str) -> None:
    """The inset of a Fig. 3 D–L panel, beside its shell: the data (grey points) and the
    fitted midline."""
    inset = ax.inset_axes(INSET_BOX)
    d, m = rec["data_midline"], rec["fitted_midline"]
    inset.plot(d["r"], d["z"], ".", ms=1.5, color="0.4")
    inset.plot(m["r"], m["z"], "-", lw=0.8, color=COLORS[variant])
    inset.set_aspect("equal")
    inset.set_anchor("NW")
    inset.set_xticks([])
    inset.set_yticks([])


#: Place of a D–L panel's inset (axes fractions): right of the shell, top-aligned.  Inside
#: the axes every place covered the shell or the cut at some stage (the late stages fill
#: them all, and the band, a patch, went uncounted).
INSET_BOX = [1.03, 0.45, 0.3, 0.55]


def _panels_DL(result, stages, nodes: int, out: Path):
    """Fig. 3 D–L: the fixed variants' fits at three stages, numerically ablated.

    Returns the ablations' observables by ``<timepoint>_<variant>`` and the first
    flat fit's (timepoint, ablation) for panel M (None if none).
    """
    import matplotlib.pyplot as plt

    from morphoshell.plotting import DOUBLE_COLUMN, label_panel, save

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
            ablations[f"{tp.name}_{v}"], num = _panel_DL(ax, tp, rec, v, nodes,
                                                         result.midline(tp))
            # (M shows a result: not a fit that stopped short, nor walls that overlap)
            if (first_flat is None and v == "flat" and num is not None
                    and rec.get("converged", False) and not num.walls_cross):
                first_flat = (tp, num)
    _fit_rows(fig, axes)
    save(fig, out / "fig3_D-L.png", ("png", "pdf"), close=True)
    return ablations, first_flat


def _panel_DL(ax, tp, rec: dict, v: str, nodes: int, midline=None):
    """One panel of D–L: the fit, numerically ablated, and its inset; a fit that did not
    converge or an ablation whose walls pass through each other flagged (hatched, a note
    in the title).  ``midline``: the timepoint's average (the fit's errors also at its
    traces' σ², as ``ablate FIT.json`` gives them).  Returns its entry of
    fig3_ablations.json and the ablation (None if it failed)."""
    from morphoshell.plotting import flag_panel, plot_ablation
    from morphoshell.workflows import (fit_uncertainty, fitted_problem, fitted_state,
                                       numerical_ablation)

    notes = [] if rec.get("converged", False) else [NOT_CONVERGED]
    try:
        # (fitted_problem and numerical_ablation warn naming the fit: <timepoint>_<variant>)
        num = numerical_ablation(fitted_problem(rec), CUT, nodes=nodes, pre=fitted_state(rec))
    except Exception as exc:     # a figure with a gap beats no figure
        # (synthetic t07, flat, on an earlier code: a misfit whose cut's continuation
        # stopped part of the way): the intact fit's midline, and the reason in the JSON
        _intact(ax, rec, v)
        entry, num, result = {"error": str(exc)}, None, "numerical ablation failed"
    else:
        plot_ablation(num.ablation, ax, title=None, legend=False)
        # (audit 28 F2: se_<obs> take σ² from the residual, 2-3.7 times too small on
        # averages; se_traces_<obs> and t95_traces from the traces' spread, ablate's keys)
        errors = fit_uncertainty(rec, num.ablation, midline)
        entry = {**num.observables(), **num.ablation.error_columns(), "steps": num.steps,
                 "cold_difference": num.cold_difference,
                 "converged": bool(rec.get("converged", False)),
                 "walls_cross": {k: c.describe() for k, c in num.contacts.items() if c},
                 **errors.columns(),
                 # (none carried: why, as ablate's fit_error_note says it)
                 **({} if errors.errors else {"fit_error_note": errors.note})}
        result = f"o = {num.ablation.opening:.3g} R"
        notes += [_contact_note(num)] if num.walls_cross else []
    ax.set_title(f"{tp.name} (t = {tp.pseudotime:.2f}), {LABELS[v]}\n"
                 f"{E_FIT} = {rec['E_fit']:.3g} R, {result}"
                 + "".join(f"\n{note}" for note in notes), fontsize=MIN_FONT_SIZE, loc="left")
    if notes:
        flag_panel(ax)
    _inset(ax, rec, v)
    return entry, num


def _contact_note(num) -> str:
    """The title's note of an ablation whose walls pass through each other, before or after
    the cut, and their closest approach (against their thickness: in the warning and in
    fig3_ablations.json)."""
    when = [w for key, w in (("pre", "before"), ("post", "after")) if num.contacts[key]]
    closest = min((c for c in num.contacts.values() if c), key=lambda c: c.distance)
    return f"walls overlap {' and '.join(when)} the cut ({closest.distance:.2g} R apart)"


def _fit_rows(fig, axes) -> None:
    """Rows of D–L as high as their shapes: each row's height ratio the largest height
    over width of its panels' shells (equal aspect), the figure's height their sum (with
    room for titles and labels); equal rows left a short row under an empty band."""
    aspects = []
    for row in axes:
        spans = [np.ptp(ax.get_ylim()) / np.ptp(ax.get_xlim()) for ax in row if ax.axison]
        aspects.append(max(spans, default=0.5))
    gs = axes[0, 0].get_subplotspec().get_gridspec()
    gs.set_height_ratios(aspects)
    width = fig.get_figwidth() / 3 * SHELL_SHARE
    fig.set_figheight(sum(width * a + ROW_MARGIN for a in aspects))


#: Width of a D–L shell panel as a fraction of its column (the rest: inset, labels), and
#: the height of a row's title (three lines) and x label, inches: the rows' heights.
SHELL_SHARE, ROW_MARGIN = 0.6, 0.75


def _intact(ax, rec: dict, v: str) -> None:
    """A D–L panel whose numerical ablation failed: the intact fit's midline."""
    m = rec["fitted_midline"]
    for sign in (1, -1):
        ax.plot(sign * np.asarray(m["r"]), m["z"], "-", lw=1.2, color=COLORS[v])
    ax.set_aspect("equal")
    ax.set_xlabel("r/R")
    ax.set_ylabel("z/R")


def _panel_M(first_flat, out: Path) -> None:
    """Fig. 3 M: the early flat fit's pre- and post-ablation sheets overlaid."""
    import matplotlib.pyplot as plt

    from morphoshell.plotting import SINGLE_COLUMN, label_panel, plot_ablation_overlay, save

    fig, ax = plt.subplots(figsize=(SINGLE_COLUMN, SINGLE_COLUMN), layout="constrained")
    tp, num = first_flat
    plot_ablation_overlay(num.ablation, ax, title=f"{tp.name}, {LABELS['flat']}: pre (red), "
                                                  f"post (cyan), overlap (white)")
    label_panel(ax, "M")
    save(fig, out / "fig3_M.png", ("png", "pdf"), close=True)


def _panel_N(df, variants, out: Path) -> None:
    """Fig. 3 N: E_fit against pseudotime for every variant, the unconverged fits open."""
    import matplotlib.pyplot as plt

    from morphoshell.plotting import SINGLE_COLUMN, label_panel, save

    fig, ax = plt.subplots(figsize=(SINGLE_COLUMN, 0.75 * SINGLE_COLUMN), layout="constrained")
    for v in variants:
        sub = df[(df.variant == v) & (df.status == "ok")]
        _series(ax, sub, sub.E_fit, v)
    ax.set_xlabel("pseudotime $t$")
    ax.set_ylabel(E_FIT_AXIS)
    ax.set_yscale("log")
    handles = ax.get_legend_handles_labels()[0] + _open_handle(df)
    ax.legend(handles=handles, fontsize=MIN_FONT_SIZE)
    label_panel(ax, "N")
    save(fig, out / "fig3_N.png", ("png", "pdf"), close=True)


def _series(ax, sub, y, v: str, **style) -> None:
    """One variant's fits against pseudotime in its colour and marker, unconverged ones open."""
    from morphoshell.plotting import plot_fit_series

    plot_fit_series(ax, sub.pseudotime, y, sub.converged.astype(bool),
                    **{"color": COLORS[v], "marker": MARKERS[v], "label": LABELS[v], **style})


def _open_handle(df) -> list:
    """The legend's entry of the open markers, if any fit drawn did not converge."""
    from morphoshell.plotting import not_converged_handle

    ok = df[df.status == "ok"]
    return [not_converged_handle()] if len(ok) and not ok.converged.astype(bool).all() else []


def _panel_O(df, truth: dict | None, out: Path) -> None:
    """Fig. 3 O: the free fit's κ₁ (95 % intervals) and 1/f₁, f₁ inset, the truth if known;
    the unconverged fits open in all three."""
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
                label=f"generating ${KAPPA}$ (synthetic)")
    ax.set_xlabel("pseudotime $t$")
    ax.set_ylabel(f"${KAPPA}\\,R$")
    # one column below the axes: two columns of these labels are wider than a column of a
    # journal page, and constrained layout then collapses the axes
    ax.legend(handles=ax.get_legend_handles_labels()[0] + _open_handle(free),
              fontsize=MIN_FONT_SIZE, loc="upper center", bbox_to_anchor=(0.5, -0.22), ncol=1,
              frameon=False)
    if len(free):
        inset = ax.inset_axes([0.62, 0.12, 0.35, 0.35])
        _series(inset, free, free.f1, "free", ms=2, label=None)
        inset.set_title(f"${RPOST}/R$", fontsize=MIN_FONT_SIZE)
        inset.tick_params(labelsize=MIN_FONT_SIZE)
    label_panel(ax, "O")
    save(fig, out / "fig3_O.png", ("png", "pdf"), close=True)


def _free_kappa1(ax, free) -> None:
    """The free fits' κ₁ with 95 % intervals and R/r_post = 1/f₁, the unconverged ones open."""
    from morphoshell.plotting import plot_fit_series

    # jackknife errors where the campaign computed them (--embryo-errors); the
    # Gauss-Newton ones are up to 4x too small (docs/campaigns.md, Standard errors)
    # bars: 95 % intervals, so that a miss of the generating kappa1 shows as one
    jack = "se_embryo_kappa1" in free and free.se_embryo_kappa1.notna().any()
    half = (free.se_embryo_kappa1 * free.embryo_t95 if jack
            else free.se_kappa1 * scipy.stats.norm.ppf(0.975))
    _series(ax, free, free.kappa1, "free", yerr=half, lw=0.8,
            label=f"fitted ${KAPPA}$ (free), 95 % interval "
            + ("(jackknife, Student's t)" if jack else "(Gauss–Newton, too narrow)"))
    # κ₁ = 1/f₁ is the unstressed hypothesis: its colour and marker
    plot_fit_series(ax, free.pseudotime, 1 / free.f1, free.converged.astype(bool), ls="--",
                    color=COLORS["unstressed"], marker=MARKERS["unstressed"],
                    label=f"$R/{RPOST}$ (free)")


#: Line style of Fig. S2's series by whose first fit gave f₁, κ₃, κ₄: the variant's own
#: (solid, as in N), or the held campaigns' (``--held``, in order).
HELD_LINES = ("-", "--", ":", "-.")


def _figure_S2(df, held: list, sources: list, stages: list, out: Path) -> None:
    """Fig. S2: the fixed variants' E_fit with their own and others' held f₁, κ₃, κ₄.

    One panel per hypothesis (as the columns of D–L, in its colour and N's marker: a square
    is κ⁰_post = R⁻¹ in every panel of Fig. 3 and S2), the line style saying whose first
    fit's values were held; the unconverged fits open, as in N; the stages of D–L marked on
    the pseudotime axis (the paper's S2 marks them with shape insets)."""
    import matplotlib.pyplot as plt

    from morphoshell.plotting import DOUBLE_COLUMN, label_panel, save

    fig, axes = plt.subplots(1, len(FIXED), figsize=(DOUBLE_COLUMN, 0.4 * DOUBLE_COLUMN),
                             layout="constrained", sharey=True)
    runs = [(df, "own")] + [(h.to_dataframe(), source) for h, source in zip(held, sources)]
    shown = []
    for ax, v, letter in zip(axes, FIXED, "ABC"):
        for (frame, whose), ls in zip(runs, HELD_LINES):
            sub = frame[(frame.variant == v) & (frame.status == "ok")]
            if len(sub) and whose != v:         # (held from itself: its own fit again)
                _series(ax, sub, sub.E_fit, v, ls=ls, label=None)
                shown.append(sub)
        ax.set_title(LABELS[v], loc="left")
        ax.set_xlabel("pseudotime $t$")
        _mark_stages(ax, stages)
        label_panel(ax, letter)
    axes[0].set_ylabel(E_FIT_AXIS)
    axes[0].set_yscale("log")
    fig.legend(handles=_held_handles(runs) + _open_handle(_concat(shown)),
               loc="outside lower center", ncols=2, fontsize=MIN_FONT_SIZE)
    save(fig, out / "figS2_held.png", ("png", "pdf"), close=True)


def _concat(frames: list):
    """The frames drawn, as one (empty if none)."""
    import pandas as pd

    return pd.concat(frames) if frames else pd.DataFrame({"status": [], "converged": []})


def _held_handles(runs: list) -> list:
    """Fig. S2's legend: whose first fit's f₁, κ₃, κ₄ each line style holds, in the
    paper's symbols (the hypotheses are the panels' titles)."""
    from matplotlib.lines import Line2D

    held = f"${RPOST}$, $\\kappa_3$, $\\kappa_4$"
    return [Line2D([], [], color="k", ls=ls, label=f"{held} held from its own first fit"
                   if whose == "own" else f"{held} held from the first fit with {LABELS[whose]}")
            for (_, whose), ls in zip(runs, HELD_LINES)] + [
        Line2D([], [], ls="none", marker="^", ms=4, color="0.6",
               label="stages of Fig. 3 D–L")]


def _mark_stages(ax, stages: list) -> None:
    """The pseudotimes of D–L's rows: ticks inside the bottom axis (grey triangles)."""
    from matplotlib.transforms import blended_transform_factory

    along = blended_transform_factory(ax.transData, ax.transAxes)
    ax.plot([tp.pseudotime for tp in stages], [0.0] * len(stages), ls="none", marker="^",
            ms=4, color="0.6", transform=along, clip_on=False, zorder=1)


def _ablations_json(ablations: dict, args) -> dict:
    """fig3_ablations.json: the entries by fit and what they were made with and are in
    (audit 27 F9: the file behind Fig. 3's numbers had no units, cut, mesh or source)."""
    from morphoshell.mechanics.ablation import UNITS

    units = {**UNITS, **{f"{k}_error": u for k, u in UNITS.items()},
             **{f"se_{k}": u for k, u in UNITS.items()},
             **{f"se_traces_{k}": u for k, u in UNITS.items()}, "t95_traces": "1", "steps": "1",
             "cold_difference": "R or rad (the unknowns' largest difference)", "cut": "R"}
    return {"ablations": ablations, "cut": CUT, "nodes": args.nodes, "units": units,
            "campaign": str(args.campaign.resolve()), "data": str(args.data.resolve())}


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
    p.add_argument("--data", type=Path, default=None,
                   help="its data folder (default: the one the campaign folder records)")
    p.add_argument("--out", type=Path, default=Path("out/figures"), help="output folder")
    p.add_argument("--nodes", type=int, default=200, help="mesh nodes of the ablations")
    p.add_argument("--held", type=Path, action="append", default=[],
                   help="output folder of a campaign run with --held-from (Fig. S2); "
                        "repeat for several")
    args = p.parse_args(argv)
    matplotlib.use("Agg")
    from morphoshell.io.problem_files import write_json
    from morphoshell.plotting import paper_style

    loaded = _campaigns(args)
    if loaded is None:
        return 2
    result, held, sources = loaded
    args.data = Path(result.data_dir or args.data)     # (the recorded one without --data)
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
            _figure_S2(df, held, sources, _stages(result), args.out)
    write_json(args.out / "fig3_ablations.json", _ablations_json(ablations, args))
    print(f"wrote fig3_D-L, fig3_M, fig3_N, fig3_O{', figS2_held' if held else ''} (.png, "
          f".pdf) and fig3_ablations.json to {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
