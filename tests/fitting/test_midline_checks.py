"""Midlines that cannot be the model's are refused before any work (fitting.midline_checks)."""
import re

import numpy as np
import pytest

from morphoshell.fitting import (check_midline, fit, intrinsic_lengths, multi_start_fit,
                                 profiled_fit, synthetic_midline, volvox_spec)

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
        with pytest.raises(ValueError, match=r"the data midline is [0-9.]+ R long, [0-9.]+× "
                                             r"(longer|shorter) than the undeformed shell "
                                             r"\(2\.84 R\); the model's midlines are about "
                                             r"1\.89-4\.26 R long"):
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


def test_a_midline_scaled_within_the_stretches_bounds_is_refused_naming_the_factor():
    """Twice or half the right scale lies within the stretches' bounds (f 0.5-2) and used to run
    to a meaningless fit (issue 41: E_fit 0.83 R and 4.9 R, stretches on their bounds); the
    message gives the factor, the trace's length over the undeformed shell's."""
    spec = volvox_spec("free", START)
    data = synthetic_midline(TRUE, spec.base, nodes=NODES)
    with pytest.raises(ValueError, match=r"is 5\.\d+ R long, 1\.9× longer than the undeformed "
                                         r"shell \(2\.84 R\).*: is the pixel size right\?"):
        check_midline(spec, 2 * data, scale_hint="is the pixel size right?")
    with pytest.raises(ValueError, match=r"2\.1× shorter than the undeformed shell"):
        check_midline(spec, 0.5 * data)
    check_midline(spec, 1.4 * data)          # (a fit still finds stretched shells)


def test_a_midline_with_its_columns_swapped_is_refused_before_any_work():
    """r and z swapped (a CSV's header still r,z) start at the pole along the axis; it used to
    "converge" to E_fit 3.7 R.  The model's midline, and the shipped synthetic ones in every
    variant, leave the pole across the axis; their swapped copies are refused."""
    from pathlib import Path

    from morphoshell.fitting import VARIANTS
    from morphoshell.io import Midline

    spec = volvox_spec("flat", START)
    data = synthetic_midline(TRUE, spec.base, nodes=NODES)
    with pytest.raises(ValueError, match=r"the data midline leaves the pole at 8\d degrees from "
                                         r"the r axis .*are its columns r and z swapped\?"):
        fit(spec, data[:, ::-1], "gradient", nodes=NODES)
    shipped = sorted((Path(__file__).parents[2] / "data" / "synthetic_inversion").glob("t*/*.csv"))
    midlines = [Midline.from_csv(p) for p in shipped if "average" in p.name or "_midline" in p.name]
    assert len(midlines) == 72
    for variant in VARIANTS:
        for m in midlines:
            check_midline(volvox_spec(variant, START), m)
    for m in midlines[::6]:
        with pytest.raises(ValueError, match="swapped"):
            check_midline(spec, m.points[:, ::-1])


def test_what_is_not_a_spec_a_start_or_points_is_refused_naming_the_argument(tmp_path):
    """A user audit: a Problem for the spec, start=3 and a file's path for the data raised
    "'Problem' object has no attribute 'base'", "'int' object has no attribute 'x'" and
    "could not convert string to float"."""
    spec = volvox_spec("free", START)
    data = synthetic_midline(TRUE, spec.base, nodes=NODES)
    with pytest.raises(TypeError, match=r"^spec = Problem\(family='volvox'.* must be a FitSpec, "
                                        r"e\.g\. volvox_spec\('free', problem\), not Problem$"):
        fit(START, data, nodes=NODES)
    with pytest.raises(TypeError, match=r"^start = 3 must be an Equilibrium"):
        fit(spec, data, nodes=NODES, start=3)
    path = str(tmp_path / "trace.csv")
    with pytest.raises(TypeError, match=rf"^data = '{re.escape(path)}' must be a Midline or "
                                        r"\(N, 2\) points \(r, z\), not a path: read a file "
                                        r"with morphoshell\.io\.load_midline$"):
        fit(spec, path, nodes=NODES)
    with pytest.raises(TypeError, match=r"^data = \[\['a', 'b'\]\] must be a Midline or"):
        fit(spec, [["a", "b"]], nodes=NODES)
    for call in (multi_start_fit, profiled_fit):
        with pytest.raises(TypeError, match=r"^spec = Problem\(.* must be a FitSpec"):
            call(START, data, nodes=NODES)


def test_a_point_that_is_not_finite_is_named():
    """It said "got shape (100, 2)", a shape that was right."""
    spec = volvox_spec("free", START)
    data = synthetic_midline(TRUE, spec.base, nodes=NODES).copy()
    data[3, 0], data[7, 1] = np.nan, np.inf
    with pytest.raises(ValueError, match=rf"^data: point 3 \(r, z\) = \(nan, "
                                         rf"{data[3, 1]:.6g}\) is not finite \(2 points are "
                                         rf"not\)$"):
        fit(spec, data, nodes=NODES)
    with pytest.raises(ValueError, match=r"^data must be N >= 3 points \(r, z\), got shape "
                                         r"\(2, 2\)$"):
        fit(spec, data[:2], nodes=NODES)


def test_a_midline_far_too_short_is_refused_for_its_scale_before_its_shape():
    """A trace read at a tenth of its scale (an audit: radius_um 10 times too large) is 0.26 R
    long and its pixel noise turns it back on itself: the fit named that, not the scale.  Too
    short comes first; too long after the turns (a retraced line is long too: above)."""
    spec = volvox_spec("free", START)
    short = 0.25 * synthetic_midline(TRUE, spec.base, nodes=NODES)
    hairpin = np.vstack([short, short[::-1][1:6] + [0.0, 0.002]])    # (back along itself)
    with pytest.raises(ValueError, match=r"^the data midline is 0\.7\d+ R long, 4× shorter than "
                                         r"the undeformed shell"):
        check_midline(spec, hairpin)
    with pytest.raises(ValueError, match="turns back on itself"):
        check_midline(spec, 4 * hairpin)         # (at the right scale it is the shape)
