"""Smoke and content test of scripts/fig2_toy_problems.py (paper Fig. 2 D–I).

Runs the script's ``--quick`` computation and drawing once (about 10 s) and
checks the files, the figures' sizes and fonts, and the physics of the
numerical points it plotted.
"""
import importlib.util
import json
import math
from pathlib import Path

import numpy as np
import pytest
from matplotlib.axes import Axes
from matplotlib.text import Text
from PIL import Image

from morphoshell.mechanics import asymptotics
from morphoshell.plotting import DOUBLE_COLUMN, MIN_FONT_SIZE, SINGLE_COLUMN

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = ROOT / "scripts" / "fig2_toy_problems.py"
PANELS = ("D", "E", "F", "G", "H", "I", "D-I")


def _load_script():
    # scripts/ is not a package
    spec = importlib.util.spec_from_file_location("fig2_toy_problems", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def script():
    return _load_script()


@pytest.fixture(scope="module")
def run(script, tmp_path_factory):
    """Output folder, the points' JSON and the figures (as main() draws them)."""
    out = tmp_path_factory.mktemp("fig2")
    _, figures = script.write(script.compute(quick=True), out, quick=True)
    return out, json.loads((out / "fig2_points.json").read_text()), figures


def test_main_parses_its_options(script, capsys):
    with pytest.raises(SystemExit) as exc:
        script.main(["--help"])
    assert exc.value.code == 0 and "--quick" in capsys.readouterr().out


def _series(data, panel):
    """{h: (x, y)} of a panel, as plotted."""
    return {s["h"]: (np.array(s["x"]), np.array(s["y"])) for s in data[panel]["series"]}


def test_files_written_and_non_trivial(run):
    out, data, _ = run
    for panel in PANELS:
        png, pdf = out / f"fig2_{panel}.png", out / f"fig2_{panel}.pdf"
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        assert pdf.read_bytes()[:5] == b"%PDF-"
        # a labelled axes without data is ~12 kB as PNG (130 dpi) and ~6 kB as
        # PDF; the panels hold curves and shells (quick run: >= 40 kB, 20 kB)
        assert png.stat().st_size > 25_000, png
        assert pdf.stat().st_size > 12_000, pdf
    assert data["script"] == "fig2_toy_problems.py"
    assert data["quick"] is True
    assert set(data["provenance"]) >= {"morphoshell", "casadi"}


def test_D_opening_approaches_the_line_as_h_decreases(run):
    _, data, _ = run
    series = _series(data, "D")
    # worst relative deviation from o/[h(1-k)] = c/2, thickest shell first
    worst = [float(np.max(np.abs(y / (x / 2) - 1))) for _, (x, y) in sorted(series.items(),
                                                                            reverse=True)]
    assert worst == sorted(worst, reverse=True) and worst[0] > 2 * worst[-1]
    # The correction to eq:Usol is O(δ³) against o = O(δ²): relative O(δ),
    # δ = 0.0054 for h = 1e-4 (measured 0.55 %, at the smallest cut Σ = 0.05).
    h_min = min(series)
    x, y = series[h_min]
    assert np.all(np.abs(y / (x / 2) - 1) < 3 * asymptotics.delta(h_min))


def test_E_F_small_and_large_cuts(run):
    _, data, _ = run
    for panel, small_cut, constant in (("E", asymptotics.rotation_small_cut, math.sqrt(1.5)),
                                       ("F", asymptotics.displacement_small_cut, 0.5)):
        for h, (x, y) in _series(data, panel).items():
            # a larger cut rotates and displaces its rim more (here Σ ≤ 1.4)
            assert np.all(np.diff(y) > 0), (panel, h)
            # ... but never beyond the leading-order constant (approached from below)
            assert np.all(y < constant * 1.01), (panel, h)
        h = min(_series(data, panel))
        x, y = _series(data, panel)[h]
        # Smallest cut (c/√h = 0.1, σ = 0.09): the nonlinear terms that the
        # Kelvin approximation drops are O(σ) smaller there (measured 0.1 %).
        sigma = np.arcsin(x[0] * math.sqrt(h) / 2)
        norm = math.sqrt(h) if panel == "E" else h
        assert y[0] == pytest.approx(small_cut(h, 0.0, sigma) / norm, rel=0.02)
        # Largest cut (c/√h = 100, σ ≈ 90): the O(1/σ) correction is < 1 %.
        assert y[-1] == pytest.approx(constant, rel=0.02)


def test_cross_sections_recoil_as_in_the_paper(run):
    _, data, _ = run
    cs = data["cross_sections"]
    # G: an intrinsically flat sheet (k = 0 < 1) curls outward: the cut opens
    assert cs["G"]["opening"] > 0 and cs["G"]["rotation"] > 0
    assert cs["G"]["problem"]["h"] == cs["G"]["problem"]["cut"] == 0.3
    # H: the anisotropic recoil is "much smaller" than that of G (measured ~10x)
    for key in ("H+", "H-"):
        assert abs(cs[key]["rotation"]) < abs(cs["G"]["rotation"]) / 4
    assert cs["H+"]["problem"]["params"]["f0"] == -cs["H-"]["problem"]["params"]["f0"] == 0.1
    # I: the fast relaxation also opens the cut outward (qualitatively like G)
    assert cs["I"]["opening"] > 0 and cs["I"]["rotation"] > 0


def _texts(fig):
    """Every visible, non-empty text of a figure (titles, labels, ticks, legends, notes)."""
    return [t for t in fig.findobj(Text) if t.get_visible() and t.get_text().strip()]


def test_paper_sizes_and_fonts(run):
    out, _, figures = run
    for key, fig in figures.items():
        width = DOUBLE_COLUMN if key == "D-I" else SINGLE_COLUMN
        assert fig.get_size_inches()[0] == pytest.approx(width), key
        # saved at that size (no cropping) and 300 dpi
        assert Image.open(out / f"fig2_{key}.png").size[0] == round(300 * width), key
        small = [(t.get_text(), t.get_fontsize()) for t in _texts(fig)
                 if t.get_fontsize() < MIN_FONT_SIZE]
        assert not small, (key, small)
    # the panel letters are bold, outside the titles
    letters = [t for t in _texts(figures["D-I"]) if t.get_text() in set("DEFGHI")]
    assert sorted(t.get_text() for t in letters) == list("DEFGHI")
    assert all(t.get_fontweight() == "bold" for t in letters)
    assert not any(ax.get_title()[:2].strip() in set("DEFGHI")
                   for ax in figures["D-I"].findobj(Axes))


def test_thickest_points_stay_visible(script, run):
    _, _, figures = run
    ax = figures["D"].axes[0]
    points = {line.get_label(): line for line in ax.get_lines() if line.get_linestyle() == "None"}
    by_h = [points[script._h_label(h)] for h in script.H_VALUES]   # thickest first
    # h = 1e-2 first: the largest, open marker, drawn on top of the others
    sizes = [line.get_markersize() for line in by_h]
    assert sizes == sorted(sizes, reverse=True) and len(set(sizes)) == 3
    assert by_h[0].get_markerfacecolor() == "none"
    assert by_h[0].get_zorder() > max(line.get_zorder() for line in by_h[1:])


def test_pole_spikes_explained_on_panel_H(run):
    _, _, figures = run
    for key in ("H", "D-I"):
        notes = [t.get_text() for t in _texts(figures[key]) if "physical" in t.get_text()]
        assert len(notes) == 1 and "pole" in notes[0] and "toy problem 3" in notes[0], key
