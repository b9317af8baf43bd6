"""A fitted shell over the traced midline it was fitted to, and the residual along it.

Two panels, one journal column wide: the fitted equilibrium (midline and
thickness band, both halves of the section) with the data points over it,
and below it the distance |model − data| (units of R) at each of the fit's
points against the arclength s of the data midline — the terms of E_fit,
showing where along the shell the model misses, which the overlay at print
size cannot.

A fit that did not converge is drawn as such wherever fits are drawn: in a
series of fits (:func:`plot_fit_series`, e.g. E_fit or a fitted parameter
against pseudotime) with an open marker (:data:`NOT_CONVERGED`, legend entry
:func:`not_converged_handle`), and a panel of its shell hatched
(:func:`~morphoshell.plotting.style.flag_panel`) with the note in its title.
"""
from __future__ import annotations

import numpy as np
from matplotlib.axes import Axes
from matplotlib.cbook import normalize_kwargs
from matplotlib.lines import Line2D

from .shells import finish_shell_axes, plot_cross_section, problem_title
from .style import SINGLE_COLUMN, add_caption, journal_figure, made_here, own_axes, styled

__all__ = ["plot_fit", "fit_axes", "fit_residuals", "plot_fit_series", "not_converged_handle",
           "NOT_CONVERGED", "DATA_STYLE", "FIT_ZORDER"]

#: The label of fits that did not converge (open markers in :func:`plot_fit_series`).
NOT_CONVERGED = "not converged"
#: The data points of :func:`plot_fit`: small open grey circles, under the fitted midline
#: (:data:`FIT_ZORDER`).  Drawn over it in black, the 200 circles of a traced midline hid
#: the fit wholly (audit 25); under it, each circle shows beside the line where the two
#: agree and apart from it where they do not.
DATA_STYLE = {"ls": "none", "marker": "o", "ms": 2.4, "mfc": "none", "mew": 0.5,
              "color": "0.4", "zorder": 3.0}
#: zorder of the fitted midline: over the data points and the thickness band.
FIT_ZORDER = 4.0


def plot_fit_series(ax: Axes, x, y, converged, *, yerr=None, color: str = "k",
                    marker: str = "o", ls: str = "-", ms: float = 3.0,
                    label: str | None = None, **line) -> list:
    """A quantity of several fits (E_fit, a fitted parameter) against e.g. pseudotime:
    a line through all of them, a filled marker where the fit converged, an open one
    where it did not.

    Parameters
    ----------
    ax : Axes
    x, y : array_like, shape (n,)
    converged : array_like of bool, shape (n,)
        Each fit's ``converged`` (a campaign's records, ``FitResult.converged``).
    yerr : array_like, shape (n,), optional
        Error bars, on the converged fits only (an unconverged fit's errors mean
        nothing).
    color, marker, ls, ms : str, str, str, float
        The series' colour, marker, line style ("" or "none": no line) and marker size.
    label : str, optional
        The legend's label of the series (its line and filled marker); the open
        markers are left out of the legend: add :func:`not_converged_handle`.
    **line
        Further properties of the line.

    Returns
    -------
    list
        The artists drawn: the series (line and filled markers, or line and error
        bars), then the open markers.
    """
    x, y = np.asarray(x, float), np.asarray(y, float)
    ok = np.asarray(converged, bool)
    no_line = ls in ("", "none", "None")
    if yerr is None:        # one artist: the legend shows the line through a filled marker
        drawn = ax.plot(x, y, ls="none" if no_line else ls, marker=marker,
                        markevery=[int(i) for i in np.flatnonzero(ok)], ms=ms, color=color,
                        label=label, **line)
    else:
        drawn = [] if no_line else ax.plot(x, y, ls=ls, color=color, label="_nolegend_",
                                           **line)
        drawn.append(ax.errorbar(x[ok], y[ok], yerr=np.asarray(yerr, float)[ok], fmt=marker,
                                 ms=ms, color=color, capsize=2, label=label))
    # open (white-filled, over the line), a little larger: visible at print size
    drawn += ax.plot(x[~ok], y[~ok], ls="none", marker=marker, ms=ms + 1, mfc="white",
                     mec=color, color=color, label="_nolegend_", zorder=3)
    return drawn


def not_converged_handle(marker: str = "o", color: str = "0.3"):
    """The legend entry of :func:`plot_fit_series`'s open markers (fits that did not converge)."""
    from matplotlib.lines import Line2D

    return Line2D([], [], ls="none", marker=marker, mfc="white", mec=color, color=color,
                  label=NOT_CONVERGED)


def fit_residuals(result) -> tuple[np.ndarray, np.ndarray]:
    """Arclength of the data midline and the distance |model − data| at each fit point.

    Parameters
    ----------
    result : morphoshell.fitting.FitResult

    Returns
    -------
    s, distance : ndarray, shape (N,)
        s from the first data point (the pole) along the data's polyline,
        and the Euclidean distance of model and data point (both in units
        of R; E_fit is the root of the sum of the distances' squares).
    """
    data, model = np.asarray(result.data, float), np.asarray(result.model, float)
    s = np.r_[0.0, np.cumsum(np.hypot(*np.diff(data, axis=0).T))]
    return s, np.hypot(*(model - data).T)


def fit_axes(*, pyplot: bool = True) -> tuple[Axes, Axes]:
    """The two axes of :func:`plot_fit` in a new single-column figure: shell above, residual below.

    Parameters
    ----------
    pyplot : bool
        See :func:`~morphoshell.plotting.journal_figure` (``False`` for the command line).
    """
    # about the height the shell (equal aspect, full width) and a strip below it need
    fig = journal_figure(SINGLE_COLUMN, 1.12 * SINGLE_COLUMN, pyplot=pyplot)
    with styled(fig):
        shell, residual = fig.subplots(2, 1, height_ratios=(2.4, 1))
    return own_axes(shell), own_axes(residual)


def plot_fit(result, ax: Axes | None = None, *, residual_ax: Axes | None = None,
             name: str | None = None, title: str | None = "auto",
             caption: str | None = "auto", **style) -> Axes:
    """A fitted shell (midline and thickness band) over the data midline, and its residual.

    Parameters
    ----------
    result : morphoshell.fitting.FitResult
    ax : matplotlib Axes, optional
        The overlay's axes.  If not given, a new figure (:func:`fit_axes`)
        holds it and the residual panel.
    residual_ax : matplotlib Axes, optional
        The residual's axes (|model − data| against s); none with a given
        ``ax`` and no ``residual_ax``.
    name : str, optional
        What was fitted (e.g. the trace's file name), named in the title.
    title : str or None
        One line (on a caller's ``ax`` broken to its width:
        :func:`~morphoshell.plotting.style.panel_title`); "auto": ``name`` (or the
        problem's), family and theory.
    caption : str or None
        Under the lowest panel; "auto": with an automatic title, the variant,
        method, fitted parameters and E_fit; none on a caller's axes (it would fall
        on the panels below).
    **style
        Line properties of the fitted midline (drawn over the data: :data:`FIT_ZORDER`).

    Returns
    -------
    Axes
        The overlay's axes.

    Raises
    ------
    ValueError
        A fit without its equilibrium (read back by :func:`morphoshell.fitting.load_fit`).
    """
    if result.equilibrium is None:
        raise ValueError("plot_fit draws the fitted equilibrium, which a fit read back from "
                         "its JSON (load_fit) does not hold: solve result.problem for it")
    if ax is None:
        ax, residual_ax = fit_axes()
    problem = result.equilibrium.problem
    if caption == "auto":
        lowest = residual_ax if residual_ax is not None else ax
        caption = _fit_caption(result) if title == "auto" and made_here(lowest) else None
    if title == "auto":
        title = problem_title(problem, name)
    with styled(ax):
        plot_cross_section(result.equilibrium, ax, title=None, legend=False, label="fit",
                           **{"zorder": FIT_ZORDER, **normalize_kwargs(style, Line2D)})
        r, z = result.data[:, 0], result.data[:, 1]
        ax.plot(np.concatenate([-r[::-1], r]), np.concatenate([z[::-1], z]), label="data",
                **DATA_STYLE)
        # the legend inside: beside, it would narrow the shell in a one-column figure
        finish_shell_axes(ax, title, "inside", None if residual_ax is not None else caption)
        if residual_ax is not None:
            _residual_panel(residual_ax, result, caption)
    return ax


def _residual_panel(ax: Axes, result, caption: str | None) -> None:
    """|model − data| against the arclength of the data, from the pole."""
    s, distance = fit_residuals(result)
    ax.plot(s, distance, "-o", color="k", lw=0.8, ms=1.8, label="|model − data|")
    ax.set_xlim(0.0, float(s[-1]))
    ax.set_ylim(0.0, None)
    ax.set_xlabel(r"arclength $s/R$ of the data, from the pole")
    ax.set_ylabel(r"$|$model − data$|/R$")
    if caption:
        add_caption(ax, caption)


def _fit_caption(result) -> str:
    """Variant, method, how many parameters, E_fit and the largest miss; the fixed values."""
    s, distance = fit_residuals(result)
    p = result.parameters
    held = f"h = {p['h']:g}, opening P = {p['opening']:g}"
    return (f"{result.variant} variant, {result.method} fit of {len(result.fitted)} parameters; "
            f"E_fit = {result.E_fit:.3g} R over {len(s)} points, largest |model − data| = "
            f"{distance.max():.2g} R; {held}")
