"""`morphoshell ablate FIT.json` carries the fit's uncertainty into the observables (audit 25,
F2: a fitted shell's rotation printed as 0.3696 rad +- 1.8e-06, the numerical error only,
where the fit's errors give +- 0.019 rad and the truth was 0.1538 rad)."""
import csv
import json
import re

import numpy as np
import pytest

from morphoshell import Problem, ablate
from morphoshell.cli import main
from morphoshell.solvers.observables import RECOIL
from morphoshell.workflows import ablation_errors, fitted_problem

FITTED = Problem("volvox", {"kappa2": -7.5, "s1": 1.2}, h=0.15, opening=0.3)
NODES = 40          # (a coarse mesh: what is printed and written is tested, not the recoil)


def _record(**changes) -> dict:
    """A free fit's record as `morphoshell fit --json` writes it, with standard errors."""
    p = FITTED
    rec = {"problem": p.describe(), "variant": "free", "converged": True, "E_fit": 0.004,
           "parameters": {**p.params, "h": p.h, "cut": p.cut, "opening": p.opening},
           "fitted": ["kappa2", "s1"], "standard_errors": {"kappa2": 0.05, "s1": 0.01},
           "solver": {"nodes": 100, "stages": 3, "method": "direct"},
           "correlation": [[1.0, -0.4], [-0.4, 1.0]],
           "note": "standard errors are Gauss-Newton lower bounds: the residuals of a traced "
                   "midline are correlated"}
    rec.update(changes)
    return json.loads(json.dumps(rec))


def _ablate(tmp_path, record, *more) -> tuple[int, str, dict, dict]:
    """Exit status, standard output, the JSON and the CSV's row of `ablate FIT.json`."""
    path, out, table = tmp_path / "fit.json", tmp_path / "a.json", tmp_path / "a.csv"
    path.write_text(json.dumps(record))
    status = main(["ablate", str(path), "--set", "cut=0.15", "--nodes", str(NODES), *more,
                   "--json", str(out), "--csv", str(table)])
    with open(table, newline="") as f:
        row = next(csv.DictReader(f))
    return status, path, json.loads(out.read_text()), row


def test_each_recoil_observable_carries_the_fits_error(tmp_path, capsys):
    """Printed beside the numerical error, labelled, and written as se_<observable> (the
    names of a campaign's fig3_ablations.json): equal to ablation_errors of the same
    ablation."""
    record = _record()
    status, path, data, row = _ablate(tmp_path, record)
    assert status == 0
    printed = capsys.readouterr().out
    want = ablation_errors(record, ablate(fitted_problem(record).with_updates(cut=0.15),
                                          nodes=NODES, stages=3))    # (the record's solver)
    for k in RECOIL:
        # (the same ablation solved again: equal to round-off of the solves, 1e-9)
        assert data[f"se_{k}"] == pytest.approx(want[k], rel=1e-9), k
        assert float(row[f"se_{k}"]) == data[f"se_{k}"], k
        assert data["units"][f"se_{k}"] == data["units"][k]
        line = re.search(rf"^  {k} +=.*\(numerical, .*\) \+- (\S+) \S+ \(fit\)$", printed, re.M)
        assert line and float(line.group(1)) == pytest.approx(want[k], rel=0.05), k
    assert not {"se_energy_released", "se_energy_removed"} & set(data)
    assert "  +- (fit): the fit's standard errors and correlations carried linearly" in printed
    assert "carried linearly" in data["fit_error_note"]
    # (the one note: the mesh the fit's JSON is solved on, audit 27 F2)
    notes = [line for line in printed.splitlines() if line.startswith("note:")]
    assert notes == [f"note: {path}: solved on {NODES} nodes (--nodes), stages 3 (as recorded)"]


def test_wide_profile_intervals_are_said_to_escape_the_fits_errors(tmp_path, capsys):
    record = _record(profile_intervals={"kappa2": [-8.0, -7.0]},
                     profiles={"kappa2": {"confidence": 0.95}})
    assert _ablate(tmp_path, record)[0] == 0
    assert ("+- (fit): these miss the profile intervals of kappa2, 5.1 times as wide"
            in capsys.readouterr().out)


@pytest.mark.parametrize("record, more, why", [
    ({k: v for k, v in _record().items() if k not in ("standard_errors", "correlation")}, (),
     "the record has no standard_errors, correlation"),
    (_record(), ("--set", "kappa2=-7"), "the ablated shell is not the fitted one (kappa2 = -7,"),
])
def test_without_the_fits_errors_one_note_says_why(tmp_path, capsys, record, more, why):
    status, path, data, row = _ablate(tmp_path, record, *more)
    assert status == 0
    notes = [n for n in capsys.readouterr().out.splitlines() if n.startswith("note:")]
    # (beside the note of the mesh the fit's JSON is solved on, audit 27 F2)
    assert notes[0] == f"note: {path}: solved on {NODES} nodes (--nodes), stages 3 (as recorded)"
    notes = notes[1:]
    assert len(notes) == 1 and notes[0].startswith(
        f"note: {path}: no errors of the fit carried into the observables: {why}")
    assert not any(k.startswith("se_") for k in (*data, *row))
    assert data["fit_error_note"].startswith("no errors of the fit carried") and why in \
        data["fit_error_note"]


def test_a_problem_file_has_neither(tmp_path, capsys):
    toml = tmp_path / "shell.toml"
    toml.write_text('[problem]\nfamily = "volvox"\nh = 0.15\nopening = 0.3\ncut = 0.15\n'
                    '[parameters]\nkappa2 = -7.5\ns1 = 1.2\n')
    out = tmp_path / "a.json"
    assert main(["ablate", str(toml), "--nodes", str(NODES), "--json", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "(fit)" not in printed and "note:" not in printed
    assert not {"fit_error_note", "se_rotation"} & set(json.loads(out.read_text()))


def test_a_fit_of_an_average_also_carries_its_traces_sigma2(tmp_path, capsys, monkeypatch):
    """Audit 28 F2: on an average of 5 traces ± (fit) (the residual's σ²) was 2–3.7 times
    too small.  The fit's midline_file read again: each recoil line adds ± (traces), √(σ²
    ratio) times ± (fit); a line says which σ² and the t factor (2.776); the JSON keeps both
    σ², the dof and t95, the CSV se_traces_<observable>; ± (fit) and its note unchanged."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "fitting"))
    from hypothesis_cases import points, spread_for

    from morphoshell.io import Midline

    monkeypatch.chdir(tmp_path)
    p = points()
    Midline(p[:, 0], p[:, 1], spread_for(4e-5), 5).to_csv(tmp_path / "average.csv")
    record = _record(midline_file="average.csv",
                     data_midline={"r": p[:, 0].tolist(), "z": p[:, 1].tolist()},
                     settings={"midline_file": "average.csv", "format": None})
    status, _, data, row = _ablate(tmp_path, record)
    printed = capsys.readouterr().out
    assert status == 0
    scale = np.sqrt(4e-5 / (0.004 ** 2 / (200 - 2)))
    traces = data["fit_error_traces"]
    assert traces["dof"] == 4 and traces["t95"] == pytest.approx(2.7764, abs=1e-4)
    for k in RECOIL:
        # (the same product of the same numbers, through JSON: to round-off)
        assert data[f"se_traces_{k}"] == pytest.approx(data[f"se_{k}"] * scale, rel=1e-12), k
        assert float(row[f"se_traces_{k}"]) == data[f"se_traces_{k}"]
        assert data["units"][f"se_traces_{k}"] == data["units"][k]
        assert re.search(rf"^  {k} +=.*\(fit\) \+- \S+ \S+ \(traces\)$", printed, re.M), k
    assert "  +- (traces): the (fit) errors at sigma^2 from the spread of 5 traces" in printed
    assert "t(0.975, 4) = 2.776" in printed
    assert "traces" not in data["fit_error_note"]
