"""A profile's crossing made sure (fitting.profile_retry): a refit that decides it without
having converged is fitted again from other starts, and the walk goes on where that lands
below the threshold; a crossing within a side's first two steps is refined.

The retries' fits and the walk's refits are faked where the test is about the bookkeeping
(which start is kept, when the retries stop, where the walk goes): a real stalled refit
takes a noisy 13-parameter fit (the audit's κ₁, 15 s at 100 nodes).
"""
import types

import numpy as np
import pytest

from morphoshell.fitting import fit, profile, synthetic_midline, volvox_spec
from morphoshell.fitting import profile_retry
from morphoshell.fitting.profile_retry import (ABOVE_FARTHER, BEFORE_CROSSING, CROSSING,
                                               NEIGHBOUR_REFITS,
                                               crossing, needs_retry,
                                               non_monotone, not_monotone_note,
                                               refine_crossing, retried, settle_side)
from morphoshell.solvers.results import SolverError

from fitting_cases import NODES, TRUE, three_parameter_spec


def _fake_fit(E2_by_label, calls):
    """A stand-in for bilevel.fit: E_fit² and convergence by the start's κ₂ (the multi-start
    labels differ in it), the held values as the parameters."""
    def fake(spec, data, method, *, nodes, tol):
        label = spec.base.params["kappa2"]
        calls.append(label)
        E2, ok = E2_by_label[label]
        if E2 is None:
            raise SolverError("no branch", "Continuation_Failed")
        return types.SimpleNamespace(E_fit=np.sqrt(E2), converged=ok,
                                     parameters=dict(spec.base.params), equilibrium="eq")
    return fake


def test_a_stalled_refit_is_fitted_again_from_other_starts_and_the_lowest_kept(monkeypatch):
    """The starts of a fit from several starts (family defaults, κ₂ = −3, −6, late stage),
    with the held value: in turn until the lowest converged or lies below the threshold; the
    lowest is kept and recorded (which start won), a start that fails is a row too."""
    spec = volvox_spec("free")
    j = spec.fitted.index("kappa1")
    theta = spec.theta0
    stalled = (spec, theta, "state", 10.0, False)             # threshold 5 below
    defaults = spec.base.params["kappa2"]
    E2, calls = {defaults: (8.0, False), -3.0: (None, False), -6.0: (4.0, False)}, []
    monkeypatch.setattr(profile_retry, "fit", _fake_fit(E2, calls))
    out, retry = retried(spec, "kappa1", 1.2, stalled, 5.0, "data", 100, 1e-8)
    # (κ₂ = −6 lands below the threshold: the late-stage start, also κ₂ = −6, not tried)
    assert calls == [defaults, -3.0, -6.0]
    assert out[3] == pytest.approx(4.0) and not out[4] and out[2] == "eq"
    assert out[1][j] == 1.2 and out[0].base.params["kappa1"] == 1.2
    assert retry.winner == "multi-start kappa2 = -6" and retry.S_before == 10.0
    assert [row["from"] for row in retry.starts] == ["family defaults",
                                                     "multi-start kappa2 = -3",
                                                     "multi-start kappa2 = -6"]
    assert "failed" in retry.starts[1] and retry.to_dict()["kept"] == retry.winner
    assert "lowest 2 R, from the multi-start kappa2 = -6 (not converged)" in \
        retry.note("kappa1")
    # a converged start ends the retries, lower or not than the ones after it
    calls.clear()
    E2.update({defaults: (7.0, True)})
    out, retry = retried(spec, "kappa1", 1.2, stalled, 5.0, "data", 100, 1e-8)
    assert calls == [defaults] and out[3] == pytest.approx(7.0) and out[4]
    # none lower than the stalled refit: it stands, every start tried
    calls.clear()
    E2.update({defaults: (12.0, True), -3.0: (11.0, False), -6.0: (13.0, False)})
    out, retry = retried(spec, "kappa1", 1.2, stalled, 5.0, "data", 100, 1e-8)
    assert out is stalled and len(calls) == 4 and retry.winner == ""
    assert retry.note("kappa1").endswith("none lay lower")


def test_only_the_unconverged_refit_that_decides_the_crossing_is_retried():
    out = ("spec", "theta", "state", 6.0, False)
    assert needs_retry(out, 5.0, [1.0, 3.0])
    assert not needs_retry(out, 5.0, [1.0, 5.5])       # (after the first beyond: cannot move it)
    assert not needs_retry(out[:4] + (True,), 5.0, [1.0])
    assert not needs_retry(out[:3] + (4.0, False), 5.0, [1.0])
    assert not needs_retry(None, 5.0, [])


def _quartic(width, S_min=1.0, height=1.0):
    """A profile S = S_min + height ((θ − 0)/width)⁴, crossing S_min + height at ±width: not
    quadratic, so that √(S − S_min) interpolated across a coarse step misses its crossing."""
    return lambda v: S_min + height * (v / width) ** 4


def test_a_crossing_within_the_first_steps_is_refined():
    """A side that crosses within its first two steps of a grid that planned ten: one or two
    refits at the interpolated crossing, from the end of the step before it.  The audit's κ₁
    crossed within its first step of 0.87 (the step was set by a Gauss-Newton error ten
    times the profile's width)."""
    S = _quartic(0.15)
    calls = []

    def refit(end, value):
        calls.append((end, value))
        return (f"end {value}", None, None, S(value), True)

    side = ([0.1, 0.2], [S(0.1), S(0.2)], [True, True], ["end 0.1", "end 0.2"])
    threshold = 2.0                    # (S_min 1 + height 1: crossing at 0.15)
    coarse = crossing(side[0], side[1], (0.0, 1.0), 1.0, threshold, 1.0)
    assert abs(coarse - 0.15) > 5e-3   # (the interpolation across the step misses it)
    made = refine_crossing(side, (0.0, 1.0, "optimum"), threshold, refit)
    assert made == 2 and len(side[0]) == 4 and np.all(np.diff(side[0]) > 0)
    assert calls[0][0] == "end 0.1"    # (from the step below the crossing)
    fine = crossing(side[0], side[1], (0.0, 1.0), 1.0, threshold, 1.0)
    # (two false-position steps of a quartic: within 1e-3 of the step's 0.1)
    assert fine == pytest.approx(0.15, abs=1e-3)
    # a crossing at the third step is resolved already
    values = [0.04, 0.08, 0.16]
    side = (list(values), [S(v) for v in values], [True] * len(values), list(values))
    assert refine_crossing(side, (0.0, 1.0, "optimum"), threshold, refit) == 0


def test_a_refinement_that_stalls_above_the_step_beyond_is_left_out():
    """A refit between the last step below and the first above that did not converge and
    lies above the first above is above the profile (it rises to its crossing): left out
    (the audit's κ₁ at 1.62 would have moved the end from 1.620 to 1.599)."""
    side = ([0.1, 0.2], [1.2, 3.0], [True, True], ["end 0.1", "end 0.2"])
    made = refine_crossing(side, (0.0, 1.0, "optimum"), 2.0,
                           lambda end, value: ("e", None, None, 3.5, False))
    assert made == 1 and side[0] == [0.1, 0.2]
    made = refine_crossing(side, (0.0, 1.0, "optimum"), 2.0,
                           lambda end, value: ("e", None, None, 2.5, False))
    assert made == 2 and len(side[0]) == 4        # (below the step beyond: kept)


@pytest.fixture(scope="module")
def three():
    spec = three_parameter_spec()
    data = synthetic_midline(TRUE, spec.base, nodes=NODES, noise=1e-3, seed=3)
    return spec, data, fit(spec, data, "gradient", nodes=NODES)


def test_a_retry_below_the_threshold_lets_the_profile_go_on_outward(three, monkeypatch):
    """The refit at the third step above stalls far above the threshold (the audit's κ₁ at
    1.64: 10× the profile's height there); the retry from the family defaults lands on the
    profile, below the threshold, so the walk goes on and the interval ends where the
    profile crosses, two steps further, not within the stalled step; the profile records
    the retry (JSON, note).  The walk's refits are faked: S = S_min + h ((θ − θ̂)/0.45)²
    with the threshold's height h (σ² given), a quadratic whose crossing the √ interpolation
    finds exactly."""
    import morphoshell.fitting.profiles as profiles

    spec, data, result = three
    sigma2, step = 1e-8, 0.01
    height = sigma2 * 3.841458820694124
    j = spec.fitted.index("f1")

    def true_S(opt, value):
        return opt.S + height * ((value - opt.theta[j]) / (4.5 * step)) ** 2

    def refit_checked(opt, name, walked, value, method, tol, jump):
        theta = np.array(walked[1], dtype=float)
        theta[j] = value
        stalled = np.isclose(value - opt.theta[j], 3 * step)
        S = opt.S + 10 * height if stalled else true_S(opt, value)
        return (walked[0], theta, walked[2], S, not stalled), ""

    def fake_fit(spec_, data_, method, *, nodes, tol):
        value = spec_.base.params["f1"]
        return types.SimpleNamespace(E_fit=np.sqrt(true_S(opt_of[0], value)),
                                     converged=True, parameters=dict(spec_.base.params),
                                     equilibrium=opt_of[0].eq)

    opt_of = []
    real_optimum = profiles._optimum
    monkeypatch.setattr(profiles, "_optimum",
                        lambda *a: opt_of.append(real_optimum(*a)) or opt_of[0])
    monkeypatch.setattr(profiles, "_refit_checked", refit_checked)
    monkeypatch.setattr(profile_retry, "fit", fake_fit)
    p = profile(spec, data, "f1", result=result, points=20, span=10 * step, noise=sigma2)
    lo, hi = p.interval
    assert hi - p.fitted_value == pytest.approx(4.5 * step, rel=1e-6)
    assert p.fitted_value - lo == pytest.approx(4.5 * step, rel=1e-6)
    above = p.values > p.fitted_value
    assert p.values[above][2] == pytest.approx(p.fitted_value + 3 * step)
    assert p.converged.all() and p.verdict() == ""
    [r] = [r for r in p.retries if not r.reason]        # (and each crossing's, from beyond)
    assert all(r.reason == CROSSING and not r.winner for r in p.retries if r.reason)
    assert r.winner == "family defaults" and r.S_before > r.S
    [d] = [d for d in p.to_dict()["retries"] if d["reason"] is None]
    assert d["kept"] == "family defaults" and d["converged"]
    assert "fitted again from 1 other start: lowest" in p.note
    assert "from the family defaults (converged)" in p.note


def test_a_crossing_about_a_refit_below_the_fit_is_a_number():
    """A refit lower than the fit by more than the threshold's height (σ² from the residual
    of a replicate in scripts/check_profile_coverage.py): the fitted value lies outside its
    threshold, and the crossing interpolated 0/0 (NaN and a RuntimeWarning).  Now the
    crossing is found outward from the steps below the threshold, in √(S − S_min)."""
    import warnings

    start = (0.0, 4.0)                      # the fit: S = 4, the profile's least S = 1
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        # above: the fit's side rises from S = 1 at 1.0 to 9 at 3.0; threshold 5 (r = 2)
        assert crossing([1.0, 2.0, 3.0], [1.0, 2.0, 9.0], start, 1.0, 5.0, 1.0) == \
            pytest.approx(2.0 + (2.0 - 1.0) / (np.sqrt(8.0) - 1.0))
        # below: never below the threshold 2: the side ends at the fitted value
        assert crossing([-1.0, -2.0], [6.0, 8.0], start, -1.0, 2.0, 1.0) == 0.0
        # the usual case is unchanged: the start is the minimum, r = √(S − 4)
        assert crossing([1.0, 2.0], [5.0, 13.0], start, 1.0, 8.0, 4.0) == \
            pytest.approx(1.0 + (2.0 - 1.0) / (3.0 - 1.0))




def _fake_f1_refits(monkeypatch, spec, S_of) -> None:
    """The profile walk's refits of f1 faked: at f1 = value the refit's θ is the walked one
    with f1 set, its objective ``S_of(opt, Δ)``, Δ = value − the fit's f1."""
    import morphoshell.fitting.profiles as profiles

    j = spec.fitted.index("f1")

    def refit_checked(opt, name, walked, value, method, tol, jump):
        theta = np.array(walked[1], dtype=float)
        theta[j] = value
        return (walked[0], theta, walked[2], S_of(opt, value - opt.theta[j]), True), ""

    monkeypatch.setattr(profiles, "_refit_checked", refit_checked)


def test_a_profile_narrower_than_its_grid_refines_its_crossings(three, monkeypatch):
    """A profile four times narrower than the Gauss–Newton step planned for (the walk's
    refits faked: S − S_min quartic in θ − θ̂, crossing at 1.5 steps on either side): each
    side gets two refits at its interpolated crossing, and the interval ends within a
    hundredth of a step of the profile's crossing, where across the step it missed by
    eight hundredths."""
    spec, data, result = three
    sigma2, step = 1e-8, 0.01
    height = sigma2 * 3.841458820694124
    _fake_f1_refits(monkeypatch, spec, lambda opt, d: opt.S + height * (d / (1.5 * step)) ** 4)
    p = profile(spec, data, "f1", result=result, points=20, span=10 * step, noise=sigma2)
    lo, hi = p.interval
    for half in (hi - p.fitted_value, p.fitted_value - lo):
        assert half == pytest.approx(1.5 * step, abs=0.01 * step)
    # (the walk's two steps per side, one to the crossing and one beyond, and two refinements)
    assert len(p.values) == 1 + 2 * (2 + 2)
    # (the refined crossings tried from the step beyond them too: no lower, nothing noted)
    assert all(r.reason == CROSSING and not r.winner for r in p.retries) and not p.note


# The audit's f₁ lower side (the synthetic t05, free, 200 nodes), outward from the optimum
# (S_min 2.5976e-5, threshold 2.9196e-5; units of 1e-5 R²): the refit at the second step
# converged in a worse minimum, above the one farther out.
AUDIT_S = [2.8823, 2.9654, 2.9418, 2.9734, 3.0118]
AUDIT_S_MIN, AUDIT_THRESHOLD = 2.5976, 2.9196


def _neighbour_refit(lower, calls):
    """A stand-in for the walk's refit: from the end named ``"end i"`` at value ``v`` it gives
    ``lower[(i, v)]`` where given, else the side's own objective at v (the same minimum)."""
    def refit(end, value):
        calls.append((end, value))
        i = AUDIT_VALUES.index(value)
        S = lower.get((end, value), AUDIT_S[i])
        return (f"new end {value}", None, None, S, True), ""
    return refit


AUDIT_VALUES = [0.7812, 0.7785, 0.7758, 0.7731, 0.7703]


def _audit_side():
    n = len(AUDIT_S)
    return (list(AUDIT_VALUES), list(AUDIT_S), [True] * n, [f"end {i}" for i in range(n)])


@pytest.fixture
def no_refinement(monkeypatch):
    """The refinement of a crossing within a side's first two steps left out (tested above,
    on any grid since audit 27's t05): the tests using this are about the refits from the
    neighbours' ends, and their fakes know the side's own values only."""
    monkeypatch.setattr(profile_retry, "REFINEMENTS", 0)


def test_a_refit_above_one_farther_out_is_fitted_again_from_its_neighbours():
    """The audit's bump at 0.7785 (2.9654, above 2.9418 at 0.7758 and above the threshold:
    the interval ended at 0.77997): fitted again from the end of the refit farther out it
    lands at 2.9134, below the threshold; the crossing, now the refit at 0.7758, lies below
    the chord of its neighbours in √(S − S_min) and is not tried again.  The lower end moves
    out beyond 0.7785."""
    side, calls = _audit_side(), []
    start = (0.7976, AUDIT_S_MIN, "optimum")
    before = crossing(side[0], side[1], start[:2], -1.0, AUDIT_THRESHOLD, AUDIT_S_MIN)
    assert before > 0.7785
    refit = _neighbour_refit({("end 2", 0.7785): 2.9134}, calls)
    retries = settle_side(side, start, AUDIT_THRESHOLD, refit, "f1")
    # (the farther neighbour first; then monotone, the new crossing below its chord)
    assert calls == [("end 2", 0.7785)]
    assert side[1][1] == 2.9134 and side[3][1] == ("new end 0.7785", None, None)
    assert side[3][2] == "end 2" and not non_monotone(side[1], 0.01 * 0.322)
    after = crossing(side[0], side[1], start[:2], -1.0, AUDIT_THRESHOLD, AUDIT_S_MIN)
    assert after < 0.7785
    [bump] = retries
    assert (bump.value, bump.reason, bump.winner) == (0.7785, ABOVE_FARTHER, "refit at f1 = 0.7758")
    assert bump.S_before == 2.9654 and bump.S == 2.9134 and bump.converged
    assert "0.7785 (E_fit 1.72203 R, above a refit farther out) fitted again from 1 other " \
        "start: lowest 1.70687 R, from the refit at f1 = 0.7758" in bump.note("f1")
    assert bump.to_dict()["kept"] == "refit at f1 = 0.7758"


def test_a_crossing_above_its_neighbours_chord_is_tried_from_beyond(no_refinement):
    """A monotone side whose crossing refit lies above the chord of its neighbours in
    √(S − S_min) (the profile bends the wrong way there: a worse local minimum, which a
    monotone side leaves unseen) is tried from its outer neighbour's end; one on or below
    the chord is not (a refit each side of every profile cost 17-24 % of the profiles'
    time)."""
    from morphoshell.fitting.profile_retry import _above_chord

    start = (0.0, 1.0, "optimum")             # θ̂ = 0, S_min = 1: √(S − 1) linear is S = 1 + θ²
    straight = ([0.1, 0.2, 0.3], [1.01, 1.04, 1.09], [True] * 3, ["e0", "e1", "e2"])
    assert not _above_chord(straight, start, 1, 1e-4) and not _above_chord(straight, start, 0, 1e-4)
    bent = ([0.1, 0.2, 0.3], [1.01, 1.05, 1.09], [True] * 3, ["e0", "e1", "e2"])
    assert _above_chord(bent, start, 1, 1e-4) and not _above_chord(bent, start, 2, 1e-4)
    for side, tried in ((straight, []), (bent, [("e2", 0.2)])):
        calls = []

        def refit(end, value, side=side):       # (the same minimum from every start)
            calls.append((end, value))
            return (end, None, None, side[1][side[0].index(value)], True), ""
        settle_side(side, start, 1.03, refit, "x")
        assert calls == tried


# Audit 27 F10: the κ₁ profile of the synthetic t02 average (free, 60 nodes, σ² from the
# traces) on 6 points, its lower side outward (units of 1e-5 R²): the first step converged in
# a worse local minimum (0.656 threshold heights; the 20-point profile lies at 0.27 there), the
# side is monotone and the crossing's refit is the walk's last, so no rule looked at it.
F10_VALUES = [-0.0219203, -0.2926639]
F10_S = [2.4496528, 3.2748352]
F10_S_MIN, F10_THRESHOLD = 2.1043032, 2.6305135
F10_LOWER = 2.2427         # (the refit at -0.0219 from the crossing's end: 0.263 heights)


def test_the_step_before_a_crossing_above_its_neighbours_chord_is_tried_from_beyond(
        no_refinement):
    """The audit's 6-point κ₁ (F10): the last refit below the threshold lies above the chord
    of the optimum and the crossing's refit in √(S − S_min), so it is tried from the crossing
    refit's end, lands lower, and the interval's lower end moves from −0.097 to −0.157 (the
    20-point profile's: −0.172; the rest is the interpolation across a step of 0.27).  A side
    whose step before the crossing lies on its chord costs no refit."""
    side = (list(F10_VALUES), list(F10_S), [True, True], ["end 0", "end 1"])
    start = (0.2488233, F10_S_MIN, "optimum")
    assert crossing(side[0], side[1], start[:2], -1.0, F10_THRESHOLD, F10_S_MIN) == \
        pytest.approx(-0.0974, abs=1e-4)
    calls = []

    def refit(end, value):
        calls.append((end, value))
        S = F10_LOWER if (end, value) == ("end 1", F10_VALUES[0]) else \
            side[1][side[0].index(value)]
        return (f"new end {value}", None, None, S, True), ""
    [retry] = settle_side(side, start, F10_THRESHOLD, refit, "kappa1")
    assert calls == [("end 1", F10_VALUES[0])]
    assert side[1] == [F10_LOWER, F10_S[1]] and side[3][0] == ("new end -0.0219203", None, None)
    assert (retry.reason, retry.winner) == (BEFORE_CROSSING, "refit at kappa1 = -0.292664")
    assert crossing(side[0], side[1], start[:2], -1.0, F10_THRESHOLD, F10_S_MIN) == \
        pytest.approx(-0.1567, abs=1e-4)
    # (√(S − S_min) linear in θ: the step before the crossing on its chord, no refit)
    calls.clear()
    straight = ([0.1, 0.2], [1.01, 1.04], [True, True], ["e0", "e1"])
    assert settle_side(straight, (0.0, 1.0, "optimum"), 1.03, refit, "x") == []
    assert calls == []


def test_the_audit_6_point_kappa1_profile_reaches_the_20_point_ends():
    """Audit 27 F10 on the data (the synthetic t02 average, free, 60 nodes, σ² from the
    traces; about 5 s): on 6 points the refits before both crossings lay in worse local
    minima and the interval read [−0.097, 0.932] with no note, where the 20-point profile
    gives [−0.172, 0.960].  Each is now tried from its crossing refit's end and the interval
    is [−0.157, 0.954]: within 0.015 of the 20-point ends, the interpolation across a step
    of 0.27 (the bounds below sit halfway between the broken and the fixed ends); with the
    lower crossing, at the first step, refined too: [−0.1725, 0.954]."""
    from pathlib import Path

    from morphoshell.io import Midline

    data = Midline.from_csv(Path(__file__).parents[2] / "data" / "synthetic_inversion" / "t02"
                            / "synthetic_average.csv")
    spec = volvox_spec("free")
    p = profile(spec, data, "kappa1", result=fit(spec, data, "gradient", nodes=60), points=6,
                nodes=60)
    lo, hi = p.interval
    assert lo < -0.125 and hi > 0.94
    kept = [r for r in p.retries if r.reason == BEFORE_CROSSING and r.winner]
    assert len(kept) == 2 and "the step before the crossing" in p.note


def test_a_coarse_grids_crossing_in_a_worse_minimum_is_refined():
    """Audit 27 on the synthetic t05 average (free, 60 nodes, σ² from the traces; about 5 s):
    on 6 points κ₁'s upper crossing refit, at 1.2447, is the walk's last and lay in a worse
    local minimum (2.15 threshold heights from the walk, the optimum and the step before;
    1.69 from the family's defaults), no rule looked at it, and the end read 0.974 where 20
    points give 1.069.  The crossing within the side's first two steps is now refined on
    any grid: 1.002 (the bound sits halfway between the broken and the fixed ends)."""
    from pathlib import Path

    from morphoshell.io import Midline

    data = Midline.from_csv(Path(__file__).parents[2] / "data" / "synthetic_inversion" / "t05"
                            / "synthetic_average.csv")
    spec = volvox_spec("free")
    p = profile(spec, data, "kappa1", result=fit(spec, data, "gradient", nodes=60), points=6,
                nodes=60)
    assert p.interval[1] > 0.988
    assert len(p.values) > 7        # (refits at the interpolated crossings, not the grid's)


def test_a_bump_no_neighbour_lowers_is_tried_once_from_each_and_warned_of(caplog,
                                                                         no_refinement):
    """The outer neighbour's end does not lower the bump: nothing is left to try for it (the
    inner neighbour's end is the walk's own start for it, unchanged; the bump is the crossing,
    and was just tried from beyond it); the step before it, 4 % of a threshold height above
    their chord, is tried from the bump's end once (no lower either).  The side stays as it
    was, and the warning (log and note) names the parameter and the values."""
    side, calls = _audit_side(), []
    retries = settle_side(side, (0.7976, AUDIT_S_MIN, "optimum"), AUDIT_THRESHOLD,
                          _neighbour_refit({}, calls), "f1")
    assert calls == [("end 2", 0.7785), ("end 1", 0.7812)]
    assert side[1] == AUDIT_S and [r.winner for r in retries] == ["", ""]
    assert [r.reason for r in retries] == [ABOVE_FARTHER, BEFORE_CROSSING]
    with caplog.at_level("WARNING"):
        note = not_monotone_note("f1", side[:2], AUDIT_THRESHOLD, AUDIT_S_MIN, "below")
    assert "profile of f1 is not monotone below" in note and note in caplog.text
    assert "2.9654 R^2 at f1 = 0.7785 above 2.9418 at 0.7758" in note
    assert not_monotone_note("f1", ([0.1, 0.2], [1.0, 2.0]), 3.0, 0.0, "above") == ""


def test_a_neighbour_lowered_is_a_new_start_and_the_refits_are_bounded():
    """Two refits above the one farther out: the outer one is lowered from its outer
    neighbour's end, but not enough; the inner one is then lowered from that new end, and the
    outer one again from the inner one's new end (a start not tried before), until the side
    is monotone.  A side whose every refit from a neighbour lowers it a little stops after
    NEIGHBOUR_REFITS refits."""
    side, calls = ([0.1, 0.2, 0.3, 0.4], [3.0, 3.2, 2.0, 4.0], [True] * 4,
                   ["e0", "e1", "e2", "e3"]), []
    lower = {("e2", 0.2): 2.5, ("new 0.2", 0.1): 1.5, ("new 0.1", 0.2): 1.8}

    def refit(end, value):
        end = end[0] if isinstance(end, tuple) else end       # (a refit's end: its spec)
        calls.append((end, value))
        return (f"new {value}", None, None, lower[(end, value)], True), ""
    retries = settle_side(side, (0.0, 1.0, "optimum"), 10.0, refit, "x")
    assert calls == [("e2", 0.2), ("new 0.2", 0.1), ("new 0.1", 0.2)]
    assert side[1] == [1.5, 1.8, 2.0, 4.0]
    assert [(r.value, r.S_before, r.S, r.winner) for r in retries] == [
        (0.2, 3.2, 1.8, "refit at x = 0.1"), (0.1, 3.0, 1.5, "refit at x = 0.2")]
    assert [row["from"] for row in retries[0].starts] == ["refit at x = 0.3",
                                                          "refit at x = 0.1"]

    count = []

    def creeping(end, value):
        count.append(value)
        return (f"e{len(count)}", None, None, side[1][side[0].index(value)] - 0.05, True), ""
    side = ([0.1 * i for i in range(1, 9)], [3.0, 2.9, 2.8, 2.7, 2.6, 2.5, 2.4, 5.0],
            [True] * 8, [f"e{i}" for i in range(8)])
    # (threshold 3: the tolerance 0.02, each refit lower by more; the crossing the last step)
    settle_side(side, (0.0, 1.0, "optimum"), 3.0, creeping, "x")
    assert len(count) == NEIGHBOUR_REFITS


def test_the_farther_neighbour_is_tried_first():
    """Of a bump's two neighbours, neither tried yet, the farther one's end comes first (it
    lies lower than the bump; the nearer was, for the walk, the bump's own start)."""
    from morphoshell.fitting.profile_retry import _untried

    side = _audit_side()
    version = {k: 0 for k in range(-1, len(side[0]))}
    assert _untried(side, (0.7976, AUDIT_S_MIN, "optimum"), AUDIT_THRESHOLD, 0.003, set(), version) == (1, 2, ABOVE_FARTHER)
    assert _untried(side, (0.7976, AUDIT_S_MIN, "optimum"), AUDIT_THRESHOLD, 0.003, {(1, 2, 0)}, version) == (1, 0, ABOVE_FARTHER)


def test_differences_below_the_tolerance_are_monotone_and_not_kept(no_refinement):
    """A bump or a lowering by less than MONOTONE_TOL of the threshold's height (round-off of
    one minimum's ends) asks for no refit and changes nothing: a profile whose refits agree
    so stays the same to the bit."""
    height = 1.0
    assert non_monotone([1.0, 1.005, 1.0, 2.0], 0.01 * height) == []
    assert non_monotone([1.0, 1.02, 1.0, 2.0, float("nan")], 0.01 * height) == [1]
    side = ([0.1, 0.2, 0.3], [1.2, 2.5, 2.9], [True] * 3, ["e0", "e1", "e2"])
    retries = settle_side(side, (0.0, 1.0, "optimum"), 2.0,
                          lambda end, value: (("e", None, None, 2.495, False), ""), "x")
    assert side[1] == [1.2, 2.5, 2.9] and side[2] == [True] * 3 and side[3][1] == "e1"
    assert [(r.value, r.reason, r.winner) for r in retries] == [(0.2, CROSSING, "")]


def test_the_audit_f1_profile_is_monotone_and_its_lower_end_reaches_past_the_bump():
    """The audit's case (the synthetic t05 average, free, σ² from its traces; 100 nodes here,
    10 s, where the walk left two bumps on the lower side, at 0.77596 and 0.77866, and the
    interval's lower end at 0.77999): refitted from their outer neighbours' ends both lie on
    the profile, which is monotone on either side, and the lower end lies beyond 0.7785
    (the audit's refit there from the next step's end: 2.913e-5 R², below the threshold)."""
    from pathlib import Path

    from morphoshell.io import Midline

    data = Midline.from_csv(Path(__file__).parents[2] / "data" / "synthetic_inversion" / "t05"
                            / "synthetic_average.csv")
    spec = volvox_spec("free")
    p = profile(spec, data, "f1", result=fit(spec, data, "gradient", nodes=100), points=20,
                nodes=100)
    j = int(np.searchsorted(p.values, p.fitted_value))
    tol = 0.01 * (p.threshold - p.S_min)
    assert non_monotone(list(p.objective[j::-1]), tol) == []       # (each side outward)
    assert non_monotone(list(p.objective[j:]), tol) == []
    assert 0.775 < p.interval[0] < 0.7785
    bumps = [r for r in p.retries if r.reason == ABOVE_FARTHER and r.winner]
    assert len(bumps) == 2 and "above a refit farther out" in p.note


def test_a_bump_no_refit_removes_is_in_the_profiles_note_and_log(three, monkeypatch, caplog):
    """The walk's refits faked (a parabola crossing at 4.5 steps, with a bump at the third
    step above that every start finds, a third of the threshold's height over the step
    beyond): the profile keeps it and says so, naming the parameter and the value."""
    spec, data, result = three
    sigma2, step = 1e-8, 0.01
    height = sigma2 * 3.841458820694124
    _fake_f1_refits(monkeypatch, spec, lambda opt, d: opt.S + height * (
        (d / step / 4.5) ** 2 + (0.6 if np.isclose(d / step, 3) else 0.0)))
    with caplog.at_level("WARNING"):
        p = profile(spec, data, "f1", result=result, points=20, span=10 * step, noise=sigma2)
    at = f"f1 = {p.fitted_value + 3 * step:.6g} above"
    assert "the profile of f1 is not monotone above the fit" in p.note and at in p.note
    assert at in caplog.text and "not monotone below" not in p.note
