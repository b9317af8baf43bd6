"""Equilibrium's accessors (solvers/results.py)."""
import pytest

from morphoshell import Problem, solve


def test_edge_refuses_anything_but_start_and_end():
    """A user audit: eq.edge("middle") returned the end's values."""
    eq = solve(Problem("uniform", {"k": 0.0}, h=0.3, cut=0.3), nodes=30)
    assert eq.edge("start")["s"] == pytest.approx(0.3, abs=0) and eq.edge("end")["s"] == eq.s[-1]
    for which in ("middle", "End", None):
        with pytest.raises(ValueError, match=rf"^which = {which!r} must be 'start' or 'end'$"):
            eq.edge(which)


def _same(a, b):
    """Whether two equilibria hold the same numbers, to the bit (the solver's wall times aside)."""
    import numpy as np

    from morphoshell.solvers.results import FIELDS

    return (a.problem == b.problem and a.energy == b.energy and a.anchors == b.anchors
            and all(np.array_equal(getattr(a, k), getattr(b, k)) for k in (*FIELDS, "x", "lam_g"))
            and all(np.array_equal(u, v) for u, v in zip(a.quadrature, b.quadrature))
            and a.error == b.error and a.solver.status == b.solver.status
            and a.solver.iterations == b.solver.iterations)


def test_an_equilibrium_pickles_with_its_mesh_but_not_its_solver():
    """A user audit: pickling a result failed on its problem and on the weak reference to
    its solver.  It comes back field for field, with its mesh: a solver of that mesh is
    rebuilt where needed, so it warm-starts on its own unknowns as the original does."""
    import pickle

    from morphoshell.solvers.direct import solver_of

    p = Problem("uniform", {"k": 0.5}, h=0.2, cut=0.3)
    eq = solve(p, nodes=40)
    back = pickle.loads(pickle.dumps(eq))
    assert _same(back, eq) and back.source[0]() is None and back.source[1:] == eq.source[1:]
    assert solver_of(back).mesh == solver_of(eq).mesh
    q = p.with_updates(k=0.55)
    assert _same(solve(q, nodes=40, warm_start=back), solve(q, nodes=40, warm_start=eq))


def _solve50(problem):
    return solve(problem, nodes=50)


def test_a_process_pool_takes_problems_and_returns_their_equilibria():
    """The audit's scan (t14.py): two spawned workers solve two problems; their results
    equal this process's to the bit."""
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    problems = [Problem("uniform", {"k": k}, h=0.3, cut=0.3) for k in (0.0, 0.5)]
    with ProcessPoolExecutor(2, mp_context=multiprocessing.get_context("spawn")) as pool:
        results = list(pool.map(_solve50, problems))
    assert all(_same(r, _solve50(p)) for r, p in zip(results, problems))
