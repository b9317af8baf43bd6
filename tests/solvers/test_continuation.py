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
