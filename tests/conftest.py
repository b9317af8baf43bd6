"""Fixtures shared by several test modules."""
import casadi as ca
import pytest

from morphoshell import Problem
from morphoshell.model.profiles import FAMILIES, ProfileFamily, Profiles, register_family


def _central_growth(s, p, cut, end):
    f = 1 + p["G"] * ca.exp(-(s / 0.3) ** 2)
    zero = 0 * s
    return Profiles(f, f, zero, zero)


@pytest.fixture(scope="module")
def blister():
    """A flat disc grown in its centre: the flat state is stationary by mirror
    symmetry but buckles; the stable state is a dome (a blister)."""
    if "central_growth" not in FAMILIES:
        register_family(ProfileFamily("central_growth", ("G",), {"G": 0.2}, _central_growth,
                                      neutral={"G": 0.0}))
    return Problem("central_growth", {"G": 0.2}, h=0.02, geometry="disc")
