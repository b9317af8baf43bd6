"""``morphoshell compare``: the hypotheses on κ₁ of fits of one midline tested against the free
fit, σ² from the traces of the midline file the fits name (audit 25 F1); bad input exit 2."""
import json
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "fitting"))
from hypothesis_cases import AUDIT_SIGMA2, audit_fits, points, retraced, spread_for  # noqa: E402

from morphoshell.cli import main  # noqa: E402
from morphoshell.io import Midline  # noqa: E402


@pytest.fixture
def fits(tmp_path, monkeypatch) -> list[str]:
    """The audit's four fit JSONs in tmp_path, naming average.csv (five traces) as the fits'
    midline, run from tmp_path (the records' paths are relative to where fit ran)."""
    monkeypatch.chdir(tmp_path)
    p = points()
    Midline(p[:, 0], p[:, 1], spread_for(AUDIT_SIGMA2), 5).to_csv(tmp_path / "average.csv")
    settings = {"midline_file": "average.csv", "format": None, "section": "auto",
                "pixel_size_um": None, "radius_um": None, "roi": None}
    names = []
    for variant, fit in audit_fits().items():
        record = {**fit.to_dict(), "midline_file": "average.csv", "settings": settings,
                  "solver": {"nodes": 200, "stages": 2, "method": "direct"}}
        names.append(f"fit_{variant}.json")
        (tmp_path / names[-1]).write_text(json.dumps(record))
    return names


def test_compare_prints_the_verdict_and_writes_json_and_csv(fits, tmp_path, capsys):
    assert main(["compare", *fits, "--json", "c.json", "--csv", "c.csv"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith("sigma^2 = 6.48e-06 R^2 from the spread of 5 traces")
    assert "F(1, 4)" in out[0]
    assert out[3].split() == ["flat", "0.00349052", "12", "1.92e-07", "0.0296", "7.71",
                              "consistent"]
    assert out[6].startswith("the data do not tell flat, undeformed, unstressed apart")
    data = json.loads((tmp_path / "c.json").read_text())
    assert data["sigma2_source"] == "traces" and data["dof"] == 4
    assert [h["verdict"] for h in data["hypotheses"]] == ["reference"] + ["consistent"] * 3
    assert (tmp_path / "c.csv").read_text().splitlines()[0] == (
        "name,variant,E_fit,fitted,restrictions,delta_S,delta_S_over_sigma2,threshold,verdict,"
        "converged,stop")


def test_compare_without_the_midline_file_takes_the_residual(fits, tmp_path, capsys):
    """The file gone: a note, σ² from the residual (χ²₁): undeformed and unstressed rejected,
    with the caveat that this noise is too small for a traced midline."""
    (tmp_path / "average.csv").unlink()
    assert main(["compare", *fits]) == 0
    out = capsys.readouterr().out
    assert out.startswith("note: average.csv (the fits' midline_file) is not a file here")
    assert "only flat is consistent with the data; rejected: undeformed, unstressed" in out
    assert "a rejection may be that noise" in out


def test_compare_of_one_image_traces_fits_scales_the_residual(fits, tmp_path, capsys):
    """The fits of one image trace (fit --pixel-size: the free fit's record carries its
    re-tracings): σ² is the residual's times κ₁'s factor, as its profile, and the line and
    the JSON say so; at a factor of 9 none of the three is rejected (the residual alone
    rejected undeformed and unstressed)."""
    (tmp_path / "average.csv").unlink()
    record = json.loads((tmp_path / "fit_free.json").read_text())
    free = retraced(audit_fits()["free"], {"kappa1": 9.0})
    (tmp_path / "fit_free.json").write_text(json.dumps({**record, **free.to_dict()}))
    assert main(["compare", *fits, "--json", "c.json"]) == 0
    out = capsys.readouterr().out
    assert "from the free fit's residual times 9, kappa1's (SE of its trace's re-tracings" in out
    assert "a rejection may be" not in out and "rejected" not in out
    data = json.loads((tmp_path / "c.json").read_text())
    assert data["sigma2_source"] == "residual, scaled by the trace's re-tracings"
    assert data["sigma2_inflation"] == {"parameter": "kappa1", "factor": 9.0}


@pytest.mark.parametrize("edit, args, message", [
    (None, ["--noise", "traces", "--midline", "nope.csv"], "--midline nope.csv: not a file"),
    ("flat", [], "fit_flat.json was fitted on 100 nodes, fit_free.json on 200"),
    (None, ["fit_free.json"], "fit_free.json is named twice"),
    (None, ["./fit_free.json"], "./fit_free.json is named twice (as fit_free.json)"),
])
def test_compare_refuses_mixed_fits_in_one_line(fits, tmp_path, capsys, edit, args, message):
    if edit:
        path = tmp_path / f"fit_{edit}.json"
        record = json.loads(path.read_text())
        record["solver"]["nodes"] = 100
        path.write_text(json.dumps(record))
    assert main(["compare", *fits, *args]) == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1, err


def test_compare_of_a_fit_that_stopped_gives_no_verdict_and_exit_3(fits, tmp_path, capsys):
    """Audit 28 F1: a hypothesis fit that stopped short (fit --max-evaluations 3) was
    "rejected", exit 0.  Now its row and the summary say not established and why, the JSON
    keeps converged and stop, and the exit status is 3 (a fit not converged)."""
    path = tmp_path / "fit_undeformed.json"
    record = json.loads(path.read_text())
    record.update(converged=False, stop="Maximum_Evaluations_Exceeded", E_fit=0.08)
    path.write_text(json.dumps(record))
    assert main(["compare", *fits, "--json", "c.json"]) == 3
    out = capsys.readouterr().out
    assert "not established (fit not converged: Maximum_Evaluations_Exceeded)" in out
    assert "not established: undeformed (undeformed's fit did not converge" in out
    assert "rejected" not in out
    row = json.loads((tmp_path / "c.json").read_text())["hypotheses"][2]
    assert (row["verdict"], row["converged"]) == ("not established", False)
