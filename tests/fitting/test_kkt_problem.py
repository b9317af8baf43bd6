"""The KKT fit's NLP (fitting.kkt_problem): its start multipliers, fit points and bounds."""
import casadi as ca
import numpy as np

from morphoshell.fitting import fit, synthetic_midline, volvox_spec

from fitting_cases import NODES, START, TRUE, three_parameter_spec


def test_kkt_start_multipliers_are_the_reduced_problems_adjoints():
    """From an equilibrium the KKT NLP starts from the adjoints: the Lagrangian is
    stationary in every unknown but θ, and its gradient in θ is the reduced
    gradient Jᵀr of the gradient method (implicit function theorem), an
    independent route (up to the blended points' O(ds³) mismatch: 6e-5 at 30
    nodes, 8e-7 at 60)."""
    from morphoshell.fitting.inner import InnerProblem
    from morphoshell.fitting.kkt_problem import KKTProblem
    from morphoshell.solvers.observables import midline_cells

    spec = volvox_spec("flat", START)
    inner = InnerProblem(spec, synthetic_midline(TRUE, spec.base, nodes=NODES, noise=1e-3),
                         NODES)
    theta, x, lam = spec.theta0, inner.eq.x, inner.eq.lam_g
    nlp = KKTProblem(spec, inner, 1e-8, 10)
    nlp._build(midline_cells(inner.solver.disc, x, spec.problem(theta).parameter_vector(),
                             inner.n))
    w0 = np.concatenate([theta, x, lam, nlp._lifted_start(theta, x)])
    data = inner.data.ravel()
    lam_g, lam_x = nlp._adjoint_duals(w0, data)
    _, grad = nlp.nlp.get_function("nlp_grad_f")(w0, data)
    grad = np.asarray(grad).ravel()
    dL = grad + nlp.lagrangian[-1](w0, data)[1].sparse().T @ lam_g + lam_x
    k = len(theta)
    reduced = inner.jacobian(inner.eq, theta).T @ inner.residuals(inner.eq)
    assert np.abs(reduced).max() > 0.1 * np.abs(grad).max()     # far from the optimum
    assert np.abs(dL[k:]).max() < 1e-12 * np.abs(grad).max()
    assert np.abs(dL[:k] - reduced).max() < 1e-5 * np.abs(reduced).max()


def test_kkt_fit_points_do_not_depend_on_the_window_around_their_cell():
    """Each NLP fit point is the midline point wherever its cell sits in its window.

    Far cells of the window evaluate a polynomial outside its cell, where
    Newton's iteration for the arclength can end on a wrong root inside the
    cell: weighted by that place, it moved a point by 110 R here (window
    shifted by two cells); weighted by the linear estimate of S, it gets none.
    """
    from morphoshell.fitting.inner import InnerProblem
    from morphoshell.fitting.kkt_problem import WINDOW, KKTProblem
    from morphoshell.solvers.observables import midline_cells

    spec = volvox_spec("flat", TRUE)
    inner = InnerProblem(spec, synthetic_midline(TRUE, spec.base, nodes=30), 30)
    theta, x, d = spec.theta0, inner.eq.x, inner.solver.disc
    p = spec.problem(theta).parameter_vector()
    y = np.asarray(inner.midline(x, p)).ravel()
    true = np.column_stack([y[:inner.n], y[inner.n:]])
    cells = midline_cells(d, x, p, inner.n)
    nlp = KKTProblem(spec, inner, 1e-8, 10)
    for shift in range(-WINDOW, WINDOW + 1):
        nlp._build(tuple(min(max(c + shift, 0), d.layout.cells - 1) for c in cells))
        w, target, _, _, f, *_ = nlp.lagrangian
        w0 = np.concatenate([theta, x, inner.eq.lam_g, nlp._lifted_start(theta, x)])
        data = true.ravel() + 0.01      # f = |rz - data|^2 / 2: rz = data - df/d(data)
        rz = data - np.asarray(ca.Function("g", [w, target], [ca.gradient(f, target)])(
            w0, data)).ravel()
        # blending differs from the midline by the cell polynomials' mismatch at
        # their ends, O(ds^3): 1.2e-5 R at 30 nodes
        assert np.abs(rz.reshape(-1, 2) - true).max() < 1e-4, shift


def test_a_kkt_start_on_a_bound_stays_an_equilibrium(monkeypatch):
    """A start with a parameter on its bound (Gauss-Newton steps that ended on a breakpoint's
    box) is not pushed off the equilibrium: Ipopt's default push of 1e-3 into the bound gave
    a first iterate violating the constraints by 4 and an NLP that failed after 60
    iterations (synthetic KKT campaign, undeformed t03)."""
    from dataclasses import replace

    from morphoshell.fitting.kkt_problem import KKTProblem

    base = three_parameter_spec()
    # the start value of s2 is its box's lower edge (and the truth lies inside)
    spec = replace(base, bounds={**base.bounds, "s2": (START.params["s2"], 1.9)})
    data = synthetic_midline(TRUE, nodes=NODES)
    violations = []
    solve = KKTProblem.solve

    def recording(self, *args, **kwargs):
        try:
            return solve(self, *args, **kwargs)
        finally:
            violations.append(self.nlp.stats()["iterations"]["inf_pr"][0])

    monkeypatch.setattr(KKTProblem, "solve", recording)
    result = fit(spec, data, "kkt", nodes=NODES)
    # (1e-3 of push in s2 moves the mesh under the state: 1e-2 or more)
    assert violations and violations[0] < 1e-6, violations
    assert result.converged and result.E_fit < 1e-6
    assert abs(result.parameters["s2"] - TRUE.params["s2"]) < 1e-4
