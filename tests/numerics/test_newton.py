"""The certified Newton back end of warm starts (morphoshell.numerics.newton)."""
import numpy as np
import pytest

from morphoshell import DirectSolver, NotAMinimumError, Problem
from morphoshell.numerics.newton import NewtonBackend

CASES = [
    Problem("anisotropic", {"f0": 0.1}, h=0.3, cut=0.3),                      # toy 3
    Problem("uniform", {"k": 0.0}, h=1e-3, cut=0.5),                            # thin, classical
    Problem("volvox", h=0.15, opening=0.3),
]
CHANGES = [{"f0": 0.102}, {"h": 1.01e-3}, {"kappa2": -7.9}]


@pytest.mark.parametrize("problem, change", list(zip(CASES, CHANGES)))
def test_newton_warm_solve_is_the_ipopt_solution(problem, change):
    newton = DirectSolver(problem.structure, 200)
    ipopt = DirectSolver(problem.structure, 200, newton=False)
    base = newton.solve(problem)
    target = problem.with_updates(**change)
    a, b = newton.solve(target, warm_start=base), ipopt.solve(target, warm_start=base)
    assert a.solver.status == "Newton_Converged" and a.solver.details["route"] == "newton"
    assert b.solver.details.get("route") is None
    assert a.solver.details["stability"].startswith("newton_ldl") and a.converged
    assert 1 <= a.solver.iterations <= 4
    # the same KKT point, both within the KKT tolerance (1e-10 here): the
    # energies differ by about the multipliers times the constraints' residuals
    # (up to 1.3e-10 relative, chord step first)
    assert np.max(np.abs(a.x - b.x)) < 1e-8 * max(1.0, np.max(np.abs(b.x)))
    assert abs(a.energy - b.energy) <= 1e-9 * abs(b.energy) + 1e-14


@pytest.mark.parametrize("problem", CASES)
@pytest.mark.parametrize("stages", [2, 3])
def test_a_cold_newton_solve_is_ipopt_s_solution_without_setting_ipopt_up(problem, stages):
    newton = DirectSolver(problem.structure, 60, stages=stages)
    a = newton.solve(problem)
    b = DirectSolver(problem.structure, 60, stages=stages, newton=False).solve(problem)
    assert a.solver.details["route"] == "newton" and not a.solver.details["chord"]
    assert newton.backend._solver is None              # Ipopt was never set up
    # the same minimum, both within the KKT tolerance (here 1e-14 to 1e-12 of x)
    assert np.max(np.abs(a.x - b.x)) < 1e-8 * max(1.0, np.max(np.abs(b.x)))
    assert abs(a.energy - b.energy) <= 1e-9 * abs(b.energy) + 1e-14


def test_a_cold_start_takes_no_step_ipopt_would_modify(blister, monkeypatch):
    """The blister's flat shape is a saddle: Newton's path from the flat start meets a system
    with the wrong inertia, where Ipopt would correct the inertia; Newton stops there and
    Ipopt solves."""
    original, steps = NewtonBackend._minimum, []

    def spy(self, K, rhs, *args):
        found = original(self, K, rhs, *args)
        if rhs is not None:            # a cold step's system (not the certificate's)
            steps.append(found)
        return found

    monkeypatch.setattr(NewtonBackend, "_minimum", spy)
    solver = DirectSolver(blister.structure, 60)
    with pytest.raises(NotAMinimumError) as exc:
        solver.solve(blister)
    assert len(steps) >= 1 and steps[-1] is None
    assert exc.value.last_iterate.solver.details.get("route") is None    # Ipopt's result


def test_newton_never_certifies_a_saddle(blister):
    solver = DirectSolver(blister.structure, 200)
    with pytest.raises(NotAMinimumError) as exc:
        solver.solve(blister)
    saddle = exc.value.last_iterate
    newton = NewtonBackend(solver.disc, tol=solver.tol, acceptable_tol=1e-6)
    D = solver.disc.pre(blister.parameter_vector(), np.zeros(0))
    # Newton converges at once there (it is a KKT point) but the inertia refuses it
    assert newton.solve(saddle.x, D, saddle.lam_g) is None
    # and a warm start from the saddle goes on to Ipopt, whose exact check rejects it too
    with pytest.raises(NotAMinimumError):
        solver.solve(blister, warm_start=saddle)


def test_far_warm_starts_fall_back_to_ipopt():
    problem = Problem("anisotropic", {"f0": 0.1}, h=0.3, cut=0.3)
    solver = DirectSolver(problem.structure, 200)
    base = solver.solve(problem)
    far = problem.with_updates(f0=0.3, h=0.1)
    newton = NewtonBackend(solver.disc, tol=solver.tol, acceptable_tol=1e-6, max_iter=2)
    D = solver.disc.pre(far.parameter_vector(), np.zeros(0))
    assert newton.solve(base.x, D, base.lam_g) is None      # two steps are not enough
    warm = solver.solve(far, warm_start=base)
    cold = DirectSolver(problem.structure, 200).solve(far)
    assert np.max(np.abs(warm.x - cold.x)) < 1e-8


def test_warm_solves_start_with_a_chord_step():
    """The first step reuses the system at the warm start (kept from the solve that produced
    it) and ends where Ipopt ends, in as many steps as Newton takes."""
    problem = Problem("anisotropic", {"f0": 0.1}, h=0.3, cut=0.3)
    solver = DirectSolver(problem.structure, 200)
    plain = DirectSolver(problem.structure, 200)
    plain.solve = _without_chord(plain)
    ipopt = DirectSolver(problem.structure, 200, newton=False)
    eq = solver.solve(problem)             # a cold solve: Ipopt's
    steps = []
    for f0 in (0.101, 0.102, 0.1015, 0.099, 0.1, 0.1005):
        target = problem.with_updates(f0=f0)
        new = solver.solve(target, warm_start=eq)
        assert new.solver.details["route"] == "newton" and new.solver.details["chord"] is True
        steps.append((new.solver.iterations, plain.solve(target, warm_start=eq).solver.iterations))
        exact = ipopt.solve(target, warm_start=eq).x
        assert np.max(np.abs(new.x - exact)) < 1e-8 * max(1.0, np.max(np.abs(exact)))
        eq = new
    # a chord step gains about as much as a Newton step: no more steps in all
    chord, newton = np.sum(steps, axis=0)
    assert chord <= newton and max(s for s, _ in steps) <= 3


@pytest.mark.parametrize("problem, change", [
    (Problem("anisotropic", {"f0": 0.1}, h=0.3, cut=0.3), {"f0": 0.102}),
    (Problem("uniform", {"k": 0.0}, h=1e-4, cut=0.5, theory="classical"), {"h": 1.01e-4})])
def test_the_third_step_in_the_first_call_changes_nothing_but_the_time(problem, change,
                                                                         monkeypatch):
    """On up to THIRD_STEP_CELLS cells the warm start's first call also takes the third step
    (the next step, or the round-off floor's test at h = 1e-4); the same arithmetic in
    another call: the same iterate, to the last bit, after as many steps."""
    results = []
    for cells in (100, 0):
        monkeypatch.setattr("morphoshell.numerics.newton.THIRD_STEP_CELLS", cells)
        solver = DirectSolver(problem.structure, 42)
        base = solver.solve(problem)
        results.append([solver.solve(problem.with_updates(**{k: v * f for k, v in change.items()}),
                                     warm_start=base) for f in (1.0, 1.005)])
    for with_third, without in zip(*results):
        assert with_third.solver.details["route"] == "newton" and with_third.solver.details["chord"]
        assert with_third.solver.iterations == without.solver.iterations
        assert np.array_equal(with_third.x, without.x)
        assert np.array_equal(with_third.lam_g, without.lam_g)
    # (a solve that ends at u₂ by tol does not use the third step: one of each ends at u₃)
    assert max(eq.solver.iterations for eq in results[0]) == 3


def _without_chord(solver):
    def solve(problem, warm_start):
        return DirectSolver.solve(solver, problem, x0=warm_start.x, lam_g0=warm_start.lam_g)
    return solve


def test_a_chord_step_does_not_depend_on_what_was_solved_before():
    """Kept or built again, the warm start's system is the same: results agree to the last
    bit (campaigns resumed in another process; workers with other histories)."""
    problem = Problem("volvox", h=0.15, opening=0.3)
    a = DirectSolver(problem.structure, 120)
    base = a.solve(problem)
    one = a.solve(problem.with_updates(kappa2=-7.2), warm_start=base)
    a.solve(problem.with_updates(kappa2=-6.5), warm_start=base)    # another history
    target = problem.with_updates(kappa2=-7.25)
    kept = a.solve(target, warm_start=one)              # one's system was kept
    fresh = DirectSolver(problem.structure, 120).solve(target, warm_start=one)    # built now
    assert kept.solver.details["chord"] and fresh.solver.details["chord"]
    assert np.array_equal(kept.x, fresh.x) and np.array_equal(kept.lam_g, fresh.lam_g)


def test_a_chord_step_that_does_not_help_is_dropped():
    problem = Problem("anisotropic", {"f0": 0.1}, h=0.3, cut=0.3)
    solver = DirectSolver(problem.structure, 200)
    base = solver.solve(problem)
    one = solver.solve(problem.with_updates(f0=0.101), warm_start=base)
    # a system that steps the wrong way (-K) in place of one's
    kept = next(k for k in solver._newton._kept
                if k.key is not None and np.array_equal(k.key[0], one.x))
    kept.K = -kept.K
    target = problem.with_updates(f0=0.102)
    new = solver.solve(target, warm_start=one)
    assert new.solver.details["chord"] is False and new.solver.iterations == 2
    exact = DirectSolver(problem.structure, 200, newton=False).solve(target, warm_start=one).x
    assert np.max(np.abs(new.x - exact)) < 1e-8


def test_a_failed_newton_solve_keeps_no_system():
    problem = Problem("anisotropic", {"f0": 0.1}, h=0.3, cut=0.3)
    solver = DirectSolver(problem.structure, 200)
    base = solver.solve(problem)
    newton = NewtonBackend(solver.disc, tol=solver.tol, acceptable_tol=1e-6, max_iter=2)
    p = problem.with_updates(f0=0.101).parameter_vector()
    ok = newton.solve(base.x, solver.disc.pre(p, np.zeros(0)), base.lam_g, at=(p, np.zeros(0)))
    assert ok is not None and sum(k.key is not None for k in newton._kept) == 1
    far = solver.disc.pre(problem.with_updates(f0=0.3, h=0.1).parameter_vector(), np.zeros(0))
    assert newton.solve(ok.x, far, ok.lam_g, at=(p, np.zeros(0))) is None
    # the failed solve keeps nothing: the first result's system only
    keys = [k.key for k in newton._kept if k.key is not None]
    assert len(keys) == 1 and np.array_equal(keys[0][0], ok.x)


def test_a_thin_shell_stops_at_its_round_off_floor_when_newton_s_correction_is_negligible(
        monkeypatch):
    """h = 1e-4: the dual residual cannot go below ~3e-8 (tol 1e-10), but Newton's correction
    there is 4e-14 of x: the warm solve stops a step earlier than by waiting for a step that
    no longer helps, at the same point to 1e-13; kept or rebuilt system, to the last bit."""
    problem = Problem("uniform", {"k": 0.0}, h=1e-4, cut=0.5, theory="classical")
    solver = DirectSolver(problem.structure, 100)
    base = DirectSolver(problem.structure, 100, newton=False).solve(problem)
    assert base.solver.status == "Solved_To_Acceptable_Level"       # Ipopt at the floor too
    one = problem.with_updates(h=1.01e-4)
    new = solver.solve(one, warm_start=base)
    monkeypatch.setattr("morphoshell.numerics.newton.STEP_TOL", 0.0)
    waited = DirectSolver(problem.structure, 100).solve(one, warm_start=base)
    monkeypatch.undo()
    assert new.solver.details["route"] == "newton" and new.solver.details["chord"]
    assert (new.solver.iterations, waited.solver.iterations) == (2, 3)
    exact = DirectSolver(problem.structure, 100, newton=False).solve(one, warm_start=base)
    for eq in (new, waited):    # both as close to Ipopt's point as the floor allows (9e-14)
        assert abs(eq.r[0] - exact.r[0]) < 1e-11 and abs(eq.psi[0] - exact.psi[0]) < 1e-11
    two = problem.with_updates(h=1.02e-4)
    kept = solver.solve(two, warm_start=new)
    fresh = DirectSolver(problem.structure, 100).solve(two, warm_start=new)
    assert kept.solver.iterations == 2
    assert np.array_equal(kept.x, fresh.x) and np.array_equal(kept.lam_g, fresh.lam_g)


def test_a_start_s_residual_alone_is_never_taken_for_the_floor():
    """A thin closed shell (h = 1e-4) hardly changes with its intrinsic curvature: from the
    stress-free k = 1 to k = 0.75 the start's residual is 8e-8, near the floor, and Newton's
    correction 8e-12 of x (the first step of toy 2's continuation).  Still a change
    to follow: the warm solve takes a step and returns the new point, not the start."""
    problem = Problem("uniform", {"k": 1.0}, h=1e-4, cut=0.0, theory="classical")
    solver = DirectSolver(problem.structure, 400)
    base = solver.solve(problem)
    target = problem.with_updates(k=0.75)
    new = solver.solve(target, warm_start=base)
    assert new.solver.iterations >= 1 and not np.array_equal(new.x, base.x)
    exact = DirectSolver(problem.structure, 400, newton=False).solve(target, warm_start=base)
    assert np.max(np.abs(new.x - exact.x)) < 1e-8
