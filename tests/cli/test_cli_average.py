"""`morphoshell average`: the traces of one stage as the files of a campaign's data folder."""
import json
import re
from pathlib import Path

import numpy as np
import pytest

from morphoshell.cli import main
from morphoshell.io import Midline

ROOT = Path(__file__).resolve().parents[2]
STAGE = ROOT / "data" / "synthetic_inversion" / "t02"
TRACES = [str(STAGE / f"synthetic_embryo{k}.csv") for k in range(1, 6)]


def _radii() -> list[str]:
    """Each shipped trace's radius R (µm), from its header, as the generator rounded it."""
    return [re.search(r"R = ([0-9.]+) um", Path(t).read_text()).group(1) for t in TRACES]


def _scale(radii) -> list[str]:
    return ["--pixel-size", "0.3", "--radius-um", ",".join(radii), "--section", "whole"]


def test_the_average_of_the_shipped_traces_is_the_shipped_average(tmp_path, capsys):
    """scripts/make_synthetic_inversion.py averaged these five pixel traces (each at its own
    radius) into t02's synthetic_average.csv and wrote each one's midline: the command gives
    both again (to round-off of the alignment's least squares, 1e-9 R)."""
    out = tmp_path / "t02" / "average.csv"
    out.parent.mkdir()
    assert main(["average", *TRACES, *_scale(_radii()), "--csv", str(out), "--traces",
                 "--json", str(tmp_path / "average.json"), "--plot", str(tmp_path / "a.png")]) == 0
    mine, shipped = Midline.from_csv(out), Midline.from_csv(STAGE / "synthetic_average.csv")
    assert mine.n_traces == 5
    for a, b in ((mine.r, shipped.r), (mine.z, shipped.z), (mine.spread, shipped.spread)):
        assert np.max(np.abs(a - b)) < 1e-9
    for k in range(1, 6):
        single = Midline.from_csv(out.parent / f"average_synthetic_embryo{k}.csv")
        expected = Midline.from_csv(STAGE / f"synthetic_embryo{k}_midline.csv")
        assert np.max(np.abs(single.points - expected.points)) < 1e-9
    data = json.loads((tmp_path / "average.json").read_text())
    distances = [t["rms_distance"] for t in data["traces"]]
    assert len(distances) == 5 and max(distances) < 2 * np.median(distances)
    assert (tmp_path / "a.png").stat().st_size > 10_000
    printed = capsys.readouterr().out
    assert "outlier" not in printed
    for trace in TRACES:            # what the reader did to each trace, printed
        assert re.search(f"note: {re.escape(trace)}: noise .* averaged in bins of 4", printed)
    # the row it prints is one a campaign's data folder reads (read_timepoints checks files)
    from morphoshell.io import read_timepoints

    row = re.search(r"for timepoints.csv in (.+): midline (\S+), traces (\S+)", printed)
    data = Path(row.group(1))
    assert data == tmp_path.resolve()
    (data / "timepoints.csv").write_text(f"timepoint,pseudotime,midline,traces\n"
                                         f"t02,0.1,{row.group(2)},{row.group(3)}\n")
    stage, = read_timepoints(data)
    assert stage.midline == "t02/average.csv" and len(stage.traces) == 5


def test_a_trace_at_the_wrong_scale_is_named_an_outlier(tmp_path, capsys):
    """Embryo 3 read with embryo 2's radius (13 % too small a scale): its rms distance from
    the traces' median is 57 times the median of the five; the last line names it, also
    among three traces (where a mean of the others would be dragged toward it)."""
    radii = _radii()
    radii[2] = radii[1]
    for n in (5, 3):
        assert main(["average", *TRACES[:n], *_scale(radii[:n])]) == 0
        last = capsys.readouterr().out.strip().splitlines()[-1]
        assert last.startswith("morphoshell average: 1 outlier (synthetic_embryo3)"), last
        # (what to do: the average written includes it)
        assert "the average includes it: check the scale (--radius-um" in last


def test_drop_outliers_averages_the_other_traces(tmp_path, capsys):
    """--drop-outliers leaves the named outlier out (a user audit: `average && campaign`
    fitted an average with a trace at the wrong scale, the flat fit's E_fit doubled): the
    average is the one of the other four traces to the bit, and its comments name it."""
    radii = _radii()
    radii[2] = radii[1]
    out, clean = tmp_path / "dropped.csv", tmp_path / "clean.csv"
    assert main(["average", *TRACES, *_scale(radii), "--drop-outliers", "--csv", str(out)]) == 0
    assert "left out of the average: synthetic_embryo3 (4 traces kept)" in capsys.readouterr().out
    others = [t for k, t in enumerate(TRACES) if k != 2]
    assert main(["average", *others, *_scale([r for k, r in enumerate(radii) if k != 2]),
                 "--csv", str(clean)]) == 0
    dropped, kept = Midline.from_csv(out), Midline.from_csv(clean)
    assert dropped.n_traces == 4 and np.array_equal(dropped.points, kept.points)
    assert "# dropped_outliers = synthetic_embryo3" in out.read_text()


def test_a_roi_manager_set_adds_every_line_roi(tmp_path, capsys):
    import sys

    sys.path.insert(0, str(ROOT / "tests" / "io"))
    from reference_midline import SCALE
    from test_roi_sets import _roi_set

    from morphoshell.io import load_midline

    path = _roi_set(tmp_path)
    out = tmp_path / "stage.csv"
    assert main(["average", str(path), "--pixel-size", str(SCALE["pixel_size_um"]),
                 "--radius-um", str(SCALE["radius_um"]), "--csv", str(out), "--traces"]) == 0
    expected = load_midline(path, roi="all", **SCALE)
    mine = Midline.from_csv(out)
    assert mine.n_traces == 3 and np.array_equal(mine.points, expected.points)
    assert sorted(p.name for p in tmp_path.glob("stage_*.csv")) == [
        f"stage_RoiSet_embryo{k}.csv" for k in (1, 2, 3)]


@pytest.mark.parametrize("argv, said", [
    (["--pixel-size", "0.3", "--radius-um", "40,41"], "--radius-um has 2 radii for 5 TRACE"),
    (["--pixel-size", "0.3"], "--pixel-size and --radius-um go together"),
    (["--traces"], "--traces writes the traces' midlines beside the --csv file"),
    # 10 times too large: the points, 0.12 R apart, are too sparse to bin, and the halves
    # differ by their noise; the scale is named first
    (["--pixel-size", "3", "--radius-um", "40"], "its halves are 29.6 R long, where a midline's "
                                                 "half is about 2-4 R (its halves differ by "),
    (["--radius-um", "-4"], "argument --radius-um: -4 must be a finite number in (0, 1e+06] um"),
])
def test_bad_options_are_one_line_and_write_nothing(tmp_path, capsys, argv, said):
    out = tmp_path / "average.csv"
    assert main(["average", *TRACES, *argv, "--json", str(tmp_path / "a.json")]) == 2
    err = capsys.readouterr().err
    assert said in err and err.count("\n") == 1, err
    assert not list(tmp_path.iterdir()) and not out.exists()


def test_one_trace_is_no_average(tmp_path, capsys):
    assert main(["average", TRACES[0], "--pixel-size", "0.3", "--radius-um", "41.7",
                 "--csv", str(tmp_path / "a.csv")]) == 2
    assert "an average needs at least 2" in capsys.readouterr().err
    assert not list(tmp_path.iterdir())


def test_quiet_prints_the_result_without_notes(capsys):
    """-q is "errors and results only": the readers' `note:` lines went on regardless (user
    audit 5); the table of the traces is the command's result and stays."""
    assert main(["average", "-q", *TRACES[:3], *_scale(_radii()[:3])]) == 0
    captured = capsys.readouterr()
    assert "note:" not in captured.out and captured.err == ""
    assert "3 traces, 100 points each" in captured.out


def test_the_average_records_the_scale_it_was_made_with(tmp_path, capsys):
    """The average's file named its traces but not the --pixel-size and --radius-um that
    scaled them: it could not be reproduced from its file (user audit 5)."""
    import morphoshell
    from morphoshell.io.provenance import code_commit

    radii = _radii()[:3]
    out = tmp_path / "t02" / "average.csv"
    out.parent.mkdir()
    assert main(["average", *TRACES[:3], *_scale(radii), "--csv", str(out), "--traces"]) == 0
    for path in (out, *out.parent.glob("average_*.csv")):
        comments = [line for line in path.read_text().splitlines() if line.startswith("#")]
        assert "# pixel_size_um = 0.3" in comments and "# section = whole" in comments
        assert [f"# radius_um = {t}: {float(r):.10g}" for t, r in zip(TRACES, radii)] == \
            [c for c in comments if c.startswith("# radius_um")]
        assert f"# morphoshell = {morphoshell.__version__}" in comments
        # (audit 27 F11: and the unit of its columns, and the commit that made it)
        assert "# units = R (r, z and spread in units of R, the embryo's radius)" in comments
        assert set(code_commit()) <= {c.split(" = ")[0][2:] for c in comments}
    assert Midline.from_csv(out).n_traces == 3           # (the reader skips them)


def test_outlier_points_of_a_trace_are_named_and_left_out_when_asked(tmp_path, capsys):
    """A trace with three mis-clicks (0.27 R off) was 4.6 times the median distance, under
    the 5 times that names a trace (audit 13, F6), and averaged in silently; its points are
    named now, by file and line, and --drop-outlier-points leaves them out (and says so in
    the average's comments)."""
    rows = Path(TRACES[1]).read_text().splitlines()
    for k in (61, 201, 331):
        x, y = map(float, rows[k - 1].split(","))
        rows[k - 1] = f"{x + 25:.2f},{y - 30:.2f}"
    clicked = tmp_path / "clicked.csv"
    clicked.write_text("\n".join(rows) + "\n")
    traces = [TRACES[0], str(clicked), *TRACES[2:]]
    assert main(["average", *traces, *_scale(_radii())]) == 0
    err = capsys.readouterr().err
    assert f"warning: {clicked}: 3 points far off the curve of their neighbours" in err, err
    assert "line 61 (0." in err and "--drop-outlier-points" in err
    out = tmp_path / "dropped.csv"
    assert main(["average", *traces, *_scale(_radii()), "--drop-outlier-points",
                 "--csv", str(out)]) == 0
    captured = capsys.readouterr()
    assert "warning" not in captured.err and "left out (--drop-outlier-points)" in captured.out
    assert "# drop_outlier_points = true" in out.read_text()


def test_a_sets_line_rois_take_one_radius_each(tmp_path, capsys):
    """--radius-um lists one radius per trace, a set's line ROIs in its order, beside one per
    TRACE file (audit 25: a RoiSet.zip of 5 embryos could only take one radius); the average's
    comments record them."""
    import sys

    sys.path.insert(0, str(ROOT / "tests" / "io"))
    from test_roi_sets import RADII, _set_of_radii

    from morphoshell.io import average, load_midline, load_midlines

    path = _set_of_radii(tmp_path)
    single = tmp_path / "single1.roi"
    radii = [*RADII, RADII[0]]
    out = tmp_path / "t01" / "average.csv"
    out.parent.mkdir()
    assert main(["average", str(path), str(single), "--pixel-size", "0.25",
                 "--radius-um", ",".join(map(str, radii)), "--csv", str(out)]) == 0
    expected = [*load_midlines(path, roi="all", pixel_size_um=0.25, radius_um=list(RADII)),
                load_midline(single, pixel_size_um=0.25, radius_um=RADII[0])]
    mine = Midline.from_csv(out)
    assert mine.n_traces == 4
    assert np.array_equal(mine.points, average(expected).points)
    comments = out.read_text().splitlines()
    assert f"# radius_um = {path}: 45, 50, 56" in comments
    assert f"# radius_um = {single}: 45" in comments
    assert main(["average", str(path), str(single), "--pixel-size", "0.25",
                 "--radius-um", "45,50"]) == 0                 # (one per file: shared by a set)
    capsys.readouterr()
    assert main(["average", str(path), "--pixel-size", "0.25", "--radius-um", "45,50"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and ("--radius-um has 2 radii for 1 TRACE files holding 3 "
                                     "traces: give one for all, one per TRACE (the line ROIs "
                                     "of a set share its file's), or one per trace, a set's "
                                     "line ROIs in its order") in err, err


def test_traces_that_differ_far_more_than_their_noise_are_warned_of(tmp_path, capsys):
    """All traces off alike make no outlier (the rule is relative): embryos of R = 45-56 µm
    read at one radius, 50, give a mean spread 58 times their noise (0.3 px on a clean
    shape), which was silent (audit 25: 19 times at R = 35-42 µm); at their own radii 0.35
    times, the shipped t02 0.47 times: no warning."""
    import sys

    sys.path.insert(0, str(ROOT / "tests" / "io"))
    from test_roi_sets import RADII, _set_of_radii

    path = _set_of_radii(tmp_path)
    assert main(["average", str(path), "--pixel-size", "0.25", "--radius-um", "50"]) == 0
    err = capsys.readouterr().err
    said = re.search(rf"warning: the 3 traces of {re.escape(str(path))} differ by more than "
                     rf"tracing does: their mean spread (\S+) R is (\d+) times their noise "
                     rf"\((\S+) R, the median of their estimates\); check each trace's "
                     rf"--radius-um and --pixel-size .* and that they are of one stage\n", err)
    assert said and float(said[2]) > 10 and err.count("\n") == 1, err
    assert main(["average", str(path), "--pixel-size", "0.25",
                 "--radius-um", ",".join(map(str, RADII))]) == 0
    assert capsys.readouterr().err == ""
    assert main(["average", *TRACES, *_scale(_radii())]) == 0
    assert capsys.readouterr().err == ""
