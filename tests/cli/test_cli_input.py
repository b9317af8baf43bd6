"""Bad command-line input: exit 2, one line naming the item, no traceback, no file left.

The cases are the findings of a 307-input sweep of the command line (issue
"the right minimum or an error"), each turned into a regression test.
"""
import os
from pathlib import Path

import pytest

from morphoshell.cli import main
from morphoshell.io.problem_files import example_path

ROOT = Path(__file__).resolve().parents[2]
TOY2 = str(example_path("toy2_ablation"))
TOY3 = str(example_path("toy3_anisotropic"))


def _run_bad(argv, capsys, named, tmp_path):
    before = set(tmp_path.rglob("*"))
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1, err
    assert named in err, err
    assert set(tmp_path.rglob("*")) == before, "an output file was left behind"


@pytest.mark.parametrize("args, named", [
    (["--json", "{tmp}/a.json", "--plot", "{tmp}/b.xyz"], "argument --plot"),
    (["--plot", "{tmp}/noext"], "argument --plot"),
    (["--json", ""], "argument --json: the output path is empty"),
    (["--json", "{tmp}/out.csv"], "argument --json"),
    (["--json", "{tmp}"], "is a folder, not a file"),
    (["--json", "{tmp}/missing/a.json"], "does not exist"),
    (["--json", "{tmp}/file.txt/a.json"], "is a file"),
    (["--linear-solver", "nonsense"], "argument --linear-solver: 'nonsense': choose one of"),
    (["--nodes", "1e9"], "argument --nodes: '1e9' is not an integer"),
    (["--nodes", "1000000000"], "argument --nodes: 1000000000 must lie in [5, 102400]"),
    (["--set", "nodes=1000000"], "nodes = 1000000 must be an integer in [5, 102400]"),
    (["--set", "stages=7"], "stages = 7 must be the integer 1, 2 or 3"),
    (["--set", "family=nonesuch"], "unknown profile family 'nonesuch'"),
    (["--set", "theory=kirchhoff"], "unknown theory 'kirchhoff'"),
    (["--set", "k=1e308"], "parameter k = 1e+308 must lie in [-1000, 1000]"),
    (["--set", "cut=3.1414"], "is shorter than 0.001"),
    # failed with unrelated solver statuses, at 1e-300 with raw CasADi warnings despite -q
    (["--set", "cut=1e-300", "-q"], "cut (Sigma) = 1e-300 must be 0 (a pole) or at least 0.0001"),
], ids=lambda v: v if isinstance(v, str) else " ".join(v)[:40])
def test_bad_solve_arguments(args, named, capsys, tmp_path):
    (tmp_path / "file.txt").write_text("x")
    args = [a.replace("{tmp}", str(tmp_path)) for a in args]
    _run_bad(["solve", TOY2, *args], capsys, named, tmp_path)


def test_read_only_folder_is_refused_before_the_solve(capsys, tmp_path, monkeypatch):
    ro = tmp_path / "ro"
    ro.mkdir()
    # the suite may run as root, who can write anywhere: the check asks os.access
    import morphoshell.cli._outputs as outputs
    real = os.access
    monkeypatch.setattr(outputs.os, "access", lambda p, mode: False if Path(p) == ro else real(p, mode))
    _run_bad(["solve", TOY2, "--json", str(ro / "a.json")], capsys, "is not writable", tmp_path)


@pytest.mark.parametrize("family_set, named", [
    (["--set", "f0=1e10"], "parameter f0 = 10000000000.0 must lie in [-0.9, 9]"),
    (["--set", "family=local_relaxation", "--set", "F0=1e308"], "parameter F0 = 1e+308"),
    (["--set", "family=volvox", "--set", "f3=1e300"], "parameter f3 = 1e+300 must lie in [0.1, 10]"),
    (["--set", "family=volvox", "--set", "sigma=1e-320"], "parameter sigma = 1e-320"),
])
def test_huge_family_values_are_named(family_set, named, capsys, tmp_path):
    extra = ["--set", "opening=0.3", "--set", "cut=0"] if "family=volvox" in family_set else []
    _run_bad(["solve", TOY3, *family_set, *extra], capsys, named, tmp_path)


@pytest.mark.parametrize("argv, named", [
    (["asymptotics", "--h", "2", "--k", "0", "--cut-angle", "0.5"], "argument --h: 2 must be"),
    (["asymptotics", "--h", "1e308", "--k", "0", "--cut-angle", "0.5"], "argument --h"),
    (["asymptotics", "--h", "nan", "--k", "0", "--cut-angle", "0.5"], "argument --h: nan"),
    (["sphere", "--h", "0.1", "--k", "0", "--c10", "1e308"], "argument --c10: 1e308"),
    (["sphere", "--h", "0.1", "--k", "0", "--c10", "-1", "--c01", "0.5"],
     "--c10 + --c01 = -0.5 must be positive"),
])
def test_bad_analytic_arguments(argv, named, capsys, tmp_path):
    _run_bad(argv, capsys, named, tmp_path)


def _file(tmp_path, data: bytes, name="p.toml"):
    path = tmp_path / name
    path.write_bytes(data)
    return str(path)


GOOD = b'[problem]\nfamily = "uniform"\nh = 0.3\ncut = 0.3\n[parameters]\nk = 0.0\n'


def test_problem_files_in_other_encodings(capsys, tmp_path):
    bad = _file(tmp_path, GOOD.replace(b"uniform", b"unif\xf6rm"), "latin1.toml")
    _run_bad(["solve", bad], capsys, "latin1.toml: not a text file in UTF-8", tmp_path)
    # a byte-order mark is fine
    assert main(["solve", _file(tmp_path, b"\xef\xbb\xbf" + GOOD, "bom.toml"), "--nodes", "50"]) == 0


def test_stages_must_be_an_integer_like_nodes(capsys, tmp_path):
    path = _file(tmp_path, GOOD + b"[solver]\nstages = 2.0\n")
    _run_bad(["solve", path], capsys, "stages = 2.0 must be the integer 1, 2 or 3", tmp_path)
    path = _file(tmp_path, GOOD + b"[solver]\nnodes = 200.0\n", "n.toml")
    _run_bad(["solve", path], capsys, "nodes = 200.0 must be an integer", tmp_path)


def test_solver_keys_and_family_through_set(capsys, tmp_path):
    out = tmp_path / "a.json"
    assert main(["solve", TOY2, "--set", "nodes=50", "--set", "stages=1",
                 "--set", "family=anisotropic", "--set", "f0=0.05", "--json", str(out)]) == 0
    assert "50 nodes, 50 points" in capsys.readouterr().out and out.exists()


def test_a_failed_solve_writes_nothing(capsys, tmp_path):
    # (a missing HSL library was the failure here: it is bad input now, refused when parsed)
    out, png = tmp_path / "a.json", tmp_path / "a.png"
    assert main(["solve", TOY2, "--method", "shooting", "--set", "h=1e-4", "--json", str(out),
                 "--plot", str(png)]) == 3
    assert "Shooting_Ill_Conditioned" in capsys.readouterr().err
    assert not out.exists() and not png.exists()
    assert list(tmp_path.iterdir()) == []


def test_bugs_exit_1_and_say_where_to_report(monkeypatch, capsys):
    import morphoshell.solvers.routes as front

    def broken(*args, **kwargs):
        raise ZeroDivisionError("an invented bug")
    monkeypatch.setattr(front, "solve", broken)
    assert main(["solve", TOY2]) == 1
    err = capsys.readouterr().err
    assert "internal error" in err and "ZeroDivisionError" in err and "report" in err
    assert "Traceback" not in err
