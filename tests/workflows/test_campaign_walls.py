"""A campaign's fits are looked at for walls that pass through each other (the model has no
self-contact): each record keeps its fit's ``walls_cross``, the summary has the column, each is
warned of by the fit's name and the last line names them, without exit status 3 (the fit is
a true minimum of the model; the shape, not the fit, is in doubt).  No fit was looked at
before (audit 20: only solve(), sweeps, branch diagrams and ablations were)."""
import json
import logging

import pandas as pd
import pytest

import morphoshell.fitting.results as results
from morphoshell.cli import main
from morphoshell.io.timepoints import Timepoint, read_timepoints
from morphoshell.solvers.contact import WallContact
from morphoshell.workflows.campaign_results import CampaignResult, load_campaign, read_records

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
    assert result.walls_unchecked() == [("t01", "unstressed")]


def test_a_resumed_campaign_names_its_reused_fits_that_were_never_checked(data, tmp_path,
                                                                          caplog):
    """Audit 24 F2: a folder written before the check, resumed, reused its fits and its last
    line named no crossing, so an upgrading user read its fits as clean (the same fits made
    afresh crossed).  A note names those reused fits and says how to check them."""
    out = tmp_path / "out"
    args = ["campaign", str(data[0]), "--variants", "flat", "--timepoints", "t01,t02",
            "--nodes", str(NODES), "--workers", "1", "--out", str(out)]
    assert main(args) == 0
    for name in ("t01", "t02"):                   # (as last week's code wrote them)
        path = out / f"{name}_flat.json"
        rec = json.loads(path.read_text())
        del rec["walls_cross"]
        path.write_text(json.dumps(rec))
    with caplog.at_level(logging.INFO, logger="morphoshell"):
        assert main(args) == 0
    notes = [r.getMessage() for r in caplog.records if "before fitted shapes were checked"
             in r.getMessage()]
    assert len(notes) == 1 and notes[0].startswith("2 reused fit(s) ") and \
        "t01_flat, t02_flat; resume=False (--no-resume) refits" in notes[0], notes


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


def test_a_record_whose_walls_cross_is_not_a_crossing_is_named_by_its_file(data, tmp_path,
                                                                          capsys):
    """Audit 23 F7: a campaign record with a broken walls_cross stopped resume and the summary
    with a message naming none of the folder's files; and one with walls farther apart than
    their thickness, or s outside the shell (of the record's problem), read as a crossing.
    Now the file is named when the folder is read (load_campaign, and a resume before any
    fit: exit status 2), as load_fit names its file."""
    name, other = (tp.name for tp in read_timepoints(data[0])[:2])
    problem = {"family": "volvox", "h": 0.15, "cut": 0.0, "opening": 0.3}
    good = {"status": "ok", "E_fit": 0.01, "problem": problem, "walls_cross": CONTACT.to_dict()}
    out = tmp_path / "out"
    out.mkdir()
    (out / f"{name}_free.json").write_text(json.dumps(good))
    assert read_records(out, [(name, "free")])[(name, "free")] == good
    path = out / f"{name}_flat.json"
    for broken, said in [({"s": [1.0], "distance": 0.1, "thickness": 0.2}, "walls_cross = "),
                         ({**CONTACT.to_dict(), "distance": 0.2}, "walls_cross.distance = 0.2"),
                         ({**CONTACT.to_dict(), "s": [0.96, 2.9]}, "in [0, 2.84159]")]:
        path.write_text(json.dumps({**good, "walls_cross": broken}))
        with pytest.raises(ValueError) as exc:
            load_campaign(out, data[0])
        assert str(exc.value).startswith(f"{path}: ") and said in str(exc.value), str(exc.value)
        capsys.readouterr()
        assert main(["campaign", str(data[0]), "--variants", "flat", "--timepoints",
                     f"{name},{other}", "--nodes", str(NODES), "--workers", "1", "--out",
                     str(out)]) == 2
        err = capsys.readouterr().err
        assert f"{path}: " in err and said in err and len(err.strip().splitlines()) == 1, err
        assert not (out / f"{other}_flat.json").exists()       # (before any fit)


def test_a_campaign_reads_each_record_and_builds_its_problem_once_after_its_fits(
        data, tmp_path, monkeypatch):
    """After the fits, the campaign's result and its summary come from one reading of the
    folder, each record's shell built once (its walls_cross checked, read_records): it read
    every record twice there (its result's, then the summary's) and built a Problem at each
    record_contact (the reading before any work, the two after, the list of crossings, the
    warning and the summary's column: 6 a record).  Counted on a resumed run of 2 stored
    fits whose walls cross (wall_contact stubbed), with the reading before any work (one of
    each a record)."""
    import morphoshell.workflows.campaign_results as campaign_results

    monkeypatch.setattr(results, "wall_contact", lambda eq: CONTACT)
    out = tmp_path / "out"
    args = ["campaign", str(data[0]), "--variants", "flat", "--timepoints", "t01,t02",
            "--nodes", str(NODES), "--workers", "1", "--out", str(out)]
    assert main(args) == 0
    reads, builds = [], []
    read, build = campaign_results.read_record, campaign_results.problem_of_record
    monkeypatch.setattr(campaign_results, "read_record", lambda path: reads.append(path) or
                        read(path))
    monkeypatch.setattr(campaign_results, "problem_of_record", lambda *a: builds.append(a) or
                        build(*a))
    assert main(args) == 0
    fits = [path for path in reads if path.name.endswith("_flat.json") and path.exists()]
    assert len(fits) == 2 * 2 and len(builds) == 2 * 2
