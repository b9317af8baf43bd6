"""The bordered KKT system (issue 38): its inertia is the reduced Hessian's, and its block
elimination solves the bordered system.

The reference is built independently of :mod:`morphoshell.numerics.bordered`: the dense
Hessian of the Lagrangian f + λᵀg and the constraint Jacobian from the transcription's
differentiable NLP (``Discretisation.hess_lag`` / ``jac_g``), the reduced Hessian Zᵀ H Z
on the null space Z of the Jacobian (the last columns of a full QR of Jᵀ: an orthonormal
basis, as ``scipy.linalg.null_space`` gives but without its SVD, slow here), and its
eigenvalues.
"""
import contextlib
import ctypes
from pathlib import Path

import casadi as ca
import numpy as np
import pytest
import scipy.linalg

from morphoshell.io.problem_files import load_problem
from morphoshell.solvers.arclength import Arclength, bordered_kkt
from morphoshell.solvers.branches import follow_branch
from morphoshell.solvers.direct import solver_of

FIXTURE = Path(__file__).resolve().parents[1] / "data" / "volvox_fold.toml"


@pytest.fixture(scope="module")
def branch():
    """The fold shell of issue 38 on a small mesh (60 nodes: 354 unknowns, 118 constraints),
    followed through its six folds."""
    return follow_branch(load_problem(FIXTURE)[0], nodes=60)


@contextlib.contextmanager
def one_blas_thread():
    """NumPy's and SciPy's OpenBLAS on one thread (Linux; elsewhere nothing changes): on a
    busy 2-core machine their spin-waiting threads make these small dense products take
    seconds instead of milliseconds (cf. ``numerics.ipopt.load_ipopt``)."""
    maps = Path("/proc/self/maps")
    paths = {line.split()[-1] for line in maps.read_text().splitlines()
             if "openblas" in line.lower()} if maps.exists() else set()
    saved = []
    for path in sorted(paths):
        lib = ctypes.CDLL(path)
        for prefix, suffix in (("scipy_openblas", "64_"), ("openblas", "")):
            if hasattr(lib, f"{prefix}_get_num_threads{suffix}"):
                setter = getattr(lib, f"{prefix}_set_num_threads{suffix}")
                saved.append((setter, getattr(lib, f"{prefix}_get_num_threads{suffix}")()))
                setter(1)
                break
    try:
        yield
    finally:
        for setter, threads in saved:
            setter(threads)


def reduced_hessian_eigenvalues(eq) -> np.ndarray:
    """Eigenvalues of the reduced Hessian at ``eq`` (dense, from the CasADi NLP)."""
    with one_blas_thread():
        return _reduced_hessian_eigenvalues(eq)


def _reduced_hessian_eigenvalues(eq) -> np.ndarray:
    d = solver_of(eq).disc
    p = eq.problem.parameter_vector()
    D = d.cell_data(p, d.check_anchors(p, ()))
    J = np.array(ca.DM(d.jac_g(eq.x, D)[1]).full())
    grad = np.array(ca.DM(d.grad_f(eq.x, D)[1]).full()).ravel()
    # the multipliers are those of f + λᵀg: a stationary point of it
    assert np.max(np.abs(grad + J.T @ eq.lam_g)) < 1e-8
    upper = np.array(ca.DM(d.hess_lag(eq.x, D, 1.0, eq.lam_g)).full())
    H = upper + np.triu(upper, 1).T
    m = len(eq.lam_g)
    Q, R = scipy.linalg.qr(J.T)
    diag = np.abs(np.diag(R))
    assert np.min(diag) > 1e-10 * np.max(diag)           # J has full row rank
    Z = Q[:, m:]
    return np.linalg.eigvalsh(Z.T @ H @ Z)


def test_inertia_is_the_reduced_hessians_on_both_sides_of_folds(branch):
    """At the points either side of the first three folds (0|1, 1|2 and 2|1 negative
    eigenvalues) and at the path's ends, the LDLᵀ inertia of the bordered system counts
    the dense reduced Hessian's negative eigenvalues; the smallest eigenvalue in modulus
    (~3e-5) is far above round-off (~1e-12 of the largest, ~1e3), so the count is sharp."""
    folds = [i for i, pt in enumerate(branch.points) if pt.event == "fold"]
    assert len(folds) == 6
    picks = [0, len(branch.points) - 1] + [j for i in folds[:3] for j in (i - 1, i + 1)]
    counts = []
    for j in picks:
        pt = branch.points[j]
        ev = reduced_hessian_eigenvalues(pt.equilibrium)
        assert np.min(np.abs(ev)) > 1e-9 * np.max(np.abs(ev))
        assert pt.negative_eigenvalues == np.sum(ev < 0), (j, pt.tau, ev[:3])
        assert pt.stable == bool(np.all(ev > 0))
        counts.append(pt.negative_eigenvalues)
    assert counts == [0, 0, 0, 1, 1, 2, 2, 1]          # both sides of each fold seen


def test_block_elimination_solves_the_bordered_system(branch):
    """(du, dτ) from :meth:`BorderedKKT.solve` satisfy ``[K F_τ; cᵀ c_τ][du; dτ] = [b; β]``
    with K dense, at a point next to the first fold (K ill-conditioned there)."""
    folds = [i for i, pt in enumerate(branch.points) if pt.event == "fold"]
    pt = branch.points[folds[0] - 1]
    arc = Arclength(solver_of(pt.equilibrium), branch.line)
    kkt = bordered_kkt(arc.solver)
    u = kkt.pack(pt.equilibrium.x, pt.equilibrium.lam_g)
    state = kkt.state(u, arc._data(pt.tau), arc._around(pt.tau))
    rng = np.random.default_rng(38)
    k = len(state.rhs)
    b, c = rng.standard_normal(k), rng.standard_normal(k)
    du, dtau = kkt.solve(state, b, c, 0.3, 0.7)
    K = np.array(state.K.full())
    A = np.block([[K, state.F_tau[:, None]], [c[None, :], np.array([[0.3]])]])
    residual = A @ np.append(du, dtau) - np.append(b, 0.7)
    assert np.max(np.abs(residual)) < 1e-8 * np.max(np.abs(A)) * np.max(np.abs(np.append(du, dtau)))


def test_the_fused_iteration_is_state_and_solve_to_the_bit(branch):
    """:meth:`BorderedKKT.iterate_around` and :meth:`~BorderedKKT.iterate` (one buffered
    call each) give the column, the step and the KKT error that :meth:`~BorderedKKT.state`
    and :meth:`~BorderedKKT.solve` give from Python, bit for bit: correctors switched to
    them without changing any branch (next to the first fold, and at a stable point)."""
    folds = [i for i, pt in enumerate(branch.points) if pt.event == "fold"]
    for pt in (branch.points[folds[0] - 1], branch.points[3]):
        arc = Arclength(solver_of(pt.equilibrium), branch.line)
        kkt = bordered_kkt(arc.solver)
        u = kkt.pack(pt.equilibrium.x, pt.equilibrium.lam_g)
        state = kkt.state(u, arc._data(pt.tau), arc._around(pt.tau))
        Z, rhs, error, column = kkt.iterate_around(u, arc.parameters(pt.tau), arc.q,
                                                   arc.around_parameters(pt.tau))
        assert np.array_equal(column, state.F_tau) and np.array_equal(rhs, state.rhs)
        assert error == state.error
        c = np.linspace(-1.0, 1.0, len(rhs))
        expected = kkt.solve(state, state.rhs, c, 0.3, 0.7)
        for got in (kkt.eliminate(Z, c, 0.3, 0.7),
                    kkt.eliminate(kkt.iterate(u, arc.parameters(pt.tau), arc.q, column)[0],
                                  c, 0.3, 0.7)):
            assert np.array_equal(got[0], expected[0]) and got[1] == expected[1]
