"""Cross-sections of a laser ablation: the shell before and after the cut.

Both shells are drawn in the gauge of the observables (far end at its
undeformed position, see :func:`morphoshell.mechanics.ablation.edge_state`),
so that the recoil seen is the one ``ablation.displacement`` gives.  The
recoil of a small cut moves the sheet by a fraction of its thickness, so the
two shells overlap almost everywhere: the pre-ablation shell is drawn as a
light band *under* the post-ablation one and again as its outline and
dashed midline *over* it, so that both stay visible wherever they are.
"""
from __future__ import annotations

import numpy as np
from matplotlib.axes import Axes
from matplotlib.cbook import normalize_kwargs
from matplotlib.collections import LineCollection
from matplotlib.colors import to_rgb
from matplotlib.legend_handler import HandlerTuple
from matplotlib.lines import Line2D
from matplotlib.patches import Patch

from .shells import (band_edges, band_path, draw_shell, far_end_shift, mirrored,
                     finish_shell_axes, problem_caption, problem_title)
from .style import made_here, new_axes, panel_title, styled

__all__ = ["plot_ablation", "plot_ablation_overlay", "ABLATION_STYLE", "recoil_caption"]

#: Styles of :func:`plot_ablation`, in the paper's colours (Fig. 2G–I, Fig. 3):
#: pre-ablation light red, dashed; post-ablation dark cyan, solid.  ``fill``
#: is the band's opacity blended with white (opaque: the post-ablation band
#: covers the pre-ablation one, whose outline and midline are then drawn on
#: top); ``zorder`` is the midline's.  Not the Okabe–Ito colours of the plots that tell
#: series apart (:data:`~morphoshell.plotting.style.OKABE_ITO`): red before and cyan after
#: the cut is the paper's convention (Fig. 1's micrographs, Fig. 2 G–I, Fig. 3 D–M;
#: docs/gallery.md), and the two differ in hue, lightness and line style alike.
ABLATION_STYLE = {"pre": {"color": "tab:red", "fill": 0.3, "ls": "--", "zorder": 4.0,
                          "label": "pre-ablation"},
                  "post": {"color": "darkcyan", "fill": 0.6, "ls": "-", "zorder": 3.0,
                           "label": "post-ablation"}}
#: Line width of the pre-ablation band's outline, drawn over the post-ablation band.
_OUTLINE_WIDTH = 0.5


def recoil_caption(ablation) -> str:
    """The recoil observables of ``ablation`` at s = Σ, with units, for a caption."""
    return (f"recoil at s = Σ: opening o = {ablation.opening:.3g} R, rotation ϱ = "
            f"{ablation.rotation:.3g} rad, displacement d = {ablation.displacement:.3g} R")


def plot_ablation(ablation, ax: Axes | None = None, *, title: str | None = "auto",
                  caption: str | None = "auto", legend: bool = True, mark_rim: bool = True,
                  midline_only: bool = False, colors: tuple[str, str] | None = None,
                  **style) -> Axes:
    """Draw the pre- (light red, dashed) and post-ablation (dark cyan, solid) cross-sections.

    The whole intact shell is drawn, cap included: its band under the
    post-ablation band, its outline and dashed midline over it; the
    post-ablation midline solid between them.  The rim s = Σ (the cut's
    edge) is marked in both states.

    Parameters
    ----------
    ablation : morphoshell.mechanics.ablation.Ablation
    ax : matplotlib Axes, optional
        Drawn into; a new single-column figure (via pyplot) if not given.
    title : str or None
        One line; "auto": :func:`~morphoshell.plotting.problem_title` of the
        ablated problem; None: no title.
    caption : str or None
        Under the axes; "auto": with an automatic title, the problem's
        parameters and the recoil observables (:func:`recoil_caption`), else none;
        none on a caller's ``ax`` (it would fall on the panels below).
    legend : bool
        Legend (pre, post, cut) beside the axes; inside them on a caller's ``ax``,
        whose figure has no room beside it.
    mark_rim : bool
        Mark the rim s = Σ before and after the cut.
    midline_only : bool
        No bands.
    colors : (str, str), optional
        Pre- and post-ablation colours (default :data:`ABLATION_STYLE`).
    **style
        Line properties of both midlines (``lw``, ``alpha``, ...).

    Returns
    -------
    Axes
        The axes drawn into; the figure stays open.
    """
    if ax is None:
        ax = new_axes(legend=bool(legend))
    if caption == "auto":
        caption = (f"{problem_caption(ablation.problem)}; {recoil_caption(ablation)}"
                   if title == "auto" and made_here(ax) else None)
    style = normalize_kwargs(style, Line2D)
    with styled(ax):
        handles = [_draw_state(ax, ablation, key, colors[i] if colors else None, midline_only,
                               mark_rim, style)
                   for i, key in enumerate(("pre", "post"))]
        finish_shell_axes(ax, problem_title(ablation.problem) if title == "auto" else title,
                          False, caption)
        if legend:
            _legend(ax, handles, mark_rim)
    return ax


def _draw_state(ax: Axes, ablation, key: str, color: str | None, midline_only: bool,
                mark_rim: bool, style: dict) -> dict:
    """One state's band, midline (and the pre-ablation outline) and rim; its legend artists."""
    from ..mechanics.ablation import edge_state

    spec = ABLATION_STYLE[key]
    eq = ablation.pre if key == "pre" else ablation.post
    color = color or spec["color"]
    face = 1 - spec["fill"] * (1 - np.array(to_rgb(color)))   # that opacity on white
    shift = far_end_shift(eq)
    line = {"color": color, "linestyle": spec["ls"], "linewidth": 0.8, "zorder": spec["zorder"],
            "label": spec["label"], **style}
    midline, patch = draw_shell(ax, eq, None if midline_only else "fill", line, face=face,
                                shift=shift, band_zorder=1.0 if key == "pre" else 2.0)
    if patch is not None:   # the legend of a caller's (panels sharing one) shows the band
        patch.set_label(midline.get_label())
        midline.set_label("_nolegend_")
        if key == "pre":    # where the post-ablation band covers it: its edges
            ax.add_collection(_outline(eq, shift, color=color, linewidths=_OUTLINE_WIDTH,
                                       linestyles=spec["ls"], zorder=spec["zorder"]),
                              autolim=False)
    rim = None
    if mark_rim:
        at = edge_state(eq, float(ablation.problem.cut))
        rim = ax.plot([at["r"], -at["r"]], [at["z"]] * 2, ls="none", marker="o", ms=3.5,
                      mfc=color, mec="white", mew=0.5, color=color, zorder=5.0)[0]
    return {"band": patch, "midline": midline, "rim": rim, "label": spec["label"]}


def _outline(eq, shift: float, **props) -> LineCollection:
    """Both edges of the band of ``eq`` (both halves of the section), as one collection."""
    segments = []
    for r, z in band_edges(eq):
        x, y = mirrored(eq, r, z + shift)
        gaps = np.flatnonzero(np.isnan(x))    # an edge at the far end: the halves apart
        segments += [np.column_stack(part) for part in zip(np.split(x, gaps), np.split(y, gaps))]
    return LineCollection([seg[~np.isnan(seg).any(axis=1)] for seg in segments], **props)


def _legend(ax: Axes, states: list[dict], mark_rim: bool) -> None:
    """Beside the axes (inside a caller's): each state as its band with its midline over it,
    and the cut's edge."""
    handles, labels = [], []
    for state in states:
        line = state["midline"]
        proxy = Line2D([], [], color=line.get_color(), ls=line.get_linestyle(),
                       lw=line.get_linewidth())
        if state["band"] is not None:
            band = Patch(facecolor=state["band"].get_facecolor(), edgecolor="none")
            proxy = (band, proxy)
        handles.append(proxy)
        labels.append(state["label"])
    # a band and its midline overlaid; the two rims side by side
    handler_map = {tuple: HandlerTuple(ndivide=1, pad=0.0)}
    if mark_rim:
        rims = tuple(Line2D([], [], ls="none", marker="o", ms=3.5, color=s["rim"].get_color(),
                            mec="white", mew=0.5) for s in states)
        handler_map[rims] = HandlerTuple(ndivide=None, pad=0.3)
        handles.append(rims)
        labels.append("cut edge s = Σ")
    where = ({"loc": "upper left", "bbox_to_anchor": (1.02, 1.0), "borderaxespad": 0.0}
             if made_here(ax) else {"loc": "best"})
    ax.legend(handles, labels, frameon=False, handler_map=handler_map, **where)


def plot_ablation_overlay(ablation, ax: Axes | None = None, *, pixels: int = 500,
                          title: str | None = None) -> Axes:
    """Pre-ablation sheet in red, post-ablation in cyan, their union white (paper Fig. 3 M).

    The overlay of the paper's micrographs (Fig. 1 A′, B‴–G‴) for numerical
    ablations: each cell sheet (midline ± half its deformed thickness, both
    halves of the section) is rasterised on a black background into the red
    channel (pre) and the green and blue channels (post), so that where the
    sheets coincide the colours add up to white.  Both states are in the
    gauge of the observables (far end at its undeformed height).

    Parameters
    ----------
    ablation : morphoshell.mechanics.ablation.Ablation
        E.g. ``numerical_ablation(...).ablation``.
    ax : matplotlib Axes, optional
    pixels : int
        Raster width (the height follows the aspect ratio).
    title : str, optional
        Broken to the width of a caller's ``ax``
        (:func:`~morphoshell.plotting.style.panel_title`).

    Returns
    -------
    Axes
        Extent of the image in units of R.
    """
    if ax is None:
        ax = new_axes()
    paths = [band_path(eq, far_end_shift(eq)) for eq in (ablation.pre, ablation.post)]
    verts = np.vstack([pth.vertices for pth in paths])
    lo, hi = verts.min(axis=0), verts.max(axis=0)
    pad = 0.05 * float(np.max(hi - lo))
    lo, hi = lo - pad, hi + pad
    width = int(pixels)
    height = max(int(round(width * (hi[1] - lo[1]) / (hi[0] - lo[0]))), 1)
    x = np.linspace(lo[0], hi[0], width)
    y = np.linspace(hi[1], lo[1], height)       # image rows from the top
    grid = np.column_stack([np.repeat(x[None, :], height, 0).ravel(),
                            np.repeat(y[:, None], width, 1).ravel()])
    pre, post = (pth.contains_points(grid).reshape(height, width) for pth in paths)
    image = np.stack([pre, post, post], axis=-1).astype(float)
    with styled(ax):
        ax.imshow(image, extent=(lo[0], hi[0], lo[1], hi[1]), interpolation="antialiased")
        ax.set_aspect("equal")
        ax.set_xlabel(r"$r/R$")
        ax.set_ylabel(r"$z/R$")
        panel_title(ax, title)
    return ax
