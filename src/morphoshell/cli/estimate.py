"""``morphoshell estimate``: intrinsic curvature k and E/μ from ablation recoils (Fig. 2 J–K).

Also the figure panels (:func:`panel_J`, :func:`panel_K`, :func:`figure_JK`),
shared with ``scripts/fig2jk_estimates.py``.
"""
from __future__ import annotations

import argparse

from ._args import add_outputs, integer, real
from ._outputs import Outputs

__all__ = ["register", "panel_J", "panel_K", "figure_JK"]

_DESCRIPTION = """\
Estimate the intrinsic curvature k of each embryo from the recoil of a laser
ablation, and E/mu from the initial recoil velocities (paper, Fig. 2 J-K).

MEASUREMENTS.csv has one row per embryo and the columns embryo, R_um
(posterior radius), H_um (sheet thickness), hole_diameter_um (diameter
2R sin(Sigma) of the ablated cap on the intact shell), opening_um (R o, the
signed change of the hole's diameter), rotation_deg (rho, positive when the
edge unfurls outwards, in (-180, 180)) and displacement_um (R d, a distance);
optionally V_um_per_s (initial recoil velocity) and the measurement errors
sigma_opening_um, sigma_rotation_deg, sigma_displacement_um (one standard
deviation). Other columns are kept and ignored; an empty cell is a missing
measure; lines starting with # are comments. The shell is nondimensionalised
by R: h = H/R, Sigma = arcsin(hole_diameter / 2R).

The observables are those of `morphoshell ablate`: the post-ablation minus
the intact (Sigma = 0) equilibrium of the same shell at the material point
s = Sigma, z in the far-end gauge (the far pole keeps its height).

Each measure gives k by: the leading-order asymptotics (Sigma = O(1)), the
small-cut Kelvin forms (rotation, displacement), the nonlinear inner problem
(all three), and numerical inversion of toy problem 2 at the embryo's own h
and Sigma (safeguarded Newton with the exact derivative); "asymptotic" is the
paper's choice (leading order for o, Kelvin for rho and d). A measure that no
k in --k-range produces gives null and a reason ("outside the range", "not
monotonic"). Errors propagate to k to first order. The combined k of an
embryo is the inverse-variance weighted mean of its numerical rho and d
estimates (their mean without errors). E/mu (1/s) is the least-squares slope
through the origin of V against H^(5/2) R^(-3/2) |1 - k|; E >= (E/mu) mu_min
(Pa) and the bending modulus E H^3 (J, mean H).

JSON: embryos (k_<measure>_<method>[_error], k_combined, notes), summary (n,
mean, std, bootstrap 95% interval of the mean, per estimate and combined) and,
with velocities, E_over_mu, E_over_mu_standard_error, E_lower_bound_Pa,
bending_modulus_lower_bound_J. CSV: the per-embryo table."""


def register(sub) -> None:
    p = sub.add_parser("estimate", help="intrinsic curvature k and E/mu from ablation recoils",
                       description=_DESCRIPTION,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("measurements", metavar="MEASUREMENTS.csv", help="the measurement table")
    p.add_argument("--theory", choices=("large_bending", "classical"), default="large_bending",
                   help="shell theory of the numerical inversion (default large_bending)")
    p.add_argument("--mu-min", type=real(0, 1e6, open_lo=True, unit=" Pa s"), default=8e-4,
                   metavar="PA_S", help="lower bound of the effective viscosity in Pa s "
                                        "(default 8e-4, algal growth medium)")
    p.add_argument("--k-range", nargs=2, type=real(-100, 100), default=(-1.0, 1.0),
                   metavar=("LO", "HI"), help="range of k searched (default -1 1: from an "
                                              "intrinsic curvature reversed relative to the sphere "
                                              "to the stress-free k = 1)")
    p.add_argument("--bootstrap", type=integer(0, 1_000_000), default=2000, metavar="N",
                   help="bootstrap resamples of the 95%% intervals (default 2000; 0: none)")
    p.add_argument("--seed", type=integer(0, 2**32 - 1), default=0, metavar="S",
                   help="seed of the bootstrap (default 0)")
    p.add_argument("--nodes", type=integer(20, 3200), default=60, metavar="N",
                   help="mesh nodes of the numerical model (default 60: k to ~4e-5)")
    p.add_argument("--workers", type=integer(1, 256), default=None, metavar="N",
                   help="processes sharing the embryos (default: one per core); the "
                        "estimates do not depend on it")
    add_outputs(p, json="write every estimate, the summary and the E/mu fit as JSON",
                csv="write the per-embryo estimates as CSV",
                plot="write Fig. 2 J (and K with velocities)")
    p.set_defaults(run=_estimate)


def _estimate(args) -> int:
    from ..inverse import estimate, read_measurements
    from ..io import write_csv, write_json

    lo, hi = args.k_range
    if not lo < hi:
        raise ValueError(f"--k-range {lo:g} {hi:g}: LO must be smaller than HI")
    data = read_measurements(args.measurements)
    result = estimate(data, theory=args.theory, k_range=(lo, hi), mu_min=args.mu_min,
                      bootstrap=args.bootstrap, seed=args.seed, nodes=args.nodes,
                      workers=args.workers)
    print(f"{args.measurements}: {result}")
    print(f"  ({result.timing['total']:.1f} s; numerical estimates "
          f"{result.timing['numerical_seconds']:.1f} s)")
    out = Outputs()
    out.add(args.json, lambda path: write_json(path, {"input": str(args.measurements),
                                                      **result.to_dict()}))
    out.add(args.csv, lambda path: write_csv(path, result.table()))
    if args.plot:
        fig = figure_JK(result)
        out.add(args.plot, lambda path: fig.savefig(path, dpi=130))
    for path in out.commit():
        print(f"  wrote {path}")
    return 0


# --------------------------------------------------------------------------
# Fig. 2 J and K
# --------------------------------------------------------------------------

#: Colours of the measures in Fig. 2 J.
COLOURS = {"opening": "tab:blue", "rotation": "tab:orange", "displacement": "tab:green"}
_LABEL = {"opening": r"opening $o$", "rotation": r"rotation $\varrho$",
          "displacement": r"displacement $d$"}


def panel_J(ax, result, truth=None, ylim=None):
    """Estimates of k per embryo (paper Fig. 2 J).

    Three groups (o, ϱ, d), one column per embryo: open markers the paper's
    asymptotic estimates, filled the numerical ones; large markers with bars
    the mean ± standard deviation of each.  Estimates off the axis (or with
    no k in the range, beyond it) are arrows at the axis.  ``truth``, a
    mapping embryo → k, adds grey ticks (synthetic data).
    """
    from ..inverse import MEASURES

    n = len(result.embryos)
    lo, hi = result.settings["k_range"]
    ylim = ylim or (max(lo, -0.6) - 0.05, min(hi, 1.0) + 0.08)
    gap = 2
    for g, measure in enumerate(MEASURES):
        x0 = g * (n + gap)
        colour = COLOURS[measure]
        for j, e in enumerate(result.embryos):
            x = x0 + j
            if truth is not None and e.measurement.embryo in truth:
                ax.plot([x - 0.35, x + 0.35], [truth[e.measurement.embryo]] * 2, color="0.5",
                        lw=1.2, zorder=1)
            for method, filled, dx in (("asymptotic", False, -0.18), ("numerical", True, 0.18)):
                est = e.estimates[(measure, method)]
                _marker(ax, x + dx, est, colour, filled, ylim)
        for method, filled, dx in (("asymptotic", False, -0.25), ("numerical", True, 0.25)):
            s = result.summary[f"{measure}_{method}"]
            if s.n:
                ax.errorbar(x0 + n + 0.2 + dx, s.mean, yerr=s.std or 0, color=colour, capsize=3,
                            marker="o", ms=9, mfc=colour if filled else "white", mew=1.5, lw=1.5,
                            zorder=3)
        ax.text(x0 + (n - 1) / 2, ylim[1] - 0.01 * (ylim[1] - ylim[0]), _LABEL[measure],
                ha="center", va="top", fontsize="small", color=colour)
    ax.axhline(0.0, color="0.8", lw=0.8, zorder=0)
    ax.axhline(1.0, color="0.8", lw=0.8, ls=":", zorder=0)   # stress-free: no recoil
    c = result.summary["combined"]
    if c.n:
        ax.axhline(c.mean, color="k", lw=1.0, ls="--", zorder=0,
                   label=rf"$\langle k\rangle = {c.mean:.3f}$ ($\varrho$ and $d$, numerical)")
    ax.set_ylim(*ylim)
    ax.set_xlim(-1, 3 * (n + gap) - gap + 1)
    ax.set_xticks([])
    ax.set_xlabel(f"embryos (N = {n}), grouped by measure; large markers: mean ± std")
    ax.set_ylabel(r"intrinsic curvature $k$ (units of $1/R$)")
    ax.plot([], [], "o", color="0.3", mfc="white", label="asymptotic (paper's formulas)")
    ax.plot([], [], "o", color="0.3",
            label=f"numerical (toy problem 2, {result.settings['theory']})")
    if truth is not None:
        ax.plot([], [], "-", color="0.5", label="true k (synthetic data)")
    ax.legend(loc="lower left", fontsize="x-small", frameon=False)


def _marker(ax, x, est, colour, filled, ylim):
    style = dict(color=colour, mfc=colour if filled else "white", mew=1.1, ms=5, zorder=2)
    if est.k is not None and ylim[0] <= est.k <= ylim[1]:
        ax.plot(x, est.k, "o", **style)
    elif est.k is not None or est.side is not None:
        below = est.k < ylim[0] if est.k is not None else est.side == "below"
        ax.plot(x, ylim[0] + 0.03 if below else ylim[1] - 0.03, "v" if below else "^", **style)


def panel_K(ax, result):
    """Initial recoil velocity V against its scaling H^{5/2}R^{−3/2}|1 − k| (paper Fig. 2 K)."""
    import numpy as np

    fit = result.velocity
    if fit is None:
        ax.text(0.5, 0.5, "no recoil velocities", transform=ax.transAxes, ha="center")
        ax.set_axis_off()
        return
    X, V = np.array(fit.X_um), np.array(fit.V_um_per_s)
    ax.plot(X, V, "o", color="tab:purple", ms=5, label="embryos")
    x = np.linspace(0, 1.1 * X.max(), 50)
    se = "" if fit.standard_error is None else rf" \pm {fit.standard_error:.2f}"
    ax.plot(x, fit.E_over_mu * x, "k-", lw=1.2,
            label=rf"$V = \langle E/\mu\rangle\,X$, $\langle E/\mu\rangle = {fit.E_over_mu:.2f}"
                  rf"{se}\,\mathrm{{s^{{-1}}}}$")
    ax.set_xlim(0, None)
    ax.set_ylim(0, None)
    ax.set_xlabel(r"$X = H^{5/2}R^{-3/2}|1-k|$ (µm)")
    ax.set_ylabel(r"initial recoil velocity $V$ (µm/s)")
    ax.legend(loc="upper left", fontsize="x-small", frameon=False)
    ax.text(0.97, 0.03, f"E ≥ {fit.E_lower_bound_Pa * 1e3:.2g} mPa (μ ≥ {fit.mu_min_Pa_s * 1e3:g} "
                        f"mPa s)\nE H³ ≥ {fit.bending_modulus_lower_bound_J:.2g} J "
                        f"(H = {fit.H_mean_um:.3g} µm)",
            transform=ax.transAxes, ha="right", va="bottom", fontsize="x-small")


def figure_JK(result, truth=None):
    """Fig. 2 J and K side by side (a Matplotlib figure)."""
    from ..plotting import plt

    fig, (a, b) = plt.subplots(1, 2, figsize=(11.5, 4.4), gridspec_kw={"width_ratios": [2.2, 1]},
                               constrained_layout=True)
    panel_J(a, result, truth)
    panel_K(b, result)
    a.set_title("J  intrinsic curvature from ablation recoils", loc="left", fontsize="medium")
    b.set_title("K  recoil velocity", loc="left", fontsize="medium")
    return fig
