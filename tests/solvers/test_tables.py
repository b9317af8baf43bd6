"""Tables: every result converts to a pandas DataFrame and an xarray Dataset, with units."""
import json
import math
import sys

import numpy as np
import pytest

from morphoshell import Problem, ablate, solve
from morphoshell import inverse as I
from morphoshell.mechanics.ablation import UNITS
from morphoshell.solvers.results import FIELD_UNITS, FIELDS

pd = pytest.importorskip("pandas")


@pytest.fixture(scope="module")
def ablation():
    return ablate(Problem("uniform", {"k": 0.0}, h=0.3, cut=0.3, name="toy2"), nodes=40)


@pytest.fixture(scope="module")
def eq(ablation):
    return ablation.post


def test_equilibrium_dataframe_has_one_row_per_point_and_units(eq):
    df = eq.to_dataframe()
    assert list(df.columns) == list(FIELDS) and len(df) == len(eq.s)
    for k in FIELDS:
        np.testing.assert_array_equal(df[k].to_numpy(), getattr(eq, k))
    assert df.attrs["units"] == FIELD_UNITS
    assert df.attrs["units"]["psi"] == "rad" and df.attrs["units"]["r"] == "R"
    assert df.attrs["problem"] == eq.problem.describe()
    assert df.attrs["energy"] == eq.energy and df.attrs["energy_units"] == "C R^2"
    assert "solver" in df.attrs["gauge"]
    json.dumps(df.attrs)                       # plain data: serialisable as it is


def test_the_json_carries_units_as_a_sweeps_does(eq, ablation):
    from morphoshell.solvers.results import Equilibrium

    units = eq.to_dict()["units"]
    assert units == {"energy": "C R^2", "h": "R", "cut": "R", "opening": "R", **FIELD_UNITS}
    assert set(units) >= set(eq.to_dict()["edge_start"])
    assert ablation.to_dict()["units"] == {"h": "R", "cut": "R", **UNITS}
    # the docstring said the moments were in units of C
    assert FIELD_UNITS["M_s"] == FIELD_UNITS["M_phi"] == "C R"
    assert "∂e/∂K_a (units of C R)" in Equilibrium.__doc__


def test_equilibrium_xarray_has_s_as_coordinate_and_the_problem_in_attrs(eq, tmp_path):
    xr = pytest.importorskip("xarray")
    ds = eq.to_xarray()
    assert isinstance(ds, xr.Dataset)
    assert list(ds.coords) == ["s"] and ds["s"].attrs["units"] == "R"
    np.testing.assert_array_equal(ds["s"].values, eq.s)
    assert set(ds.data_vars) == set(FIELDS) - {"s"}
    np.testing.assert_array_equal(ds["psi"].values, eq.psi)
    assert ds["psi"].attrs["units"] == "rad" and ds["psi"].dims == ("s",)
    assert ds.attrs["family"] == "uniform" and ds.attrs["cut"] == 0.3
    assert ds.attrs["param_k"] == 0.0 and ds.attrs["energy"] == eq.energy
    assert json.loads(ds.attrs["problem"]) == eq.problem.describe()
    for v in ds.attrs.values():                # netCDF-valid attributes: strings and numbers
        assert isinstance(v, (str, int, float))
    # labelled selection by the material coordinate
    assert float(ds["r"].sel(s=eq.s[3])) == eq.r[3]
    # and it can be written and read back (scipy's netCDF3 writer)
    path = tmp_path / "eq.nc"
    ds.to_netcdf(path, engine="scipy")
    back = xr.open_dataset(path, engine="scipy")
    np.testing.assert_allclose(back["z"].values, eq.z)
    assert back.attrs["family"] == "uniform"
    back.close()


def test_ablation_dataframe_is_one_row_of_problem_and_observables(ablation):
    df = ablation.to_dataframe()
    assert len(df) == 1
    row = df.iloc[0]
    assert row["family"] == "uniform" and row["cut"] == 0.3 and row["opening_P"] == 0.0
    assert row["k"] == 0.0 and row["h"] == 0.3
    for key, value in ablation.observables().items():
        assert row[key] == value
    assert df.attrs["units"]["rotation"] == "rad" and df.attrs["units"]["opening"] == "R"
    assert set(UNITS) <= set(df.attrs["units"])
    assert "far-end" in df.attrs["gauge"]
    # a sweep is a concatenation of rows
    both = pd.concat([df, df], ignore_index=True)
    assert len(both) == 2


def test_ablation_xarray_holds_observables_and_both_states(ablation):
    pytest.importorskip("xarray")
    ds = ablation.to_xarray()
    assert float(ds["rotation"]) == ablation.rotation and ds["rotation"].attrs["units"] == "rad"
    assert ds["r_pre"].dims == ("s_pre",) and ds["r_post"].dims == ("s_post",)
    np.testing.assert_array_equal(ds["s_post"].values, ablation.post.s)
    np.testing.assert_array_equal(ds["psi_pre"].values, ablation.pre.psi)
    assert ds.attrs["cut"] == 0.3 and "far-end" in ds.attrs["gauge"]


def test_inverse_result_tables():
    m = I.Measurement("A", 40.0, 11.0, 8.0, opening_um=0.5, rotation_deg=15.0,
                      displacement_um=1.5, V_um_per_s=0.9)
    res = I.estimate([m], methods=("leading_order", "kelvin"), bootstrap=0, workers=1)
    df = res.to_dataframe()
    assert list(df["embryo"]) == ["A"] and df["cut_rad"].iloc[0] == pytest.approx(m.cut)
    assert df.attrs["units"]["k_rotation_kelvin"] == "1/R"
    assert df.attrs["units"]["cut_rad"] == "rad"
    assert math.isfinite(df["k_rotation_kelvin"].iloc[0])
    pytest.importorskip("xarray")
    ds = res.to_xarray()
    assert list(ds.coords) == ["embryo"]
    assert float(ds["k_rotation_kelvin"].sel(embryo="A")) == df["k_rotation_kelvin"].iloc[0]
    assert ds.attrs["theory"] == "large_bending"


def test_to_xarray_without_xarray_names_the_extra(eq, monkeypatch):
    monkeypatch.setitem(sys.modules, "xarray", None)      # import xarray now fails
    with pytest.raises(ImportError, match=r"pip install 'morphoshell\[xarray\]'"):
        eq.to_xarray()
