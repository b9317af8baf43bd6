"""Past a stall of solve()'s continuation (solvers/crossings.py): a fold or branch point just
past the target is not crossed, the shell reaching the target before it; nothing is solved
beyond the target."""
from pathlib import Path

import pytest

from morphoshell import Problem, solve
from morphoshell.io.problem_files import load_problem
from morphoshell.solvers import continuation
from morphoshell.solvers.branches import follow_branch
from morphoshell.solvers.paths import ParameterLine, neutral_problem
from morphoshell.solvers.routes import direct_solver

FIXTURE = Path(__file__).resolve().parents[1] / "data" / "volvox_fold.toml"


@pytest.fixture(scope="module")
def just_before():
    """Targets 1e-5 of their paths before an event, at 60 nodes: the volvox_fold path's
    first fold (the event at τ = 1 + 1e-5 of the target's own path) and the blister's first
    branch point (as far past)."""
    volvox = load_problem(FIXTURE)[0]
    fold = next(pt for pt in follow_branch(volvox, nodes=60).events if pt.event == "fold")
    blister = Problem("central_growth", {"G": 0.2}, h=0.02, geometry="disc")
    bp = follow_branch(blister, nodes=60).events[0]
    assert bp.event == "branch_point"
    line = ParameterLine.between(neutral_problem(volvox), volvox)
    return {"fold": line.at(fold.tau * (1 - 1e-5)),
            "branch_point": blister.with_updates(G=0.2 * bp.tau * (1 - 1e-5))}


@pytest.mark.parametrize("route", ["solve", "continue_between"])
@pytest.mark.parametrize("kind", ["fold", "branch_point"])
def test_an_event_just_past_the_target_is_not_crossed(just_before, kind, route, monkeypatch):
    """Natural continuation reaches these targets (a solve before an event converges) and
    never stalls there; forced to (its steps refused past 0.998 of the way), the crossing
    of the stall walked past τ = 1 to the event beyond and crossed it: solve() snapped from
    the fold at 1.00001, built its problem there and returned the inverted state re-solved
    at the target, energy 0.017773 where the target's is 0.022599; it switched at the branch
    point at 1.00001 (a value never given); continue_between (a fit's, no switching) ended
    at the branch point with "it reaches the target unstable" although the target is
    stable.  Past the target every problem raises here, as at a range ending there (the
    fold's problem's ValueError ended the solve as bad input).  Now the branch is taken at
    τ = 1: the unforced solve's state, energy to 1e-8 relative (1e-5 before the event the
    mode is soft: Newton's and Ipopt's end points agree to the tolerance over that
    stiffness; measured 1e-13 at the fold, 9.5e-10 at the branch point)."""
    target = just_before[kind]
    reference = solve(target, nodes=60)
    line = ParameterLine.between(neutral_problem(target), target)
    name, a, b = line.names[0], line.a[0], line.b[0]
    real_solve_at, real_at = continuation._solve_at, ParameterLine.at

    def stalled(solver, problem, eq, anchors):
        tau = (problem.params[name] - a) / (b - a)
        return None if tau > 0.998 else real_solve_at(solver, problem, eq, anchors)

    def at(self, tau):
        if tau > 1:
            raise ValueError(f"a problem at {tau!r} of the way, past the target (test)")
        return real_at(self, tau)
    monkeypatch.setattr(continuation, "_solve_at", stalled)
    monkeypatch.setattr(ParameterLine, "at", at)
    if route == "solve":
        eq = solve(target, nodes=60)
    else:
        solver = direct_solver(target, 60)
        eq = continuation.continue_between(solver, solver.solve(line.source), target,
                                           first_step=0.25, snap=True)
    path = eq.solver.details["path"]
    assert "retried" in path and "snapped" not in path and "switched" not in path, path
    assert eq.problem.params == target.params
    assert abs(eq.energy - reference.energy) < 1e-8 * reference.energy
