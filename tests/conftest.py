"""Fixtures shared by several test modules."""
import pytest

from morphoshell import Problem


@pytest.fixture(scope="module")
def blister():
    """A flat disc grown in its centre (the packaged family ``central_growth``, the example
    ``blister``): the flat state is stationary by mirror symmetry but buckles; the stable
    state is a dome (a blister)."""
    return Problem("central_growth", {"G": 0.2}, h=0.02, geometry="disc")
