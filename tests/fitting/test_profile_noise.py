"""Where a profile's σ² comes from (fitting.profile_noise), and that the Python route the docs
show (io.load_midline, then profiled_fit) takes it where the command line does."""
import logging
from argparse import Namespace
from pathlib import Path

import numpy as np
import pytest

from morphoshell.fitting import noise_variance, profiled_fit, traces_missing, volvox_spec
from morphoshell.fitting import profiles as fp
from morphoshell.io import Midline, load_midline

AVERAGE = Path(__file__).parents[2] / "data" / "synthetic_inversion" / "t05" / "synthetic_average.csv"


def test_what_keeps_the_noise_from_the_traces_is_named():
    pts = np.column_stack([np.linspace(0, 1, 10), np.zeros(10)])
    assert "no spread" in traces_missing(pts)
    assert "n_traces = 1" in traces_missing(Midline(*pts.T, np.full(10, 1e-3), 1))
    assert "zero everywhere" in traces_missing(Midline(*pts.T, np.zeros(10), 5))
    assert traces_missing(Midline(*pts.T, np.full(10, 1e-3), 5)) == ""
    with pytest.raises(ValueError, match="the data hold n_traces = 1"):
        noise_variance(Midline(*pts.T, np.full(10, 1e-3), 1), 1.0, 3, "traces")


def test_the_documented_loader_gives_the_command_lines_noise():
    """User audit: io.load_midline of an average returned no spread, so profiled_fit took σ²
    from the residual (χ²₁) while the command line took it from the traces (F(1, 4)): the
    intervals of one fit were half as wide by the documented route.  Now both read the
    same σ² from the same file: exactly (the file's 100 rows are the 100 fitted points)."""
    loaded, exact = load_midline(AVERAGE, n=100), Midline.from_csv(AVERAGE)
    assert noise_variance(loaded, 1.0, 13) == noise_variance(exact, 1.0, 13)
    assert noise_variance(loaded, 1.0, 13)[1] == "traces"


def test_an_average_of_other_rows_keeps_its_noise(tmp_path):
    """The audit's second case: an average of 150 rows (n_traces 5) fitted at 100 points fell
    back to the residual under auto and was refused under traces.  Now its spread is moved
    onto the fitted points; σ² is its mean square over them, the same as over the file's
    rows within 1 %: the spread varies slowly along the midline, so means over two grids of
    one curve differ by the grids' sampling of it (measured 0.11 %, and 0.11 % on the
    audit's own avg150.csv, averaged from the traces at 150 points)."""
    avg = Midline.from_csv(AVERAGE)
    t, t150 = np.linspace(0, 1, len(avg.r)), np.linspace(0, 1, 150)
    path = tmp_path / "avg150.csv"
    Midline(np.interp(t150, t, avg.r), np.interp(t150, t, avg.z), np.interp(t150, t, avg.spread),
            avg.n_traces, avg.source).to_csv(path)
    loaded = load_midline(path, n=100)
    sigma2, source = noise_variance(loaded, 1.0, 13)
    assert source == "traces" and loaded.n_traces == 5
    assert sigma2 == pytest.approx(noise_variance(Midline.from_csv(path), 1.0, 13)[0], rel=0.01)
    from morphoshell.cli._profiles import profile_data
    args = Namespace(midline=path, profile_noise="traces")
    assert profile_data(args, volvox_spec("free"), loaded) is loaded


def test_auto_says_where_its_noise_came_from(caplog, monkeypatch):
    """profiled_fit(noise="auto") warns when it falls back to the residual (data that lost an
    average's spread did so unseen) and says so at INFO for the traces; before any work (the
    optimum's refit stubbed out here: only the message is tested)."""
    class Stop(Exception):
        pass

    def stop(*args, **kwargs):
        raise Stop
    monkeypatch.setattr(fp, "_optimum", stop)
    avg = Midline.from_csv(AVERAGE)
    spec = volvox_spec("free")
    for data, level, said in ((avg.points, logging.WARNING, "from the fit's residual"),
                              (avg, logging.INFO, "from the spread of 5 traces")):
        caplog.clear()
        with caplog.at_level(logging.INFO, logger="morphoshell"), pytest.raises(Stop):
            profiled_fit(spec, data, ["kappa1"], points=4, nodes=60)
        [record] = [r for r in caplog.records if "sigma^2" in r.getMessage()]
        assert record.levelno == level and said in record.getMessage()
    caplog.clear()
    with caplog.at_level(logging.INFO, logger="morphoshell"), pytest.raises(Stop):
        profiled_fit(spec, avg.points, ["kappa1"], points=4, nodes=60, noise="residual")
    assert not [r for r in caplog.records if "sigma^2" in r.getMessage()]


def test_the_command_line_notes_a_fallback_to_the_residual(capsys):
    from morphoshell.cli._profiles import profile_data
    avg = Midline.from_csv(AVERAGE)
    single = Midline(avg.r, avg.z)
    profile_data(Namespace(midline="x.csv", profile_noise=None), volvox_spec("free"), single)
    assert "note: --profile-noise auto: the midline holds no spread" in capsys.readouterr().out
    profile_data(Namespace(midline="x.csv", profile_noise=None), volvox_spec("free"), avg)
    assert capsys.readouterr().out == ""


def test_a_single_traces_profile_noise_is_scaled_per_parameter():
    # a single trace's ± are its re-tracings' sandwich errors, 1.3-1.8x the Gauss-Newton
    # ones; its profiles took the residual's sigma^2 and stayed that much narrower than the
    # errors printed beside them: the residual's sigma^2 is scaled per parameter
    from morphoshell.fitting.profile_noise import (RETRACED, check_inflation, noise_variance,
                                                   parameter_noise)
    points = np.zeros((50, 2))
    base, source = noise_variance(points, 2.0, 3, "residual")
    sigma2, source, dof = parameter_noise(points, 2.0, 3, "residual", {"f1": 2.25}, "f1")
    assert sigma2 == 2.25 * base and source == RETRACED
    assert parameter_noise(points, 2.0, 3, "residual", {"f1": 2.25}, "s1")[:2] == (base,
                                                                                  "residual")
    assert parameter_noise(points, 2.0, 3, 0.5, {"f1": 2.25}, "f1")[:2] == (0.5, "given")
    with pytest.raises(ValueError, match=r"inflation\['f1'\] = -1 must be a positive number"):
        check_inflation({"f1": -1}, ["f1"])
