"""A sweep says once, naming the points, what solve() says of each shell: walls that pass
through each other, a mesh too coarse for the estimate, an estimate it could not make, a
fold snapped through; the rows keep the flags."""
import logging

import numpy as np
import pytest

from morphoshell import Problem, solve
from morphoshell.solvers.refinement import COARSE
from morphoshell.workflows.sweeps import sweep

TOY2 = Problem("uniform", {"k": 0.0}, h=0.3, cut=0.3, name="toy2")


def _warnings(caplog):
    return [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING]


@pytest.fixture(scope="module")
def volvox_fold():
    from pathlib import Path

    from morphoshell.io.problem_files import load_problem
    return load_problem(Path(__file__).parents[1] / "data" / "volvox_fold.toml")[0]


def test_walls_that_cross_and_folds_are_flagged_in_rows_and_said_once(volvox_fold, caplog):
    """The folded Volvox shells (kappa2 = -8, -7) pass through themselves: solve() warns of
    each, a sweep said nothing (user audit).  Both are reached by a continuation that
    snapped through a fold; its -v note names the point."""
    with caplog.at_level(logging.INFO, logger="morphoshell"):
        df = sweep(volvox_fold, {"kappa2": [-8.0, -7.0, -3.0]}, nodes=60, workers=1,
                   errors="none").to_dataframe()
    assert df["walls_cross"].tolist() == [True, True, False]
    assert df["event"].tolist() == ["snapped", "snapped", ""]
    warnings = _warnings(caplog)
    assert len(warnings) == 1, warnings
    assert "walls pass through each other at 2 of 3 points (kappa2 = -8, -7; column " \
           "walls_cross)" in warnings[0]
    notes = [r.getMessage() for r in caplog.records]
    assert any(n.startswith("continuation to volvox_fold (kappa2 = -8): snapped through a "
                            "fold") for n in notes), notes
    assert "sweep: the continuation to 2 of 3 points snapped through a fold (kappa2 = -8, " \
           "-7; column event)" in notes
    with caplog.at_level(logging.WARNING, logger="morphoshell"):
        caplog.clear()
        solve(volvox_fold.with_updates(kappa2=-7.0), nodes=60)    # (solve() warns alike)
        assert "walls pass through each other" in _warnings(caplog)[0]


def test_a_mesh_too_coarse_for_the_estimate_is_said_once_as_solve_says_it(caplog):
    """On 12 nodes the toy shell at h = 0.03 and k = 0.9 (nearly stress-free, its energy
    small against the mesh's discretisation error) has an energy estimate 3.3 times it:
    solve() warns, the sweep did not (user audit: psi_start off by 3.3e2 rad at F0 = 9,
    h = 0.001, silent).  k = 0 and 2 (estimates 0.03, 0.04) pass."""
    thin = TOY2.with_updates(h=0.03)
    with caplog.at_level(logging.WARNING, logger="morphoshell"):
        res = sweep(thin, {"k": [0.0, 0.9, 2.0]}, nodes=12, workers=1, errors="all")
        warnings = _warnings(caplog)
        caplog.clear()
        eq = solve(thin.with_updates(k=0.9), nodes=12)
        alone = _warnings(caplog)
    assert len(warnings) == 1 and "the error estimates exceed 0.1" in warnings[0]
    assert "at 1 of 3 points (k = 0.9; the largest: energy 3.3)" in warnings[0]
    assert "refine it (nodes=, --nodes)" in warnings[0]
    assert "the error estimate of energy is 3.3 (relative) on 12 nodes" in alone[0]
    df = res.to_dataframe()
    # the row's estimate is solve()'s (the same three meshes), relative above COARSE
    assert df["energy_error"][1] == pytest.approx(eq.error.errors["energy"], rel=1e-6)
    assert df["energy_error"][1] / abs(df["energy"][1]) > COARSE


def test_estimates_that_cannot_be_made_are_said(caplog):
    """On 5 nodes there is no half mesh: solve() says 'unavailable: too few nodes to halve',
    a sweep left its *_error columns empty without a word (user audit)."""
    with caplog.at_level(logging.WARNING, logger="morphoshell"):
        res = sweep(TOY2, {"k": [0.0, 1.0]}, nodes=5, workers=1, errors="all")
    assert np.all(np.isnan(res.columns["energy_error"]))
    warnings = _warnings(caplog)
    assert warnings == ["sweep: no error estimate at 2 of 2 points where one was asked for "
                        "(k = 0, 1): too few nodes to halve; their *_error columns are empty"]


def test_points_are_named_by_every_axis():
    res = sweep(TOY2, {"k": [0.0, 0.5], "h": [0.2, 0.3]}, nodes=20, workers=1, errors="none")
    assert res.points([0, 3]) == "(k, h) = (0, 0.2), (0.5, 0.3)"
    assert res.points(np.array([False, True, False, False])) == "(k, h) = (0, 0.3)"


def test_a_stress_free_point_is_judged_by_solves_energy_scale(caplog):
    """At k = 1 the toy sphere is stress-free: its energy (2e-12 C R^2) is the discretisation
    of zero, and solve() scales its error (1.5e-9) by h, 3e-8 of it, no warning.  The sweep
    built its own estimate with the round-off floor and warned 'energy 6.6e+02 ... too
    coarse' (audit 17 F1); it now takes solve()'s (refinement.error_estimate).  A truly
    coarse mesh (12 nodes, k = 0.9 beside it: energy 3.3 of itself) still warns."""
    with caplog.at_level(logging.WARNING, logger="morphoshell"):
        sweep(TOY2, {"k": [1.0, 1.4], "h": [0.05, 0.1]}, nodes=60, workers=1)
        assert _warnings(caplog) == []
        solve(TOY2.with_updates(k=1.0, h=0.05), nodes=60)
        assert _warnings(caplog) == []
        sweep(TOY2.with_updates(h=0.03), {"k": [0.9, 1.0]}, nodes=12, workers=1, errors="all")
    warnings = _warnings(caplog)
    assert len(warnings) == 1 and "at 1 of 2 points (k = 0.9; the largest: energy" in warnings[0]
