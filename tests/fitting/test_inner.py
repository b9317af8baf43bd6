"""The inner problem of a fit (fitting.inner): solves that stay on one branch."""
import numpy as np
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

    inner.nodes = 40
    inner.solver = types.SimpleNamespace(solve=warm, mesh=fitting.mesh_spec(spec.base, 40, 2))
    continued = []
    monkeypatch.setattr(fitting, "continue_between",
                        lambda solver, eq, problem, first_step, snap: continued.append(eq) or "eq")
    theta = spec.theta0 * (1 + 1e-3)          # well within NEAR of the start
    with pytest.raises(SolverError, match="warm solve failed"):
        inner.solve(theta, trial=True)
    assert continued == [] and inner.solves == 0
    assert inner.solve(theta) == "eq" and continued == [start] and inner.solves == 1


def test_a_failed_trial_on_a_stale_mesh_is_tried_on_a_mesh_of_its_own(monkeypatch):
    """A trial whose breakpoints lie STALE_MESH knot widths or more from the mesh's knots, and
    whose solve there fails, is solved once more on a mesh built for it (from the nearest
    state), which becomes the inner problem's; a trial near the knots still fails at once.
    (The synthetic sequence's undeformed t12, fitted from t06's fit: the fit stalled at
    E_fit 1.34 R on the family defaults' mesh, 0.028 R with this.)"""
    import types

    import morphoshell.fitting.inner as fitting
    from morphoshell.solvers.results import SolverError

    spec = three_parameter_spec()
    base = spec.problem(spec.theta0)
    inner = fitting.InnerProblem.__new__(fitting.InnerProblem)
    start = types.SimpleNamespace(name="start")
    inner.spec, inner.solves, inner._cache, inner.nodes, inner.n = spec, 0, {}, 40, 10
    inner.snap_trials = True
    inner._archive = [(spec.theta0, start)]

    def failing(problem, warm_start):
        raise SolverError("warm solve failed", "Maximum_Iterations_Exceeded")

    old = types.SimpleNamespace(solve=failing, mesh=fitting.mesh_spec(base, 40, 2))
    inner.solver = old
    built = []
    monkeypatch.setattr(fitting, "DirectSolver", lambda structure, mesh: built.append(mesh)
                        or types.SimpleNamespace(mesh=mesh, disc=None))
    monkeypatch.setattr(fitting, "midline", lambda disc, n: "midline")
    monkeypatch.setattr(fitting, "solve_from", lambda solver, problem, eq: ("new", eq))
    monkeypatch.setattr(fitting, "continue_between", lambda *args, **kw: failing(None, None))
    breakpoints = [i for i, name in enumerate(spec.fitted) if name.startswith("s")]
    assert breakpoints, spec.fitted
    near = spec.theta0.copy()
    near[breakpoints[0]] *= 1.001                       # within NEAR: one warm solve
    with pytest.raises(SolverError, match="warm solve failed"):
        inner.solve(near, trial=True)
    assert built == [] and inner.solver is old
    stale = near.copy()
    stale[breakpoints[0]] *= 1.1
    assert inner._stale(spec.problem(stale))
    assert inner.solve(stale, trial=True) == ("new", start)
    assert built == [fitting.mesh_spec(spec.problem(stale), 40, 2)]
    assert inner.solver.mesh == built[0] and inner.midline == "midline"


def test_inner_solves_cross_a_snap_through_instead_of_failing():
    """A fit's step across a fold of the inner branch (the issue's shell: its path from the
    stress-free parameters folds at 0.872): the inner solve snaps through to the stable
    equilibrium there, the cold solve's, instead of raising Continuation_Failed."""
    from pathlib import Path

    from morphoshell import solve
    from morphoshell.fitting.inner import InnerProblem
    from morphoshell.fitting.spec import FitSpec
    from morphoshell.io.problem_files import load_problem
    from morphoshell.solvers.paths import ParameterLine, neutral_problem

    target, _ = load_problem(Path(__file__).parents[1] / "data" / "volvox_fold.toml")
    line = ParameterLine.between(neutral_problem(target), target)
    spec = FitSpec(line.at(0.85), tuple(line.names))
    inner = InnerProblem(spec, np.zeros((10, 2)), 200)
    eq = inner.solve(np.array([target.params[n] for n in spec.fitted]))
    assert eq.solver.details.get("snaps"), eq.solver.details.get("path")
    cold = solve(target, nodes=200)
    assert abs(eq.r[-1] - cold.r[-1]) < 1e-8 and abs(eq.z[-1] - cold.z[-1]) < 1e-8


def test_a_state_kept_after_the_mesh_moved_is_read_through_its_own_mesh():
    """The gradient fit keeps its best point's state when its trials stall; trials that
    moved the breakpoints far had built a new mesh.  The kept state must be read through
    its own mesh: through the new one's midline, a profile refit of the synthetic t05
    reported E_fit² = 1.6 R² for a state whose own is 2.9e-5 R².  (Fails without
    InnerProblem._adopt: the residuals differ by O(1).)"""
    from morphoshell.fitting import synthetic_midline, volvox_spec
    from morphoshell.fitting.inner import InnerProblem

    spec = volvox_spec("free")
    data = synthetic_midline(spec.base, nodes=120, n=60)
    inner = InnerProblem(spec, data, 60)
    theta = spec.theta0
    eq = inner.solve(theta)
    before = inner.residuals(eq)
    moved = theta.copy()
    moved[spec.fitted.index("s3")] += 0.3     # (what a trial far along s3 builds)
    inner._build(spec.problem(moved))
    assert inner.solver is not eq.source[0]()
    inner.keep(theta, eq)
    after = inner.residuals(inner.solve(theta))
    np.testing.assert_array_equal(after, before)


def test_a_profile_refit_does_not_snap_its_trial_points_through(monkeypatch):
    """Trial points far from every kept state are continued to; across a fold of the branch
    a fit's trial snaps through, a profile refit's is rejected (snap_trials False: a failed
    snap costs far more, and the retry from the optimum tries other branches)."""
    import types

    import morphoshell.fitting.inner as fitting

    spec = three_parameter_spec()
    inner = fitting.InnerProblem.__new__(fitting.InnerProblem)
    start = types.SimpleNamespace(name="start")
    inner.spec, inner.solves, inner._cache = spec, 0, {}
    inner._archive = [(spec.theta0, start)]
    inner.solver, inner.snap_trials = object(), True
    snaps = []
    monkeypatch.setattr(fitting, "continue_between",
                        lambda solver, eq, problem, snap: snaps.append(snap) or "eq")
    far = spec.theta0 + 0.5 * (spec.box()[1] - spec.box()[0])
    inner.solve(far, trial=True)
    inner.snap_trials, inner._cache = False, {}
    inner.solve(far * 1.01, trial=True)
    inner.solve(far * 1.02)
    assert snaps == [True, False, True]
