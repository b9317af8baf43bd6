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
