"""Checks of traced curves: what names a closed trace, and the warning of traces that differ
far more than their noise (io/trace_checks.py; the other checks are tested through the
readers, test_traces.py and test_midlines.py)."""
import math
import re
from pathlib import Path

import numpy as np
import pytest

from morphoshell.io import MidlineError
from morphoshell.io.trace_checks import SPREAD_RATIO, check_open, spread_warning
from morphoshell.io.trace_noise import bin_noisy
from morphoshell.io.traces import read_trace

DATA = Path(__file__).resolve().parents[2] / "data" / "synthetic_inversion"


def test_the_spread_warning_names_the_ratio_above_its_limit():
    noises = [0.003, 0.002, math.nan, 0.004]            # (nan: a csv or segmented line)
    assert spread_warning(SPREAD_RATIO * 0.003, noises) is None
    said = spread_warning(0.0542, noises, "the 4 traces of a.zip")
    assert said == ("the 4 traces of a.zip differ by more than tracing does: their mean spread "
                    "0.054 R is 18 times their noise (0.003 R, the median of their estimates); "
                    "check each trace's radius_um and pixel_size_um (radii 5 % off by turns "
                    "gave 12 times, one radius for embryos of R = 35-42 µm 19) and that they "
                    "are of one stage")
    # without two estimates (csv midlines, segmented lines) nothing is compared
    assert spread_warning(1.0, [0.003, math.nan, math.nan]) is None
    assert spread_warning(1.0, []) is None


def test_the_shipped_traces_are_not_taken_for_closed_ones():
    """Their halves lie at least 0.40 of their length apart somewhere within 0.4 of it from
    their ends (the limit is 0.2), their ends 14 median steps or more (the limit 2)."""
    for path in sorted(DATA.glob("t*/synthetic_embryo?.csv")):
        header = path.read_text()
        scale = {"pixel_size_um": float(re.search(r"pixel size ([0-9.]+)", header)[1]),
                 "radius_um": float(re.search(r"R = ([0-9.]+) um", header)[1])}
        check_open(str(path), bin_noisy(read_trace(path, **scale).points).points)


def test_a_trace_that_comes_back_along_itself_is_closed():
    """A hairpin of arms 3 R long, 0.2 R apart (0.032 of its length 6.2 R), is closed; 2 R
    apart (0.25 of its 8 R), as the halves of a midline, not (the limit: 0.2)."""
    s = np.linspace(0.0, 3.0, 301)
    for gap, closed in ((0.2, True), (2.0, False)):
        arms = np.vstack([np.column_stack([s, np.zeros_like(s)]),
                          np.column_stack([s[::-1], np.full_like(s, gap)])])
        if closed:
            with pytest.raises(MidlineError, match=rf"a\.txt: the trace is closed \(its first "
                                                   rf"and last points lie {gap:g} R apart"):
                check_open("a.txt", arms)
        else:
            check_open("a.txt", arms)
