"""The golden set: every public route's numbers equal, to the bit, to their recording.

``scripts/golden.py`` runs the command line on the packaged examples, an ablation, the
estimates, a fit by each method, a short campaign and a sweep.  A change that should not
touch arithmetic (a move, a split, a renamed helper) must leave all of it unchanged; a
change meant to alter results re-records the set (``python scripts/golden.py record``)
and says why in its commit.  Bits depend on the processor and the numeric libraries as
well, so the comparison runs only on the kind of machine the set was recorded on.
"""
import importlib.util
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
spec = importlib.util.spec_from_file_location("golden", ROOT / "scripts" / "golden.py")
golden = importlib.util.module_from_spec(spec)
spec.loader.exec_module(golden)


def test_golden_set_unchanged_to_the_bit():
    recorded = golden.load(golden.DEFAULT_FILE)
    if recorded["machine"] != golden.machine():
        pytest.skip(f"golden set recorded on {recorded['machine']}, not this machine")
    diffs = golden.compare(recorded["cases"], golden.run())
    assert not diffs, f"{len(diffs)} values changed, first: " + "; ".join(diffs[:5])


def test_compare_sees_a_change_in_the_last_bit():
    a = {"case": {"x": (0.1).hex(), "n": 3}}
    b = {"case": {"x": (0.1 + 2**-56).hex(), "n": 3}}
    assert golden.compare(a, a) == []
    assert golden.compare(a, b) == [f"x: 0.1 -> {0.1 + 2**-56!r}"]
