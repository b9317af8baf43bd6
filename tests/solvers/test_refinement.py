"""The error estimate's coarse levels (solvers/refinement.py)."""
import math

import pytest

from morphoshell import Problem, solve

VOLVOX = Problem("volvox", {}, h=0.15, opening=0.3)


def test_a_coarse_level_that_cannot_hold_the_knots_is_skipped():
    """The Volvox shell's 4 knots fit 20 nodes but not the estimate's quarter mesh of 5
    (a user audit: solve(p, nodes=20) raised "4 cells cannot hold 4 mesh knots" although
    12, 16 and 24 worked): the estimate uses the two levels there are, and on 10 nodes,
    whose half mesh is the 5 nodes, it is unavailable with a note, as for a half mesh that
    does not converge.  (No tolerance: which levels are used is exact.)"""
    eq = solve(VOLVOX, nodes=20)
    assert eq.error.reference_nodes == 10 and eq.error.note == ""
    assert all(math.isfinite(v) for v in eq.error.errors.values())
    eq = solve(VOLVOX, nodes=10)
    assert eq.error.reference_nodes == 0
    assert eq.error.note == "the half mesh (5 nodes) cannot hold the mesh's knots"
    assert all(math.isnan(v) for v in eq.error.errors.values())


def test_nodes_too_few_for_the_knots_are_refused_naming_the_least():
    """The user's own mesh too small for the family's knots is bad input, one line naming
    ``nodes`` and the fewest nodes that hold the knots (6 here: a cell per segment)."""
    with pytest.raises(ValueError, match=r"^nodes = 5 is too few for this shell's 4 mesh "
                       r"knots .*: the fewest nodes that hold them are 6$"):
        solve(VOLVOX, nodes=5)
    solve(VOLVOX, nodes=6)
