"""A campaign's results (workflows/campaign_results.py) at a glance and as a grid: records made
by hand (no fitting), one fit of each kind: converged, stopped short, failed, missing."""
import json
from pathlib import Path

import numpy as np
import pytest

from morphoshell.workflows import CampaignResult, Timepoint

TIMEPOINTS = (Timepoint("t01", 0.0, "a.csv"), Timepoint("t02", 0.5, "b.csv"),
              Timepoint("t10", 1.0, "c.csv"))


def _record(E_fit: float, converged: bool, **extra) -> dict:
    return {"status": "ok", "E_fit": E_fit, "converged": converged, "nodes": 60,
            "method": "gradient", "constrained": [], "standard_errors": {"f1": 0.01, "s2": None},
            "parameters": {"f1": 0.9, "kappa2": -8.0, "s2": 1.6, "h": 0.15}, **extra}


@pytest.fixture
def result() -> CampaignResult:
    records = {("t01", "flat"): _record(0.01, True, walls_cross=None),
               ("t02", "flat"): _record(0.02, False, walls_cross=None),
               ("t01", "free"): {"status": "failed", "message": "no start solved"},
               ("t10", "free"): _record(0.03, True)}        # (written before walls_cross)
    return CampaignResult(Path("out/fits"), TIMEPOINTS, ("flat", "free"), records)


def test_a_campaign_is_one_line_when_echoed(result):
    """Audit 21 F11: the repr held every record (135 000 characters for 3 fits)."""
    assert repr(result) == ("CampaignResult(out/fits, 3 timepoints x 2 variants, 4 fits, "
                            "1 failed, 1 not converged)")


def test_a_campaign_is_a_grid_of_timepoints_and_variants(result, tmp_path):
    """Audit 21 F14: the docs said every result converts to an xarray Dataset; a campaign
    did not.  It is the summary on (timepoint, variant), in the campaign's order (t10 after
    t02, not sorted as text), pseudotime along timepoint, units attached; NaN or "" where a
    fit has no value; flags bool where every fit has one, else 1/0/NaN.  It survives netCDF."""
    import xarray as xr

    ds = result.to_xarray()
    assert list(ds.timepoint.values) == ["t01", "t02", "t10"]
    assert list(ds.variant.values) == ["flat", "free"]
    assert ds.pseudotime.values.tolist() == [0.0, 0.5, 1.0]
    assert np.array_equal(ds.E_fit.values, [[0.01, np.nan], [0.02, np.nan], [np.nan, 0.03]],
                          equal_nan=True)
    assert ds.E_fit.attrs["units"] == "R" and ds.kappa2.attrs["units"] == "1/R"
    assert ds.se_f1.attrs["units"] == "1" and "units" not in ds.status.attrs
    assert ds.status.values.tolist() == [["ok", "failed"], ["ok", ""], ["", "ok"]]
    # converged: the failed fit's row says False, the missing ones have none
    assert np.array_equal(ds.converged.values, [[1, 0], [0, np.nan], [np.nan, 1]],
                          equal_nan=True)
    assert np.isnan(ds.se_s2.values).all()          # (null: on a constraint)
    assert json.loads(ds.attrs["settings"]) == {} and ds.attrs["out"] == "out/fits"
    complete = CampaignResult(result.out, TIMEPOINTS[:1], ("flat",),
                              {("t01", "flat"): result.records[("t01", "flat")]}).to_xarray()
    assert complete.converged.dtype == bool and complete.walls_cross.dtype == bool
    ds.to_netcdf(tmp_path / "campaign.nc")
    assert xr.load_dataset(tmp_path / "campaign.nc").identical(ds)


def _folder(tmp_path, data) -> Path:
    """An output folder recording the data folder ``data``, with t01's flat record."""
    out = tmp_path / "out"
    out.mkdir()
    (out / "campaign_settings.json").write_text(json.dumps({"data": str(data), "nodes": 60}))
    (out / "t01_flat.json").write_text(json.dumps(_record(0.01, True, walls_cross=None)))
    return out


def test_load_campaign_reads_the_data_folder_the_campaign_recorded(tmp_path):
    """Audit 27 F11: load_campaign(out) needed the data folder that out records."""
    from morphoshell.workflows.campaign_results import load_campaign

    data = Path(__file__).resolve().parents[2] / "data" / "synthetic_inversion"
    loaded = load_campaign(_folder(tmp_path, data))
    assert [tp.name for tp in loaded.timepoints][:2] == ["t01", "t02"]
    assert set(loaded.records) == {("t01", "flat")}


@pytest.mark.parametrize("settings, said", [
    ({"data": "/no/such/folder"}, r"the recorded data folder /no/such/folder is not there"),
    ({"nodes": 60}, r"no data folder recorded"),
])
def test_load_campaign_without_its_data_folder_says_so(tmp_path, settings, said):
    from morphoshell.workflows.campaign_results import load_campaign

    out = _folder(tmp_path, "/x")
    (out / "campaign_settings.json").write_text(json.dumps(settings))
    with pytest.raises(ValueError, match=r"campaign_settings.json: " + said +
                       r".*load_campaign\(out, data_dir\)"):
        load_campaign(out)


def test_a_timepoints_average_by_name_for_the_fits_errors(tmp_path):
    """Audit 28 F2: the average a campaign's fits were made to (for fit_uncertainty's σ² of
    the traces), by timepoint or name; an unknown name refused naming the campaign's."""
    from morphoshell.workflows.campaign_results import load_campaign

    data = Path(__file__).resolve().parents[2] / "data" / "synthetic_inversion"
    loaded = load_campaign(_folder(tmp_path, data))
    by_name, by_tp = loaded.midline("t01"), loaded.midline(loaded.timepoints[0])
    assert by_name.n_traces == 5 and by_name.spread is not None
    assert np.array_equal(by_name.r, by_tp.r)
    with pytest.raises(ValueError, match=r"timepoint t99: not one of the campaign's \(t01, t02"):
        loaded.midline("t99")
