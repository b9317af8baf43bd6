"""The measurement table of ablations (morphoshell.io.measurements), as the inverse estimates read it.

Units and extra columns, and bad rows and tables named by row and column.
"""
import math

import pytest

import morphoshell.io.measurements as I


# --------------------------------------------------------------------------
# measurements
# --------------------------------------------------------------------------

HEADER = ("embryo,R_um,H_um,hole_diameter_um,opening_um,rotation_deg,displacement_um,"
          "V_um_per_s,sigma_rotation_deg,note")


def test_table_reading_units_and_extras(tmp_path):
    path = tmp_path / "t.csv"
    path.write_text(f"# a comment\n{HEADER}\nA,40,11,8,0.5,15,1.5,0.9,2,first\n"
                    "B, 38 ,12,10,,-3,1.7,,,\n")
    a, b = I.read_measurements(path)
    assert a.h == pytest.approx(11 / 40) and a.Sigma == pytest.approx(math.asin(0.1))
    assert a.value("rotation") == pytest.approx(math.radians(15))
    assert a.value("opening") == pytest.approx(0.5 / 40) and a.error("rotation") == \
        pytest.approx(math.radians(2))
    assert a.extra == {"note": "first"} and a.row == 1
    assert b.opening_um is None and b.V_um_per_s is None and b.error("rotation") is None
    assert b.R_um == 38.0


def test_a_misspelt_optional_column_is_named_and_a_semicolon_table_explained(tmp_path,
                                                                              caplog):
    """Other columns are kept and ignored; one that looks like an optional column is named
    with the one it resembles (V_um_s: its recoil velocities, and so E/mu, had vanished
    without a word; user audit).  A table separated by ';' says so."""
    import logging

    path = tmp_path / "t.csv"
    header = HEADER.replace("V_um_per_s", "V_um_s").replace("sigma_rotation_deg", "sigma_rot")
    path.write_text(f"{header}\nA,40,11,8,0.5,15,1.5,0.9,2,first\n")
    with caplog.at_level(logging.WARNING, logger="morphoshell"):
        a, = I.read_measurements(path)
    assert a.V_um_per_s is None and a.extra["V_um_s"] == "0.9"
    assert "column 'V_um_s' is not read (did you mean 'V_um_per_s'?)" in caplog.text
    assert "'note'" not in caplog.text and "sigma_rot'" not in caplog.text   # (not near enough)
    path.write_text(f"{HEADER.replace(',', ';')}\nA;40;11;8;0.5;15;1.5;0.9;2;first\n")
    with pytest.raises(I.MeasurementError, match="separated by ';', not ','"):
        I.read_measurements(path)


@pytest.mark.parametrize("spelling", ["NA", "na", "N/A", "#N/A", "NaN", "nan", "NULL", "None",
                                      " NA "])
def test_missing_value_spellings_read_as_an_empty_cell(tmp_path, spelling):
    """``NA`` was refused ("'NA' is not a number") where an empty cell is a missing measure
    (user audit 5, finding 11b): lab tables from R, pandas or Excel write it so.  The rows
    must equal those of the table with empty cells, field by field."""
    empty = tmp_path / "empty.csv"
    empty.write_text(f"{HEADER}\nA,40,11,8,,15,1.5,,,first\n")
    spelt = tmp_path / "spelt.csv"
    spelt.write_text(f"{HEADER}\nA,40,11,8,{spelling},15,1.5,{spelling},{spelling},first\n")
    assert I.read_measurements(spelt) == I.read_measurements(empty)
    spelt.write_text(f"{HEADER}\nA,{spelling},11,8,0.5,15,1.5,,,\n")      # required: named
    with pytest.raises(I.MeasurementError, match="column 'R_um': the cell is empty"):
        I.read_measurements(spelt)


@pytest.mark.parametrize("row, named", [
    ("A,40,-11,8,0.5,15,1.5,,,",
     "row 1 (line 2, embryo 'A'), column 'H_um': -11.0 must be positive"),
    ("A,40,11,8,inf,15,1.5,,,", "column 'opening_um': inf must be a finite number"),
    ("A,40,11,8,0.5,15,n.a.,,,", "column 'displacement_um': 'n.a.' is not a number (a missing "
                                 "value is an empty cell or #N/A, N/A, NA, NAN, NONE, NULL)"),
    ("A,40,11,8,0.5,190,1.5,,,", "column 'rotation_deg': 190.0 must lie in (-180, 180)"),
    ("A,40,11,81,0.5,15,1.5,,,", "column 'hole_diameter_um': the hole (81.0 um) is larger"),
    ("A,40,11,8,0.5,15,abc,,,", "column 'displacement_um': 'abc' is not a number"),
    ("A,40,11,8,0.5,15,-1.5,,,", "column 'displacement_um': -1.5 must be non-negative"),
    ("A,40,41,8,0.5,15,1.5,,,", "column 'H_um': the thickness H = 41.0 um must be smaller"),
    ("A,,11,8,0.5,15,1.5,,,", "column 'R_um': the cell is empty (required)"),
    ("A,40,11,8,0.5,15,1.5,,0,", "column 'sigma_rotation_deg': 0.0 must be positive"),
    ("A,40,11,8,0.5,15", "row 1 (line 2, embryo 'A'): 6 cells, but the header has 10"),
])
def test_bad_rows_name_row_and_column(tmp_path, row, named):
    path = tmp_path / "t.csv"
    path.write_text(f"{HEADER}\n{row}\n")
    with pytest.raises(I.MeasurementError) as info:
        I.read_measurements(path)
    assert named in str(info.value)


@pytest.mark.parametrize("text, named", [
    ("", "empty file"),
    ("# only a comment\n", "empty file"),
    ("embryo,R_um,H_um,hole_diameter_um,opening_um,rotation_deg\n", "missing column(s) "
                                                                    "['displacement_um']"),
    (HEADER + "\n", "no measurements"),
    (HEADER + ",R_um\n", "appear more than once"),
    (HEADER + "\nA,40,11,8,0.5,15,1.5,,,\nA,40,11,8,0.5,15,1.5,,,\n", "also row 1's"),
])
def test_bad_tables(tmp_path, text, named):
    path = tmp_path / "t.csv"
    path.write_text(text)
    with pytest.raises(I.MeasurementError, match=None) as info:
        I.read_measurements(path)
    assert named in str(info.value)
    with pytest.raises(I.MeasurementError, match="no such file"):
        I.read_measurements(tmp_path / "missing.csv")


def test_equal_estimates_get_equal_intervals():
    """Every summary's bootstrap draws the same resamples of the embryos: rotation's
    asymptotic and Kelvin estimates are equal, and so are their intervals (they had their
    own streams: [-0.118, 0.027] against [-0.118, 0.023]; user audits)."""
    from pathlib import Path

    from morphoshell import estimate

    data = Path(__file__).resolve().parents[2] / "data" / "synthetic_ablations.csv"
    est = estimate(data, methods=("leading_order", "kelvin"))
    a, b = est.summary["rotation_asymptotic"], est.summary["rotation_kelvin"]
    assert a.mean == b.mean and a.interval == b.interval


def _table(path, rotations):
    """A table of one row per rotation (None: an empty cell), the other cells plausible."""
    rows = [f"E{i},40,11,8,0.5,{'' if r is None else r},1.5,,," for i, r in enumerate(rotations)]
    path.write_text("\n".join([HEADER, *rows]) + "\n")
    return path


@pytest.mark.parametrize("rotations, noted", [
    ([0.34, 0.27, -0.05, None, 0.43, 3.1], "rows 1-3, 5-6: every rotation lies within ±π"),
    ([0.34, 0.27, -0.05, 0.43, 3.1], "rows 1-5: every rotation"),
    ([0.34, 0.27, 0.05, 0.43], None),                  # four rows: too few to tell
    ([0.34, 0.27, 0.05, 0.43, 3.2], None),             # one beyond pi: degrees
    ([15.3, 19.3, 12.4, 20.4, 24.8], None),            # the synthetic table's range
])
def test_rotations_that_look_like_radians_are_noted(tmp_path, caplog, rotations, noted):
    """Rotations entered in radians (every one < 1 degree) gave k near 0.45 without a word
    (user audit 5, finding 11e): a warning names the column and the rows; the rule (at least
    5 rotations, all within pi) is _note_radians's docstring.  The values are read as they
    are: a note, not a refusal."""
    import logging

    with caplog.at_level(logging.WARNING, logger="morphoshell"):
        rows = I.read_measurements(_table(tmp_path / "t.csv", rotations))
    assert [m.rotation_deg for m in rows] == rotations
    if noted is None:
        assert "rotation_deg" not in caplog.text
    else:
        assert f"t.csv: column 'rotation_deg', {noted}" in caplog.text
        assert "radians in a column of degrees?" in caplog.text
