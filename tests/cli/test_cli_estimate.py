"""``morphoshell estimate``: a run with every output, and bad input (exit 2, nothing written)."""
import json
from pathlib import Path

import pytest

from morphoshell.cli import main

HEADER = ("embryo,R_um,H_um,hole_diameter_um,opening_um,rotation_deg,displacement_um,"
          "V_um_per_s,sigma_opening_um,sigma_rotation_deg,sigma_displacement_um,remark")
GOOD = ["A,40,11,8,0.5,15,1.5,0.9,0.3,2,0.2,first", "B,38,12,10,,17,1.7,1.0,0.3,2,0.2,"]


def _table(tmp_path: Path, rows, header=HEADER) -> str:
    path = tmp_path / "m.csv"
    path.write_text("\n".join([header, *rows]) + "\n" if header is not None else "")
    return str(path)


def test_estimate_writes_json_csv_and_plot(tmp_path, capsys):
    table = _table(tmp_path, GOOD)
    out = {k: tmp_path / f"out.{k}" for k in ("json", "csv", "png")}
    argv = ["estimate", table, "--bootstrap", "200", "--seed", "3", "--json", str(out["json"]),
            "--csv", str(out["csv"]), "--plot", str(out["png"])]
    assert main(argv) == 0
    text = capsys.readouterr().out
    assert "2 embryos" in text and "E/mu = " in text and "1/s" in text
    data = json.loads(out["json"].read_text())
    a, b = data["embryos"]
    assert a["embryo"] == "A" and a["extra"] == {"remark": "first"}
    for measure in ("opening", "rotation", "displacement"):
        for method in ("asymptotic", "numerical"):
            assert isinstance(a[f"k_{measure}_{method}"], float)
            assert isinstance(a[f"k_{measure}_{method}_error"], float)
    # B has no opening: null and the reason
    assert b["k_opening_numerical"] is None and "opening, numerical: no opening measured" in \
        b["notes"]
    assert data["summary"]["combined"]["n"] == 2 and len(data["summary"]["combined"][
        "interval_95"]) == 2
    assert data["E_over_mu"] > 0 and data["E_lower_bound_Pa"] == pytest.approx(
        data["E_over_mu"] * 8e-4)
    assert data["settings"]["seed"] == 3 and data["input"] == table
    assert out["csv"].read_text().startswith("embryo,row,h,cut_rad")
    assert out["png"].read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_help_states_the_observables(capsys):
    assert main(["estimate", "--help"]) == 0
    text = " ".join(capsys.readouterr().out.split())
    assert "post-ablation minus the intact (Sigma = 0) equilibrium" in text
    assert "material point s = Sigma" in text and "far-end gauge" in text


def _bad(argv, capsys, tmp_path, named):
    before = set(tmp_path.rglob("*"))
    out = tmp_path / "out.json"
    assert main([*argv, "--json", str(out)]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1, err
    assert named in err, err
    assert set(tmp_path.rglob("*")) == before and not out.exists()


@pytest.mark.parametrize("rows, named", [
    (["A,40,11,8,0.5,15,1.5,0.9,0.3,2,0.2,", "B,38,-12,10,,17,1.7,1.0,0.3,2,0.2,"],
     "row 2 (line 3, embryo 'B'), column 'H_um': -12.0 must be positive"),
    (["A,40,11,8,0.5,Inf,1.5,0.9,0.3,2,0.2,"], "row 1 (line 2, embryo 'A'), column "
                                               "'rotation_deg': inf must be a finite"),
    (["A,40,11,8,0.5,-180,1.5,0.9,0.3,2,0.2,"], "column 'rotation_deg': -180.0 must lie in "
                                                "(-180, 180) degrees"),
    (["A,40,11,80.5,0.5,15,1.5,0.9,0.3,2,0.2,"], "column 'hole_diameter_um': the hole (80.5 um)"
                                                 " is larger than the shell"),
    (["A,40,11,8,0.5,15,1.5,fast,0.3,2,0.2,"], "column 'V_um_per_s': 'fast' is not a number"),
    (["A,40,11,8,0.5,15,-0.1,0.9,0.3,2,0.2,"], "column 'displacement_um': -0.1 must be "
                                               "non-negative"),
], ids=["negative H", "infinite rotation", "rotation -180", "hole too large", "non-numeric",
        "negative d"])
def test_bad_cells_exit_2_naming_row_and_column(rows, named, capsys, tmp_path):
    _bad(["estimate", _table(tmp_path, rows)], capsys, tmp_path, named)


@pytest.mark.parametrize("header, rows, named", [
    (None, [], "empty file"),
    ("embryo,R_um,H_um,hole_diameter_um,opening_um,displacement_um", GOOD[:1],
     "missing column(s) ['rotation_deg']"),
    (HEADER, [], "no measurements (only a header)"),
], ids=["empty", "missing column", "header only"])
def test_bad_tables_exit_2(header, rows, named, capsys, tmp_path):
    _bad(["estimate", _table(tmp_path, rows, header)], capsys, tmp_path, named)


@pytest.mark.parametrize("args, named", [
    (["--k-range", "1", "0"], "--k-range 1 0: LO must be smaller than HI"),
    (["--k-range", "0", "nan"], "argument --k-range: nan must be a finite number"),
    (["--bootstrap", "-1"], "argument --bootstrap: -1 must lie in"),
    (["--bootstrap", "1"], "argument --bootstrap: 1: too few resamples to estimate the 2.5 %"),
    (["--mu-min", "0"], "argument --mu-min: 0 must be a finite number in (0, 1e+06] Pa s"),
    (["--theory", "kirchhoff"], "argument --theory: invalid choice"),
])
def test_bad_options_exit_2(args, named, capsys, tmp_path):
    _bad(["estimate", _table(tmp_path, GOOD), *args], capsys, tmp_path, named)


def test_missing_file_exits_2(capsys, tmp_path):
    _bad(["estimate", str(tmp_path / "nope.csv")], capsys, tmp_path, "nope.csv: no such file")


def test_an_empty_sigma_cell_is_named_and_keeps_the_weighted_summary(tmp_path, capsys):
    """User audit: one empty sigma_* cell made that embryo's k_combined a plain mean unseen,
    dropped its k_*_error keys and the weighted summary from the terminal and the JSON.  Now
    the embryo's note names the column, the keys are null, and the weighted summary is over
    the embryos with errors, saying how many."""
    rows = [*GOOD, "C,41,11,9,0.6,16,1.6,0.95,0.3,,0.2,"]
    out = tmp_path / "out.json"
    assert main(["estimate", _table(tmp_path, rows), "--workers", "1", "--bootstrap", "0",
                 "--json", str(out)]) == 0
    text = capsys.readouterr().out
    assert "C: plain mean of rotation, displacement, not weighted: no sigma_rotation_deg" in text
    assert "inverse-variance weighted:" in text and "over the 2 of 3 embryos" in text
    data = json.loads(out.read_text())
    a, _, c = data["embryos"]
    assert set(a) == set(c) and c["k_rotation_numerical_error"] is None
    assert any("sigma_rotation_deg" in n for n in c["notes"])
    combined = data["summary"]["combined"]
    assert combined["weighted_n"] == 2 and isinstance(combined["weighted_mean"], float)
    assert data["summary"]["opening_kelvin"]["weighted_mean"] is None     # (none: null, kept)


def test_a_successful_parallel_run_prints_nothing_on_stderr(tmp_path):
    """Audit: ``estimate -q`` exited 0 but printed worker tracebacks ("Process
    ForkPoolWorker-2: ... Terminated") in about half the runs: the forked workers inherited
    the command line's SIGTERM handler, and the pool's terminate() at its end made each
    idle worker raise.  Several runs (the race is lost in some of them), stderr empty."""
    import os
    import subprocess
    import sys

    src = Path(__file__).resolve().parents[2] / "src"
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(src), os.environ.get("PYTHONPATH", "")])}
    rows = [f"{label}{row[1:]}" for label in "ABC" for row in GOOD[:1]]
    argv = [sys.executable, "-m", "morphoshell.cli", "estimate", _table(tmp_path, rows),
            "--workers", "2", "--bootstrap", "0", "--nodes", "20", "-q"]
    for _ in range(6):
        run = subprocess.run(argv, capture_output=True, text=True, env=env, timeout=120)
        assert run.returncode == 0 and run.stderr == "", run.stderr
