"""Ctrl-C on a sweep (morphoshell.workflows.sweep_runs): one line that says how far it got,
exit status 130 (143 after SIGTERM), the finished chunks kept in files marked partial, and
--resume computes only the rest, giving the rows of a sweep never interrupted.  (It showed
CasADi's line, said only "interrupted", and dropped every finished point: user audit 9.)

The interruption is driven deterministically: the point function of the fourth point
raises it (or sends the signal itself), with two points per chunk, so the first chunk is
finished, the second cut short and the third not begun.
"""
import csv
import io
import json
import os
import re
import signal
import sys

import numpy as np
import pandas as pd
import pytest

from morphoshell import Problem
from morphoshell.cli import main
from morphoshell.workflows.sweep_runs import NOT_COMPUTED, PARTIAL, SweepInterrupted
from morphoshell.workflows.sweeps import sweep

TOY2 = Problem("uniform", {"k": 0.0}, h=0.3, cut=0.3, name="toy2")
AXES = {"k": [0.0, 0.4, 0.8, 1.2, 1.6, 2.0]}
KW = dict(nodes=30, workers=1, chunk_size=2)
#: The point at which the sweep is interrupted (the second point of the second chunk).
STOP = 1.2
SWEEPS = sys.modules["morphoshell.workflows.sweeps"]


def _stopping(monkeypatch, stop=lambda: (_ for _ in ()).throw(KeyboardInterrupt)):
    """The point function of the sweep, calling ``stop()`` at k = STOP; the k it was
    called at."""
    real, calls = SWEEPS._solve_point, []

    def point(row, problem, *args):
        calls.append(problem.params["k"])
        if problem.params["k"] == STOP:
            stop()
        return real(row, problem, *args)

    monkeypatch.setattr(SWEEPS, "_solve_point", point)
    return calls


@pytest.fixture(scope="module")
def whole():
    return sweep(TOY2, AXES, **KW)


def _same_rows(a, b):
    """Every column equal to the bit (NaN where NaN), but the wall times."""
    assert list(a.columns) == list(b.columns)
    for key in a.columns:
        if key != "seconds":
            assert np.array_equal(a.columns[key], b.columns[key],
                                  equal_nan=a.columns[key].dtype == float), key


def test_ctrl_c_keeps_the_finished_chunks_and_resume_computes_only_the_rest(
        tmp_path, monkeypatch, whole):
    _stopping(monkeypatch)
    with pytest.raises(SweepInterrupted) as info:
        sweep(TOY2, AXES, **KW)
    exc = info.value
    assert str(exc) == "interrupted after 2 of 6 points" and (exc.done, exc.total) == (2, 6)
    status = exc.result.columns["status"]
    assert list(status[2:]) == [NOT_COMPUTED] * 4 and NOT_COMPUTED not in status[:2]
    assert np.isnan(exc.result.columns["energy"][2:]).all()
    csv_path, json_path = exc.write(tmp_path / "part.csv"), exc.write(tmp_path / "part.json")
    head = csv_path.read_text().splitlines()
    # a reader that takes the first line for the header fails on the next one
    assert head[0].startswith(f"# {PARTIAL}: 2 of 6 points computed") and "," not in head[0]
    with pytest.raises(pd.errors.ParserError):
        pd.read_csv(csv_path)
    data = json.loads(json_path.read_text())
    assert data["complete"] is False and data["points_done"] == 2
    monkeypatch.undo()
    for path in (csv_path, json_path):
        calls = _stopping(monkeypatch, stop=lambda: None)
        res = sweep(TOY2, AXES, **KW, resume=path)
        assert calls == AXES["k"][2:] and res.timing["restored"] == 2, path
        _same_rows(res, whole)


def test_resume_refuses_a_file_of_other_settings_or_a_complete_one(tmp_path, monkeypatch):
    _stopping(monkeypatch)
    with pytest.raises(SweepInterrupted) as info:
        sweep(TOY2, AXES, **KW)
    path = info.value.write(tmp_path / "part.json")
    monkeypatch.undo()
    monkeypatch.setattr(SWEEPS, "_run_chunk", lambda *a, **k: pytest.fail("work began"))
    for change, match in [
            (dict(nodes=40), r"with nodes = 30, not 40 \(--nodes\)"),
            (dict(chunk_size=3), r"with chunk_size = 2, not 3 \(--chunk-size\)"),
            (dict(axes={"k": [0.0, 0.5]}), r"with axes\.k = \[0\.0, \.\.\., 2\.0\] \(6 values\), "
                                           r"not \[0\.0, 0\.5\] \(--set k\)"),
            (dict(problem=TOY2.with_updates(h=0.2)), r"with problem\.h = 0\.3, not 0\.2")]:
        args = {"problem": TOY2, "axes": AXES, **KW, **change}
        with pytest.raises(ValueError, match=match):
            sweep(args.pop("problem"), args.pop("axes"), **args, resume=path)
    complete = tmp_path / "complete.csv"
    complete.write_text("k,energy\n0.0,1.0\n")
    # (a complete file does not record every setting to be checked: refused, saying what to do)
    with pytest.raises(ValueError, match=r"complete\.csv: a complete sweep, or none \(no "
                                         r"'morphoshell sweep PARTIAL' mark\): nothing to resume"
                                         r".* run without --resume to compute it again"):
        sweep(TOY2, AXES, **KW, resume=complete)


@pytest.mark.parametrize("sig, status, word", [
    (signal.SIGINT, 130, "interrupted"), (signal.SIGTERM, 143, r"terminated \(SIGTERM\)")])
def test_cli_one_line_exit_status_partial_files_and_resume(tmp_path, capsys, monkeypatch, sig,
                                                           status, word):
    from morphoshell.io.problem_files import example_text

    problem = tmp_path / "toy2.toml"
    problem.write_text(example_text("toy2_ablation"))
    csv_path, json_path = tmp_path / "out.csv", tmp_path / "out.json"
    args = ["sweep", str(problem), "--set", "k=0,0.4,0.8,1.2,1.6,2", "--nodes", "30",
            "--workers", "1", "--chunk-size", "2", "--csv", str(csv_path), "--json", str(json_path)]
    assert main(args) == 0
    whole = pd.read_csv(csv_path)
    capsys.readouterr()
    _stopping(monkeypatch, stop=lambda: os.kill(os.getpid(), sig))     # the real signal
    assert main(args) == status
    err = capsys.readouterr().err
    files = f"{re.escape(str(csv_path))} and {re.escape(str(json_path))}"
    assert re.fullmatch(rf"morphoshell: {word} after 2 of 6 points; kept in {files}, marked "
                        rf"partial: the same command with --resume computes the rest\n", err), err
    assert json.loads(json_path.read_text())["complete"] is False
    assert pd.read_csv(csv_path, comment="#")["status"].tolist()[2:] == [NOT_COMPUTED] * 4
    monkeypatch.undo()
    assert main([*args, "--resume"]) == 0
    assert "2 restored by --resume" in capsys.readouterr().out
    done = pd.read_csv(csv_path)          # complete: a plain CSV again
    pd.testing.assert_frame_equal(done.drop(columns="seconds"), whole.drop(columns="seconds"))
    assert "complete" not in json.loads(json_path.read_text())
    assert main([*args, "--resume"]) == 2       # nothing partial to resume
    assert "a complete sweep, or none" in capsys.readouterr().err


def test_cli_resume_needs_an_output_file(tmp_path, capsys):
    from morphoshell.io.problem_files import example_text

    problem = tmp_path / "toy2.toml"
    problem.write_text(example_text("toy2_ablation"))
    assert main(["sweep", str(problem), "--set", "k=0,1", "--resume"]) == 2
    assert "--resume needs the --csv or --json file" in capsys.readouterr().err


def test_workers_end_with_the_sweeps_process(monkeypatch):
    """A process pool's workers outlived a killed sweep, idle (they hold no lifeline)."""
    from morphoshell._runtime import lifeline

    watched = []
    monkeypatch.setattr(SWEEPS.lifeline, "watch", watched.append)
    sweep(TOY2, {"k": [0.0, 0.5]}, nodes=30, workers=1, errors="none")
    assert watched == [lifeline.owner()]


# --------------------------------------------------------------------------
# rows restored by their coordinates (user audit 12: by their position, a partial file
# with one row deleted gave 49 rows holding the next point's values, exit 0)
# --------------------------------------------------------------------------

@pytest.fixture(scope="module")
def computed(tmp_path_factory, whole):
    """A partial CSV and JSON holding every row of ``whole`` computed (three whole chunks),
    with the settings an interrupted sweep records."""
    mp = pytest.MonkeyPatch()
    _stopping(mp)
    with pytest.raises(SweepInterrupted) as info:
        sweep(TOY2, AXES, **KW)
    mp.undo()
    full = SweepInterrupted(whole, len(whole), info.value.settings)
    folder = tmp_path_factory.mktemp("computed")
    return full.write(folder / "all.csv"), full.write(folder / "all.json")


def _edited(path, tmp_path, edit):
    """A copy of the partial file ``path`` whose rows (dicts, CSV text or JSON) are
    ``edit(rows)``."""
    out = tmp_path / f"edited{path.suffix}"
    if path.suffix == ".json":
        data = json.loads(path.read_text())
        data["rows"] = edit(data["rows"])
        out.write_text(json.dumps(data))
        return out
    lines = path.read_text().splitlines(keepends=True)
    rows = edit(list(csv.DictReader(io.StringIO("".join(lines[2:])))))
    text = io.StringIO()
    writer = csv.DictWriter(text, fieldnames=list(rows[0]), lineterminator="\n")
    writer.writeheader()
    writer.writerows(rows)
    out.write_text("".join(lines[:2]) + text.getvalue())
    return out


@pytest.mark.parametrize("kind", ["csv", "json"])
@pytest.mark.parametrize("edit, computed_k", [
    (lambda rows: rows[:1] + rows[2:], [0.0, 0.4]),    # k = 0.4 deleted: its chunk again
    (lambda rows: rows[::-1], []),                     # the rows in another order: all kept
])
def test_resume_restores_rows_at_their_coordinates(tmp_path, monkeypatch, whole, computed, kind,
                                                   edit, computed_k):
    path = _edited(computed[kind == "json"], tmp_path, edit)
    calls = _stopping(monkeypatch, stop=lambda: None)
    res = sweep(TOY2, AXES, **KW, resume=path)
    assert calls == computed_k and res.timing["restored"] == 6 - len(computed_k)
    _same_rows(res, whole)


def _nan(row):
    """An empty value as the file holds it (CSV: no text, JSON: null)."""
    return "" if isinstance(row["k"], str) else None


def _with_k(row, k):
    """``row`` with its axis cell k set to ``k`` (as the file holds it: text in a CSV)."""
    return {**row, "k": k if isinstance(row["k"], float) else repr(k)}


@pytest.mark.parametrize("kind", ["csv", "json"])
@pytest.mark.parametrize("edit, match", [
    # a row moved off the grid (audit 12: a cut edited to 0.9 passed for its old point)
    (lambda rows: [_with_k(rows[0], 0.9), *rows[1:]],
     r", row 1: k = 0\.9 is not a point of this sweep \(k = 0\.9 is none of its 6 values; "
     r"nearest 0\.8\): the file was edited or made by another sweep"),
    # a value rounded by hand (or by a spreadsheet): not the grid's float, refused
    (lambda rows: [rows[0], _with_k(rows[1], 0.4000001), *rows[2:]],
     r", row 2: k = 0\.4 is not a point of this sweep \(k = 0\.4000001 is none"),
    (lambda rows: [*rows, rows[3]], r", row 7: k = 1\.2 repeats row 4: delete one of them"),
    (lambda rows: [{k: v for k, v in r.items() if k != "k"} for r in rows],
     r", row 1 has no column 'k'"),
    (lambda rows: [rows[0], {**rows[1], "energy": "banana"}, *rows[2:]],
     r", row 2, column 'energy': 'banana' is not a number"),
    # cells other than the coordinates (audit 17 F6: restored and written back, exit 0)
    (lambda rows: [rows[0], {**rows[1], "status": "Bogus_Status"}, *rows[2:]],
     r", row 2, column 'status': 'Bogus_Status' is not a status of morphoshell "
     r"\(numerics\.status\.STATUSES\): the file was edited"),
    (lambda rows: [rows[0], {**rows[1], "energy": _nan(rows[1])}, *rows[2:]],
     r", row 2, column 'energy': nan on a row that did not fail \(status Newton_Converged, "
     r"no message\)"),
    (lambda rows: [rows[0], {**rows[1], "walls_cross": "yes"}, *rows[2:]],
     r", row 2, column 'walls_cross': 'yes' is not True or False"),
])
def test_resume_refuses_a_row_not_at_a_point_of_the_grid(tmp_path, monkeypatch, computed, kind,
                                                         edit, match):
    path = _edited(computed[kind == "json"], tmp_path, edit)
    monkeypatch.setattr(SWEEPS, "_run_chunk", lambda *a, **k: pytest.fail("work began"))
    with pytest.raises(ValueError, match=re.escape(str(path)) + match):
        sweep(TOY2, AXES, **KW, resume=path)


@pytest.mark.parametrize("edit, match", [
    (lambda lines: lines[:1] + lines[2:],
     r"a partial sweep without its '# settings: \{\.\.\.\}' line \(line 2\): it cannot be "
     r"checked against this sweep's settings; run without --resume"),
    (lambda lines: [lines[0], lines[1][:40] + "\n", *lines[2:]],
     r"a partial sweep whose settings line \(line 2\) is damaged"),
    (lambda lines: [lines[0], "# settings: 3\n", *lines[2:]],
     r"a partial sweep whose settings line \(line 2\) is damaged"),
])
def test_resume_names_a_missing_or_damaged_settings_line(tmp_path, computed, edit, match):
    """It was called 'not a partial sweep' although its first line is the mark (audit 12)."""
    path = tmp_path / "part.csv"
    path.write_text("".join(edit(computed[0].read_text().splitlines(keepends=True))))
    with pytest.raises(ValueError, match=re.escape(str(path)) + ": " + match):
        sweep(TOY2, AXES, **KW, resume=path)


def test_resume_names_a_partial_json_without_settings(tmp_path, computed):
    data = json.loads(computed[1].read_text())
    del data["settings"]
    path = tmp_path / "part.json"
    path.write_text(json.dumps(data))
    with pytest.raises(ValueError, match=re.escape(str(path)) + r': a partial sweep without '
                                                                r'its "settings"'):
        sweep(TOY2, AXES, **KW, resume=path)


@pytest.mark.parametrize("cell, value, match", [
    ("status", 5, r"column 'status': 5 is not text"),
    ("iterations", 1.5, r"column 'iterations': 1\.5 is not a whole number"),
    ("walls_cross", 0, r"column 'walls_cross': 0 is not True or False"),
    ("energy", True, r"column 'energy': True is not a number"),
])
def test_resume_refuses_a_json_cell_of_another_type(tmp_path, computed, cell, value, match):
    """JSON's types were cast: a status 5 read '5', iterations 1.5 read 1 (audit 17 F6)."""
    path = _edited(computed[1], tmp_path, lambda rows: [{**rows[0], cell: value}, *rows[1:]])
    with pytest.raises(ValueError, match=re.escape(str(path)) + ", row 1, " + match):
        sweep(TOY2, AXES, **KW, resume=path)


@pytest.mark.parametrize("kind", ["csv", "json"])
def test_resume_reads_a_file_with_a_byte_order_mark(tmp_path, monkeypatch, whole, computed,
                                                    kind):
    """An editor's BOM before the mark read as 'a complete sweep ... no PARTIAL mark'."""
    path = tmp_path / f"bom.{kind}"
    path.write_bytes(b"\xef\xbb\xbf" + computed[kind == "json"].read_bytes())
    monkeypatch.setattr(SWEEPS, "_run_chunk", lambda *a, **k: pytest.fail("work began"))
    res = sweep(TOY2, AXES, **KW, resume=path)
    assert res.timing["restored"] == 6
    _same_rows(res, whole)


@pytest.mark.parametrize("kind", ["csv", "json"])
def test_resume_names_a_file_that_is_not_utf8(tmp_path, computed, kind):
    """It said "'utf-8' codec can't decode byte 0xff in position 0", naming no file."""
    path = tmp_path / f"latin.{kind}"
    text = computed[kind == "json"].read_bytes()
    path.write_bytes(text[:60] + b"\xff" + text[60:])
    with pytest.raises(ValueError, match=re.escape(str(path)) + r": not UTF-8 text \(byte 0xff "
                                                                r"at 60\)"):
        sweep(TOY2, AXES, **KW, resume=path)


def test_resume_names_a_csv_row_cut_short(tmp_path, computed):
    """A file cut mid-row said "row 6, column 'iterations': None is not a number"."""
    path = tmp_path / "cut.csv"
    text = computed[0].read_text()
    path.write_text(text[:text.rindex("Newton_Converged") + 3] + "\n")
    with pytest.raises(ValueError, match=re.escape(str(path)) + r", row 6, column 'iterations': "
                                                                r"the row is cut short"):
        sweep(TOY2, AXES, **KW, resume=path)
    path.write_text(text.rstrip("\n") + ",extra\n")
    with pytest.raises(ValueError, match=re.escape(str(path)) + r", row 6: more cells than"):
        sweep(TOY2, AXES, **KW, resume=path)


def test_resume_names_what_is_not_a_partial_json(tmp_path, computed):
    """A JSON list, or an object without "complete": false, was refused in the CSV's words
    (no 'morphoshell sweep PARTIAL' mark)."""
    path = tmp_path / "list.json"
    path.write_text("[1, 2]")
    with pytest.raises(ValueError, match=re.escape(str(path)) + r": not a sweep's JSON \(a list "
                                                                r"at the top, not an object\)"):
        sweep(TOY2, AXES, **KW, resume=path)
    data = json.loads(computed[1].read_text())
    del data["complete"]
    path.write_text(json.dumps(data))
    with pytest.raises(ValueError, match=r'a complete sweep, or none \(no "complete": false\)'):
        sweep(TOY2, AXES, **KW, resume=path)


def test_resume_calls_the_automatic_chunk_size_automatic(computed):
    """It said 'chunk_size = 2, not None' (None is the automatic size)."""
    with pytest.raises(ValueError, match=r"with chunk_size = 2, not automatic \(--chunk-size\)"):
        sweep(TOY2, AXES, **{**KW, "chunk_size": None}, resume=computed[0])


def test_cli_refuses_an_edited_status_exit_2(tmp_path, capsys, monkeypatch):
    """On the command line: one line naming the file, the row and the column, exit 2, the
    file left as it was."""
    from morphoshell.io.problem_files import example_text

    problem = tmp_path / "toy2.toml"
    problem.write_text(example_text("toy2_ablation"))
    path = tmp_path / "part.csv"
    args = ["sweep", str(problem), "--set", "k=0,0.4,0.8,1.2,1.6,2", "--nodes", "30",
            "--workers", "1", "--chunk-size", "2", "--csv", str(path)]
    _stopping(monkeypatch)
    assert main(args) == 130
    monkeypatch.undo()
    lines = path.read_text().splitlines(keepends=True)
    assert lines[3].count("Newton_Converged") == 1         # row 1, computed
    path.write_text("".join([*lines[:3], lines[3].replace("Newton_Converged", "Bogus_Status"),
                             *lines[4:]]))
    before = path.read_bytes()
    capsys.readouterr()
    assert main([*args, "--resume"]) == 2
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1, err
    assert f"{path}, row 1, column 'status': 'Bogus_Status' is not a status" in err
    assert path.read_bytes() == before
