"""Paper Fig. 2 J and K: k per embryo from ablation recoils, and the recoil velocities.

Drawn from an :class:`~morphoshell.inverse.InverseResult`
(``morphoshell.inverse.estimate``).  Every kind of marker is in the legend —
the off-scale arrows too, which otherwise read as data at the axis' ends.
"""
from __future__ import annotations

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.legend_handler import HandlerTuple
from matplotlib.lines import Line2D

from .style import DOUBLE_COLUMN, MIN_FONT_SIZE, journal_figure, made_here, styled

__all__ = ["plot_k_estimates", "plot_recoil_velocity", "figure_JK", "MEASURE_COLOURS",
           "OFF_SCALE_LABEL"]

#: Colours of the measures in Fig. 2 J.
MEASURE_COLOURS = {"opening": "tab:blue", "rotation": "tab:orange", "displacement": "tab:green"}
_MEASURE_LABEL = {"opening": r"opening $o$", "rotation": r"rotation $\varrho$",
                  "displacement": r"displacement $d$"}
#: Legend entry of the arrows at the axis' ends (:func:`plot_k_estimates`).
OFF_SCALE_LABEL = "off scale or no k in range"
#: Columns between the groups of embryos (one group per measure).
_GAP = 2
#: Marker sizes (points): one embryo's estimate, a group's mean.
_MS, _MS_MEAN = 4.5, 7.0


def plot_k_estimates(ax: Axes, result, truth=None, ylim=None, *, legend: str = "auto") -> Axes:
    """Estimates of k per embryo (paper Fig. 2 J).

    Three groups (o, ϱ, d), one column per embryo: open markers the paper's
    asymptotic estimates, filled the numerical ones; large markers with bars
    the mean ± standard deviation of each.  Estimates off the axis (or with
    no k in the range, beyond it) are arrows at the axis.  ``truth``, a
    mapping embryo → k, adds grey ticks (synthetic data).  The legend names
    every kind of marker drawn.

    Parameters
    ----------
    ax : Axes
    result
        The result of ``morphoshell.inverse.estimate``.
    truth : mapping, optional
        Embryo → true k.
    ylim : (float, float), optional
        The k axis' range (default: from the result's k range).
    legend : {"auto", "below", "inside", "figure"}
        Under the axes, inside them, or under the whole figure (wider than the
        axes: for a figure of several panels, :func:`figure_JK`); "auto": under
        axes the package made (:func:`~morphoshell.plotting.new_axes`), inside a
        caller's panel (under it, it fell on the panels below).

    Returns
    -------
    Axes
        ``ax``.
    """
    from ..inverse import MEASURES

    if legend not in ("auto", "below", "inside", "figure"):
        raise ValueError(f"legend = {legend!r}: use 'auto', 'below', 'inside' or 'figure'")
    n = len(result.embryos)
    lo, hi = result.settings["k_range"]
    ylim = ylim or (max(lo, -0.6) - 0.05, min(hi, 1.0) + 0.08)
    with styled(ax):
        off_scale = False
        for g, measure in enumerate(MEASURES):
            off_scale |= _group(ax, result, measure, g * (n + _GAP), truth, ylim)
        _reference_lines(ax, result)
        ax.set_ylim(*ylim)
        ax.set_xlim(-1, 3 * (n + _GAP) - _GAP + 1)
        ax.set_xticks([])
        ax.set_xlabel(f"embryos (N = {n}), grouped by measure")
        ax.set_ylabel(r"intrinsic curvature $k$ (units of $1/R$)")
        _k_legend(ax, result, truth is not None, off_scale, legend)
    return ax


def _group(ax: Axes, result, measure: str, x0: float, truth, ylim) -> bool:
    """One measure's column of embryos and its means; whether an estimate was off scale."""
    n, colour, off_scale = len(result.embryos), MEASURE_COLOURS[measure], False
    for j, e in enumerate(result.embryos):
        x = x0 + j
        if truth is not None and e.measurement.embryo in truth:
            ax.plot([x - 0.35, x + 0.35], [truth[e.measurement.embryo]] * 2, color="0.5",
                    lw=1.2, zorder=1)
        for method, filled, dx in (("asymptotic", False, -0.18), ("numerical", True, 0.18)):
            off_scale |= _marker(ax, x + dx, e.estimates[(measure, method)], colour, filled,
                                 ylim)
    for method, filled, dx in (("asymptotic", False, -0.25), ("numerical", True, 0.25)):
        s = result.summary[f"{measure}_{method}"]
        if s.n:
            ax.errorbar(x0 + n + 0.2 + dx, s.mean, yerr=s.std or 0, color=colour, capsize=2.5,
                        marker="o", ms=_MS_MEAN, mfc=colour if filled else "white", mew=1.2,
                        lw=1.2, zorder=3)
    ax.text(x0 + (n - 1) / 2, ylim[1] - 0.01 * (ylim[1] - ylim[0]), _MEASURE_LABEL[measure],
            ha="center", va="top", fontsize=MIN_FONT_SIZE + 1, color=colour)
    return off_scale


def _marker(ax, x, est, colour, filled, ylim) -> bool:
    """One estimate: a circle on the axis, or an arrow at its end; True for an arrow."""
    style = dict(color=colour, mfc=colour if filled else "white", mew=1.0, ms=_MS, zorder=2)
    if est.k is not None and ylim[0] <= est.k <= ylim[1]:
        ax.plot(x, est.k, "o", **style)
        return False
    if est.k is None and est.side is None:
        return False
    below = est.k < ylim[0] if est.k is not None else est.side == "below"
    ax.plot(x, ylim[0] + 0.03 if below else ylim[1] - 0.03, "v" if below else "^", **style)
    return True


def _reference_lines(ax: Axes, result) -> None:
    """k = 0, the stress-free k = 1 (no recoil) and the combined ⟨k⟩."""
    ax.axhline(0.0, color="0.8", lw=0.8, zorder=0)
    ax.axhline(1.0, color="0.8", lw=0.8, ls=":", zorder=0)
    c = result.summary["combined"]
    if c.n:
        ax.axhline(c.mean, color="k", lw=1.0, ls="--", zorder=0,
                   label=rf"$\langle k\rangle = {c.mean:.3f}$ ($\varrho$ and $d$, numerical)")


def _k_legend(ax: Axes, result, truth: bool, off_scale: bool, where: str) -> None:
    """Every marker kind, in grey (the colours are the measures, named above the groups)."""
    from ..inverse.result import methods_ran

    grey = dict(color="0.3", ls="none", mew=1.0)
    entries = []
    if methods_ran(result.settings, "asymptotic"):
        entries.append((Line2D([], [], marker="o", mfc="white", ms=_MS, **grey),
                        "asymptotic (paper's formulas)"))
    if methods_ran(result.settings, "numerical"):   # (an entry of a method not run misled)
        entries.append((Line2D([], [], marker="o", ms=_MS, **grey),
                        f"numerical (toy problem 2, "
                        f"{result.settings['theory'].replace('_', '-')})"))
    entries.append((Line2D([], [], marker="o", ms=_MS_MEAN, **grey), "mean ± std"))
    if off_scale:
        entries.append(((Line2D([], [], marker="^", ms=_MS, **grey),
                         Line2D([], [], marker="v", ms=_MS, **grey)), OFF_SCALE_LABEL))
    if truth:
        entries.append((Line2D([], [], color="0.5", lw=1.2), "true k (synthetic)"))
    handles, labels = ax.get_legend_handles_labels()     # the ⟨k⟩ line
    entries += list(zip(handles, labels))
    options = dict(ncol=3, handler_map={tuple: HandlerTuple(ndivide=None, pad=0.3)},
                   frameon=False, fontsize=MIN_FONT_SIZE, columnspacing=1.2)
    if where == "auto":
        where = "below" if made_here(ax) else "inside"
    if where == "figure":
        ax.figure.legend(*zip(*entries), loc="outside lower center", **options)
    elif where == "inside":
        ax.legend(*zip(*entries), loc="best", **{**options, "ncol": 1})
    else:
        ax.legend(*zip(*entries), loc="upper center", bbox_to_anchor=(0.5, -0.09),
                  borderaxespad=0.0, **options)


def plot_recoil_velocity(ax: Axes, result) -> Axes:
    """Initial recoil velocity V against its scaling H^{5/2}R^{−3/2}|1 − k| (paper Fig. 2 K).

    Main text and Supplementary, "Recoil velocity: scaling argument": the
    straight-line fit through the origin estimates ⟨E/μ⟩.

    Returns
    -------
    Axes
        ``ax``.
    """
    fit = result.velocity
    with styled(ax):
        if fit is None:
            ax.text(0.5, 0.5, "no recoil velocities", transform=ax.transAxes, ha="center")
            ax.set_axis_off()
            return ax
        X, V = np.array(fit.X_um), np.array(fit.V_um_per_s)
        ax.plot(X, V, "o", color="tab:purple", ms=_MS, label="embryos")
        x = np.linspace(0, 1.1 * X.max(), 50)
        se = "" if fit.standard_error is None else rf" \pm {fit.standard_error:.2f}"
        ax.plot(x, fit.E_over_mu * x, "k-", lw=1.0,
                label=r"$V = \langle E/\mu\rangle\,X$ (least squares)")
        ax.set_xlim(0, None)
        ax.set_ylim(0, None)
        ax.set_xlabel(r"$X = H^{5/2}R^{-3/2}|1-k|$ (µm)")
        ax.set_ylabel(r"initial recoil velocity $V$ (µm/s)")
        ax.legend(loc="upper left", fontsize=MIN_FONT_SIZE, frameon=False)
        # the slope with the bounds it gives, in the corner the line leaves free
        ax.text(0.97, 0.03, rf"$\langle E/\mu\rangle = {fit.E_over_mu:.2f}{se}\,"
                            rf"\mathrm{{s^{{-1}}}}$" "\n"
                            f"E ≥ {fit.E_lower_bound_Pa * 1e3:.2g} mPa (μ ≥ "
                            f"{fit.mu_min_Pa_s * 1e3:g} mPa s)\nE H³ ≥ "
                            f"{fit.bending_modulus_lower_bound_J:.2g} J (H = {fit.H_mean_um:.3g} µm)",
                transform=ax.transAxes, ha="right", va="bottom", fontsize=MIN_FONT_SIZE)
    return ax


def figure_JK(result, truth=None, *, pyplot: bool = True) -> Figure:
    """Fig. 2 J and K side by side, two journal columns wide, of an
    :class:`~morphoshell.inverse.InverseResult`.

    Parameters
    ----------
    result : InverseResult
    truth : mapping, optional
        Embryo → true k (synthetic data), drawn as grey ticks.
    pyplot : bool
        Register the figure with pyplot (see :func:`~morphoshell.plotting.journal_figure`).

    Returns
    -------
    Figure
        :func:`plot_k_estimates` and :func:`plot_recoil_velocity`.
    """
    fig = journal_figure(DOUBLE_COLUMN, 0.46 * DOUBLE_COLUMN, pyplot=pyplot)
    with styled(fig):
        a, b = fig.subplots(1, 2, width_ratios=[2.1, 1])
        plot_k_estimates(a, result, truth, legend="figure")
        plot_recoil_velocity(b, result)
        a.set_title("J  intrinsic curvature from ablation recoils", loc="left")
        b.set_title("K  recoil velocity", loc="left")
    return fig
