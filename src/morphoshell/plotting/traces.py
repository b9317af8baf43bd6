"""The traces of one stage over their average, and where along the midline they differ.

Two panels, one journal column wide: each single-trace midline (model gauge,
units of R) with their average and its ±spread band over them, and below
it each trace's distance from the traces' pointwise median against the
average's arclength.  The check before a campaign: a trace at the wrong
scale, flipped or traced along another path stands out in both.
"""
from __future__ import annotations

import os
from typing import Sequence

import numpy as np
from matplotlib.figure import Figure
from matplotlib.transforms import ScaledTranslation

from .style import (MIN_FONT_SIZE, OKABE_ITO, SINGLE_COLUMN, add_caption, journal_figure,
                    styled, text_width)

__all__ = ["plot_traces", "trace_styles", "TRACE_DASHES"]

#: Line styles of the traces, one per round of the colours (:func:`trace_styles`): solid,
#: dotted, dash-dotted; the dashes are the average's.
TRACE_DASHES = ("-", ":", "-.")

#: The legend's top under the shape's axes, in ems of MIN_FONT_SIZE: under its tick labels
#: (pad + a line) and the r label (pad + a line).
_BELOW_AXIS = 4.0


def _short_names(names: Sequence[str]) -> tuple[list[str], str | None]:
    """The part of each name that differs from the others, and what they share as a title
    ("synthetic_embryo…_midline" over "1" … "5"), or the names and None where nothing is
    shared: five file names took half a column beside the shape (audit 19).  A shared
    end stops at digits, so that embryo10 and embryo11 keep their numbers whole."""
    if len(names) < 2:
        return list(names), None
    head = os.path.commonprefix(list(names)).rstrip("0123456789")
    tail = os.path.commonprefix([n[::-1] for n in names])[::-1].lstrip("0123456789")
    if len(head) + len(tail) == 0 or any(len(n) <= len(head) + len(tail) for n in names):
        return list(names), None
    return [n[len(head):len(n) - len(tail)] for n in names], f"{head}…{tail}"


def trace_styles(n: int) -> list[dict]:
    """Colour and line style of each of ``n`` traces: the Okabe–Ito colours
    (:data:`~morphoshell.plotting.style.OKABE_ITO`, told apart with red–green colour
    blindness, which Matplotlib's default cycle is not: its green, orange and red were
    three of five traces, audit 25), then the same colours again in the next of
    :data:`TRACE_DASHES`, so that no two of the first 18 traces look alike."""
    colours = list(OKABE_ITO.values())
    return [{"color": colours[k % len(colours)],
             "ls": TRACE_DASHES[(k // len(colours)) % len(TRACE_DASHES)]} for k in range(n)]


def _legend_columns(names: Sequence[str]) -> int:
    """Columns of the traces' legend (their names, "± spread", "average") that fit in the
    column's width at MIN_FONT_SIZE: a handle and its gap (2.4 ems), a gap between columns."""
    width = max(text_width(name, MIN_FONT_SIZE) for name in [*names, "± spread"])
    column = width + 2.4 * MIN_FONT_SIZE + 2.0 * MIN_FONT_SIZE
    return max(1, min(len(names) + 2, int(0.95 * SINGLE_COLUMN * 72 // column)))


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
        The traces' labels (default: "trace 1", "trace 2", ...).  The legend, under the
        shape, shows the part that differs between them, and what they share as its
        title ("synthetic_embryo…_midline" over 1 … 5); the caption names a trace in full.
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
    labels, shared = _short_names(names)
    fig = journal_figure(SINGLE_COLUMN, 1.25 * SINGLE_COLUMN, pyplot=pyplot)
    from ..io.midlines import trace_distances

    distances = trace_distances(midlines)
    s = np.r_[0.0, np.cumsum(np.hypot(*np.diff(mean.points, axis=0).T))]
    with styled(fig):
        top, bottom = fig.subplots(2, 1, height_ratios=(2.2, 1))
        for m, label, d, look in zip(midlines, labels, distances, trace_styles(len(midlines))):
            top.plot(m.r, m.z, lw=0.8, label=label, **look)
            bottom.plot(s, d, lw=0.7, **look)
        if mean.spread is not None:
            top.fill_between(mean.r, mean.z - mean.spread, mean.z + mean.spread, color="0.8",
                             lw=0, label="± spread", zorder=0)
        # thin and dashed: the traces differ by a few 1e-3 R and would vanish under it
        top.plot(mean.r, mean.z, color="k", lw=0.6, ls="--", label="average", zorder=3)
        # the shape at its own aspect in the whole width left by nothing beside it (audit 19:
        # the file names' legend beside it took half the column, and datalim padded z, so
        # the shell was drawn 0.9 in wide and the distances below as narrow)
        top.set_aspect("equal", adjustable="box")
        top.set_xlabel(r"$r/R$")
        top.set_ylabel(r"$z/R$")
        below = ScaledTranslation(0, -_BELOW_AXIS * MIN_FONT_SIZE / 72, fig.dpi_scale_trans)
        top.legend(loc="upper center", bbox_to_anchor=(0.5, 0.0),
                   bbox_transform=top.transAxes + below, borderaxespad=0.0,
                   ncol=_legend_columns(labels), fontsize=MIN_FONT_SIZE, frameon=False,
                   title=shared, title_fontsize=MIN_FONT_SIZE)
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
