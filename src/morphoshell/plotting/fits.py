"""A fitted shell over the traced midline it was fitted to, and the residual along it.

Two panels, one journal column wide: the fitted equilibrium (midline and
thickness band, both halves of the section) with the data points over it,
and below it the distance |model − data| (units of R) at each of the fit's
points against the arclength s of the data midline — the terms of E_fit,
showing where along the shell the model misses, which the overlay at print
size cannot.
"""
from __future__ import annotations

import numpy as np
from matplotlib.axes import Axes

from .shells import finish_shell_axes, plot_cross_section, problem_title
from .style import SINGLE_COLUMN, add_caption, journal_figure, made_here, own_axes, styled

__all__ = ["plot_fit", "fit_axes", "fit_residuals"]


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
        One line; "auto": ``name`` (or the problem's), family and theory.
    caption : str or None
        Under the lowest panel; "auto": with an automatic title, the variant,
        method, fitted parameters and E_fit; none on a caller's axes (it would fall
        on the panels below).
    **style
        Line properties of the fitted midline.

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
                           **style)
        r, z = result.data[:, 0], result.data[:, 1]
        ax.plot(np.concatenate([-r[::-1], r]), np.concatenate([z[::-1], z]), ls="none",
                marker="o", ms=2.0, mfc="none", mew=0.5, color="k", label="data", zorder=3)
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
