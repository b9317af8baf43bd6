"""Fixtures shared by several test modules."""
import pytest

from morphoshell import Problem


@pytest.fixture(scope="module")
def blister():
    """A flat disc grown in its centre (the packaged family ``central_growth``, the example
    ``blister``): the flat state is stationary by mirror symmetry but buckles; the stable
    state is a dome (a blister)."""
    return Problem("central_growth", {"G": 0.2}, h=0.02, geometry="disc")


@pytest.fixture
def recorded_bar():
    """(seen, counter): a stand-in for ``morphoshell._runtime.console.counter`` that records
    each bar's (total, unit) and every update's count in ``seen``."""
    from contextlib import contextmanager

    seen = []

    class Bar:
        def update(self, n=1):
            seen.append(n)

    @contextmanager
    def counter(total=None, desc="", unit="it", enabled=None):
        seen.append((total, unit))
        yield Bar()

    return seen, counter
