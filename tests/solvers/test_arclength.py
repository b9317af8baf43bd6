"""Pseudo-arclength continuation at a fold (issue 38): located, with the right normal form,
the inertia changing exactly there, convergent with the mesh and agreeing with the BVP route.

The fold is the first one of the Volvox shell of ``tests/data/volvox_fold.toml`` on its
path from the stress-free parameters (λ ≈ 0.87226), reached by a few arclength steps
from a natural-continuation solution just before it.
"""
from pathlib import Path

import numpy as np
import pytest

from morphoshell import Problem, SolverError, solve
from morphoshell.io.problem_files import load_problem
from morphoshell.solvers import arclength, crossings
from morphoshell.solvers.arclength import Arclength
from morphoshell.solvers.crossings import snap_through
from morphoshell.solvers.continuation import continue_to
from morphoshell.solvers.paths import ParameterLine, neutral_problem
from morphoshell.solvers.routes import direct_solver

FIXTURE = Path(__file__).resolve().parents[1] / "data" / "volvox_fold.toml"


@pytest.fixture(scope="module")
def volvox():
    return load_problem(FIXTURE)[0]


def near_fold(problem, nodes, max_step=0.02, tau0=0.85):
    """(arc, the last point before the first fold, the step that crossed it) on ``nodes``
    nodes: arclength steps (as follow_branch's) from the natural-continuation solution
    at ``tau0``."""
    solver = direct_solver(problem, nodes, (), stages=2)
    line = ParameterLine.between(neutral_problem(problem), problem)
    arc = Arclength(solver, line)
    point = arc.start(continue_to(solver, line.at(tau0), ()), tau0)
    ds = max_step / 4
    for _ in range(200):
        new = arc.correct(point, ds)
        if new is None or arc.turned(point, new):
            ds /= 2
            continue
        if new.t_tau < 0:
            return arc, point, ds
        point = new
        ds = min(arclength.GROWTH * ds, max_step) if new.iterations <= arclength.EASY else ds
    raise AssertionError("no fold found")


@pytest.fixture(scope="module")
def fold100(volvox):
    arc, prev, ds = near_fold(volvox, 100)
    return arc, prev, ds, arc.locate_fold(prev, ds)


def test_fold_is_located_to_1e8_whatever_the_bracket(volvox, fold100):
    """Another start, another step (hence another Brent bracket): the same fold to 1e-8 in
    λ; the tangent there is vertical (t_τ = 0 to the located arclength times the
    curvature of τ(s), ~20 × 1e-9)."""
    arc, prev, ds, fold = fold100
    other_arc, other_prev, other_ds = near_fold(volvox, 100, max_step=0.01, tau0=0.8)
    assert other_ds != ds and other_prev.tau != prev.tau
    other = other_arc.locate_fold(other_prev, other_ds)
    assert abs(other.tau - fold.tau) < 1e-8
    # a bracket cut at the fold's far side: still the same root
    assert abs(arc.locate_fold(prev, 0.5 * ds + 0.5 * _s(arc, prev, fold)).tau - fold.tau) < 1e-8
    for point in (fold, other):
        assert abs(point.t_tau) < 1e-6
    # and the fold is a maximum of λ: every point of the branch near it lies below
    assert fold.tau > prev.tau and fold.tau > arc.correct(fold, 1e-3).tau


def _s(arc, prev, fold):
    """The fold's arclength from ``prev`` (the border row's measure)."""
    du = arc.kkt.free(fold.u) - arc.kkt.free(prev.u)
    return float(arc._weight * prev.t @ du + prev.t_tau * (fold.tau - prev.tau))


def test_inertia_changes_exactly_at_the_fold(fold100):
    """Stable up to the fold, one negative eigenvalue right after it: 1e-6 of arclength
    (λ within 1e-11 of the fold's) either side."""
    arc, prev, ds, fold = fold100
    assert prev.inertia.negative == 0 and prev.inertia.zero == 0
    before, after = arc.correct(fold, -1e-6), arc.correct(fold, 1e-6)
    assert before.inertia.negative == 0 and before.inertia.stable
    assert after.inertia.negative == 1
    assert abs(before.tau - fold.tau) < 1e-10 and abs(after.tau - fold.tau) < 1e-10


def test_fold_has_the_quadratic_normal_form(fold100):
    """τ_f − τ ≈ c (y − y_f)² for the rim's height y = z_end on both sides: the exponent of
    |τ − τ_f| against |y − y_f|, fitted over arclengths 2e-3 ... 2e-2 from the fold, is 2
    (observed 1.998 and 2.002; within 0.05: the cubic term of the expansion changes the
    local slope by O(δ) ~ 1e-2 over this range; a cusp would give 3/2 or 3, a transcritical
    point 1).  Not r_end: the rim's radius hardly moves along the fold's null direction
    (its first-order change nearly vanishes), so its fitted exponent is meaningless."""
    arc, prev, ds, fold = fold100
    y_f = arc.equilibrium(fold).z[-1]
    for side in (-1.0, 1.0):
        dtau, dy = [], []
        for delta in np.geomspace(2e-3, 2e-2, 6):
            point = arc.correct(fold, side * delta)
            dtau.append(fold.tau - point.tau)
            dy.append(abs(arc.equilibrium(point).z[-1] - y_f))
        assert min(dtau) > 0                     # λ turns back on both sides
        slope = np.polyfit(np.log(dy), np.log(dtau), 1)[0]
        assert abs(slope - 2) < 0.05, (side, slope)


def test_fold_converges_with_the_mesh_at_the_schemes_order(volvox):
    """Gauss–Legendre with 2 stages is of order 4: the fold's λ on meshes of N·√2ᵏ nodes
    changes by factors (√2)⁴ = 4 (observed 3.7–4.1 from N = 100 on; at least 3.5)."""
    nodes = (100, 141, 200, 283, 400)
    taus = []
    for n in nodes:
        arc, prev, ds = near_fold(volvox, n)
        taus.append(arc.locate_fold(prev, ds).tau)
    diffs = np.abs(np.diff(taus))
    orders = np.log(diffs[:-1] / diffs[1:]) / np.log(np.sqrt(2))
    assert np.all(orders > 3.5), orders
    assert abs(taus[-1] - 0.8722619) < 1e-7          # the value (400 nodes)


def test_fold_agrees_with_the_bvp_route(volvox):
    """The BVP route (independent collocation, ``solve_bvp``) on the stable side 1e-3 below
    the 400-node fold gives the arclength point there to 1e-6 (rim and angle; observed
    3e-7 in z, which varies like √(τ_f − τ) here), converges 1e-5 below the fold and
    fails 1e-5 above it, warm-started from there: its own fold is within 1e-5 of ours."""
    arc, prev, ds = near_fold(volvox, 400)
    fold = arc.locate_fold(prev, ds)
    tau = fold.tau - 1e-3
    point = arc.at_tau(arc.correct(fold, -np.sqrt(1e-3 / 8.4)), tau)   # τ_f − τ ≈ 8.4 δ²
    mine = arc.equilibrium(point)
    bvp = solve(arc.line.at(tau), method="bvp")
    assert bvp.solver.method == "bvp"
    for name in ("r", "z", "psi"):
        assert abs(getattr(bvp, name)[-1] - getattr(mine, name)[-1]) < 1e-6, name
    assert abs(bvp.energy - mine.energy) < 1e-8
    below = solve(arc.line.at(fold.tau - 1e-5), method="bvp", warm_start=bvp)
    assert abs(below.z[-1] - arc.equilibrium(fold).z[-1]) < 1e-2      # still on the branch
    with pytest.raises(SolverError):
        solve(arc.line.at(fold.tau + 1e-5), method="bvp", warm_start=below, max_seconds=4)


def test_snap_through_lands_lower_or_fails_by_name(fold100, monkeypatch):
    """From the located fold the shell snaps to a stable state of lower energy; when every
    descent slides back onto the fold's state (forced here), a named error with the
    fold's state attached."""
    arc, prev, ds, fold = fold100
    eq, snap = snap_through(arc, fold)
    assert eq.converged and snap.tau == fold.tau and snap.tau_after > fold.tau
    assert snap.energy_landed < snap.energy_before and snap.energy_after < snap.energy_before
    monkeypatch.setattr(crossings, "_moved", lambda eq, before: False)
    with pytest.raises(SolverError) as err:
        snap_through(arc, fold)
    assert err.value.status == "Snap_Through_Failed"
    last = err.value.last_iterate
    assert last is not None and not last.converged
    assert abs(last.energy - snap.energy_before) < 1e-12


def test_a_small_snap_is_judged_at_the_folds_own_tau():
    """A thin sphere's free edge curls over at a fold (make fuzz's reproducer: h = 4.4e-4,
    ψ at the edge jumps by 2.2 rad): the snap releases 1.7e-10 C R², while the energy grows
    by 1.7e-7 over the 1e-3 in τ past the fold where the landing is solved, so comparing
    the landing with the fold across τ refused it (``Snap_Through_Failed``). Judged at the
    fold's τ, the solve snaps, at the same fold and to the same end on 400 and 600 nodes
    (the fold to 2e-4 in τ, the energy to 1e-6 relative; 800 nodes: fold 0.829448,
    energy 7.977922e-5 C R², 7.5e-7 relative from 400's). The coarser 300-node mesh (its
    error estimate warns) has a second fold at τ = 0.968 that 400 and 800 nodes do not
    have, past which no landing is found: a named ``Snap_Through_Failed``."""
    problem = Problem("anisotropic", {"f0": -0.278375609690089}, h=4.3723617825288633e-4,
                      cut=0.02)
    ends = []
    for nodes in (400, 600):
        eq = solve(problem, nodes=nodes)
        (snap,) = eq.solver.details["snaps"]
        assert abs(snap["tau"] - 0.829448) < 2e-4
        released = snap["energy_before"] - snap["energy_landed"]
        assert 1e-10 < released < 3e-10 < snap["energy_after"] - snap["energy_before"]
        ends.append(eq.energy)
    assert abs(ends[0] - ends[1]) < 1e-6 * ends[1] and abs(ends[1] - 7.977922e-5) < 1e-10
    with pytest.raises(SolverError) as exc:
        solve(problem, nodes=300)
    assert exc.value.status == "Snap_Through_Failed" and "0.967737" in str(exc.value)


def test_fold_location_survives_a_failed_corrector(volvox):
    """A corrector that fails inside Brent's bracket (as it may next to a fold) leaves the
    bracket's best point, not None (which the walk then recorded: an AttributeError
    instead of a branch; found by a second verification run)."""
    arc, prev, ds = near_fold(volvox, 60)
    correct, calls, failed = arc.correct, [], []

    def flaky(start, s):
        calls.append(s)
        if 0 < s < ds and len(calls) > 3:           # from Brent's second inner step on
            failed.append(s)
            return None
        return correct(start, s)
    arc.correct = flaky
    located = arc.locate_fold(prev, ds)
    assert failed and located is not None
    ends = [correct(prev, 0.0).t_tau, correct(prev, ds).t_tau]
    assert abs(located.t_tau) <= min(map(abs, ends))


def test_the_walk_past_a_stall_stops_where_it_reaches_the_target_unstable(monkeypatch):
    """A branch that goes on past τ = 1 on unstable points (its stability lost without a
    fold) ends there, "Branch_Ended", instead of walking on to the 200th point: beyond
    τ = 1 the parameters are extrapolated (the synthetic campaign's walks reached τ = 4.8,
    where the breakpoints cross, 0.9 s each for nothing). Cheap fake branch: τ grows
    with the arclength, every point unstable."""
    import types

    asked = []

    class Branch:
        def __init__(self, solver, line, anchors):
            pass

        def start(self, eq, tau, direction):
            return types.SimpleNamespace(tau=tau, t_tau=1.0, iterations=1,
                                         inertia=types.SimpleNamespace(stable=True))

        def correct(self, prev, ds):
            asked.append(prev.tau + ds)
            return types.SimpleNamespace(tau=prev.tau + ds, t_tau=1.0, iterations=1,
                                         inertia=types.SimpleNamespace(stable=False))

        def turned(self, prev, new):
            return False

        def at_tau(self, prev, tau):
            return None

        def equilibrium(self, point):
            return f"state at {point.tau:.3f}"

    monkeypatch.setattr(crossings, "Arclength", Branch)
    with pytest.raises(SolverError) as info:
        crossings.cross_fold(None, None, None, 0.9)
    assert info.value.status == "Branch_Ended"
    assert max(asked) <= 1 + arclength.MAX_STEP and len(asked) < 30
    assert info.value.last_iterate.startswith("state at 0.9")


@pytest.mark.parametrize("nodes", [100, 200])
def test_a_weakly_singular_pole_does_not_stall_the_continuation(nodes):
    """The anisotropic shell (toy problem 3, h = Σ = 0.3) to f0 = −0.62: its stretches at the
    far pole are singular, f_s ~ d^(β−1) with β = 0.13 (the pole's exponent), and the mesh
    puts ever more unknowns ever nearer to it.  Their mean square dominated the norm and the
    walk ran out of its 2000 points at 100 nodes (λ = 0.80 of 5000 at 200; a user audit);
    capped by their share of the pole's area, it takes 180 and 167 (91-93 at 400-800 with a
    wider cap).  The end is solve()'s at f0 = −0.62: the same Newton tolerance on one mesh,
    so the energies agree to round-off (6e-14 seen; 1e-10 bound)."""
    from morphoshell import follow_branch

    problem = Problem("anisotropic", {"f0": 0.1}, h=0.3, cut=0.3)
    branch = follow_branch(problem, "f0", -0.62, nodes=nodes)
    ref = solve(problem.with_updates(f0=-0.62), nodes=nodes)
    assert branch.end.tau == 1 and len(branch.points) < 400
    assert abs(branch.end.energy - ref.energy) < 1e-10 * abs(ref.energy)


def test_a_soft_corrector_is_taken_at_tol_not_after_one_slow_step(blister):
    """A corrector's Newton step that cuts the KKT error only a few-fold is no round-off
    floor: the blister 1e-3 past its first branch point (60 nodes), where the dome's mode is
    soft, had its stable walk end after one step from 1.5e-6 to 2.0e-7 (7.7-fold), 1.1e-4 of
    x from the dome: energy 8.08853e-9 C R^2, above both the dome solve() finds (8.08663e-9)
    and the unstable flat state at the same G and mesh (8.086635e-9, one negative
    eigenvalue), z_end 0.001416 for 0.001325.  Now it is an equilibrium of the target to the
    solver's tol, below the flat state (the dome's depth below it is 6.7e-15), and solve()'s
    dome to 1e-7 relative (measured 2.4e-8: both within tol, the mode soft; 1e-3 was
    2.3e-4 off)."""
    from morphoshell.solvers.branches import follow_branch
    from morphoshell.solvers.direct import solver_of

    bp = follow_branch(blister, nodes=60).events[0]
    target = blister.with_updates(G=blister.params["G"] * bp.tau * (1 + 1e-3))
    walk = follow_branch(target, nodes=60, follow="stable")
    flat = follow_branch(target, nodes=60).end
    assert len(walk.switches) == 1 and walk.end.stable and not flat.stable
    end = walk.end.equilibrium
    assert end.problem == target == flat.equilibrium.problem
    solver = solver_of(end)
    kkt = arclength.bordered_kkt(solver)
    state = kkt.state(kkt.pack(end.x, end.lam_g),
                      solver.disc.pre_numeric(target.parameter_vector(), np.asarray(end.anchors)))
    assert state.error <= solver.tol
    assert walk.end.energy < flat.energy
    assert abs(walk.end.energy - solve(target, nodes=60).energy) < 1e-7 * walk.end.energy
