"""The local solutions at a pole (solvers/poles.py) and which poles are weakly singular."""
import pytest

from morphoshell import Problem
from morphoshell.solvers.poles import pole_solutions, weakly_singular


def test_thick_sphere_poles_are_weakly_singular_on_the_way_from_stress_free():
    """h = 0.8: k = 0.8 gives β₁ = 0.754 at both poles (measured; the isotropic k = 0 is
    regular, β = 1 twice).  The exponents are roots of a quartic: 1e-3 is far above its
    round-off and far below the distance to 1."""
    out = weakly_singular(Problem("uniform", {"k": 0.8}, h=0.8))
    assert set(out) == {"start", "end"}
    assert out["start"] == pytest.approx(0.754, abs=1e-3)
    assert weakly_singular(Problem("uniform", {"k": 0.0}, h=0.8)) == {}


def test_only_poles_count():
    """A cut shell has one pole, at its end; the regular anisotropic stretch f0 > 0 has
    β = (1 + f0)² > 1 classically (1.42 here, measured) and is not weakly singular."""
    assert set(weakly_singular(Problem("uniform", {"k": 0.8}, h=0.8, cut=0.3))) == {"end"}
    assert set(pole_solutions(Problem("uniform", {"k": 0.8}, h=0.8, cut=0.3))) == {"end"}
    assert weakly_singular(Problem("anisotropic", {"f0": 0.19}, h=0.0019)) == {}
