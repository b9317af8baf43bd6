"""The hypotheses on κ₁ tested against the free fit (fitting/hypotheses.py), on fits made by
hand: audit 25 F1's numbers (the E_fit ranking named flat, the data tell none apart)."""
import math

import numpy as np
import pytest

from hypothesis_cases import (AUDIT_E_FIT, AUDIT_SIGMA2, audit_fits, fit_of, points, retraced,
                              spread_for)
from morphoshell.fitting.hypotheses import compare_hypotheses
from morphoshell.fitting.profile_noise import RETRACED, parameter_noise, threshold_quantile
from morphoshell.io import Midline


def _average(sigma2: float = AUDIT_SIGMA2) -> Midline:
    p = points()
    return Midline(p[:, 0], p[:, 1], spread_for(sigma2), 5)


def test_the_audits_hypotheses_are_not_told_apart():
    """Audit 25 F1: flat had the lowest E_fit (truth κ₁ = 0.6), but ΔS/σ² = 0.030, 0.21,
    0.33 against F(1, 4)'s 7.71 with σ² from the five traces: all three consistent."""
    test = compare_hypotheses(audit_fits(), _average())
    assert test.nested and test.sigma2_source == "traces" and test.dof == 4
    assert test.sigma2 == pytest.approx(AUDIT_SIGMA2, rel=1e-12)   # (round-off of the mean)
    ratios = {h.variant: h.ratio for h in test.hypotheses}
    # (the audit's independent check, to its printed digits)
    assert ratios["flat"] == pytest.approx(0.0296, abs=5e-5)
    assert ratios["undeformed"] == pytest.approx(0.208, abs=5e-4)
    assert ratios["unstressed"] == pytest.approx(0.334, abs=5e-4)
    for h in test.hypotheses[1:]:
        assert h.threshold == pytest.approx(7.7086, abs=1e-4) and h.restrictions == 1
        # ΔS = E_V² − E_free²: no factor N (E_fit² is already the sum of squares)
        assert h.delta_S == pytest.approx(h.E_fit ** 2 - AUDIT_E_FIT["free"] ** 2, rel=1e-12)
    assert test.of("consistent") == ["flat", "undeformed", "unstressed"]
    assert test.summary().startswith("the data do not tell flat, undeformed, unstressed apart")
    assert "F(1, 4)" in test.noise_line()


def test_a_hypothesis_beyond_the_threshold_is_rejected():
    """At σ² / 30 the ratios are 0.89, 6.2 and 10.0: only unstressed is rejected (7.71); at
    σ² / 100, 2.96, 20.8 and 33.4: only flat remains."""
    test = compare_hypotheses(audit_fits(), _average(AUDIT_SIGMA2 / 30))
    assert [test.verdict(v) for v in ("flat", "undeformed", "unstressed")] == [
        "consistent", "consistent", "rejected"]
    assert test.summary().endswith("; rejected: unstressed")
    test = compare_hypotheses(audit_fits(), _average(AUDIT_SIGMA2 / 100))
    assert test.of("consistent") == ["flat"] and test.of("rejected") == ["undeformed",
                                                                         "unstressed"]
    assert test.summary().startswith("only flat is consistent with the data")


def test_without_traces_the_residual_and_chi2():
    """σ² from the free fit's residual, S_free/(2N − 13), with χ²₁ (as the profiles take
    it); the line says it is a lower bound on traced data."""
    test = compare_hypotheses(audit_fits())
    assert test.sigma2_source == "residual" and math.isinf(test.dof)
    assert test.sigma2 == AUDIT_E_FIT["free"] ** 2 / (200 - 13)
    assert test.hypotheses[1].threshold == pytest.approx(3.8415, abs=1e-4)
    assert "residual" in test.noise_line() and "chi2_1" in test.noise_line()


def test_one_traces_sigma2_is_scaled_as_kappa1s_profile():
    """A free fit of one image trace with its re-tracings' errors (κ₁'s 3× the Gauss–Newton
    one, f₁'s 2×): σ² is the residual's × 9, κ₁'s factor, the σ² of κ₁'s profile
    (parameter_noise), for fits and for their records alike; ΔS/σ² is 9× smaller, so that
    undeformed and unstressed, rejected on the residual's σ², are consistent (the docs'
    embryo 1: flat rejected at 32.8 on the residual)."""
    fits = {**audit_fits(), "free": retraced(audit_fits()["free"], {"kappa1": 9.0, "f1": 4.0})}
    plain = compare_hypotheses(audit_fits())
    for given in (fits, {v: f.to_dict() for v, f in fits.items()}):
        test = compare_hypotheses(given)
        assert test.sigma2_source == RETRACED and test.inflation == ("kappa1", 9.0)
        # (the same product of the same numbers: to round-off)
        assert test.sigma2 == pytest.approx(9.0 * plain.sigma2, rel=1e-12)
        profile = parameter_noise(points(), AUDIT_E_FIT["free"] ** 2, 13, "auto",
                                  {"kappa1": 9.0, "f1": 4.0}, "kappa1")
        assert (test.sigma2, test.sigma2_source, test.dof) == pytest.approx(profile)
        assert [h.ratio for h in test.hypotheses] == pytest.approx(
            [h.ratio / 9.0 for h in plain.hypotheses], rel=1e-12)
    assert plain.of("rejected") == ["undeformed", "unstressed"]
    assert test.of("rejected") == [] and "a rejection may be" not in test.summary()
    assert "times 9, kappa1's (SE of its trace's re-tracings / Gauss-Newton SE)^2" in \
        test.noise_line()
    assert test.to_dict()["sigma2_inflation"] == {"parameter": "kappa1", "factor": 9.0}
    # a rejection on the scaled σ² names what that σ² leaves out
    strong = {**fits, "free": retraced(audit_fits()["free"], {"kappa1": 2.0})}
    summary = compare_hypotheses(strong).summary()
    assert summary.endswith("unstressed; sigma^2 holds the trace's pixel noise only, "
                            "not a hand's slow wiggles (compare fits of an average of traces)")
    assert plain.to_dict()["sigma2_inflation"] is None


def test_re_tracings_do_not_scale_the_traces_sigma2_or_four_restrictions():
    """σ² from an average's traces needs no factor; hypotheses that restrict κ₁, f₁, κ₃ and
    κ₄ (a campaign's later timepoints) have no single factor: σ² stays the residual's (not
    calibrated: the summary's caveat)."""
    free = retraced(audit_fits()["free"], {"kappa1": 9.0})
    test = compare_hypotheses({**audit_fits(), "free": free}, _average())
    assert test.sigma2_source == "traces" and test.inflation is None
    fits = {"free": free, "flat": fit_of("flat", 0.0053, held=("f1", "kappa3", "kappa4"))}
    test = compare_hypotheses(fits)
    assert test.sigma2_source == "residual" and test.inflation is None
    assert test.sigma2 == AUDIT_E_FIT["free"] ** 2 / (200 - 13)
    assert "a rejection may be that noise" in test.summary()
    # (one hypothesis of each kind: no one factor either)
    mixed = {**fits, "undeformed": fit_of("undeformed", 0.0050)}
    assert compare_hypotheses(mixed).inflation is None


def test_held_values_count_as_restrictions():
    """A campaign's later timepoints: flat holds f1, κ3, κ4 too (9 fitted, free 13): d = 4,
    threshold 4·F(4, 4); a threshold of one restriction is the profiles' F(1, 4)."""
    fits = {"free": fit_of("free", 0.0046), "flat": fit_of("flat", 0.0053,
                                                           held=("f1", "kappa3", "kappa4"))}
    flat = compare_hypotheses(fits, _average(6.8e-7)).hypotheses[1]
    assert flat.restrictions == 4 and flat.fitted == 9
    assert flat.threshold == pytest.approx(4 * 6.3882, rel=1e-4)
    assert threshold_quantile(0.95, 4.0) == threshold_quantile(0.95, 4.0, 1)


def test_a_hypothesis_not_nested_in_free_is_not_tested():
    """Free holding κ₄ at a value flat does not have: flat is not free under restrictions."""
    fits = {"free": fit_of("free", 0.0046, held=("kappa4",), kappa4=-1.0),
            "flat": fit_of("flat", 0.0050)}
    assert compare_hypotheses(fits).verdict("flat") == "not nested"


def test_without_a_free_fit_there_is_no_test():
    """Non-nested hypotheses: ΔS/σ² against the best, no threshold, and the line says the
    test needs the free fit."""
    fits = audit_fits()
    del fits["free"]
    test = compare_hypotheses(fits, _average())
    assert not test.nested and test.reference == "flat"
    assert [h.verdict for h in test.hypotheses] == ["best", "", ""]
    assert all(math.isnan(h.threshold) for h in test.hypotheses)
    assert test.hypotheses[1].ratio == pytest.approx(0.179, abs=5e-4)
    assert test.summary().startswith("no test: no free fit")


def test_a_free_fit_above_a_hypothesis_is_named():
    """A hypothesis below free: free did not reach its minimum."""
    test = compare_hypotheses({"free": fit_of("free", 0.005), "flat": fit_of("flat", 0.004)})
    assert test.verdict("flat") == "consistent"
    assert "free fit is not at its minimum" in test.summary()


@pytest.mark.parametrize("change, message", [
    (lambda f: {**f, "flat": fit_of("flat", 0.0035, data=points() + 2e-9)},
     "flat was fitted to other data than free"),
    (lambda f: {**f, "flat": fit_of("flat", 0.0035, data=points(50))},
     r"other data than free \(50 points against 100\)"),
    (lambda f: {**f, "flat": fit_of("flat", 0.0035, h=0.12)},
     "flat is a fit of another shell than free"),
    (lambda f: {"a": f["free"], "b": f["free"]}, "a and b are both fits of the variant free"),
    (lambda f: {"free": f["free"]}, "needs two or more fits"),
])
def test_fits_of_other_data_or_shells_are_refused(change, message):
    """One line naming the fit: a comparison across midlines would read data as evidence."""
    with pytest.raises(ValueError, match=message):
        compare_hypotheses(change(audit_fits()))


def test_fits_on_other_meshes_and_data_not_theirs_are_refused():
    """Records name their mesh (fit JSON: solver.nodes; campaign: nodes)."""
    fits = audit_fits()
    records = {v: fits[v].to_dict() for v in ("free", "flat")}
    records["free"]["solver"] = {"nodes": 200}
    records["flat"]["nodes"] = 100
    with pytest.raises(ValueError, match="flat was fitted on 100 nodes, free on 200"):
        compare_hypotheses(records)
    records["flat"]["nodes"] = 200
    assert compare_hypotheses(records).verdict("flat") == "consistent"
    other = Midline(np.linspace(0, 1, 100), np.zeros(100), spread_for(1e-6), 5)
    with pytest.raises(ValueError, match="the data given are not those the fits were made to"):
        compare_hypotheses(records, other)


def _stopped(fit, stop: str = "Maximum_Evaluations_Exceeded"):
    """``fit`` as a fit that stopped short (its E_fit only bounds its minimum from above)."""
    from dataclasses import replace

    return replace(fit, converged=False, stop=stop)


def test_a_hypothesis_whose_fit_stopped_is_not_rejected():
    """Audit 28 F1: undeformed stopped after 3 evaluations far above its minimum was
    "rejected".  At σ²/100 undeformed and unstressed lie above 7.71: unstressed's fit stopped,
    so its rejection is not established (its ΔS is an upper bound), and the line says why;
    flat's fit stopped below the threshold: consistent stands (its minimum lies lower still);
    as records (a campaign's) alike."""
    fits = audit_fits()
    fits["unstressed"] = _stopped(fits["unstressed"])
    fits["flat"] = _stopped(fits["flat"], "Fit_Stalled")
    for given in (fits, {v: f.to_dict() for v, f in fits.items()}):
        test = compare_hypotheses(given, _average(AUDIT_SIGMA2 / 100))
        assert [test.verdict(v) for v in ("flat", "undeformed", "unstressed")] == [
            "consistent", "rejected", "not established"]
        row = test.hypotheses[3].to_dict()
        assert (row["converged"], row["stop"]) == (False, "Maximum_Evaluations_Exceeded")
        summary = test.summary()
        assert summary.startswith("flat is consistent with the data; rejected: undeformed; "
                                  "not established: unstressed (unstressed's fit did not "
                                  "converge (stop Maximum_Evaluations_Exceeded)")
        assert "flat did not converge (stop Fit_Stalled); the verdicts shown stand" in summary
        assert "not established (fit not converged: Maximum_Evaluations_Exceeded)" in \
            test.table()


def test_a_free_fit_that_stopped_calls_none_consistent():
    """A stopped free fit: every ΔS is a lower bound, so consistent is not established while a
    rejection (of a converged hypothesis, σ² from the traces) stands; with σ² scaled by the
    stopped fit's own re-tracings no verdict stands."""
    fits = {**audit_fits(), "free": _stopped(audit_fits()["free"])}
    test = compare_hypotheses(fits, _average(AUDIT_SIGMA2 / 30))
    assert [test.verdict(v) for v in ("flat", "undeformed", "unstressed")] == [
        "not established", "not established", "rejected"]
    assert test.summary().startswith(
        "no hypothesis is established as consistent with the data; rejected: unstressed; not "
        "established: flat, undeformed (free's fit did not converge")
    fits["free"] = _stopped(retraced(audit_fits()["free"], {"kappa1": 1.0}))
    test = compare_hypotheses(fits)
    assert test.sigma2_source == RETRACED and test.of("rejected") == []
    assert test.of("not established") == ["flat", "undeformed", "unstressed"]
    # converged, the same fits give verdicts (the residual's σ² rejects two)
    fits["free"] = retraced(audit_fits()["free"], {"kappa1": 1.0})
    assert compare_hypotheses(fits).of("rejected") == ["undeformed", "unstressed"]
