"""The certified Newton back end of warm starts (morphoshell.newton)."""
import numpy as np
import pytest

from morphoshell import DirectSolver, NotAMinimumError, Problem
from morphoshell.newton import NewtonBackend

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
    # the same KKT point: Newton's quadratic convergence ends at the round-off
    # floor of the KKT error (~1e-12 relative); Ipopt's stops within tol
    assert np.max(np.abs(a.x - b.x)) < 1e-8 * max(1.0, np.max(np.abs(b.x)))
    assert abs(a.energy - b.energy) <= 1e-10 * abs(b.energy) + 1e-14


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
