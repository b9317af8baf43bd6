"""A campaign's fits are looked at for walls that pass through each other (the model has no
self-contact): each record keeps its fit's ``walls_cross``, the summary has the column, each is
warned of by the fit's name and the last line names them, without exit status 3 (the fit is
a true minimum of the model; the shape, not the fit, is in doubt).  No fit was looked at
before (audit 20: only solve(), sweeps, branch diagrams and ablations were)."""
import json
import logging

import pandas as pd

import morphoshell.fitting.results as results
from morphoshell.cli import main
from morphoshell.io.timepoints import Timepoint
from morphoshell.solvers.contact import WallContact
from morphoshell.workflows.campaign_results import CampaignResult

NODES = 60
#: A contact as wall_contact gives one (the fold shell's, tests/solvers/test_contact.py).
CONTACT = WallContact((0.96, 2.57), 0.064, 0.166)


def test_the_summary_and_the_list_take_walls_cross_from_the_records(tmp_path):
    """A record with a contact is named; null, a failed fit and a record written before the
    check (no entry) are not; the column is False for null, None (an empty cell) where no
    shape was checked."""
    tps = (Timepoint("t01", 0.0, "t01.csv"),)
    variants = ("flat", "undeformed", "unstressed", "free")
    records = {("t01", "flat"): {"status": "ok", "E_fit": 0.01,
                                 "walls_cross": CONTACT.to_dict()},
               ("t01", "undeformed"): {"status": "ok", "E_fit": 0.01, "walls_cross": None},
               ("t01", "unstressed"): {"status": "ok", "E_fit": 0.01},
               ("t01", "free"): {"status": "failed", "message": "no start solved"}}
    result = CampaignResult(tmp_path, tps, variants, records)
    assert result.walls_cross() == [("t01", "flat")]
    assert result.to_dataframe().walls_cross.tolist() == [True, False, None, None]


def test_a_campaign_warns_of_its_fits_whose_walls_cross_and_exits_0(data, tmp_path, capsys,
                                                                    caplog, monkeypatch):
    """Every fitted shape taken for crossing (wall_contact stubbed): each record keeps the
    contact, the summary says True, one warning per fit names it as an ablation's do
    (``t01_flat, ...``), and the last line adds the names to 'all 2 fits converged' with
    exit status 0."""
    monkeypatch.setattr(results, "wall_contact", lambda eq: CONTACT)
    out = tmp_path / "out"
    with caplog.at_level(logging.WARNING, logger="morphoshell"):
        assert main(["campaign", str(data[0]), "--variants", "flat", "--timepoints", "t01,t02",
                     "--nodes", str(NODES), "--workers", "1", "--out", str(out)]) == 0
    last = capsys.readouterr().out.strip().splitlines()[-1]
    assert last == ("all 2 fits converged; 2 fitted shapes whose walls pass through each other "
                    "(the model has no self-contact: not physical shapes): t01_flat, t02_flat")
    warned = [r.getMessage() for r in caplog.records if "walls pass through" in r.getMessage()]
    assert [w.split(":")[0] for w in warned] == ["t01_flat, fitted shell", "t02_flat, fitted shell"]
    assert all(CONTACT.describe() in w for w in warned), warned
    summary = pd.read_csv(out / "campaign_summary.csv")
    assert summary.walls_cross.tolist() == [True, True]
    for name in ("t01", "t02"):
        rec = json.loads((out / f"{name}_flat.json").read_text())
        assert rec["walls_cross"] == CONTACT.to_dict()
