"""Bifurcation diagrams of branches of equilibria (:func:`morphoshell.follow_branch`).

A branch is drawn against its path parameter (λ, or the one parameter
continued in) with one observable on the other axis: stable parts solid,
unstable parts dashed (thin, grey), folds, branch points and snap-throughs
marked, and the shells at the events and at the ends beside it, so that the
diagram and the shapes it stands for are read together.  Lengths in units of
R, energies in C R².

Drawn in the journal style (:mod:`.style`): two columns wide with the shapes,
one without; the title names the problem, the caption the path, the
parameters and the mesh.  Colours are the Okabe–Ito palette, which stays
distinguishable with red–green colour blindness, and every switched branch
also has a marker of its own, so that no branch is told apart by colour alone.
"""
from __future__ import annotations

from typing import Sequence

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure, SubFigure
from matplotlib.transforms import Affine2D

from ..solvers.refinement import COARSE
from .shells import plot_cross_section, problem_caption, problem_title
from .style import (DOUBLE_COLUMN, MIN_FONT_SIZE, OKABE_ITO, SINGLE_COLUMN, add_caption,
                    journal_figure, styled)

__all__ = ["plot_branch", "BRANCH_STYLE", "EVENT_MARKERS", "AXIS_LABELS", "MAX_SHAPES",
           "SWITCHED_COLOURS", "SWITCHED_MARKERS", "OKABE_ITO", "branch_caption", "axis_label",
           "default_y", "Y_CANDIDATES"]

#: Most shells drawn beside a diagram (start, events, end): more would be too small to read.
MAX_SHAPES = 8

#: Lines of the diagram: stable and unstable parts (a grey dark enough to stay apart from
#: the bluish green of a switched branch with red–green colour blindness).
BRANCH_STYLE = {"stable": {"color": "k", "ls": "-", "lw": 1.2},
                "unstable": {"color": "0.35", "ls": "--", "lw": 0.9}}
#: Markers of the events: (marker, colour, legend entry).
EVENT_MARKERS = {"fold": ("o", OKABE_ITO["vermillion"], "fold"),
                 "branch_point": ("D", OKABE_ITO["reddish purple"], "branch point"),
                 "snap": ("v", OKABE_ITO["blue"], "after a snap-through")}
#: Colours of the branches switched to at branch points (:func:`switch_branch`), by origin:
#: the Okabe–Ito colours the events leave.
SWITCHED_COLOURS = (OKABE_ITO["bluish green"], OKABE_ITO["orange"], OKABE_ITO["sky blue"])
#: Markers along the switched branches, by origin: the cue that does not need colour (none
#: is an event's marker).  With the colours cycling, the first six origins differ in both.
SWITCHED_MARKERS = ("s", "X", "P", "*", "^", ">")
#: Spacing of the markers along a switched branch (a fraction of the axes' diagonal).
MARK_EVERY = 0.08
#: The default diagram's observable: the first of these that varies along the branch
#: (:func:`default_y`).  ψ at the far end separates a branch's parts best where it moves;
#: a shell with a cut ends in its pole, where ψ = π and r = 0 at every point (audit 14:
#: a cap's diagram was one flat line, its folds on it), and its height moves instead.
Y_CANDIDATES = ("psi_end", "z_end", "r_end", "energy")
#: A column varies along a branch if its range exceeds this, relative to its largest
#: magnitude (at least 1): a pole's ψ and r are exact (range 0); a far end that moves,
#: moves by far more than round-off (1e-3 R and rad on the audited shells).
CONSTANT = 1e-9
#: Axis labels of the branch table's columns.
AXIS_LABELS = {"lambda": r"path fraction $\lambda$", "energy": r"energy $E$ ($C R^2$)",
               "r_end": r"$r$ at the far end ($R$)",
               "z_end": r"far end's height above the first point ($R$)",
               "psi_end": r"$\psi$ at the far end (rad)",
               "negative_eigenvalues": "negative eigenvalues"}


def plot_branch(branch, *, y: str = "auto", x: str | None = None, shapes: bool = True,
                fig: Figure | None = None, switched: Sequence = (), title: str | None = "auto",
                caption: str | None = "auto") -> Figure:
    """A bifurcation diagram of ``branch``, with the shapes at its events beside it.

    Parameters
    ----------
    branch : Branch
        From :func:`morphoshell.solvers.branches.follow_branch`.
    y : str
        The observable: a column of the branch's table (``psi_end``,
        ``r_end``, ``z_end``, ``energy``); "auto" (default): the first of
        :data:`Y_CANDIDATES` that varies along the branch or the switched
        ones (:func:`default_y`).
    x : str, optional
        ``"lambda"`` or the continued parameter (default: the parameter if
        the branch continues one, else λ).
    shapes : bool
        Draw the cross-sections at the start, the events and the end below
        the diagram (at most :data:`MAX_SHAPES`).
    fig : Figure, optional
        Drawn into.  If None, a new figure in the journal style, outside
        pyplot: two journal columns wide with the shapes
        (:data:`~morphoshell.plotting.DOUBLE_COLUMN`), one without
        (:data:`~morphoshell.plotting.SINGLE_COLUMN`).
    switched : sequence of Branch
        Branches followed from ``branch``'s branch points
        (:func:`morphoshell.solvers.branches.switch_branch`): drawn in one
        colour and marker per branch point (:data:`SWITCHED_COLOURS`,
        :data:`SWITCHED_MARKERS`), solid where stable, their ends first
        among the shapes.
    title : str or None
        One line over the diagram; "auto": the problem (name, family,
        theory); None: none.
    caption : str or None
        Under the diagram; "auto": the path, the parameters and the mesh
        (:func:`branch_caption`); None: none.

    Returns
    -------
    Figure
    """
    table = branch.columns()
    x = x or (branch.parameter or "lambda")
    y = default_y(branch, switched) if y == "auto" else y
    for name, what in ((x, "x"), (y, "y")):
        if name not in table or name in ("stable", "event", "lambda_error"):
            numeric = [k for k in table if k not in ("stable", "event", "lambda_error")]
            raise ValueError(f"{what} = {name!r}: choose one of {numeric}")
    if fig is None:
        width = DOUBLE_COLUMN if shapes else SINGLE_COLUMN
        fig = journal_figure(width, (0.85 if shapes else 1.0) * width, pyplot=False)
    styles = list(zip(switched, _switched_styles(switched)))
    with styled(fig):
        if shapes:
            top, bottom = fig.subfigures(2, 1, height_ratios=(1.2, 1))
            ax = top.add_subplot()
            _shapes(bottom, branch, styles)
        else:
            ax = fig.add_subplot()
        _diagrams(ax, table, styles, x, y, beside=shapes)
        units = branch.units()
        ax.set_xlabel(axis_label(x, units))
        ax.set_ylabel(axis_label(y, units))
        if title:
            ax.set_title(problem_title(branch.problem) if title == "auto" else title)
        if caption:
            add_caption(ax, branch_caption(branch, switched) if caption == "auto" else caption)
    return fig


def default_y(branch, switched: Sequence = ()) -> str:
    """The first of :data:`Y_CANDIDATES` that varies (by more than :data:`CONSTANT`,
    relative) along ``branch`` and the ``switched`` branches drawn with it: ``psi_end``
    where the far end turns (a blister's flat disc keeps ψ, the domes switched to from it
    do not), ``z_end`` for a shell with a cut (its far end is the pole); the last
    candidate if none varies."""
    tables = [b.columns() for b in (branch, *switched)]
    for name in Y_CANDIDATES:
        values = np.concatenate([np.asarray(t[name], float) for t in tables])
        if np.ptp(values) > CONSTANT * max(1.0, float(np.max(np.abs(values)))):
            return name
    return Y_CANDIDATES[-1]


def branch_caption(branch, switched: Sequence = ()) -> str:
    """What a diagram's title leaves out: the path, the parameters, the method and mesh.

    The parameters are those of the path's end (τ = 1, ``branch.problem``).
    """
    if branch.parameter:
        path = (f"continued in {branch.parameter} from {branch.line.a[0]:g} to "
                f"{branch.line.b[0]:g}")
    else:
        path = "λ from the stress-free parameters (0) to these (1)"
    path += (", the connected branch" if branch.follow == "branch"
             else ", the quasi-static path, snapping through at folds")
    solver = branch.points[0].equilibrium.solver
    parts = [problem_caption(branch.problem), path,
             f"{solver.method} method, {solver.nodes} nodes"]
    if switched:
        parts.append("in colour, with markers: the branches switched to at branch points")
    parts += _warnings(branch)
    return "; ".join(parts)


def _warnings(branch) -> list[str]:
    """What the caption must say of a branch: where it ended early and why (its last point
    the last physical state), and the events the mesh does not resolve."""
    out = []
    if branch.ended is not None and branch.ended.stopped:
        # (why, in the JSON and the CSV: a caption of its length left the axes no room)
        out.append(f"PARTIAL: the walk stopped early at λ = {branch.end.tau:.4g}")
    elif branch.ended is not None:
        out.append(f"ends at λ = {branch.ended.tau:.6g}: past it the meridian crosses the "
                   f"axis ({branch.ended.status})")
    if branch.unresolved:
        kinds = sorted({pt.event.replace("_", " ") for pt in branch.unresolved})
        out.append(f"not resolved by the mesh (artefacts?): the {' and '.join(kinds)}s at "
                   f"λ = {', '.join(f'{pt.tau:.4g}' for pt in branch.unresolved)}")
    return out


def _switched_styles(switched: Sequence) -> list[tuple[str, str]]:
    """(colour, marker) per branch point of origin (both halves of its branch alike)."""
    origins = list(dict.fromkeys(b.origin for b in switched))
    return [(SWITCHED_COLOURS[k % len(SWITCHED_COLOURS)],
             SWITCHED_MARKERS[k % len(SWITCHED_MARKERS)])
            for k in (origins.index(b.origin) for b in switched)]


def _diagrams(ax: Axes, table: dict, styles: list, x: str, y: str, *, beside: bool) -> None:
    """The branch's diagram (:func:`_diagram`) over the switched ones, each in its style.

    The legend goes beside the axes (``beside``: the two-column figure has
    the width) or under the caption (one column).
    """
    for other, style in styles:
        _line(ax, other.columns(), x, y, *style)
    _diagram(ax, table, x, y)
    for origin, (colour, marker) in dict((b.origin, s) for b, s in styles).items():
        ax.plot([], [], color=colour, marker=marker, lw=1.2,
                label=f"branch from λ = {origin:.4g}")
    # one legend, never over the lines: beside them in two columns, below the caption in one
    if beside:
        ax.legend(loc="center left", bbox_to_anchor=(1.0, 0.5))
    else:
        ax.figure.legend(*ax.get_legend_handles_labels(), loc="outside lower center", ncols=2)


def _line(ax: Axes, table: dict, x: str, y: str, colour: str, marker: str) -> None:
    """A switched branch: solid where stable, dashed where not, in its colour and marker."""
    xs, ys = np.asarray(table[x], float), np.asarray(table[y], float)
    for i0, i1, is_stable in _runs(np.asarray(table["stable"], bool), list(table["event"])):
        style = {**BRANCH_STYLE["stable" if is_stable else "unstable"], "color": colour}
        ax.plot(xs[i0:i1 + 1], ys[i0:i1 + 1], marker=marker, markevery=MARK_EVERY,
                ms=3.5, **style)


def _diagram(ax: Axes, table: dict, x: str, y: str) -> None:
    """The branch as a line, solid where stable, dashed where not, events marked."""
    xs, ys = np.asarray(table[x], float), np.asarray(table[y], float)
    stable = np.asarray(table["stable"], bool)
    events = list(table["event"])
    for i0, i1, is_stable in _runs(stable, events):
        style = BRANCH_STYLE["stable" if is_stable else "unstable"]
        ax.plot(xs[i0:i1 + 1], ys[i0:i1 + 1], **style)
    # an event the half mesh does not reproduce (Branch.unresolved: "unresolved" in the
    # legend, the caption says by what) is an open marker: it may be an artefact of the
    # mesh (audit 14: toy 3's folds on 200 nodes)
    loose = np.asarray(table.get("lambda_error", np.full(len(events), np.nan)), float) > COARSE
    for kind, (marker, colour, label) in EVENT_MARKERS.items():
        for unresolved, face, name in ((False, colour, label),
                                       (True, "white", f"{label} (unresolved)")):
            at = [i for i, e in enumerate(events) if e == kind and loose[i] == unresolved]
            if at:
                ax.plot(xs[at], ys[at], marker, color=colour, mfc=face, ms=5, ls="none",
                        label=name, zorder=3)
    for i, event in enumerate(events):
        if event == "snap" and i > 0:       # the jump: from the fold to where it lands
            ax.annotate("", (xs[i], ys[i]), (xs[i - 1], ys[i - 1]),
                        arrowprops={"arrowstyle": "->", "color": EVENT_MARKERS["snap"][1],
                                    "lw": 0.8, "ls": ":"})
    ax.plot([], [], **BRANCH_STYLE["stable"], label="stable")
    if not stable[[e == "" for e in events]].all():
        ax.plot([], [], **BRANCH_STYLE["unstable"], label="unstable")


def axis_label(name: str, units: dict) -> str:
    """The label of the column ``name``: :data:`AXIS_LABELS`'s, else the name with its unit
    from ``units`` (``Branch.units()``: a family's parameter, κ₂ in 1/R, had none; none
    for a pure number, "1")."""
    if name in AXIS_LABELS:
        return AXIS_LABELS[name]
    unit = units.get(name, "1")
    return name if unit == "1" else f"{name} (${unit}$)"


def _runs(stable: np.ndarray, events: Sequence[str]) -> list[tuple[int, int, bool]]:
    """Index ranges (first, last, stable) of the parts of one stability.

    Each segment between neighbouring points takes the stability of its
    ordinary end (a fold or branch point is marginal: the parts on either
    side meet there); no segment leads into a snap-through (the shell jumps).
    """
    runs: list[tuple[int, int, bool]] = []
    for i in range(len(stable) - 1):
        if events[i + 1] == "snap":
            continue
        ordinary = i + 1 if events[i] in ("fold", "branch_point") else i
        kind = bool(stable[ordinary])
        if runs and runs[-1][1] == i and runs[-1][2] == kind:
            runs[-1] = (runs[-1][0], i + 1, kind)
        else:
            runs.append((i, i + 1, kind))
    return runs


def _shapes(fig: SubFigure, branch, switched: list) -> None:
    """Small cross-sections of the shell at the start, the switched branches' ends, each event
    and the end; their titles and ticks in :data:`MIN_FONT_SIZE`, the smallest legible."""
    later = [pt for pt in branch.points[1:-1] if pt.event] + [branch.points[-1]]
    shown = [(branch.points[0], "start", "k")]
    shown += [(b.end, f"from λ = {b.origin:.4g} ({'+' if b.direction > 0 else '−'})", colour)
              for b, (colour, _) in switched]
    shown += [(pt, *(EVENT_MARKERS[pt.event][2:0:-1] if pt.event else ("end", "k")))
              for pt in later]
    shown = shown[:MAX_SHAPES]
    columns = min(len(shown), MAX_SHAPES // 2)
    rows = -(-len(shown) // columns)
    axes = np.atleast_1d(fig.subplots(rows, columns)).ravel()
    limits = _limits([pt.equilibrium for pt, _, _ in shown])
    for ax, (pt, what, colour) in zip(axes, shown):
        state = ("marginal" if pt.event in ("fold", "branch_point") else
                 "stable" if pt.stable else f"unstable ({pt.negative_eigenvalues})")
        plot_cross_section(pt.equilibrium, ax, title=None, legend=False, color=colour)
        _from_first_point(ax, pt.equilibrium)
        # two short lines: one long line ran past the figure's edge
        ax.set_title(f"{what}\nλ = {pt.tau:.4g}, {state}", fontsize=MIN_FONT_SIZE)
        ax.set_aspect("equal", adjustable="box")
        ax.set(xlim=limits[0], ylim=limits[1], xlabel="", ylabel="")
        ax.tick_params(labelsize=MIN_FONT_SIZE)
    for ax in axes[len(shown):]:
        ax.set_axis_off()
    fig.supxlabel(r"$r/R$")
    fig.supylabel(r"$z/R$ above the first point")


def _from_first_point(ax: Axes, eq) -> None:
    """Move a shape drawn in the solver's gauge (the first point at its undeformed height)
    so that its first point is at z = 0: the gauge of the diagram's ``z_end``, the far
    end's height above the first point.  Audit 19: the thumbnail's far pole stood 1 − cos Σ
    (0.045 R) above the diagram's value for the same shell."""
    shift = Affine2D().translate(0.0, -float(eq.z[0])) + ax.transData
    for artist in (*ax.lines, *ax.patches, *ax.collections):
        artist.set_transform(shift)


def _limits(eqs) -> tuple[tuple[float, float], tuple[float, float]]:
    """Common (r, z) limits of the mirrored shells (z above their first points, as
    :func:`_from_first_point` draws them), with a margin: one scale for all panels."""
    r = max(float(np.max(eq.r)) for eq in eqs) * 1.08
    z = np.concatenate([eq.z - eq.z[0] for eq in eqs])
    pad = 0.08 * (float(z.max()) - float(z.min()) + 1e-12)
    return (-r, r), (float(z.min()) - pad, float(z.max()) + pad)
