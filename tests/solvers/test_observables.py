"""Observables as functions of (x, p): exact Jacobians against re-solves.

Every Jacobian comes from the implicit function theorem on the KKT system
(morphoshell.solvers.parametric); here it is compared with central differences of
warm-started re-solves.  The difference quotient's error is O(eps^2) times
the third derivative plus the solver's convergence error (~1e-12 in x) over
eps = 1e-5: about 1e-7 of the derivative's scale, so 1e-6 relative can fail
only if the derivative is wrong.
"""
import numpy as np
import pytest

from morphoshell import DirectSolver, Problem, ablate
from morphoshell.mechanics.ablation import recoil_jacobian
from morphoshell.solvers.observables import midline, state_at
from morphoshell.solvers.parametric import parametric


def _check_columns(problem, names, J, evaluate):
    """Column j of J against central differences of ``evaluate(problem with names[j] moved)``."""
    for j, name in enumerate(names):
        v = problem.params[name] if name in problem.params else getattr(problem, name)
        eps = 1e-5 * max(1.0, abs(v))
        fd = (evaluate(problem.with_updates(**{name: v + eps}))
              - evaluate(problem.with_updates(**{name: v - eps}))) / (2 * eps)
        _assert_close(fd, J[:, j], name)


def _assert_close(fd, exact, what):
    scale = max(np.max(np.abs(exact)), 1e-3)
    err = np.max(np.abs(fd - exact)) / scale
    assert err < 1e-6, (what, err)


CASES = [
    (Problem("anisotropic", {"f0": 0.1}, h=0.3, cut=0.3), 1.1, ("f0", "h", "cut")),
    (Problem("volvox", h=0.15, opening=0.3), 1.75, ("kappa2", "s2", "f1", "opening")),
]


@pytest.mark.parametrize("problem, s_star, names", CASES, ids=[c[0].family for c in CASES])
def test_state_at_a_material_point(problem, s_star, names):
    solver = DirectSolver(problem.structure, 200)
    eq = solver.solve(problem)
    p = problem.parameter_vector()
    obs = state_at(solver.disc, s_star, solver.disc.cell_of(p, (), s_star), gauge="far_end")
    value, J = parametric(solver).jacobian(eq, obs, names)
    # the observable is the solution's own state there (z: far-end gauge): the
    # cell polynomial and a spline through the points agree to their
    # interpolation errors (2.4e-6 in psi in the Volvox bend, where kappa_s0 = -9)
    at = eq.at(s_star)
    assert abs(value[0] - at["r"]) < 1e-5 and abs(value[2] - at["psi"]) < 1e-5
    _check_columns(problem, names, J, lambda sub: obs.at(solver.solve(sub, warm_start=eq)))


def test_midline_points():
    problem = Problem("volvox", h=0.15, opening=0.3)
    solver = DirectSolver(problem.structure, 200)
    eq = solver.solve(problem)
    p = problem.parameter_vector()
    obs = midline(solver.disc, 25)
    names = ("kappa2", "s1", "f4", "opening")
    value, J = parametric(solver).jacobian(eq, obs, names)
    r, z = value[:25], value[25:]
    # equally spaced in the deformed arclength, from the pole (origin) to the rim
    assert r[0] == 0 and z[0] == 0
    assert abs(r[-1] - eq.r[-1]) < 1e-12 and abs(z[-1] - (eq.z[-1] - eq.z[0])) < 1e-12
    chords = np.hypot(np.diff(r), np.diff(z))
    assert np.ptp(chords) < 0.05 * chords.mean()   # chords of equal arcs of a smooth curve
    _check_columns(problem, names, J, lambda sub: obs.at(solver.solve(sub, warm_start=eq)))



def test_midline_jacobian_is_casadis():
    """The midline's own chain rule (∂y/∂x an operator, never formed) against CasADi's
    MX Jacobians of the observable's function, on a mesh whose nodes move with the
    breakpoints (so ∂y/∂p has its node terms)."""
    import dataclasses

    import casadi as ca

    from morphoshell.numerics.mesh import mesh_spec

    problem = Problem("volvox", h=0.15, opening=0.3)
    solver = DirectSolver(problem.structure, mesh=mesh_spec(problem, 60, 2))
    eq = solver.solve(problem)
    obs = midline(solver.disc, 25)
    inputs = obs.inputs(eq.x, problem.parameter_vector(), eq.anchors)
    f = obs.function
    args = [f.mx_in(i) for i in range(f.n_in())]
    direct = ca.Function("direct", args, [ca.jacobian(f(*args), args[0]),
                                          ca.jacobian(f(*args), args[1])])
    yx, yp = (np.array(ca.densify(v)) for v in direct(*inputs))
    y, op, own = obs.jacobian(*inputs)
    # the value too, by the same cell polynomials in another kernel
    assert np.abs(y - obs(eq.x, problem.parameter_vector(), eq.anchors)).max() < 1e-14
    # the same derivatives summed in another order (cumulative sums over the cells):
    # rounding only (measured 4e-15 and 1e-13 relative at 200 nodes)
    assert np.abs(yx).max() > 0.1 and np.abs(yp).max() > 0.1
    assert np.abs(op.toarray() - yx).max() < 1e-11 * np.abs(yx).max()
    assert np.abs(own - yp).max() < 1e-11 * np.abs(yp).max()
    M = np.random.default_rng(0).normal(size=(yx.shape[1], 3))
    assert np.abs(op @ M - yx @ M).max() < 1e-11 * np.abs(yx @ M).max()
    # and through the implicit function theorem, against parametric's generic route
    names = ("kappa2", "s2", "f1", "opening")
    _, one = parametric(solver).jacobian(eq, obs, names)
    _, two = parametric(solver).jacobian(eq, dataclasses.replace(obs, jacobian=None), names)
    assert np.abs(one - two).max() < 1e-11 * np.abs(two).max()

@pytest.mark.parametrize("problem, names", [
    (Problem("uniform", {"k": 0.5}, h=0.3, cut=0.3), ("k", "h")),
    (Problem("anisotropic", {"f0": 0.1}, h=0.3, cut=0.3), ("f0",)),
    (Problem("local_relaxation", {"F0": 0.35, "s0": 0.2}, h=0.3, cut=0.3), ("F0", "h")),
], ids=["uniform", "anisotropic", "local_relaxation"])
def test_ablation_observables(problem, names):
    ab = ablate(problem)
    value, J = recoil_jacobian(ab, names)
    assert np.allclose(value[:3], [ab.opening, ab.rotation, ab.displacement], rtol=0, atol=1e-14)

    def recoil(sub):
        a = ablate(sub)
        return np.array([a.opening, a.rotation, a.displacement])
    _check_columns(problem, names, J[:3], recoil)


def test_recoil_jacobian_refuses_the_cut():
    ab = ablate(Problem("uniform", {"k": 0.5}, h=0.3, cut=0.3))
    with pytest.raises(ValueError, match="with respect to the cut"):
        recoil_jacobian(ab, ("cut",))


def test_sensitivities_include_z():
    problem = Problem("uniform", {"k": 0.5}, h=0.3, cut=0.3)
    solver = DirectSolver(problem.structure, 100)
    eq = solver.solve(problem)
    sens = parametric(solver).sensitivities(eq)
    eps = 1e-5
    fd = (solver.solve(problem.with_updates(k=0.5 + eps), warm_start=eq).z
          - solver.solve(problem.with_updates(k=0.5 - eps), warm_start=eq).z) / (2 * eps)
    _assert_close(fd, sens.column("k")["z"], "dz/dk")
    # the displacement of the rim needs it: in the solver's gauge (z fixed at
    # the rim) the far pole moves with k
    assert abs(sens.column("k")["z"][-1]) > 0.01


def test_kkt_residual_vanishes_at_solutions_only():
    problem = Problem("anisotropic", {"f0": 0.1}, h=0.3, cut=0.3)
    solver = DirectSolver(problem.structure, 100)
    eq = solver.solve(problem)
    F = parametric(solver).kkt_residual
    p = problem.parameter_vector()
    at_solution = np.max(np.abs(np.asarray(F(eq.x, eq.lam_g, p, []))))
    assert at_solution < 1e-8
    moved = problem.with_updates(f0=0.12).parameter_vector()
    assert np.max(np.abs(np.asarray(F(eq.x, eq.lam_g, moved, [])))) > 1e3 * at_solution


def test_derivatives_move_the_mesh_with_the_breakpoints():
    # on a mesh whose nodes follow s1..s4, d/ds2 includes the nodes' motion,
    # like the re-solves, which move them too
    from morphoshell.numerics.mesh import mesh_spec
    problem = Problem("volvox", h=0.15, opening=0.3)
    solver = DirectSolver(problem.structure, mesh=mesh_spec(problem, 200, 2))
    eq = solver.solve(problem)
    p = problem.parameter_vector()
    obs = state_at(solver.disc, 2.6, solver.disc.cell_of(p, (), 2.6))
    _, J = parametric(solver).jacobian(eq, obs, ("s2", "s4", "sigma"))
    _check_columns(problem, ("s2", "s4", "sigma"), J,
                   lambda sub: obs.at(solver.solve(sub, warm_start=eq)))
