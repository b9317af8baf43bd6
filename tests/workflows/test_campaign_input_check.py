"""A campaign's records carry ``morphoshell fit``'s verdict on a fit far above what the model
leaves of a traced midline (``input_check``), its summary has the column and its last line
names the fits; exit status 3 only where a timepoint's best fit has it (audit 15, F2: 6 of
12 fits at 0.1-0.63 R, "all 12 fits converged", no word)."""
import json

import pandas as pd

import morphoshell.fitting.midline_checks as checks
from morphoshell.cli import main
from morphoshell.io.timepoints import Timepoint
from morphoshell.workflows import campaign
from morphoshell.workflows.campaign_results import CampaignResult

NODES = 60
VARIANTS = ("flat", "undeformed")


def _last_line(capsys) -> str:
    return capsys.readouterr().out.strip().splitlines()[-1]


def test_the_best_fit_of_a_timepoint_decides_the_exit_status():
    """A wrong hypothesis may fit badly (no exit 3); a timepoint whose lowest E_fit among the
    fits that finished is far above has no variant that describes its data (exit 3)."""
    tps = tuple(Timepoint(n, t, f"{n}.csv") for n, t in (("t01", 0.0), ("t02", 0.5)))
    records = {("t01", "flat"): {"status": "ok", "E_fit": 0.05},
               ("t01", "undeformed"): {"status": "ok", "E_fit": 0.3},
               ("t02", "flat"): {"status": "failed", "message": "no E_fit"},
               ("t02", "undeformed"): {"status": "ok", "E_fit": 0.2}}
    result = CampaignResult(None, tps, VARIANTS, records)
    assert result.far_above() == [("t01", "undeformed"), ("t02", "undeformed")]
    assert result.best_far_above() == [("t02", "undeformed")]


def test_records_summary_and_last_line_carry_the_fits_input_check(data, tmp_path, capsys,
                                                                  monkeypatch):
    """Every fit far above (threshold 0 here): each record's input_check is fit's verdict,
    the summary has it, the last line names them and, each timepoint's best fit among
    them, exits 3 (0 with --allow-failures)."""
    monkeypatch.setattr(checks, "IMPLAUSIBLE_E_FIT", 0.0)
    out = tmp_path / "out"
    args = ["campaign", str(data[0]), "--variants", ",".join(VARIANTS), "--timepoints",
            "t01,t02", "--nodes", str(NODES), "--workers", "1", "--out", str(out)]
    assert main(args) == 3
    last = _last_line(capsys)
    assert last.startswith("all 4 fits converged; 4 fit far above what the model leaves of a "
                           "traced midline (check the input or the hypothesis): t01_flat, "
                           "t01_undeformed, t02_flat, t02_undeformed; 2 of them the best fit "
                           "of a timepoint (no variant describes its data: check the input): "
                           "t01_flat, t02_flat"), last
    assert last.endswith("exit status 3, --allow-failures for 0)")
    summary = pd.read_csv(out / "campaign_summary.csv", keep_default_na=False)
    for name in ("t01", "t02"):
        for v in VARIANTS:
            rec = json.loads((out / f"{name}_{v}.json").read_text())
            assert rec["input_check"] == checks.input_check(rec["E_fit"])    # (fit's verdict)
            assert rec["input_check"].startswith("E_fit is far above what the model leaves")
            row = summary[(summary.timepoint == name) & (summary.variant == v)]
            assert list(row.input_check) == [rec["input_check"]]
    assert main([*args, "--allow-failures"]) == 0
    assert _last_line(capsys).endswith("(--allow-failures: exit status 0)")


def test_a_losing_hypothesis_far_above_is_named_with_exit_0_and_old_records_get_it(
        data, tmp_path, capsys, monkeypatch):
    """The threshold between each timepoint's best fit and a worse one: only the worse are
    named, exit 0.  Records of a folder written before input_check get it on resume without
    a refit (a label: the digest that chains the fits leaves it out)."""
    out = tmp_path / "out"
    first = campaign(data[0], VARIANTS, workers=1, out=out, nodes=NODES,
                     timepoints=("t01", "t02"))
    e_fit = {key: rec["E_fit"] for key, rec in first.records.items()}
    best = max(min(e_fit[(t, v)] for v in VARIANTS) for t in ("t01", "t02"))
    worse = sorted(key for key, e in e_fit.items() if e > best)
    assert worse, e_fit                 # (undeformed fits the flat-generated data worse)
    for path in out.glob("t0*.json"):   # as a folder before input_check wrote them
        rec = json.loads(path.read_text())
        del rec["input_check"]
        path.write_text(json.dumps(rec, indent=1, sort_keys=True) + "\n")
    monkeypatch.setattr(checks, "IMPLAUSIBLE_E_FIT", best)
    assert main(["campaign", str(data[0]), "--variants", ",".join(VARIANTS), "--timepoints",
                 "t01,t02", "--nodes", str(NODES), "--workers", "1", "--out", str(out)]) == 0
    out_text = capsys.readouterr().out
    assert "4 reused" in out_text and "0 failed" in out_text
    named = ", ".join(f"{t}_{v}" for t, v in worse)
    assert out_text.strip().splitlines()[-1] == (
        f"all 4 fits converged; {len(worse)} fit far above what the model leaves of a traced "
        f"midline (check the input or the hypothesis): {named}")
    for (name, v), e in e_fit.items():
        rec = json.loads((out / f"{name}_{v}.json").read_text())
        assert (rec["input_check"] is not None) == ((name, v) in worse)
