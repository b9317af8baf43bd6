"""Exact parametric derivatives of direct solutions (implicit function theorem).

The future fitting issues need d(solution)/d(parameters); here they are
checked against central finite differences of full re-solves.
"""
import numpy as np
import pytest

from morphoshell import DirectSolver, Parametric, Problem

CASES = [
    (Problem("uniform", {"k": 0.5}, h=0.3, cut=0.3), ("k", "h", "cut")),
    (Problem("anisotropic", {"f0": 0.1}, h=0.3, cut=0.3), ("f0",)),
    (Problem("volvox", h=0.15, opening=0.3), ("kappa2", "s2", "f1", "opening")),
]


@pytest.mark.parametrize("problem, names", CASES, ids=[c[0].family for c in CASES])
def test_sensitivities_match_finite_differences(problem, names):
    solver = DirectSolver(problem.structure, 200)
    eq = solver.solve(problem)
    sens = Parametric(solver).sensitivities(eq)
    for name in names:
        value = problem.params.get(name, getattr(problem, name, None))
        eps = 1e-5 * max(1.0, abs(value))
        plus = solver.solve(problem.with_updates(**{name: value + eps}), warm_start=eq)
        minus = solver.solve(problem.with_updates(**{name: value - eps}), warm_start=eq)
        col = sens.column(name)
        # central differences are accurate to O(eps^2) ~ 1e-10 relative plus
        # the solver tolerance over eps; measured agreement 1e-9 to 1e-12
        scale = max(np.max(np.abs(col["r"])), 1e-3)
        assert np.max(np.abs((plus.r - minus.r) / (2 * eps) - col["r"])) < 1e-6 * scale
        assert np.max(np.abs((plus.psi - minus.psi) / (2 * eps) - col["psi"])) < 1e-6 * max(
            np.max(np.abs(col["psi"])), 1e-3)
        fd_energy = (plus.energy - minus.energy) / (2 * eps)
        assert abs(fd_energy - col["energy"]) < 1e-6 * max(abs(col["energy"]), 1e-6)


def test_sensitivity_names():
    problem = Problem("uniform", {"k": 0.5}, h=0.3, cut=0.3)
    solver = DirectSolver(problem.structure, 100)
    sens = Parametric(solver).sensitivities(solver.solve(problem))
    assert sens.names == ("h", "cut", "opening", "k")
    with pytest.raises(ValueError, match="unknown parameter 'f0'"):
        sens.column("f0")


@pytest.mark.parametrize("compiled", ["1", "0"], ids=["compiled", "casadi"])
@pytest.mark.parametrize("problem", [
    pytest.param("toy3_anisotropic", id="toy3"),
    pytest.param(Problem("volvox", h=0.15, opening=0.3), id="volvox")])
def test_kkt_residual_parameter_derivative_is_the_assembled_jacobian(problem, compiled,
                                                                      monkeypatch):
    """∂F/∂p from cell kernels (∂F/∂D per cell times dD/dp per Gauss point) equals the
    MX Jacobian of the assembled KKT residual through the differentiable data D(p)."""
    import casadi as ca

    from morphoshell.numerics import discretisation
    from morphoshell.io.problem_files import example_path, load_problem
    from morphoshell.numerics.mesh import mesh_spec

    if isinstance(problem, str):
        problem = load_problem(example_path(problem))[0]
    monkeypatch.setenv("MORPHOSHELL_COMPILE", compiled)
    discretisation.compiled_cell_functions.cache_clear()
    try:
        solver = DirectSolver(problem.structure, mesh=mesh_spec(problem, 30, 2))
        d = solver.disc
        assert compiled == "1" or d.kernels == "casadi"
        n, m = d.layout.size, d.constraints
        x, lam = ca.MX.sym("x", n), ca.MX.sym("lam", m)
        direct = ca.Function("direct", [x, lam, d.p, d.q],
                             [ca.jacobian(Parametric(solver).kkt_residual(x, lam, d.p, d.q),
                                          d.p)])
        rng = np.random.default_rng(0)
        p, q = problem.parameter_vector(), np.zeros(d.q.shape[0])
        x0, lam0 = d.initial_guess(p, q) + 0.01 * rng.normal(size=n), rng.normal(size=m)
        one = np.array(direct(x0, lam0, p, q))
        two = d.kkt_residual_theta_numeric(x0, lam0, d.cell_data(p, q),
                                           np.array(d.pre_jacobian(p, q)))
        assert one.shape == two.shape == (n + m, len(p))
        # the same derivatives summed in another order: rounding only (measured 1.5e-16, 5e-16)
        assert np.abs(one).max() > 1
        assert np.abs(one - two).max() < 1e-12 * np.abs(one).max()
    finally:
        discretisation.compiled_cell_functions.cache_clear()


def test_kkt_matrix_is_the_assembled_jacobian():
    """K, gathered from the Hessian's and Jacobian's nonzeros by a pattern built once,
    equals the MX Jacobian of the assembled KKT residual in (x, λ); its LUs (the
    first one's column order reused by the next) solve K z = b."""
    import casadi as ca
    import scipy.sparse.linalg

    from morphoshell.numerics.mesh import mesh_spec

    problem = Problem("volvox", h=0.15, opening=0.3)
    solver = DirectSolver(problem.structure, mesh=mesh_spec(problem, 30, 2))
    d, par = solver.disc, Parametric(solver)
    n, m = d.layout.size, d.constraints
    x, lam = ca.MX.sym("x", n), ca.MX.sym("lam", m)
    direct = ca.Function("direct", [x, lam, d.p, d.q], [ca.jacobian(
        par.kkt_residual(x, lam, d.p, d.q), ca.vertcat(x, lam))])
    rng = np.random.default_rng(0)
    p, q = problem.parameter_vector(), np.zeros(d.q.shape[0])
    D = d.cell_data(p, q)
    b = rng.normal(size=(n + m, 3))
    for first in (True, False):     # two points off the equilibrium: every term counts
        x0, lam0 = d.initial_guess(p, q) + 0.01 * rng.normal(size=n), rng.normal(size=m)
        one = np.array(ca.densify(direct(x0, lam0, p, q)))
        K = par.kkt_matrix(x0, D, lam0)
        # the same second derivatives summed in another order: rounding only
        assert np.abs(one).max() > 1
        assert np.abs(one - K.toarray()).max() < 1e-12 * np.abs(one).max()
        z = par._factor(x0, D, lam0)(b)
        assert par._ordered is not None       # kept for the next point
        # the reused order is the one SuperLU chooses itself: the same solution up to
        # rounding (measured: identical), and a backward-stable one
        ref = scipy.sparse.linalg.splu(K).solve(b)
        assert np.abs(z - ref).max() < 1e-12 * np.abs(ref).max()
        assert np.abs(K @ z - b).max() < 1e-12 * abs(K).max() * np.abs(z).max()
