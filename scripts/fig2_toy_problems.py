#!/usr/bin/env python3
"""Reproduce Fig. 2 D–I of the paper: ablations of the mechanical toy problems.

Panels (paper, main text "Mechanical toy problems", Fig. 2 caption, Materials
and Methods "Numerical solution of the toy problems"):

D  cut opening o/[h(1−k)] against the cut radius c = 2 sin Σ: asymptotic line
   o/[h(1−k)] = sin Σ = c/2 (eq:Usol) and numerical ablations of toy problem 2
   (classical theory, uniform family, k = 0) for h = 1e-2, 1e-3, 1e-4;
E  cut rotation ϱ/[√h(1−k)] against c/√h: leading order √(3/2) (eq:cutr), the
   Kelvin-function approximation for small cuts Σ = O(δ), the numerical
   solution of the nonlinear inner problem (eq:prob) it approximates
   (:func:`morphoshell.asymptotics.inner_problem`), and numerical ablations;
F  cut displacement d/[h(1−k)] against c/√h: leading order 1/2 (eq:cutd),
   Kelvin approximation, inner problem, numerical ablations;
G  cross-sections before and after the ablation of toy problem 2
   (problems/toy2_ablation.toml: large-bending theory, h = Σ = 0.3, k = 0);
H  the same for toy problem 3 (problems/toy3_anisotropic.toml) with
   f0 = +0.1 and f0 = −0.1;
I  the same for a fast active relaxation at the cut
   (problems/fast_relaxation.toml: F0 = 0.35, s0 = 0.2).

Writes fig2_D.png … fig2_I.png, the combined fig2_D-I.png (each also as PDF)
and fig2_points.json (the numerical points plotted) to ``--out``.

Usage: python scripts/fig2_toy_problems.py [--out out/figures] [--quick]
"""
from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

from morphoshell import asymptotics
from morphoshell.equilibrium import solve
from morphoshell.io import load_problem, write_json
from morphoshell.ablation import ablate, edge_state
from morphoshell.plotting import plot_ablation, plt, sheet_outline
from morphoshell.problem import Problem

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = Path(__file__).name
PROBLEMS = ROOT / "problems"

#: Thicknesses of the numerical points in D–F, thickest first.
H_VALUES = (1e-2, 1e-3, 1e-4)
#: Intrinsic curvature of D–F (an intrinsically flat sheet, as in G).
K = 0.0
#: Largest cut of the sweeps (Σ over (0.05, 1.4) in D).
SIGMA_MAX = 1.4
#: Range of c/√h in E and F.
X_RANGE = (0.1, 100.0)
MARKERS = ("o", "s", "^", "D")
DPI = 130
FORMATS = ("png", "pdf")


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
    for sigma in sigmas:
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


def panel_D(ax, data):
    c = np.linspace(0, 2 * math.sin(SIGMA_MAX), 100)
    ax.plot(c, c / 2, color="k", lw=1.2, label=r"$\sin\Sigma = c/2$ (asymptotic)", zorder=1)
    for i, (h, pts) in enumerate(data.items()):
        y = np.array(pts["opening"]) / (h * (1 - K))
        ax.plot(pts["c"], y, ls="none", marker=MARKERS[i], ms=5, mfc="none", mew=1.1,
                color=f"C{i}", label=_h_label(h))
    ax.set_xlabel(r"cut radius $c = 2\sin\Sigma$")
    ax.set_ylabel(r"opening $o/[h(1-k)]$")
    ax.set_xlim(0, None)
    ax.set_ylim(0, None)
    ax.legend(loc="upper left", fontsize="small", frameon=False)
    # inset: ratio to the asymptote, where the approach as h → 0 is visible
    ins = ax.inset_axes([0.56, 0.1, 0.41, 0.36])
    ins.axhline(1.0, color="k", lw=1.0)
    for i, (h, pts) in enumerate(data.items()):
        ratio = np.array(pts["opening"]) / (h * (1 - K) * np.sin(pts["Sigma"]))
        ins.plot(pts["c"], ratio, marker=MARKERS[i], ms=3.5, mfc="none", mew=0.9, lw=0.6,
                 color=f"C{i}")
    ins.set_xscale("log")
    ins.set_ylabel(r"$o/[h(1-k)\sin\Sigma]$", fontsize="x-small")
    ins.set_xlabel(r"$c$", fontsize="x-small", labelpad=1)
    ins.tick_params(labelsize="x-small")


def _small_cut_panel(ax, data, inner, key: str):
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
    ax.axhline(const, color="k", lw=1.0, ls="--", label=const_label, zorder=1)
    ax.plot(x, kelvin, color="k", lw=1.2, label="Kelvin approximation", zorder=1)
    x_inner = inner["sigma"] * 2 / 12**0.25
    ax.plot(x_inner, inner[key] / (1 - K), color="0.55", lw=2.4, alpha=0.6, zorder=0,
            label="nonlinear inner problem")
    for i, (h, pts) in enumerate(data.items()):
        xs = np.array(pts["c"]) / math.sqrt(h)
        ax.plot(xs, np.array(pts[key]) / scale(h), ls="none", marker=MARKERS[i], ms=5,
                mfc="none", mew=1.1, color=f"C{i}", label=_h_label(h))
    ax.set_xscale("log")
    ax.set_xlim(*X_RANGE)
    ax.set_ylim(0, const * 1.12)
    ax.set_xlabel(r"$c/\sqrt{h}$")
    ax.legend(loc="lower right", fontsize="x-small", frameon=False, ncol=1)


def panel_E(ax, data, inner):
    _small_cut_panel(ax, data, inner, "rotation")
    ax.set_ylabel(r"rotation $\varrho/[\sqrt{h}\,(1-k)]$")


def panel_F(ax, data, inner):
    _small_cut_panel(ax, data, inner, "displacement")
    ax.set_ylabel(r"displacement $d/[h\,|1-k|]$")


def _cross_section(ax, ab, title, limits=None):
    plot_ablation(ab, ax=ax, title=title)
    if limits is not None:
        ax.set_xlim(*limits[0])
        ax.set_ylim(*limits[1])
    ax.legend(loc="center", fontsize="x-small", frameon=False)
    # the corner is outside the (near-spherical) shells
    ax.text(0.03, 0.03, rf"$o = {ab.opening:.3f}$" "\n" rf"$\varrho = {ab.rotation:.3f}$" "\n"
            rf"$d = {ab.displacement:.3f}$", transform=ax.transAxes, ha="left", va="bottom",
            fontsize="x-small")


PANEL_TITLES = {
    "D": "D  toy problem 2: cut opening",
    "E": "E  toy problem 2: cut rotation",
    "F": "F  toy problem 2: cut displacement",
    "G": "G  toy problem 2, $k = 0$",
    "H+": "H  toy problem 3, $f_0 = +0.1$",
    "H-": "H  toy problem 3, $f_0 = -0.1$",
    "I": "I  fast relaxation",
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
    for key, name, over in (("G", "toy2_ablation", {}),
                            ("H+", "toy3_anisotropic", {"f0": 0.1}),
                            ("H-", "toy3_anisotropic", {"f0": -0.1}),
                            ("I", "fast_relaxation", {})):
        problem, settings = load_problem(PROBLEMS / f"{name}.toml")
        problem = problem.with_updates(**over)
        opts = {"stages": settings.stages} if settings.method == "direct" else {}
        cross[key] = ablate(problem, nodes=settings.nodes, method=settings.method, **opts)
    return {"nodes": nodes, "D": fig_d, "EF": fig_ef, "inner": inner, "cross": cross}


def _common_limits(ablations, margin: float = 0.06):
    """Axis limits holding every cross-section, so that all panels share one scale.

    Bands as drawn by :func:`plot_ablation`: z in the far-end gauge of
    :func:`morphoshell.ablation.edge_state`.
    """
    r_max, z_lo, z_hi = 0.0, np.inf, -np.inf
    for ab in ablations:
        for eq in (ab.pre, ab.post):
            shift = edge_state(eq, float(eq.s[0]))["z"] - float(eq.z[0])
            pr, pz = sheet_outline(eq)
            r_max = max(r_max, float(np.max(np.abs(pr))))
            z_lo, z_hi = min(z_lo, float(np.min(pz)) + shift), max(z_hi, float(np.max(pz)) + shift)
    return (-r_max - margin, r_max + margin), (z_lo - margin, z_hi + margin)


def draw(res: dict, out: Path) -> list[Path]:
    written: list[Path] = []
    limits = _common_limits(res["cross"].values())

    def single(key, fn, *args, size=(4.4, 3.8)):
        fig, ax = plt.subplots(figsize=size, constrained_layout=True)
        fn(ax, *args)
        ax.set_title(PANEL_TITLES[key][3:], fontsize="medium")
        written.extend(_save(fig, out / f"fig2_{key}"))

    single("D", panel_D, res["D"])
    single("E", panel_E, res["EF"], res["inner"])
    single("F", panel_F, res["EF"], res["inner"])
    for key in ("G", "I"):
        single(key, _cross_section, res["cross"][key], None, limits, size=(4.0, 4.6))
    fig, axes = plt.subplots(1, 2, figsize=(7.6, 4.6), constrained_layout=True)
    for ax, key in zip(axes, ("H+", "H-")):
        _cross_section(ax, res["cross"][key], None, limits)
        ax.set_title(PANEL_TITLES[key][3:], fontsize="medium")
    written.extend(_save(fig, out / "fig2_H"))

    fig = plt.figure(figsize=(13.5, 8.4), constrained_layout=True)
    grid = fig.add_gridspec(2, 12)
    top = [fig.add_subplot(grid[0, 4 * i:4 * i + 4]) for i in range(3)]
    bottom = [fig.add_subplot(grid[1, 3 * i:3 * i + 3]) for i in range(4)]
    panel_D(top[0], res["D"])
    panel_E(top[1], res["EF"], res["inner"])
    panel_F(top[2], res["EF"], res["inner"])
    for ax, key in zip(top, "DEF"):
        ax.set_title(PANEL_TITLES[key], fontsize="medium", loc="left")
    for ax, key in zip(bottom, ("G", "H+", "H-", "I")):
        _cross_section(ax, res["cross"][key], None, limits)
        ax.set_title(PANEL_TITLES[key], fontsize="medium", loc="left")
    written.extend(_save(fig, out / "fig2_D-I"))
    return written


def _save(fig, stem: Path) -> list[Path]:
    stem.parent.mkdir(parents=True, exist_ok=True)
    paths = []
    for fmt in FORMATS:
        path = stem.with_suffix("." + fmt)
        fig.savefig(path, dpi=DPI)
        paths.append(path)
    plt.close(fig)
    return paths


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
    args = parser.parse_args(argv)
    out = Path(args.out)
    t0 = time.perf_counter()
    res = compute(args.quick)
    t1 = time.perf_counter()
    written = draw(res, out)
    written.append(write_json(out / "fig2_points.json", points_json(res, args.quick)))
    for path in written:
        print(f"wrote {path}")
    print(f"{SCRIPT}: solved in {t1 - t0:.1f} s, plotted in {time.perf_counter() - t1:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
