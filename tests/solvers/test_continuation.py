"""Continuation paths (solvers.continuation): what they report."""
from morphoshell import Problem
from morphoshell.solvers.continuation import continue_between, continue_to
from morphoshell.solvers.direct import DirectSolver


def test_a_path_says_where_its_continuation_started():
    """continue_to starts from the stress-free parameters, continue_between from a previous
    solution, and each path's description says which (the second said the first's)."""
    a, b = Problem("uniform", {"k": 1.5}, h=0.1), Problem("uniform", {"k": 2.0}, h=0.1)
    solver = DirectSolver(a.structure, 20)
    first = continue_to(solver, a)
    second = continue_between(solver, first, b)
    assert first.solver.details["path"].startswith(
        "continuation from the stress-free parameters in ")
    assert second.solver.details["path"].startswith("continuation from a previous solution in ")


def test_the_first_step_keeps_to_the_branch_out_of_the_stress_free_shell(monkeypatch):
    """A cap 0.005 R wide at the pole, nearly flat, bends one way from the stress-free shell
    and as stably the other, 1 % higher. The first natural step (a quarter of the way) has
    no earlier step to judge a jump by and landed on the other (ψ at the edge 3.81 instead
    of 2.47: make fuzz's branch property found it); judged by the tangent out of the
    stress-free shell it is retried smaller and ends where the branch followed by
    pseudo-arclength steps ends (an independent route: no natural steps)."""
    import numpy as np
    from morphoshell import solve
    from morphoshell.solvers import continuation
    from morphoshell.solvers.branches import follow_branch

    cap = Problem("anisotropic", {"f0": 0.25221546672634093}, h=1e-3, cut=3.136327902231522,
                  theory="classical")
    branch = follow_branch(cap, nodes=40)
    assert all(pt.stable for pt in branch.points)           # no fold, no branch point
    eq = solve(cap, nodes=40)
    assert np.max(np.abs(eq.x - branch.end.equilibrium.x)) < 1e-9
    assert abs(eq.psi[0] - 2.4707) < 1e-4
    monkeypatch.setattr(continuation, "_tangent", lambda *args: None)
    jumped = solve(cap, nodes=40)
    assert abs(jumped.psi[0] - 3.8065) < 1e-4 and jumped.energy > 1.009 * eq.energy
