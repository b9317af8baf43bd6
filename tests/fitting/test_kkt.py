"""The KKT fit's routes (fitting.kkt): saddles rejected, given states kept, route B after a
failed NLP."""
import numpy as np
import pytest

from morphoshell.fitting import (FitError, FitSpec, fit, model_midline, synthetic_midline,
                                 volvox_spec)
from morphoshell.numerics.mesh import mesh_spec
from morphoshell.solvers.direct import DirectSolver
from morphoshell.solvers.results import NotAMinimumError

from fitting_cases import NODES, START, TRUE


def test_a_start_on_a_saddle_is_rejected(blister):
    # A flat disc grown in its centre (the blister fixture): the flat state is an
    # equilibrium by mirror symmetry but a saddle (it buckles into a dome).  Data that are
    # that flat state, and a KKT fit started on it, satisfy every KKT
    # condition of the fit at once: it must be rejected, not returned.
    problem = blister
    solver = DirectSolver(problem.structure, mesh=mesh_spec(problem, NODES, 2))
    with pytest.raises(NotAMinimumError) as exc:
        solver.solve(problem)
    saddle = exc.value.last_iterate
    spec = FitSpec(problem, ("G",), bounds={"G": (0.05, 0.5)})
    with pytest.raises(FitError) as exc:
        fit(spec, model_midline(saddle), "kkt", nodes=NODES, start=saddle)
    assert exc.value.status == "Fit_Saddle" and "not a minimum" in str(exc.value)


def test_a_kkt_fit_from_a_given_state_starts_there(monkeypatch):
    """A KKT fit given a start state (a campaign step) starts from it: loose
    Gauss–Newton steps, then the NLP; no coarse refit from the stress-free
    parameters, which discarded the start (on the synthetic campaign its data
    homotopy then failed from t03 on).  It reaches the gradient fit's optimum."""
    from morphoshell.fitting.inner import InnerProblem

    nodes = 90              # a mesh that used to get a coarse stage (over 80 nodes)
    spec = volvox_spec("flat", START, hold={"kappa3": 0.0, "kappa4": 0.0})
    data = synthetic_midline(TRUE, spec.base, nodes=nodes, noise=1e-3, seed=3)
    start = InnerProblem(spec, data, nodes).eq          # the start's own state, on the fit's mesh
    reference = fit(spec, data, "gradient", nodes=nodes, start=start)
    made = []
    inner = InnerProblem.__init__

    def recording(self, spec, data, nodes, start=None):
        made.append(nodes)
        inner(self, spec, data, nodes, start)

    monkeypatch.setattr(InnerProblem, "__init__", recording)
    result = fit(spec, data, "kkt", nodes=nodes, start=start)
    assert made == [nodes]
    assert result.converged and abs(result.E_fit / reference.E_fit - 1) < 1e-3


@pytest.mark.parametrize("warm", [False, True])
def test_a_failed_kkt_nlp_is_followed_by_one_from_the_reduced_optimum(monkeypatch, warm):
    """When the KKT fit's first NLP fails (as from the family's defaults or a previous
    fit's state on the synthetic campaign), Gauss–Newton steps run to the fit's
    tolerance and one NLP starts from their end, the gradient fit's optimum: the fit
    reaches that optimum and counts the failed NLP's iterations."""
    from morphoshell.fitting import kkt
    from morphoshell.fitting.inner import InnerProblem

    # (s3, s4 held: with kappa3, kappa4 = 0 they slide towards s2, and the boxes
    # that order them move, each move with an NLP of its own)
    spec = volvox_spec("flat", START, hold={"kappa3": 0.0, "kappa4": 0.0, "s3": 1.9, "s4": 2.3})
    data = synthetic_midline(TRUE, spec.base, nodes=NODES, noise=1e-3, seed=3)
    start = InnerProblem(spec, data, NODES).eq if warm else None
    # (both fits on the start's mesh: the optimum of the end's own mesh, where fit()
    # goes on to, is another NLP's, tests/fitting/test_fitting.py)
    monkeypatch.setattr(InnerProblem, "on_own_mesh", lambda self, theta: True)
    reference = fit(spec, data, "gradient", nodes=NODES, start=start)
    optimum = np.array([reference.parameters[n] for n in spec.fitted])
    calls, nlp = [], kkt._kkt_nlp

    def failing_once(spec, inner, tol, max_iterations, theta0, eq, **kw):
        calls.append(np.array(theta0))
        if len(calls) == 1:
            exc = FitError("the NLP failed", "Maximum_Iterations_Exceeded")
            exc.iterations = 1000
            raise exc
        return nlp(spec, inner, tol, max_iterations, theta0, eq, **kw)

    monkeypatch.setattr(kkt, "_kkt_nlp", failing_once)
    result = fit(spec, data, "kkt", nodes=NODES, start=start)
    assert len(calls) == 2
    # the second NLP starts at the optimum (to 1e-5 of |θ|), far closer than the first
    gap = [np.abs(c - optimum).max() / np.abs(optimum).max() for c in calls]
    assert gap[1] < 1e-5 and gap[1] < 0.1 * gap[0], gap
    assert result.converged and abs(result.E_fit / reference.E_fit - 1) < 1e-3
    assert result.outer_iterations > 1000
