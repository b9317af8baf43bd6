"""Provenance of written files: the code's git commit and the input files' checksums."""
import hashlib
import json
import shutil
import subprocess
from pathlib import Path

import pytest

from morphoshell.cli import main
import morphoshell.io.provenance as prov
from morphoshell.io.problem_files import example_path, write_json

ROOT = Path(__file__).resolve().parents[2]
CHECKOUT = (ROOT / ".git").exists() and shutil.which("git") is not None


def test_input_records_are_absolute_paths_and_their_checksums(tmp_path, monkeypatch):
    (tmp_path / "a.toml").write_text("x")
    monkeypatch.chdir(tmp_path)
    record = prov.input_record("a.toml")       # (typed relative to the working folder)
    assert record == {"path": str(tmp_path / "a.toml"),
                      "sha256": hashlib.sha256(b"x").hexdigest()}


@pytest.mark.skipif(not CHECKOUT, reason="the package does not run from a git checkout")
def test_the_commit_is_the_checkouts_head():
    head = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "HEAD"], capture_output=True,
                          text=True, check=True).stdout.strip()
    found = prov.code_commit()
    assert found["git_commit"] == head and isinstance(found["git_modified"], bool)
    assert prov.code_commit() is found          # (once per process)


@pytest.mark.skipif(shutil.which("git") is None, reason="needs git")
def test_no_commit_and_no_error_outside_a_checkout(tmp_path, monkeypatch):
    """A package installed inside another repository (a virtual environment in a checkout),
    outside any, or no git: no commit, nothing said."""
    def git(*args):
        subprocess.run(["git", "-C", str(tmp_path), "-c", "user.name=t", "-c",
                        "user.email=t@t", *args], check=True, capture_output=True)
    git("init", "-q")
    (tmp_path / "other").write_text("x")
    git("add", "other")
    git("commit", "-q", "-m", "another repository's commit")
    package = tmp_path / "venv" / "morphoshell"
    package.mkdir(parents=True)
    (package / "__init__.py").write_text("")
    monkeypatch.setattr(prov, "_PACKAGE", package)
    prov.code_commit.cache_clear()
    try:
        assert prov.code_commit() == {}
        monkeypatch.setattr(prov, "_PACKAGE", tmp_path.parent)
        prov.code_commit.cache_clear()
        assert prov.code_commit() == {}
        assert not {"git_commit", "git_modified"} & set(prov.provenance())
        monkeypatch.setenv("PATH", str(tmp_path))       # (no git program at all)
        prov.code_commit.cache_clear()
        assert prov.code_commit() == {}
    finally:
        prov.code_commit.cache_clear()


@pytest.mark.skipif(shutil.which("git") is None, reason="needs git")
def test_modified_says_whether_the_source_differs(tmp_path, monkeypatch):
    """A tracked package file in a scratch repository: clean, then edited."""
    def git(*args):
        subprocess.run(["git", "-C", str(tmp_path), "-c", "user.name=t", "-c",
                        "user.email=t@t", *args], check=True, capture_output=True)
    package = tmp_path / "src" / "morphoshell"
    package.mkdir(parents=True)
    (package / "__init__.py").write_text("")
    (tmp_path / "notes.txt").write_text("")
    git("init", "-q")
    git("add", ".")
    git("commit", "-q", "-m", "c")
    monkeypatch.setattr(prov, "_PACKAGE", package)
    try:
        prov.code_commit.cache_clear()
        assert prov.code_commit()["git_modified"] is False
        (tmp_path / "notes.txt").write_text("outside src/: not the package's source")
        prov.code_commit.cache_clear()
        assert prov.code_commit()["git_modified"] is False
        (package / "__init__.py").write_text("x = 1")
        prov.code_commit.cache_clear()
        assert prov.code_commit()["git_modified"] is True
    finally:
        prov.code_commit.cache_clear()


def test_write_json_records_the_inputs(tmp_path):
    data = tmp_path / "in.csv"
    data.write_text("r,z\n")
    path = write_json(tmp_path / "out.json", {"a": 1}, [data])
    got = json.loads(path.read_text())["provenance"]
    assert got["inputs"] == [{"path": str(data), "sha256": hashlib.sha256(b"r,z\n").hexdigest()}]
    assert set(got) >= {"morphoshell", "casadi", "numpy", "written"}
    assert "inputs" not in json.loads(write_json(tmp_path / "b.json", {}).read_text())[
        "provenance"]


@pytest.mark.skipif(not CHECKOUT, reason="the package does not run from a git checkout")
def test_solve_json_names_its_problem_file_and_commit(tmp_path, monkeypatch):
    """Audit 27 F4: a solve JSON held only the problem's name and version 0.1.0."""
    problem = tmp_path / "toy2.toml"
    shutil.copy(example_path("toy2_ablation"), problem)
    monkeypatch.chdir(tmp_path)
    assert main(["solve", "toy2.toml", "--nodes", "20", "--json", "s.json", "-q"]) == 0
    got = json.loads((tmp_path / "s.json").read_text())["provenance"]
    assert got["inputs"] == [prov.input_record(problem)]
    assert got["git_commit"] == prov.code_commit()["git_commit"]


T01 = ROOT / "data" / "synthetic_inversion" / "t01" / "synthetic_average.csv"
T02 = ROOT / "data" / "synthetic_inversion" / "t02"
ABLATIONS = ROOT / "data" / "synthetic_ablations.csv"


@pytest.mark.parametrize("argv, inputs", [
    (["ablate", "P", "--set", "cut=0.2", "--nodes", "20"], ["P"]),
    (["sweep", "P", "--set", "k=0.5,1", "--nodes", "20", "--workers", "1"], ["P"]),
    (["continue", "P", "--nodes", "20"], ["P"]),
    (["average", str(T02 / "synthetic_embryo1_midline.csv"),
      str(T02 / "synthetic_embryo2_midline.csv")],
     [T02 / "synthetic_embryo1_midline.csv", T02 / "synthetic_embryo2_midline.csv"]),
    (["fit", str(T01), "--variant", "flat", "--nodes", "20"], [T01]),
    (["estimate", str(ABLATIONS), "--bootstrap", "0", "--nodes", "40", "--workers", "1"],
     [ABLATIONS]),
], ids=["ablate", "sweep", "continue", "average", "fit", "estimate"])
def test_each_command_records_the_files_it_read(argv, inputs, tmp_path, capsys):
    problem = tmp_path / "toy2.toml"
    shutil.copy(example_path("toy2_ablation"), problem)
    out = tmp_path / "out.json"
    argv = [str(problem) if a == "P" else a for a in argv]
    assert main([*argv, "--json", str(out), "-q"]) == 0, capsys.readouterr()
    got = json.loads(out.read_text())["provenance"]["inputs"]
    assert got == [prov.input_record(problem if p == "P" else p) for p in inputs]


def _future(tmp_path, record: dict, fmt=prov.FORMAT + 1) -> Path:
    path = tmp_path / "future.json"
    path.write_text(json.dumps({**record, "provenance": {**record.get("provenance", {}),
                                                         "format": fmt}}))
    return path


def test_written_files_carry_the_format():
    assert prov.provenance()["format"] == prov.FORMAT


@pytest.mark.parametrize("fmt, said", [
    (prov.FORMAT + 1, rf"future.json: written in file format {prov.FORMAT + 1} \(by "
                      rf"morphoshell .*\); this morphoshell reads format {prov.FORMAT} and "
                      rf"older: update it"),
    ("1", r"future.json: provenance.format = '1' is not a format number"),
    (True, r"future.json: provenance.format = True is not a format number"),
])
def test_a_file_of_a_newer_format_is_refused_by_every_json_reader(tmp_path, fmt, said):
    """Audit 27 F5: a file from a newer morphoshell loaded without a word."""
    from morphoshell.io.problem_files import read_json

    path = _future(tmp_path, {"a": 1}, fmt)
    with pytest.raises(ValueError, match=said):
        read_json(path)


def test_older_files_and_this_format_are_read(tmp_path):
    from morphoshell.io.problem_files import read_json

    for record in ({"a": 1}, {"provenance": {"morphoshell": "0.1.0"}}, [1, 2]):
        (tmp_path / "old.json").write_text(json.dumps(record))
        assert read_json(tmp_path / "old.json") == record
    assert read_json(_future(tmp_path, {"a": 1}, prov.FORMAT))["a"] == 1


def test_solve_refuses_a_newer_result_in_one_line(tmp_path, capsys):
    from morphoshell.io.problem_files import read_json

    solved = tmp_path / "s.json"
    assert main(["solve", str(example_path("toy2_ablation")), "--nodes", "20", "--json",
                 str(solved), "-q"]) == 0
    assert read_json(solved)["provenance"]["format"] == prov.FORMAT
    future = _future(tmp_path, json.loads(solved.read_text()))
    assert main(["solve", str(future)]) == 2
    err = capsys.readouterr().err
    assert "future.json: written in file format" in err and len(err.strip().splitlines()) == 1


def test_a_campaign_record_of_a_newer_format_is_refused(tmp_path):
    from morphoshell.workflows.campaign_results import read_record

    with pytest.raises(ValueError, match="future.json: written in file format"):
        read_record(_future(tmp_path, {"status": "ok"}))


def test_unknown_entries_are_warned_of_once_per_reader(caplog):
    import logging

    with caplog.at_level(logging.WARNING, logger="morphoshell"):
        prov.note_unknown({"a": 1, "zz_test_new": 2}, ["a"], "x.json", "test reader")
        prov.note_unknown({"a": 1, "zz_test_new": 2}, ["a"], "y.json", "test reader")
        prov.note_unknown({"a": 1}, ["a"], "z.json", "test reader")
    assert caplog.text.count("zz_test_new") == 1
    assert ("x.json: entries 'zz_test_new' are not read by test reader (edited by hand, or "
            "written by a newer morphoshell?)") in caplog.text


def test_a_partial_sweep_of_a_newer_format_is_refused(tmp_path):
    from morphoshell.workflows.sweep_runs import _read_json

    with pytest.raises(ValueError, match="future.json: written in file format"):
        _read_json(_future(tmp_path, {"complete": False}))
