"""Points equally spaced in arclength: a midline's rows read at other fractions of it.

resample is tested with the alignment (test_midlines.py); the reference shape:
reference_midline.py.
"""
import numpy as np
import pytest

from morphoshell.io import MidlineError
from morphoshell.io.resampling import at_fractions, resample
from reference_midline import truth

#: The not-a-knot spline through 100 rows h ≈ 0.027 R apart errs by O(h⁴) ≈ 5e-7 R (times the
#: shape's derivatives); measured 4e-8 to 8e-8 R at n = 60, 150, 333.  In the chord-length
#: parameter instead of the rows' fraction of arclength it errs by 1.8e-5 R, linear
#: interpolation by 1.6e-4 R.
SPLINE_ERROR = 2e-7


@pytest.mark.parametrize("n", [60, 150, 333])
def test_rows_equally_spaced_are_read_at_their_fractions_of_arclength(n):
    assert np.abs(at_fractions(truth(100), n) - truth(n)).max() < SPLINE_ERROR


def test_at_their_own_number_the_rows_are_returned_as_a_copy():
    rows = truth(100)
    read = at_fractions(rows, 100)
    assert np.array_equal(read, rows) and read is not rows
    read[1] = 0.0
    assert rows[1, 0] != 0.0


def test_a_bad_n_is_named():
    with pytest.raises(MidlineError, match=r"^n = 1 must be an integer >= 2$"):
        at_fractions(truth(10), 1)


@pytest.mark.parametrize("exponent", [-1000, -700, -40, 1, 40])
def test_a_curve_resampled_at_any_scale_is_the_same_to_the_bit(exponent):
    """Audit 26, F3: a trace 1e-200 R long overflowed the spline (1/du², a raw warning) and
    underflowed its tangents' norms: NaN points.  The curve is built of the points scaled by a
    power of two, exact: a midline scaled by 2^e resamples to the same points times 2^e."""
    import warnings

    rows = truth(37)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        scaled = resample(np.ldexp(rows, exponent), 50)
    assert np.array_equal(scaled, np.ldexp(resample(rows, 50), exponent))


def test_a_curve_1e_200_long_is_resampled():
    rows = truth(37)
    # (1e-200 is no power of two: the points differ by a rounding, 1e-16 relative, and so
    # the spline through them)
    assert np.allclose(resample(rows * 1e-200, 50), resample(rows, 50) * 1e-200,
                       rtol=1e-12, atol=0)
