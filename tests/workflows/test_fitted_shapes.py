"""Numerical ablations of fitted shapes (workflows/fitted_shapes.py): both shells are looked
at for walls that pass through each other, which the continuation in Σ never did (it does
not go through solve(), whose check it was: audit 19, F1, the unconverged flat t07 fit's
post-ablation shell, walls 0.003 R apart against a thickness of 0.13 R, unwarned)."""
import logging
from dataclasses import replace
from pathlib import Path

import pytest

from morphoshell import ablate, solve
from morphoshell.io.problem_files import example_path, load_problem
from morphoshell.workflows import numerical_ablation

FOLD = Path(__file__).resolve().parents[1] / "data" / "volvox_fold.toml"
NODES = 100


def _contact_warnings(caplog) -> list[str]:
    return [r.getMessage() for r in caplog.records if r.name.endswith("solvers.contact")]


def test_an_ablation_whose_walls_pass_through_each_other_is_flagged_naming_it(caplog):
    """The documented fold shell (tests/test_contact.py: walls 0.06 R apart, 0.17 R thick),
    ablated: both its shells overlap, each is recorded and warned of by the problem's name
    and state, after the cut as well as before."""
    problem, _ = load_problem(FOLD)
    with caplog.at_level(logging.WARNING, logger="morphoshell"):
        num = numerical_ablation(problem, 0.15, nodes=NODES)
    assert num.walls_cross
    for key in ("pre", "post"):
        assert num.contacts[key].overlaps, key
        assert num.contacts[key].distance < 0.1 < num.contacts[key].thickness
    warned = _contact_warnings(caplog)
    assert any(w.startswith("volvox_fold, post-ablation (Σ = 0.15) shell: the shell's walls "
                            "pass through each other") for w in warned), warned
    assert any(w.startswith("volvox_fold, intact (pre-ablation) shell") for w in warned), warned


def test_an_ordinary_ablation_has_no_contact_and_no_warning(caplog):
    problem, _ = load_problem(example_path("toy2_ablation"))
    with caplog.at_level(logging.WARNING, logger="morphoshell"):
        num = numerical_ablation(problem, 0.3, nodes=NODES)
    assert num.contacts == {"pre": None, "post": None} and not num.walls_cross
    assert not _contact_warnings(caplog)


def test_a_numerical_ablation_is_its_ablations_table_with_its_checks(tmp_path):
    """Audit 21 F14: a NumericalAblation had no table.  Its DataFrame is its ablation's row
    (the problem, the observables and their errors, as ablate --csv writes them) with steps,
    rejected, cold_difference and walls_cross; its Dataset the ablation's with them among
    its attributes, netCDF-ready."""
    import xarray as xr

    problem, _ = load_problem(example_path("toy2_ablation"))
    num = numerical_ablation(problem, 0.3, nodes=NODES)
    df, row = num.to_dataframe(), num.ablation.to_dataframe()
    assert list(df.columns) == [*row.columns, "steps", "rejected", "cold_difference",
                                "walls_cross"]
    assert df[row.columns].equals(row) and df.attrs["units"] == row.attrs["units"]
    assert df.steps[0] == num.steps and df.cold_difference[0] == num.cold_difference
    assert "energy_released_error" in df and not df.walls_cross[0]
    ds = num.to_xarray()
    assert ds.attrs["steps"] == num.steps and ds.attrs["walls_cross"] == 0
    assert ds.attrs["cold_difference"] == num.cold_difference
    assert ds.rotation.item() == num.ablation.rotation and ds.rotation.attrs["units"] == "rad"
    ds.to_netcdf(tmp_path / "ablation.nc")
    assert xr.load_dataset(tmp_path / "ablation.nc").identical(ds)


def _ablation_warnings(caplog) -> list[str]:
    return [r.getMessage() for r in caplog.records if r.name.endswith("mechanics.ablation")]


def test_a_numerical_ablation_has_ablates_estimates_and_warns_as_it_does(caplog):
    """Audit 21 F17: ablate() warned of a fitted shell's energy_released on 100 nodes while
    numerical_ablation(), on the same numbers, made no estimate and said nothing.  Both now
    estimate from the same levels and warn by one rule (ablation_of).  The Volvox example,
    cut 0.15, 100 nodes: energy_released 3.4 % off (against 1600 nodes), estimated at 2.3 of
    its value: one warning each, the same.  The errors agree to 1e-8 relative: the same
    equilibria (reached by continuation in the cut, or in the parameters), converged to
    the solver's tol, 1e-10 (measured: 1e-12)."""
    problem = load_problem(example_path("volvox_inversion"))[0]
    with caplog.at_level(logging.WARNING, logger="morphoshell"):
        num = numerical_ablation(problem, 0.15, nodes=NODES, cold=False)
        numerical = _ablation_warnings(caplog)
        caplog.clear()
        ab = ablate(problem.with_updates(cut=0.15), nodes=NODES)
        direct = _ablation_warnings(caplog)
    assert num.ablation.error_note == "" and set(num.ablation.errors) == set(ab.errors)
    for key, error in ab.errors.items():
        assert num.ablation.errors[key] == pytest.approx(error, rel=1e-8), key
    assert len(numerical) == 1 and numerical == direct
    assert numerical[0].startswith("the error estimates of the ablation's energy_released (2.3)")
    assert "may not resolve the cut" in numerical[0]


def test_a_numerical_ablation_from_a_carried_start_is_estimated_too(caplog):
    """A ``pre`` carried over (a campaign's fitted state: no levels of its own) is estimated
    on its anchored mesh as solve() would; toy problem 2 (every relative estimate below
    1e-4 on 100 nodes) warns of nothing."""
    problem, _ = load_problem(example_path("toy2_ablation"))
    start = solve(problem.with_updates(cut=0.0), nodes=NODES)
    with caplog.at_level(logging.WARNING, logger="morphoshell"):
        num = numerical_ablation(problem, 0.3, nodes=NODES, pre=replace(start, error=None),
                                 cold=False)
    assert [eq.solver.nodes for eq in num.ablation.pre.error.levels] == [50, 25]
    assert max(num.ablation.relative_errors().values()) < 1e-4
    assert not _ablation_warnings(caplog)


def test_what_is_not_a_problem_is_refused_naming_it():
    """A user audit: numerical_ablation("x") raised "'str' object has no attribute 'end'"."""
    with pytest.raises(TypeError, match=r"^problem = 'x' must be a morphoshell Problem"):
        numerical_ablation("x", cut=0.1)


@pytest.mark.parametrize("change, error, message", [
    ({"cut": "0.1"}, ValueError, r"^cut = '0\.1' must be a real number$"),
    ({"pre": "x"}, TypeError, r"^pre = 'x' must be an Equilibrium or fitted_state\(record\) "
                              r"\(fields s, r, psi, f_s\), not str$"),
    ({"cold": "no"}, TypeError, r"^cold = 'no' must be True or False$"),
    ({"nodes": 99999}, ValueError, r"^nodes = 99999 must be an integer in \[20, 3200\]$"),
    ({"nodes": 10}, ValueError, r"^nodes = 10 must be an integer in \[20, 3200\]$"),
])
def test_each_argument_is_refused_naming_it_before_any_work(monkeypatch, change, error,
                                                             message):
    """Audit 23 F9: cut='0.1' raised "'<' not supported", pre='x' "'str' object has no
    attribute 's'", cold='no' solved cold (a string is true), and nodes=99999 (within
    solve()'s [5, 102400]) died of std::bad_alloc after 89 s.  Each is refused before any
    solve (which here would fail the test), nodes in the fits' range (FIT_NODES)."""
    import morphoshell.workflows.fitted_shapes as module

    def no_work(*args, **kwargs):
        raise AssertionError("solved before the arguments were checked")
    monkeypatch.setattr(module, "solve", no_work)
    monkeypatch.setattr(module, "solve_from", no_work)
    problem, _ = load_problem(example_path("toy2_ablation"))
    with pytest.raises(error, match=message):
        numerical_ablation(problem, **{"cut": 0.3, "nodes": NODES, "pre": None, **change})


def test_a_fit_solved_again_onto_another_shape_is_warned_of(caplog):
    """Audit 24 F4: `solve FIT.json` and `ablate FIT.json` solve the fitted parameters from
    the stress-free shell, which for a campaign's t08 free fit ended on another equilibrium
    1.02 R from the fitted midline, without a word.  off_the_fit measures the distance of
    the re-solved fit points from the record's and warns above OFF_THE_FIT (0.01 R; the same
    branch agreed to 7e-5 R at 100 and 200 nodes)."""
    from morphoshell.fitting.inner import model_midline
    from morphoshell.workflows.fitted_shapes import OFF_THE_FIT, off_the_fit

    problem = load_problem(example_path("volvox_inversion"))[0]
    eq = solve(problem.with_updates(cut=0.0), nodes=NODES)
    points = model_midline(eq, 100)
    same = {"fitted_midline": {"r": points[:, 0].tolist(), "z": points[:, 1].tolist()}}
    moved = {"fitted_midline": {"r": points[:, 0].tolist(),
                                "z": (points[:, 1] + 2 * OFF_THE_FIT).tolist()}, "state": {}}
    with caplog.at_level(logging.WARNING, logger="morphoshell"):
        assert off_the_fit(eq, same, "same.json") < 1e-12
        assert not caplog.records
        assert off_the_fit(eq, moved, "moved.json") == pytest.approx(2 * OFF_THE_FIT)
    [warning] = [r.getMessage() for r in caplog.records]
    assert warning.startswith("moved.json: the shell solved from the fitted parameters is not "
                              "the fitted one: its midline lies up to 0.02 R") and \
        "pre=fitted_state(record)" in warning
