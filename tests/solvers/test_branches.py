"""Branches of equilibria (issue 38): events located independently of the step, the inertia
changing exactly at them, agreement with natural-parameter continuation and with cold
solves, solve() crossing a snap-through, named errors, and the paths refused."""
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from morphoshell import Problem, SolverError, solve
from morphoshell.io.problem_files import load_problem
from morphoshell.solvers import crossings
from morphoshell.solvers.arclength import Arclength
from morphoshell.solvers.branches import follow_branch, switch_branch
from morphoshell.solvers.direct import solver_of
from morphoshell.solvers.paths import ParameterLine

FIXTURE = Path(__file__).resolve().parents[1] / "data" / "volvox_fold.toml"
#: The issue's folds of the fold shell (400 nodes, to the digits given there).
FOLDS_400 = (0.8722619, 0.3757453, 0.5491197, 0.3126880, 0.5465312, 0.5459553)


@pytest.fixture(scope="module")
def volvox():
    return load_problem(FIXTURE)[0]


@pytest.fixture(scope="module")
def branch60(volvox):
    return follow_branch(volvox, nodes=60)


def _events(branch, kind):
    return [i for i, pt in enumerate(branch.points) if pt.event == kind]


def test_folds_do_not_depend_on_the_step(volvox, branch60):
    """Halving the largest step (other points, other brackets): the same six folds to 1e-8
    in λ, the same sequence of events, the same end."""
    finer = follow_branch(volvox, nodes=60, max_step=0.01)
    assert len(finer.points) > len(branch60.points)
    a = [pt.tau for pt in branch60.events]
    b = [pt.tau for pt in finer.events]
    assert [pt.event for pt in branch60.events] == ["fold"] * 6
    assert [pt.event for pt in finer.events] == ["fold"] * 6
    assert np.max(np.abs(np.subtract(a, b))) < 1e-8
    assert np.allclose(a, FOLDS_400, atol=1e-4)      # 60 nodes: within 4e-5 of the 400's
    assert finer.end.tau == 1 and abs(finer.end.r_end - branch60.end.r_end) < 1e-9


@pytest.mark.parametrize("max_step", [0.05, 0.5, 1.0])
def test_a_pair_of_folds_within_one_large_step_is_found(volvox, branch60, max_step,
                                                        monkeypatch):
    """The folds at λ = 0.5465 and 0.5460 bound a loop narrower than a large step: at
    --max-step 0.05 one step crossed both, t_τ kept its sign and they were missed (a user
    audit: four folds of six, no word). Steps that go back in τ against both tangents or
    turn by more than 26° are retried at half: the six folds at every largest step, to 1e-8
    of the default step's. Without the turn test, 0.05 finds four again."""
    from morphoshell.solvers import arclength

    a = [pt.tau for pt in branch60.events]
    coarse = follow_branch(volvox, nodes=60, max_step=max_step)
    assert [pt.event for pt in coarse.events] == ["fold"] * 6
    assert np.max(np.abs(np.subtract(a, [pt.tau for pt in coarse.events]))) < 1e-8
    if max_step == 0.05:
        monkeypatch.setattr(arclength, "SMOOTH_COS", -1.0)
        assert len(follow_branch(volvox, nodes=60, max_step=max_step).events) == 4


def test_inertia_changes_by_one_exactly_at_each_fold(branch60):
    """At every fold the points next to it on the branch have k and k ± 1 negative
    eigenvalues (the fold itself: the fewer, and not stable); and 1e-6 of arclength either
    side of the located fold the inertia already differs by one."""
    arc = Arclength(solver_of(branch60.end.equilibrium), branch60.line)
    sides = []
    for i in _events(branch60, "fold"):
        before, fold, after = branch60.points[i - 1:i + 2]
        k = (before.negative_eigenvalues, after.negative_eigenvalues)
        assert abs(k[0] - k[1]) == 1
        assert fold.negative_eigenvalues == min(k) and not fold.stable
        start = arc.start(fold.equilibrium, fold.tau)
        near = {arc.correct(start, ds).inertia.negative for ds in (-1e-6, 1e-6)}
        assert near == set(k), (fold.tau, near, k)
        sides.append(k)
    assert sides == [(0, 1), (1, 2), (2, 1), (1, 0), (0, 1), (1, 0)]
    assert branch60.end.stable and branch60.end.negative_eigenvalues == 0


def test_branch_points_are_located_to_1e8(blister):
    """The flat disc of the blister problem loses stability at branch points (one more
    negative eigenvalue each, no fold): located by bisection, the same to 1e-8 in λ with
    half the step, and 1e-7 in λ either side of each the inertia differs by one."""
    a = follow_branch(blister, nodes=60)
    b = follow_branch(blister, nodes=60, max_step=0.01)
    ta = [pt.tau for pt in a.events if pt.event == "branch_point"]
    tb = [pt.tau for pt in b.events if pt.event == "branch_point"]
    assert len(ta) >= 5 and len(ta) == len(tb)
    assert np.max(np.abs(np.subtract(ta, tb))) < 1e-8
    arc = Arclength(solver_of(a.end.equilibrium), a.line)
    for k, i in enumerate(_events(a, "branch_point")[:4]):
        pt = a.points[i]
        start = arc.start(pt.equilibrium, pt.tau)
        below, above = arc.at_tau(start, pt.tau - 1e-7), arc.at_tau(start, pt.tau + 1e-7)
        assert (below.inertia.negative, above.inertia.negative) == (k, k + 1)


def test_bisection_trials_start_on_the_brackets_line(blister, monkeypatch):
    """Locating a branch point, each trial after the first bracket starts from the line
    between the bracket's two points: its KKT error there shrinks with the bracket's
    square, below the tolerance after a dozen halvings (from the tangent it stays at
    5e-4: the step's), and one Newton step follows.  The point found is where bisection
    with full correctors finds it, to 1e-10 in lambda, with the same inertia."""
    a = follow_branch(blister, nodes=60)
    i = _events(a, "branch_point")[0]
    before = a.points[i - 1]
    arc = Arclength(solver_of(a.end.equilibrium), a.line)
    prev = arc.start(before.equilibrium, before.tau)
    ds = 2 * (a.points[i].tau - before.tau) / prev.t_tau
    new = arc.correct(prev, ds)
    assert new.inertia.negative == prev.inertia.negative + 1
    first, iterate = [], arc.kkt.iterate_around

    def recorded(*args):
        out = iterate(*args)
        first.append(out[2])
        return out
    monkeypatch.setattr(arc.kkt, "iterate_around", recorded)
    point, = arc.locate_changes(prev, new, ds)
    assert len(first) > 25 and max(first[-15:]) < arc.tol

    lo, hi, ref = 0.0, ds, None               # the bisection with full correctors
    while (hi - lo) * abs(prev.t_tau) > 1e-11:
        mid = 0.5 * (lo + hi)
        trial = arc.correct(prev, mid)
        if trial.inertia.negative == prev.inertia.negative:
            lo = mid
        else:
            hi, ref = mid, trial
    assert abs(point.tau - ref.tau) < 1e-10
    assert (point.inertia.negative, ref.inertia.negative) == (1, 1)


def test_a_branch_stays_on_its_path_in_order(blister):
    """Points in the order of the branch: without folds, λ grows from 0 to 1 and no event
    lies past the path's end (60 nodes put a branch point just past λ = 1)."""
    branch = follow_branch(blister, nodes=60)
    taus = [pt.tau for pt in branch.points]
    assert taus[0] == 0 and taus[-1] == 1
    assert np.all(np.diff(taus) > 0)


def test_arclength_reproduces_natural_continuation(branch60):
    """Where natural-parameter continuation works (the fold shell before its first fold),
    the branch at given λ (a natural step from the nearest point before) is solve()'s
    solution there (continuation from the stress-free parameters, same mesh): rim and
    angle to 1e-8 R, unknowns to 1e-7."""
    arc = Arclength(solver_of(branch60.end.equilibrium), branch60.line)
    points = branch60.points[:_events(branch60, "fold")[0]]
    for tau in (0.2, 0.5, 0.8):
        near = max((pt for pt in points if pt.tau <= tau), key=lambda pt: pt.tau)
        mine = arc.equilibrium(arc.at_tau(arc.start(near.equilibrium, near.tau), tau))
        ref = solve(branch60.line.at(tau), nodes=60)
        assert ref.solver.details["path"].startswith("continuation")
        for name in ("r", "z", "psi"):
            assert abs(getattr(mine, name)[-1] - getattr(ref, name)[-1]) < 1e-8, (tau, name)
        assert np.max(np.abs(mine.x - ref.x)) < 1e-7


def test_arclength_reproduces_natural_continuation_without_folds():
    """A fold-free path (uniform shell, k from its neutral 1 to 0.5): every point of the
    branch is solve()'s solution at its λ to 1e-8 (the free edge's r, z and all
    unknowns)."""
    problem = Problem("uniform", {"k": 0.5}, h=0.3, cut=0.3)
    branch = follow_branch(problem, nodes=60)
    assert not branch.events and all(pt.stable for pt in branch.points)
    for pt in branch.points[1::10]:
        ref = solve(branch.line.at(pt.tau), nodes=60)
        eq = pt.equilibrium
        assert abs(eq.r[0] - ref.r[0]) < 1e-8 and abs(eq.z[0] - ref.z[0]) < 1e-8
        assert np.max(np.abs(eq.x - ref.x)) < 1e-8


def test_solve_snaps_through_the_fold_to_the_cold_and_branch_solution(volvox):
    """solve() on the issue's 400-node shell: converged, the snap recorded at the fold
    (λ = 0.8722619) with the energy falling; the same rim as a cold solve, as the followed
    branch's end and as the issue's to 1e-8 R."""
    eq = solve(volvox, nodes=400)
    assert eq.converged and eq.solver.status in ("Newton_Converged", "Solve_Succeeded")
    snaps = eq.solver.details["snaps"]
    assert len(snaps) == 1 and abs(snaps[0]["tau"] - FOLDS_400[0]) < 1e-7
    assert snaps[0]["energy_before"] > snaps[0]["energy_landed"]
    assert "snapped through a fold at 0.872262" in eq.solver.details["path"]
    cold = solve(volvox, nodes=400, continuation=False)
    end = follow_branch(volvox, nodes=400).end
    assert end.tau == 1 and end.stable
    for r, z in ((cold.r[-1], cold.z[-1]), (end.r_end, end.z_end),
                 (0.3903494154, 0.4628866317)):
        assert abs(eq.r[-1] - r) < 1e-8 and abs(eq.z[-1] - z) < 1e-8


@pytest.mark.parametrize("kind", ["fold", "branch_point"])
def test_a_target_just_past_an_event_is_solved_at_itself(volvox, blister, branch60, kind):
    """A target within the landing's overshoot past a fold (10^-6 in lambda) or a branch
    point (10^-4): the snap or switch had landed past lambda = 1, and solve() returned that
    state, at extrapolated parameters (energy 4e-6 off), and the quasi-static walk never
    reached lambda = 1 (user audit).  Now both end at the target itself, stable, where a
    warm solve there ends and where the followed branch ends."""
    if kind == "fold":
        base, nodes = volvox, 60
        event = next(pt for pt in branch60.events if pt.event == "fold")
        line = ParameterLine.between(branch60.line.source, volvox)
        target = line.at(event.tau * (1 + 1e-6))
    else:
        base, nodes = blister, 60
        event = follow_branch(blister, nodes=nodes).events[0]
        target = blister.with_updates(G=blister.params["G"] * event.tau * (1 + 1e-4))
    eq = solve(target, nodes=nodes)
    crossed = eq.solver.details["snaps" if kind == "fold" else "switches"]
    assert len(crossed) == 1 and crossed[0]["tau_after"] > 1      # the landing was past it
    assert eq.problem == target and eq.converged          # (a direct solve: a certified minimum)
    again = solver_of(eq).solve(target, warm_start=eq)
    assert abs(eq.energy - again.energy) < 1e-12 * abs(eq.energy)
    walk = follow_branch(target, nodes=nodes, follow="stable")
    assert walk.end.tau == 1 and walk.end.stable and walk.end.equilibrium.problem == target
    assert abs(walk.end.energy - eq.energy) < 1e-9 * abs(eq.energy)


def test_a_walk_that_leaves_the_parameters_ranges_ends_there_with_its_part(volvox,
                                                                         monkeypatch):
    """Beyond the path's ends the parameters are extrapolated and may leave their ranges
    (sigma below 1e-3 a step past a path to 1e-3: ParameterLine.invalid says so).  A branch
    that goes there ends at its last point within them with Branch_Ended and its part, not
    with the problem's ValueError, read as bad input (audit 17).  Forced here: the ranges
    made to end at lambda = 0.3."""
    line = ParameterLine.along(volvox, "sigma", 0.001)
    assert "sigma = " in line.invalid(1.02) and line.invalid(0.5) is None
    real = ParameterLine.invalid
    monkeypatch.setattr(ParameterLine, "invalid", lambda self, tau: "out of range (test)"
                        if tau > 0.3 else real(self, tau))
    with pytest.raises(SolverError) as err:
        follow_branch(volvox, nodes=40)
    assert err.value.status == "Branch_Ended"
    assert "it left the parameters' ranges at lambda = " in str(err.value)
    assert "out of range (test)" in str(err.value)
    taus = [pt.tau for pt in err.value.branch.points]
    assert 0.2 < taus[-1] <= 0.3 and taus == sorted(taus)


def _bounded(problem: Problem, name: str, sign: float) -> Problem:
    """``problem`` with a family whose range of ``name`` ends at its value (above it for
    ``sign`` = +1, below for −1): a path to it ends at a bound, as a path to sigma = 1e-3."""
    fam, bound = problem.family_obj, problem.params[name]

    def validate(values, cut, end):
        fam.validate(values, cut, end)
        if sign * (values[name] - bound) > 0:
            raise ValueError(f"parameter {name} = {values[name]!r} beyond its bound (test)")
    return replace(problem, family=replace(fam, validate=validate))


@pytest.mark.parametrize("kind", ["fold", "branch_point", "switch"])
def test_an_event_just_before_a_bound_is_crossed_at_the_paths_end(volvox, blister, branch60,
                                                                 kind, monkeypatch):
    """A fold or branch point within the descent's overshoot (1e-3 to 0.064 in lambda)
    before a path's end at a parameter's bound: the snap's or buckle's descent was solved
    beyond it, and the walk ended with the family's ValueError, read as bad input, naming
    a value never given (kappa2 = -6.8585 past -6.85069).  It is solved at the end itself,
    where an unbounded walk's landing is re-solved: the same state (energy to 1e-9
    relative past the fold, measured 7e-12; 1e-7 past the branch point, measured 6e-9:
    1e-4 past it the dome's mode is soft, and two minimisations there, one from a descent
    at lambda = 1.001, agree to the solver's tolerance over its stiffness).  So is the
    other branch's first point past the branch point (``switch``: the half followed, not
    the descent), 5e-5 of the way past the end in the walk, 3e-4 in solve(): it had been
    built there, G = 0.00304937 (walk) and 0.00305017 (solve) for 0.00304921; measured
    2e-9 (walk) and 5.5e-8 (solve) from the unbounded walk's end."""
    if kind == "fold":
        event = next(pt for pt in branch60.events if pt.event == "fold")
        target = ParameterLine.between(branch60.line.source, volvox).at(event.tau * (1 + 1e-6))
        name, sign, tol = "kappa2", -1.0, 1e-9
    else:
        if kind == "branch_point":       # (the descent: no half of the other branch)
            monkeypatch.setattr(Arclength, "first_step", lambda self, start, ds: None)
        event = follow_branch(blister, nodes=60).events[0]
        target = blister.with_updates(G=blister.params["G"] * event.tau * (1 + 1e-4))
        name, sign, tol = "G", 1.0, 1e-7
    free = follow_branch(target, nodes=60, follow="stable")
    bounded = _bounded(target, name, sign)
    line = ParameterLine.along(bounded, name, 0.0)
    assert line.invalid(-1e-6) is not None and line.clipped(-0.01) == 0.0
    assert line.clipped(0.5) == 0.5 and line.clipped(1.5) == 1.5
    walk = follow_branch(bounded, nodes=60, follow="stable")
    crossed = walk.snaps if kind == "fold" else walk.switches
    assert len(crossed) == 1 and crossed[0].tau_after == 1.0
    assert walk.end.tau == 1 and walk.end.stable
    assert all(walk.line.invalid(pt.tau) is None for pt in walk.points)
    assert abs(walk.end.energy - free.end.energy) < tol * free.end.energy
    eq = solve(bounded, nodes=60)
    assert abs(eq.energy - free.end.energy) < tol * free.end.energy


@pytest.mark.parametrize("bound", [False, True])
def test_a_fold_just_past_the_paths_end_is_not_reached(volvox, branch60, bound):
    """A target 1e-4 of the way before a fold: a step passed lambda = 1 and came back, the
    fold was located beyond the end and recorded there, and the quasi-static walk snapped
    from it, ending inverted (energy 0.01777) where the shell never gets to the fold and
    solve() ends unsnapped (0.02260); at a bound, the fold's own parameters are out of
    range, a ValueError.  The walk ends at lambda = 1 first, where solve() does (energy to
    1e-9 relative: measured 6e-13)."""
    event = next(pt for pt in branch60.events if pt.event == "fold")
    target = ParameterLine.between(branch60.line.source, volvox).at(event.tau * (1 - 1e-4))
    target = _bounded(target, "kappa2", -1.0) if bound else target
    eq = solve(target, nodes=60)
    for follow in ("branch", "stable"):
        walk = follow_branch(target, nodes=60, follow=follow)
        assert walk.events == [] and walk.end.tau == 1 and walk.end.stable
        assert abs(walk.end.energy - eq.energy) < 1e-9 * eq.energy


def test_no_stable_way_past_the_fold_is_a_named_error(volvox, monkeypatch):
    """When every descent from the fold slides back onto the fold's state (forced:
    ``_moved`` says so), solve() and the quasi-static walk raise Snap_Through_Failed with
    the fold's state attached; a walk out of points raises Branch_Ended with its last
    point."""
    with pytest.raises(SolverError) as err:
        follow_branch(volvox, nodes=60, max_points=20)
    assert err.value.status == "Branch_Ended" and "(20 points)" in str(err.value)
    last = err.value.last_iterate                        # the 20th point, before the fold
    assert last is not None and 0 < last.energy and "0.8722" not in str(err.value)
    monkeypatch.setattr(crossings, "_moved", lambda eq, before: False)
    for run in (lambda: solve(volvox, nodes=60),
                lambda: follow_branch(volvox, nodes=60, follow="stable")):
        with pytest.raises(SolverError) as err:
            run()
        assert err.value.status == "Snap_Through_Failed"
        last = err.value.last_iterate
        assert last is not None and not last.converged
        assert "fold at 0.8722" in str(err.value)           # (0.872298 on 60 nodes)


def test_paths_refuse_to_open_a_pole(volvox):
    """A cut or an opening from 0 to > 0 (or back) turns a pole into a free edge: refused."""
    closed = Problem("uniform", {"k": 0.5}, h=0.3)
    with pytest.raises(ValueError, match="cut"):
        ParameterLine.along(closed, "cut", 0.2)
    with pytest.raises(ValueError, match="cut"):
        ParameterLine.between(closed.with_updates(cut=0.2), closed)
    with pytest.raises(ValueError, match="cut"):
        follow_branch(closed, "cut", 0.2, nodes=60)
    assert volvox.cut == 0 and volvox.opening > 0
    with pytest.raises(ValueError, match="opening"):
        ParameterLine.along(volvox, "opening", 0.0)
    line = ParameterLine.along(volvox, "opening", 0.2)      # > 0 to > 0: fine
    assert line.names == ("opening",)


@pytest.fixture(scope="module")
def flat_disc(blister):
    """The blister's flat branch at 60 nodes: nine branch points, unstable at its end."""
    return follow_branch(blister, nodes=60)


@pytest.fixture(scope="module")
def domes(flat_disc):
    """Both halves of the branch through the flat disc's first branch point."""
    from morphoshell.solvers.branches import switch_branch

    return switch_branch(flat_disc, 0, 1), switch_branch(flat_disc, 0, -1)


def test_switching_at_the_first_branch_point_reaches_the_stable_dome(blister, flat_disc, domes):
    """The other branch through the first branch point (a pitchfork: the disc buckles up or
    down) is stable from its first step to lambda = 1, where it is the dome a cold Ipopt
    solve finds from a tilted start on the same mesh (unknowns to 1e-7, energy to 1e-10
    relative) with an energy 40 times below the flat disc's; its halves are mirror images."""
    from morphoshell.solvers.direct import solver_of

    up, down = domes
    bp = _events(flat_disc, "branch_point")[0]
    for half in domes:
        assert half.origin == flat_disc.points[bp].tau and half.points[0].event == "branch_point"
        assert all(pt.stable for pt in half.points[1:]), [pt.tau for pt in half.points
                                                          if not pt.stable]
        assert half.end.tau == 1 and half.end.energy < flat_disc.end.energy / 40
    assert up.end.z_end > 0.25 and up.end.psi_end > 0
    for a, b in zip(up.points, down.points):
        assert abs(a.tau - b.tau) < 1e-10 and abs(a.z_end + b.z_end) < 1e-10
    solver = solver_of(up.end.equilibrium)
    x0 = solver.disc.initial_guess(blister.parameter_vector())
    n = solver.disc.layout.free_points
    x0[n:2 * n] = 0.1 * solver.disc.points(blister.parameter_vector())[1:]   # tilt it up
    dome = solver.solve(blister, x0=x0)
    assert np.max(np.abs(dome.x - up.end.equilibrium.x)) < 1e-7
    assert abs(dome.energy - up.end.energy) < 1e-10 * dome.energy


def test_the_switched_tangent_leaves_the_branch_across_it(blister, flat_disc):
    """At the branch point the switched tangent is orthogonal to the flat branch's (the
    continuation's norm) and changes no parameter (a pitchfork); the flat disc's second
    branch point leads to a branch with one negative eigenvalue all along (the second
    buckling mode), and a fold is refused as no branch point."""
    from morphoshell.solvers.branches import switch_branch
    from morphoshell.solvers.direct import solver_of

    arc = Arclength(solver_of(flat_disc.end.equilibrium), flat_disc.line)
    pt = flat_disc.points[_events(flat_disc, "branch_point")[0]]
    own = arc.start(pt.equilibrium, pt.tau)
    other = arc.switch(own)
    assert abs(arc._weight @ (own.t * other.t) + own.t_tau * other.t_tau) < 1e-8
    assert abs(other.t_tau) < 1e-8 and abs(arc.norm(other.t, other.t_tau) - 1) < 1e-12
    second = switch_branch(flat_disc, 1, 1)
    assert {pt.negative_eigenvalues for pt in second.points[1:]} == {1}
    with pytest.raises(ValueError, match="the branch has 9 branch point"):
        switch_branch(flat_disc, 9)
    with pytest.raises(ValueError, match="direction = 0 must be"):
        switch_branch(flat_disc, 0, 0)


@pytest.mark.parametrize("call, error, match", [
    # accepted, then a Branch_Ended after the work (user audit)
    (lambda b: switch_branch(b, 0, 1, max_step=-1), ValueError, r"max_step = -1 must lie in \(0, 1\]"),
    (lambda b: switch_branch(b, 0, 1, max_step=0), ValueError, r"max_step = 0 must lie in"),
    (lambda b: switch_branch(b, 0, 1, max_points=1), ValueError,
     r"max_points = 1 must be an integer in \[2, 100000\]"),
    (lambda b: follow_branch(b.problem, nodes=60, max_points=-5), ValueError,
     r"max_points = -5 must be an integer in \[2, 100000\]"),
    (lambda b: follow_branch(b.problem, nodes=60, max_step=True), ValueError,
     r"max_step = True must be a real number"),
    (lambda b: follow_branch(b.problem.describe(), nodes=60), TypeError,
     r"problem = \{.*must be a morphoshell Problem"),
    # True == 1 passed for a direction; a float index raised a raw TypeError of a list
    (lambda b: switch_branch(b, 0, True), ValueError, r"direction = True must be \+1 or -1"),
    (lambda b: switch_branch(b, 1.0), TypeError, r"at = 1.0 must be an integer"),
    (lambda b: switch_branch(b.points, 0), TypeError, r"branch must be a Branch"),
])
def test_bad_walk_arguments_are_named_before_any_work(flat_disc, call, error, match):
    from morphoshell.solvers.routes import cache_info

    builds = cache_info()["builds"]
    with pytest.raises(error, match=match):
        call(flat_disc)
    assert cache_info()["builds"] == builds


def test_a_branch_ends_at_its_target_exactly_and_says_so_in_a_line():
    """0.5 + 1 (0.1 - 0.5) = 0.09999999999999998: BranchPoint.values said so at lambda = 1
    (user audit); repr(Branch) was a dump of every point (12-80 kB)."""
    problem = Problem("uniform", {"k": 0.5}, h=0.3, cut=0.5, name="toy2")
    line = ParameterLine.along(problem, "cut", 0.1)
    assert line.a + 1.0 * (line.b - line.a) != line.b          # (the case in point)
    assert line.values(1.0) == {"cut": 0.1} and line.values(0.0) == {"cut": 0.5}
    assert line.values(0.5) == {"cut": 0.5 + 0.5 * (0.1 - 0.5)}
    branch = follow_branch(problem, "cut", 0.1, nodes=40)
    assert branch.end.tau == 1.0 and branch.end.values == {"cut": 0.1}
    assert branch.end.values["cut"] == branch.end.equilibrium.problem.cut
    text = repr(branch)
    assert "\n" not in text and len(text) < 300, text
    assert text == (f"Branch('toy2', cut: 0.5 -> 0.1, follow='branch', {len(branch.points)} points, "
                    f"lambda in [0, 1], cut in [0.1, 0.5], events: none, 0 snaps)")
    assert branch.to_dict()["units"]["cut"] == "R"
    assert branch.to_dataframe().attrs["units"]["cut"] == "R"


def test_a_fold_is_no_branch_point_to_switch_at(branch60):
    from morphoshell.solvers.direct import solver_of

    arc = Arclength(solver_of(branch60.end.equilibrium), branch60.line)
    fold = branch60.points[_events(branch60, "fold")[0]]
    with pytest.raises(ValueError, match="a fold, not a branch point"):
        arc.switch(arc.start(fold.equilibrium, fold.tau))


def test_solve_switches_to_the_stable_branch_where_the_flat_disc_buckles(blister, domes):
    """solve() on the blister: natural continuation stalls where the flat disc loses its
    stability (no fold: a branch point); it switches to the stable half of the branch through
    it and goes on to the dome of switch_branch (energy to 1e-10 relative, edge to 1e-9 R),
    saying so in its path.  A fit's inner solve (continue_to without switch) still stops there,
    named."""
    from morphoshell.solvers.continuation import continue_to
    from morphoshell.solvers.direct import solver_of

    eq = solve(blister, nodes=60)
    up = domes[0].end
    assert eq.converged                 # (certified a minimum, as every solve)
    assert abs(eq.energy - up.energy) < 1e-10 * up.energy
    assert abs(eq.z[-1] - up.z_end) < 1e-9 and abs(eq.r[-1] - up.r_end) < 1e-9
    switch, = eq.solver.details["switches"]
    assert abs(switch["tau"] - domes[0].origin) < 1e-8 and switch["direction"] == 1.0
    assert "switched branches at a branch point at 0.0152445" in eq.solver.details["path"]
    with pytest.raises(SolverError) as exc:
        continue_to(solver_of(up.equilibrium), blister)
    assert exc.value.status == "Continuation_Failed" and "reaches the target unstable" in \
        str(exc.value)


def test_the_quasi_static_path_buckles_onto_the_stable_dome(blister, domes):
    """follow="stable" (what a slowly grown disc does): flat up to the first branch point,
    where it loses its stability, then the stable half of the dome branch to lambda = 1,
    every ordinary point stable (before, the walk went on along the unstable flat disc); the
    end is switch_branch's dome (energy to 1e-10 relative)."""
    path = follow_branch(blister, nodes=60, follow="stable")
    switch, = path.switches
    assert abs(switch.tau - domes[0].origin) < 1e-8 and switch.direction == 1.0
    assert [pt.event for pt in path.events] == ["branch_point"]
    assert all(pt.stable for pt in path.points if not pt.event)
    assert path.end.tau == 1 and abs(path.end.energy - domes[0].end.energy) < \
        1e-10 * domes[0].end.energy
    assert path.to_dict()["switches"][0]["tau"] == switch.tau


def test_where_no_half_can_be_followed_the_shell_buckles_down_its_unstable_mode(blister, domes,
                                                                                monkeypatch):
    """When no step onto the other branch works (a subcritical branch point, where the shell
    jumps, or a corrector that fails), solve() leaves the branch point as the shell would:
    minimised down its unstable mode just past it, then on to lambda = 1, named in its path;
    here it lands on the same dome as switching does (energy to 1e-9 relative), as does the
    quasi-static walk (follow="stable")."""
    monkeypatch.setattr(Arclength, "first_step", lambda self, start, ds: None)
    eq = solve(blister, nodes=60)
    switch, = eq.solver.details["switches"]
    assert switch["descent"] and abs(switch["tau"] - domes[0].origin) < 1e-8
    assert switch["tau_after"] == pytest.approx(switch["tau"] + crossings.BUCKLE_OVERSHOOT)
    assert "buckled at a branch point at 0.0152445" in eq.solver.details["path"]
    assert abs(eq.energy - domes[0].end.energy) < 1e-9 * eq.energy
    path = follow_branch(blister, nodes=60, follow="stable")      # the quasi-static walk too
    assert path.switches[0].descent and path.end.stable
    assert abs(path.end.energy - domes[0].end.energy) < 1e-9 * eq.energy


@pytest.fixture(scope="module")
def thin_disc():
    """The blister at h = 1e-3: its first branch point at lambda = 3.8e-5 (proportional to
    h^2), its KKT matrix with other eigenvalues near zero (a pair of unknowns at the centre)."""
    return follow_branch(Problem("central_growth", {"G": 0.2}, h=1e-3, geometry="disc"),
                         nodes=60)


def test_a_thin_disc_switches_at_its_first_branch_points(thin_disc):
    """Every branch point is located, one per negative eigenvalue gained (before: one step
    passed ten, recorded as one); switching at the first three gives branches that leave
    with 0, 1 and 2 negative eigenvalues.  solve() ends on the switched dome
    (energy to 1e-10 relative), 40x below the unstable flat disc; 100 nodes give its energy
    to 2e-5."""
    assert thin_disc.events[0].tau == pytest.approx(3.838e-5, rel=1e-3)
    assert [pt.negative_eigenvalues for pt in thin_disc.events[:15]] == list(range(15))
    dome = switch_branch(thin_disc, 0, +1)
    for k in (1, 2):
        other = switch_branch(thin_disc, k, +1)
        assert other.end.tau == 1 and abs(other.end.psi_end) > 0.01       # off the flat disc
        assert other.points[1].negative_eigenvalues == k
    assert all(pt.stable for pt in dome.points[1:]) and dome.end.tau == 1
    eq = solve(thin_disc.problem, nodes=60)
    switch, = eq.solver.details["switches"]
    assert not switch["descent"] and abs(switch["tau"] - thin_disc.events[0].tau) < 1e-12
    assert abs(eq.energy - dome.end.energy) < 1e-10 * eq.energy
    assert eq.energy < thin_disc.end.energy / 40
    assert solve(thin_disc.problem, nodes=100).energy == pytest.approx(eq.energy, rel=2e-5)


def test_branch_points_of_a_thinner_disc_are_located_closely_enough_to_switch(monkeypatch):
    """At h = 1e-2 on 200 nodes, the first branch point (tau = 0.0038) located to 1e-9 left
    the null vector unconverged (inverse iterations changing it by 2e-5) and solve() failed;
    located to 1e-11 the switch goes along the other branch, and lands where minimisation down
    the unstable mode lands (the descent, a route without the other branch: to 1e-10)."""
    disc = Problem("central_growth", {"G": 0.2}, h=1e-2, geometry="disc")
    eq = solve(disc, nodes=200)
    switch, = eq.solver.details["switches"]
    assert not switch["descent"] and switch["tau"] == pytest.approx(0.0038312, rel=1e-5)
    monkeypatch.setattr(Arclength, "first_step", lambda self, start, ds: None)
    descended = solve(disc, nodes=200)
    assert descended.solver.details["switches"][0]["descent"]
    assert abs(descended.energy - eq.energy) < 1e-10 * eq.energy


def test_a_parameter_branch_starts_where_solve_does(blister):
    """Along h the branch starts at the problem's solution as solve() finds it: the blister's
    dome, past the branch point where the flat disc buckles (before, its start stopped there,
    Continuation_Failed), and at h = 0.01 ends on the dome that the stress-free path reaches
    at that h on the same mesh (energy to 1e-9)."""
    from morphoshell.solvers.continuation import continue_to

    branch = follow_branch(blister, "h", 0.01, nodes=60)
    assert branch.points[0].stable and branch.points[0].z_end > 0.25
    assert branch.end.tau == 1 and branch.end.stable
    target = blister.with_updates(h=0.01)
    direct = continue_to(solver_of(branch.end.equilibrium), target, switch=True)
    assert abs(direct.energy - branch.end.energy) < 1e-9 * direct.energy


def test_the_switched_half_is_the_one_whose_rim_rises():
    """Direction +1 is the half along which the far end rises, whatever the parameters, and a
    solve keeps to it after the switch (it goes on by arclength steps 0.01 in lambda before
    natural ones: at G = 0.005 the first natural steps from next to the branch point jumped
    to the mirror half, z_end -0.034, while the switch said +1): the blister's solves and a
    sweep of it all rise."""
    from morphoshell.workflows.sweeps import sweep

    for G in (0.005, 0.2):
        eq = solve(Problem("central_growth", {"G": G}, h=0.02, geometry="disc"), nodes=60)
        assert eq.z[-1] > 0.03 and eq.solver.details["switches"][0]["direction"] == 1.0
    table = sweep(Problem("central_growth", {"G": 0.2}, h=0.02, geometry="disc"),
                  {"G": [0.005, 0.02, 0.2], "h": [0.01, 0.02]}, nodes=60,
                  workers=1).to_dataframe()
    assert (table["z_end"] > 0.03).all(), table[["G", "h", "z_end"]]


def test_a_barely_grown_thin_annulus_buckles_by_a_tiny_amount():
    """(make fuzz) An annulus cut beyond the grown centre (G = 0.1, w = 0.1, Sigma = 1/3,
    h = 1e-4: energies of 1e-20) loses stability at lambda = 0.16 where neither half of the
    other branch can be followed; minimised down its unstable mode it buckles by 3e-5 (its
    unknowns), which the snap-through's test of having left the point (1e-3) refused:
    Continuation_Failed.  A certified minimum there is off the unstable point whatever its
    distance; the two meshes agree on it as the scheme's fourth order says (energy 1.4e-6
    apart, 6e-8 between 200 and 399 nodes; z_end 4e-7)."""
    annulus = Problem("central_growth", {"G": 0.1, "w": 0.1}, h=1e-4, cut=1 / 3,
                      geometry="disc")
    a, b = solve(annulus, nodes=100), solve(annulus, nodes=200)
    assert a.solver.details["switches"][0]["descent"]
    assert abs(a.energy - b.energy) < 3e-6 * b.energy and b.z[-1] > 1e-4
    assert abs(a.z[-1] - b.z[-1]) < 1e-6 * b.z[-1]


def test_a_cut_shells_z_end_is_its_height_above_the_first_point():
    """z_end of a branch is what a sweep and an error estimate call z_end, the far end's
    height above the first point; it had been z there in solve's gauge, 1 - cos(cut) more
    on a cut shell (user audit)."""
    problem = Problem("uniform", {"k": 0.5}, h=0.3, cut=0.3)
    end = follow_branch(problem, nodes=40).end
    eq = solve(problem, nodes=40)
    assert abs(eq.z[0] - (1 - np.cos(0.3))) < 1e-12             # the gauge: not 0 here
    assert abs(end.z_end - eq.estimated_values()["z_end"]) < 1e-9


@pytest.mark.parametrize("param, to", [("s1", 1.0), ("opening", 0.8)])
def test_a_parameter_that_moves_the_knots_is_followed_on_rebuilt_meshes(volvox, param, to,
                                                                        monkeypatch):
    """Breakpoints and the opening move the mesh's knots with the parameters; on its first
    mesh a knot passed its neighbour and the folded mesh's inertia made spurious branch
    points (s1 0.65 -> 1: three, the end "unstable" with 12 negative eigenvalues; opening
    0.3 -> 0.8: fifteen, 80 negative; a user audit). Rebuilt where a cell is stretched
    twofold, the branch has no event and every point is stable; its end is next to the
    strict minimum on the mesh solve() builds for the end (a warm solve there: the energy
    within 1e-6, the two 100-node meshes' knots at other places: measured 9e-9 and 4e-14).
    With the mesh kept, the spurious branch points come back."""
    from morphoshell.solvers import branches
    from morphoshell.solvers.routes import direct_solver

    branch = follow_branch(volvox, param, to, nodes=100)
    assert branch.remeshed and not branch.events
    assert all(pt.stable for pt in branch.points)
    end = branch.end.equilibrium
    again = direct_solver(end.problem, 100).solve(end.problem, warm_start=end)
    assert again.energy == pytest.approx(end.energy, rel=1e-6)
    monkeypatch.setattr(branches._Walk, "_holds", lambda self, new: True)
    kept = follow_branch(volvox, param, to, nodes=100)
    assert not kept.remeshed and _events(kept, "branch_point")


def test_the_blister_buckles_on_a_fine_mesh_too(blister, monkeypatch):
    """The packaged blister solved at 200-400 nodes and failed from 600 (a user audit:
    "try a finer mesh" where finer failed): past its branch point the disc is moved down
    the unstable mode and minimised, and a move of unit Euclidean length, whose entries
    shrink like 1/sqrt(n), ended back at the flat saddle. A move of unit root mean square
    leaves it: the 600-node dome is the 400-node one to 1e-8 (their estimates: ~1e-8).
    That descent is the fall-back where no half of the other branch is followed: since
    the null vector is found among the soft modes (audit 22 F2) the switch itself works
    there, so it is made to fail."""
    coarse = solve(blister, nodes=400)
    assert "switched branches" in coarse.solver.details["path"]
    monkeypatch.setattr(Arclength, "switch", _no_switch)
    fine = solve(blister, nodes=600)
    assert "buckled" in fine.solver.details["path"]
    assert fine.energy == pytest.approx(coarse.energy, rel=1e-7)
    assert fine.z[-1] - fine.z[0] == pytest.approx(coarse.z[-1] - coarse.z[0], rel=1e-6)


def _no_switch(arc, point, direction=1.0, sign=-1.0, mode=None):
    raise ValueError("no switch (test)")


def test_a_continuation_that_fails_on_a_fine_mesh_is_solved_from_a_coarser_one(blister,
                                                                              monkeypatch):
    """The blister's crossing of its branch point failed from 800 nodes (its modes crowded:
    audit 22 F2, since fixed, so the crossing is made to fail there), where a solve refined
    for rtol reaches 3185: solve() continues on a coarser mesh and solves on its own from
    there, saying so. The 800-node dome is the 400-node one to 1e-8 (both estimates ~1e-9
    relative; 1600 and 3200 nodes: 7.9262731748e-7 C R^2, the same rising half). Without
    the coarser mesh the solve fails."""
    from morphoshell.solvers import routes

    real = crossings.switch_stable

    def fails_when_fine(arc, bp, ds, *args, **kwargs):
        if arc.solver.nodes >= 800:
            raise crossings.branch_ended(bp.tau, "no crossing (test)", None)
        return real(arc, bp, ds, *args, **kwargs)

    monkeypatch.setattr(crossings, "switch_stable", fails_when_fine)
    fine, coarse = solve(blister, nodes=800), solve(blister, nodes=400)
    assert "(on 800 it failed), then solved on 800 nodes from there" in \
        fine.solver.details["path"]
    assert fine.energy == pytest.approx(coarse.energy, rel=1e-8)
    assert fine.z[-1] - fine.z[0] == pytest.approx(coarse.z[-1] - coarse.z[0], rel=1e-6)
    monkeypatch.setattr(routes, "COARSEST", 10**6)
    with pytest.raises(SolverError):
        solve(blister, nodes=800)


def test_the_blister_switches_where_soft_modes_crowd_near_zero(blister):
    """On 400-800 nodes the flat disc's KKT matrix has two soft positive eigenvalues near
    the branch point's (1.7e-12 and 4.6e-12 at 800 nodes, N^-7, against its -4.6e-11):
    ten inverse iterations of one vector did not converge there and switching failed at
    every branch point ("not a located branch point", audit 22 F2). The mode that changed
    sign is the negative one nearest zero (the located point is past the loss of
    stability): found among six by subspace iteration, converged and told apart at the
    first three, where the switch works (at the third: a branch with 2 negative
    eigenvalues; solve() on 400 nodes: test_the_blister_buckles_on_a_fine_mesh_too)."""
    flat = follow_branch(blister, nodes=800)
    other = switch_branch(flat, 2, +1)
    assert other.end.tau == 1 and other.end.z_end > 0.01       # off the flat disc
    assert other.points[1].negative_eigenvalues == 2
    for bp in flat.events[:3]:
        arc = Arclength(solver_of(bp.equilibrium), flat.line, bp.equilibrium.anchors,
                        at=bp.tau)
        mode = arc.null_vector(arc.start(bp.equilibrium, bp.tau))
        # located to 1e-11 in lambda, its eigenvalue is -3e-11 to -6e-11 (the soft ones'
        # +1.7e-12, +4.6e-12, the next 4e-10): -1e-9 bounds it with room; crowding is
        # SEPARATION's bound, here ~5e-3 (over the farthest of the six)
        assert -1e-9 < mode.value < 0 and mode.change < 1e-8 and mode.crowding < 0.1


def test_a_branch_whose_shown_shapes_overlap_says_so(volvox, caplog):
    """The fold shell's end and its last two folds pass through themselves (walls 0.064 R
    apart at h = 0.15; a user audit saw it in the docs' figures): the branch warns, naming
    those λ, as solve() does; the blister's domes do not overlap and say nothing."""
    from morphoshell import example_path, load_problem

    with caplog.at_level("WARNING", logger="morphoshell.solvers.branches"):
        follow_branch(volvox, nodes=60)
    assert "at lambda = 0.545971, 0.546549, 1 have walls that pass through each other" \
        in caplog.text
    caplog.clear()
    with caplog.at_level("WARNING", logger="morphoshell.solvers.branches"):
        follow_branch(load_problem(example_path("blister"))[0], nodes=40)
    assert "pass through" not in caplog.text


def test_a_branch_that_turns_back_off_the_path_says_so(volvox):
    """Started at the everted branch's fold in κ₂ (-6.5738549 on 200 nodes, audit 14 F4), the
    branch turns back along its unstable part and leaves the path beyond λ = -0.5: the
    message names that fold and what helps, not a smaller step or a finer mesh (neither
    happened nor helps)."""
    at_fold = volvox.with_updates(kappa2=-6.573854)
    with pytest.raises(SolverError) as ended:
        follow_branch(at_fold, "kappa2", -8.0, nodes=200)
    text = str(ended.value)
    assert ended.value.status == "Branch_Ended" and "it left the path" in text
    assert "turned back at the fold at lambda" in text and "(kappa2 = -6.57385)" in text
    assert "beyond lambda = -0.5" in text and "--follow stable" in text
    assert "smaller --max-step" not in text
@pytest.fixture(scope="module")
def cap_branch():
    """A uniform cap with a cut (toy 1, h = 0.05, cut 1) continued in k from 1 to 3 on 40
    nodes: its far end is the pole (ψ = π, r = 0 at every point)."""
    from morphoshell import example_path, load_problem

    cap = load_problem(example_path("toy1_sphere"))[0].with_updates(h=0.05, cut=1.0, k=1.0)
    return follow_branch(cap, "k", 3.0, nodes=40)


def test_the_start_shape_is_checked_for_walls_that_cross(cap_branch, monkeypatch, caplog):
    """The plot draws the branch's start; the walls' warning checked only the events and
    the end (audit 14: the fold shell's own state at kappa2 = -8, crossed, passed without
    a word).  Here only the start's walls cross (wall_contact stubbed): the warning names
    lambda = 0."""
    from morphoshell.solvers import branches

    start = cap_branch.points[0].equilibrium
    monkeypatch.setattr(branches, "wall_contact", lambda eq: "crossed" if eq is start else None)
    with caplog.at_level("WARNING", logger="morphoshell.solvers.branches"):
        branches._checked(cap_branch, branches.MAX_STEP, 0.0)
    assert "the shapes of the branch at lambda = 0 have walls that pass through" in caplog.text


def test_a_family_parameter_continued_in_has_the_familys_unit(volvox):
    """kappa2 had no unit in the branch's units (JSON, plot), where a sweep gives the
    family's declared 1/R (audit 14); h keeps R, the path fraction 1."""
    units = follow_branch(volvox, "kappa2", -7.9, nodes=40).units()
    assert units["kappa2"] == "1/R" and units["lambda"] == "1"
    assert list(units)[:2] == ["lambda", "kappa2"]


def test_a_branch_that_stops_early_goes_with_its_error(volvox):
    """The SolverError of a walk that stopped early (here max_points) carries the branch
    followed up to there (it had only the last point), marked: ended says why, the JSON's
    complete is False; a complete branch has neither key."""
    with pytest.raises(SolverError) as info:
        follow_branch(volvox, nodes=40, max_points=5)
    part = info.value.branch
    assert len(part.points) == 5 and "the points ran out" in part.ended.why
    assert part.ended.stopped and part.ended.tau == part.end.tau
    assert part.to_dict()["complete"] is False
    assert part.to_dict()["ended"] == part.ended.to_dict()
    whole = follow_branch(volvox, "kappa2", -7.9, nodes=40)
    assert whole.ended is None and "complete" not in whole.to_dict()


def test_a_branch_on_meshes_that_miss_the_steps_warns(caplog):
    """Continued to sigma = 0.001 R (the low end of its range), the points of a 200-node
    mesh were 5e-4 R off at the edges and its events' estimates made on two meshes that both
    miss the steps, without a word (audit 22, F8): it warns at the start, naming the
    nodes needed, for the narrower end of the path; the default 0.05 R does not."""
    import logging

    problem = load_problem(FIXTURE)[0]
    with caplog.at_level(logging.WARNING, logger="morphoshell"):
        with pytest.raises(SolverError):        # (two points: the warning comes first)
            follow_branch(problem, "sigma", 0.001, nodes=40, max_points=2)
    assert "smoothed steps of width 0.001 R" in caplog.text and "use 1249 nodes" in caplog.text
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="morphoshell"):
        with pytest.raises(SolverError):
            follow_branch(problem, "sigma", 0.1, nodes=40, max_points=2)
    assert "smoothed steps" not in caplog.text
