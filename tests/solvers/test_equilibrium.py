"""The front door: solver reuse, bounded caches, options, and names registered twice."""
import casadi as ca
import numpy as np
import pytest

from morphoshell import DirectSolver, Problem, solve
from morphoshell.solvers import routes as front
from morphoshell.model.coefficients import Coefficients, classical, register_theory
from morphoshell.numerics.mesh import mesh_spec
from morphoshell.model.profiles import FAMILIES, ProfileFamily, Profiles, register_family


def _bump(scale):
    def build(s, p, cut, end):
        one = 1 + 0 * s
        return Profiles(one, one, scale * p["k"] * one, scale * p["k"] * one)
    return build


@pytest.fixture
def restore_registries():
    from morphoshell.model.coefficients import THEORIES
    families, theories = dict(FAMILIES), dict(THEORIES)
    yield
    FAMILIES.clear(), FAMILIES.update(families)
    THEORIES.clear(), THEORIES.update(theories)


@pytest.mark.parametrize("method", ["direct", "bvp"])
def test_re_registering_a_family_changes_the_answer(restore_registries, method):
    # what a notebook user does: run the cell defining a family, solve, edit
    # the cell and run it again
    register_family(ProfileFamily("bump", ("k",), {"k": 0.5}, _bump(1.0)))
    first = Problem("bump", h=0.3, cut=0.3)
    e1 = solve(first, method=method).energy
    register_family(ProfileFamily("bump", ("k",), {"k": 0.5}, _bump(2.0)))
    second = Problem("bump", h=0.3, cut=0.3)
    e2 = solve(second, method=method).energy
    # kappa0 = 2k = 1 is the undeformed curvature: nearly stress free
    assert e2 < 1e-6 * e1
    assert second.profiles([0.5])["kappa_s0"][0] == 1.0
    # a problem keeps the family it was created with, in every route
    assert first.profiles([0.5])["kappa_s0"][0] == 0.5
    assert solve(first, method=method).energy == pytest.approx(e1, rel=1e-9)


def test_re_registering_a_theory_changes_the_answer(restore_registries):
    p = Problem("uniform", {"k": 0.0}, h=0.3, cut=0.3, theory="classical")
    e1 = solve(p).energy

    def stiffer(eta):
        return Coefficients(*[2 * c for c in classical(eta)])
    register_theory("classical", stiffer)
    e2 = solve(Problem("uniform", {"k": 0.0}, h=0.3, cut=0.3, theory="classical")).energy
    # every coefficient doubled: the same shape at twice the energy
    assert e2 == pytest.approx(2 * e1, rel=1e-8)
    assert solve(p).energy == pytest.approx(e1, rel=1e-9)


def _rss_mb():
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * 4096 / 2**20


def test_sweep_over_h_and_cut_reuses_solvers():
    builds0 = front.cache_info()["builds"]
    rss0, peak = _rss_mb(), 0.0
    results = {}
    hs, cuts = np.linspace(0.02, 0.3, 10), np.linspace(0.05, 1.4, 20)
    for h in hs:
        for cut in cuts:
            p = Problem("uniform", {"k": 0.0}, h=h, cut=cut, theory="classical")
            results[h, cut] = solve(p, nodes=200)
            peak = max(peak, _rss_mb() - rss0)
    builds = front.cache_info()["builds"] - builds0
    # h over 15x and the cut over 28x cross 3 octaves of the boundary layer
    # relative to the shell, and small cuts add their own grading: 7 meshes,
    # each with its half and quarter mesh for the error estimate (some of
    # these coarse twins coincide: 18 builds measured)
    assert builds <= 3 * 7, builds
    assert peak < 150, peak
    assert front.cache_info()["solvers"] <= front.SOLVER_CACHE_SIZE
    # the same answers as solvers built for each problem alone
    for h, cut in list(results)[::23]:
        p = Problem("uniform", {"k": 0.0}, h=h, cut=cut, theory="classical")
        fresh = DirectSolver(p.structure, mesh=mesh_spec(p, 200, 2)).solve(p)
        assert np.max(np.abs(fresh.x - results[h, cut].x)) < 1e-9
        assert fresh.energy == pytest.approx(results[h, cut].energy, rel=1e-9)


def test_every_documented_option_works_through_solve():
    p = Problem("uniform", {"k": 0.5}, h=0.3, cut=0.3)
    base = solve(p)
    for options in ({"ipopt_options": {"max_iter": 100, "mu_strategy": "adaptive"}},
                    {"stability": "exact"}, {"tol": 1e-12}, {"max_iter": 200},
                    {"linear_solver": "mumps"}, {"stages": 3}):
        eq = solve(p, **options)
        assert eq.energy == pytest.approx(base.energy, rel=1e-6), options
    bvp = solve(p, method="bvp", tol=1e-6, bc_tol=1e-6, pole_offset=1e-4, max_nodes=100000,
                homotopy_steps=1)
    assert bvp.energy == pytest.approx(base.energy, rel=1e-5)
    with pytest.raises(ValueError, match=r"unknown option\(s\) \['pole_offset'\] for method 'direct'"):
        solve(p, pole_offset=1e-3)
    with pytest.raises(ValueError, match=r"unknown option\(s\) \['stages'\] for method 'bvp'"):
        solve(p, method="bvp", stages=2)


def test_solver_cache_is_bounded():
    front.clear_cache()
    for n in range(20, 20 + front.SOLVER_CACHE_SIZE + 4):
        solve(Problem("uniform", {"k": 0.5}, h=0.3, cut=0.3), nodes=n)
    assert front.cache_info()["solvers"] == front.SOLVER_CACHE_SIZE


def test_compiled_functions_do_not_depend_on_names():
    # the per-cell functions see the family and theory only through the data
    # (so they are shared, and nothing keyed on a name can go stale)
    # and, while both live, two structures of one size share the assembly built from
    # them: each still solves to the bits it has alone
    import gc

    from morphoshell.numerics.cell_kernels import cell_functions as _cell_functions
    pa, pb = Problem("uniform", h=0.1), Problem("anisotropic", h=0.1, theory="classical")
    gc.collect()
    alone = DirectSolver(pb.structure, 20).solve(pb)
    a = DirectSolver(pa.structure, 20)
    b = DirectSolver(pb.structure, 20)
    assert a.disc.grad_f is b.disc.grad_f
    a.solve(pa)
    assert np.array_equal(b.solve(pb).x, alone.x)
    assert _cell_functions.cache_info().currsize <= 3
    assert isinstance(_cell_functions(2)["f"], ca.Function)
