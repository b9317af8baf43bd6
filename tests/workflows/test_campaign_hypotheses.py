"""A campaign's summary and last lines test each timepoint's hypotheses against its free fit
(workflows/campaign_results.py, cli/campaign.py; audit 25 F1: the lowest E_fit named a
winner the data do not single out).  Records made by hand, no fitting."""
import math
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "fitting"))
from hypothesis_cases import AUDIT_SIGMA2, audit_fits, fit_of, points, spread_for  # noqa: E402

from morphoshell.cli.campaign import _hypothesis_lines  # noqa: E402
from morphoshell.io import Midline  # noqa: E402
from morphoshell.io.timepoints import Timepoint  # noqa: E402
from morphoshell.workflows.campaign_results import CampaignResult, column_unit  # noqa: E402

VARIANTS = ("free", "flat", "undeformed", "unstressed")


def _record(fit) -> dict:
    return {**fit.to_dict(), "status": "ok", "nodes": 60}


@pytest.fixture
def result(tmp_path) -> CampaignResult:
    """t01: the audit's four fits and its five traces' σ²; t02: σ² a hundredth of it (only
    flat consistent); t03: a failed free fit (no test)."""
    tps = tuple(Timepoint(n, t, f"{n}.csv") for n, t in (("t01", 0.0), ("t02", 0.5),
                                                        ("t03", 1.0)))
    p = points()
    for name, sigma2 in (("t01", AUDIT_SIGMA2), ("t02", AUDIT_SIGMA2 / 100),
                         ("t03", AUDIT_SIGMA2)):
        Midline(p[:, 0], p[:, 1], spread_for(sigma2), 5).to_csv(tmp_path / f"{name}.csv")
    fits = audit_fits()
    records = {(t, v): _record(fits[v]) for t in ("t01", "t02") for v in VARIANTS}
    records[("t03", "free")] = {"status": "failed", "message": "no start solved"}
    records[("t03", "flat")] = _record(fit_of("flat", 0.004))
    return CampaignResult(tmp_path, tps, VARIANTS, records, data_dir=tmp_path)


def test_the_summary_has_each_fits_verdict(result):
    """Existing columns stay; the test's four come last: ΔS/σ², threshold, verdict, noise."""
    df = result.to_dataframe()
    assert list(df.columns[-4:]) == ["delta_S_over_sigma2", "hypothesis_threshold",
                                     "hypothesis_test", "hypothesis_noise"]
    assert list(df.columns[:5]) == ["timepoint", "pseudotime", "variant", "status", "E_fit"]
    cell = {(r.timepoint, r.variant): r for r in df.itertuples()}
    assert [cell[("t01", v)].hypothesis_test for v in VARIANTS] == [
        "reference", "consistent", "consistent", "consistent"]
    assert [cell[("t02", v)].hypothesis_test for v in VARIANTS] == [
        "reference", "consistent", "rejected", "rejected"]
    # (audit 25's ratios, to its printed digits; F(1, 4) from five traces)
    assert cell[("t01", "undeformed")].delta_S_over_sigma2 == pytest.approx(0.208, abs=5e-4)
    assert cell[("t01", "flat")].hypothesis_threshold == pytest.approx(7.7086, abs=1e-4)
    assert cell[("t01", "flat")].hypothesis_noise == "traces"
    assert cell[("t03", "flat")].hypothesis_test == ""
    assert math.isnan(cell[("t03", "flat")].delta_S_over_sigma2)
    assert column_unit("delta_S_over_sigma2") == "1" == column_unit("hypothesis_threshold")


def test_without_the_data_folder_sigma2_is_the_residuals(result):
    """A result without its data set: σ² from the free fit's residual, said in the column."""
    bare = CampaignResult(result.out, result.timepoints, result.variants, result.records)
    assert set(bare.to_dataframe().hypothesis_noise) == {"residual", ""}


def test_the_last_lines_say_which_hypotheses_the_data_tell_apart(result):
    lines = _hypothesis_lines(result)
    assert lines[0].startswith("hypotheses against free")
    assert lines[1].startswith("  t01: the data do not tell flat, undeformed, unstressed apart")
    assert "flat 0.0296/7.71" in lines[1] and "sigma^2 from the traces" in lines[1]
    assert lines[2].startswith("  t02: only flat is consistent with the data; rejected: "
                               "undeformed, unstressed")
    assert lines[3] == "  t03: not tested (1 finished fit(s))"
    no_free = CampaignResult(result.out, result.timepoints, VARIANTS[1:], result.records,
                             data_dir=result.data_dir)
    assert _hypothesis_lines(no_free)[0].startswith("hypotheses: not tested (the test of each "
                                                    "against the data needs the free fit")


def test_a_fit_kept_ok_but_not_converged_is_not_rejected(result):
    """Audit 28 F1: a campaign keeps an unconverged fit with status "ok"; t02's unstressed
    (rejected when converged) stopped short: its summary cell and its timepoint's line say
    not established, and why."""
    rec = result.records[("t02", "unstressed")]
    rec.update(converged=False, stop="Maximum_Evaluations_Exceeded")
    cell = {(r.timepoint, r.variant): r for r in result.to_dataframe().itertuples()}
    assert [cell[("t02", v)].hypothesis_test for v in VARIANTS] == [
        "reference", "consistent", "rejected", "not established"]
    line = next(x for x in _hypothesis_lines(result) if x.startswith("  t02:"))
    assert "not established: unstressed (unstressed's fit did not converge" in line
    assert "unstressed 33.4/7.71" in line
