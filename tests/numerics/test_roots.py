"""numerics.roots.brentq: scipy.optimize.brentq's root to the bit, without its import."""
import math
import subprocess
import sys

import numpy as np
import pytest
from scipy import optimize

from morphoshell.numerics.roots import brentq

#: Functions with a root in [a, b]: smooth, steep, flat (a multiple root), one-sided,
#: discontinuous, and values that underflow when multiplied (1e-200 f).
CASES = [
    (lambda x: x ** 3 - 2 * x - 5, 2.0, 3.0),
    (lambda x: math.cos(x) - x, 0.0, 1.0),
    (lambda x: math.exp(x) - 1e6, 0.0, 20.0),
    (lambda x: (x - 0.3) ** 3, 0.0, 1.0),
    (lambda x: (x - 1 / 3) ** 5, -2.0, 1.0),
    (lambda x: math.atan(1e4 * (x - 0.123)), -1.0, 1.0),
    (lambda x: 1.0 if x > 0.7 else -1.0, 0.0, 1.0),
    (lambda x: 1e-200 * (x - 0.3), 0.0, 1.0),
    (lambda x: math.tanh(x - 2.5) + 0.01 * x, 5.0, -3.0),
    (lambda x: x * math.exp(-x) - 0.1, 0.0, 1.5),
]


@pytest.mark.parametrize("f, a, b", CASES)
@pytest.mark.parametrize("xtol, rtol", [(2e-12, 4 * np.finfo(float).eps), (1e-6, 1e-10),
                                        (1e-300, 4 * np.finfo(float).eps)])
def test_the_root_is_scipys_to_the_bit(f, a, b, xtol, rtol):
    # exact equality: the same iteration in the same floating-point operations (a fold's
    # location, a sphere's radius: the golden values stay equal)
    calls, mine = [], []
    assert brentq(lambda x: mine.append(x) or f(x), a, b, xtol, rtol, maxiter=500) == \
        optimize.brentq(lambda x: calls.append(x) or f(x), a, b, xtol=xtol, rtol=rtol,
                        maxiter=500)
    assert mine == calls     # the same trial points, one by one


def test_errors_are_scipys():
    with pytest.raises(ValueError, match="different signs"):
        brentq(lambda x: x * x + 1, -1.0, 1.0)
    with pytest.raises(ValueError, match="NaN"):
        brentq(lambda x: math.nan if x > 0.5 else x - 0.75, 0.0, 1.0)
    with pytest.raises(RuntimeError, match="failed to converge after 3 iterations"):
        brentq(lambda x: (x - 1 / 3) ** 3, 0.0, 1.0, maxiter=3)
    with pytest.raises(ValueError, match="rtol too small"):
        brentq(lambda x: x - 0.5, 0.0, 1.0, rtol=1e-17)
    assert brentq(lambda x: x, 0.0, 1.0) == 0.0      # a root at an end


def test_it_does_not_import_scipy_optimize():
    # its reason to be (scipy.optimize's import: 0.3 s of a solve that meets a fold)
    code = ("import sys; from morphoshell.numerics.roots import brentq; "
            "brentq(lambda x: x - 0.5, 0.0, 1.0); print('scipy.optimize' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True)
    assert out.stdout.strip().splitlines()[-1] == "False"
