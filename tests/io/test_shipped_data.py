"""The shipped synthetic inversion data are what today's reader makes of their traces.

data/synthetic_inversion holds each embryo's trace (pixels), the midline the reader makes of
it (``synthetic_embryoN_midline.csv``: the campaign's jackknife fits them) and their average.
When the reader changes, these files must be written again by
scripts/make_synthetic_inversion.py, or the campaign's inputs are no longer what its
documentation says they are.  (The files hold what the reader wrote, and
:func:`morphoshell.io.load_midline` reads them back as they are: their ``# n_traces``
comment marks them as midlines.)
"""
import json
from pathlib import Path

import numpy as np
import pytest

from morphoshell.io import Midline, average, load_midline

DATA = Path(__file__).resolve().parents[2] / "data" / "synthetic_inversion"
TRUTH = json.loads((DATA / "synthetic_inversion.json").read_text())
#: The script's pixel size and points per midline (scripts/make_synthetic_inversion.py).
PIXEL_UM, N_FIT = 0.3, 100


@pytest.mark.parametrize("tp", TRUTH["timepoints"][::3], ids=lambda tp: tp["timepoint"])
def test_single_midlines_and_average_are_the_readers(tp):
    singles = []
    for embryo in tp["embryos"]:
        read = load_midline(DATA / embryo["file"], "xy", n=N_FIT, section="whole",
                            pixel_size_um=PIXEL_UM, radius_um=embryo["radius_um"])
        shipped = _points(embryo["file"].replace(".csv", "_midline.csv"))
        # (round-off: the files' midlines and today's differ by < 1e-11 R; the reader's
        # changes of the last week moved midlines by 1e-4 to 1e-3 R)
        assert np.abs(read.points - shipped).max() < 1e-9, embryo["file"]
        singles.append(read)
    assert np.abs(average(singles).points - _points(tp["average"])).max() < 1e-10, tp["average"]


@pytest.mark.parametrize("path", sorted(DATA.glob("t*/*_midline.csv")) +
                         sorted(DATA.glob("t*/*_average.csv")),
                         ids=lambda p: f"{p.parent.name}/{p.name}")
def test_every_shipped_midline_reads_back_as_shipped(path):
    """(audit: read at their own 100 points, the single-trace midlines moved by up to
    2.2e-3 R, the averages by up to 2.5e-6 R: resampled along the spline through their rows.)
    1e-12 R: round-off only."""
    shipped = Midline.from_csv(path)
    read = load_midline(path, n=len(shipped.r))
    assert np.abs(read.points - shipped.points).max() <= 1e-12
    assert read.n_traces == shipped.n_traces
    assert (read.spread is None) == (shipped.spread is None)
    if shipped.spread is not None:
        assert np.array_equal(read.spread, shipped.spread)


def _points(name: str) -> np.ndarray:
    """A shipped midline's (r, z) as written (read as a trace it would be resampled)."""
    rows = [line for line in (DATA / name).read_text().splitlines() if not line.startswith("#")]
    assert rows[0].startswith("r,z"), name
    return np.array([[float(v) for v in row.split(",")[:2]] for row in rows[1:]])
