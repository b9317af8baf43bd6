"""A data set's table, timepoints.csv: read, or refused saying what is wrong with it."""
import pytest

from morphoshell.io.timepoints import read_timepoints

EXPECTED = ("; expected a header timepoint,pseudotime,midline (cells separated by ',') and at "
            "least one row")


def _folder(tmp_path, text):
    (tmp_path / "m.csv").write_text("r,z\n")      # (read only as a path that exists)
    (tmp_path / "timepoints.csv").write_text(text, encoding="utf-8")
    return tmp_path


def test_a_table_is_read(tmp_path):
    tp, = read_timepoints(_folder(tmp_path, "# a comment\ntimepoint,pseudotime,midline\n"
                                            "t01,0.5,m.csv\n"))
    assert (tp.name, tp.pseudotime, tp.midline, tp.traces) == ("t01", 0.5, "m.csv", ())


@pytest.mark.parametrize("text, why", [
    # audit 26, F6: each was told "expected a header timepoint,pseudotime,midline", which it
    # had, and nothing else
    ("timepoint\tpseudotime\tmidline\nt01\t0\tm.csv\n",
     r"line 1, the header, reads 'timepoint\tpseudotime\tmidline': cells separated by tabs, "
     r"not ','"),
    ("timepoint;pseudotime;midline\nt01;0,5;m.csv\n",
     "line 1, the header, reads 'timepoint;pseudotime;midline': cells separated by ';', "
     "not ','"),
    ("Timepoint,Pseudotime,Midline\nt01,0,m.csv\n",
     "line 1, the header, reads 'Timepoint,Pseudotime,Midline': column names are lower case"),
    ("# t01 to t10\ntimepoint,time,midline\nt01,0,m.csv\n",
     "line 2, the header, reads 'timepoint,time,midline': no column pseudotime"),
    ("timepoint,pseudotime,midline\n", "line 1, the header, reads "
                                       "'timepoint,pseudotime,midline' but no row follows it"),
    ("# nothing yet\n\n", "no header (the file is empty or all comments)"),
])
def test_a_bad_header_is_named_with_what_is_wrong(tmp_path, text, why):
    folder = _folder(tmp_path, text)
    with pytest.raises(ValueError) as info:
        read_timepoints(folder)
    assert str(info.value) == f"{folder / 'timepoints.csv'}: {why}{EXPECTED}"
