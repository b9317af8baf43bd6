"""Fixtures shared by the plotting tests."""
import matplotlib.pyplot as plt
import pytest

from morphoshell.model.problem import Problem
from morphoshell.solvers.routes import solve


@pytest.fixture(scope="module")
def volvox():
    """A large family with a long description: the title once wrapped to three lines."""
    return solve(Problem("volvox", {"kappa1": 1.1}, h=0.15, opening=0.3, name="volvox_demo"),
                 nodes=50)


@pytest.fixture(autouse=True)
def _close_figures():
    yield
    plt.close("all")
