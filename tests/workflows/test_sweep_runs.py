"""Ctrl-C on a sweep (morphoshell.workflows.sweep_runs): one line that says how far it got,
exit status 130 (143 after SIGTERM), the finished chunks kept in files marked partial, and
--resume computes only the rest, giving the rows of a sweep never interrupted.  (It showed
CasADi's line, said only "interrupted", and dropped every finished point: user audit 9.)

The interruption is driven deterministically: the point function of the fourth point
raises it (or sends the signal itself), with two points per chunk, so the first chunk is
finished, the second cut short and the third not begun.
"""
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
    with pytest.raises(ValueError, match=r"complete\.csv: not a partial sweep"):
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
    assert "not a partial sweep" in capsys.readouterr().err


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
