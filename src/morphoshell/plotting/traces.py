"""The traces of one stage over their average, and where along the midline they differ.

Two panels, one journal column wide: each single-trace midline (model gauge,
units of R) with their average and its ±spread band over them, and below
it each trace's distance from the traces' pointwise median against the
average's arclength.  The check before a campaign: a trace at the wrong
scale, flipped or traced along another path stands out in both.
"""
from __future__ import annotations

from typing import Sequence

import numpy as np
from matplotlib.figure import Figure

from .style import SINGLE_COLUMN, add_caption, journal_figure, styled

__all__ = ["plot_traces"]


def plot_traces(mean, midlines: Sequence, names: Sequence[str] | None = None, *,
                caption: str | None = "auto", pyplot: bool = True) -> Figure:
    """The single traces over their average, and each one's distance from their median.

    Parameters
    ----------
    mean : morphoshell.io.Midline
        The average (:func:`morphoshell.io.average` of ``midlines``).
    midlines : sequence of morphoshell.io.Midline
        The single-trace midlines, at least two.
    names : sequence of str, optional
        The traces' labels (default: "trace 1", "trace 2", ...).
    caption : str or None
        Under the lower panel; "auto": how many traces, the mean spread and
        the largest rms distance.
    pyplot : bool
        See :func:`~morphoshell.plotting.journal_figure` (``False`` for the command line).

    Returns
    -------
    Figure
    """
    names = list(names or (f"trace {k}" for k in range(1, len(midlines) + 1)))
    fig = journal_figure(SINGLE_COLUMN, 1.25 * SINGLE_COLUMN, pyplot=pyplot)
    from ..io.midlines import trace_distances

    distances = trace_distances(midlines)
    s = np.r_[0.0, np.cumsum(np.hypot(*np.diff(mean.points, axis=0).T))]
    with styled(fig):
        top, bottom = fig.subplots(2, 1, height_ratios=(2.2, 1))
        for m, name, d in zip(midlines, names, distances):
            line, = top.plot(m.r, m.z, lw=0.8, label=name)
            bottom.plot(s, d, lw=0.7, color=line.get_color())
        if mean.spread is not None:
            top.fill_between(mean.r, mean.z - mean.spread, mean.z + mean.spread, color="0.8",
                             lw=0, label="± spread", zorder=0)
        # thin and dashed: the traces differ by a few 1e-3 R and would vanish under it
        top.plot(mean.r, mean.z, color="k", lw=0.6, ls="--", label="average", zorder=3)
        top.set_aspect("equal", adjustable="datalim")
        top.set_xlabel(r"$r/R$")
        top.set_ylabel(r"$z/R$")
        top.legend(loc="center left", bbox_to_anchor=(1.0, 0.5), fontsize="x-small",
                   frameon=False)
        bottom.set_xlim(0.0, float(s[-1]))
        bottom.set_ylim(0.0, None)
        bottom.set_xlabel(r"arclength $s/R$ of the average, from the pole")
        bottom.set_ylabel(r"distance$/R$")
        if caption == "auto":
            rms = np.sqrt((distances ** 2).mean(axis=1))
            spread = float(np.mean(mean.spread)) if mean.spread is not None else 0.0
            caption = (f"below: each trace's distance from the traces' pointwise median; "
                       f"{len(midlines)} traces, mean spread {spread:.2g} R, "
                       f"largest rms distance {rms.max():.2g} R ({names[int(rms.argmax())]})")
        if caption:
            add_caption(bottom, caption)
    return fig
