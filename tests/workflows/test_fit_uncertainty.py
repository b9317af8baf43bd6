"""A fit's uncertainty carried into its shell's ablation (workflows/fitted_shapes.py:
fit_uncertainty, ablation_errors' checks).  Audit 25, F2: the ablation of a fitted shell
printed only its numerical error (rotation +- 1.8e-6 rad) where the fit's errors give
+- 0.019 rad, and ablation_errors of a record without standard errors died of a KeyError."""
import json
import math

import numpy as np
import pytest

from morphoshell import Problem, ablate
from morphoshell.workflows import (PROFILE_WIDER, ablation_errors, fit_uncertainty,
                                   fitted_problem)

FITTED = Problem("volvox", {"kappa2": -7.5, "s1": 1.2}, h=0.15, opening=0.3)
SE = {"kappa2": 0.05, "s1": 0.01}
NODES = 40          # (the cut on a coarse mesh: the propagation, not the recoil, is tested)


def _record(**changes) -> dict:
    """A free fit's record as `morphoshell fit --json` writes it, with standard errors."""
    p = FITTED
    rec = {"problem": p.describe(), "variant": "free", "converged": True, "E_fit": 0.004,
           "parameters": {**p.params, "h": p.h, "cut": p.cut, "opening": p.opening},
           "fitted": list(SE), "standard_errors": dict(SE),
           "correlation": [[1.0, -0.4], [-0.4, 1.0]],
           "note": "standard errors are Gauss-Newton lower bounds: the residuals of a traced "
                   "midline are correlated"}
    rec.update(changes)
    return json.loads(json.dumps(rec))


@pytest.fixture(scope="module")
def ablation():
    return ablate(fitted_problem(_record()).with_updates(cut=0.15), nodes=NODES)


def test_the_fits_errors_are_ablation_errors_with_what_they_are(ablation):
    record = _record()
    fit = fit_uncertainty(record, ablation)
    want = ablation_errors(record, ablation)
    assert fit.errors == want and all(v > 0 for v in want.values())
    assert fit.columns() == {f"se_{k}": v for k, v in want.items()}
    assert "carried linearly" in fit.note and "lower bounds" in fit.note
    assert fit.wider == {}          # (no profiles in the record)


def test_profile_intervals_far_wider_than_the_errors_are_named(ablation):
    """kappa2's interval is 1.0 / (2 * 1.96 * 0.05) = 5.1 times its ± 1.96 SE; s1's 1.5, within
    PROFILE_WIDER; an interval open on one side is infinitely wider."""
    wide = {"kappa2": [-8.0, -7.0], "s1": [1.2 - 0.0294, 1.2 + 0.0294]}
    fit = fit_uncertainty(_record(profile_intervals=wide,
                                  profiles={"kappa2": {"confidence": 0.95}}), ablation)
    assert list(fit.wider) == ["kappa2"] and 1.5 < PROFILE_WIDER
    assert fit.wider["kappa2"] == pytest.approx(1.0 / (2 * 1.959964 * 0.05), rel=1e-6)
    open_side = fit_uncertainty(_record(profile_intervals={"s1": [None, 1.3]}), ablation)
    assert open_side.wider == {"s1": math.inf}


@pytest.mark.parametrize("record, why", [
    (_record(standard_errors=None), "the record has no standard_errors: "),
    ({k: v for k, v in _record().items() if k not in ("standard_errors", "correlation")},
     "the record has no standard_errors, correlation: "),
    (_record(standard_errors={"kappa2": None, "s1": None}),
     "the record has no standard error of a fitted parameter"),
    (_record(parameters={**_record()["parameters"], "kappa2": -7.0}),
     "the ablated shell is not the fitted one (kappa2 = -7.5, fitted -7)"),
])
def test_a_record_that_cannot_give_errors_says_why(ablation, record, why):
    with pytest.raises(ValueError, match=why.replace("(", r"\(").replace(")", r"\)")):
        ablation_errors(record, ablation)
    fit = fit_uncertainty(record, ablation)
    assert fit.errors == {} and fit.columns() == {} and fit.wider == {}
    assert fit.note.startswith("no errors of the fit carried into the observables: " + why)


def test_not_the_direct_method_has_no_errors_of_the_fit():
    problem = fitted_problem(_record()).with_updates(cut=0.15)
    bvp = ablate(problem, nodes=NODES, method="bvp")
    fit = fit_uncertainty(_record(), bvp)
    assert fit.errors == {} and "direct method" in fit.note
    assert np.isfinite(bvp.rotation)


def _on_average(sigma2: float = 4e-5, **changes):
    """The record fitted to 100 points of an average of 5 traces whose σ² is ``sigma2``,
    and that average (hypothesis_cases' half circle and spread)."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "fitting"))
    from hypothesis_cases import points, spread_for

    from morphoshell.io import Midline

    p = points()
    record = _record(data_midline={"r": p[:, 0].tolist(), "z": p[:, 1].tolist()}, **changes)
    return record, Midline(p[:, 0], p[:, 1], spread_for(sigma2), 5)


def test_on_an_average_the_errors_are_also_given_at_the_traces_sigma2(ablation):
    """Audit 28 F2: ± (fit) takes σ² from the residual, E_fit²/(2N − k) = 0.004²/198, and
    covered the true recoil 0.45–0.81 of the time on 5-trace averages.  With the average
    the errors are also given at σ² from its traces (4e-5: ×495 here), i.e. times √495,
    with t₀.₉₇₅(4) = 2.776; the fit's own errors stay as they were."""
    record, average = _on_average()
    fit = fit_uncertainty(record, ablation, average)
    plain = ablation_errors(record, ablation)
    assert fit.errors == plain
    tr = fit.traces
    residual = 0.004 ** 2 / (200 - 2)
    # (σ² from the spread: the mean of equal squares, exact but for round-off)
    assert tr.sigma2_traces == pytest.approx(4e-5, rel=1e-12)
    assert tr.sigma2_residual == pytest.approx(residual, rel=1e-12)
    assert tr.dof == 4 and tr.t95 == pytest.approx(2.7764, abs=1e-4)
    assert tr.errors == pytest.approx({k: v * np.sqrt(4e-5 / residual)
                                       for k, v in plain.items()}, rel=1e-12)
    assert fit.columns()["t95_traces"] == tr.t95
    assert fit.columns()["se_traces_rotation"] == tr.errors["rotation"]
    assert "t(0.975, 4) = 2.776" in tr.text() and "spread of 5 traces" in tr.text()


@pytest.mark.parametrize("how", ["no data", "re-tracings", "other points", "one trace"])
def test_without_the_averages_own_traces_no_traces_errors(ablation, how):
    """Only the traces of the fit's own points, and only for Gauss–Newton errors (a single
    trace's re-tracings' errors are not the residual's σ²)."""
    from morphoshell.io import Midline

    record, average = _on_average(
        **({"standard_errors_source": "re-tracings"} if how == "re-tracings" else {}))
    if how == "other points":
        average = Midline(average.r + 1e-6, average.z, average.spread, 5)
    if how == "one trace":
        average = Midline(average.r, average.z, None, 1)
    fit = fit_uncertainty(record, ablation, None if how == "no data" else average)
    assert fit.errors and fit.traces is None
    assert "t95_traces" not in fit.columns()
