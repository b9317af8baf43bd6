"""Paper Fig. 2 J and K: k per embryo from ablation recoils, and the recoil velocities.

Drawn from an :class:`~morphoshell.inverse.InverseResult`
(``morphoshell.inverse.estimate``).  Every kind of marker is in the legend —
the off-scale arrows too, which otherwise read as data at the axis' ends.
"""
from __future__ import annotations

import warnings

import matplotlib as mpl
import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.font_manager import FontProperties
from matplotlib.legend_handler import HandlerTuple
from matplotlib.lines import Line2D
from matplotlib.transforms import ScaledTranslation

from .style import (DECORATION, DOUBLE_COLUMN, MIN_FONT_SIZE, OKABE_ITO, axes_size,
                    journal_figure, made_here, panel_room, styled, text_width)

__all__ = ["plot_k_estimates", "plot_recoil_velocity", "figure_JK", "MEASURE_COLOURS",
           "VELOCITY_COLOUR",
           "OFF_SCALE_LABEL"]

#: Colours of the measures in Fig. 2 J: Okabe–Ito's (were tab10's blue, orange and green,
#: whose orange and green are 0.097 apart in sRGB as seen with protanopia, one colour:
#: tests/plotting/test_journal_figures.py).
MEASURE_COLOURS = {"opening": OKABE_ITO["blue"], "rotation": OKABE_ITO["orange"],
                   "displacement": OKABE_ITO["bluish green"]}
#: Colour of the embryos' recoil velocities in Fig. 2 K (was tab10's purple).
VELOCITY_COLOUR = OKABE_ITO["reddish purple"]
_MEASURE_LABEL = {"opening": r"opening $o$", "rotation": r"rotation $\varrho$",
                  "displacement": r"displacement $d$"}
#: The measures' symbols: a group's label where the whole name does not fit under it.
_MEASURE_SYMBOL = {"opening": r"$o$", "rotation": r"$\varrho$", "displacement": r"$d$"}
#: Legend entry of the arrows at the axis' ends (:func:`plot_k_estimates`).
OFF_SCALE_LABEL = "off scale or no k in range"
#: Columns between the groups of embryos (one group per measure).
_GAP = 2
#: Marker sizes (points): one embryo's estimate, a group's mean.
_MS, _MS_MEAN = 4.5, 7.0
#: Columns of empty axis right of the last group's means: their markers (7 pt) were cut
#: in half at the axes' edge (a column is 3 pt wide on a 2.3 in panel).
_RIGHT_PAD = 2.0
#: Headroom above the estimates for a legend inside a caller's panel, as a multiple of the
#: legend's estimated height: the estimate uses the axes' size before constrained layout,
#: which shrinks it by up to ~15 % on a 2.4 in high row (audit 19's grids).
_HEADROOM_SAFETY = 1.1
#: Most of a caller's panel the legend's headroom takes (the rest: the estimates).
_MAX_HEADROOM = 0.45
#: The sizes of the legend inside a caller's panel in ems of its font: a handle and the gap
#: to its text (handlelength 1.2 + handletextpad 0.5, shorter than the package's 1.6 + 0.8
#: to fit two columns in a 2.3 in panel), the space between columns, a row
#: (1 + labelspacing 0.5) and the border pads above and below (2 × 0.4 + borderaxespad 0.5).
_HANDLE_EMS, _COLUMN_EMS, _ROW_EMS, _PAD_EMS = 1.7, 0.8, 1.5, 1.3
#: The legend under the axes: its top this many ems of MIN_FONT_SIZE below the axes, under
#: the group labels (tick pad + a line) and the x label (label pad + a line).
_BELOW_AXIS = 4.0


def plot_k_estimates(ax: Axes, result, truth=None, ylim=None, *, legend: str = "auto") -> Axes:
    """Estimates of k per embryo (paper Fig. 2 J).

    Three groups (o, ϱ, d), one column per embryo: open markers the paper's
    asymptotic estimates, filled the numerical ones; large markers with bars
    the mean ± standard deviation of each.  Estimates off the axis (or with
    no k in the range, beyond it) are arrows at the axis.  ``truth``, a
    mapping embryo → k, adds grey ticks (synthetic data).  The legend names
    every kind of marker drawn.  The measures' names are the x axis' labels,
    under their groups (their symbols alone where a name is wider than its
    group, on a small panel).

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
        ax.set_xlim(-1, 3 * (n + _GAP) - _GAP + _RIGHT_PAD)
        _group_labels(ax, MEASURES, n)
        ax.set_xlabel(f"embryos (N = {n}) by measure")
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
    return off_scale


def _group_labels(ax: Axes, measures, n: int) -> None:
    """The measures' names as the x axis' tick labels, one under each group, in its colour.

    Under the axis, not at its top: there they were printed over the off-scale arrows
    (audit 19: "openÅing o"), and on a 2.3 in panel over one another and past the axes'
    edge.  The whole name where it fits in a group's width, else the symbol alone.
    """
    width = axes_size(ax)[0] * (n + _GAP) / (3 * (n + _GAP) - _GAP + 1 + _RIGHT_PAD)
    size = FontProperties(size=mpl.rcParams["xtick.labelsize"]).get_size_in_points()
    fits = all(text_width(_MEASURE_LABEL[m], size) <= 0.9 * width for m in measures)
    names = _MEASURE_LABEL if fits else _MEASURE_SYMBOL
    ax.set_xticks([g * (n + _GAP) + n / 2 for g in range(len(measures))],
                  [names[m] for m in measures])
    ax.tick_params(axis="x", length=0)
    for label, m in zip(ax.get_xticklabels(), measures):
        label.set_color(MEASURE_COLOURS[m])


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
    """Every marker kind, in grey (the colours are the measures, named under the groups)."""
    if where == "auto":
        where = "below" if made_here(ax) else "inside"
    entries = _legend_entries(ax, result, truth, off_scale, short=where == "inside")
    options = dict(ncol=3, handler_map={tuple: HandlerTuple(ndivide=None, pad=0.3)},
                   frameon=False, fontsize=MIN_FONT_SIZE, columnspacing=1.2)
    if where == "figure":
        ax.figure.legend(*zip(*entries), loc="outside lower center", **options)
    elif where == "inside":
        _legend_inside(ax, entries, options)
    else:
        _legend_below(ax, entries, options)


def _legend_below(ax: Axes, entries: list, options: dict):
    """The legend under the axes' tick labels and x label (offset in points: they do not
    scale with the axes), which constrained layout makes room for."""
    below = ScaledTranslation(0, -_BELOW_AXIS * MIN_FONT_SIZE / 72, ax.figure.dpi_scale_trans)
    return ax.legend(*zip(*entries), loc="upper center", bbox_to_anchor=(0.5, 0.0),
                     bbox_transform=ax.transAxes + below, borderaxespad=0.0, **options)


def _legend_entries(ax: Axes, result, truth: bool, off_scale: bool, *, short: bool) -> list:
    """(handle, label) of every marker kind drawn; ``short``: labels of a word or two, for a
    legend inside a small panel."""
    from ..inverse.result import methods_ran

    grey = dict(color="0.3", ls="none", mew=1.0)
    entries = []
    if methods_ran(result.settings, "asymptotic"):
        entries.append((Line2D([], [], marker="o", mfc="white", ms=_MS, **grey),
                        "asymptotic" if short else "asymptotic (paper's formulas)"))
    if methods_ran(result.settings, "numerical"):   # (an entry of a method not run misled)
        entries.append((Line2D([], [], marker="o", ms=_MS, **grey),
                        "numerical" if short else
                        f"numerical (toy problem 2, "
                        f"{result.settings['theory'].replace('_', '-')})"))
    entries.append((Line2D([], [], marker="o", ms=_MS_MEAN, **grey), "mean ± std"))
    if off_scale:
        entries.append(((Line2D([], [], marker="^", ms=_MS, **grey),
                         Line2D([], [], marker="v", ms=_MS, **grey)),
                        "off scale" if short else OFF_SCALE_LABEL))
    if truth:
        entries.append((Line2D([], [], color="0.5", lw=1.2),
                        "true k" if short else "true k (synthetic)"))
    c = result.summary["combined"]
    if c.n:   # the ⟨k⟩ line
        mean = rf"$\langle k\rangle = {c.mean:.3f}$"
        entries.append((Line2D([], [], color="k", lw=1.0, ls="--"),
                        mean if short else rf"{mean} ($\varrho$ and $d$, numerical)"))
    return entries


def _legend_inside(ax: Axes, entries: list, options: dict) -> None:
    """The legend across the top of a caller's panel, in as many columns as its width takes,
    over headroom added above the estimates (and their off-scale arrows), so that it covers
    none of them; the k axis' ticks stay within the estimates' range.

    Audit 19: on a 2.3 in panel one column of the long labels, placed "best", lay over the y
    label and the opening group's estimates.
    """
    size = options["fontsize"]
    width, height = axes_size(ax)
    spacing = _COLUMN_EMS * size
    column = max(_entry_width(label, size) for _, label in entries)
    ncol = int(max(1, min(len(entries), (0.95 * width + spacing) // (column + spacing))))
    rows = -(-len(entries) // ncol)
    needed = _HEADROOM_SAFETY * _legend_height(rows, size)
    share = min(needed / height, _MAX_HEADROOM)
    if needed / height > _MAX_HEADROOM:
        warnings.warn(f"plot_k_estimates: a panel of {width / 72:.1f} × {height / 72:.1f} in "
                      f"(axes) is too small for the legend inside it, which covers estimates; "
                      f"use legend='figure' (under the whole figure) or a panel of about "
                      f"2.3 × 1.8 in or more", UserWarning, stacklevel=4)
    low, high = ax.get_ylim()
    ticks = [t for t in ax.get_yticks() if low <= t <= high]
    ax.set_ylim(low, low + (high - low) / (1.0 - share))
    ax.set_yticks(ticks)
    ax.legend(*zip(*entries), loc="upper center", **{**options, "ncol": ncol,
                                                     "columnspacing": _COLUMN_EMS,
                                                     "handlelength": 1.2, "handletextpad": 0.5})


def _entry_width(label: str, size: float) -> float:
    """Width (points) of a legend entry of ``label`` in a font of ``size``: its handle, the
    gap and its text (:data:`_HANDLE_EMS`); Fig. 2 J's legend and K's small one."""
    return text_width(label, size) + _HANDLE_EMS * size


def _legend_height(rows: int, size: float) -> float:
    """Height (points) of a legend of ``rows`` rows (its title's lines included) in a font
    of ``size``, its border pads included; Fig. 2 J's legend and K's small one."""
    return (rows * _ROW_EMS + _PAD_EMS) * size


def plot_recoil_velocity(ax: Axes, result) -> Axes:
    """Initial recoil velocity V against its scaling H^{5/2}R^{−3/2}|1 − k| (paper Fig. 2 K).

    Main text and Supplementary, "Recoil velocity: scaling argument": the
    straight-line fit through the origin estimates ⟨E/μ⟩.  Its slope and the bounds it
    gives are written in the corner the line leaves free where they fit there; on a
    small panel (a 1.75 in column of a journal's grid, figure_JK's 2.3 in) they and the
    legend, its labels short, go under the axes (constrained layout makes room; in a
    figure without it they may fall on a panel below), and the y label is the symbol
    alone where the whole name is longer than the axes.  A panel too small for them
    (about 1.75 × 1.6 in; smaller, the axes shrink to nothing) gives a warning naming
    the size that holds them.

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
        ax.plot(X, V, "o", color=VELOCITY_COLOUR, ms=_MS)
        x = np.linspace(0, 1.1 * X.max(), 50)
        ax.plot(x, fit.E_over_mu * x, "k-", lw=1.0)
        ax.set_xlim(0, None)
        ax.set_ylim(0, None)
        ax.set_xlabel(r"$X = H^{5/2}R^{-3/2}|1-k|$ (µm)")
        lines = _velocity_lines(fit)
        handles = [Line2D([], [], ls="none", marker="o", color=VELOCITY_COLOUR, ms=_MS),
                   Line2D([], [], color="k", lw=1.0)]
        below = 0.0
        if _fits_in_corners(ax, lines):
            ax.legend(handles, ["embryos", _FIT_LABEL], loc="upper left",
                      fontsize=MIN_FONT_SIZE, frameon=False)
            ax.text(0.97, 0.03, "\n".join(lines), transform=ax.transAxes, ha="right",
                    va="bottom", fontsize=MIN_FONT_SIZE)
        else:
            options = _small_legend(ax, lines)
            _legend_below(ax, list(zip(handles, ["embryos", "least squares"])), options)
            below = _room_below(ax, lines, options["ncol"])
        _velocity_ylabel(ax, axes_size(ax)[1] - below)
    return ax


def _small_legend(ax: Axes, lines: list[str]) -> dict:
    """Options of the legend under a small panel: the slope and bounds its title (over its
    entries), its two entries side by side where that is no wider than the axes or the
    title."""
    size = MIN_FONT_SIZE
    room = max(axes_size(ax)[0], *(text_width(line, size) for line in lines))
    return dict(ncol=2 if _entries_width(2) <= room else 1, frameon=False, fontsize=size,
                title="\n".join(lines), title_fontsize=size, columnspacing=_COLUMN_EMS,
                handlelength=1.2, handletextpad=0.5)


def _entries_width(ncol: int) -> float:
    """Width (points) of the entries of the legend under a small panel, in ``ncol`` columns."""
    size = MIN_FONT_SIZE
    widths = [_entry_width(label, size) for label in ("embryos", "least squares")]
    return sum(widths) + _COLUMN_EMS * size if ncol == 2 else max(widths)


def _room_below(ax: Axes, lines: list[str], ncol: int) -> float:
    """The height (points) the legend under a small panel's axes takes from them, beyond the
    x tick labels and label (:data:`DECORATION`) it replaces; warns where the panel is too
    small for it (:data:`_MIN_AXES`).

    Audit 23: on a 2.5 in square the whole y label, chosen for the axes' height before the
    legend was put under them, ran 5 pt past the figure's top; at 1.6 in and less the axes
    shrank to nothing, the legend being wider than the panel.
    """
    size = MIN_FONT_SIZE
    rows = len(lines) + (1 if ncol == 2 else 2)    # the title's lines and the entries' rows
    height = _BELOW_AXIS * size + _legend_height(rows, size)
    width = max(_entries_width(ncol), *(text_width(line, size) for line in lines)) + \
        _BORDER_EMS * size
    need = (max(width, _MIN_AXES + DECORATION), height + _MIN_AXES)
    room = panel_room(ax, _MIN_AXES)
    if room[0] < need[0] or room[1] < need[1]:
        cell = [(s + DECORATION) / 72 for s in axes_size(ax)]
        smallest = [np.ceil(s / 72 * 20) / 20 for s in need]    # to 0.05 in
        warnings.warn(f"plot_recoil_velocity: a panel of {cell[0]:.2f} × {cell[1]:.2f} in "
                      f"is too small for the slope, bounds and legend under its axes, which "
                      f"shrink to less than {_MIN_AXES / 72:g} in; use a panel of about "
                      f"{smallest[0]:.2f} × {smallest[1]:.2f} in or more", UserWarning,
                      stacklevel=4)
    return height - DECORATION


#: The legend's label of the least-squares line where the panel has room for it.
_FIT_LABEL = r"$V = \langle E/\mu\rangle\,X$ (least squares)"
#: Most of the axes' width the slope-and-bounds text (lower right, under the line) and the
#: legend (upper left, over it) may take each; the data lie along the diagonal between.
_CORNER_SHARE = 0.6
#: Most of the axes' height the two may take together (legend rows and text lines).
_CORNERS_HEIGHT = 0.5
#: Least width and height (points) of the axes of a small panel, its slope, bounds and
#: legend under them (half an inch: on a 1.75 in square they are 83 × 48 pt).
_MIN_AXES = 36.0
#: The legend's border pads left and right of its widest line (2 × 0.4), in ems.
_BORDER_EMS = 0.8


def _velocity_lines(fit) -> list[str]:
    """The slope ⟨E/μ⟩ (± its standard error) and the bounds on E and E H³ it gives."""
    se = "" if fit.standard_error is None else rf" \pm {fit.standard_error:.2f}"
    return [rf"$\langle E/\mu\rangle = {fit.E_over_mu:.2f}{se}\,\mathrm{{s^{{-1}}}}$",
            f"E ≥ {fit.E_lower_bound_Pa * 1e3:.2g} mPa (μ ≥ {fit.mu_min_Pa_s * 1e3:g} mPa s)",
            f"E H³ ≥ {fit.bending_modulus_lower_bound_J:.2g} J (H = {fit.H_mean_um:.3g} µm)"]


def _fits_in_corners(ax: Axes, lines: list[str]) -> bool:
    """Whether the legend (upper left) and the slope and bounds (lower right) fit in the
    corners the data leave free (estimated, before anything is drawn).  Audit: on a
    1.75 in panel they covered the data, the line and the y label."""
    width, height = axes_size(ax)
    size = MIN_FONT_SIZE
    widest = max(*(text_width(t, size) for t in lines), _entry_width(_FIT_LABEL, size))
    tall = (len(lines) + 2) * _ROW_EMS * size
    return widest <= _CORNER_SHARE * width and tall <= _CORNERS_HEIGHT * height


def _velocity_ylabel(ax: Axes, height: float) -> None:
    """The y label: its whole name, or the symbol alone where the name is longer than the
    axes' ``height`` (points) (it ran past the figure's edge at 1.75 in)."""
    name = r"initial recoil velocity $V$ (µm/s)"
    size = FontProperties(size=mpl.rcParams["axes.labelsize"]).get_size_in_points()
    ax.set_ylabel(name if text_width(name, size) <= height else r"$V$ (µm/s)")


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
