"""The look every morphoshell figure shares: journal sizes, fonts, titles, captions, saving.

One place for the sizes and fonts, so that the command line's figures, the
notebook's and the paper's scripts agree: a figure made here
(:func:`new_axes`, :func:`journal_figure`) is a journal column wide and
remembers its style, and the plot functions draw into it in that style
(:func:`styled`); figures of the caller's own keep the caller's rcParams.

A figure says what it shows in two places: a one-line title (the problem:
name, family, theory) and a caption under the axes (parameters, method,
what the data are, see :func:`add_caption`), so that the title never wraps
or runs past the figure's edge.
"""
from __future__ import annotations

import contextlib
import os
import re
from pathlib import Path
from typing import Any, Sequence

import matplotlib as mpl
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.font_manager import FontProperties
from matplotlib.layout_engine import ConstrainedLayoutEngine
from matplotlib.text import Text
from matplotlib.transforms import Bbox

__all__ = ["SINGLE_COLUMN", "DOUBLE_COLUMN", "MIN_FONT_SIZE", "SCRIPT_SCALE", "MIN_SCRIPT_SIZE",
           "OKABE_ITO", "PAPER_RC", "paper_style", "styled", "journal_figure", "new_axes",
           "made_here", "own_axes", "add_caption", "get_caption", "panel_title", "label_panel",
           "flag_panel", "is_flagged", "save"]

#: Figure widths of journals (inches): one column and the full page width.
SINGLE_COLUMN = 3.4
DOUBLE_COLUMN = 7.0
#: Smallest font size (points) of :data:`PAPER_RC`: legible in print at these widths.
MIN_FONT_SIZE = 7.0
#: Size of mathtext's sub- and superscripts relative to their text: Matplotlib's fixed
#: ratio (``SHRINK_FACTOR`` of its mathtext layout, not a setting), so E_fit² and κ₁ in
#: the 8 pt axis labels have scripts of 5.6 pt, and 10⁻³ in 7 pt tick labels of 4.9 pt.
SCRIPT_SCALE = 0.7
#: Smallest size (points) of a sub- or superscript in the paper style: one in text of
#: :data:`MIN_FONT_SIZE`.
MIN_SCRIPT_SIZE = SCRIPT_SCALE * MIN_FONT_SIZE
#: The Okabe–Ito colours (Okabe & Ito 2008, without its black and its yellow, too light
#: on white): distinct with protanopia and deuteranopia as well as with normal vision.
#: The colours of every plot that tells lines apart by colour (branches, traces).
OKABE_ITO = {"orange": "#E69F00", "sky blue": "#56B4E9", "bluish green": "#009E73",
             "blue": "#0072B2", "vermillion": "#D55E00", "reddish purple": "#CC79A7"}

#: rcParams of :func:`paper_style`.  Named font sizes are relative to
#: ``font.size`` ("small" = 0.83×), so figures drawn in this style should use
#: the rc defaults or absolute sizes; TrueType fonts (type 42) keep the text
#: of the PDF editable, as journals ask, and ``svg.fonttype: none`` that of
#: the SVG (``<text>`` elements in the font's name, not glyphs as paths: the
#: reader's fonts draw it, DejaVu Sans where installed, else a sans-serif).
PAPER_RC: dict[str, Any] = {
    "font.size": 8, "axes.titlesize": 8, "axes.labelsize": 8, "figure.titlesize": 8,
    "figure.labelsize": 8, "xtick.labelsize": MIN_FONT_SIZE, "ytick.labelsize": MIN_FONT_SIZE,
    "legend.fontsize": MIN_FONT_SIZE, "legend.frameon": False, "legend.handlelength": 1.6,
    "axes.linewidth": 0.6, "axes.titlepad": 4.0, "axes.labelpad": 2.0,
    "xtick.major.width": 0.6, "ytick.major.width": 0.6, "xtick.minor.width": 0.4,
    "ytick.minor.width": 0.4, "xtick.major.size": 3.0, "ytick.major.size": 3.0,
    "xtick.minor.size": 1.8, "ytick.minor.size": 1.8,
    "lines.linewidth": 1.0, "lines.markersize": 4.0, "lines.markeredgewidth": 0.8,
    "savefig.dpi": 300, "pdf.fonttype": 42, "ps.fonttype": 42, "svg.fonttype": "none",
}

#: Attribute that marks a figure made in the paper style (see :func:`styled`).
_STYLED = "_morphoshell_paper_style"
#: gid of a caption's text, by which :func:`get_caption` finds it.
_CAPTION = "morphoshell-caption"
#: gid of the hatched background of :func:`flag_panel`.
_FLAG = "morphoshell-flag"
#: The gid of the axes :func:`new_axes` makes (:func:`made_here`).
_OWN_AXES = "morphoshell-axes"
#: Width of a character in ems (DejaVu Sans, mixed text): to break captions into lines.
_EM_PER_CHAR = 0.55


def paper_style():
    """Context manager of the paper style (:data:`PAPER_RC`): text ≥ 7 pt (its sub- and
    superscripts at :data:`SCRIPT_SCALE` of it), 300 dpi.

    Create *and* save the figures inside it: fonts are set when artists are
    made, the PDF font type when the file is written.
    """
    return mpl.rc_context(PAPER_RC)


def _figure_of(fig_or_ax) -> Figure:
    """The top-level figure holding an Axes, SubFigure or Figure."""
    fig = fig_or_ax
    while not isinstance(fig, Figure):   # Axes -> (SubFigure ->) Figure
        fig = fig.figure
    return fig


def styled(fig_or_ax):
    """The paper style if ``fig_or_ax`` is in a figure made here, else no change.

    The plot functions draw inside it: a legend, title or caption made later
    than the figure takes the rcParams of that moment, and a figure made at a
    journal's width needs the paper's fonts for all of them.
    """
    if getattr(_figure_of(fig_or_ax), _STYLED, False):
        return paper_style()
    return contextlib.nullcontext()


def journal_figure(width: float = SINGLE_COLUMN, height: float | None = None, *,
                   pyplot: bool = True) -> Figure:
    """An empty figure of a journal's width in the paper style, laid out by constrained layout.

    Parameters
    ----------
    width : float
        Inches: :data:`SINGLE_COLUMN` (default) or :data:`DOUBLE_COLUMN`.
    height : float, optional
        Inches (default: 0.9 × the width).
    pyplot : bool
        Register the figure with pyplot (shown inline in Jupyter, closed by
        ``plt.close``).  ``False`` gives a figure unknown to pyplot: no
        backend, no window, freed with its last reference — for programs
        that only save it (the command line).

    Returns
    -------
    Figure
        Axes added to it later are in the paper style (:func:`styled`).
    """
    size = (width, 0.9 * width if height is None else height)
    # made outside paper_style: pyplot's first figure resolves the backend, and
    # Jupyter's inline backend then turns interactive mode on, which leaving an
    # rc_context entered before would turn off again (no more inline plots)
    fig = (plt.figure(figsize=size, layout="constrained") if pyplot
           else Figure(figsize=size, layout="constrained"))
    setattr(fig, _STYLED, True)
    return fig


def new_axes(figsize: tuple[float, float] | None = None, *, legend: bool = False,
             pyplot: bool = True) -> Axes:
    """Axes in a new single-column figure in the paper style (a legend beside the axes fits).

    Parameters
    ----------
    figsize : (float, float), optional
        Width and height (inches); default :data:`SINGLE_COLUMN` wide, a
        little less high with ``legend`` (the legend takes width, the
        shell keeps its aspect).
    legend : bool
        Leave room for a legend beside the axes (default size only).
    pyplot : bool
        See :func:`journal_figure`.

    Returns
    -------
    Axes
    """
    width, height = figsize or (SINGLE_COLUMN, (0.78 if legend else 0.95) * SINGLE_COLUMN)
    fig = journal_figure(width, height, pyplot=pyplot)
    with paper_style():   # the ticks' and labels' fonts are fixed when the axes are made
        ax = fig.add_subplot()
    return own_axes(ax)


def made_here(ax: Axes) -> bool:
    """Whether the package made ``ax`` (:func:`new_axes`, :func:`own_axes`): its figure has
    room for a legend beside it and a caption under it.  A caller's axes (a panel of their
    grid) has not: the plots then put their legend inside and leave out the automatic
    caption, which would fall on the neighbouring panels."""
    return ax.get_gid() == _OWN_AXES


def own_axes(ax: Axes) -> Axes:
    """``ax``, marked as a figure of the package's own (:func:`made_here`)."""
    ax.set_gid(_OWN_AXES)
    return ax


def wrap_items(text: str, width: int, sep: str = ", ") -> str:
    """Break ``text`` into lines of at most ``width`` characters between its items (``sep``).

    Matplotlib's own wrapping breaks at any space ("h =" / "0.15").
    """
    lines: list[str] = []
    for line in text.split("\n"):
        out = ""
        for item in line.split(sep):
            joined = f"{out}{sep}{item}" if out else item
            if out and len(joined) > width:
                lines.append(out + sep.rstrip())
                joined = item
            out = joined
        lines.append(out)
    return "\n".join(lines)


def add_caption(ax: Axes, text: str, *, width: float | None = None) -> Text:
    """A short caption under the x label of ``ax``: what the title leaves out.

    Broken between its items (", " and "; ") to the figure's width (or
    ``width`` inches) and set in :data:`MIN_FONT_SIZE`; anchored to the x
    label, so that constrained layout makes room for it and nothing is cut.

    Returns
    -------
    Text
        The caption (found again by :func:`get_caption`).
    """
    width = width or 0.95 * _figure_of(ax).get_figwidth()
    chars = int(width * 72 / (_EM_PER_CHAR * MIN_FONT_SIZE))
    lines = "\n".join(wrap_items(part, chars) for part in text.split("; "))
    return ax.annotate(lines, xy=(0.5, 0.0), xycoords=ax.xaxis.label, xytext=(0, -3),
                       textcoords="offset points", ha="center", va="top",
                       fontsize=MIN_FONT_SIZE, color="0.25", gid=_CAPTION)


def get_caption(ax: Axes) -> str:
    """The caption :func:`add_caption` put under ``ax`` (its lines joined by spaces), or ""."""
    texts = [t.get_text() for t in ax.texts if t.get_gid() == _CAPTION]
    return " ".join(" ".join(texts).split("\n"))


def text_width(text: str, size: float) -> float:
    """Estimated width (points) of one line of ``text`` set in ``size`` points (DejaVu Sans,
    :data:`_EM_PER_CHAR`): a mathtext command (``\\varrho``) counts as one character, ``$``
    as none.  For choosing a layout before anything is drawn."""
    visible = re.sub(r"\\[A-Za-z]+", "x", text).replace("$", "")
    return len(visible) * _EM_PER_CHAR * size


#: Room (points) constrained layout leaves around a panel's axes inside its grid cell for
#: tick labels and an axis label on each of two sides (measured on audit 19's grids: the
#: axes of a 7 in × 2.4 in row of three, 168 × 173 pt cells, were 137 × 135 pt).
DECORATION = 33.0


def _grid_of(ax: Axes):
    """The grid cell of ``ax`` and the grid's width and height ratios where constrained layout
    will place it, else None."""
    spec = ax.get_subplotspec()
    if spec is None or not isinstance(_figure_of(ax).get_layout_engine(),
                                      ConstrainedLayoutEngine):
        return None
    grid = spec.get_gridspec()
    return spec, (np.asarray(grid.get_width_ratios() or [1] * grid.ncols, float),
                  np.asarray(grid.get_height_ratios() or [1] * grid.nrows, float))


def axes_size(ax: Axes) -> tuple[float, float]:
    """Width and height (points) the axes ``ax`` will have when drawn, for choosing a layout
    before anything is drawn: its grid cell's less :data:`DECORATION` under constrained
    layout (which has not run yet: the axes' place now is the grid's default, up to 20 %
    narrower), else its place now."""
    fig, dpi = ax.figure, ax.figure.dpi
    found = _grid_of(ax)
    if found is None:
        box = ax.get_window_extent()
        return box.width * 72 / dpi, box.height * 72 / dpi
    spec, (widths, heights) = found
    width = fig.bbox.width * widths[spec.colspan].sum() / widths.sum()
    height = fig.bbox.height * heights[spec.rowspan].sum() / heights.sum()
    return width * 72 / dpi - DECORATION, height * 72 / dpi - DECORATION


def panel_room(ax: Axes, least: float) -> tuple[float, float]:
    """Width and height (points) the panel of ``ax`` (its axes and all drawn around them) can
    take at most while every other panel of its grid keeps axes of ``least`` points.

    Constrained layout makes room for one panel's wide or tall decoration (a legend under
    its axes) by narrowing or lowering every panel of the grid alike (the ratios hold
    between the axes): the panel can take its figure's width less, for each other column,
    its decoration (:data:`DECORATION`) and its share of ``least``; its height likewise.
    Without constrained layout: the axes' place now and their decoration.
    """
    found = _grid_of(ax)
    if found is None:
        return tuple(s + DECORATION for s in axes_size(ax))
    spec, ratios = found
    figure = np.array(ax.figure.bbox.size) * 72 / ax.figure.dpi
    room = []
    for total, r, span in zip(figure, ratios, (spec.colspan, spec.rowspan)):
        own = r[span].sum()
        room.append(total - (r.sum() - own) / own * least - (len(r) - len(span)) * DECORATION)
    return room[0], room[1]


def panel_title(ax: Axes, title: str | None) -> None:
    """Title ``ax`` with ``title`` (one line; None or "": leave the title as it is).

    On a caller's axes (a panel of their grid, :func:`made_here`), whose width the plot
    does not choose, the title is broken to the axes' width: after its name (": "), then
    between its items (", "), as :func:`add_caption` breaks a caption.  A one-line title
    wider than its panel ran past the panel's edges, into its neighbours and under the
    panel's letter (:func:`label_panel`; audit 25: "average of 5 traces: volvox,
    large-bending" over a 1.7 in wide shell).  Call it in the figure's style
    (:func:`styled`): the title's size is read from the rcParams.
    """
    if not title:
        return
    if not made_here(ax):
        size = FontProperties(size=mpl.rcParams["axes.titlesize"]).get_size_in_points()
        width = axes_size(ax)[0]
        if text_width(title, size) > width:
            chars = max(1, int(width / (_EM_PER_CHAR * size)))
            title = ":\n".join(wrap_items(part, chars) for part in title.split(": "))
    ax.set_title(title)


def label_panel(ax: Axes, letter: str, *, size: float = 10.0, dx: float = -4.0,
                dy: float = 4.0):
    """Bold panel letter above the top-left corner of ``ax``, clear of its title.

    The letter ends left of the axes' left edge, where a title no wider than the axes
    (:func:`panel_title`) does not reach; where a wider title (centred over the axes)
    begins further left, the letter stands left of the title's start instead, placed
    when the figure is drawn (after the layout has placed the title).

    Parameters
    ----------
    letter : str
    size : float
        Font size (points).
    dx, dy : float
        Offset of the letter's right/bottom edge from the axes' corner, or from the
        title's left edge if that lies further left (points).

    Returns
    -------
    matplotlib.text.Annotation
    """
    def corner(renderer) -> Bbox:
        """The axes' box, widened to the left edge of a centred title that overhangs it."""
        box = ax.get_window_extent(renderer)
        title = ax.title
        if title.get_visible() and title.get_text().strip():
            return Bbox.from_extents(min(box.x0, title.get_window_extent(renderer).x0),
                                     box.y0, box.x1, box.y1)
        return box

    return ax.annotate(letter, xy=(0.0, 1.0), xycoords=corner, xytext=(dx, dy),
                       textcoords="offset points", ha="right", va="bottom", fontsize=size,
                       fontweight="bold")


#: Look of a panel whose content is no result (:func:`flag_panel`): a light grey
#: background hatched under the data.
FLAG_STYLE = {"facecolor": "0.94", "edgecolor": "0.78", "hatch": "////", "linewidth": 0.0}


def flag_panel(ax: Axes):
    """Hatch the background of ``ax`` grey: what it draws is not a result (a fit that did
    not converge, a shape whose walls pass through each other); say why in its title.

    The hatching lies under every artist of the axes (zorder below the lines and bands),
    so the data stay readable, and it survives greyscale printing, which a coloured
    background would not.

    Returns
    -------
    matplotlib.patches.Rectangle
        The hatched background, its gid ``"morphoshell-flag"``.
    """
    from matplotlib.patches import Rectangle

    return ax.add_patch(Rectangle((0.0, 0.0), 1.0, 1.0, transform=ax.transAxes, zorder=0.1,
                                  gid=_FLAG, **FLAG_STYLE))


def is_flagged(ax: Axes) -> bool:
    """Whether :func:`flag_panel` marked ``ax``."""
    return any(p.get_gid() == _FLAG for p in ax.patches)


#: Metadata :func:`save` gives each vector format by default: no creation date, so that a
#: figure saved twice is the same file (audit 19: the PDFs of two runs differed in their
#: /CreationDate alone, the SVGs in their dc:date).  PostScript has no way to leave it out.
_NO_DATE = {"pdf": {"CreationDate": None}, "svg": {"Date": None}}
#: Salt of the SVG's ids (clip paths, glyphs): Matplotlib's default is random per file.
_SVG_SALT = "morphoshell"


def _metadata(fmt: str, metadata: dict | None) -> dict | None:
    """The ``savefig`` metadata of format ``fmt``: the caller's over :data:`_NO_DATE`'s;
    with ``SOURCE_DATE_EPOCH`` set, that date (Matplotlib reads it) instead of none."""
    default = {} if os.environ.get("SOURCE_DATE_EPOCH") else _NO_DATE.get(fmt, {})
    merged = {**default, **(metadata or {})}
    return merged or None


#: Drawing passes before saving a laid-out figure (see :func:`_settle_layout`).
_LAYOUT_PASSES = 2


def _settle_layout(fig: Figure) -> None:
    """Draw (without rendering) until constrained layout has settled.

    The layout is made before an equal aspect shrinks the axes' box, which
    then moves the title, tick labels and caption: saved after one pass, a
    title ended above the figure's top edge.  Each further pass starts from
    the shrunk box; two are enough for the shells' figures.
    """
    if fig.get_layout_engine() is not None:
        for _ in range(_LAYOUT_PASSES):
            fig.draw_without_rendering()


def _height_cropped(fig: Figure, pad: float = 0.04, band: float = 0.2) -> Bbox | None:
    """The figure's box at its full width, cropped above or below where an empty band of
    more than ``band`` inches lies between the drawn content (with ``pad`` inches of
    margin) and the edge, or None: a wide, flat shell at equal aspect left an inch of
    empty figure above it.  A journal's width is kept, and a figure that fills its height
    keeps its size."""
    width, height = fig.get_size_inches()
    drawn = fig.get_tightbbox()
    low = drawn.y0 - pad if drawn.y0 - pad > band else 0.0
    high = drawn.y1 + pad if height - (drawn.y1 + pad) > band else height
    if low == 0.0 and high == height:
        return None
    return Bbox([[0.0, low], [width, high]])


def save(fig_or_ax, path: str | Path, formats: Sequence[str] | None = None, *,
         dpi: float = 300, close: bool = False, tight: bool | None = None,
         metadata: dict | None = None) -> list[Path]:
    """Save a figure; returns the paths written.

    The same figure saved twice gives the same files, byte for byte: PNG as
    Matplotlib writes it, PDF and SVG without their creation date and the
    SVG's ids from a fixed salt.  With the environment variable
    ``SOURCE_DATE_EPOCH`` set (seconds since 1970, the reproducible-builds
    convention), PDF, SVG and PostScript carry that date instead; PostScript
    otherwise has the time of writing.

    Parameters
    ----------
    fig_or_ax : Figure, SubFigure or Axes
        The figure saved is the one holding it.
    path : str or Path
        Target; its suffix is replaced by each of ``formats``.
    formats : sequence of str, optional
        E.g. ``("png", "pdf")``; default: the suffix of ``path`` (png if none).
    dpi : float
        Resolution of raster formats (dots per inch).
    close : bool
        Close the figure afterwards (pyplot figures; the default keeps it open).
    tight : bool, optional
        Crop to the drawn content.  Default: only figures without a layout
        engine, so that a figure laid out at a journal's width keeps its size.
    metadata : dict, optional
        Matplotlib's ``savefig`` metadata, over the default (no date), e.g.
        ``{"CreationDate": datetime.now()}`` for a PDF that has one; applied
        to every format saved.

    Returns
    -------
    list of Path
        One per format.
    """
    fig = _figure_of(fig_or_ax)
    if tight is None:
        tight = fig.get_layout_engine() is None
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    out = []
    # a figure of the paper style keeps its text editable in the PDF (read on saving)
    with styled(fig), mpl.rc_context({"svg.hashsalt": _SVG_SALT}):
        if not tight:
            _settle_layout(fig)
        box = "tight" if tight else _height_cropped(fig)
        for fmt in formats or [path.suffix.lstrip(".") or "png"]:
            target = path.with_suffix("." + fmt)
            fig.savefig(target, dpi=dpi, bbox_inches=box, metadata=_metadata(fmt, metadata))
            out.append(target)
    if close:
        plt.close(fig)
    return out

