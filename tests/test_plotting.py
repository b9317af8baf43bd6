"""Plotting in notebooks and scripts: backend, API, titles, saving, Jupyter views.

Equilibria on coarse meshes (50 nodes): the drawing is under test, not the solution.
"""
import os
import subprocess
import sys
from pathlib import Path

import matplotlib.pyplot as plt
import pytest
from matplotlib.colors import to_rgba
from PIL import Image

from morphoshell.mechanics.ablation import ablate
from morphoshell.solvers.routes import solve
from morphoshell.plotting import (get_caption, new_axes, plot_ablation, plot_cross_section,
                                  problem_label, save)
from morphoshell.model.problem import Problem

ROOT = Path(__file__).resolve().parents[1]
NODES = 50


@pytest.fixture(scope="module")
def eqs():
    """Two shells that differ in k only (uniform family, h = 0.1; k = 0 is the default)."""
    return [solve(Problem("uniform", {"k": k}, h=0.1, name="demo"), nodes=NODES)
            for k in (0.0, 0.5)]


@pytest.fixture(scope="module")
def ablation():
    return ablate(Problem("uniform", {"k": 0.0}, h=0.3, cut=0.3, name="toy2"), nodes=NODES)


@pytest.fixture(autouse=True)
def _close_figures():
    yield
    plt.close("all")


def _headless_env(**extra) -> dict:
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "MPLBACKEND")}
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT / "src"), env.get("PYTHONPATH", "")])
    return {**env, **extra}


@pytest.mark.parametrize("backend", ["svg", "pdf"])
def test_import_keeps_the_backend(backend):
    # A Jupyter kernel sets its inline backend this way (MPLBACKEND); importing
    # the module switched it to Agg, and plots stopped showing inline.
    code = ("import matplotlib; before = matplotlib.get_backend(); "
            "import morphoshell.plotting; print(before, matplotlib.get_backend())")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         env=_headless_env(MPLBACKEND=backend), check=True).stdout.split()
    assert out == [backend, backend]


def test_cli_plots_without_display_or_backend(tmp_path):
    png = tmp_path / "shell.png"
    subprocess.run([sys.executable, "-m", "morphoshell.cli", "solve",
                    str(ROOT / "problems" / "toy1_sphere.toml"), "--nodes", "20",
                    "--plot", str(png)], capture_output=True, text=True, env=_headless_env(),
                   check=True)
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_cli_leaves_no_pyplot_figure(tmp_path, capsys):
    from morphoshell.cli import main

    plt.close("all")     # figures other tests of this process left open
    assert main(["ablate", str(ROOT / "problems" / "toy2_ablation.toml"), "--nodes", "30",
                 "--plot", str(tmp_path / "a.png")]) == 0
    assert plt.get_fignums() == []
    assert (tmp_path / "a.png").stat().st_size > 10_000


def test_one_result_or_several(eqs):
    one = plot_cross_section(eqs[0])
    assert len(one.get_lines()) == 1 and len(one.patches) == 1   # midline and band
    assert one.get_legend() is None                              # nothing to tell apart
    several = plot_cross_section(eqs)
    assert len(several.get_lines()) == 2 and len(several.patches) == 0   # midlines only
    assert plot_cross_section(tuple(eqs), band="fill").patches.__len__() == 2


def test_draws_into_the_given_axes_and_leaves_the_figure_open(eqs, ablation):
    fig, (left, right) = plt.subplots(1, 2)
    assert plot_cross_section(eqs[0], left) is left
    assert plot_ablation(ablation, ax=right) is right
    assert left.get_lines() and right.get_lines()
    assert plt.fignum_exists(fig.number)


def test_style_reaches_the_artists(eqs):
    ax = plot_cross_section(eqs[0], color="k", lw=2.5, ls="--", alpha=0.7)
    line = ax.get_lines()[0]
    assert to_rgba(line.get_color()) == to_rgba("k")
    assert (line.get_linewidth(), line.get_linestyle(), line.get_alpha()) == (2.5, "--", 0.7)
    assert to_rgba(ax.patches[0].get_facecolor())[:3] == to_rgba("k")[:3]   # band: same colour
    # a list gives one value per result
    ax = plot_cross_section(eqs, color=["k", "tab:red"], linewidth=[1.0, 2.0])
    assert [to_rgba(l.get_color()) for l in ax.get_lines()] == [to_rgba("k"), to_rgba("tab:red")]
    assert [l.get_linewidth() for l in ax.get_lines()] == [1.0, 2.0]


def test_ablation_style(ablation):
    ax = plot_ablation(ablation, lw=2.0, colors=("k", "tab:blue"))
    midlines = [l for l in ax.get_lines() if l.get_linestyle() != "None"]
    assert [l.get_linewidth() for l in midlines] == [2.0, 2.0]
    assert [to_rgba(l.get_color()) for l in midlines] == [to_rgba("k"), to_rgba("tab:blue")]


def test_midline_only_draws_no_band(eqs, ablation):
    for ax in (plot_cross_section(eqs[0], midline_only=True),
               plot_cross_section(eqs[0], band=False),
               plot_cross_section(eqs, band="outline"),
               plot_ablation(ablation, midline_only=True)):
        assert len(ax.patches) == 0 and len(ax.collections) == 0
    # the outline: both edges of each band as lines beside the midline
    assert len(plot_cross_section(eqs, band="outline").get_lines()) == 6


def test_save_writes_300_dpi_png_and_pdf_and_keeps_the_figure(eqs, tmp_path):
    ax = plot_cross_section(eqs[0], new_axes((3.0, 2.0)))
    paths = save(ax, tmp_path / "shell", formats=("png", "pdf"))
    assert [p.suffix for p in paths] == [".png", ".pdf"]
    # a laid-out figure keeps its size (a journal's width): 3 × 2 in at 300 dpi
    assert Image.open(paths[0]).size == (900, 600)
    assert paths[1].read_bytes()[:5] == b"%PDF-"
    assert plt.fignum_exists(ax.figure.number)
    save(ax, tmp_path / "again.png", close=True)
    assert not plt.fignum_exists(ax.figure.number)


def test_saving_twice_gives_the_same_files_with_the_svg_text_as_text(eqs, tmp_path,
                                                                     monkeypatch):
    # audit 19 F8: the PDFs of two runs differed in /CreationDate, the SVGs in dc:date
    # (and Matplotlib salts the SVG's ids at random); F9: the SVG's text was glyph paths
    import time

    monkeypatch.delenv("SOURCE_DATE_EPOCH", raising=False)

    def figure():                         # made afresh, as by a second run
        return plot_cross_section(eqs[0], new_axes((3.0, 2.0)))

    first = save(figure(), tmp_path / "a.pdf", ("pdf", "svg", "png"))
    time.sleep(1.1)                       # the dates are written to the second
    ax = figure()
    second = save(ax, tmp_path / "b.pdf", ("pdf", "svg", "png"))
    for a, b in zip(first, second):
        assert a.read_bytes() == b.read_bytes(), a.suffix
    svg = first[1].read_text()
    assert "<dc:date>" not in svg and b"CreationDate" not in first[0].read_bytes()
    assert svg.count("<text") >= 10 and ">direct method, 50 nodes</text>" in svg
    # a date a caller asks for, or the reproducible-builds one, is written
    monkeypatch.setenv("SOURCE_DATE_EPOCH", "1700000000")
    dated = save(ax, tmp_path / "c.pdf", ("pdf", "svg"))
    assert b"/CreationDate (D:20231114" in dated[0].read_bytes()
    assert "<dc:date>2023-11-14" in dated[1].read_text()


def test_save_crops_an_empty_band_above_a_flat_shell_but_keeps_the_width(tmp_path):
    # audit 13: a wide, flat shell at equal aspect left an inch of empty figure above it
    ax = new_axes((3.4, 3.4))
    ax.plot([-1.2, 1.2], [0.0, 0.5])
    ax.set_aspect("equal", adjustable="box")
    ax.set_title("a flat shell")
    png = save(ax, tmp_path / "flat.png", close=True)[0]
    width, height = Image.open(png).size
    assert width == 1020 and height < 0.6 * 1020          # 3.4 in wide at 300 dpi


def test_titles_and_legends_say_what_was_solved(eqs, ablation):
    changed = Problem("uniform", {"k": 0.5}, h=0.2, cut=0.3, opening=0.4,
                      theory="classical", name="demo")
    label = problem_label(changed)
    for part in ("demo", "uniform", "classical", "h = 0.2", "cut Σ = 0.3", "opening P = 0.4",
                 "k = 0.5"):
        assert part in label, part
    assert "cut" not in problem_label(eqs[0].problem)   # no cut, no opening: not mentioned
    # one result: the title names the problem (one line), the caption its parameters
    ax = plot_cross_section(eqs[1])
    assert ax.get_title() == "demo: uniform, large-bending"
    assert "k = 0.5" in get_caption(ax) and "h = 0.1" in get_caption(ax)
    assert "direct method, 50 nodes" in get_caption(ax)
    # several: title and caption say what they share, the entries what sets them apart
    ax = plot_cross_section(eqs)
    assert "h = 0.1" in get_caption(ax) and "k =" not in get_caption(ax) + ax.get_title()
    assert [t.get_text() for t in ax.get_legend().get_texts()] == ["k = 0", "k = 0.5"]
    # the legend is beside the axes, not over the shells
    ax.figure.canvas.draw()
    assert (ax.get_legend().get_window_extent().x0
            >= ax.get_window_extent().x1 - 1e-6)
    ax = plot_ablation(ablation)
    assert ax.get_title() == "toy2: uniform, large-bending"
    assert "cut Σ = 0.3" in get_caption(ax) and f"{ablation.rotation:.3g} rad" in get_caption(ax)
    # a caller's own title (or none, for a panel): no caption of ours
    for ax in (plot_cross_section(eqs[0], title=None), plot_ablation(ablation, title="B")):
        assert get_caption(ax) == ""
    assert plot_cross_section(eqs[0], title=None).get_title() == ""


def test_large_families_name_only_the_changed_parameters():
    from morphoshell.model.profiles import FAMILIES

    f1 = FAMILIES["volvox"].defaults["f1"] * 1.01
    label = problem_label(Problem("volvox", {"f1": f1}, h=0.15, opening=0.3))
    assert f"f1 = {f1:g}" in label and "f2" not in label and "kappa" not in label


def test_html_views_show_energy_and_units(eqs, ablation):
    eq = eqs[1]
    html = eq._repr_html_()
    assert f"{eq.energy:.10g} C R²" in html
    assert "k = 0.5" in html and "rad" in html and "continuation" in html   # path
    assert "error estimate" in html
    text = repr(eq)
    assert "\n" not in text and len(text) < 120
    html = ablation._repr_html_()
    assert f"{ablation.rotation:.6g} rad" in html and f"{ablation.opening:.6g} R" in html
    assert "pre-ablation energy" in html and "post-ablation energy" in html


def test_html_view_escapes_names():
    eq = solve(Problem("uniform", name="<b>x</b>"), nodes=20)
    assert "<b>x</b>" not in eq._repr_html_() and "&lt;b&gt;x&lt;/b&gt;" in eq._repr_html_()


def test_bifurcation_diagram_draws_stability_events_and_shapes():
    """plot_branch: solid where stable, dashed where not (no line across a snap), one marker
    per fold, and the shells at the start, the events and the end beside the diagram."""
    from pathlib import Path

    from morphoshell import follow_branch
    from morphoshell.io.problem_files import load_problem
    from morphoshell.plotting import BRANCH_STYLE, plot_branch

    problem, _ = load_problem(Path(__file__).parent / "data" / "volvox_fold.toml")
    branch = follow_branch(problem, nodes=100)
    fig = plot_branch(branch)
    diagram = fig.subfigs[0].axes[0]
    lines = [ln for ln in diagram.get_lines() if len(ln.get_xdata())]
    solid = [ln for ln in lines if ln.get_linestyle() == "-" and ln.get_marker() in ("None", "")]
    dashed = [ln for ln in lines if ln.get_linestyle() == "--"]
    assert solid and dashed
    assert all(ln.get_color() == BRANCH_STYLE["stable"]["color"] for ln in solid)
    folds = [ln for ln in lines if ln.get_marker() == "o"]
    assert len(folds) == 1 and len(folds[0].get_xdata()) == sum(
        pt.event == "fold" for pt in branch.points)
    # every stable point lies on a solid line, every unstable one on a dashed one
    on_solid = {float(x) for ln in solid for x in ln.get_xdata()}
    for pt in branch.points:
        if not pt.event:
            assert (pt.tau in on_solid) == pt.stable
    shapes = [ax for ax in fig.subfigs[1].axes if ax.axison]
    assert len(shapes) == min(8, 2 + len(branch.events))
    assert diagram.get_xlabel().startswith("path fraction") and "psi" in diagram.get_ylabel()
    with pytest.raises(ValueError, match="y = 'stable'"):
        plot_branch(branch, y="stable")


def test_traces_over_their_average_show_each_ones_distance_from_the_others():
    """plot_traces: the traces, their average and spread above; below, each trace's distance
    from their pointwise median, the same as io.trace_distances; the caption names the
    farthest trace."""
    import numpy as np

    from morphoshell.io import Midline, average, trace_distances
    from morphoshell.plotting import plot_traces

    s = np.linspace(0.0, 1.0, 50)
    base = np.column_stack([np.sin(2 * s), 1 - np.cos(2 * s)])
    traces = [Midline(*(base * (1 + e)).T) for e in (0.0, 0.01, -0.01, 0.2)]
    fig = plot_traces(average(traces), traces, ["a", "b", "c", "far"])
    top, bottom = fig.axes
    assert len(top.get_lines()) == 5 and len(bottom.get_lines()) == 4
    distances = trace_distances(traces)
    for line, d in zip(bottom.get_lines(), distances):
        assert np.allclose(line.get_ydata(), d)
    rms = np.sqrt((distances ** 2).mean(axis=1))
    assert rms.argmax() == 3 and rms[3] > 10 * np.median(rms)
    assert "(far)" in get_caption(bottom)
    plt.close(fig)


def test_plots_on_a_callers_panel_stay_inside_it():
    # API audit 11: on a panel of the caller's grid the legend was drawn beside
    # it (over the next panel) and the caption under it (over the panel below)
    ab = ablate(Problem("uniform", {"k": 0.5}, h=0.1, cut=0.4), nodes=60)
    fig, axs = plt.subplots(2, 2, figsize=(7, 6))
    panels = [plot_ablation(ab, ax=axs[0, 0]),
              plot_cross_section([ab.pre, ab.post], ax=axs[0, 1])]
    fig.canvas.draw()
    for ax in panels:
        assert get_caption(ax) == ""
        legend, box = ax.get_legend().get_window_extent(), ax.get_window_extent()
        assert box.x0 <= legend.x0 and legend.x1 <= box.x1 and box.y0 <= legend.y0 <= legend.y1 <= box.y1
    plt.close(fig)
    # on its own figure: the caption under the axes and the legend beside them
    ax = plot_ablation(ab)
    ax.figure.canvas.draw()
    assert "recoil at s" in get_caption(ax)
    assert ax.get_legend().get_window_extent().x0 > ax.get_window_extent().x1
    plt.close(ax.figure)


def test_plot_fit_of_a_fit_read_back_says_what_it_lacks():
    """A fit read back from its JSON has no equilibrium to draw: said, not an AttributeError."""
    from types import SimpleNamespace

    import numpy as np

    from morphoshell.fitting import FitResult, volvox_spec
    from morphoshell.fitting.results import fit_result
    from morphoshell.plotting import plot_fit

    spec = volvox_spec("free")
    # (one point of a shell: no walls to cross, fit_result checks them)
    eq = SimpleNamespace(problem=spec.base, **dict.fromkeys(("s", "r", "z", "f_s", "f_phi"),
                                                            np.ones(1)))
    inner = SimpleNamespace(solve=lambda theta: eq, residuals=lambda eq: np.full(200, 1e-3),
                            jacobian=lambda eq, theta: np.eye(200, len(spec.fitted)),
                            data=np.ones((100, 2)), n=100, solves=1)
    back = FitResult.from_dict(fit_result("gradient", spec, inner, spec.theta0, 5, 0.1, True,
                                          "").to_dict())
    with pytest.raises(ValueError, match="fit read back from its JSON .*solve result.problem"):
        plot_fit(back)


def test_a_branch_diagram_defaults_to_an_observable_that_varies():
    """A shell with a cut ends in its pole, ψ = π at every point: the default diagram (ψ at
    the far end) was one flat line with the folds on it (audit 14).  The default is the
    first of ψ, z, r and the energy that varies: z at the far end there, ψ for the fold
    shell (whose far end turns); the x axis of a family's parameter carries its unit."""
    import numpy as np

    from morphoshell import example_path, load_problem
    from morphoshell.plotting import plot_branch
    from morphoshell.plotting.branches import default_y
    from morphoshell.solvers.branches import follow_branch

    cap = load_problem(example_path("toy1_sphere"))[0].with_updates(h=0.05, cut=1.0, k=1.0)
    branch = follow_branch(cap, "k", 3.0, nodes=40)
    assert default_y(branch) == "z_end"
    ax = plot_branch(branch, shapes=False).axes[0]
    assert ax.get_ylabel().startswith("far end's height above the first point")
    assert ax.get_xlabel() == "k ($1/R$)"
    # audit 19 F15: the shapes below the diagram are in its gauge, z = 0 at the first point:
    # their far ends (the pole, r = 0) stand where the diagram's ends are (they stood
    # 1 − cos Σ higher, in the solver's gauge)
    fig = plot_branch(branch)
    diagram = fig.subfigs[0].axes[0].get_lines()[0].get_ydata()
    shapes = [a for a in fig.subfigs[1].axes if a.axison]
    for shape, expected in zip((shapes[0], shapes[-1]), (diagram[0], diagram[-1])):
        drawn = shape.get_lines()[0]
        xy = drawn.get_transform().transform(drawn.get_xydata())        # as drawn
        pole = shape.transData.inverted().transform(xy[np.argmin(np.abs(drawn.get_xdata()))])
        assert pole[1] == pytest.approx(expected, abs=1e-9)
    fold = load_problem(Path(__file__).parent / "data" / "volvox_fold.toml")[0]
    assert default_y(follow_branch(fold, "kappa2", -7.9, nodes=40)) == "psi_end"


def test_an_event_the_mesh_does_not_resolve_has_an_open_marker():
    # audit 14: unresolved folds were named in the caption only, drawn as resolved ones
    from morphoshell.plotting.branches import _diagram

    fig, ax = plt.subplots()
    table = {"lambda": [0.0, 0.5, 1.0], "energy": [1.0, 2.0, 1.5], "stable": [True, False, True],
             "event": ["", "fold", "fold"], "lambda_error": [float("nan"), 1e-8, float("inf")]}
    _diagram(ax, table, "lambda", "energy")
    folds = {line.get_label(): line.get_markerfacecolor() for line in ax.get_lines()
             if line.get_label().startswith("fold")}
    assert set(folds) == {"fold", "fold (unresolved)"}
    assert folds["fold (unresolved)"] == "white" != folds["fold"]
    plt.close(fig)


def test_traces_figure_gives_the_shape_and_the_distances_the_columns_width():
    # audit 19 F13: five file names in a legend beside the shape took half the column; the
    # shape (datalim aspect) was drawn 0.9 in wide and the distances under it as narrow
    import numpy as np

    from morphoshell.io import Midline, average
    from morphoshell.plotting import SINGLE_COLUMN, plot_traces

    s = np.linspace(0.0, 2.5, 80)
    base = np.column_stack([np.sin(s) * 1.1, 1 - np.cos(s)])
    traces = [Midline(*(base * (1 + e)).T) for e in (0.0, 0.01, -0.01, 0.005, -0.005)]
    names = [f"synthetic_embryo{k}_midline" for k in range(1, 6)]
    fig = plot_traces(average(traces), traces, names, pyplot=False)
    fig.draw_without_rendering()
    top, bottom = fig.axes
    legend = top.get_legend()
    assert [t.get_text() for t in legend.get_texts()][:5] == ["1", "2", "3", "4", "5"]
    assert legend.get_title().get_text() == "synthetic_embryo…_midline"
    width = lambda ax: ax.get_window_extent().width / fig.dpi          # inches
    assert width(bottom) > 0.75 * SINGLE_COLUMN                        # was ~1 in
    assert legend.get_window_extent().y1 <= top.get_window_extent().y0  # under the shape
    # the shape at equal scales by its box, not by limits padded past it (the audit's z
    # axis ran from -0.8 for a shell from 0), so the shape fills the axes
    box = top.get_window_extent()
    (x0, x1), (y0, y1) = top.get_xlim(), top.get_ylim()
    assert box.width / box.height == pytest.approx((x1 - x0) / (y1 - y0), rel=0.02)
    z = np.concatenate([m.z for m in traces])
    assert y1 - y0 <= 1.15 * (z.max() - z.min())     # Matplotlib's margins: 5 % a side
