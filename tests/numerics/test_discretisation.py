"""The transcription: quadrature, integration to the points, cell polynomials, order 6."""
import casadi as ca
import numpy as np
import pytest

from morphoshell import Problem, solve
from morphoshell.mechanics.ablation import edge_state
from morphoshell.solvers.direct import DirectSolver
from morphoshell.numerics.discretisation import Discretisation
from morphoshell.numerics.scheme import collocation


@pytest.fixture(scope="module", params=[1, 2, 3])
def disc(request):
    problem = Problem("uniform", h=0.1, cut=0.3)
    t = np.linspace(0, 1, 12) ** 1.3
    return problem, Discretisation(problem.structure, t, request.param)


def test_gauss_rule_and_integration_are_exact(disc):
    problem, d = disc
    S, p = d.stages, problem.parameter_vector()
    s_pts = d.points(p)
    nodes = s_pts[::S]
    s_g = (nodes[:-1, None] + np.diff(nodes)[:, None] * d.tau[None, :]).ravel()
    # cell totals are Gauss rules: exact for degree 2S - 1 at the nodes
    c = np.arange(1, 2 * S + 1)
    poly = np.polynomial.Polynomial(c)
    integral = d.integrate_to_points(poly(s_g), p)
    exact = poly.integ()(s_pts) - poly.integ()(s_pts[0])
    assert np.max(np.abs(integral[::S] - exact[::S])) < 1e-12 * np.max(np.abs(exact))
    # between nodes the Gauss interpolant (degree S - 1) is integrated exactly
    low = np.polynomial.Polynomial(c[:S])
    integral = d.integrate_to_points(low(s_g), p)
    assert np.allclose(integral, low.integ()(s_pts) - low.integ()(s_pts[0]), rtol=0, atol=1e-12)
    # and a degree-2S integrand is not exact: the test can fail
    high = np.polynomial.Polynomial(np.arange(1, 2 * S + 2))
    err = d.integrate_to_points(high(s_g), p)[-1] - (high.integ()(s_pts[-1]) - high.integ()(s_pts[0]))
    assert abs(err) > 1e-9


def test_collocation_bases(disc):
    _, d = disc
    tau, w, values, derivs, integrals, anti = collocation(d.stages)
    assert w.sum() == pytest.approx(1.0) and np.allclose(values.sum(axis=1), 1.0)
    assert np.allclose(derivs.sum(axis=1), 0.0, atol=1e-12)
    assert np.allclose(integrals[-1], w)   # ∫₀¹ of the Gauss basis = the weights
    assert np.allclose([np.polynomial.Polynomial(a)(1.0) for a in anti], w)


def test_live_discretisations_of_one_size_share_the_assembly_and_nothing_else():
    """Meshes graded for h = 1e-3 and 3e-3 with 50 nodes (the same layout): while the first
    solver lives the second shares its symbols and Newton system, and solves to the same bits
    as when built alone; the sharing ends with the last user (weakly held)."""
    import gc

    from morphoshell.numerics import discretisation as dm
    from morphoshell.solvers.routes import clear_cache
    from morphoshell.numerics.mesh import mesh_spec

    a, b = (Problem("uniform", {"k": 0.0}, h=h, cut=0.5, theory="classical")
            for h in (1e-3, 3e-3))
    clear_cache()     # (solve()'s cached solvers of this size, from earlier tests, would share)
    gc.collect()
    alone = DirectSolver(b.structure, mesh=mesh_spec(b, 50, 2)).solve(b)
    gc.collect()
    first = DirectSolver(a.structure, mesh=mesh_spec(a, 50, 2))
    first.solve(a)
    second = DirectSolver(b.structure, mesh=mesh_spec(b, 50, 2))
    assert not np.array_equal(first.t, second.t)                 # different meshes
    assert second.disc.x is first.disc.x and second.disc._shared is first.disc._shared
    assert second.disc.newton_system() is first.disc.newton_system()
    eq = second.solve(b)
    assert eq.solver.details["route"] == "newton"
    assert np.array_equal(eq.x, alone.x) and np.array_equal(eq.lam_g, alone.lam_g)
    # other sizes and orders have their own
    assert DirectSolver(a.structure, mesh=mesh_spec(a, 51, 2)).disc._shared is not first.disc._shared
    assert DirectSolver(a.structure, stages=3,
                        mesh=mesh_spec(a, 50, 3)).disc._shared is not first.disc._shared
    key = (first.disc.layout, id(first.disc._cell))
    del first, second, eq
    gc.collect()
    assert key not in dm._SHARED


def test_energy_is_the_quadrature_and_edge_state_the_polynomial():
    problem = Problem("anisotropic", {"f0": 0.1}, h=0.3, cut=0.3)
    eq = solve(problem, nodes=100)
    assert eq.energy_between(eq.s[0], eq.s[-1]) == pytest.approx(eq.energy, rel=1e-13)
    # at a point (a node or an interior point) the cell polynomial is the value
    for i in (0, 7, 8, 51):
        st = edge_state(eq, eq.s[i])
        shift = st["z"] - eq.z[i]
        assert abs(st["r"] - eq.r[i]) < 1e-13 and abs(st["psi"] - eq.psi[i]) < 1e-13
        assert abs(shift - (eq.problem.geometry_obj.numeric(eq.s[-1])[1] - eq.z[-1])) < 1e-13
    # between points it agrees with a spline through them to interpolation accuracy
    s = 0.5 * (eq.s[20] + eq.s[21])
    assert abs(edge_state(eq, s)["r"] - eq.at(s)["r"]) < 1e-6


def test_stages_3_is_sixth_order():
    # self-convergence of the edge values and energy on 25..200 nodes:
    # orders 6.05-6.5 on these meshes
    problem = Problem("anisotropic", {"f0": 0.1}, h=0.3, cut=0.3)
    V = np.array([[eq.r[0], eq.psi[0], eq.energy] for eq in
                  (solve(problem, nodes=n, stages=3) for n in (25, 50, 100))])
    order = np.log2(np.abs(V[0] - V[1]) / np.abs(V[1] - V[2]))
    assert np.all(np.abs(order - 6) < 0.6), order


def test_anchored_solution_equals_the_unanchored_one_to_the_mesh_error():
    problem = Problem("uniform", {"k": 0.5}, h=0.3)
    plain = DirectSolver(problem.structure, 400).solve(problem)
    eq = solve(problem, nodes=400, anchors=(0.7,))
    assert 0.7 in eq.s
    i = int(np.flatnonzero(eq.s == 0.7)[0])
    assert abs(eq.r[i] - plain.at(0.7)["r"]) < 1e-8
    assert eq.energy == pytest.approx(plain.energy, rel=1e-9)
    with pytest.raises(ValueError, match=r"anchor s = 4.0 must lie inside the shell \(0, 3.14159\)"):
        solve(problem, nodes=400, anchors=(4.0,))


@pytest.mark.parametrize("problem", [Problem("volvox", h=0.15, opening=0.3),
                                     Problem("uniform", {"k": 0.3}, h=0.3, cut=0.3)],
                         ids=["volvox", "uniform-cut"])
def test_kkt_curvature_equals_the_hessian_of_the_assembled_residual(problem):
    """The per-cell kernels give ∂²/∂(x, λ)² of μ·F − μ_dz·Δz − μ_dS·ΔS exactly."""
    from morphoshell.numerics.mesh import mesh_spec
    from morphoshell.solvers.parametric import parametric

    solver = DirectSolver(problem.structure, mesh=mesh_spec(problem, 30, 2))
    d = solver.disc
    n, m, nc = d.layout.size, d.g.shape[0], d.layout.cells
    x, lam = ca.MX.sym("x", n), ca.MX.sym("lam", m)
    F = parametric(solver).kkt_residual(x, lam, d.p, d.q)
    sh = d.shape(x, d.p, d.q)
    dz, dS = sh.increments()
    mu, a, b = ca.MX.sym("mu", n + m), ca.MX.sym("a", nc), ca.MX.sym("b", nc)
    direct = ca.triu(ca.hessian(ca.dot(mu, F) - ca.dot(a, dz) - ca.dot(b, dS),
                                ca.vertcat(x, lam))[0])
    kernels = d.kkt_curvature(x, lam, d.pre(d.p, d.q), mu, a, b, sh.s_nodes[1:] - sh.s_nodes[:nc])
    f = ca.Function("f", [x, lam, d.p, d.q, mu, a, b], [direct, kernels])
    rng = np.random.default_rng(0)
    p = problem.parameter_vector()
    x0 = d.initial_guess(p, np.zeros(0)) + 0.01 * rng.normal(size=n)
    one, two = (np.array(v) for v in f(x0, rng.normal(size=m), p, np.zeros(d.q.shape[0]),
                                       rng.normal(size=n + m), rng.normal(size=nc),
                                       rng.normal(size=nc)))
    assert np.abs(one).max() > 1
    assert np.abs(one - two).max() < 1e-12 * np.abs(one).max()


@pytest.mark.parametrize("stages", [1, 2, 3])
def test_result_points_are_the_symbolic_shape(stages):
    # Results compute s and z in NumPy; observables and fits differentiate the
    # CasADi shape: both must be the same numbers (to round-off of z ~ 1).
    problem = Problem("volvox", {"kappa1": 0.0, "kappa2": -8.0, "f1": 0.88, "s2": 1.62},
                      h=0.15, opening=0.3)
    solver = DirectSolver(problem.structure, 40, stages=stages)
    eq = solver.solve(problem)
    d, p, q = solver.disc, problem.parameter_vector(), np.asarray(eq.anchors)
    pts = d.symbolic_points(d.x, d.p, d.q)
    s, z = (np.asarray(v).ravel() for v in
            ca.Function("points", [d.x, d.p, d.q], [pts["s"], pts["z"]])(eq.x, p, q))
    assert np.max(np.abs(eq.s - s)) < 1e-14 and np.max(np.abs(eq.z - z)) < 1e-14
    assert np.ptp(eq.z) > 0.1     # a deformed shell, not a trivial comparison


def _structures():
    """toy 3 (a cut, no knots) and volvox (an opening, four breakpoints moving with p)."""
    from morphoshell.io.problem_files import example_path, load_problem

    return [load_problem(example_path("toy3_anisotropic"))[0],
            Problem("volvox", h=0.15, opening=0.3)]


@pytest.mark.parametrize("compiled", ["1", "0"], ids=["compiled", "casadi"])
@pytest.mark.parametrize("problem", _structures(), ids=["toy3", "volvox"])
def test_cell_data_jacobian_is_the_jacobian_of_the_cell_data(problem, compiled, monkeypatch):
    """The per-point chain rule (compiled or not) is dD/dp of the differentiable data."""
    from morphoshell.numerics.mesh import mesh_spec

    monkeypatch.setenv("MORPHOSHELL_COMPILE", compiled)
    d = DirectSolver(problem.structure, mesh=mesh_spec(problem, 30, 2)).disc
    direct = ca.Function("direct", [d.p, d.q], [ca.jacobian(d.pre(d.p, d.q), d.p)])
    p, q = problem.parameter_vector(), np.zeros(d.q.shape[0])
    one, two = np.array(direct(p, q)), np.array(d.pre_jacobian(p, q))
    assert one.shape == two.shape == (d.D.shape[0], len(p))
    # the same derivatives summed in another order: rounding only (about 2e-16)
    assert np.abs(one).max() > 1
    assert np.abs(one - two).max() < 1e-12 * np.abs(one).max()


@pytest.mark.parametrize("compiled", ["1", "0"], ids=["compiled", "casadi"])
@pytest.mark.parametrize("problem", _structures(), ids=["toy3", "volvox"])
def test_cell_data_hessian_is_the_hessian_of_the_cell_data(problem, compiled, monkeypatch):
    """The per-point chain rule of second order (mesh moving with p) is d²(c·D)/dp²."""
    from morphoshell.numerics.mesh import mesh_spec

    monkeypatch.setenv("MORPHOSHELL_COMPILE", compiled)
    d = DirectSolver(problem.structure, mesh=mesh_spec(problem, 30, 2)).disc
    c = ca.MX.sym("c", d.D.shape[0])
    direct = ca.Function("direct", [d.p, d.q, c],
                         [ca.hessian(ca.dot(c, d.pre(d.p, d.q)), d.p)[0]])
    p, q = problem.parameter_vector(), np.zeros(d.q.shape[0])
    weights = np.random.default_rng(1).standard_normal(d.D.shape[0])
    one, two = np.array(direct(p, q, weights)), np.array(d.pre_hessian(p, q, weights))
    assert one.shape == two.shape == (len(p), len(p))
    # the mesh's own curvature (breakpoints moving the nodes) must count: without
    # its term the volvox Hessian is off by O(1) relative
    assert np.abs(one).max() > 1
    # rounding only (about 5e-15 relative on toy 3, 2e-18 on volvox)
    assert np.abs(one - two).max() < 1e-12 * np.abs(one).max()


@pytest.mark.parametrize("compiled", ["1", "0"], ids=["compiled", "casadi"])
@pytest.mark.parametrize("nodes", [30, 400])
@pytest.mark.parametrize("case", ["toy3", "volvox", "anchored"])
def test_evaluated_cell_data_are_the_differentiable_cell_data_to_the_bit(case, nodes, compiled,
                                                                         monkeypatch):
    """``pre_numeric`` (one kernel per cell fed the mesh's numbers) is ``pre`` (the mesh's
    MX expressions), for the plain map, the family's breakpoints and anchors, and the
    compiled blocks of large meshes."""
    from morphoshell.numerics.mesh import Knot

    monkeypatch.setenv("MORPHOSHELL_COMPILE", compiled)
    toy3, volvox = _structures()
    problem = volvox if case == "volvox" else toy3
    t = np.linspace(0, 1, nodes) ** 1.2
    knots = ()
    if case == "volvox":
        solver = DirectSolver(problem.structure, nodes)
        t, knots = solver.t, solver.mesh.knots
    elif case == "anchored":      # two anchors, one moved off its knot's place
        t = np.sort(np.concatenate([t, [0.3, 0.6]]))
        knots = (Knot(0.3, "anchor", 0), Knot(0.6, "anchor", 1))
    d = Discretisation(problem.structure, t, 2, knots)
    p = problem.parameter_vector()
    a, b = d.shell_ends(p)
    q = a + (b - a) * np.array([0.3, 0.6]) + [0.02, -0.01] if d.anchors else np.zeros(0)
    evaluated, differentiable = (np.asarray(f(p, q)).ravel() for f in (d.pre_numeric, d.pre))
    assert evaluated.shape == (d.D.shape[0],) and np.ptp(evaluated) > 0
    assert np.array_equal(evaluated, differentiable)


@pytest.mark.parametrize("stages", [1, 3])
@pytest.mark.parametrize("nodes", [30, 400])
def test_evaluated_cell_data_of_every_order_are_the_differentiable_ones_to_the_bit(stages,
                                                                                   nodes):
    """The kernel per cell is built per number of stages (its Gauss points and weights are
    constants in it): orders 2 and 6, on the map and on the compiled blocks, with anchors."""
    from morphoshell.numerics.mesh import Knot

    toy3, _ = _structures()
    t = np.sort(np.concatenate([np.linspace(0, 1, nodes) ** 1.2, [0.3, 0.6]]))
    d = Discretisation(toy3.structure, t, stages, (Knot(0.3, "anchor", 0),
                                                    Knot(0.6, "anchor", 1)))
    p = toy3.parameter_vector()
    a, b = d.shell_ends(p)
    q = a + (b - a) * np.array([0.3, 0.6]) + [0.02, -0.01]
    evaluated, differentiable = (np.asarray(f(p, q)).ravel() for f in (d.pre_numeric, d.pre))
    assert evaluated.shape == (d.D.shape[0],) and np.ptp(evaluated) > 0
    assert np.array_equal(evaluated, differentiable)
