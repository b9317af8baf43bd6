"""The cell order of the KKT unknowns and the Newton system's assembly in it."""
import casadi as ca
import numpy as np
import pytest

from morphoshell import Problem
from morphoshell.numerics import cell_order
from morphoshell.numerics.cell_order import CellOrder, assembly, offsets
from morphoshell.solvers.direct import DirectSolver
from morphoshell.numerics.cell_kernels import NEWTON_EPSILON
from morphoshell.numerics.scheme import POLE_VALUES
from morphoshell.io.problem_files import example_path, load_problem
from morphoshell.numerics.mesh import mesh_spec

POLES = [(False, False), (True, False), (False, True), (True, True)]


def _by_hand(S: int, cells: int):
    """Every (u row, u col) of K and every u entry with the cells' values that sum there, by
    loops over the cells' local slots (values numbered n_tri + 1, resp. L + 1, per cell)."""
    b, L = 4 * S, 4 * S + 2
    n_tri = L * (L + 1) // 2
    ku, lu = np.triu_indices(L)
    tri = np.zeros((L, L), dtype=int)
    tri[ku, lu] = tri[lu, ku] = np.arange(n_tri)
    off = offsets(S)
    K, u = {}, {}
    for c in range(cells):
        for i in range(L):
            u.setdefault(c * b + off[i], []).append(c * (L + 1) + i)
            for j in range(L):
                K.setdefault((c * b + off[i], c * b + off[j]), []).append(c * (n_tri + 1)
                                                                          + tri[i, j])
    return K, u, n_tri, L


def _summed(values: np.ndarray, first, pairs) -> np.ndarray:
    """What ``gathers.summed`` makes of ``values``, in NumPy."""
    out = values.copy()
    a, b = (np.array(v, dtype=float).ravel().astype(int) for v in pairs)
    assert len(np.unique(a)) == len(a)     # (each sum once)
    out[a] += values[b]
    return out[np.array(first, dtype=float).ravel().astype(int)]


@pytest.mark.parametrize("S", [1, 2, 3])
@pytest.mark.parametrize("cells", [1, 2, 5, 64, 65])
@pytest.mark.parametrize("poles", POLES)
def test_assembly_sums_each_cells_values_into_place(S, cells, poles, monkeypatch):
    if cells == 1 and all(poles):
        pytest.skip("one cell between two poles has no free node")
    if cells == 65:    # beyond the kept tables: a table of the mesh's own size
        monkeypatch.setattr(cell_order, "LARGEST_TABLE", 64)
    order = CellOrder(cells, S, *poles)
    a = assembly(order)
    K, u, n_tri, L = _by_hand(S, cells)
    lo, hi = order.lo, order.hi
    rng = np.random.default_rng(S * 1000 + cells)
    values = rng.normal(size=(cells, n_tri + 1))
    values[:, -1] = 0.0             # (each cell's last value is the kernels' zero)
    values = values.ravel()
    got = np.zeros((hi - lo, hi - lo))
    rows, cols = a.K.get_triplet()
    got[rows, cols] = _summed(values, a.first, a.pairs)
    want, pattern = np.zeros_like(got), np.zeros(got.shape, dtype=bool)
    for (i, j), src in K.items():
        if lo <= i < hi and lo <= j < hi:
            want[i - lo, j - lo] = sum(values[s] for s in src)
            pattern[i - lo, j - lo] = True
    assert a.K.nnz() == pattern.sum() and pattern[rows, cols].all()
    assert np.array_equal(got, want)      # (two values: the sum is the same bits either way)
    v = rng.normal(size=(cells, L + 1))
    v[:, -1] = 0.0
    v = v.ravel()
    assert np.array_equal(_summed(v, a.rhs_first, a.rhs_pairs),
                          [sum(v[s] for s in u[j]) for j in range(lo, hi)])
    assert np.array_equal(np.array(a.local).ravel(),
                          (4 * S * np.arange(cells)[:, None] + offsets(S)).ravel())
    px, pl = order.positions
    mask = np.zeros(order.size)
    mask[px] = 1
    assert np.array_equal(np.array(a.x_mask).ravel(), mask[lo:hi])


@pytest.mark.parametrize("poles", POLES)
def test_pack_and_unpack_are_inverse_and_fill_the_poles(poles):
    order = CellOrder(7, 3, *poles)
    px, pl = order.positions
    fixed = np.setdiff1d(np.arange(order.size), np.concatenate([px, pl]))
    assert len(np.unique(np.concatenate([px, pl]))) == len(px) + len(pl)
    assert np.array_equal(fixed, np.r_[[0, 1] if poles[0] else [],
                                       [order.size - 2, order.size - 1] if poles[1] else []])
    assert order.hi - order.lo == len(px) + len(pl)
    x, lam = np.arange(len(px)) + 0.5, -np.arange(len(pl)) - 0.5
    u = order.pack(x, lam, POLE_VALUES)
    assert all(np.array_equal(a, b) for a, b in zip(order.unpack(u), (x, lam)))
    if poles[0]:
        assert list(u[:2]) == [POLE_VALUES[0], POLE_VALUES[1]]
    if poles[1]:
        assert list(u[-2:]) == [POLE_VALUES[0], POLE_VALUES[2]]


@pytest.mark.parametrize("case", ["toy3", "classical"])
@pytest.mark.parametrize("stages", [1, 3])
def test_newton_system_is_ipopts_kkt_matrix_in_cell_order(case, stages):
    """K from the cells' kernels, in cell order, against K built from Ipopt's assembled
    Hessian and Jacobian (another assembly: index lists in the NLP's order) at a random
    point: [[H + Jᵀ W J, Jᵀ], [J, −ε W⁻¹]] permuted, and rhs = −(∇f + Jᵀ(λ + W g), g)."""
    if case == "toy3":
        problem, _ = load_problem(example_path("toy3_anisotropic"))     # a pole at the start
    else:
        problem = Problem("uniform", {"k": 0.0}, h=1e-3, cut=0.5, theory="classical")
    solver = DirectSolver(problem.structure, stages=stages, mesh=mesh_spec(problem, 12, stages))
    d = solver.disc
    p = problem.parameter_vector()
    D = d.cell_data(p, ())
    rng = np.random.default_rng(stages)
    x = d.initial_guess(p, ()) + 1e-2 * rng.normal(size=d.layout.size)
    lam = rng.normal(size=d.constraints)
    u = d.kkt_pack(x, lam)
    K, rhs, dual, primal, l1, w = (np.array(ca.densify(v)) for v in
                                   d.newton_system()(u, D, 1.0))
    w = w.ravel()
    nlp = d.numeric
    f, grad = nlp["grad_f"](x, D)
    g, J = nlp["jac_g"](x, D)
    H = ca.densify(nlp["hess_lag"](x, D, 1.0, lam))
    H, J, g, grad = (np.array(ca.densify(v)) for v in (H, J, g, grad))
    H = np.triu(H) + np.triu(H, 1).T
    g, grad = g.ravel(), grad.ravel()
    want = np.block([[H + J.T @ np.diag(w) @ J, J.T], [J, np.diag(-NEWTON_EPSILON / w)]])
    px, pl = d.cell_order.positions
    perm = np.concatenate([px, pl]) - d.cell_order.lo        # NLP entry i sits at perm[i]
    got = K[np.ix_(perm, perm)]
    assert np.allclose(got, want, rtol=1e-12, atol=1e-12 * np.abs(want).max())
    assert np.array_equal(K != 0, K.T != 0) and np.allclose(K, K.T, rtol=0, atol=0)
    want_rhs = -np.concatenate([grad + J.T @ (lam + w * g), g])
    assert np.allclose(rhs.ravel()[perm], want_rhs, rtol=1e-12,
                       atol=1e-12 * np.abs(want_rhs).max())
    assert np.isclose(dual.item(), np.abs(grad + J.T @ lam).max(), rtol=1e-12)
    assert primal.item() == np.abs(g).max() and np.isclose(l1.item(), np.abs(lam).sum())
