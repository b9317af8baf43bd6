"""Isolated outlier points of a trace (io.trace_outliers): found, named, kept or left out.

The reference half midline at 200 px per R (reference_midline.py), whole sections of it
1 px apart with ½ px of noise, the case of audit 13 F6 (mis-clicks 0.29 R off 0.5 px noise).
"""
import logging
import re

import numpy as np
import pytest

from morphoshell.io import midlines as ml
from morphoshell.io import traces as tr
from morphoshell.io.trace_outliers import OUTLIER_SIGMAS, find_outliers
from reference_midline import SCALE, TRUTH, half

#: Units of R per pixel of the reference images.
PX = SCALE["pixel_size_um"] / SCALE["radius_um"]


def _trace(noise_px=0.5, seed=0, moved=(), by_px=(40.0, -50.0), n=401, rounded=False):
    """A whole section traced 1.3 px apart (n points a half), points ``moved`` by ``by_px``."""
    from morphoshell.io import to_image

    px = to_image(half(n), radius_px=1 / PX, angle_deg=30.0, offset_px=(500.0, 500.0))
    px = px + np.random.default_rng(seed).normal(0.0, noise_px, px.shape)
    px[list(moved)] += by_px
    if rounded:
        px = np.round(px)
        px = px[np.r_[True, np.any(np.diff(px, axis=0) != 0, axis=1)]]
    return tr.pixel_trace("trace.txt", "xy", px, [f"line {k + 1}" for k in range(len(px))], PX)


def _csv(tmp_path):
    """A midline csv (units of R, 400 points) with a point 0.03 R off."""
    points = half(400)
    points[200] += 0.03
    path = tmp_path / "midline.csv"
    path.write_text("r,z\n" + "".join(f"{r:.17g},{z:.17g}\n" for r, z in points))
    assert len(find_outliers(points).index) == 1        # (if it were tested)
    return path


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("noise_px, rounded", [(0.1, False), (0.5, False), (1.0, False),
                                               (0.3, True), (0.0, False)])
def test_clean_traces_have_no_outliers(seed, noise_px, rounded):
    """No false alarm on clean traces, noisy, pixel-rounded or noise-free: their points lie
    within about 4-5 σ of their neighbours' curves (the module docstring's measurements;
    the threshold is 10 σ), and noise-free ones within a small fraction of a pixel."""
    assert len(find_outliers(_trace(noise_px, seed, rounded=rounded).points)) == 0


@pytest.mark.parametrize("moved", [(60, 200, 330), (0, 800), (399, 400, 401)])
def test_mis_clicks_are_found_with_their_distance(moved):
    """Isolated mis-clicks, the two ends, and three in a row (each hides the others from a
    single fit of its neighbours: they are left out of one another's fits and the test
    repeated) are found, at their distance of 64 px = 0.32 R."""
    found = find_outliers(_trace(moved=moved).points)
    assert found.index.tolist() == list(moved)
    # (less by up to a few steps: a point may lie anywhere between its kept neighbours along
    # the curve, 2 steps apart for three in a row, and their curve is noisy)
    assert found.distance / PX == pytest.approx(np.hypot(40, 50), abs=6.0)
    assert found.sigma / PX == pytest.approx(0.5, rel=0.2)


def test_a_point_moved_along_the_curve_is_an_outlier():
    """A point moved 0.3 R along the curve lies on it but out of order: it lengthens the
    trace by 0.6 R as much as one moved across (one of the audit's three was such)."""
    trace = _trace()
    tangent = trace.points[401] - trace.points[399]
    moved = _trace(moved=[300], by_px=tuple(60 * tangent / np.hypot(*tangent) * [1, -1]))
    assert find_outliers(moved.points).index.tolist() == [300]


def test_alignment_warns_naming_them_and_drops_them_when_asked(caplog):
    """Kept, a warning names each by its line, in R and in px, with the option that leaves
    them out; left out, a note says so, and the midline is the clean trace's again."""
    trace = _trace(moved=(60, 200, 330), by_px=(20.0, -25.0))     # 32 px = 0.16 R
    with caplog.at_level(logging.INFO, logger="morphoshell.io"):
        kept = ml.align(trace, "whole")
    warning, = [r for r in caplog.records if r.levelno == logging.WARNING]
    assert re.match(rf"trace.txt: 3 points far off the curve of their neighbours \(beyond "
                    rf"{OUTLIER_SIGMAS:g} times the trace's noise 0.002\d R; mis-clicks\?\): "
                    rf"line 61 \(0.1\d R = 3\d.?\d* px\), line 201 \(0.1\d R = 3\d.?\d* px\), "
                    rf"line 331 \(0.1\d R = 3\d.?\d* px\); kept: .* drop_outlier_points=True",
                    warning.getMessage()), warning.getMessage()
    caplog.clear()
    with caplog.at_level(logging.INFO, logger="morphoshell.io"):
        dropped = ml.align(trace, "whole", drop_outlier_points=True)
    assert not [r for r in caplog.records if r.levelno == logging.WARNING]
    assert any("left out (drop_outlier_points=True)" in r.getMessage() for r in caplog.records)
    clean = ml.align(_trace(), "whole")

    def error(a):
        return np.sqrt(np.mean(np.sum((ml.resample(a.points, 100) - TRUTH) ** 2, axis=1)))
    # the mis-clicks moved the midline several times as far from the truth as the noise
    # does; left out, it is as close as the clean trace's
    assert error(kept) > 3 * error(clean)
    assert error(dropped) < 1.5 * error(clean)


def test_sparse_points_and_csv_midlines_are_not_tested(caplog, tmp_path):
    """The corners of a segmented line (points 0.1-0.35 R apart) are not noise, nor is a
    midline csv (a model-gauge half: an average, or a fit's input) tested."""
    sparse = _trace(noise_px=0.0, moved=[10], by_px=(10.0, -12.0), n=21)    # 26 px apart
    assert find_outliers(sparse.points).index.tolist() == [10]    # (if it were tested)
    with caplog.at_level(logging.INFO, logger="morphoshell.io"):
        ml.align(sparse, "whole")
        ml.load_midline(_csv(tmp_path), section="half")
    # (the moved vertex, 0.08 R, does make the halves differ by 0.011 R, which the asymmetry
    # warning rightly names; no point is named an outlier)
    warnings = [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING]
    assert len(warnings) == 1 and "halves of this whole section differ by 0.011 R" in warnings[0]
