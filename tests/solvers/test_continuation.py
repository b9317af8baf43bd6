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


def test_a_later_step_keeps_to_the_branch_where_a_stretch_hides_its_turn(monkeypatch):
    """A cap 1e-3 R wide at the pole of a thin shell (h = 1e-4) stays flat until it buckles
    near f0 = 0.013, to the side the sphere's curvature favours; a step from 0.011 to 0.026
    landed on the mirror side (ψ at the edge 3.85 instead of 2.43, 0.15 % higher) at 4× the
    rate of max |Δx| before, which the stretch f, moving with f0, dominated (make fuzz's
    mesh property found it). Judged by the turn of ψ against its own rate the step is
    retried smaller and the solve ends where pseudo-arclength steps end (no natural steps);
    without that test it ends on the mirror side."""
    import numpy as np
    from morphoshell import solve
    from morphoshell.solvers import continuation
    from morphoshell.solvers.branches import follow_branch

    cap = Problem("anisotropic", {"f0": 0.2421875}, h=1e-4, cut=np.pi - 1e-3)
    branch = follow_branch(cap, nodes=40)
    assert all(pt.stable for pt in branch.points)
    eq = solve(cap, nodes=40)
    assert np.max(np.abs(eq.x - branch.end.equilibrium.x)) < 1e-9
    assert abs(eq.psi[0] - 2.4276) < 1e-4
    monkeypatch.setattr(continuation, "JUMP_TURN", np.inf)
    jumped = solve(cap, nodes=40)
    assert abs(jumped.psi[0] - 3.8548) < 1e-4 and jumped.energy > 1.001 * eq.energy


def test_a_warm_solve_past_a_fold_says_it_left_the_warm_starts_branch(caplog):
    """The fold shell warm-started at its first fold and solved 1e-6 past it lands on the
    inverted branch, 0.0048 C R^2 lower, with Solve_Succeeded and no word (audit 14).  The
    solve now says it left the warm start's branch (path, details["left_branch"] with the
    energies, an INFO note); solved 1e-3 back along the stable branch it does not."""
    import logging
    from pathlib import Path

    from morphoshell import solve
    from morphoshell.io.problem_files import load_problem
    from morphoshell.solvers.branches import follow_branch
    from morphoshell.solvers.continuation import left_branch
    from morphoshell.solvers.direct import solver_of

    volvox = load_problem(Path(__file__).parents[1] / "data" / "volvox_fold.toml")[0]
    branch = follow_branch(volvox, nodes=60)
    fold = branch.events[0]
    with caplog.at_level(logging.INFO, logger="morphoshell.solvers.routes"):
        past = solve(branch.line.at(fold.tau + 1e-6), nodes=60, warm_start=fold.equilibrium)
    jump = past.solver.details["left_branch"]
    assert jump["energy_before"] == fold.energy and jump["energy_landed"] == past.energy
    assert past.energy < fold.energy - 1e-3       # (the snap releases 0.0048 C R^2)
    assert "left the warm start's branch" in past.solver.details["path"]
    assert "left the warm start's branch" in caplog.text
    back = solve(branch.line.at(fold.tau - 1e-3), nodes=60, warm_start=fold.equilibrium)
    assert "left_branch" not in back.solver.details and back.solver.details["path"] == "warm start"
    # an ordinary step along the branch is judged by its tangent alone
    a, b = branch.points[1], branch.points[2]
    solver = solver_of(a.equilibrium)
    assert not left_branch(solver, a.equilibrium, solver.solve(b.equilibrium.problem,
                                                               warm_start=a.equilibrium))
