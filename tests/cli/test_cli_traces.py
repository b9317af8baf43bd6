"""A new user's traces on the command line (issue 41): a wrong scale or swapped columns are
refused before any solve, naming the options to check; image traces without a scale are told
the command line's options, not the library's arguments."""
from pathlib import Path

import numpy as np
import pytest

from morphoshell.cli import main
from morphoshell.io import Midline

ROOT = Path(__file__).resolve().parents[2]
T01 = ROOT / "data" / "synthetic_inversion" / "t01"
#: The scale the synthetic trace of embryo 1 was written at (its header comment).
PIXEL_UM, RADIUS_UM = 0.3, 43.9927


@pytest.fixture(scope="module")
def fiji_xy(tmp_path_factory):
    """The synthetic embryo's image trace as Fiji's XY Coordinates export: x<TAB>y, no header."""
    rows = [ln for ln in (T01 / "synthetic_embryo1.csv").read_text().splitlines()
            if ln[:1].isdigit()]
    path = tmp_path_factory.mktemp("traces") / "trace_xy.txt"
    path.write_text("".join(ln.replace(",", "\t") + "\n" for ln in rows))
    return path


def _refused(argv, capsys, tmp_path, *named):
    out = tmp_path / "fit.json"
    assert main([*argv, "--json", str(out)]) == 2
    captured = capsys.readouterr()
    err = captured.err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    assert "note:" not in captured.out            # (the reader's notes: once a trace is accepted)
    for word in named:
        assert word in err, err
    assert not out.exists()
    return err


@pytest.mark.parametrize("factor, named", [
    (4, "3.6× longer than the undeformed shell"),
    (2, "1.8× longer than the undeformed shell"),
    (0.25, "4.5× shorter than the undeformed shell"),
])
def test_a_wrong_pixel_size_is_refused_naming_the_factor_and_the_options(
        fiji_xy, factor, named, capsys, tmp_path):
    """4x off used to end at E_fit 20 R (exit 3), 2x at 0.83 R with stretches on their bounds."""
    size = PIXEL_UM * factor
    _refused(["fit", str(fiji_xy), "--variant", "free", "--pixel-size", f"{size:g}",
              "--radius-um", str(RADIUS_UM)], capsys, tmp_path,
             named, f"is --pixel-size {size:g} the size of a pixel in µm",
             f"--radius-um {RADIUS_UM:g} the embryo's radius R in µm?")


@pytest.mark.parametrize("decimals, named", [
    (3, "the coordinates look like µm already (non-integer, and the midline is 1/0.3 = 3.33× "
        "too short: 2."),
    (0, "the coordinates may be in µm already (the midline is 1/0.3 = 3.33× too short: 2."),
])
def test_a_fiji_export_in_micrometres_is_told_to_pass_pixel_size_1(
        fiji_xy, decimals, named, capsys, tmp_path):
    """Fiji writes a calibrated image's XY coordinates in µm; read with the pixel size, the
    message asked "is --pixel-size 0.25 the size of a pixel in µm?", which it is (audit 25).
    Where the length at --pixel-size 1 is one the check allows, the message names the mistake;
    decimals make it likely (a trace in pixels from Fiji's line tools has none)."""
    rows = np.loadtxt(fiji_xy) * PIXEL_UM
    um = tmp_path / "trace_um.txt"
    np.savetxt(um, rows.round(decimals), fmt=f"%.{decimals}f", delimiter="\t")
    err = _refused(["fit", str(um), "--variant", "free", "--pixel-size", f"{PIXEL_UM:g}",
                    "--radius-um", str(RADIUS_UM)], capsys, tmp_path, named,
                   "× shorter than the undeformed shell", "R long at --pixel-size 1)")
    if decimals:
        assert err.endswith("): pass --pixel-size 1 (Fiji writes the XY coordinates of a "
                            "calibrated image in µm)\n"), err
    else:
        assert err.endswith("pass --pixel-size 1; else is --pixel-size 0.3 the size of a pixel "
                            "in µm (Fiji: Image › Properties), and --radius-um 43.9927 the "
                            "embryo's radius R in µm?\n"), err


def test_a_roi_or_a_length_wrong_at_pixel_size_1_too_is_not_taken_for_micrometres(
        fiji_xy, capsys, tmp_path):
    """A .roi is in pixels whatever the image's calibration (here one with the µm values of
    the export above); a trace whose length at --pixel-size 1 the check refuses too is asked
    about its options, as before."""
    import roifile

    roi = roifile.ImagejRoi.frompoints(np.loadtxt(fiji_xy) * PIXEL_UM)
    roi.roitype = roifile.ROI_TYPE.POLYLINE
    roi.tofile(tmp_path / "trace.roi")
    for path, size in ((tmp_path / "trace.roi", PIXEL_UM), (fiji_xy, 0.1)):
        err = _refused(["fit", str(path), "--variant", "free", "--pixel-size", f"{size:g}",
                        "--radius-um", str(RADIUS_UM)], capsys, tmp_path,
                       "× shorter than the undeformed shell",
                       f"is --pixel-size {size:g} the size of a pixel in µm")
        assert "µm already" not in err, err


def test_swapped_columns_are_refused_naming_the_likely_cause(capsys, tmp_path):
    """An r,z CSV with r and z swapped (header still r,z) used to "converge" to E_fit 3.7 R
    (t01) and write its JSON; a later stage's swapped r goes negative."""
    for stage, named in (("t01", "leaves the pole at 89 degrees from the r axis"),
                         ("t10", "the midline crosses the axis")):
        m = Midline.from_csv(T01.parent / stage / "synthetic_average.csv")
        path = tmp_path / f"{stage}_swapped.csv"
        Midline(m.z, m.r).to_csv(path)
        _refused(["fit", str(path), "--variant", "free"], capsys, tmp_path, named,
                 "are its columns r and z swapped?")


def test_a_csv_of_the_wrong_scale_names_its_units(capsys, tmp_path):
    m = Midline.from_csv(T01 / "synthetic_average.csv")
    path = tmp_path / "big.csv"
    Midline(3 * m.r, 3 * m.z).to_csv(path)
    _refused(["fit", str(path), "--variant", "flat"], capsys, tmp_path,
             "2.7× longer", "are its r and z in units of R")


@pytest.mark.parametrize("scale", [1e-100, 1e-200, 1e-300])
def test_a_csv_of_tiny_coordinates_is_refused_for_its_length(scale, capsys, tmp_path):
    """Audit 26, F3: r, z scaled by 1e-200 overflowed the spline of the resampling (a raw
    SciPy warning, then "point 0 (r, z) = (nan, nan) is not finite"); refused for its length
    as at 1e-100, in one line."""
    m = Midline.from_csv(T01 / "synthetic_average.csv")
    path = tmp_path / "tiny.csv"          # a plain r,z table (no '# n_traces'): resampled
    np.savetxt(path, np.column_stack([m.r, m.z]) * scale, delimiter=",", header="r,z",
               comments="")
    _refused(["fit", str(path), "--variant", "flat", "--nodes", "40"], capsys, tmp_path,
             f"the midline is 2.53e{round(np.log10(scale))} R long",
             "shorter than the undeformed shell", "are its r and z in units of R")


def test_messages_name_the_command_line_options(fiji_xy, capsys, tmp_path):
    """The library's messages name its Python arguments (pixel_size_um); the command line's
    name its options."""
    err = _refused(["fit", str(fiji_xy), "--variant", "free"], capsys, tmp_path,
                   "pass --pixel-size (µm per pixel) and --radius-um (the embryo radius R in µm)")
    assert "pixel_size_um" not in err and "radius_um" not in err
    err = _refused(["fit", str(fiji_xy), "--variant", "free", "--radius-um", "44"], capsys,
                   tmp_path, "pass --pixel-size (µm per pixel) to convert")
    csv = T01 / "synthetic_average.csv"
    _refused(["fit", str(csv), "--variant", "free", "--pixel-size", "0.3"], capsys, tmp_path,
             "csv traces are in units of R: --pixel-size does not apply")
    asymmetric = tmp_path / "half.txt"          # a half section passed as whole
    rows = fiji_xy.read_text().splitlines()
    asymmetric.write_text("\n".join(rows[len(rows) // 2 - 40:]) + "\n")
    _refused(["fit", str(asymmetric), "--variant", "free", "--pixel-size", str(PIXEL_UM),
              "--radius-um", str(RADIUS_UM)], capsys, tmp_path,
             "only a trace that starts at the pole is a half section (--section half)")


def test_a_rim_traced_short_is_told_the_rule_not_section_half(fiji_xy, capsys, tmp_path):
    """One rim traced 6 % short was told "if it is a half section, pole first, pass --section
    half", which was wrong: the pole is taken at half the trace's length."""
    rows = fiji_xy.read_text().splitlines()
    short = tmp_path / "short.txt"
    short.write_text("\n".join(rows[int(0.06 * len(rows)):]) + "\n")
    err = _refused(["fit", str(short), "--variant", "free", "--pixel-size", str(PIXEL_UM),
                    "--radius-um", str(RADIUS_UM)], capsys, tmp_path,
                   "the pole is taken at half the trace's length, so both rims must be traced "
                   "to their ends", "rms from their mirror average (at most 0.05 R)")
    assert "pass --section half" not in err and "max_asymmetry" not in err


def _stopped_fit(monkeypatch):
    """fit's fitting replaced by a stop (exit 3) that keeps the midline it was given."""
    import morphoshell.fitting as fitting
    from morphoshell.fitting import FitError
    seen = []

    def fake_fit(spec, midline, *args, **kwargs):
        seen.append(midline)
        raise FitError("stopped here", "Maximum_Iterations_Exceeded")

    monkeypatch.setattr(fitting, "fit", fake_fit)
    return seen


def test_fit_prints_what_the_reader_did_to_the_trace(fiji_xy, capsys, tmp_path, monkeypatch):
    """Binning a dense trace and reading a segmented line's vertices as a spline were silent,
    even with -v; now a note says so (stdout), once the trace is accepted."""
    _stopped_fit(monkeypatch)
    scale = ["--pixel-size", str(PIXEL_UM), "--radius-um", str(RADIUS_UM)]
    rows = fiji_xy.read_text().splitlines()
    vertices = tmp_path / "vertices.txt"
    vertices.write_text("\n".join(rows[::len(rows) // 19]) + "\n")
    for path, note in ((fiji_xy, "averaged in bins of 4"),
                       (vertices, "20 points 0.2"),
                       (vertices, "the midline between them is the cubic spline through them")):
        assert main(["fit", str(path), "--variant", "flat", *scale]) == 3
        out = capsys.readouterr().out
        assert f"note: {path}: " in out and note in out, out


def test_a_noisy_half_section_is_refused_naming_whole_sections(capsys, tmp_path):
    """--section half took the axis from the first points' tangent: any real noise misplaced
    the midline, silently, or gave "the midline crosses the axis"."""
    import sys
    sys.path.insert(0, str(ROOT / "tests" / "io"))
    from reference_midline import SCALE, half, write

    path = write(tmp_path, "fiji-xy", points=half(801), section="half", angle_deg=20.0,
                 offset_px=(500.0, 500.0), noise_px=0.5, seed=1)
    scale = ["--pixel-size", str(SCALE["pixel_size_um"]), "--radius-um", str(SCALE["radius_um"])]
    err = _refused(["fit", str(path), "--variant", "flat", "--section", "half", *scale], capsys,
                   tmp_path, "the axis of this half section is uncertain",
                   "trace the whole section, rim to rim through the pole (--section whole)")
    assert "section='whole'" not in err


def test_section_help_states_the_rules(capsys):
    for command in ("fit", "average"):
        assert main([command, "--help"]) == 0
        text = " ".join(capsys.readouterr().out.split())
        assert "the pole is taken at half the trace's length, so trace both rims to their " \
               "ends" in text
        assert "trace whole sections where you can" in text
        assert "Save As > XY Coordinates (no header, x<TAB>y), read as xy" in text


def test_fit_help_says_image_traces_need_the_scale(capsys):
    assert main(["fit", "--help"]) == 0
    text = " ".join(capsys.readouterr().out.split())
    assert "pixel coordinates: Fiji XY, .roi, RoiSet.zip, x,y CSV" in text
    assert "need --pixel-size and --radius-um" in text


def test_campaign_messages_name_its_options(capsys, tmp_path):
    """workflows.campaign names its Python arguments (embryo_errors); the command line its
    options."""
    data = ROOT / "data" / "synthetic_inversion"
    out = tmp_path / "out"
    for argv, named in ((["--variants", "flat", "--embryo-errors", "free"],
                         "error: --embryo-errors free: ['free'] not among --variants flat"),
                        (["--timepoints", "t99"], "error: --timepoints 't99': ['t99'] not in")):
        assert main(["campaign", str(data), "--out", str(out), *argv]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and named in err, err
        assert not out.exists()


def test_fit_reads_a_roi_manager_set(tmp_path, capsys, monkeypatch):
    """A RoiSet.zip was read as text ("line 1: not UTF-8 text (byte 11)"); now --roi chooses a
    line ROI by name or position, or all of them, averaged; without a choice among several
    the message names them and the option."""
    import sys

    import morphoshell.fitting as fitting
    from morphoshell.fitting import FitError

    sys.path.insert(0, str(ROOT / "tests" / "io"))
    from test_roi_sets import _roi_set
    from reference_midline import SCALE

    path = _roi_set(tmp_path)
    scale = ["--pixel-size", str(SCALE["pixel_size_um"]), "--radius-um", str(SCALE["radius_um"])]
    err = _refused(["fit", str(path), "--variant", "flat", *scale], capsys, tmp_path,
                   "choose one with --roi NAME or INDEX (from 1), or --roi all to average them")
    assert "roi=" not in err
    seen = []

    def fake_fit(spec, midline, *args, **kwargs):
        seen.append(midline)
        raise FitError("stopped here", "Maximum_Iterations_Exceeded")

    monkeypatch.setattr(fitting, "fit", fake_fit)
    for choice, traces in (("all", 3), ("embryo2", 1), ("3", 1)):
        assert main(["fit", str(path), "--variant", "flat", "--roi", choice, *scale]) == 3
        assert seen[-1].n_traces == traces
    assert seen[-1].source == (f"{path}, ROI 'embryo3'",)


def test_fit_of_a_roi_set_takes_a_radius_per_line_roi(tmp_path, capsys, monkeypatch, fiji_xy):
    """fit --roi all took one --radius-um for every embryo of a set, where average takes one
    per line ROI: now fit does too (average's parsing), each ROI scaled by its own; several
    radii for one trace, or a count other than the set's line ROIs, are refused naming the
    option, before any work."""
    import sys

    import morphoshell.fitting as fitting
    from morphoshell.fitting import FitError
    from morphoshell.io import load_midline

    sys.path.insert(0, str(ROOT / "tests" / "io"))
    from test_roi_sets import _roi_set
    from reference_midline import SCALE

    path, radii = _roi_set(tmp_path, others=False), [SCALE["radius_um"] * f for f in (1.0, 1.03, 0.97)]
    seen = []

    def fake_fit(spec, midline, *args, **kwargs):
        seen.append(midline)
        raise FitError("stopped here", "Maximum_Iterations_Exceeded")

    monkeypatch.setattr(fitting, "fit", fake_fit)
    assert main(["fit", str(path), "--variant", "flat", "--roi", "all", "--pixel-size",
                 str(SCALE["pixel_size_um"]), "--radius-um", ",".join(map(str, radii))]) == 3
    expected = load_midline(path, roi="all", pixel_size_um=SCALE["pixel_size_um"],
                            radius_um=radii)
    one = load_midline(path, roi="all", **SCALE)
    # (the same reader on the same radii: to the bit; one radius for all differs by 1e-3 R)
    assert np.array_equal(seen[-1].points, expected.points)
    assert not np.allclose(seen[-1].points, one.points, atol=1e-4)
    capsys.readouterr()
    scale = ["--pixel-size", str(SCALE["pixel_size_um"])]
    _refused(["fit", str(path), "--variant", "flat", "--roi", "all", *scale,
              "--radius-um", "50,52"], capsys, tmp_path, "--radius-um has 2 radii for the 3 line")
    _refused(["fit", str(fiji_xy), "--variant", "flat", "--pixel-size", str(PIXEL_UM),
              "--radius-um", "43,44"], capsys, tmp_path,
             "--radius-um lists radii, one per line ROI of a ROI Manager set")


def test_a_trace_drawn_out_and_back_is_refused_in_one_line(fiji_xy, capsys, tmp_path):
    """The trace followed by its reverse (audit 13, F5) failed with "cannot convert float NaN
    to integer"; now one line names the file and where it turns, before any work."""
    rows = fiji_xy.read_text().splitlines()
    path = tmp_path / "backforth.txt"
    path.write_text("\n".join(rows + rows[::-1][1:]) + "\n")
    err = _refused(["fit", str(path), "--variant", "free", "--pixel-size", str(PIXEL_UM),
                    "--radius-um", str(RADIUS_UM)], capsys, tmp_path,
                   f"{path}: the trace doubles back on itself at line {len(rows)} (arclength",
                   "trace the midline once, from pole to rim")
    assert "NaN" not in err


def _mis_clicked(fiji_xy, tmp_path, lines=(61, 201, 331)):
    """The synthetic trace with points clicked 39 px (0.27 R) off, as in audit 13, F6 (their
    distances from the curve are a little less: part of the move is along it)."""
    rows = fiji_xy.read_text().splitlines()
    for k in lines:
        x, y = map(float, rows[k - 1].split("\t"))
        rows[k - 1] = f"{x + 25:.2f}\t{y - 30:.2f}"
    path = tmp_path / "misclicked.txt"
    path.write_text("\n".join(rows) + "\n")
    return path


def test_fit_names_outlier_points_and_drops_them_when_asked(fiji_xy, capsys, tmp_path,
                                                            monkeypatch):
    """Mis-clicks passed silently (audit 13, F6: E_fit five times the clean trace's); now a
    warning names each by its line, in R and px, and the option that leaves them out, and
    with that option a note says they were left out."""
    _stopped_fit(monkeypatch)
    path = _mis_clicked(fiji_xy, tmp_path)
    scale = ["--pixel-size", str(PIXEL_UM), "--radius-um", str(RADIUS_UM)]
    assert main(["fit", str(path), "--variant", "flat", *scale]) == 3
    captured = capsys.readouterr()
    assert (f"warning: {path}: 3 points far off the curve of their neighbours" in captured.err
            and "line 61 (0.26 R = 38.3 px)" in captured.err and "line 331 (0.27 R" in captured.err
            and "--drop-outlier-points" in captured.err), captured.err
    assert main(["fit", str(path), "--variant", "flat", *scale, "--drop-outlier-points"]) == 3
    captured = capsys.readouterr()
    assert "warning" not in captured.err, captured.err
    assert f"note: {path}: 3 points far off" in captured.out
    assert "left out (--drop-outlier-points)" in captured.out
    assert main(["fit", str(fiji_xy), "--variant", "flat", *scale]) == 3     # a clean trace
    assert "far off the curve" not in str(capsys.readouterr())


def test_retracings_the_reader_refuses_are_left_out_or_the_gauss_newton_errors_stand(
        monkeypatch, capsys):
    """A re-tracing that the reader refuses never refuses the trace (audit 15 F7: a valid
    20-vertex ROI, exit 2, "re-tracing: the halves ... differ"): a few are left out with a
    note saying how many; more than a tenth and the Gauss–Newton errors stand, said so (and
    in the result: audit 27 F1, its record said nothing of which errors it held)."""
    from argparse import Namespace

    import numpy as np

    from morphoshell.cli.fit import _retracings, _trace_errors
    from morphoshell.fitting import trace_errors

    why = ("the halves of this whole section differ by 0.0519 R rms from their mirror average "
           "(max_asymmetry = 0.05): the pole is taken at half the trace's length")
    args = Namespace(section=None, radius_um=RADIUS_UM, pixel_size=PIXEL_UM, midline="x.csv",
                     format=None, roi=None)
    result = _stand_in(np.zeros((100, 2)), np.eye(200, 2))
    monkeypatch.setattr(trace_errors, "single_trace", lambda *a, **k: object())
    for refused, kept in ((2, True), (11, False)):
        made = trace_errors.ReaderErrors(np.ones((100 - refused, 200)), 0.002, (why,) * refused,
                                         0, 0.5)
        monkeypatch.setattr(trace_errors, "reader_errors", lambda *a, made=made, **k: made)
        retraced = _retracings(result, args)
        out = capsys.readouterr().out
        assert out.count("note:") == 1 and "about 0.5 px" in out, out
        assert "the first: the halves of this whole section differ by 0.0519 R rms from their " \
               "mirror average (at most 0.05 R))" in out, out
        assert retraced is made
        source = _trace_errors(result, retraced).standard_errors_source
        if kept:
            assert "from 98 simulated re-tracings" in out and "2 of 100 refused by the " \
                   "reader and left out" in out, out
            assert source == "re-tracings"
        else:
            assert "the ± are the Gauss–Newton errors" in out and "11 of the 100 simulated " \
                   "re-tracings" in out, out
            assert source == "gauss-newton"


def _stand_in(data, jacobian):
    """A fit's stand-in with what the re-tracings need: its data, Jacobian, two fitted
    parameters and their Gauss–Newton errors."""
    import numpy as np

    from morphoshell.fitting.results import FitResult

    return FitResult("gradient", "free", ("f1", "kappa1"), {"f1": 0.8, "kappa1": 0.1},
                     {"f1": 0.01, "kappa1": 0.1}, np.eye(2), [], 0.01, np.zeros(200), None,
                     data, data, 1, 1, 1.0, True, problem=object(), jacobian=jacobian)


def test_fit_json_and_csv_say_which_standard_errors_they_hold(fiji_xy, tmp_path, capsys):
    """Audit 27 F1: fit --json of one image trace wrote the re-tracings' errors (κ₁ 0.24)
    under the note "standard errors are Gauss-Newton lower bounds", with neither their count
    nor seed, and the CSV said nothing: both say which now, the JSON how they were made (and
    F7: each parameter's unit); a csv midline's are Gauss–Newton's, said so too."""
    import csv
    import json

    scale = ["--pixel-size", str(PIXEL_UM), "--radius-um", str(RADIUS_UM)]
    short = ["--variant", "flat", "--nodes", "60", "--max-evaluations", "2"]   # (quick: exit 3)
    for midline, extra, source in ((fiji_xy, scale, "re-tracings"),
                                   (T01 / "synthetic_average.csv", [], "gauss-newton")):
        out_json, out_csv = tmp_path / f"{source}.json", tmp_path / f"{source}.csv"
        assert main(["fit", str(midline), *extra, *short, "--json", str(out_json),
                     "--csv", str(out_csv)]) == 3
        printed = capsys.readouterr().out
        record = json.loads(out_json.read_text())
        assert record["standard_errors_source"] == source
        assert record["units"]["kappa2"] == "1/R" and record["units"]["f1"] == "1"
        with open(out_csv, newline="") as f:
            assert {row["standard_errors_source"] for row in csv.DictReader(f)} == {source}
        if source == "re-tracings":
            made = record["re_tracings"]
            assert (made["replicates"], made["seed"], made["sigma_units"]) == (100, 0, "R")
            assert made["refused"] == 0 and 0.2 < made["sigma_px"] < 2, made
            assert "sandwich of 100 re-tracings" in record["note"], record["note"]
            assert "± from 100 re-tracings" in printed, printed
        else:
            assert "re_tracings" not in record
            assert record["note"].startswith("standard errors are Gauss-Newton lower bounds")
            assert "± Gauss–Newton (lower bounds" in printed, printed


def test_a_fit_that_carries_its_re_tracings_errors_keeps_them_after_its_profiles():
    """Review of stop 56: after ``fit --profile``, a re-centring that kept a copy of the fit
    (``re_tracings`` already set) had the re-tracings applied again, which
    ``with_trace_errors`` refuses: the run ended with exit 2 after all its profiles."""
    from types import SimpleNamespace

    from morphoshell.cli.fit import _trace_errors

    carried = SimpleNamespace(re_tracings=object())
    assert _trace_errors(carried, object()) is carried
