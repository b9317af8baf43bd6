"""scripts/fig3_fits.py (paper Fig. 3 D–O): what is not a result is drawn as such.

A fit that did not converge is marked wherever it is drawn (its D–L panel hatched with
"not converged" in the title; open markers in N, in O's κ₁ series, its 1/f₁ line and its
f₁ inset: audit 19, F1–F2), an ablation whose walls pass through each other is flagged in
its panel and in fig3_ablations.json (F1), each hypothesis has its own marker and a
colour of its own grey (F11), and no text is below the package's 7 pt (F12).  A campaign
of two SYNTHETIC timepoints (flat and free variants, 60 nodes), one fit of each variant
then marked unconverged in its record.
"""
import importlib.util
import json
import shutil
from dataclasses import replace
from types import SimpleNamespace
from pathlib import Path

import numpy as np
import pytest
from matplotlib.colors import to_rgb
from matplotlib.lines import Line2D
from matplotlib.text import Text

from morphoshell.plotting import MIN_FONT_SIZE, is_flagged
from morphoshell.solvers.contact import WallContact
from morphoshell.workflows import campaign

ROOT = Path(__file__).resolve().parents[2]
NODES = 60
#: The fits marked unconverged (their records edited: these converge).
STALLED = ("t02", ("flat", "free"))


def _script():
    spec = importlib.util.spec_from_file_location("fig3_fits", ROOT / "scripts" / "fig3_fits.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def stalled(data, tmp_path_factory):
    """A campaign's folder in which t02's flat and free fits did not converge."""
    out = tmp_path_factory.mktemp("campaign")
    campaign(data[0], ("flat", "free"), method="gradient", workers=1, out=out, nodes=NODES,
             timepoints=("t01", "t02"))
    tp, variants = STALLED
    for v in variants:
        path = out / f"{tp}_{v}.json"
        record = json.loads(path.read_text())
        assert record["converged"], path                # (so the mark is the edit's)
        path.write_text(json.dumps({**record, "converged": False}))
    return out


def _draw(stalled, data, tmp_path, monkeypatch):
    """Run the script; the figures it saved (kept open) by name, and fig3_ablations.json."""
    import morphoshell.plotting as plotting

    figures, save = {}, plotting.save

    def keep(fig, path, *args, **kwargs):
        figures[Path(path).stem] = fig
        return save(fig, path, *args, **{**kwargs, "close": False})
    monkeypatch.setattr(plotting, "save", keep)
    fig3 = _script()
    assert fig3.main(["--campaign", str(stalled), "--data", str(data[0]), "--out",
                      str(tmp_path), "--nodes", str(NODES)]) == 0
    return fig3, figures, json.loads((tmp_path / "fig3_ablations.json").read_text())["ablations"]


def _panel(fig, name: str):
    """The D–L axes whose title begins with ``name`` (a timepoint)."""
    return next(ax for ax in fig.axes if ax.get_title(loc="left").startswith(name))


def _open_x(ax) -> set:
    """Pseudotimes of the open (white-filled) markers drawn in ``ax``."""
    return {round(float(x), 6) for line in ax.get_lines() if line.get_markerfacecolor() == "white"
            for x in line.get_xdata()}


def test_an_unconverged_fit_is_marked_in_every_panel(stalled, data, tmp_path, monkeypatch):
    _, figures, ablations = _draw(stalled, data, tmp_path, monkeypatch)
    t02 = json.loads((stalled / "t02_flat.json").read_text())["pseudotime"]
    # D–L: the stalled flat fit's panel hatched, "not converged" in its title; t01's not
    stalled_ax, fine = _panel(figures["fig3_D-L"], "t02"), _panel(figures["fig3_D-L"], "t01")
    assert "not converged" in stalled_ax.get_title(loc="left") and is_flagged(stalled_ax)
    assert "not converged" not in fine.get_title(loc="left") and not is_flagged(fine)
    assert ablations["t02_flat"]["converged"] is False
    # (audit 27 F9: what the numbers are in and were made with, beside them)
    meta = json.loads((tmp_path / "fig3_ablations.json").read_text())
    assert (meta["cut"], meta["nodes"]) == (_script().CUT, NODES)
    assert meta["campaign"] == str(stalled.resolve()) and meta["data"] == str(data[0].resolve())
    assert meta["units"]["rotation"] == meta["units"]["se_rotation"] == "rad"
    assert set(ablations["t01_flat"]) - {"walls_cross", "converged"} <= set(meta["units"])
    assert ablations["t01_flat"]["rotation_error"] >= 0
    # (audit 28 F2: the fit's errors also at the average's traces' σ², ablate's keys; the
    # synthetic averages are of 2 embryos' traces, so t₀.₉₇₅(1) = 12.71; σ² of the traces
    # above the residual's here, as on every average the audit drew: larger errors)
    entry = ablations["t01_flat"]
    assert entry["t95_traces"] == pytest.approx(12.706, abs=1e-3)
    assert entry["se_traces_rotation"] > entry["se_rotation"] > 0
    assert meta["units"]["se_traces_opening"] == "R" and meta["units"]["t95_traces"] == "1"
    assert {"morphoshell", "numpy", "written"} <= set(meta["provenance"])
    # N: open markers at t02 for both variants (flat and free), and a legend entry
    (n,) = figures["fig3_N"].axes
    assert _open_x(n) == {round(t02, 6)}
    assert sum(line.get_markerfacecolor() == "white" and line.get_xdata().size
               for line in n.get_lines()) == 2
    assert "not converged" in [t.get_text() for t in n.get_legend().get_texts()]
    # O: the free fit's κ₁, its 1/f₁ line and the f₁ inset all mark it
    (o,) = figures["fig3_O"].axes
    (inset,) = o.child_axes
    assert _open_x(o) == _open_x(inset) == {round(t02, 6)}
    assert sum(line.get_markerfacecolor() == "white" and line.get_xdata().size
               for line in o.get_lines()) == 2


def test_an_ablation_whose_walls_cross_is_flagged(stalled, data, tmp_path, monkeypatch):
    """numerical_ablation found the t01 flat shell's walls overlapping after the cut (made
    up: the synthetic shells do not): the panel is hatched and says so, the JSON has it."""
    import morphoshell.workflows as workflows

    real = workflows.numerical_ablation
    contact = WallContact((1.647, 2.513), 0.003, 0.129)      # audit 19's t07 flat

    def crossing(problem, *args, **kwargs):
        num = real(problem, *args, **kwargs)
        return replace(num, contacts={"pre": None, "post": contact}) \
            if problem.name == "t01_flat" else num
    monkeypatch.setattr(workflows, "numerical_ablation", crossing)
    _, figures, ablations = _draw(stalled, data, tmp_path, monkeypatch)
    ax = _panel(figures["fig3_D-L"], "t01")
    assert is_flagged(ax) and "not converged" not in ax.get_title(loc="left")
    assert "walls overlap after the cut (0.003 R apart)" in ax.get_title(loc="left")
    assert ablations["t01_flat"]["walls_cross"] == {"post": contact.describe()}
    assert ablations["t01_flat"]["converged"] is True
    assert "fig3_M" not in figures          # (M draws the first flat result: none here)


def _grey(color) -> float:
    """Luminance of a colour in print without colour (ITU-R 601, as PIL's "L")."""
    return float(np.dot(to_rgb(color), (0.299, 0.587, 0.114)))


def test_each_hypothesis_has_its_own_marker_and_grey():
    fig3 = _script()
    variants = list(fig3.COLORS)
    assert len({fig3.MARKERS[v] for v in variants}) == len(variants)
    greys = sorted(_grey(fig3.COLORS[v]) for v in variants)
    # (audit 19: C0 and C2 printed the same grey, 0.02 apart)
    assert min(np.diff(greys)) > 0.15, greys


def test_no_text_below_the_minimum_font_size(stalled, data, tmp_path, monkeypatch):
    _, figures, _ = _draw(stalled, data, tmp_path, monkeypatch)
    for name, fig in figures.items():
        small = [(t.get_text(), t.get_fontsize()) for t in fig.findobj(Text)
                 if t.get_visible() and t.get_text().strip() and t.get_fontsize() < MIN_FONT_SIZE]
        assert not small, (name, small)


def _held_runs(converged_t07: bool):
    """Campaign tables as Fig. S2 reads them (to_dataframe()): the fixed variants at three
    pseudotimes, E_fit made up; own, and held from flat's and free's first fits; flat's
    t07 fit (own) unconverged unless ``converged_t07``."""
    import pandas as pd

    def table(scale, stalled=()):
        rows = [{"timepoint": tp, "pseudotime": t, "variant": v, "status": "ok",
                 "converged": (tp, v) not in stalled, "E_fit": scale * (1 + i + t)}
                for tp, t in (("t01", 0.0), ("t07", 0.55), ("t12", 1.0))
                for i, v in enumerate(("flat", "undeformed", "unstressed"))]
        return pd.DataFrame(rows)
    own = table(0.01, () if converged_t07 else (("t07", "flat"),))
    held = [SimpleNamespace(to_dataframe=lambda s=s: table(s)) for s in (0.02, 0.03)]
    return own, held


def test_figure_S2_has_a_panel_per_hypothesis_in_Fig3s_conventions(tmp_path, monkeypatch):
    # session 55's look at S2: one axes of eight series, a square there meaning "held from
    # flat" where N's square is kappa0_post = 1/R, variant names ("flat's first fit") in the
    # legend, the unconverged flat fit's open circle under another series' marker
    import morphoshell.plotting as plotting
    from matplotlib.colors import to_hex

    from morphoshell.plotting import paper_style

    fig3, figures, save = _script(), {}, plotting.save
    monkeypatch.setattr(plotting, "save", lambda fig, path, *a, **k: figures.setdefault(
        Path(path).stem, fig) and save(fig, path, *a, **{**k, "close": False}))
    own, held = _held_runs(converged_t07=False)
    stages = [SimpleNamespace(pseudotime=t) for t in (0.0, 0.55, 1.0)]
    with paper_style():
        fig3._figure_S2(own, held, ["flat", "free"], stages, tmp_path)
        fig = figures["figS2_held"]
        fig.canvas.draw()
    assert [ax.get_title(loc="left") for ax in fig.axes] == [fig3.LABELS[v] for v in fig3.FIXED]
    for ax, v in zip(fig.axes, fig3.FIXED):
        series = [line for line in ax.get_lines() if line.get_xdata().size
                  and line.get_color() != "0.6"]            # (not the stages' marks)
        # own, flat's (not in flat's panel: its own fit again) and free's held values
        # (the open markers: no line)
        assert len({line.get_linestyle() for line in series} - {"None"}) == (2 if v == "flat"
                                                                               else 3)
        assert {line.get_marker() for line in series} == {fig3.MARKERS[v]}
        assert {to_hex(line.get_color()) for line in series} == {to_hex(fig3.COLORS[v])}
        # the unconverged fit open, in its panel only
        assert _open_x(ax) == ({0.55} if v == "flat" else set())
    labels = [t.get_text() for t in fig.legends[0].get_texts()]
    assert "not converged" in labels
    assert not any(name in label for label in labels for name in ("flat", "free", "undeformed"))
    texts = [t for t in fig.findobj(Text) if t.get_visible() and t.get_text().strip()]
    assert min(t.get_fontsize() for t in texts) >= MIN_FONT_SIZE
    boxes = [t.get_window_extent() for t in texts if t not in fig.legends[0].get_texts()]
    boxes.append(fig.legends[0].get_window_extent())
    assert not [(a, b) for i, a in enumerate(boxes) for b in boxes[i + 1:]
                if min(a.x1, b.x1) - max(a.x0, b.x0) > 1 and min(a.y1, b.y1) - max(a.y0, b.y0) > 1]
    # all converged: no open marker, no legend entry for them
    figures.clear()
    with paper_style():
        fig3._figure_S2(*_held_runs(converged_t07=True), ["flat", "free"], stages, tmp_path)
    assert not any(_open_x(ax) for ax in figures["figS2_held"].axes)
    assert "not converged" not in [t.get_text() for t in figures["figS2_held"].legends[0].get_texts()]
