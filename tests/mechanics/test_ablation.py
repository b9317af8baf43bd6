"""ablate's arguments and recoil_jacobian's result (mechanics/ablation.py)."""
import logging

import numpy as np
import pytest

from morphoshell import Problem, SolverError, ablate, solve
from morphoshell.solvers import routes

CUT = Problem("uniform", {"k": 0.0}, h=0.3, cut=0.3)


@pytest.mark.parametrize("args, kwargs, match", [
    # a user audit: AttributeError: 'int' object has no attribute 'problem'
    ((CUT,), {"pre": 5}, r"^pre = 5 must be an Equilibrium"),
    (("uniform",), {}, r"^problem = 'uniform' must be a morphoshell Problem"),
])
def test_arguments_of_the_wrong_kind_are_named_before_any_work(args, kwargs, match):
    builds = routes.cache_info()["builds"]
    with pytest.raises(TypeError, match=match):
        ablate(*args, nodes=50, **kwargs)
    assert routes.cache_info()["builds"] == builds


def test_recoil_jacobian_names_its_rows_and_still_unpacks():
    """Rows in RECOIL's order (a user audit: a bare tuple of 5 unnamed rows); the pair
    unpacks as before.  Exact equality: the same arrays, picked by name."""
    from morphoshell.mechanics.ablation import recoil_jacobian
    from morphoshell.solvers.observables import RECOIL
    ab = ablate(CUT, nodes=50)
    result = recoil_jacobian(ab, ["k", "h"])
    values, jacobian = result
    assert result.rows == RECOIL and jacobian.shape == (5, 2)
    value, gradient = result.row("rotation")
    assert value == ab.rotation == values[1] and list(gradient) == list(jacobian[1])
    with pytest.raises(ValueError, match="row = 'energy_released': choose one of"):
        result.row("energy_released")


def test_an_ablation_pickles_and_its_derivatives_survive():
    """A user audit: ablate's result did not pickle (its equilibria's problems and solvers).
    Unpickled, its observables and recoil_jacobian (which needs both states' solvers,
    rebuilt from their meshes) are the original's, to the bit."""
    import pickle

    import numpy as np

    from morphoshell.mechanics.ablation import recoil_jacobian

    ab = ablate(Problem("uniform", {"k": 0.5}, h=0.2, cut=0.3), nodes=50)
    back = pickle.loads(pickle.dumps(ab))
    assert back.problem == ab.problem and back.observables() == ab.observables()
    for a, b in zip(recoil_jacobian(back, ["k", "h"]), recoil_jacobian(ab, ["k", "h"])):
        assert np.array_equal(a, b)


# --------------------------------------------------------------------------
# the observables' error estimates (audit 8, F5)
# --------------------------------------------------------------------------

#: The smallest cut at the thinnest shell of the audit: d = 1.25e-7 R, 27 % off on 200 nodes.
TINY = Problem("uniform", {"k": 0.0}, h=1e-4, cut=1e-4, theory="classical")


@pytest.mark.parametrize("problem, nodes, most", [
    # toy problem 2 (measured: estimate / true error 29-50 for every observable);
    (CUT, 100, 100),
    # the tiny cut (measured 31-40; energy_released 550: it converges at order 6 there and
    # the quarter mesh's difference, divided by 2^4 - 1 only, dominates)
    (TINY, 200, 1000),
])
def test_the_estimates_bound_every_observables_error(problem, nodes, most):
    """Against 4x the nodes (its own error 2^-8 of this one's at order 4, the order measured
    on both cases), every estimate is at least the error and at most ``most`` times it:
    SAFETY (2) x (2^p - 1) = 30 on a fourth-order mesh, the factor solve()'s estimate has."""
    from morphoshell.mechanics.ablation import OBSERVABLES

    ab, ref = ablate(problem, nodes=nodes), ablate(problem, nodes=4 * (nodes - 1) + 1)
    assert set(ab.errors) == set(OBSERVABLES) and ab.error_note == ""
    for k in OBSERVABLES:
        true = abs(getattr(ab, k) - getattr(ref, k))
        assert true <= ab.errors[k] <= most * true, k


def test_a_tiny_cuts_displacement_warns_once_naming_it_and_a_finer_mesh(caplog):
    """The audit's case: d is 27 % off on 200 nodes, which the edges' absolute estimates (3e-6
    R) did not show.  One warning names it (relative estimate 6.9) and 399 nodes; toy problem 2
    (relative estimates below 1e-6) and the stress-free sphere at the same h and cut (every
    observable the discretisation error of 0: d = 3e-8 R, relative to 1 R) warn of nothing."""
    import logging

    with caplog.at_level(logging.WARNING, logger="morphoshell.mechanics.ablation"):
        ab = ablate(TINY)
    records = [r for r in caplog.records if r.name == "morphoshell.mechanics.ablation"]
    assert len(records) == 1
    assert "displacement (6.9)" in records[0].getMessage()
    assert "nodes=399" in records[0].getMessage()
    assert ab.relative_errors()["displacement"] == ab.errors["displacement"] / ab.displacement
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="morphoshell.mechanics.ablation"):
        ablate(CUT)
        ablate(TINY.with_updates(k=1.0))
    assert not [r for r in caplog.records if r.name == "morphoshell.mechanics.ablation"]


def test_the_estimate_is_solves_own_applied_to_the_observables():
    """No further solve: the levels are those of both states' own estimates (the solver
    cache builds nothing more), and the errors are level_errors of the observables measured
    on them, to the bit."""
    from morphoshell.mechanics.ablation import measure
    from morphoshell.solvers.refinement import level_errors

    ab = ablate(CUT, nodes=100)
    levels = [measure(CUT.cut, *(eq.error.levels[i] for eq in (ab.pre, ab.post)))
              for i in range(2)]
    assert ab.errors == level_errors(ab.observables(), *levels, order=4)
    assert [eq.solver.nodes for eq in ab.post.error.levels] == [50, 25]


def test_an_ablation_without_levels_says_why_and_does_not_warn(caplog):
    """A ``pre`` without its estimate's levels (read back, or built by hand): NaN errors, a
    note, no warning; the JSON says so."""
    import dataclasses
    import logging
    import math

    from morphoshell.mechanics.ablation import intact_problem

    pre = solve(intact_problem(CUT), nodes=100, anchors=(CUT.cut,))
    with caplog.at_level(logging.WARNING, logger="morphoshell.mechanics.ablation"):
        ab = ablate(CUT, nodes=100, pre=dataclasses.replace(pre, error=None))
    assert all(math.isnan(v) for v in ab.errors.values()) and "no coarser levels" in ab.error_note
    assert not caplog.records
    assert ab.to_dict(arrays=False)["error_note"] == ab.error_note


#: A small cut whose observables need 400 nodes for 5 % (energy_released: 0.21 relative on
#: 200 nodes, 0.003 on 400), while its edges meet 5 % on 200 nodes.
SMALL = Problem("uniform", {"k": 0.0}, h=1e-2, cut=1e-3)


def test_rtol_refines_both_states_until_the_observables_meet_it():
    ab = ablate(SMALL, rtol=0.05)
    assert ab.pre.solver.nodes == ab.post.solver.nodes == 399
    assert max(ab.relative_errors().values()) <= 0.05
    assert "for the ablation's observables (rtol = 0.05)" in ab.post.solver.details["path"]
    with pytest.raises(SolverError, match="ablation's energy_released .* does not meet rtol = "
                                          "0.05 within 300 nodes") as info:
        ablate(SMALL, rtol=0.05, max_nodes=300)
    assert info.value.status == "Tolerance_Not_Met"


def test_a_stress_free_caps_energy_is_not_read_as_unresolved(caplog):
    # audit 12: the fast-relaxation example (the intact shell stress-free, the cut one
    # not) warned that its removed cap's energy, 1e-15 C R^2 of a zero, was 58 % off:
    # its scale was the round-off floor, not the intact shell's stress-free floor h
    p = Problem("local_relaxation", {"F0": 0.35, "s0": 0.2}, h=0.3, cut=0.3)
    with caplog.at_level(logging.WARNING, logger="morphoshell.mechanics.ablation"):
        ab = ablate(p)
    assert not [r for r in caplog.records if r.name == "morphoshell.mechanics.ablation"]
    rel = ab.relative_errors()
    assert abs(ab.energy_removed) < 1e-13 and rel["energy_removed"] < 1e-9
    assert max(rel.values()) < 1e-5      # every observable resolved (1e-8-1e-7 by refinement)


def _volvox_fold():
    from morphoshell.io.problem_files import example_path, load_problem
    return load_problem(example_path("volvox_fold"))[0]


@pytest.mark.parametrize("family, breakpoint, nodes", [("local_relaxation", 0.2, 200),
                                                       ("volvox", 0.65, 100)])
def test_a_cut_at_or_next_to_a_breakpoint_ablates_continuously(family, breakpoint, nodes):
    """A cut at the intact shell's breakpoint (local_relaxation's s0, a Volvox step s1), or
    1e-4 from it, was refused ("anchors and breakpoints at [0.2, 0.2] are too close
    together to be mesh nodes", exit status 2; user audit).  The rim is now one node with
    the breakpoint (1e-6 off it too: merged), or a node of its own (1e-4 off), and the
    observables are smooth in Σ through it.  The slopes over 1e-6 on either side agree to
    the curvature's share, |v''| 1e-6 < 1e-5 (measured up to 7e-6), and the round-off
    (1e-12 of the values over 1e-6); the slope over ±1e-4 agrees with them to 1e-2 of the
    largest: those two shells have their own meshes (the rim a node apart from the
    breakpoint), and their discretisation errors differ (measured: up to 4e-3 of it,
    Volvox's opening, nearly stationary, on 100 nodes; below 1e-4 elsewhere)."""
    base = (Problem("local_relaxation", {"F0": 0.35, "s0": 0.2}, h=0.3, cut=0.3)
            if family == "local_relaxation" else _volvox_fold())
    keys = ("opening", "rotation", "displacement", "energy_released")
    at = {d: ablate(base.with_updates(cut=breakpoint + d), nodes=nodes)
          for d in (-1e-4, -1e-6, 0.0, 1e-6, 1e-4)}
    for k in keys:
        v = {d: getattr(ab, k) for d, ab in at.items()}
        below, above = (v[0.0] - v[-1e-6]) / 1e-6, (v[1e-6] - v[0.0]) / 1e-6
        across = (v[1e-4] - v[-1e-4]) / 2e-4
        assert abs(above - below) <= 1e-5 + 1e-12 * abs(v[0.0]) / 1e-6, (k, below, above)
        assert abs(across - above) <= 1e-2 * max(map(abs, (below, above, across))), \
            (k, across, above)


def test_an_ablation_of_direct_solutions_imports_no_scipy():
    # scipy.interpolate (0.3-0.5 s, with scipy.special/optimize/linalg) was imported by
    # energy_between for every ablation, though only BVP solutions integrate a spline:
    # 40 % of `morphoshell ablate` (audit 18, F2). A fresh process: this one has scipy.
    import subprocess
    import sys
    run = ("from morphoshell import Problem, ablate; "
           "ablate(Problem('uniform', {'k': 0.5}, h=0.3, cut=0.3), nodes=40)")
    code = f"import sys; {run}; print(sorted(m for m in sys.modules if m.startswith('scipy')))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True)
    assert out.stdout.strip().splitlines()[-1] == "[]"


def test_a_thin_shells_note_is_logged_once_for_both_states(caplog):
    """Both states are one shell, of one thickness: its thin-shell note once (ablate, and
    `morphoshell ablate`, logged the same line twice); a solve after the ablation still says
    it (the note is kept once only within the ablation)."""
    thin = CUT.with_updates(h=1.5e-5)   # (below MIN_DIRECT_THICKNESS, 2e-5)

    def notes():
        return [r for r in caplog.records if "thinner" in r.getMessage()]

    with caplog.at_level(logging.WARNING, logger="morphoshell.solvers.routes"):
        ablate(thin, nodes=100)
        assert len(notes()) == 1
        solve(thin, nodes=100)
    assert len(notes()) == 2
