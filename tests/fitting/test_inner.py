"""The inner problem of a fit (fitting.inner): solves that stay on one branch."""
import pytest

from fitting_cases import three_parameter_spec


def test_a_failed_trial_is_rejected_without_continuation(monkeypatch):
    """A least-squares trial whose warm solve fails raises at once; any other solve at θ
    continues from the nearest state (the fit's own points must be reached)."""
    import types

    import morphoshell.fitting.inner as fitting
    from morphoshell.solvers.results import SolverError

    spec = three_parameter_spec()
    inner = fitting.InnerProblem.__new__(fitting.InnerProblem)
    start = types.SimpleNamespace(name="start")
    inner.spec, inner.solves, inner._cache = spec, 0, {}
    inner._archive = [(spec.theta0, start)]

    def warm(problem, warm_start):
        raise SolverError("warm solve failed", "Maximum_Iterations_Exceeded")

    inner.solver = types.SimpleNamespace(solve=warm)
    continued = []
    monkeypatch.setattr(fitting, "continue_between",
                        lambda solver, eq, problem, first_step: continued.append(eq) or "eq")
    theta = spec.theta0 * (1 + 1e-3)          # well within NEAR of the start
    with pytest.raises(SolverError, match="warm solve failed"):
        inner.solve(theta, trial=True)
    assert continued == [] and inner.solves == 0
    assert inner.solve(theta) == "eq" and continued == [start] and inner.solves == 1
