"""Profile likelihoods of fitted parameters (:mod:`morphoshell.fitting.profiles`).

One panel per parameter: the least-squares objective E_fit² with the other
parameters refitted, against the parameter's value, the threshold that defines
the interval, and the interval itself — where a picture shows what the numbers
hide: an asymmetric profile, a flat one (the data do not determine the
parameter), or refits that did not converge near the crossing.
"""
from __future__ import annotations

import math
import re
from typing import Mapping

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from .style import (DOUBLE_COLUMN, OKABE_ITO, SINGLE_COLUMN, journal_figure, panel_title,
                    styled)

__all__ = ["plot_profiles", "plot_profile", "parameter_label", "parameter_axis_label"]

#: Panels side by side in :func:`plot_profiles` (three fit a double column).
COLUMNS = 3
#: The refits, those that did not converge and the interval, in the package's colours
#: (:data:`~morphoshell.plotting.style.OKABE_ITO`: the tab10 blue, red and orange they were
#: drawn in are not told apart by every reader).
REFIT, NOT_CONVERGED, INTERVAL = (OKABE_ITO["blue"], OKABE_ITO["vermillion"],
                                  OKABE_ITO["orange"])


def parameter_label(name: str) -> str:
    """A fitted parameter's name as the paper writes it (``kappa1`` -> κ₁, ``s3`` -> s₃)."""
    match = re.fullmatch(r"([A-Za-z]+?)(\d*)", name)
    if match is None:
        return name
    base, index = match.groups()
    symbol = {"kappa": r"\kappa", "eta": r"\eta", "sigma": r"\sigma"}.get(base, base)
    return f"${symbol}_{{{index}}}$" if index else f"${symbol}$"


def parameter_axis_label(name: str, units: Mapping[str, str] | None = None) -> str:
    """An axis label of a fitted parameter with its unit: ``κ₁ (1/R)``, ``s₃ (R)``, ``f₁``
    (dimensionless: none), as every other axis of the package has one.

    Parameters
    ----------
    name : str
    units : mapping of str to str, optional
        Parameter → unit as a family declares them (``"R"``, ``"1/R"``, ``"1"``); default:
        the Volvox family's, whose parameters the package fits, with h and the opening
        (lengths).
    """
    if units is None:
        from ..model.profiles import get_family

        units = {"h": "R", "opening": "R", "cut": "R", **get_family("volvox").units}
    unit = units.get(name, "1")
    return parameter_label(name) if unit in ("1", "") else f"{parameter_label(name)} (${unit}$)"


def plot_profile(profile, ax: Axes, *, legend: bool = True,
                 units: Mapping[str, str] | None = None) -> Axes:
    """One profile on ``ax``: E_fit² (R²) against the parameter.

    The refits as blue dots (open vermillion circles where they did not converge), the
    threshold dashed, the interval shaded orange (to the panel's edge on an open
    side), the fit a black dot; the title names the parameter and says when
    the data do not determine it (broken to the width of a caller's ``ax``:
    :func:`~morphoshell.plotting.style.panel_title`).

    Parameters
    ----------
    profile : morphoshell.fitting.Profile
    ax : matplotlib Axes
    legend : bool
        Draw the legend.
    units : mapping of str to str, optional
        The parameters' units, for the x axis (:func:`parameter_axis_label`; default: the
        Volvox family's).
    """
    p = profile
    ok = np.asarray(p.converged, bool) & np.isfinite(p.objective)
    with styled(ax):
        ax.plot(p.values, p.objective, color=REFIT, lw=1.0)
        ax.plot(p.values[ok], p.objective[ok], "o", color=REFIT, ms=3, label="refit")
        if not ok.all():
            ax.plot(p.values[~ok], p.objective[~ok], "o", mfc="none", color=NOT_CONVERGED, ms=4,
                    label="not converged")
        ax.axhline(p.threshold, color="k", ls="--", lw=0.8, label="threshold")
        lo, hi = p.interval
        left, right = ax.get_xlim()
        ax.axvspan(lo if math.isfinite(lo) else left, hi if math.isfinite(hi) else right,
                   color=INTERVAL, alpha=0.2, lw=0, label=f"{100 * p.confidence:g} % interval")
        ax.set_xlim(left, right)
        ax.plot([p.fitted_value], [p.S_min], "o", color="k", ms=4, label="fit")
        ax.set_xlabel(parameter_axis_label(p.name, units))
        ax.set_ylabel(r"$E_\mathrm{fit}^2$ ($R^2$)")
        panel_title(ax, parameter_label(p.name) + _short_verdict(p))
        if legend:
            ax.legend(frameon=False)
    return ax


def plot_profiles(profiles: Mapping, *, pyplot: bool = True,
                  units: Mapping[str, str] | None = None) -> Figure:
    """A panel per profile (:func:`plot_profile`), :data:`COLUMNS` a row, one legend below.

    Parameters
    ----------
    profiles : mapping of str to morphoshell.fitting.Profile
        As :func:`morphoshell.fitting.profile_intervals` returns them.
    pyplot : bool
        See :func:`~morphoshell.plotting.journal_figure` (``False`` for the command line).
    units : mapping of str to str, optional
        The parameters' units (:func:`plot_profile`).

    Returns
    -------
    Figure
        One journal column wide for one profile, two for more.
    """
    n = len(profiles)
    if n == 0:
        raise ValueError("no profiles to plot")
    cols = min(n, COLUMNS)
    rows = -(-n // cols)
    width = SINGLE_COLUMN if cols == 1 else DOUBLE_COLUMN
    fig = journal_figure(width, rows * 0.8 * width / cols + 0.3, pyplot=pyplot)
    with styled(fig):
        axes = fig.subplots(rows, cols, squeeze=False).ravel()
    for ax, p in zip(axes, profiles.values()):
        plot_profile(p, ax, legend=False, units=units)
    for ax in axes[n:]:
        ax.set_visible(False)
    # one legend below the panels, of every kind drawn in any (not over a curve)
    kinds: dict = {}
    for ax in axes[:n]:
        for handle, label in zip(*ax.get_legend_handles_labels()):
            kinds.setdefault(label, handle)
    with styled(fig):
        fig.legend(kinds.values(), kinds.keys(), loc="outside lower center",
                   ncols=len(kinds) if cols > 1 else 3, frameon=False)
    return fig


def _short_verdict(p) -> str:
    """A panel title's words for :meth:`~morphoshell.fitting.profiles.Profile.verdict`."""
    if p.flat:
        return ": not determined"
    if "failed" in p.open_sides():
        return ": open where a refit failed"
    return ": may reach further" if any(p.uncertain_sides()) else ""
