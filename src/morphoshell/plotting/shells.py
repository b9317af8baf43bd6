"""Cross-section plots of equilibria, ablations and fits, estimates, and paper-figure styling.

Shells are drawn as in the paper's figures: the meridian (r, z) and its
mirror image (−r, z), with the cell sheet as a band of the deformed thickness
h/(f_s f_φ) (incompressible cells: volume is conserved) around the midline.
Lengths are in units of the undeformed radius R.

Importing this module leaves the Matplotlib backend alone, so plots show
inline in Jupyter.  Programs that run without a display choose theirs: the
scripts call ``matplotlib.use("Agg")`` in ``main()``; the command line draws
into figures outside pyplot (``new_axes(pyplot=False)``), which need no
backend and leave the calling process's state untouched.

Overlaying several results: a band per shell turns into a smear where the
translucent bands overlap, so several results are drawn as midlines only
unless ``band="fill"`` or ``band="outline"`` (the band's edges as thin
lines) is asked for.  One result gets its band.  Titles and legend entries
say what was solved (:func:`problem_label`): the title what the results
share, each legend entry what sets it apart.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any, Sequence

import matplotlib as mpl
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.axes import Axes
from matplotlib.cbook import normalize_kwargs
from matplotlib.colors import to_rgb
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import PathPatch
from matplotlib.path import Path as MplPath
from matplotlib.transforms import ScaledTranslation

from ..model.problem import Problem
from ..solvers.results import Equilibrium

__all__ = ["plot_fit", "plot_k_estimates", "plot_recoil_velocity", "figure_JK", "MEASURE_COLOURS",
           "sheet_outline", "far_end_shift", "problem_label", "new_axes", "plot_cross_section",
           "plot_ablation", "plot_ablation_overlay", "save", "paper_style", "label_panel", "SINGLE_COLUMN",
           "DOUBLE_COLUMN", "MIN_FONT_SIZE", "PAPER_RC", "ABLATION_STYLE"]

#: Figure widths of journals (inches): one column and the full page width.
SINGLE_COLUMN = 3.4
DOUBLE_COLUMN = 7.0
#: Smallest font size (points) of :data:`PAPER_RC`: legible in print at these widths.
MIN_FONT_SIZE = 7.0

#: rcParams of :func:`paper_style`.  Named font sizes are relative to
#: ``font.size`` ("small" = 0.83×), so figures drawn in this style should use
#: the rc defaults or absolute sizes; TrueType fonts (type 42) keep the text
#: of the PDF editable, as journals ask.
PAPER_RC: dict[str, Any] = {
    "font.size": 8, "axes.titlesize": 8, "axes.labelsize": 8, "figure.titlesize": 8,
    "figure.labelsize": 8, "xtick.labelsize": MIN_FONT_SIZE, "ytick.labelsize": MIN_FONT_SIZE,
    "legend.fontsize": MIN_FONT_SIZE, "legend.frameon": False, "legend.handlelength": 1.6,
    "axes.linewidth": 0.6, "axes.titlepad": 4.0, "axes.labelpad": 2.0,
    "xtick.major.width": 0.6, "ytick.major.width": 0.6, "xtick.minor.width": 0.4,
    "ytick.minor.width": 0.4, "xtick.major.size": 3.0, "ytick.major.size": 3.0,
    "xtick.minor.size": 1.8, "ytick.minor.size": 1.8,
    "lines.linewidth": 1.0, "lines.markersize": 4.0, "lines.markeredgewidth": 0.8,
    "savefig.dpi": 300, "pdf.fonttype": 42, "ps.fonttype": 42,
}

#: Colours of :func:`plot_ablation`, as in the paper (Fig. 2G–I, Fig. 3):
#: pre-ablation light red, post-ablation dark cyan.  ``fill`` is the opacity
#: of the band, blended with white (opaque, so that the post-ablation band
#: hides the pre-ablation one where they overlap); the midlines are drawn on top.
ABLATION_STYLE = {"pre": {"color": "tab:red", "fill": 0.3, "ls": "--", "label": "pre-ablation"},
                  "post": {"color": "darkcyan", "fill": 0.85, "ls": "-",
                           "label": "post-ablation"}}

#: Families with at most this many parameters are described with all their
#: values (a default is a value too: "f0 = 0.1" says more than nothing);
#: larger families (volvox: 14) only with those that differ from the defaults.
SHOW_ALL_PARAMETERS = 3
#: Opacity of the band of :func:`plot_cross_section` (``band="fill"``).
BAND_ALPHA = 0.3
#: Default figure size (inches) of a new cross-section plot.
_FIGSIZE = (4.8, 4.8)


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
    outer, inner = _band_edges(eq)
    return np.concatenate([outer[0], inner[0][::-1]]), np.concatenate([outer[1], inner[1][::-1]])


def _band_edges(eq: Equilibrium) -> tuple[tuple[np.ndarray, np.ndarray], ...]:
    """(r, z) of the two edges of the sheet: the midline ± h/(2 f_s f_φ) along the normal."""
    half = eq.problem.h / (eq.f_s * eq.f_phi) / 2
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


def _mirrored(eq: Equilibrium, r: np.ndarray, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A curve along the meridian and back along its mirror image, as one polyline.

    The halves meet at a pole at the far end; where the shell has an edge
    there (an opening) a NaN keeps them apart.
    """
    gap = [] if eq.problem.structure.end == "pole" else [np.nan]
    return np.r_[r, gap, -r[::-1]], np.r_[z, gap, z[::-1]]


def _band_path(eq: Equilibrium, shift: float) -> MplPath:
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


def _draw_shell(ax: Axes, eq: Equilibrium, band: str | None, line: dict, *,
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
        patch = ax.add_patch(PathPatch(_band_path(eq, shift), facecolor=fc, edgecolor="none",
                                       zorder=band_zorder))
    elif band == "outline":
        lw = 0.5 * line.get("linewidth", 1.0)
        for r, z in _band_edges(eq):
            ax.plot(*_mirrored(eq, r, z + shift), color=color, lw=lw, alpha=0.8,
                    zorder=band_zorder)
    return ax.plot(*_mirrored(eq, eq.r, eq.z + shift), **line)[0], patch


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
    """One line saying what was solved.

    Name, family, theory, h, the cut Σ and the opening P (if not 0) and the
    family's parameters (those that differ from their defaults if the family
    has more than :data:`SHOW_ALL_PARAMETERS`), e.g.
    ``"toy2_ablation: uniform, large-bending, h = 0.3, cut Σ = 0.3, k = 0.5"``.
    """
    return _join(_problem_items(problem))


def _describe(eqs: Sequence[Equilibrium]) -> tuple[str, list[str]]:
    """What a set of results shares (a title) and what sets each apart (its legend entry).

    A parameter away from its default in any result is named in every
    entry; the method and mesh are named only where they differ.
    """
    show = {k for eq in eqs for k in _problem_items(eq.problem)}
    items = [{**_problem_items(eq.problem, show), "method": eq.solver.method,
              "nodes": f"{eq.solver.nodes} nodes"} for eq in eqs]
    keys = list(dict.fromkeys(k for it in items for k in it))
    shared = {k for k in keys if all(it.get(k) == items[0].get(k) for it in items)}
    title = _join({k: v for k, v in items[0].items() if k in shared - {"method", "nodes"}})
    labels = [_join({k: it[k] for k in keys if k in it and k not in shared}) or f"#{i + 1}"
              for i, it in enumerate(items)]
    return title, labels


# --------------------------------------------------------------------------
# Fig. 2 J and K
# --------------------------------------------------------------------------

#: Colours of the measures in Fig. 2 J.
MEASURE_COLOURS = {"opening": "tab:blue", "rotation": "tab:orange", "displacement": "tab:green"}
_MEASURE_LABEL = {"opening": r"opening $o$", "rotation": r"rotation $\varrho$",
          "displacement": r"displacement $d$"}


def plot_k_estimates(ax: Axes, result, truth=None, ylim=None) -> Axes:
    """Estimates of k per embryo (paper Fig. 2 J).

    Three groups (o, ϱ, d), one column per embryo: open markers the paper's
    asymptotic estimates, filled the numerical ones; large markers with bars
    the mean ± standard deviation of each.  Estimates off the axis (or with
    no k in the range, beyond it) are arrows at the axis.  ``truth``, a
    mapping embryo → k, adds grey ticks (synthetic data).

    Parameters
    ----------
    ax : Axes
    result
        The result of ``morphoshell.inverse.estimate``.
    truth : mapping, optional
        Embryo → true k.
    ylim : (float, float), optional
        The k axis' range (default: from the result's k range).

    Returns
    -------
    Axes
        ``ax``.
    """
    from ..inverse import MEASURES

    n = len(result.embryos)
    lo, hi = result.settings["k_range"]
    ylim = ylim or (max(lo, -0.6) - 0.05, min(hi, 1.0) + 0.08)
    gap = 2
    for g, measure in enumerate(MEASURES):
        x0 = g * (n + gap)
        colour = MEASURE_COLOURS[measure]
        for j, e in enumerate(result.embryos):
            x = x0 + j
            if truth is not None and e.measurement.embryo in truth:
                ax.plot([x - 0.35, x + 0.35], [truth[e.measurement.embryo]] * 2, color="0.5",
                        lw=1.2, zorder=1)
            for method, filled, dx in (("asymptotic", False, -0.18), ("numerical", True, 0.18)):
                est = e.estimates[(measure, method)]
                _marker(ax, x + dx, est, colour, filled, ylim)
        for method, filled, dx in (("asymptotic", False, -0.25), ("numerical", True, 0.25)):
            s = result.summary[f"{measure}_{method}"]
            if s.n:
                ax.errorbar(x0 + n + 0.2 + dx, s.mean, yerr=s.std or 0, color=colour, capsize=3,
                            marker="o", ms=9, mfc=colour if filled else "white", mew=1.5, lw=1.5,
                            zorder=3)
        ax.text(x0 + (n - 1) / 2, ylim[1] - 0.01 * (ylim[1] - ylim[0]), _MEASURE_LABEL[measure],
                ha="center", va="top", fontsize="small", color=colour)
    ax.axhline(0.0, color="0.8", lw=0.8, zorder=0)
    ax.axhline(1.0, color="0.8", lw=0.8, ls=":", zorder=0)   # stress-free: no recoil
    c = result.summary["combined"]
    if c.n:
        ax.axhline(c.mean, color="k", lw=1.0, ls="--", zorder=0,
                   label=rf"$\langle k\rangle = {c.mean:.3f}$ ($\varrho$ and $d$, numerical)")
    ax.set_ylim(*ylim)
    ax.set_xlim(-1, 3 * (n + gap) - gap + 1)
    ax.set_xticks([])
    ax.set_xlabel(f"embryos (N = {n}), grouped by measure; large markers: mean ± std")
    ax.set_ylabel(r"intrinsic curvature $k$ (units of $1/R$)")
    ax.plot([], [], "o", color="0.3", mfc="white", label="asymptotic (paper's formulas)")
    ax.plot([], [], "o", color="0.3",
            label=f"numerical (toy problem 2, {result.settings['theory']})")
    if truth is not None:
        ax.plot([], [], "-", color="0.5", label="true k (synthetic data)")
    ax.legend(loc="lower left", fontsize="x-small", frameon=False)
    return ax


def _marker(ax, x, est, colour, filled, ylim):
    style = dict(color=colour, mfc=colour if filled else "white", mew=1.1, ms=5, zorder=2)
    if est.k is not None and ylim[0] <= est.k <= ylim[1]:
        ax.plot(x, est.k, "o", **style)
    elif est.k is not None or est.side is not None:
        below = est.k < ylim[0] if est.k is not None else est.side == "below"
        ax.plot(x, ylim[0] + 0.03 if below else ylim[1] - 0.03, "v" if below else "^", **style)


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
    if fit is None:
        ax.text(0.5, 0.5, "no recoil velocities", transform=ax.transAxes, ha="center")
        ax.set_axis_off()
        return ax
    X, V = np.array(fit.X_um), np.array(fit.V_um_per_s)
    ax.plot(X, V, "o", color="tab:purple", ms=5, label="embryos")
    x = np.linspace(0, 1.1 * X.max(), 50)
    se = "" if fit.standard_error is None else rf" \pm {fit.standard_error:.2f}"
    ax.plot(x, fit.E_over_mu * x, "k-", lw=1.2,
            label=rf"$V = \langle E/\mu\rangle\,X$, $\langle E/\mu\rangle = {fit.E_over_mu:.2f}"
                  rf"{se}\,\mathrm{{s^{{-1}}}}$")
    ax.set_xlim(0, None)
    ax.set_ylim(0, None)
    ax.set_xlabel(r"$X = H^{5/2}R^{-3/2}|1-k|$ (µm)")
    ax.set_ylabel(r"initial recoil velocity $V$ (µm/s)")
    ax.legend(loc="upper left", fontsize="x-small", frameon=False)
    ax.text(0.97, 0.03, f"E ≥ {fit.E_lower_bound_Pa * 1e3:.2g} mPa (μ ≥ {fit.mu_min_Pa_s * 1e3:g} "
                        f"mPa s)\nE H³ ≥ {fit.bending_modulus_lower_bound_J:.2g} J "
                        f"(H = {fit.H_mean_um:.3g} µm)",
            transform=ax.transAxes, ha="right", va="bottom", fontsize="x-small")
    return ax


def figure_JK(result, truth=None) -> Figure:
    """Fig. 2 J and K side by side (a Matplotlib figure) of an :class:`~morphoshell.inverse.InverseResult`.

    Returns
    -------
    Figure
        :func:`plot_k_estimates` and :func:`plot_recoil_velocity`, in pyplot.
    """
    fig, (a, b) = plt.subplots(1, 2, figsize=(11.5, 4.4), gridspec_kw={"width_ratios": [2.2, 1]},
                               constrained_layout=True)
    plot_k_estimates(a, result, truth)
    plot_recoil_velocity(b, result)
    a.set_title("J  intrinsic curvature from ablation recoils", loc="left", fontsize="medium")
    b.set_title("K  recoil velocity", loc="left", fontsize="medium")
    return fig


# --------------------------------------------------------------------------
# plots
# --------------------------------------------------------------------------

def new_axes(figsize: tuple[float, float] | None = None, *, legend: bool = False,
             pyplot: bool = True) -> Axes:
    """Axes in a new figure with a constrained layout (a legend beside the axes fits).

    Parameters
    ----------
    figsize : (float, float), optional
        Width and height (inches); default 4.8 × 4.8, 1.6 wider with ``legend``.
    legend : bool
        Leave room for a legend beside the axes (default size only).
    pyplot : bool
        Register the figure with pyplot (shown inline in Jupyter, closed by
        ``plt.close``).  ``False`` gives a figure unknown to pyplot: no
        backend, no window, freed with its last reference — for programs
        that only save it (the command line).

    Returns
    -------
    Axes
    """
    if figsize is None:
        figsize = (_FIGSIZE[0] + 1.6 * legend, _FIGSIZE[1])
    fig = (plt.figure(figsize=figsize, layout="constrained") if pyplot
           else Figure(figsize=figsize, layout="constrained"))
    return fig.add_subplot()


def _wrap(text: str, ax: Axes) -> str:
    """Break a long description between its items (", ") to fit above the axes.

    Matplotlib's own wrapping breaks at any space ("h =" / "0.15"); the width
    in characters is estimated from the font size (a character ≈ 0.55 em) and
    the axes' width (a fifth more: a title may overhang the axes).
    """
    size = mpl.font_manager.FontProperties(size=mpl.rcParams["axes.titlesize"])
    inches = 1.2 * ax.get_window_extent().width / ax.figure.dpi
    width = int(inches * 72 / (0.55 * size.get_size_in_points()))
    lines: list[str] = []
    for line in text.split("\n"):
        out = ""
        for item in line.split(", "):
            joined = f"{out}, {item}" if out else item
            if out and len(joined) > width:
                lines.append(out + ",")
                joined = item
            out = joined
        lines.append(out)
    return "\n".join(lines)


def _finish(ax: Axes, title: str | None, legend: bool) -> Axes:
    """Cross-section axes: equal aspect, lengths in units of R, title, legend outside."""
    # equal scales by widening the data limits, not by shrinking the box: the
    # box then fills the space the layout gave it, legend beside it included
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel(r"$r/R$")
    ax.set_ylabel(r"$z/R$")
    if title:
        ax.set_title(_wrap(title, ax))
    if legend:
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
                       legend: bool | str = "auto", **style) -> Axes:
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
        "auto": what the results share (:func:`problem_label` for one); None: no title.
    legend : bool or "auto"
        Legend beside the axes (outside the shells); "auto": for several results or
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
    auto_title, auto_labels = _describe(eqs)
    if len(eqs) == 1:
        auto_labels = [problem_label(eqs[0].problem)]
    if ax is None:
        ax = new_axes(legend=bool(legend))
    style = normalize_kwargs(style, Line2D)
    for i, (eq, label) in enumerate(zip(eqs, labels or auto_labels)):
        line = {"color": f"C{i}", "linewidth": 1.0, "zorder": 2.0, "label": label,
                **_per_result(style, i)}
        _draw_shell(ax, eq, band, line)
    return _finish(ax, auto_title if title == "auto" else title, legend)


def plot_fit(result, ax: Axes | None = None, *, title: str | None = "auto", **style) -> Axes:
    """A fitted shell (midline and thickness band) over the data midline it was fitted to.

    Parameters
    ----------
    result : morphoshell.fitting.FitResult
    ax : matplotlib Axes, optional
    title : str or None
        "auto": method, variant and E_fit (units of R).
    **style
        Line properties of the fitted midline.

    Returns
    -------
    Axes
    """
    ax = plot_cross_section(result.equilibrium, ax, title=None, legend=False,
                            label="fit", **style)
    r, z = result.data[:, 0], result.data[:, 1]
    ax.plot(np.concatenate([-r[::-1], r]), np.concatenate([z[::-1], z]), ls="none",
            marker="o", ms=2.5, mfc="none", color="k", label="data", zorder=3)
    if title == "auto":
        title = (f"{result.method} fit, {result.variant}: E_fit = {result.E_fit:.3g} R "
                 f"({len(result.fitted)} parameters)")
    return _finish(ax, title, True)


def plot_ablation(ablation, ax: Axes | None = None, *, title: str | None = "auto",
                  legend: bool = True, mark_rim: bool = True, midline_only: bool = False,
                  colors: tuple[str, str] | None = None, **style) -> Axes:
    """Draw the pre- (light) and post-ablation (dark) cross-sections of an ablation.

    Both shells are drawn in the gauge of the observables (far end at its
    undeformed position, see :func:`morphoshell.mechanics.ablation.edge_state`), so
    the recoil seen is the one ``ablation.displacement`` gives.  The
    whole intact shell is drawn, cap included, as an opaque band under the
    post-ablation one; both midlines (pre dashed) are drawn on top.

    Parameters
    ----------
    ablation : morphoshell.mechanics.ablation.Ablation
    ax : matplotlib Axes, optional
        Drawn into; a new figure (via pyplot) if not given.
    title : str or None
        "auto": :func:`problem_label` of the ablated problem; None: no title.
    legend : bool
        Legend (pre/post) beside the axes.
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
    from ..mechanics.ablation import edge_state

    if ax is None:
        ax = new_axes(legend=bool(legend))
    style = normalize_kwargs(style, Line2D)
    sigma = float(ablation.problem.cut)
    for i, (key, eq) in enumerate((("pre", ablation.pre), ("post", ablation.post))):
        spec = ABLATION_STYLE[key]
        color = colors[i] if colors else spec["color"]
        face = 1 - spec["fill"] * (1 - np.array(to_rgb(color)))   # that opacity on white
        shift = far_end_shift(eq)
        # midlines above both bands, so that the pre-ablation shape stays visible
        line = {"color": color, "linestyle": spec["ls"], "linewidth": 0.8, "zorder": 3.0,
                "label": spec["label"], **style}
        midline, patch = _draw_shell(ax, eq, None if midline_only else "fill", line, face=face,
                                     shift=shift, band_zorder=1.0 + i)
        if patch is not None:   # the legend shows the band's colour
            patch.set_label(midline.get_label())
            midline.set_label("_nolegend_")
        if mark_rim:
            rim = edge_state(eq, sigma)
            ax.plot([rim["r"], -rim["r"]], [rim["z"]] * 2, ls="none", marker="o", ms=3.5,
                    color=color, zorder=4.0)
    label = problem_label(ablation.problem)
    return _finish(ax, label if title == "auto" else title, legend)


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

    Returns
    -------
    Axes
        Extent of the image in units of R.
    """
    if ax is None:
        ax = new_axes()
    paths = [_band_path(eq, far_end_shift(eq)) for eq in (ablation.pre, ablation.post)]
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
    ax.imshow(image, extent=(lo[0], hi[0], lo[1], hi[1]), interpolation="antialiased")
    ax.set_aspect("equal")
    ax.set_xlabel("r / R")
    ax.set_ylabel("z / R")
    if title:
        ax.set_title(title)
    return ax


def save(fig_or_ax, path: str | Path, formats: Sequence[str] | None = None, *,
         dpi: float = 300, close: bool = False, tight: bool | None = None) -> list[Path]:
    """Save a figure; returns the paths written.

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

    Returns
    -------
    list of Path
        One per format.
    """
    fig = fig_or_ax
    while not isinstance(fig, Figure):   # Axes -> (SubFigure ->) Figure
        fig = fig.figure
    if tight is None:
        tight = fig.get_layout_engine() is None
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    out = []
    for fmt in formats or [path.suffix.lstrip(".") or "png"]:
        target = path.with_suffix("." + fmt)
        fig.savefig(target, dpi=dpi, bbox_inches="tight" if tight else None)
        out.append(target)
    if close:
        plt.close(fig)
    return out


# --------------------------------------------------------------------------
# paper figures
# --------------------------------------------------------------------------

def paper_style():
    """Context manager of the paper style (:data:`PAPER_RC`): fonts ≥ 7 pt, 300 dpi.

    Create *and* save the figures inside it: fonts are set when artists are
    made, the PDF font type when the file is written.
    """
    return mpl.rc_context(PAPER_RC)


def label_panel(ax: Axes, letter: str, *, size: float = 10.0, dx: float = -4.0,
                dy: float = 4.0):
    """Bold panel letter above the top-left corner of ``ax``, outside its title.

    Parameters
    ----------
    letter : str
    size : float
        Font size (points).
    dx, dy : float
        Offset of the letter's right/bottom edge from the axes' corner (points).

    Returns
    -------
    matplotlib.text.Text
    """
    offset = ScaledTranslation(dx / 72, dy / 72, ax.figure.dpi_scale_trans)
    return ax.text(0.0, 1.0, letter, transform=ax.transAxes + offset, ha="right", va="bottom",
                   fontsize=size, fontweight="bold")
