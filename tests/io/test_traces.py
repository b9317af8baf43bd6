"""Trace files: formats, image coordinates, ImageJ spline-fit ROIs, the midline csv and bad files.

The reference midline and its trace files: reference_midline.py.
"""
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
import roifile
from scipy.interpolate import make_interp_spline

from morphoshell.io import midlines as ml
from morphoshell.io import traces as tr
from morphoshell.io import Midline, MidlineError
from reference_midline import SCALE, TRUTH, half, write


# ------------------------------------------------------------------ image coordinates

def test_image_y_points_down(tmp_path):
    """Anterior up on screen (angle 0) puts the rims above the pole: smaller y in the files."""
    text = write(tmp_path, "fiji-xy", angle_deg=0.0, offset_px=(300.0, 400.0))
    rows = np.loadtxt(text)
    assert rows[0, 1] < rows[800, 1] and rows[-1, 1] < rows[800, 1]
    assert rows[800] == pytest.approx([300.0, 400.0])            # the pole where it was put
    roi = roifile.ImagejRoi.fromfile(write(tmp_path, "roi", angle_deg=0.0, offset_px=(300, 400)))
    assert np.allclose(roi.coordinates(), rows, atol=1e-4)      # float32
    trace = tr.read_trace(text, **SCALE)                        # read with y up
    assert trace.points[0, 1] > trace.points[800, 1]


def test_spline_fit_roi_is_interpolated(tmp_path):
    """A spline-fit ROI stores 25 control points; the curve between them is ImageJ's spline."""
    control = half(13)
    path = write(tmp_path, "roi", points=control, angle_deg=30.0, offset_px=(400.0, 400.0),
                 spline_fit=True)
    trace = tr.read_trace(path, **SCALE)
    assert len(trace.points) == tr.SPLINE_SUBDIVISIONS * 24 + 1
    stored = np.asarray(roifile.ImagejRoi.fromfile(path).coordinates(), dtype=float)
    assert np.allclose(trace.points[::tr.SPLINE_SUBDIVISIONS], stored * [0.005, -0.005])
    # ImageJ's curve, written independently: natural B-spline in the centripetal parameter
    t = np.r_[0, np.cumsum(np.sqrt(np.hypot(*np.diff(stored, axis=0).T)))]
    imagej = make_interp_spline(t, stored, k=3, bc_type="natural")((t[1:] + t[:-1]) / 2)
    between = trace.points[tr.SPLINE_SUBDIVISIONS // 2::tr.SPLINE_SUBDIVISIONS]
    assert np.abs(between - imagej * [0.005, -0.005]).max() < 1e-12
    # ... not the spline this module puts through plain points (not-a-knot, chord length)
    chord = np.r_[0, np.cumsum(np.hypot(*np.diff(stored, axis=0).T))]
    plain = make_interp_spline(chord, stored, k=3)((chord[1:] + chord[:-1]) / 2)
    assert np.abs(between - plain * [0.005, -0.005]).max() > 1e-4
    assert np.abs(ml.load_midline(path, **SCALE).points - TRUTH).max() < 3e-3


def test_dense_noisy_trace_is_one_curve(tmp_path):
    """Noise as large as the spacing makes tiny loops; they are not a second curve."""
    path = write(tmp_path, "fiji-xy", points=half(801), noise_px=0.5, seed=1)
    assert len(tr.read_trace(path, **SCALE).points) == 1601


def test_loops_of_noise_larger_than_the_spacing_are_not_crossings(tmp_path):
    """½ px of noise at 0.19 px spacing (an automatic contour): its loops span 8-10 points, more
    than the 10 median steps that were let cross, and each of these 4 traces was refused as
    intersecting itself (audit 10, F5).  Loops of noise stay within ~10 σ of where they start
    (trace_checks._JITTER); the loops of a curve that crosses itself do not."""
    for seed in range(4):
        path = write(tmp_path, "fiji-xy", points=half(2701), noise_px=0.5, seed=seed)
        assert len(tr.read_trace(path, **SCALE).points) == 5401


def test_a_noisy_trace_that_crosses_itself_is_refused_naming_the_noise(tmp_path):
    """A figure of eight crosses itself however noisy; with noise larger than the point spacing
    the message says so (it lengthens the trace and makes loops), and not without."""
    s = np.linspace(-0.5, 2 * np.pi - 1, 4000)
    loop = np.column_stack([np.sin(2 * s), np.sin(s)])          # 0.3 px apart at 200 px per R
    path = write(tmp_path, "xy", "noisy", points=loop, section="half", noise_px=0.5, seed=0)
    with pytest.raises(MidlineError, match=r"noisy.csv: .*crosses the segment .*intersects "
                                           r"itself \(noise larger than the point spacing: ≈ "
                                           r"0\.\d+ px at 0\.\d+ px: subsample or smooth"):
        tr.read_trace(path, **SCALE)
    path = write(tmp_path, "xy", "clean", points=loop, section="half")
    with pytest.raises(MidlineError, match=r"clean.csv: .*intersects itself$"):
        tr.read_trace(path, **SCALE)


# ------------------------------------------------------------------ midline csv

def test_midline_csv_round_trip(tmp_path):
    rng = np.random.default_rng(0)
    mean = ml.average([Midline(*(TRUTH + rng.normal(0, 0.01, TRUTH.shape)).T,
                               source=(f"embryo {i}.roi",)) for i in range(3)])
    mean.to_csv(tmp_path / "mean.csv")
    back = Midline.from_csv(tmp_path / "mean.csv")
    assert np.array_equal(back.points, mean.points) and np.array_equal(back.spread, mean.spread)
    assert back.n_traces == 3 and back.source == mean.source
    trace = tr.read_trace(tmp_path / "mean.csv")                # the same file as a trace
    assert trace.format == "csv" and np.array_equal(trace.points, mean.points)
    (tmp_path / "empty.csv").write_text("# n_traces = 3\nr,z,spread\n")  # (a campaign's reader)
    with pytest.raises(MidlineError, match="empty.csv: no points: only the header 'r,z,spread'"):
        Midline.from_csv(tmp_path / "empty.csv")


def test_a_midline_csv_is_marked_as_a_midlines_rows(tmp_path):
    """Trace.written: the n_traces comment of Midline.to_csv marks rows equally spaced in
    arclength; an r,z table without it, or a midline with a row repeated (dropped, it would
    shift the fractions of arclength of the rows after it), is a trace."""
    Midline(*TRUTH.T).to_csv(tmp_path / "midline.csv")
    assert tr.read_trace(tmp_path / "midline.csv").written
    text = (tmp_path / "midline.csv").read_text().splitlines()
    (tmp_path / "table.csv").write_text("\n".join(text[1:]) + "\n")
    assert not tr.read_trace(tmp_path / "table.csv").written
    (tmp_path / "repeated.csv").write_text("\n".join(text[:5] + text[4:]) + "\n")
    repeated = tr.read_trace(tmp_path / "repeated.csv")
    assert len(repeated.points) == len(TRUTH) and not repeated.written


def _average_csv(tmp_path, n_traces="3", spread=None, sources=3):
    """A csv average of 3 noisy copies of the reference midline as Midline.to_csv writes it,
    its n_traces comment and one spread (its third point's, line 8 of the file) edited."""
    rng = np.random.default_rng(1)
    mean = ml.average([Midline(*(TRUTH + rng.normal(0, 0.01, TRUTH.shape)).T,
                               source=(f"embryo {i}.roi",)) for i in range(sources)])
    mean.to_csv(tmp_path / "avg.csv")
    lines = (tmp_path / "avg.csv").read_text().splitlines()
    lines[0] = f"# n_traces = {n_traces}"
    if spread is not None:
        r, z, _ = lines[4 + sources].split(",")
        lines[4 + sources] = f"{r},{z},{spread}"
    (tmp_path / "avg.csv").write_text("\n".join(lines) + "\n")
    return tmp_path / "avg.csv"


@pytest.mark.parametrize("edit, message", [
    # (audit 23 F11: n_traces 1e9 shrank a fit's profile interval to zero width, a spread of
    # 1e6 made it (-inf, inf), 0 and negative ones were taken)
    ({"n_traces": "0"}, "comment 'n_traces = 0' must be at least 1 (the traces averaged)"),
    ({"n_traces": "-2"}, "comment 'n_traces = -2' must be at least 1"),
    ({"n_traces": "1000000000"}, "comment 'n_traces = 1000000000' disagrees with its 3 'source' "
                                 "comments, one per trace averaged"),
    ({"n_traces": "2"}, "comment 'n_traces = 2' disagrees with its 3 'source' comments"),
    ({"n_traces": "2.5"}, "comment 'n_traces = 2.5' is not an integer"),
    ({"spread": "-0.001"}, "line 8 (spread): -0.001 must lie in [0, 20] R"),
    ({"spread": "1e6"}, "line 8 (spread): 1000000.0 must lie in [0, 20] R"),
])
def test_an_averages_n_traces_and_spread_are_checked(tmp_path, edit, message):
    path = _average_csv(tmp_path, **edit)
    for read in (Midline.from_csv, tr.read_trace, ml.load_midline):
        with pytest.raises(MidlineError) as err:
            read(path)
        assert str(err.value) == f"{path}: {message}" or str(err.value).startswith(
            f"{path}: {message}"), (read, str(err.value))


def test_an_average_that_can_be_one_is_read(tmp_path):
    """What the checks let pass: n_traces as many as the sources, a spread of 0 (the pole's)
    and up to 20 R, and one source with several traces (a loaded average written again:
    load_midline names the file it read)."""
    assert ml.load_midline(_average_csv(tmp_path, spread="0")).n_traces == 3
    assert tr.read_trace(_average_csv(tmp_path, spread="20")).spread.max() == 20
    once = ml.load_midline(_average_csv(tmp_path))
    assert once.source == (str(tmp_path / "avg.csv"),) and once.n_traces == 3
    once.to_csv(tmp_path / "again.csv")
    assert ml.load_midline(tmp_path / "again.csv").n_traces == 3


# ------------------------------------------------------------------ bad input

def _file(tmp_path, name, content):
    path = tmp_path / name
    path.write_bytes(content if isinstance(content, bytes) else content.encode())
    return path


GOOD_ROWS = [f"{x:.3f}\t{y:.3f}" for x, y in 200 * half(20) + 300]
JUMP = "\n".join(GOOD_ROWS[:6] + ["5000\t5000"] + GOOD_ROWS[6:]) + "\n"


@pytest.mark.parametrize("name, content, message", [
    ("empty.txt", "", "empty.txt: empty file"),
    ("blank.csv", "\n  \n# only a comment\n", "blank.csv: empty file"),
    ("word.csv", "x,y\n1,2\n3,abc\n5,6\n7,8\n", "word.csv: line 3, column 2 (y): 'abc' is not a number"),
    ("ragged.csv", "r,z\n0,0\n1,2,3\n", "ragged.csv: line 3: 3 values, expected 2 (r, z)"),
    ("nan.txt", "1\t2\nnan\t3\n4\t5\n6\t7\n", "nan.txt: line 2, column 1 (x): nan is not finite"),
    ("few.txt", "1\t2\n3\t4\n5\t6\n", "few.txt: 3 distinct points; a midline needs at least 4"),
    # a header alone, or with blank lines, used to be an IndexError (audit 3, #6)
    ("header_only.csv", "r,z\n", "header_only.csv: no points: only the header 'r,z' (line 1)"),
    ("spread_only.csv", "# n_traces = 3\nr,z,spread\n\n\n", "no points: only the header "
                                                            "'r,z,spread' (line 2)"),
    ("xy_only.csv", "x,y\n", "xy_only.csv: no points: only the header 'x,y'"),
    ("index_only.csv", " ,X,Y\n\n", "index_only.csv: no points: only the header ',X,Y'"),
    ("one.csv", "x,y\n1,2\n", "one.csv: 1 distinct point; a midline needs at least 4"),
    ("latin1.csv", b"x,y\n1,2\n3,4\n# caf\xe9\n", "latin1.csv: line 4: not UTF-8"),
    ("dump.txt", "10\t20\t255\n11\t20\t254\n", "dump.txt: line 1: 3 columns: this is a pixel list"),
    ("area.csv", " ,X,Y,Value\n1,10,20,255\n", "area.csv: line 1: columns ',X,Y,Value': this is"),
    ("header.csv", "a,b\n1,2\n", "header.csv: line 1: unrecognised header 'a,b'"),
    ("jump.txt", JUMP, "jump.txt: line 6 to line 7: a step of"),
    ("negative.csv", "r,z\n0,0\n-0.5,0.1\n-1,0.4\n-1.2,1\n", "negative.csv: line 3: r = -0.5 < 0"),
    # in units of R a midline stays near its pole (at 1e300 the spline overflowed)
    ("far.csv", "r,z\n0,0\n0.1,0.1\n1e300,1\n0.3,0.3\n", "far.csv: line 4: 1e+300 R from the first"),
])
def test_malformed_files(tmp_path, name, content, message):
    path = _file(tmp_path, name, content)
    scale = {} if name.endswith("csv") and "r,z" in str(content) else SCALE
    with pytest.raises(MidlineError) as exc:
        tr.read_trace(path, **scale)
    assert message in str(exc.value) and str(path) in str(exc.value)


@pytest.mark.parametrize("name, rows, said", [
    ("huge.txt", GOOD_ROWS[:6] + ["1e308\t545"] + GOOD_ROWS[6:],
     r"line 7: \(1e\+308, 545\) px, a coordinate so far out that the trace's length overflows"),
    ("huge.txt", ["1.7e308\t0", "-1.7e308\t0"] + GOOD_ROWS, r"line 1: \(1\.7e\+308, 0\) px"),
    ("huge.csv", ["r,z", "1.7e308,0", "-1.7e308,0", "0,1", "0,2"],
     r"line 3: inf R from the first point"),
])
def test_an_absurd_coordinate_is_refused_at_its_line_without_a_warning(tmp_path, name, rows,
                                                                        said):
    """Audit 17 F7: a pixel trace with one cell 1e308 leaked numpy's overflow RuntimeWarning
    (the sum of its steps) and was refused as doubling back on itself; a trace whose length
    overflows is refused naming the point, and a csv trace's distance beyond floats is inf
    (refused by the extent check, without a warning)."""
    import warnings

    path = _file(tmp_path, name, "\n".join(rows) + "\n")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(MidlineError, match=f"{name}: {said}"):
            tr.read_trace(path, **({} if name.endswith("csv") else SCALE))


def test_pixel_dump_names_the_right_export(tmp_path):
    path = _file(tmp_path, "pixels.txt", "0\t0\t12\n1\t0\t13\n")
    with pytest.raises(MidlineError, match="File › Save As › XY Coordinates"):
        tr.read_trace(path, **SCALE)


def test_two_pieces_and_self_intersection(tmp_path):
    s = np.linspace(-0.5, 2 * np.pi - 1, 80)
    pieces = np.vstack([half(40), half(40)[::-1] * [-1, 1] + [0, 3]])     # second one far off
    loop = np.column_stack([np.sin(2 * s), np.sin(s)])                   # a figure of eight
    for name, points, message in (("pieces", pieces, "is not one curve"),
                                  ("loop", loop, "crosses the segment")):
        path = write(tmp_path, "xy", name, points=points, section="half")
        with pytest.raises(MidlineError, match=f"{name}.csv: .*{message}"):
            tr.read_trace(path, **SCALE)


# ------------------------------------------------------------------ text forms

PIXELS = 200 * half(20) + 300
ROWS = [(f"{x:.3f}", f"{y:.3f}") for x, y in PIXELS]


def _joined(sep, header=None, index=None, end=""):
    """The rows joined by ``sep``, under ``header``, after row numbers from ``index``."""
    lines = [] if header is None else [header]
    for k, row in enumerate(ROWS):
        cells = ([str(index + k)] if index is not None else []) + list(row)
        lines.append(sep.join(cells) + end)
    return "\n".join(lines) + "\n"


@pytest.mark.parametrize("name, content", [
    ("tab_header.txt", _joined("\t", "X\tY")),                  # was "header 'X\tY' is not 'x,y'"
    ("spaces.txt", _joined("  ", "x y")),
    ("spaces_bare.txt", _joined(" ")),
    ("no_header.csv", _joined(",")),                              # was "1 values, expected 2"
    ("fiji_results.csv", _joined(",", " ,X,Y", index=1)),        # was "this is a pixel list"
    ("pandas.csv", _joined(",", ",x,y", index=0)),
    ("fiji_results.txt", _joined("\t", " \tX\tY", index=1)),    # the empty name is stripped
    ("trailing.csv", _joined(",", "X,Y,", end=",")),              # was "this is a pixel list"
    ("quoted.csv", _joined(",", '"x","y"')),
])
def test_text_forms_that_are_read(tmp_path, name, content):
    """Tab-, space- and comma-separated pixels, with or without a header, after row numbers."""
    trace = tr.read_trace(_file(tmp_path, name, content), **SCALE)
    assert np.abs(trace.points - np.round(PIXELS, 3) * [0.005, -0.005]).max() < 1e-12
    assert trace.where[0] == ("line 1" if content[0].isdigit() else "line 2")


def test_named_columns_in_another_order_are_read_by_name(tmp_path):
    """An honest header ``y,x`` was refused as a pixel list (x, y, value) and ``z,r,spread`` as
    an unrecognised header (user audit 5, finding 11a): the names say which column is which.
    Exact equality: the same numbers are only moved between columns."""
    swapped = "\n".join(["Y,X", *(f"{y},{x}" for x, y in ROWS)]) + "\n"
    trace = tr.read_trace(_file(tmp_path, "yx.csv", swapped), **SCALE)
    plain = tr.read_trace(_file(tmp_path, "xy.csv", _joined(",", "x,y")), **SCALE)
    assert trace.format == "xy" and np.array_equal(trace.points, plain.points)
    mid = Midline(half(20)[:, 0], half(20)[:, 1], np.linspace(0.0, 0.01, 20), 3)
    mid.to_csv(tmp_path / "rz.csv")
    lines = (tmp_path / "rz.csv").read_text().splitlines()
    rows = [line.split(",") for line in lines if not line.startswith("#")]
    (tmp_path / "zr.csv").write_text("\n".join(
        [line for line in lines if line.startswith("#")]
        + [",".join((z, spread, r)) for r, z, spread in rows]) + "\n")
    assert rows[0] == ["r", "z", "spread"]
    for read in (Midline.from_csv(tmp_path / "zr.csv"), tr.read_trace(tmp_path / "zr.csv")):
        assert np.array_equal(read.spread, mid.spread) and read.n_traces == 3
    back = Midline.from_csv(tmp_path / "zr.csv")
    assert np.array_equal(back.r, mid.r) and np.array_equal(back.z, mid.z)


@pytest.mark.parametrize("name, content, message", [
    ("yxv.csv", "y,x,value\n1,2,3\n", "columns 'y,x,value': this is a pixel list"),
    ("zq.csv", "r,q\n0,0\n1,1\n", "unrecognised header 'r,q'; a trace file has a header 'x,y' "
                                   "(pixels) or 'r,z' (units of R), in any order"),
])
def test_other_headers_say_what_was_found_and_expected(tmp_path, name, content, message):
    """A third column, or a name that is not x, y, r, z or spread, is still refused in one line
    naming the header found and the ones read."""
    path = _file(tmp_path, name, content)
    with pytest.raises(MidlineError) as exc:
        tr.read_trace(path, **({} if "r," in content else SCALE))
    assert message in str(exc.value) and str(path) in str(exc.value)


@pytest.mark.parametrize("name, content, message", [
    ("semicolons.csv", "x;y\n1,5;2,5\n", "line 1: cells separated by ';' (a spreadsheet with "
                                          "decimal commas?)"),
    ("decimal_tabs.txt", "1,5\t2,5\n3,5\t4,5\n", "line 1: numbers with decimal commas ('1,5')"),
    ("decimal_rows.txt", "x\ty\n1,5\t2,5\n", "line 2, column 1 (x): '1,5' is not a number: a "
                                               "decimal comma?"),
    ("row_numbers.csv", " ,X,Y\n1,0,0\n2,1,1\n4,2,3\n5,3,6\n", "line 4: the first column, "
                                                              "without a name, holds 4 where a "
                                                              "row number would be 3"),
    ("image.png", b"\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR", "image.png: an image (PNG), not a trace"),
    ("image.tif", b"II*\x00\x08\x00\x00\x00", "image.tif: an image (TIFF), not a trace"),
    ("utf16.csv", "x,y\n1,2\n".encode("utf-16"), "utf16.csv: UTF-16 text: save it as UTF-8"),
    ("utf16be.csv", "x,y\n1,2\n".encode("utf-16-be"), "utf16be.csv: UTF-16 text"),
])
def test_text_forms_that_are_refused_say_what_they_are(tmp_path, name, content, message):
    """One line naming the file, what it found and (for text) the forms accepted."""
    path = _file(tmp_path, name, content)
    with pytest.raises(MidlineError) as exc:
        tr.read_trace(path, **SCALE)
    assert message in str(exc.value) and str(path) in str(exc.value)
    if name.endswith(("semicolons.csv", "tabs.txt")):
        assert "separated by commas, tabs or spaces" in str(exc.value)


def test_fiji_xy_and_xy_read_alike(tmp_path):
    """--format fiji-xy of an x,y CSV said "line 4: 1 values, expected 2 (x, y)"."""
    path = _file(tmp_path, "header.csv", "# a comment\n\n" + _joined(",", "x,y"))
    both = [tr.read_trace(path, fmt, **SCALE) for fmt in ("xy", "fiji-xy")]
    assert np.array_equal(both[0].points, both[1].points) and both[0].where[0] == "line 4"
    bare = _file(tmp_path, "bare.csv", _joined(","))            # units unknown without r,z
    with pytest.raises(MidlineError, match="bare.csv: line 1: no header: a csv trace starts with "
                                           "the line 'r,z'"):
        tr.read_trace(bare, "csv")


@pytest.mark.parametrize("options, message", [
    ({}, "pass pixel_size_um (µm per pixel) and radius_um (the embryo radius R in µm)"),
    ({"radius_um": 50.0}, "pass pixel_size_um (µm per pixel) to convert"),
    ({"pixel_size_um": 0.25}, "pass radius_um (the embryo radius R in µm) to convert"),
    ({"pixel_size_um": -0.25, "radius_um": 50.0}, "pixel_size_um = -0.25 must be positive"),
    ({"pixel_size_um": 0.25, "radius_um": "50"}, "radius_um = '50' must be a real number"),
    ({"pixel_size_um": 0.25, "radius_um": 1e-4}, "R from the first point; a midline lies within "
                                                  "20 R of its pole (check the pixel size"),
])
def test_scale_options(tmp_path, options, message):
    path = write(tmp_path, "roi")
    with pytest.raises(MidlineError) as exc:
        tr.read_trace(path, **options)
    assert message in str(exc.value) and str(path) in str(exc.value)


def test_csv_refuses_pixel_options(tmp_path):
    with pytest.raises(MidlineError, match="csv traces are in units of R: pixel_size_um"):
        tr.read_trace(write(tmp_path, "csv"), pixel_size_um=0.25)


def test_bad_roi_files(tmp_path):
    area = roifile.ImagejRoi.frompoints(200 * half(20) + 300)     # a freehand area selection
    area.tofile(tmp_path / "area.roi")
    _file(tmp_path, "broken.roi", b"Iout\x00\x01")
    for name, message in (("area.roi", "an area selection (freehand), not a line"),
                          ("broken.roi", "not a readable ImageJ ROI file")):
        with pytest.raises(MidlineError) as exc:
            tr.read_trace(tmp_path / name, **SCALE)
        assert f"{name}: {message}" in str(exc.value)


def test_a_pixel_trace_where_a_midline_is_read_points_to_average(tmp_path):
    """A campaign's folder lists midlines in units of R (format csv); a trace in pixels there
    had only been told its header is not 'r,z' (user audit): the message says what it is
    and the command that makes a midline of it."""
    path = _file(tmp_path, "trace.csv", "X,Y\n" + "\n".join(r.replace("\t", ",")
                                                          for r in GOOD_ROWS) + "\n")
    with pytest.raises(MidlineError, match=r"a trace in image pixels \(header 'X,Y'\), where a "
                                           r"midline in units of R .* `morphoshell average"):
        tr.read_trace(path, "csv")


# ------------------------------------------------------------------ traces that double back

def _pixels(points, noise_px=0.0, seed=0):
    """Model-gauge points as pixels of a whole section at the reference scale (200 px per R)."""
    from morphoshell.io import to_image
    px = to_image(points, radius_px=200.0, angle_deg=20.0, offset_px=(500.0, 500.0))
    return px + np.random.default_rng(seed).normal(0.0, noise_px, px.shape)


@pytest.mark.parametrize("noise_px, again_px", [(0.0, 0.0), (0.5, 0.0), (0.5, 0.05)])
def test_a_trace_drawn_out_and_back_is_refused_where_it_turns(tmp_path, noise_px, again_px):
    """Rim to rim and back along itself (audit 13, F5): the retraced points made a chord of
    4 steps vanish, its direction NaN, and the reader failed with "cannot convert float NaN to
    integer".  Now one line names the file and the point where it turns (the last of the way
    out), whether the way back repeats the points or lies within 0.05 px of them."""
    out = _pixels(half(301), noise_px)
    back = out[::-1][1:] + np.random.default_rng(1).normal(0.0, again_px, out[1:].shape)
    rows = "\n".join(f"{x:.4f}\t{y:.4f}" for x, y in np.r_[out, back]) + "\n"
    path = _file(tmp_path, "backforth.txt", rows)
    with pytest.raises(MidlineError, match=r"backforth.txt: the trace doubles back on itself "
                                           r"at line 601 \(arclength [0-9.]+ px of [0-9.]+\): "
                                           r"trace the midline once"):
        tr.read_trace(path, **SCALE)


def test_a_hairpin_fold_is_not_a_trace_that_doubles_back(tmp_path):
    """A U-turn of radius 0.035 R with straight arms 0.6 R long (a Volvox fold is no
    tighter) is read: its ends lie 0.07 R apart, not on top of each other."""
    turn = np.linspace(-np.pi / 2, np.pi / 2, 40)
    arm = np.linspace(0.6, 0.0, 120)[:-1]
    u = np.vstack([np.column_stack([arm, -0.035 + 0 * arm]),
                   np.column_stack([0.035 * np.cos(turn), 0.035 * np.sin(turn)]),
                   np.column_stack([arm[::-1], 0.035 + 0 * arm])]) + [1.0, 1.0]
    for noise_px in (0.0, 0.5):
        rows = "\n".join(f"{x:.4f}\t{y:.4f}" for x, y in 200 * u
                         + np.random.default_rng(0).normal(0, noise_px, u.shape)) + "\n"
        assert len(tr.read_trace(_file(tmp_path, "hairpin.txt", rows), **SCALE).points) == len(u)


# fuzzing the reader and the alignment: whatever the shape, a trace is read and aligned, or
# refused with one MidlineError, never another error (a NaN that reached an integer, audit 13)
_EDITS = ("repeat", "reverse", "back", "walk", "stairs", "loop4")


@given(edit=st.sampled_from(_EDITS), n=st.integers(12, 400), seed=st.integers(0, 2 ** 16),
       noise_px=st.sampled_from([0.0, 0.3, 2.0]))
@settings(max_examples=60, deadline=None, derandomize=True, database=None)
def test_fuzzed_traces_are_read_or_refused_by_name(edit, n, seed, noise_px):
    from morphoshell.io.trace_noise import noise_estimate

    rng = np.random.default_rng(seed)
    px = _pixels(half(n), noise_px, seed)
    i, j = sorted(rng.choice(n, 2, replace=False))
    if edit == "repeat":            # points repeated in place and further on (zero-length steps)
        px = np.insert(px, rng.integers(0, n, 5), px[rng.integers(0, n, 5)], axis=0)
    elif edit == "reverse":         # a stretch in reverse order
        px[i:j + 1] = px[i:j + 1][::-1].copy()
    elif edit == "back":            # out and back along a stretch
        px = np.r_[px[:j + 1], px[i:j][::-1], px[i + 1:]]
    elif edit == "walk":            # a random polyline
        px = np.cumsum(rng.normal(0.0, 3.0, (n, 2)), axis=0) + 500
    elif edit == "stairs":          # pixel-rounded: points repeat and step back and forth
        px = np.round(px + rng.normal(0.0, 0.7, px.shape))
    else:                           # a loop of 4 pixels that returns to its start
        px = np.insert(px, i, px[i] + [[1, 0], [1, 1], [0, 1]], axis=0)
    where = [f"line {k + 1}" for k in range(len(px))]
    try:
        trace = tr.pixel_trace("fuzz.txt", "xy", px, where, 0.25 / 50.0)
        assert np.all(np.isfinite(noise_estimate(trace.points))) or len(trace.points) < 12
        for section in ("whole", "half"):
            assert np.all(np.isfinite(ml.resample(ml.align(trace, section).points, 50)))
    except MidlineError as exc:
        assert str(exc).startswith("fuzz.txt: ") or "fitted axis" in str(exc), exc


def test_a_midline_is_one_line_when_echoed():
    """Audit 21 F8: a Midline's repr listed every point (62 lines, 4.6 k characters for the
    shipped average); it is one line, as the other results', with its points, traces,
    length (a quarter circle: pi/2 R) and first source."""
    import numpy as np

    from morphoshell.io import Midline

    t = np.linspace(0, np.pi / 2, 100)
    arc = Midline(np.sin(t), 1 - np.cos(t), np.full(100, 0.01), 5, ("a.csv", "b.csv", "c.csv"))
    # (a polygon of 99 chords of the arc: pi/2 to 2e-5, below the 3 digits printed)
    assert repr(arc) == ("Midline(100 points, 5 traces, length 1.57 R, with spread, "
                         "source='a.csv' and 2 more)")
    assert repr(Midline(arc.r[:3], arc.z[:3])) == "Midline(3 points, 1 trace, length 0.0317 R)"


def test_an_rz_csv_in_micrometres_is_told_its_units(tmp_path):
    """An r,z CSV in µm (R = 37.5 µm) was told "a trace in pixels is read with format 'xy'
    ...", not that r,z CSVs are in units of R (audit 25 F5); a midline file so too."""
    path = tmp_path / "um.csv"
    np.savetxt(path, TRUTH * 37.5, delimiter=",", header="r,z", comments="")
    said = ("R from the first point; a midline lies within 20 R of its pole (r,z csv traces are "
            "in units of R, the embryo's radius: divide r and z in µm by the radius in µm; a "
            "trace in pixels is read with format 'xy', 'fiji-xy' or 'roi' and a scale)")
    for read in (tr.read_trace, Midline.from_csv):
        with pytest.raises(MidlineError) as exc:
            read(path)
        message = str(exc.value)
        assert message.startswith(f"{path}: line ") and message.endswith(said), message
