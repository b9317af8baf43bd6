#!/usr/bin/env python3
"""Reproduce Fig. 2 D–I of the paper: ablations of the mechanical toy problems.

Panels (paper, main text "Mechanical toy problems", Fig. 2 caption, Materials
and Methods "Numerical solution of the toy problems"):

D  cut opening o/[h(1−k)] against the cut radius c = 2 sin Σ: asymptotic line
   o/[h(1−k)] = sin Σ = c/2 (Supplementary, toy problem 2, "Cut opening") and
   numerical ablations of toy problem 2 (classical theory, uniform family,
   k = 0) for h = 1e-2, 1e-3, 1e-4;
E  cut rotation ϱ/[√h(1−k)] against c/√h: leading order √(3/2) (Supplementary,
   "Cut rotation and cut displacement"), the Kelvin-function approximation for
   small cuts Σ = O(δ), the numerical solution of the nonlinear inner problem
   (Supplementary, "Asymptotic governing equations for small ablations") it
   approximates (:func:`morphoshell.mechanics.asymptotics.inner_problem`), and numerical
   ablations;
F  cut displacement d/[h(1−k)] against c/√h: leading order 1/2 (Supplementary,
   "Cut rotation and cut displacement"), Kelvin approximation, inner problem,
   numerical ablations;
G  cross-sections before and after the ablation of toy problem 2
   (example toy2_ablation: large-bending theory, h = Σ = 0.3, k = 0);
H  the same for toy problem 3 (example toy3_anisotropic) with
   f0 = +0.1 and f0 = −0.1;
I  the same for a fast active relaxation at the cut
   (example fast_relaxation: F0 = 0.35, s0 = 0.2).

Writes fig2_D.png … fig2_I.png (single-column width, 3.4 in), the combined
fig2_D-I.png (double-column width, 7 in), each at 300 dpi and also as PDF,
and fig2_points.json (the numerical points plotted) to ``--out``.

Usage: python scripts/fig2_toy_problems.py [--out out/figures] [--quick] [-v | -q]

Progress bars (one per sweep) show on a terminal; -q/--quiet hides them and
warnings, -v/--verbose adds notes.
"""
from __future__ import annotations

import argparse
import math
import sys
import textwrap
import time
from pathlib import Path

import matplotlib
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.figure import Figure

from morphoshell.mechanics import asymptotics
from morphoshell._runtime.console import run_script, progress
from morphoshell.solvers.routes import solve
from morphoshell.io.problem_files import EXAMPLES_DIR, load_problem, write_json
from morphoshell.mechanics.ablation import ablate
from morphoshell.plotting import (DOUBLE_COLUMN, MIN_FONT_SIZE, SINGLE_COLUMN, far_end_shift,
                                  label_panel, paper_style, plot_ablation, save, sheet_outline)
from morphoshell.model.problem import Problem

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = Path(__file__).name
PROBLEMS = EXAMPLES_DIR   # the packaged examples (also problems/)

#: Thicknesses of the numerical points in D–F, thickest first.
H_VALUES = (1e-2, 1e-3, 1e-4)
#: Intrinsic curvature of D–F (an intrinsically flat sheet, as in G).
K = 0.0
#: Largest cut of the sweeps (Σ over (0.05, 1.4) in D).
SIGMA_MAX = 1.4
#: Range of c/√h in E and F.
X_RANGE = (0.1, 100.0)
#: Markers of the thicknesses in H_VALUES: nested (large open circle, open
#: square, small filled triangle), so that coinciding points all stay visible.
MARKERS = ({"marker": "o", "ms": 6.0, "mfc": "none", "mew": 0.9},
           {"marker": "s", "ms": 3.9, "mfc": "none", "mew": 0.9},
           {"marker": "^", "ms": 3.0, "mew": 0.0})
FORMATS = ("png", "pdf")
#: Caption note of panel H (also in docs/gallery.md): the spikes look like a
#: drawing error but are in the solution (Supplementary, toy problem 3).
POLE_NOTE = (r"The spikes at the poles are physical: a pole forces equal stretches "
             r"$f_s=f_\phi$, which the anisotropic contraction $f_s^0=1/f_\phi^0\neq1$ "
             r"cannot match; the stretches, and with them the thickness $h/(f_sf_\phi)$, "
             r"are weakly singular there (Supplementary, toy problem 3).")


# --------------------------------------------------------------------------
# numerics
# --------------------------------------------------------------------------

def sweep(h: float, sigmas, nodes: int) -> dict[str, list[float]]:
    """Ablations of toy problem 2 (classical theory, k = K) for the cuts ``sigmas``.

    The pre-ablation shell depends on h and k only, so it is solved once.
    """
    base = Problem("uniform", {"k": K}, h=h, cut=float(sigmas[0]), theory="classical",
                   name=f"toy2_h{h:g}")
    pre = solve(base.with_updates(cut=0.0), nodes=nodes)
    out: dict[str, list[float]] = {k: [] for k in (
        "Sigma", "c", "opening", "rotation", "displacement", "iterations")}
    for sigma in progress(sigmas, desc=f"D-F sweep, h = {h:g}", unit="cut"):
        ab = ablate(base.with_updates(cut=float(sigma)), nodes=nodes, pre=pre)
        out["Sigma"].append(float(sigma))
        out["c"].append(2 * math.sin(sigma))
        out["opening"].append(ab.opening)
        out["rotation"].append(ab.rotation)
        out["displacement"].append(ab.displacement)
        out["iterations"].append(ab.post.solver.iterations)
    return out


def x_to_sigma(x):
    """σ = Σ/δ for c/√h = x in the small-cut limit (c ≈ 2Σ, δ/√h = 12^{−1/4})."""
    return np.asarray(x) * 12**0.25 / 2


# --------------------------------------------------------------------------
# panels
# --------------------------------------------------------------------------

def _h_label(h: float) -> str:
    return rf"$h = 10^{{{round(math.log10(h))}}}$"


def _points(ax, x, y, i: int, **kw):
    """The numerical points of the i-th thickness, thickest on top (its marker is largest)."""
    ax.plot(x, y, ls="none", color=f"C{i}", zorder=3 + len(H_VALUES) - i, **MARKERS[i], **kw)


def _legend(ax, what: set[str], **kw):
    """Legend of the curves ("curves": lines) and/or the points ("points": markers)."""
    handles, labels = ax.get_legend_handles_labels()
    keep = [(h, lab) for h, lab in zip(handles, labels)
            if ("points" if h.get_linestyle() == "None" else "curves") in what]
    if keep:
        ax.legend(*zip(*keep), **kw)


def panel_D(ax, data, legend=("curves", "points")):
    c = np.linspace(0, 2 * math.sin(SIGMA_MAX), 100)
    ax.plot(c, c / 2, color="k", label=r"$\sin\Sigma = c/2$ (asymptotic)", zorder=1)
    for i, (h, pts) in enumerate(data.items()):
        _points(ax, pts["c"], np.array(pts["opening"]) / (h * (1 - K)), i, label=_h_label(h))
    ax.set_xlabel(r"cut radius $c = 2\sin\Sigma$")
    ax.set_ylabel(r"opening $o/[h(1-k)]$")
    ax.set_xlim(0, None)
    ax.set_ylim(0, None)
    _legend(ax, set(legend), loc="upper left")
    # inset (below the line): ratio to the asymptote, where the approach as h → 0 is visible
    ins = ax.inset_axes([0.6, 0.12, 0.37, 0.24])
    ins.axhline(1.0, color="k", lw=0.8)
    for i, (h, pts) in enumerate(data.items()):
        ratio = np.array(pts["opening"]) / (h * (1 - K) * np.sin(pts["Sigma"]))
        ins.plot(pts["c"], ratio, color=f"C{i}", lw=0.5, zorder=2 + len(H_VALUES) - i,
                 **{**MARKERS[i], "ms": 0.7 * MARKERS[i]["ms"]})
    ins.set_xscale("log")   # x: c, as in the main axes
    ins.set_title(r"$o/[h(1-k)\sin\Sigma]$", pad=2, loc="right", fontsize=MIN_FONT_SIZE)


def _small_cut_panel(ax, data, inner, key: str, legend):
    x = np.geomspace(*X_RANGE, 300)
    h_ref = 1e-12            # Σ ≪ 1, so the Kelvin curve is a function of c/√h
    sig = np.arcsin(x * math.sqrt(h_ref) / 2)
    if key == "rotation":
        const, const_label = math.sqrt(1.5), r"$\sqrt{3/2}$ (leading order)"
        kelvin = asymptotics.rotation_small_cut(h_ref, K, sig) / (math.sqrt(h_ref) * (1 - K))
        scale = lambda h: math.sqrt(h) * (1 - K)  # noqa: E731
    else:
        const, const_label = 0.5, r"$1/2$ (leading order)"
        kelvin = asymptotics.displacement_small_cut(h_ref, K, sig) / (h_ref * abs(1 - K))
        scale = lambda h: h * abs(1 - K)  # noqa: E731
    ax.axhline(const, color="k", lw=0.8, ls="--", label=const_label, zorder=1)
    ax.plot(x, kelvin, color="k", label="Kelvin approximation", zorder=1)
    x_inner = inner["sigma"] * 2 / 12**0.25
    ax.plot(x_inner, inner[key] / (1 - K), color="0.55", lw=2.2, alpha=0.6, zorder=0,
            label="nonlinear inner problem")
    for i, (h, pts) in enumerate(data.items()):
        _points(ax, np.array(pts["c"]) / math.sqrt(h), np.array(pts[key]) / scale(h), i,
                label=_h_label(h))
    ax.set_xscale("log")
    ax.set_xlim(*X_RANGE)
    ax.set_ylim(0, const * 1.12)
    ax.set_xlabel(r"$c/\sqrt{h}$")
    _legend(ax, set(legend), loc="lower right")


def panel_E(ax, data, inner, legend=("curves", "points")):
    _small_cut_panel(ax, data, inner, "rotation", legend)
    ax.set_ylabel(r"rotation $\varrho/[\sqrt{h}\,(1-k)]$")


def panel_F(ax, data, inner, legend=("curves", "points")):
    _small_cut_panel(ax, data, inner, "displacement", legend)
    ax.set_ylabel(r"displacement $d/[h\,|1-k|]$")


def _cross_section(ax, ab, limits, y_axis: bool = True):
    """Pre/post cross-sections on the common scale; the observables below the axes.

    Without ``y_axis`` the z labels are left to the panel on the left (same scale).
    """
    plot_ablation(ab, ax=ax, title=None, legend=False)
    ax.set_aspect("equal", adjustable="box")   # the common limits are kept
    ax.set_xlim(*limits[0])
    ax.set_ylim(*limits[1])
    if not y_axis:
        ax.set_ylabel("")
        ax.tick_params(labelleft=False)
    ax.annotate(rf"$o = {ab.opening:.3f}$" "\n" rf"$\varrho = {ab.rotation:.3f}$" "\n"
                rf"$d = {ab.displacement:.3f}$", xy=(0.5, 0.0), xycoords=ax.xaxis.label,
                xytext=(0, -1), textcoords="offset points", ha="center", va="top")


def _text_row(fig, spec, *, note: str | None = None, chars: int = 60, legend_from=None,
              ncol: int = 1):
    """An axes without frame under the cross-sections, for the shared legend or a note.

    The note is broken into lines of about ``chars`` characters (TeX source:
    write its formulas without spaces, which mathtext spaces itself).
    """
    ax = fig.add_subplot(spec)
    ax.axis("off")
    if legend_from is not None:
        ax.legend(*legend_from.get_legend_handles_labels(), ncol=ncol, borderaxespad=0.0,
                  loc="upper left" if ncol == 1 else "upper center")
    if note is not None:
        ax.text(0.0, 1.0, textwrap.fill(note, chars), transform=ax.transAxes, ha="left",
                va="top")
    return ax


PANEL_TITLES = {
    "D": "toy problem 2: cut opening",
    "E": "toy problem 2: cut rotation",
    "F": "toy problem 2: cut displacement",
    "G": "toy problem 2\n$k = 0$",
    "H+": "toy problem 3\n$f_0 = +0.1$",
    "H-": "toy problem 3\n$f_0 = -0.1$",
    "I": "fast relaxation\n$F_0 = 0.35$, $s_0 = 0.2$",
}


# --------------------------------------------------------------------------
# main
# --------------------------------------------------------------------------

def compute(quick: bool) -> dict:
    """All numerical results of the figure."""
    n_d, n_ef = (6, 7) if quick else (15, 19)
    nodes = 800 if quick else 1600
    d_sigmas = np.linspace(0.05, SIGMA_MAX, n_d)
    fig_d, fig_ef = {}, {}
    for h in H_VALUES:
        fig_d[h] = sweep(h, d_sigmas, nodes)
        x = np.geomspace(*X_RANGE, n_ef)
        sig = np.arcsin(np.clip(x * math.sqrt(h) / 2, 0, 1))
        fig_ef[h] = sweep(h, sig[sig <= SIGMA_MAX], nodes)
    inner = asymptotics.inner_problem(x_to_sigma(np.geomspace(*X_RANGE, 25 if quick else 60)), K)
    cross = {}
    for key, name, over in progress((("G", "toy2_ablation", {}),
                                     ("H+", "toy3_anisotropic", {"f0": 0.1}),
                                     ("H-", "toy3_anisotropic", {"f0": -0.1}),
                                     ("I", "fast_relaxation", {})),
                                    desc="G-I cross-sections", unit="ablation"):
        problem, settings = load_problem(PROBLEMS / f"{name}.toml")
        problem = problem.with_updates(**over)
        opts = {"stages": settings.stages} if settings.method == "direct" else {}
        cross[key] = ablate(problem, nodes=settings.nodes, method=settings.method, **opts)
    return {"nodes": nodes, "D": fig_d, "EF": fig_ef, "inner": inner, "cross": cross}


def _common_limits(ablations, margin: float = 0.06):
    """Axis limits holding every cross-section, so that all panels share one scale.

    Bands as drawn by :func:`plot_ablation`: z in the far-end gauge
    (:func:`morphoshell.plotting.far_end_shift`).
    """
    r_max, z_lo, z_hi = 0.0, np.inf, -np.inf
    for ab in ablations:
        for eq in (ab.pre, ab.post):
            shift = far_end_shift(eq)
            pr, pz = sheet_outline(eq)
            r_max = max(r_max, float(np.max(np.abs(pr))))
            z_lo, z_hi = min(z_lo, float(np.min(pz)) + shift), max(z_hi, float(np.max(pz)) + shift)
    return (-r_max - margin, r_max + margin), (z_lo - margin, z_hi + margin)


#: Heights (inches) of the single-panel files; the width is SINGLE_COLUMN.
HEIGHT_CURVES, HEIGHT_SECTION = 2.6, 3.3


def _figure(width: float, height: float) -> Figure:
    return plt.figure(figsize=(width, height), layout="constrained")


def figures(res: dict) -> dict[str, Figure]:
    """Every figure of the script, keyed by file stem ("D" … "I", "D-I").

    Draw inside :func:`morphoshell.plotting.paper_style` (fonts ≥ 7 pt).
    """
    figs: dict[str, Figure] = {}
    limits = _common_limits(res["cross"].values())
    for key, panel, args in (("D", panel_D, (res["D"],)),
                             ("E", panel_E, (res["EF"], res["inner"])),
                             ("F", panel_F, (res["EF"], res["inner"]))):
        figs[key] = fig = _figure(SINGLE_COLUMN, HEIGHT_CURVES)
        ax = fig.add_subplot()
        panel(ax, *args)
        ax.set_title(PANEL_TITLES[key])
    for key in ("G", "I"):
        figs[key] = fig = _figure(SINGLE_COLUMN, HEIGHT_SECTION)
        grid = fig.add_gridspec(2, 1, height_ratios=(1, 0.06))
        ax = fig.add_subplot(grid[0])
        _cross_section(ax, res["cross"][key], limits)
        ax.set_title(PANEL_TITLES[key])
        _text_row(fig, grid[1], legend_from=ax, ncol=2)
    figs["H"] = fig = _figure(SINGLE_COLUMN, HEIGHT_SECTION + 0.8)
    grid = fig.add_gridspec(3, 2, height_ratios=(1, 0.06, 0.4))
    for col, key in enumerate(("H+", "H-")):
        ax = fig.add_subplot(grid[0, col])
        _cross_section(ax, res["cross"][key], limits, y_axis=col == 0)
        ax.set_title(PANEL_TITLES[key])
    _text_row(fig, grid[1, :], legend_from=ax, ncol=2)
    _text_row(fig, grid[2, :], note=POLE_NOTE, chars=54)
    figs["D-I"] = combined(res, limits)
    return figs


def combined(res: dict, limits) -> Figure:
    """Panels D–I at double-column width: D–F above, the cross-sections G–I below."""
    fig = _figure(DOUBLE_COLUMN, 5.3)
    top, bottom = fig.subfigures(2, 1, height_ratios=(1, 1.25))
    axes = top.subplots(1, 3)
    panel_D(axes[0], res["D"])
    panel_E(axes[1], res["EF"], res["inner"], legend=("curves",))   # the points: as in D
    panel_F(axes[2], res["EF"], res["inner"], legend=())              # the curves: as in E
    for ax, key in zip(axes, "DEF"):
        ax.set_title(PANEL_TITLES[key])
        label_panel(ax, key)
    grid = bottom.add_gridspec(2, 4, height_ratios=(1, 0.12))
    for col, key in enumerate(("G", "H+", "H-", "I")):
        ax = bottom.add_subplot(grid[0, col])
        _cross_section(ax, res["cross"][key], limits, y_axis=col == 0)
        ax.set_title(PANEL_TITLES[key])
        if key != "H-":
            label_panel(ax, key[0])
        if key == "G":
            legend_from = ax
    _text_row(bottom, grid[1, 0], legend_from=legend_from)
    _text_row(bottom, grid[1, 1:], note="H: " + POLE_NOTE, chars=100)
    return fig


def write(res: dict, out: Path, quick: bool) -> tuple[list[Path], dict[str, Figure]]:
    """Draw (paper style) and save every figure, 300 dpi PNG and PDF, and the points' JSON.

    Returns the paths written and the figures (closed, for inspection).
    """
    written: list[Path] = []
    with paper_style():   # saved inside too: the PDF's font type is read on saving
        figs = figures(res)
        for key, fig in figs.items():
            written.extend(save(fig, out / f"fig2_{key}", formats=FORMATS, close=True))
    written.append(write_json(out / "fig2_points.json", points_json(res, quick)))
    return written, figs


def points_json(res: dict, quick: bool) -> dict:
    """The numerical points plotted, normalised as on the axes."""
    def series(data, xkey, ykey, xscale, yscale):
        return [{"h": h, "Sigma": pts["Sigma"],
                 "x": list(np.array(pts[xkey]) / xscale(h)),
                 "y": list(np.array(pts[ykey]) / yscale(h)),
                 "raw": {k: pts[k] for k in ("opening", "rotation", "displacement")}}
                for h, pts in data.items()]

    one = lambda h: 1.0  # noqa: E731
    return {
        "script": SCRIPT,
        "description": "Fig. 2 D-I of the paper: numerical points of toy problems 2 and 3",
        "quick": quick, "k": K, "theory_D-F": "classical", "family_D-F": "uniform",
        "nodes_D-F": res["nodes"],
        "D": {"x": "c = 2 sin(Sigma)", "y": "o/(h(1-k))", "asymptote": "y = x/2",
              "series": series(res["D"], "c", "opening", one, lambda h: h * (1 - K))},
        "E": {"x": "c/sqrt(h)", "y": "rho/(sqrt(h)(1-k))", "asymptote": math.sqrt(1.5),
              "series": series(res["EF"], "c", "rotation", math.sqrt,
                               lambda h: math.sqrt(h) * (1 - K))},
        "F": {"x": "c/sqrt(h)", "y": "d/(h|1-k|)", "asymptote": 0.5,
              "series": series(res["EF"], "c", "displacement", math.sqrt,
                               lambda h: h * abs(1 - K))},
        "inner_problem": {"x": list(res["inner"]["sigma"] * 2 / 12**0.25),
                          "rotation": res["inner"]["rotation"],
                          "displacement": res["inner"]["displacement"]},
        "cross_sections": {key: {"problem": ab.problem.describe(), **ab.observables()}
                           for key, ab in res["cross"].items()},
    }


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="out/figures", help="output folder (default: out/figures)")
    parser.add_argument("--quick", action="store_true", help="fewer points and a coarser mesh")
    return run_script(parser, argv, _run)


def _run(args) -> int:
    matplotlib.use("Agg")   # files only: runs without a display
    t0 = time.perf_counter()
    res = compute(args.quick)
    t1 = time.perf_counter()
    written, _ = write(res, Path(args.out), args.quick)
    for path in written:
        print(f"wrote {path}")
    print(f"{SCRIPT}: solved in {t1 - t0:.1f} s, plotted in {time.perf_counter() - t1:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
