"""Cross-sections of equilibria: the geometry of the drawing, what was solved, the plot.

Shells are drawn as in the paper's figures: the meridian (r, z) and its
mirror image (−r, z), with the cell sheet as a band of the deformed thickness
h/(f_s f_φ) (incompressible cells: volume is conserved) around the midline.
Lengths are in units of the undeformed radius R.  Ablations are drawn by
:mod:`.ablation`, fits by :mod:`.fits`, the look they share is :mod:`.style`.

Importing this module leaves the Matplotlib backend alone, so plots show
inline in Jupyter.  Programs that run without a display choose theirs: the
scripts call ``matplotlib.use("Agg")`` in ``main()``; the command line draws
into figures outside pyplot (``new_axes(pyplot=False)``), which need no
backend and leave the calling process's state untouched.

Overlaying several results: a band per shell turns into a smear where the
translucent bands overlap, so several results are drawn as midlines only
unless ``band="fill"`` or ``band="outline"`` (the band's edges as thin
lines) is asked for.  One result gets its band.  Titles, captions and legend
entries say what was solved: the title (one line) the problem the results
share — name, family, theory (:func:`problem_title`) —, the caption under
the axes its parameters and the solver, each legend entry what sets a
result apart.
"""
from __future__ import annotations

from typing import Sequence

import matplotlib as mpl
import numpy as np
from matplotlib.axes import Axes
from matplotlib.cbook import normalize_kwargs
from matplotlib.lines import Line2D
from matplotlib.patches import PathPatch
from matplotlib.path import Path as MplPath

from ..model.problem import Problem
from ..solvers.contact import half_thickness
from ..solvers.results import Equilibrium
from .style import add_caption, made_here, new_axes, panel_title, styled

__all__ = ["sheet_outline", "far_end_shift", "problem_label", "problem_title",
           "problem_caption", "plot_cross_section", "finish_shell_axes", "draw_shell",
           "band_path", "band_edges", "mirrored", "SHOW_ALL_PARAMETERS", "BAND_ALPHA",
           "TITLE_ITEMS"]

#: Families with at most this many parameters are described with all their
#: values (a default is a value too: "f0 = 0.1" says more than nothing);
#: larger families (volvox: 14) only with those that differ from the defaults.
SHOW_ALL_PARAMETERS = 3
#: The parts of a problem's description that its title names; the others
#: (h, cut, opening, parameters) go to the caption.
TITLE_ITEMS = ("name", "family", "theory", "geometry")
#: Opacity of the band of :func:`plot_cross_section` (``band="fill"``).
BAND_ALPHA = 0.3

# --------------------------------------------------------------------------
# geometry of the drawing
# --------------------------------------------------------------------------

def sheet_outline(eq: Equilibrium) -> tuple[np.ndarray, np.ndarray]:
    """Closed polygon (r, z) of the cell sheet: midline ± half the deformed thickness.

    The right half (r ≥ 0) only, in units of R: the outer edge from the
    first point to the last, then the inner edge back.

    Returns
    -------
    r, z : ndarray, shape (2N,)
        For the N points of ``eq``.
    """
    outer, inner = band_edges(eq)
    return np.concatenate([outer[0], inner[0][::-1]]), np.concatenate([outer[1], inner[1][::-1]])


def band_edges(eq: Equilibrium) -> tuple[tuple[np.ndarray, np.ndarray], ...]:
    """(r, z) of the two edges of the sheet: the midline ± h/(2 f_s f_φ) along the normal."""
    half = half_thickness(eq)
    # At a pole f_φ → f_s: the nodal values are finite by construction.
    nr, nz = -np.sin(eq.psi), np.cos(eq.psi)   # normal to the meridian (tangent (cos ψ, sin ψ))
    return (eq.r + half * nr, eq.z + half * nz), (eq.r - half * nr, eq.z - half * nz)


def far_end_shift(eq: Equilibrium) -> float:
    """z shift (units of R) that puts ``eq`` in the gauge of the ablation observables.

    :func:`morphoshell.mechanics.ablation.edge_state` keeps the far end of the shell
    at its undeformed height; its z at the first point minus the solver's
    z there is that shift (exact: the first point is not interpolated).
    """
    from ..mechanics.ablation import edge_state

    return edge_state(eq, float(eq.s[0]))["z"] - float(eq.z[0])


def mirrored(eq: Equilibrium, r: np.ndarray, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A curve along the meridian and back along its mirror image, as one polyline.

    The halves meet at a pole at the far end; where the shell has an edge
    there (an opening) a NaN keeps them apart.
    """
    gap = [] if eq.problem.structure.end == "pole" else [np.nan]
    return np.r_[r, gap, -r[::-1]], np.r_[z, gap, z[::-1]]


def band_path(eq: Equilibrium, shift: float) -> MplPath:
    """Both halves of the band as one compound path.

    One patch, so that a translucent band shows no seam or darker overlap
    where the halves meet at the poles; the mirror image is reversed to keep
    the orientation of the right half (nonzero winding fills the union).
    """
    r, z = sheet_outline(eq)
    z = z + shift
    right = np.column_stack([r, z])
    left = np.column_stack([-r, z])[::-1]
    return MplPath.make_compound_path(*(MplPath(np.vstack([v, v[:1]]), closed=True)
                                        for v in (right, left)))


def draw_shell(ax: Axes, eq: Equilibrium, band: str | None, line: dict, *,
                face=None, shift: float = 0.0, band_zorder: float = 1.0
                ) -> tuple[Line2D, PathPatch | None]:
    """Midline of ``eq`` in the style ``line``, and its band: "fill", "outline" or None.

    ``line`` holds Line2D properties by their full names (``normalize_kwargs``).

    ``face`` is the band's fill colour (default: the line's colour at
    :data:`BAND_ALPHA`).  Returns the midline and the filled band (or None).
    """
    color, patch = line["color"], None
    if band == "fill":
        fc = face if face is not None else mpl.colors.to_rgba(color, BAND_ALPHA)
        patch = ax.add_patch(PathPatch(band_path(eq, shift), facecolor=fc, edgecolor="none",
                                       zorder=band_zorder))
    elif band == "outline":
        lw = 0.5 * line.get("linewidth", 1.0)
        for r, z in band_edges(eq):
            ax.plot(*mirrored(eq, r, z + shift), color=color, lw=lw, alpha=0.8,
                    zorder=band_zorder)
    return ax.plot(*mirrored(eq, eq.r, eq.z + shift), **line)[0], patch


# --------------------------------------------------------------------------
# what was solved
# --------------------------------------------------------------------------

def _problem_items(problem: Problem, show: set[str] = frozenset()) -> dict[str, str]:
    """The parts of a problem's description, keyed: what is not a default, and ``show``.

    Always the name (if any), family, theory and h; the cut, opening,
    geometry and parameters where they differ from their defaults (all
    parameters of small families, :data:`SHOW_ALL_PARAMETERS`) or are in ``show``.
    """
    items = {"name": problem.name, "family": problem.family,
             "theory": problem.theory.replace("_", "-")}
    if problem.geometry != "sphere" or "geometry" in show:
        items["geometry"] = problem.geometry
    items["h"] = f"h = {problem.h:g}"
    if problem.cut or "cut" in show:
        items["cut"] = f"cut Σ = {problem.cut:g}"
    if problem.opening or "opening" in show:
        items["opening"] = f"opening P = {problem.opening:g}"
    defaults = problem.family_obj.defaults
    every = len(defaults) <= SHOW_ALL_PARAMETERS
    items.update({k: f"{k} = {v:g}" for k, v in problem.params.items()
                  if every or v != defaults[k] or k in show})
    return {k: v for k, v in items.items() if v}


def _join(items: dict[str, str]) -> str:
    """'name: family, theory, h = …' (the name, if any, leads)."""
    rest = ", ".join(v for k, v in items.items() if k != "name")
    return f"{items['name']}: {rest}" if "name" in items and rest else items.get("name", rest)


def problem_label(problem: Problem) -> str:
    """One line saying what was solved (a legend entry, a log line).

    Name, family, theory, h, the cut Σ and the opening P (if not 0) and the
    family's parameters (those that differ from their defaults if the family
    has more than :data:`SHOW_ALL_PARAMETERS`), e.g.
    ``"toy2_ablation: uniform, large-bending, h = 0.3, cut Σ = 0.3, k = 0.5"``.
    """
    return _join(_problem_items(problem))


def problem_title(problem: Problem, name: str | None = None) -> str:
    """The title of a figure of ``problem``: name, family, theory (and a geometry
    other than the sphere), e.g. ``"toy2_ablation: uniform, large-bending"``.

    ``name`` replaces the problem's own (e.g. the traced file a fit is of).
    """
    items = {k: v for k, v in _problem_items(problem).items() if k in TITLE_ITEMS}
    return _join({**items, "name": name} if name else items)


def problem_caption(problem: Problem) -> str:
    """What :func:`problem_title` leaves out: h, cut, opening and the parameters.

    A large family's parameters are named where they differ from its
    defaults, and the caption says the others are the defaults.
    """
    return _caption_of(_problem_items(problem), problem)


def _caption_of(items: dict[str, str], problem: Problem) -> str:
    """The non-title items, and a note on the defaults of a large family."""
    text = ", ".join(v for k, v in items.items() if k not in TITLE_ITEMS)
    if len(problem.family_obj.defaults) > SHOW_ALL_PARAMETERS:
        text += f" (other parameters: the {problem.family} defaults)"
    return text


def _shared_caption(common: dict[str, str], problem: Problem) -> str:
    """The caption of what all results share: parameters; then method and mesh."""
    solver = ", ".join(f"{common['method']} method" if k == "method" else common[k]
                       for k in ("method", "nodes") if k in common)
    params = _caption_of({k: v for k, v in common.items() if k not in ("method", "nodes")},
                         problem)
    return "; ".join(part for part in (params, solver) if part)


def _describe(eqs: Sequence[Equilibrium]) -> tuple[str, str, list[str]]:
    """What a set of results shares (title and caption) and what sets each apart (legend).

    A parameter away from its default in any result is named in every
    entry; the method and mesh are named where they differ (legend), else
    in the caption.
    """
    show = {k for eq in eqs for k in _problem_items(eq.problem)}
    items = [{**_problem_items(eq.problem, show), "method": eq.solver.method,
              "nodes": f"{eq.solver.nodes} nodes"} for eq in eqs]
    keys = list(dict.fromkeys(k for it in items for k in it))
    shared = {k for k in keys if all(it.get(k) == items[0].get(k) for it in items)}
    common = {k: v for k, v in items[0].items() if k in shared}
    title = _join({k: v for k, v in common.items() if k in TITLE_ITEMS})
    caption = _shared_caption(common, eqs[0].problem)
    labels = [_join({k: it[k] for k in keys if k in it and k not in shared}) or f"#{i + 1}"
              for i, it in enumerate(items)]
    return title, caption, labels


# --------------------------------------------------------------------------
# the plot
# --------------------------------------------------------------------------

def finish_shell_axes(ax: Axes, title: str | None, legend: bool | str,
                      caption: str | None = None) -> Axes:
    """Cross-section axes: equal aspect, lengths in units of R, a one-line title (broken to
    the width of a caller's axes: :func:`~morphoshell.plotting.style.panel_title`), the
    caption under the axes, the legend beside them (or ``"inside"``; inside on a caller's
    axes, :func:`~morphoshell.plotting.style.made_here`)."""
    # equal scales by shrinking the box, not by widening the data limits: limits
    # set at drawing time, after the layout, give new tick labels the layout
    # made no room for, and the z label was pushed off the figure
    ax.set_aspect("equal", adjustable="box")
    ax.set_xlabel(r"$r/R$")
    ax.set_ylabel(r"$z/R$")
    panel_title(ax, title)
    if caption:
        add_caption(ax, caption)
    if legend == "inside" or (legend and not made_here(ax)):  # the fewest points covered
        ax.legend(loc="best", frameon=False)
    elif legend:
        # beside the axes, never over the shell
        ax.legend(loc="upper left", bbox_to_anchor=(1.02, 1.0), borderaxespad=0.0,
                  frameon=False)
    return ax


def _per_result(style: dict, i: int) -> dict:
    """The style of result ``i``: a list value gives one entry per result (cycled)."""
    return {k: v[i % len(v)] if isinstance(v, list) else v for k, v in style.items()}


def plot_cross_section(eqs: Equilibrium | Sequence[Equilibrium], ax: Axes | None = None, *,
                       labels: Sequence[str] | None = None, midline_only: bool = False,
                       band: str | bool = "auto", title: str | None = "auto",
                       caption: str | None = "auto", legend: bool | str = "auto",
                       **style) -> Axes:
    """Draw one or more equilibria as mid-sagittal cross-sections (lengths in units of R).

    Parameters
    ----------
    eqs : Equilibrium or sequence of Equilibrium
    ax : matplotlib Axes, optional
        Drawn into; a new figure (via pyplot, so it shows in Jupyter) if not given.
    labels : sequence of str, optional
        Legend entries; by default what sets each result apart (parameters,
        or method and mesh when the problems are the same).
    midline_only : bool
        Draw the midlines only (same as ``band=False``).
    band : {"auto", "fill", "outline"} or bool
        The band of deformed thickness h/(f_s f_φ): translucent ("fill" or
        True), its two edges as thin lines ("outline"), or none (False).
        "auto": "fill" for one result, none for several (overlaid
        translucent bands blend into a smear).
    title : str or None
        One line (on a caller's ``ax`` broken to its width:
        :func:`~morphoshell.plotting.style.panel_title`); "auto": the problem the results
        share (:func:`problem_title`: name, family, theory); None: no title.
    caption : str or None
        Under the axes; "auto": with an automatic title, what it leaves out
        that the results share (h, cut, parameters; method and mesh), else
        none (a caller who titles a panel describes it); none on a caller's
        ``ax`` either (it would fall on the panels below).
    legend : bool or "auto"
        Legend beside the axes (outside the shells; inside them on a caller's
        ``ax``, whose figure has no room beside it); "auto": for several results or
        when ``labels`` are given.
    **style
        Line properties of the midlines (``color``, ``lw``, ``ls``, ``alpha``,
        ...); the band takes the line's colour.  A list gives one value per
        result, e.g. ``color=["k", "tab:red"]``.

    Returns
    -------
    Axes
        The axes drawn into; the figure stays open.
    """
    eqs = [eqs] if isinstance(eqs, Equilibrium) else list(eqs)
    if not eqs:
        raise ValueError("plot_cross_section needs at least one equilibrium")
    if labels is not None and len(labels) != len(eqs):
        raise ValueError(f"{len(labels)} labels for {len(eqs)} equilibria")
    if band == "auto":
        band = "fill" if len(eqs) == 1 else None
    band = {True: "fill", False: None}.get(band, band)
    if band not in ("fill", "outline", None):
        raise ValueError(f"band = {band!r}: use 'auto', 'fill', 'outline' or False")
    if midline_only:
        band = None
    if legend == "auto":
        legend = len(eqs) > 1 or labels is not None
    auto_title, auto_caption, auto_labels = _describe(eqs)
    if len(eqs) == 1:
        auto_labels = [problem_label(eqs[0].problem)]
    if ax is None:
        ax = new_axes(legend=bool(legend))
    if caption == "auto":
        caption = auto_caption if title == "auto" and made_here(ax) else None
    style = normalize_kwargs(style, Line2D)
    with styled(ax):
        for i, (eq, label) in enumerate(zip(eqs, labels or auto_labels)):
            line = {"color": f"C{i}", "linewidth": 1.0, "zorder": 2.0, "label": label,
                    **_per_result(style, i)}
            draw_shell(ax, eq, band, line)
        return finish_shell_axes(ax, auto_title if title == "auto" else title, legend, caption)


