"""Assembly by index gathers (numerics.gathers): the same matrices, to the bit, as the scatters."""
import casadi as ca
import numpy as np

from morphoshell.numerics.gathers import assembled, gather, scatter


def _triplets(rng, trial: int, size: int, entries: int, sources: int):
    """Random (shape, n_src, rows, cols, src); every third trial repeats half its triplets."""
    nr, nc = (int(v) for v in rng.integers(1, size, 2))
    k, n_src = int(rng.integers(0, entries)), int(rng.integers(1, sources))
    r, c, s = rng.integers(0, nr, k), rng.integers(0, nc, k), rng.integers(0, n_src, k)
    if trial % 3 == 0:
        r, c, s = (np.concatenate([v, v[:k // 2]]) for v in (r, c, s))
    return nr, nc, n_src, r, c, s


def test_scatter_is_the_triplet_matrices():
    # scatter builds its matrices in compressed form: exactly CasADi's triplet constructors'
    rng = np.random.default_rng(0)
    for trial in range(100):
        nr, nc, n_src, r, c, s = _triplets(rng, trial, 25, 60, 30)
        sp, B = scatter((nr, nc), r, c, s, n_src)
        uniq, pos = np.unique(c * nr + r, return_inverse=True)
        assert sp == ca.Sparsity.triplet(nr, nc, (uniq % nr).tolist(), (uniq // nr).tolist())
        ref = ca.DM.triplet(pos.ravel().tolist(), s.tolist(), ca.DM.ones(len(s), 1), len(uniq),
                            n_src)
        assert B.shape == ref.shape and B.sparsity() == ref.sparsity()
        assert B.nonzeros() == ref.nonzeros()
        if trial % 3:          # and the (row, col) entry sums values[src] (of distinct triplets)
            v = rng.normal(size=n_src)
            dense = np.zeros((nr, nc))
            ru, cu, su = np.unique(np.stack([r, c, s]), axis=1)
            np.add.at(dense, (ru, cu), v[su])
            assert np.allclose(np.array(ca.densify(ca.DM(sp, B @ v))), dense, atol=1e-14)


def test_gathers_assemble_the_scatter_to_the_bit():
    # gather's index lists sum each nonzero's values in the order B @ values does
    rng = np.random.default_rng(1)
    for trial in range(60):     # (repeated triplets count once, as in B)
        nr, nc, n_src, r, c, s = _triplets(rng, trial, 20, 80, 40)
        sp, B = scatter((nr, nc), r, c, s, n_src)
        sp_g, first, extras = gather((nr, nc), r, c, s, n_src)
        assert sp_g == sp
        v = ca.MX.sym("v", n_src)
        f = ca.Function("f", [v], [ca.MX(sp, ca.mtimes(B, v)),
                                   assembled(sp_g, first, extras, v)])
        one, two = f(rng.normal(size=n_src) * 10.0 ** rng.integers(-8, 8, n_src))
        assert one.sparsity() == two.sparsity()
        assert np.array_equal(np.array(one.nonzeros()), np.array(two.nonzeros()))
