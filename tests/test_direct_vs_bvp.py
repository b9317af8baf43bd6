"""Direct minimisation against the boundary-value reference, and mesh refinement.

Two independent routes to the same equilibrium: the discretised energy
minimised by Ipopt, and the Euler–Lagrange (Pontryagin) equations solved by
scipy's collocation solver.  They share only the pointwise energy density.
"""
import numpy as np
import pytest

from morphoshell import Problem, solve

NODES = (1600, 3200, 6400, 12800)

CASES = {
    "uniform k=0": Problem("uniform", {"k": 0.0}, h=0.3, cut=0.3),
    "uniform k=0.5": Problem("uniform", {"k": 0.5}, h=0.3, cut=0.3),
    "uniform k=2": Problem("uniform", {"k": 2.0}, h=0.3, cut=0.3),
    "anisotropic f0=+0.1": Problem("anisotropic", {"f0": 0.1}, h=0.3, cut=0.3),
    "anisotropic f0=-0.1": Problem("anisotropic", {"f0": -0.1}, h=0.3, cut=0.3),
    "volvox pole": Problem("volvox", h=0.15, opening=0.3),
    "volvox cut": Problem("volvox", h=0.15, opening=0.3, cut=0.2),
}


def _edge_values(eq):
    edge = "start" if eq.problem.structure.start == "free" else "end"
    e = eq.edge(edge)
    return np.array([e["r"], e["psi"], eq.energy])


@pytest.fixture(scope="module", params=list(CASES), ids=list(CASES))
def runs(request):
    problem = CASES[request.param]
    direct = {n: solve(problem, nodes=n) for n in NODES}
    # The Volvox shapes have several equilibria: seed the BVP with the direct
    # solution so that both describe the same one (the guess selects the
    # branch; the BVP's own equations and tolerance decide the answer).
    guess = direct[NODES[0]] if problem.family == "volvox" else None
    bvp = solve(problem, method="bvp", warm_start=guess)
    return problem, direct, bvp


def test_volvox_cases_reach_large_eta():
    # The issue asks for a Volvox-like profile with abs(eta) >= 0.7.
    for name in ("volvox pole", "volvox cut"):
        assert CASES[name].max_abs_eta() >= 0.7


def test_edge_values_and_energy_agree(runs):
    problem, direct, bvp = runs
    rel = np.abs(_edge_values(direct[NODES[-1]]) / _edge_values(bvp) - 1)
    # 1e-6 relative on the finest mesh, as the issue demands (measured worst:
    # 4.5e-7 for the psi of the Volvox shell with a cut).
    assert np.all(rel < 1e-6), rel


def test_richardson_limit_agrees_much_better(runs):
    # If both routes converge to the same equilibrium, removing the O(N^-2)
    # term of the direct error must leave a far smaller gap (measured
    # 1e-9 or less; 2e-8 leaves margin for the BVP's own tolerance).
    problem, direct, bvp = runs
    fine, finer = _edge_values(direct[NODES[-2]]), _edge_values(direct[NODES[-1]])
    limit = finer + (finer - fine) / 3
    assert np.all(np.abs(limit / _edge_values(bvp) - 1) < 2e-8)


def test_observed_order_is_two(runs):
    problem, direct, bvp = runs
    V = np.array([_edge_values(direct[n]) for n in NODES])
    # Self-convergence (no reference needed): successive differences shrink 4x.
    p_self = np.log2(np.abs(V[:-2] - V[1:-1]) / np.abs(V[1:-1] - V[2:]))
    # Convergence to the BVP solution.
    err = np.abs(V - _edge_values(bvp))
    p_ref = np.log2(err[:-1] / err[1:])
    # The scheme is second order; +-0.15 allows for the BVP's own error
    # (its tol is 1e-8) in the smallest differences.
    assert np.all(np.abs(p_self - 2) < 0.15), p_self
    assert np.all(np.abs(p_ref[:-1] - 2) < 0.15), p_ref


def test_bvp_is_converged_and_consistent(runs):
    problem, direct, bvp = runs
    assert bvp.converged and bvp.solver.method == "bvp"
    assert bvp.solver.details["max_rms_residual"] < 1e-7
    # s increases, z follows from z' = f_s sin(psi) in both routes: the height
    # of the far end agrees to the discretisation error.
    assert np.all(np.diff(bvp.s) > 0)
    d = direct[NODES[-1]]
    assert abs((d.z[-1] - d.z[0]) - (bvp.z[-1] - bvp.z[0])) < 1e-6
