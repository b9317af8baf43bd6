"""Midlines that cannot be the model's are refused before any work (fitting.midline_checks)."""
import numpy as np
import pytest

from morphoshell.fitting import (check_midline, fit, intrinsic_lengths, synthetic_midline,
                                 volvox_spec)

from fitting_cases import NODES, START, TRUE


def test_a_midline_of_the_wrong_scale_is_refused_before_any_work():
    """A 0.36 R midline used to "converge" to E_fit 8.9 R: the model's midline, as long as
    its stretches times L - P, cannot follow a midline of a fifth of that length."""
    spec = volvox_spec("free", START)
    shortest, longest = intrinsic_lengths(spec)
    assert (shortest, longest) == pytest.approx((0.5 * START.end, 2.0 * START.end), rel=1e-12)
    data = synthetic_midline(TRUE, spec.base, nodes=NODES)
    check_midline(spec, data)                    # the model's own midline passes
    for scale in (0.2, 5.0):                    # outside LENGTH_SLACK either way
        with pytest.raises(ValueError, match=r"the data midline is [0-9.]+ R long, but the "
                                             r"model's midlines are about 1\.42-5\.68 R"):
            fit(spec, scale * data, "gradient", nodes=NODES)
    # held stretches narrow the range to what they allow
    held = volvox_spec("flat", START, hold={n: 1.0 for n in ("f1", "f2", "f3")})
    assert intrinsic_lengths(held) == pytest.approx((START.end, START.end), rel=1e-12)


def test_a_midline_listed_rim_first_is_refused_before_any_work():
    """The model's midline starts at the pole, the origin of its gauge; listed rim first the
    data used to "converge" to E_fit 9.8 R.  Noise at the pole, or a pole 0.05 R off, passes."""
    spec = volvox_spec("flat", START)
    data = synthetic_midline(TRUE, spec.base, nodes=NODES)
    with pytest.raises(ValueError, match=r"the data midline starts at \(r, z\) = \(0\.3\d+, "
                                         r"1\.\d+\), 1\.\d+ R from the posterior pole"):
        fit(spec, data[::-1], "gradient", nodes=NODES)
    check_midline(spec, data + [0.03, 0.04])
    with pytest.raises(ValueError, match="0.15 R from the posterior pole"):
        check_midline(spec, data + [0.09, 0.12])


def test_a_retraced_midline_is_refused_before_any_work():
    """Out to the rim and back, 0.01 R or 0.05 R to one side (no crossing, a plausible length):
    it used to "converge" to E_fit 4.3 R.  The hairpin turns by ~180 degrees within 0.1 R, the
    model's midlines (and the shipped synthetic data) by less than 45."""
    spec = volvox_spec("flat", START)
    data = synthetic_midline(TRUE, spec.base, nodes=NODES)
    tangent = np.gradient(data, axis=0)
    tangent /= np.hypot(*tangent.T)[:, None]
    for apart in (0.01, 0.05):
        back = (data + apart * np.column_stack([-tangent[:, 1], tangent[:, 0]]))[::-1][:60]
        with pytest.raises(ValueError, match=r"the data midline turns back on itself 2\.[67]\d R "
                                             r"along it \(by 1[78]\d degrees within 0\.1 R\)"):
            fit(spec, np.vstack([data, back]), "gradient", nodes=NODES)
    check_midline(spec, data)
