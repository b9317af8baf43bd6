"""Figures a journal would take (issue 41, item 7): one-line titles that name the problem,
parameters in a caption, nothing cut at the figure's edge, both ablation states visible,
the fit's residual along the midline, every marker kind of Fig. 2 J in its legend,
single-column sizes and fonts >= 7 pt.

Equilibria on coarse meshes (40-50 nodes): the drawing is under test, not the solution.
"""
import re
import warnings
from types import SimpleNamespace

import matplotlib.pyplot as plt
import numpy as np
import pytest
from matplotlib.collections import LineCollection
from matplotlib.colors import to_rgba
from matplotlib.text import Text

from morphoshell.mechanics.ablation import ablate
from morphoshell.model.problem import Problem
from morphoshell.plotting import (ABLATION_STYLE, DOUBLE_COLUMN, MIN_FONT_SIZE, OFF_SCALE_LABEL,
                                  SINGLE_COLUMN, fit_axes, fit_residuals, get_caption, new_axes,
                                  plot_ablation, plot_cross_section, plot_fit, plot_k_estimates,
                                  save)


@pytest.fixture(scope="module")
def ablation():
    return ablate(Problem("uniform", {"k": 0.0}, h=0.3, cut=0.3, name="toy2"), nodes=40)




def _texts(fig):
    return [t for t in fig.findobj(Text) if t.get_visible() and t.get_text().strip()]


def _outside_figure(fig, tmp_path) -> list[str]:
    """The axes whose drawn content (title, labels, ticks, caption, legend) reaches past
    the edges of the figure as saved; "" for each, titled by its title."""
    # at the figure's own dpi: the extents below are those of the last drawing
    save(fig, tmp_path / "figure.png", dpi=fig.dpi)
    box = fig.bbox
    return [ax.get_title() for ax in fig.axes
            if (e := ax.get_tightbbox()).x0 < box.x0 - 1 or e.x1 > box.x1 + 1
            or e.y0 < box.y0 - 1 or e.y1 > box.y1 + 1]


def test_the_title_is_one_line_naming_the_problem_and_the_caption_has_the_parameters(
        volvox, tmp_path):
    ax = plot_cross_section(volvox, new_axes(pyplot=False))
    assert ax.get_title() == "volvox_demo: volvox, large-bending"
    caption = get_caption(ax)
    for part in ("h = 0.15", "opening P = 0.3", "kappa1 = 1.1", "volvox defaults",
                 "direct method, 50 nodes"):
        assert part in caption, part
    # the figure is one journal column wide and every text is legible and inside it
    assert ax.figure.get_figwidth() == pytest.approx(SINGLE_COLUMN)
    assert min(t.get_fontsize() for t in _texts(ax.figure)) >= MIN_FONT_SIZE
    assert _outside_figure(ax.figure, tmp_path) == []


def test_ablation_draws_both_states_distinctly_and_marks_the_cut(ablation, tmp_path):
    ax = plot_ablation(ablation, new_axes(legend=True, pyplot=False))
    pre, post = sorted((l for l in ax.get_lines() if l.get_linestyle() != "None"),
                       key=lambda l: l.get_linestyle() != "--")
    assert pre.get_linestyle() == "--" and post.get_linestyle() == "-"
    assert to_rgba(pre.get_color()) == to_rgba(ABLATION_STYLE["pre"]["color"])
    assert to_rgba(post.get_color()) == to_rgba(ABLATION_STYLE["post"]["color"])
    # the pre-ablation shell is not hidden: its band under the post-ablation band, its
    # midline and outline (both edges of its band) over it
    pre_band, post_band = sorted(ax.patches, key=lambda p: p.get_zorder())
    assert pre_band.get_label() == "pre-ablation" and post_band.get_label() == "post-ablation"
    outline = [c for c in ax.collections if isinstance(c, LineCollection)]
    assert len(outline) == 1 and outline[0].get_zorder() > post_band.get_zorder()
    assert pre.get_zorder() > post.get_zorder() > post_band.get_zorder()
    # the cut's edge, in both states, and a legend entry for each kind
    rims = [l for l in ax.get_lines() if l.get_marker() == "o"]
    assert len(rims) == 2 and all(len(l.get_xdata()) == 2 for l in rims)
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert labels == ["pre-ablation", "post-ablation", "cut edge s = Σ"]
    assert "rotation ϱ" in get_caption(ax) and "cut Σ = 0.3" in get_caption(ax)
    assert "\n" not in ax.get_title() and ax.get_title().startswith("toy2")
    assert min(t.get_fontsize() for t in _texts(ax.figure)) >= MIN_FONT_SIZE
    assert _outside_figure(ax.figure, tmp_path) == []


def _fake_fit(eq):
    """A FitResult's fields that plot_fit reads, with known residuals."""
    rng = np.random.default_rng(1)
    model = np.column_stack([eq.r, eq.z])[::3]
    data = model + rng.normal(scale=0.01, size=model.shape)
    return SimpleNamespace(equilibrium=eq, data=data, model=model, method="gradient",
                           variant="free", fitted=("f1", "kappa1"), E_fit=0.123,
                           parameters={"h": 0.15, "opening": 0.3})


def test_fit_figure_has_the_residual_along_the_midline(volvox, tmp_path):
    result = _fake_fit(volvox)
    shell, residual = fit_axes(pyplot=False)
    plot_fit(result, shell, residual_ax=residual, name="trace.csv")
    line = residual.get_lines()[0]
    distance = np.hypot(*(result.model - result.data).T)
    np.testing.assert_allclose(line.get_ydata(), distance)
    steps = np.hypot(*np.diff(result.data, axis=0).T)
    np.testing.assert_allclose(line.get_xdata(), np.r_[0, np.cumsum(steps)])
    np.testing.assert_allclose(fit_residuals(result)[1], distance)
    assert "s/R" in residual.get_xlabel() and "model" in residual.get_ylabel()
    assert shell.get_title() == "trace.csv: volvox, large-bending"
    assert "E_fit = 0.123 R" in get_caption(residual)
    assert [t.get_text() for t in shell.get_legend().get_texts()] == ["fit", "data"]
    assert min(t.get_fontsize() for t in _texts(shell.figure)) >= MIN_FONT_SIZE
    assert _outside_figure(shell.figure, tmp_path) == []


def test_fit_on_a_callers_panels_keeps_its_caption_off_the_panels_below(volvox):
    # audit 12: plot_fit's caption fell under the caller's panel, over the next row
    fig, axs = plt.subplots(2, 2, figsize=(7, 6))
    plot_fit(_fake_fit(volvox), axs[0, 0], residual_ax=axs[1, 0])
    assert get_caption(axs[1, 0]) == "" and get_caption(axs[0, 0]) == ""
    plt.close(fig)


def _estimates(ks):
    """An InverseResult's fields that plot_k_estimates reads: every estimate of embryo j is
    ks[j] (None with a side: no k in range)."""
    from morphoshell.inverse import MEASURES

    def est(k):
        return SimpleNamespace(k=k, side=None if k is not None else "above")

    embryos = [SimpleNamespace(measurement=SimpleNamespace(embryo=f"e{j}"),
                               estimates={(m, method): est(k) for m in MEASURES
                                          for method in ("asymptotic", "numerical")})
               for j, k in enumerate(ks)]
    stats = SimpleNamespace(n=len(ks), mean=0.1, std=0.05)
    return SimpleNamespace(embryos=embryos, settings={"k_range": (-1, 1),
                                                      "theory": "large_bending"},
                           summary={**{f"{m}_{method}": stats for m in MEASURES
                                       for method in ("asymptotic", "numerical")},
                                    "combined": stats})


@pytest.mark.parametrize("ks, off_scale", [([0.1, 0.2, 5.0], True), ([0.1, None], True),
                                           ([0.1, 0.2], False)])
def test_every_marker_kind_of_fig2J_is_in_its_legend(ks, off_scale):
    ax = plot_k_estimates(new_axes((7.0, 3.0), pyplot=False), _estimates(ks),
                          truth={"e0": 0.0})
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert (OFF_SCALE_LABEL in labels) == off_scale
    for kind in ("asymptotic", "numerical", "mean ± std", "true k", r"\langle k\rangle"):
        assert any(kind in label for label in labels), kind
    arrows = [l for l in ax.get_lines() if l.get_marker() in ("^", "v")]
    assert bool(arrows) == off_scale
    assert min(t.get_fontsize() for t in _texts(ax.figure)) >= MIN_FONT_SIZE


def test_fig2J_on_a_callers_panel_keeps_its_legend_inside_and_names_only_methods_run():
    # audit 13: the legend went under a caller's panel, over the next row, and named
    # "numerical" for a run of the asymptotic forms alone
    fig, axs = plt.subplots(2, 1, figsize=(7, 6))
    result = _estimates([0.1, 0.2])
    result.settings["methods"] = ["leading_order", "kelvin"]
    result.summary["combined"] = SimpleNamespace(n=0, mean=None, std=None)   # (numerical's)
    ax = plot_k_estimates(axs[0], result)
    fig.canvas.draw()
    legend, box = ax.get_legend().get_window_extent(), ax.get_window_extent()
    assert box.y0 <= legend.y0 and legend.y1 <= box.y1
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert any("asymptotic" in label for label in labels)
    assert not any("numerical" in label for label in labels)
    plt.close(fig)
    with pytest.raises(ValueError, match="legend = 'left'"):
        plot_k_estimates(new_axes(pyplot=False), result, legend="left")


def _profile(name, values, objective, converged, interval, flat=False):
    from morphoshell.fitting import Profile
    values = np.asarray(values, float)
    return Profile(name, 0.0, values, np.asarray(objective, float), np.asarray(converged),
                   interval, 2.0, 1.0, 0.1, "traces", 0.95, flat, "gradient")


def test_profile_figure_is_journal_sized_and_shows_every_kind_of_refit(tmp_path):
    """fit --profile-plot: two journal columns for several profiles, fonts >= 7 pt, one
    line per title, nothing outside the figure; the unconverged refit, the threshold and
    the interval are in the legend, and an open side is shaded to the panel's edge."""
    from morphoshell.plotting import DOUBLE_COLUMN, plot_profiles
    x = np.linspace(-1, 1, 5)
    profiles = {"kappa1": _profile("kappa1", x, 1 + x ** 2, [True, True, True, True, False],
                                   (-1.0, np.inf), flat=True),
                "f1": _profile("f1", x, 1 + 4 * x ** 2, [True] * 5, (-0.5, 0.5))}
    fig = plot_profiles(profiles, pyplot=False)
    assert fig.get_size_inches()[0] == pytest.approx(DOUBLE_COLUMN)
    first, second = fig.axes[:2]
    assert first.get_title() == r"$\kappa_{1}$: not determined" and second.get_title() == "$f_{1}$"
    (legend,) = fig.legends                         # one, below the panels
    labels = [t.get_text() for t in legend.get_texts()]
    assert {"not converged", "threshold", "95 % interval", "fit"} <= set(labels)
    span = next(p for p in first.patches)           # the interval, open above
    assert span.get_x() + span.get_width() == pytest.approx(first.get_xlim()[1])
    for one in (fig, plot_profiles({"kappa1": profiles["kappa1"]}, pyplot=False)):
        assert _outside_figure(one, tmp_path) == []
        box, drawn = one.bbox, one.legends[0].get_window_extent()
        assert box.x0 <= drawn.x0 and drawn.x1 <= box.x1 and box.y0 <= drawn.y0
        assert min(t.get_fontsize() for t in _texts(one)) >= MIN_FONT_SIZE
        assert all("\n" not in ax.get_title() for ax in one.axes)


@pytest.fixture(scope="module")
def blister():
    """The blister's flat branch (60 nodes) and both halves of the branches through its
    first two branch points: the most crowded diagram of the docs."""
    from morphoshell import follow_branch, switch_branch
    from morphoshell.io.problem_files import load_problem
    from morphoshell.io.problem_files import example_path

    flat = follow_branch(load_problem(example_path("blister"))[0], nodes=60)
    return flat, [switch_branch(flat, k, d) for k in (0, 1) for d in (1, -1)]


@pytest.mark.parametrize("shapes, width", [(True, 7.0), (False, SINGLE_COLUMN)])
def test_bifurcation_diagram_is_in_the_journal_style(blister, shapes, width, tmp_path):
    """plot_branch (continue --plot): two journal columns with the shapes, one without; every
    text >= 7 pt and inside the figure; a one-line title naming the problem, a caption with
    the parameters, the path and the mesh; the PDF's fonts TrueType (no Type 3)."""
    from morphoshell.plotting import plot_branch
    flat, switched = blister
    fig = plot_branch(flat, switched=switched, shapes=shapes)
    assert fig.get_figwidth() == pytest.approx(width)
    diagram = fig.axes[0]
    assert diagram.get_title() == "blister: central_growth, large-bending, disc"
    caption = get_caption(diagram)
    for part in ("h = 0.02", "G = 0.2", "λ from the stress-free parameters",
                 "direct method, 60 nodes", "branches switched to at branch points"):
        assert part in caption, part
    assert _outside_figure(fig, tmp_path) == []
    # after the drawing, which makes the tick labels
    assert min(t.get_fontsize() for t in _texts(fig)) >= MIN_FONT_SIZE
    legends = [*fig.legends, *(ax.get_legend() for ax in fig.axes if ax.get_legend())]
    assert len(legends) == 1
    box, drawn = fig.bbox, legends[0].get_window_extent()
    assert box.x0 <= drawn.x0 and drawn.x1 <= box.x1 and box.y0 <= drawn.y0
    save(fig, tmp_path / "branch.pdf")
    assert b"/Type3" not in (tmp_path / "branch.pdf").read_bytes()


#: Machado, Oliveira & Fernandes (2009), severity 1.0: linear RGB -> linear RGB as seen
#: with protanopia and deuteranopia.
MACHADO = {"protanopia": np.array([[0.152286, 1.052583, -0.204868],
                                   [0.114503, 0.786281, 0.099216],
                                   [-0.003882, -0.048116, 1.051998]]),
           "deuteranopia": np.array([[0.367322, 0.860646, -0.227968],
                                     [0.280085, 0.672501, 0.047413],
                                     [-0.011820, 0.042940, 0.968881]])}


def _seen(colour, matrix) -> np.ndarray:
    """sRGB of ``colour`` as seen through ``matrix`` (applied in linear RGB)."""
    from matplotlib.colors import to_rgb
    c = np.array(to_rgb(colour))
    linear = np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)
    seen = np.clip(matrix @ linear, 0.0, 1.0)
    return np.where(seen <= 0.0031308, 12.92 * seen, 1.055 * seen ** (1 / 2.4) - 0.055)


def test_the_diagrams_colours_stay_apart_with_red_green_colour_blindness():
    """Every two colours of a diagram (the main branch's two, the events', the switched
    branches') differ by >= 0.2 in sRGB (Euclidean, channels in [0, 1]) as seen with
    protanopia and deuteranopia.  The threshold: the old palette's tab:green and
    tab:orange came to 0.097 (one colour), tab:orange and tab:olive to 0.18 (user audit);
    the Okabe-Ito colours' closest pairs are 0.20 (reddish purple against bluish green and
    blue), against about 0.8 for colours told apart at a glance."""
    from itertools import combinations

    from morphoshell.plotting.branches import BRANCH_STYLE, EVENT_MARKERS, SWITCHED_COLOURS
    colours = [*(s["color"] for s in BRANCH_STYLE.values()),
               *(c for _, c, _ in EVENT_MARKERS.values()), *SWITCHED_COLOURS]
    assert len(set(colours)) == len(colours)
    for name, matrix in MACHADO.items():
        for a, b in combinations(colours, 2):
            distance = np.linalg.norm(_seen(a, matrix) - _seen(b, matrix))
            assert distance >= 0.2, (name, a, b, distance)


def test_each_switched_branch_has_a_marker_of_its_own(blister):
    """The cue that needs no colour: the lines of the branch from one branch point carry one
    marker (both halves, stable and unstable parts), different from the other branch's and
    from the events' markers, and the legend shows it."""
    from morphoshell.plotting import plot_branch
    from morphoshell.plotting.branches import EVENT_MARKERS
    flat, switched = blister
    diagram = plot_branch(flat, switched=switched, shapes=False).axes[0]
    drawn = [ln for ln in diagram.get_lines()          # (lines, not the events' markers)
             if len(ln.get_xdata()) > 1 and ln.get_linestyle() != "None"]
    by_origin = {}
    for branch in switched:
        ys = set(np.round(branch.columns()["psi_end"], 12))
        for ln in drawn:
            if set(np.round(ln.get_ydata(), 12)) <= ys and ln.get_marker() not in ("None", ""):
                by_origin.setdefault(branch.origin, set()).add(ln.get_marker())
    assert len(by_origin) == 2 and all(len(m) == 1 for m in by_origin.values())
    markers = [m.pop() for m in by_origin.values()]
    assert len(set(markers)) == 2
    assert not set(markers) & {m for m, _, _ in EVENT_MARKERS.values()}
    legend = diagram.figure.legends[0]
    shown = {h.get_marker() for h, t in zip(legend.legend_handles, legend.get_texts())
             if t.get_text().startswith("branch from")}
    assert shown == set(markers)


def test_fig2J_on_a_small_callers_panel_covers_no_estimate_and_its_labels_do_not_overlap():
    # audit 19 F4/F17: on a 2.3 in panel of a constrained 1 x 3 row the legend lay over the
    # y label and the estimates, the group labels over one another and (at the top) over
    # the off-scale arrows
    from morphoshell.plotting import DOUBLE_COLUMN, paper_style

    ks = [0.1, 0.98, 0.3, 5.0, 0.0, 0.95, 0.2, None, 0.1, 0.98, 0.25, 1.0, -0.3, 0.9]
    with paper_style():
        fig, axs = plt.subplots(1, 3, figsize=(DOUBLE_COLUMN, 2.4), layout="constrained")
        ax = plot_k_estimates(axs[0], _estimates(ks), truth={"e0": 0.0})
        fig.canvas.draw()
    box, legend = ax.get_window_extent(), ax.get_legend().get_window_extent()
    assert box.x0 <= legend.x0 and legend.x1 <= box.x1 and box.y0 <= legend.y0 <= legend.y1 <= box.y1
    for line in ax.get_lines():                     # estimates, arrows, means, true k
        xy = ax.transData.transform(line.get_xydata())
        under = ((xy[:, 0] > legend.x0) & (xy[:, 0] < legend.x1)
                 & (xy[:, 1] > legend.y0) & (xy[:, 1] < legend.y1))
        assert not under.any(), line
    labels = [t.get_window_extent() for t in ax.get_xticklabels() if t.get_text()]
    assert len(labels) == 3
    assert all(a.x1 < b.x0 for a, b in zip(labels, labels[1:]))     # no overlap, in order
    assert box.x0 <= labels[0].x0 and labels[-1].x1 <= box.x1
    assert all(label.y1 <= box.y0 for label in labels)                # under the axis
    assert ax.get_yticks().max() <= 1.08 + 1e-9                       # no k ticks over the legend
    plt.close(fig)


def test_profile_axes_name_the_parameters_units():
    # audit 19 F7: the x axes read "κ₁" and "f₁" with no unit, unlike every other axis
    from morphoshell.plotting import plot_profiles
    x = np.linspace(-1, 1, 5)
    names = ("kappa1", "f1", "s3")
    fig = plot_profiles({n: _profile(n, x, 1 + x ** 2, [True] * 5, (-0.5, 0.5)) for n in names},
                        pyplot=False)
    assert [ax.get_xlabel() for ax in fig.axes[:3]] == [
        r"$\kappa_{1}$ ($1/R$)", "$f_{1}$", "$s_{3}$ ($R$)"]
    fig = plot_profiles({"k": _profile("k", x, 1 + x ** 2, [True] * 5, (-0.5, 0.5))},
                        pyplot=False, units={"k": "1/R"})
    assert fig.axes[0].get_xlabel() == "$k$ ($1/R$)"


def _velocity_result():
    """An InverseResult's ``velocity``, as plot_recoil_velocity reads it: the SYNTHETIC
    table's fit (data/synthetic_ablations.csv, rounded)."""
    X = (1.196, 1.032, 1.463, 1.641, 1.611, 1.275, 2.537, 1.862, 1.483, 2.379, 1.896, 1.157,
         1.802, 1.232)
    V = (0.75, 0.628, 1.026, 1.03, 0.869, 0.534, 1.296, 1.38, 0.937, 1.679, 0.933, 0.562,
         0.804, 0.521)
    return SimpleNamespace(velocity=SimpleNamespace(
        E_over_mu=0.5785, standard_error=0.0295, X_um=X, V_um_per_s=V, mu_min_Pa_s=8e-4,
        H_mean_um=11.115, E_lower_bound_Pa=4.628e-4, bending_modulus_lower_bound_J=6.355e-19))


def _overlaps(boxes: list) -> list:
    """The pairs of boxes (name, Bbox) that overlap by more than a pixel."""
    return [(a, b) for i, (a, p) in enumerate(boxes) for b, q in boxes[i + 1:]
            if min(p.x1, q.x1) - max(p.x0, q.x0) > 1 and min(p.y1, q.y1) - max(p.y0, q.y0) > 1]


def _fig2K_clashes(ax) -> tuple[list, list]:
    """After an Agg draw: the overlapping pairs of Fig. 2 K's texts (labels, ticks, the
    legend, the slope-and-bounds note), and the data (points, and the line sampled) under
    any text inside the axes."""
    fig = ax.figure
    fig.canvas.draw()
    box = ax.get_window_extent()
    legend = ax.get_legend()
    texts = [(t.get_text(), t.get_window_extent()) for t in _texts(fig)
             if t.axes is ax and t not in legend.get_texts() and t is not legend.get_title()]
    boxes = texts + [("legend", legend.get_window_extent())]
    points = np.vstack([ax.transData.transform(np.column_stack(
        [np.linspace(*line.get_xdata()[[0, -1]], 200), np.linspace(*line.get_ydata()[[0, -1]],
                                                                     200)]))
                        if line.get_linestyle() == "-" else
                        ax.transData.transform(line.get_xydata()) for line in ax.get_lines()])
    covered = [name for name, b in boxes if b.overlaps(box) and
               ((points[:, 0] > b.x0) & (points[:, 0] < b.x1)
                & (points[:, 1] > b.y0) & (points[:, 1] < b.y1)).any()]
    return _overlaps(boxes), covered


@pytest.mark.parametrize("size", ["1.75 in panel of a row", "1.75 in square", "default",
                                  "figure_JK"])
def test_fig2K_texts_do_not_overlap_each_other_or_the_data(size, tmp_path):
    # audit 20: on a 1.75 in panel (a column of a journal's four-column grid) the slope and
    # bounds lay over the y label, the points and the line, the legend over the line and
    # past the axes' edge, the y label ran past the figure
    from morphoshell.plotting import journal_figure, paper_style, plot_recoil_velocity, styled
    from morphoshell.plotting.estimates import figure_JK

    result = _velocity_result()
    if size == "default":                      # fig2jk_estimates.py's fig2_K
        ax = plot_recoil_velocity(new_axes((SINGLE_COLUMN, 3.0), pyplot=False), result)
    elif size == "figure_JK":
        ax = figure_JK(SimpleNamespace(**vars(_estimates([0.1, 0.2])), **vars(result)),
                       pyplot=False).axes[1]
    else:
        fig = journal_figure(*((7.0, 2.0) if "row" in size else (1.75, 1.75)), pyplot=False)
        with styled(fig):
            axs = fig.subplots(1, 4 if "row" in size else 1, squeeze=False)[0]
        for other in axs[:-1]:
            other.plot([0, 1], [0, 1])
        ax = plot_recoil_velocity(axs[-1], result)
    with paper_style():
        assert not _outside_figure(ax.figure, tmp_path)
        overlapping, covered = _fig2K_clashes(ax)
    assert not overlapping and not covered, (overlapping, covered)
    notes = " ".join(t.get_text() for t in _texts(ax.figure))
    for number in ("0.58", "0.03", "0.46 mPa", "0.8 mPa s", "6.4e-19 J", "11.1 µm"):
        assert number in notes, number                  # the numbers are all still there


def _fig2K_panel(width: float, height: float, panels: int = 1):
    """Fig. 2 K of _velocity_result() in the last of a row of ``panels`` panels, each
    ``width`` × ``height`` in (the others drawn first, as a caller's grid would be)."""
    from morphoshell.plotting import journal_figure, plot_recoil_velocity, styled

    fig = journal_figure(panels * width, height, pyplot=False)
    with styled(fig):
        axs = fig.subplots(1, panels, squeeze=False)[0]
    for other in axs[:-1]:
        other.plot([0, 1], [0, 1])
    return plot_recoil_velocity(axs[-1], _velocity_result())


def _fig2K_faults(ax, tmp_path) -> list:
    """What is wrong with a drawn Fig. 2 K: texts past the figure, over one another or the
    data, tick labels over one another ("0.02.5" when the axes collapsed), axes of less than
    half an inch either way, a number missing."""
    from morphoshell.plotting import paper_style

    with paper_style():
        faults = [("outside", a) for a in _outside_figure(ax.figure, tmp_path)]
        overlapping, covered = _fig2K_clashes(ax)
    ticks = [(t.get_text(), t.get_window_extent()) for t in
             ax.get_xticklabels() + ax.get_yticklabels() if t.get_text()]
    box = ax.get_window_extent()
    size = (float(box.width) * 72 / ax.figure.dpi, float(box.height) * 72 / ax.figure.dpi)
    notes = " ".join(t.get_text() for t in _texts(ax.figure))
    return (faults + overlapping + [("covers data", c) for c in covered] + _overlaps(ticks)
            + ([("axes of (pt)", size)] if min(size) < 36 else [])
            + [("missing", n) for n in ("0.58", "0.03", "0.46 mPa", "0.8 mPa s", "6.4e-19 J",
                                        "11.1 µm") if n not in notes])


@pytest.mark.parametrize("side", [1.75, 2.0, 2.3, 2.5, 3.0, 3.4])
@pytest.mark.parametrize("row", [False, True], ids=["square", "in a row"])
def test_fig2K_is_whole_and_unwarned_on_every_panel_from_1_75_in(side, row, tmp_path):
    # audit 23: on a 2.5 in square (and a 1.9 × 2.5 in panel) the whole y label, chosen for
    # the axes' height before the legend went under them, ran 5 pt past the figure's top.
    # In a row: as many square panels as a page's width takes (up to four, K the last)
    with warnings.catch_warnings():
        warnings.simplefilter("error")               # no warning of ours or Matplotlib's
        ax = _fig2K_panel(side, side, min(4, int(DOUBLE_COLUMN // side)) if row else 1)
        assert _fig2K_faults(ax, tmp_path) == []


@pytest.mark.parametrize("width, height", [(1.5, 1.5), (1.6, 1.6), (3.4, 1.4), (1.5, 3.0)])
def test_fig2K_on_a_panel_too_small_says_so_and_names_one_that_holds_it(width, height,
                                                                         tmp_path):
    # audit 23: at 1.5 in the axes shrank to nothing ("0.02.5" for x ticks), without a word
    with pytest.warns(UserWarning, match=rf"a panel of {width:.2f} × {height:.2f} in is too "
                                         rf"small .* use a panel of about") as caught:
        _fig2K_panel(width, height)
    ours = [w for w in caught if "plot_recoil_velocity" in str(w.message)]
    assert len(ours) == 1 and "\n" not in str(ours[0].message)
    assert ours[0].filename == __file__              # points at the caller's line
    named = re.search(r"about ([\d.]+) × ([\d.]+) in", str(ours[0].message)).groups()
    with warnings.catch_warnings():
        warnings.simplefilter("error")               # the size named holds it, unwarned
        assert _fig2K_faults(_fig2K_panel(*map(float, named)), tmp_path) == []


def test_fig2K_in_a_row_takes_room_from_its_neighbours_unwarned(tmp_path):
    # a row of 1.65 in panels: the legend under K, wider than its cell, narrows all four
    # panels a little (constrained layout), which hold it: no warning
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        ax = _fig2K_panel(1.65, 1.75, 4)
        assert _fig2K_faults(ax, tmp_path) == []


def test_fig2JKs_series_are_drawn_in_okabe_ito_colours_that_stay_apart():
    """Fig. 2 J's three measures (markers and group labels) and K's embryos in the
    Okabe–Ito colours (style.OKABE_ITO, one definition), as drawn; J's three measures
    >= 0.2 apart as seen with protanopia and deuteranopia (the threshold of the diagrams'
    test above: tab10's orange and green, J's colours before, came to 0.097 with
    protanopia)."""
    from itertools import combinations

    from matplotlib.colors import to_hex

    from morphoshell.plotting import OKABE_ITO
    from morphoshell.plotting.estimates import MEASURE_COLOURS, figure_JK
    okabe = {c.lower() for c in OKABE_ITO.values()}
    result = SimpleNamespace(**vars(_estimates([0.1, 0.2])), **vars(_velocity_result()))
    fig = figure_JK(result, pyplot=False)
    j, k = fig.axes[:2]
    drawn = {to_hex(line.get_color()) for line in j.get_lines()
             if line.get_marker() not in ("None", "", None)}
    labels = {to_hex(t.get_color()) for t in j.get_xticklabels()}    # (each measure's group)
    assert len(drawn) == 3 and drawn == labels and drawn <= okabe, (drawn, labels)
    (points,) = [line for line in k.get_lines() if line.get_marker() == "o"]
    assert to_hex(points.get_color()) in okabe
    for name, matrix in MACHADO.items():
        for a, b in combinations(MEASURE_COLOURS.values(), 2):
            assert np.linalg.norm(_seen(a, matrix) - _seen(b, matrix)) >= 0.2, (name, a, b)
