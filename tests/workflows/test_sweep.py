"""Sweeps: rows agree with solve()/ablate(), workers do not change the numbers, failures stay.

Small meshes (40–60 nodes) keep this file fast; the equalities hold on any
mesh because a sweep solves each point on the mesh solve()/ablate() use.
"""
import json
import logging
import math
import re
import sys

import numpy as np
import pandas as pd
import pytest

from morphoshell import Problem, ablate, solve
from morphoshell import sweep as sweep_function
from morphoshell.cli import main
from morphoshell.solvers.results import SolverError
from morphoshell.workflows.sweeps import MIN_TASKS, SweepResult, chunk_plan, sweep

TOY2 = Problem("uniform", {"k": 0.0}, h=0.3, cut=0.3, name="toy2")
#: Both routes converge every point to Ipopt's tolerance (1e-10, scaled) on the
#: same mesh from different starts (warm vs continuation): their differences in the
#: observables (order-one quantities) stay two orders of magnitude below this bound.
SAME_MESH = 1e-8

#: statuses of a solved point: Ipopt's, or certified Newton steps from a warm start
SOLVED = ("Solve_Succeeded", "Newton_Converged")


@pytest.fixture(scope="module")
def ablations():
    return sweep(TOY2, {"k": [0.0, 2.0], "cut": np.linspace(0.1, 1.2, 5)}, ablate=True,
                 nodes=60, workers=1)


def test_the_top_level_sweep_is_the_function():
    assert sweep_function is sweep


def test_ablation_rows_agree_with_ablate_at_every_point(ablations):
    df = ablations.to_dataframe()
    assert len(df) == 10 and list(df.columns[:2]) == ["k", "cut"]
    assert df["status"].isin(SOLVED).all() and ablations.failed == 0
    # C order of the product: the last axis fastest
    assert df["k"].tolist() == [0.0] * 5 + [2.0] * 5
    assert np.allclose(df["cut"][:5], np.linspace(0.1, 1.2, 5))
    for i in (0, 3, 9):
        ab = ablate(TOY2.with_updates(k=df["k"][i], cut=df["cut"][i]), nodes=60)
        for key in ("opening", "rotation", "displacement", "energy_released", "energy_removed"):
            assert abs(df[key][i] - getattr(ab, key)) < SAME_MESH, (i, key)
    # warm starts: a chunk's first point by continuation, the rest cheaper
    assert df["path"][0] == "continuation"
    assert set(df["path"][1:5]) <= {"warm", "remesh", "split"}
    assert df["iterations"][1:5].max() < df["iterations"][0]


def test_error_estimates_at_the_ends_of_each_line_bound_the_error(ablations):
    df = ablations.to_dataframe()
    est = df["rotation_error"].to_numpy()
    ends = np.array([0, 4, 5, 9])
    assert np.all(np.isfinite(est[ends])) and np.all(np.isnan(np.delete(est, ends)))
    # the estimate (60 nodes vs 30 and 15) bounds the error against a 4x finer mesh
    fine = ablate(TOY2.with_updates(k=2.0, cut=1.2), nodes=237)
    for key in ("opening", "rotation", "displacement"):
        err = abs(df[key][9] - getattr(fine, key))
        assert err <= df[f"{key}_error"][9], key
        assert df[f"{key}_error"][9] < 1e-4          # and is not vacuous


def test_solve_rows_agree_with_solve_and_errors_everywhere():
    res = sweep(TOY2, {"h": [0.1, 0.3], "k": [0.0, 0.5, 1.0]}, nodes=40, workers=1,
                errors="all")
    df = res.to_dataframe()
    assert list(df.columns[:2]) == ["h", "k"] and res.units["energy"] == "C R^2"
    assert np.all(np.isfinite(df["energy_error"]))
    for i in (1, 5):
        eq = solve(TOY2.with_updates(h=df["h"][i], k=df["k"][i]), nodes=40)
        assert abs(df["energy"][i] - eq.energy) < SAME_MESH * abs(eq.energy)
        assert abs(df["psi_start"][i] - eq.psi[0]) < SAME_MESH
        # the same estimate as solve()'s (the same three meshes)
        assert df["energy_error"][i] == pytest.approx(eq.error.errors["energy"], rel=1e-3,
                                                      abs=1e-12)
    none = sweep(TOY2, {"k": [0.0, 0.5]}, nodes=40, workers=1, errors="none")
    assert none.to_dataframe()["energy_error"].isna().all()


def test_xarray_has_the_axes_as_dimensions(ablations):
    ds = ablations.to_xarray()
    assert ds["rotation"].dims == ("k", "cut") and ds["rotation"].shape == (2, 5)
    assert ds["rotation"].attrs["units"] == "rad" and ds["cut"].attrs["units"] == "R"
    df = ablations.to_dataframe()
    assert float(ds["opening"].sel(k=2.0).isel(cut=1)) == df["opening"][6]
    assert ds.attrs["family"] == "uniform" and ds.attrs["ablate"] == 1
    assert str(ds["status"].sel(k=0.0).values[0]) in SOLVED


def test_a_word_axis_and_the_far_end_opening():
    res = sweep(TOY2, {"theory": ["classical", "large_bending"], "opening": [0.0, 0.5],
                       "k": [0.0]}, ablate=True, nodes=40, workers=1, errors="none")
    df = res.to_dataframe()
    assert list(df.columns[:3]) == ["theory", "opening_P", "k"]      # opening is o
    assert df["theory"].tolist() == ["classical"] * 2 + ["large_bending"] * 2
    assert res.failed == 0 and res.to_xarray()["rotation"].dims == ("theory", "opening_P", "k")


def test_chunks_cover_every_point_once_in_order_along_the_longest_axis():
    axis, chunks = chunk_plan({"k": [0, 0.5, 2], "cut": list(range(333))})
    assert axis == "cut" and len(chunks) == MIN_TASKS
    flat = sorted(i for c in chunks for i in c)
    assert flat == list(range(999))
    assert all(np.all(np.diff(c) == 1) for c in chunks)       # consecutive cuts, one k
    assert {len(c) for c in chunks} <= {83, 84}
    # the longest numeric axis, wherever it is
    axis, chunks = chunk_plan({"cut": list(range(20)), "k": [0, 1]})
    assert axis == "cut" and all(np.all(np.diff(c) == 2) for c in chunks)
    assert chunk_plan({"k": [0, 1]})[1] == [[0, 1]]
    assert [len(c) for c in chunk_plan({"k": list(range(10))}, chunk_size=4)[1]] == [3, 4, 3]


def test_the_default_workers_follow_the_measured_crossover(monkeypatch):
    from morphoshell.workflows import sweeps

    monkeypatch.setattr(sweeps.os, "cpu_count", lambda: 2)
    monkeypatch.setattr(sweeps, "no_free_core", lambda: False)
    # docs/benchmarks.md, "when workers pay": on 2 cores two Dask workers break even with
    # one process at about 200 ablations (400 solves) with a core free, 600-700 at load 3-6
    assert (sweeps.SERIAL_BELOW, sweeps.SERIAL_BELOW_BUSY) == (400, 1400)
    assert sweeps._local_workers(None, 399, chunks=12) == 1
    assert sweeps._local_workers(None, 400, chunks=12) == 2
    monkeypatch.setattr(sweeps, "no_free_core", lambda: True)
    assert sweeps._local_workers(None, 1399, chunks=12) == 1
    assert sweeps._local_workers(None, 1400, chunks=12) == 2
    # never more workers than chunks, asked for or not: a worker without a chunk only
    # costs its start
    assert sweeps._local_workers(None, 5000, chunks=1) == 1
    assert sweeps._local_workers(4, 10, chunks=3) == 3
    with pytest.raises(ValueError, match=r"workers = 0 must be a positive integer"):
        sweeps._local_workers(0, 10, chunks=3)


def test_an_ablation_counts_two_solves_and_one_chunk_runs_in_this_process(monkeypatch):
    from morphoshell.workflows import sweeps

    seen = []
    choose = sweeps._local_workers
    monkeypatch.setattr(sweeps, "_local_workers",
                        lambda *a: seen.append(a) or choose(*a))
    # the audit's 21-point sweep on 2 workers: one chunk, the second worker had idled
    res = sweep(TOY2, {"cut": np.linspace(0.2, 1.0, 21)}, ablate=True, nodes=40, workers=2)
    assert seen == [(2, 42, 1)]
    assert res.timing["backend"] == "serial" and res.timing["workers"] == 1


def test_two_dask_workers_give_the_same_numbers_as_one_process():
    pytest.importorskip("distributed")
    axes = {"k": [0.0, 2.0], "cut": np.linspace(0.2, 1.0, 8)}
    one = sweep(TOY2, axes, ablate=True, nodes=40, workers=1, chunk_size=4)
    two = sweep(TOY2, axes, ablate=True, nodes=40, workers=2, chunk_size=4)
    assert two.timing["backend"] == "dask" and two.timing["chunks"] == 4
    # the same chunks, each started alike: the same iterations and (bitwise) numbers
    assert np.array_equal(one.columns["iterations"], two.columns["iterations"])
    for key in ("opening", "rotation", "displacement", "energy_released", "rotation_error"):
        assert np.array_equal(one.columns[key], two.columns[key], equal_nan=True), key


def test_failed_points_keep_their_row_and_the_next_restarts_safely(monkeypatch):
    from morphoshell.solvers.direct import DirectSolver

    real = DirectSolver.solve

    def failing(self, problem, *args, **kwargs):
        if problem.params["k"] == 0.5:
            raise SolverError("forced failure", "Maximum_Iterations_Exceeded")
        return real(self, problem, *args, **kwargs)

    monkeypatch.setattr(DirectSolver, "solve", failing)
    res = sweep(TOY2, {"k": [0.0, 0.5, 1.5]}, ablate=True, nodes=40, workers=1)
    df = res.to_dataframe()
    assert len(df) == 3 and res.failed == 1
    # warm steps failed, and so did the last resort, continuation from k = 1
    assert df["status"][1] == "Continuation_Failed" and df["path"][1] == "failed"
    assert "continuation from the stress-free parameters stopped" in df["message"][1]
    assert df[["opening", "rotation"]].iloc[1].isna().all()
    assert df["status"][2] in SOLVED and df["path"][2] == "continuation"


@pytest.mark.parametrize("axes, ablate_, match", [
    ({"q": [1, 2]}, False, r"sweep axis 'q' is not a key of a 'uniform' problem"),
    ({"k": []}, False, r"sweep axis 'k' has no values"),
    ({"k": [0, 0.5, 0]}, False, r"repeats the value\(s\) \[0\]"),
    ({"k": [0, math.nan]}, False, r"'k': nan is not a finite number"),
    ({"h": [0.1, 1.5]}, False, r"sweep point h = 1\.5: thickness h = 1\.5 must lie in \[1e-06, 1\)"),
    ({"cut": [0.0, 0.5]}, True, r"sweep point cut = 0\.0: .*an ablation needs a cut > 0"),
    ({"k": "0,1"}, False, r"must be a list"),
])
def test_bad_axes_are_named_before_any_work(axes, ablate_, match, monkeypatch):
    monkeypatch.setattr(sys.modules["morphoshell.workflows.sweeps"], "_run_chunk",
                        lambda chunk: pytest.fail("work began"))
    with pytest.raises(ValueError, match=match):
        sweep(TOY2, axes, ablate=ablate_, workers=1)


def test_bad_options_and_session_families_are_named():
    with pytest.raises(ValueError, match=r"errors = 'some' must be one of"):
        sweep(TOY2, {"k": [0]}, errors="some")
    with pytest.raises(ValueError, match=r"unknown option\(s\) \['rtol'\]"):
        sweep(TOY2, {"k": [0]}, rtol=1e-3)
    from dataclasses import replace

    from morphoshell.model.profiles import FAMILIES
    mine = replace(FAMILIES["uniform"], name="mine", _function={})
    # (two chunks: a sweep of one chunk runs in this process whatever its workers)
    with pytest.raises(ValueError, match=r"family 'mine' is registered only in this session"):
        sweep(Problem(mine, h=0.3, cut=0.3), {"k": [0.0, 1.0], "h": [0.2, 0.3]}, workers=2)
    # in this process it works (the family object travels with the task)
    res = sweep(Problem(mine, h=0.3, cut=0.3), {"k": [0.0, 0.5]}, nodes=30, workers=1)
    assert res.failed == 0


def test_json_ready_and_repr(ablations):
    d = ablations.to_dict()
    assert d["axes"]["k"] == [0.0, 2.0] and len(d["rows"]) == 10
    assert d["units"]["rotation"] == "rad" and d["rows"][0]["status"] in SOLVED
    json.dumps(d)
    assert isinstance(ablations, SweepResult)
    assert repr(ablations).startswith("SweepResult(10 ablations: 2 k x 5 cut; 0 failed")


# --------------------------------------------------------------------------
# the command line
# --------------------------------------------------------------------------

def _problem_file(tmp_path):
    from morphoshell.io.problem_files import example_text
    path = tmp_path / "toy2.toml"
    path.write_text(example_text("toy2_ablation"))
    return path


def test_cli_sweep_writes_the_rows_of_the_api(tmp_path, capsys, ablations):
    path = _problem_file(tmp_path)
    csv, js = tmp_path / "out.csv", tmp_path / "out.json"
    code = main(["sweep", str(path), "--set", "k=0,2", "--set", "cut=0.1:1.2:5", "--ablate",
                 "--nodes", "60", "--workers", "1", "--csv", str(csv), "--json", str(js)])
    out = capsys.readouterr().out
    assert code == 0, out
    assert "sweep of 10 ablations (2 k x 5 cut)" in out and "rotation [rad]" in out
    df = pd.read_csv(csv, keep_default_na=False, na_values=[""])
    api = ablations.to_dataframe()           # the same sweep from Python
    assert list(df.columns) == list(api.columns)
    assert np.allclose(df["rotation"], api["rotation"], rtol=0, atol=1e-15)
    assert json.loads(js.read_text())["rows"][9]["k"] == 2.0


@pytest.mark.parametrize("items, match", [
    (["cut=0.1:0.5"], r"--set 'cut=0\.1:0\.5': a range is start:stop:num"),
    (["cut=0.1:0.5:x"], r"the number of values 'x' is not an integer"),
    (["k=0,a"], r"--set 'k=a': k needs a number"),
    (["k=0,,1"], r"--set 'k=0,,1': an empty value in the list '0,,1'"),
    (["nodes=20,40"], r"nodes cannot be a sweep axis"),
    (["q=1,2"], r"sweep axis 'q' is not a key"),
    (["k=0,1", "k=2"], r"k is set more than once"),
    (["h=0.1,1.5"], r"sweep point h = 1\.5: thickness h = 1\.5 must lie in \[1e-06, 1\)"),
    (["h=0.1"], r"no axis to sweep"),
    # the check continue makes too (audit 26, F5)
    (["k=0,0.5", "method=bvp"], r"\.toml: method = 'bvp': sweeps use the direct method$"),
])
def test_cli_bad_axes_exit_2_with_one_line_and_no_file(tmp_path, capsys, items, match):
    path = _problem_file(tmp_path)
    csv = tmp_path / "out.csv"
    args = ["sweep", str(path), "--csv", str(csv), "--workers", "1"]
    for item in items:
        args += ["--set", item]
    assert main(args) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.startswith("morphoshell: error:"), err
    assert re.search(match, err), err
    assert not csv.exists()


def test_a_deprecated_axis_name_warns_once(caplog):
    """``--set Sigma=0.1,0.2`` warned of the alias once per value (audit)."""
    import logging

    from morphoshell.cli.sweep import parse_axes
    with caplog.at_level(logging.WARNING, logger="morphoshell"):
        axes, _ = parse_axes(["Sigma=0.1,0.2,0.3"])
    assert axes == {"cut": [0.1, 0.2, 0.3]}
    assert sum("deprecated" in r.getMessage() for r in caplog.records) == 1


def test_the_max_points_advice_is_the_whole_grids_size():
    """A 100-value range beside 3 values of h, over --max-points 60: the range alone was
    refused, advising --max-points 100, which the 300-point grid then exceeded (audit 17 F2).
    The first refusal gives 300, which works; a huge range is still refused before any list
    of values is made."""
    from morphoshell.cli.sweep import parse_axes
    from morphoshell.io.problem_files import ProblemFileError
    items = ["k=1:3:100", "h=0.05,0.1,0.2"]
    with pytest.raises(ProblemFileError, match=r"^--set: the grid k=1:3:100 \(100\) x "
                                               r"h=0.05,0.1,0.2 \(3\) has 300 points, more than "
                                               r"60: give fewer values, or --max-points 300 "):
        parse_axes(items, max_points=60)
    axes, _ = parse_axes(items, max_points=300)
    assert [len(v) for v in axes.values()] == [100, 3]
    with pytest.raises(ProblemFileError, match=r"\(1,000,000,000,000,000\) has 3,000,000,000,000,000 points"):
        parse_axes(["h=0.1,0.2,0.3", "k=0:1:1000000000000000"])


def test_a_sweep_past_a_branch_point_gives_solves_dome(blister):
    """Past the blister disc's first branch point (G = 0.003) the flat disc is unstable: a
    sweep's point there falls back on continuation, which switches to the stable dome as
    solve() does (energies to 1e-10 relative); before, the point failed."""
    from morphoshell import solve
    from morphoshell.workflows.sweeps import sweep

    df = sweep(blister, {"G": [0.002, 0.1, 0.2]}, nodes=60, workers=1).to_dataframe()
    for G, energy in zip(df["G"], df["energy"]):
        expected = solve(blister.with_updates(G=G), nodes=60).energy
        assert abs(energy - expected) < 1e-10 * expected, (G, energy, expected)
    assert df["energy"].iloc[1] > 100 * df["energy"].iloc[0]     # (0.1: the dome, not flat)


@pytest.mark.parametrize("alone", ["", "_crossed", "_left_solves_branch"])
def test_a_sweep_through_a_bistable_range_gives_solves_states(alone, monkeypatch):
    """The Volvox shell is bistable in kappa1: from -8, solve() snaps to an inverted state,
    from 0 not.  A sweep's warm steps from -8 had stayed on the inverted state up to
    kappa1 = 3 (energy 0.027 at 0 against solve()'s 0.018; user audit).  After a snap the
    next point keeps to solve()'s route, and a chunk whose warm path ends on another state
    than that route is solved again by it; each alone (the other switched off) suffices
    here.  Every row is solve()'s (energies to 1e-9)."""
    from morphoshell.io.problem_files import example_path, load_problem
    from morphoshell.workflows import sweep_steps, sweeps

    if alone:
        monkeypatch.setattr(sweep_steps if alone == "_crossed" else sweeps, alone,
                            lambda *args: False)
    volvox = load_problem(example_path("volvox_inversion"))[0]
    df = sweep(volvox, {"kappa1": [-8.0, -4.0, 0.0, 2.0]}, nodes=60, workers=1,
               errors="none").to_dataframe()
    for k, energy in zip(df["kappa1"], df["energy"]):
        expected = solve(volvox.with_updates(kappa1=k), nodes=60).energy
        assert abs(energy - expected) < 1e-9 * expected, (k, energy, expected)


def test_a_sweep_across_a_moved_breakpoint_rebuilds_the_mesh_on_the_way():
    """A Volvox breakpoint s2 swept from 1.4 to 1.8 moves its mesh knot past where the mesh
    of 1.8 holds at 1.4: carrying the solution at 1.4 onto it raised ValueError ("the
    mesh's anchors are too far from its knots"), taken for bad input (exit status 2)
    after the work began (user audit).  The warm step is now split, each half on its own
    end's mesh, as continue rebuilds its mesh; the rows are solve()'s (energies to 1e-10
    relative: the same mesh and tolerance, from another start)."""
    from morphoshell.io.problem_files import example_path, load_problem

    volvox = load_problem(example_path("volvox_inversion"))[0]
    df = sweep(volvox, {"s2": [1.4, 1.8]}, nodes=60, workers=1, errors="none").to_dataframe()
    assert df["path"].tolist() == ["continuation", "split"]     # warm, not a fresh start
    for s2, energy in zip(df["s2"], df["energy"]):
        expected = solve(volvox.with_updates(s2=s2), nodes=60).energy
        assert abs(energy - expected) < 1e-10 * expected, (s2, energy, expected)


def test_units_of_every_axis_come_from_the_family():
    from morphoshell.io.problem_files import example_path, load_problem

    volvox = load_problem(example_path("volvox_inversion"))[0]
    res = sweep(volvox, {"s1": [1.2, 1.3], "sigma": [0.05], "kappa1": [1.1], "f1": [0.9],
                         "opening": [0.3]}, nodes=60, workers=1, errors="none")
    units = res.to_dict()["units"]
    assert {k: units[k] for k in ("s1", "sigma", "kappa1", "f1", "opening")} == \
        {"s1": "R", "sigma": "R", "kappa1": "1/R", "f1": "1", "opening": "R"}
    assert units["iterations"] == "1" and "theory" not in units


def test_json_names_the_far_end_opening_axis_as_its_column():
    """An ablation sweep's axis P is the column opening_P (opening is the observable o):
    the JSON's axes called it opening, colliding with the observable (user audit)."""
    res = sweep(TOY2, {"opening": [0.0, 0.3], "k": [0.0]}, ablate=True, nodes=30, workers=1,
                errors="none")
    d = res.to_dict()
    assert list(d["axes"]) == ["opening_P", "k"] and "opening_P" in d["rows"][0]
    assert d["units"]["opening_P"] == "R"
    assert list(res.to_dataframe().attrs["axes"]) == ["opening_P", "k"]


def test_progress_counts_points(monkeypatch, recorded_bar):
    """The bar counted chunks: a sweep of up to 31 points is one chunk, and sat at 0/1 to
    the end (user audit).  It counts points, each as it is solved."""
    from morphoshell.workflows import sweep_runs

    seen, counter = recorded_bar
    monkeypatch.setattr(sweep_runs, "counter", counter)
    sweep(TOY2, {"k": [0.0, 0.5, 1.0]}, nodes=30, workers=1, errors="none")
    assert seen == [(3, "point"), 1, 1, 1]


def test_cli_exits_3_when_a_point_failed_unless_failures_are_allowed(tmp_path, capsys):
    """A sweep whose every point failed exited 0 (user audit); as a campaign, it exits 3
    naming them on the last line, and writes the rows either way.  The messages advise
    in a sweep's terms: it has neither --rtol nor --method bvp."""
    path = _problem_file(tmp_path)
    js = tmp_path / "fail.json"
    args = ["sweep", str(path), "--set", "h=0.00001", "--set", "cut=1", "--set", "k=-20,20",
            "--workers", "1", "--json", str(js)]
    assert main(args) == 3
    out = capsys.readouterr().out.strip().splitlines()
    assert out[-1].startswith("of 2 points, 2 failed: k = -20, 20 (")
    rows = json.loads(js.read_text())["rows"]
    for row in rows:
        assert row["path"] == "failed" and row["iterations"] > 0       # (was 0 after 53)
        assert "--method bvp)" not in row["message"] and "--rtol" not in row["message"]
        assert "morphoshell solve --method bvp" in row["message"]
        assert "(k = " in row["message"]              # the problem named by its point
    js.unlink()
    assert main([*args, "--allow-failures"]) == 0 and js.exists()
    assert "(--allow-failures: exit status 0)" in capsys.readouterr().out


def test_an_ablation_sweep_warns_where_ablate_does(caplog):
    # the sweep compared the recoil's absolute errors (R, rad) with 0.1: a tiny
    # cut's d, 27 % off on 200 nodes (error estimate 1.1e-6 R), passed silently
    p = Problem("uniform", {"k": 0.0}, h=1e-4, cut=1e-4, theory="classical")
    with caplog.at_level(logging.WARNING, logger="morphoshell"):
        row = sweep_function(p, {"cut": [1e-4]}, ablate=True, workers=1).to_dataframe().iloc[0]
    single = ablate(p)
    assert row["displacement_error"] == single.errors["displacement"]
    warned = [r.getMessage() for r in caplog.records if r.getMessage().startswith("sweep: the error")]
    assert len(warned) == 1 and "relative to the observables" in warned[0]
    assert single.relative_errors()["displacement"] > 0.1     # ablate() warns of it too


#: local_relaxation: the intact shell's kink stays at s0 = 0.2 for every cut.
RELAX = Problem("local_relaxation", {"F0": 0.35, "s0": 0.2}, h=0.3, cut=0.3)


@pytest.mark.parametrize("cuts", [[0.1, 0.3], [0.199, 0.2, 0.2001]])
def test_an_ablation_sweep_across_the_breakpoint_keeps_every_row(cuts):
    """cut = 0.1, 0.3 died whole, exit status 2 and no rows ("anchors and breakpoints at
    [0.2, 0.2] are too close together to be mesh nodes"; user audit): the warm step of the
    intact shell, halved, put its rim onto s0; and cut = 0.2 or 0.2001 was refused before
    any work.  Every row is now ablate()'s, on the same mesh (SAME_MESH)."""
    df = sweep(RELAX, {"cut": cuts}, ablate=True, nodes=100, workers=1,
               errors="none").to_dataframe()
    assert df["status"].isin(SOLVED).all() and df["cut"].tolist() == cuts
    for i, cut in enumerate(cuts):
        ab = ablate(RELAX.with_updates(cut=cut), nodes=100)
        for key in ("opening", "rotation", "displacement", "energy_released"):
            assert abs(df[key][i] - getattr(ab, key)) < SAME_MESH, (cut, key)


def test_a_warm_step_whose_midpoint_has_no_mesh_is_split_around_it(monkeypatch):
    """Where the mesh of a warm step's midpoint cannot be built (ValueError, as the rim at
    a breakpoint's was), the step splits on or ends in continuation, as where a mesh does
    not hold the solution carried onto it: the point keeps its row, the sweep its other
    points (the ValueError had ended the sweep as bad input, exit status 2)."""
    from morphoshell.workflows import sweep_steps

    real, refused = sweep_steps._solver, []

    def no_mesh_between(problem, nodes, anchors, options):
        if anchors and 0.1 < anchors[0] < 0.3:
            refused.append(anchors[0])
            raise ValueError(f"no mesh for the anchor {anchors[0]}")
        return real(problem, nodes, anchors, options)

    monkeypatch.setattr(sweep_steps, "_solver", no_mesh_between)
    # (the intact shell's warm step from the rim at 0.1 to 0.3 is split: RELAX, not TOY2)
    df = sweep(RELAX, {"cut": [0.1, 0.3]}, ablate=True, nodes=100, workers=1,
               errors="none").to_dataframe()
    assert refused and df["status"].isin(SOLVED).all()
    ab = ablate(RELAX.with_updates(cut=0.3), nodes=100)
    assert abs(df["opening"][1] - ab.opening) < SAME_MESH


def test_a_warm_path_that_jumps_past_a_fold_is_solved_and_flagged_as_solve_does(caplog):
    """The fold shell swept in kappa2 towards -8: its warm path stayed on the everted
    branch to -6.5 and at -7 (past the fold at -6.57) jumped to the inverted one, the
    row's event empty, while solve() at -7, and the same row swept the other way, said
    snapped (audit 14).  The jump is found, the point solved by solve()'s route: its
    event is snapped, its energy solve()'s (to 1e-10 relative: the same mesh and route),
    and the sweep's note names the point."""
    from pathlib import Path

    from morphoshell.io.problem_files import load_problem

    fold = load_problem(Path(__file__).parents[1] / "data" / "volvox_fold.toml")[0]
    with caplog.at_level(logging.INFO, logger="morphoshell.workflows.sweeps"):
        df = sweep(fold, {"kappa2": [-6.0, -6.5, -7.0]}, nodes=40, workers=1,
                   errors="none").to_dataframe()
    assert df["event"].tolist() == ["", "", "snapped"]
    assert df["path"].tolist() == ["continuation", "warm", "continuation"]
    expected = solve(fold.with_updates(kappa2=-7.0), nodes=40)
    assert expected.solver.details["snaps"]
    assert abs(df["energy"][2] - expected.energy) < 1e-10 * expected.energy
    assert "left its branch at 1 of 3 points (kappa2 = -7:" in caplog.text
