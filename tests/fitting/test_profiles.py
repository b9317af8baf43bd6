"""Profile-likelihood intervals (fitting.profiles): the profile's minimum is the fit, its
interval that of a nearly linear problem, a parameter the data do not see is flagged;
``morphoshell fit --profile``.

The three-parameter flat fit of fitting_cases.py (κ₂, f₁, s₂) to noisy data on a
coarse mesh: nearly linear at the noise of 10⁻³ R, so the profile intervals should
be the Gauss–Newton ones.
"""
import json
import re

import numpy as np
import pytest

from morphoshell.cli import main
from morphoshell.fitting import (fit, noise_dof, noise_variance, profile, profile_intervals,
                                 profiled_fit, synthetic_midline, threshold_quantile,
                                 volvox_spec)
from morphoshell.io import Midline

from fitting_cases import NODES, THREE, TRUE, three_parameter_spec


@pytest.fixture(scope="module")
def three():
    spec = three_parameter_spec()
    data = synthetic_midline(TRUE, spec.base, nodes=NODES, noise=1e-3, seed=3)
    result = fit(spec, data, "gradient", nodes=NODES)
    found, profiles = profiled_fit(spec, data, THREE, result=result, points=6)
    assert found is result              # (at its minimum: the fit stands)
    return spec, data, result, profiles


def test_the_profile_minimum_is_the_fit(three):
    _, _, result, profiles = three
    S_fit = result.E_fit ** 2
    for name, p in profiles.items():
        assert p.fitted_value == pytest.approx(result.parameters[name], abs=1e-3 * abs(
            result.standard_errors[name]) + 1e-12), name
        assert p.S_min == pytest.approx(S_fit, rel=1e-6), name
        # every refit is a constrained version of the fit: never below it
        assert np.all(p.objective >= S_fit * (1 - 1e-9)), name
        assert p.values[np.argmin(p.objective)] == p.fitted_value, name
        assert np.all(np.diff(p.values) > 0) and p.converged.all(), name


def test_a_determined_parameter_has_the_gauss_newton_interval(three):
    _, _, result, profiles = three
    for name, p in profiles.items():
        lo, hi = p.interval
        assert not p.flat and np.isfinite(lo) and np.isfinite(hi), name
        assert lo < p.fitted_value < hi, name
        assert p.sigma2_source == "residual"        # (plain points: no traces)
        gn = 1.96 * result.standard_errors[name]
        # a nearly linear problem: the same interval within a few per cent
        for half in (p.fitted_value - lo, hi - p.fitted_value):
            assert 0.9 < half / gn < 1.1, (name, half, gn)


def test_a_fit_short_of_its_minimum_is_replaced_by_the_profiles_refit(three):
    """The profiles' refit goes on from the fit's end; where it lies lower the fit had not
    reached its minimum (the synthetic t02 embryo 1, free, 60 nodes: 'converged' at E_fit
    0.01236 R, κ₁ 1.295, while the profile's minimum was 0.01215 R at 1.417 and the JSON held
    both), and the lower refit is the fit the profiles are about: its parameters are the
    profiles' fitted values, its E_fit² their least objective."""
    spec, data, full, _ = three
    short = fit(spec, data, "gradient", nodes=NODES, max_iterations=2)
    assert short.E_fit > 2 * full.E_fit                  # (far from the minimum)
    found, profiles = profiled_fit(spec, data, ["f1"], result=short, points=4)
    assert found is not short and found.converged
    assert found.E_fit == pytest.approx(full.E_fit, rel=1e-4)
    assert "had not reached its minimum (E_fit " in found.message
    p = profiles["f1"]
    assert found.parameters["f1"] == p.fitted_value
    assert p.S_min == pytest.approx(found.E_fit ** 2, rel=1e-9) and not p.below_fit
    assert set(found.standard_errors) == set(THREE)


def test_a_profile_below_the_fit_moves_the_fit_there_and_profiles_again(three, monkeypatch):
    """A refit with one parameter held can lie below the optimum the profiles started from
    (here made so: the optimum's own refit gets one evaluation): all the parameters are fitted
    again from the lowest refit and the profiles computed about that fit.  Without another
    round (MAX_RECENTRINGS = 0) the fit is flagged as not the minimum, and each profile says
    where it went lower."""
    import morphoshell.fitting.profiles as profiles_module

    spec, data, full, _ = three
    short = fit(spec, data, "gradient", nodes=NODES, max_iterations=2)
    real, calls = profiles_module.fit_moving_boxes, []

    def first_weak(run, spec_, inner, tol, max_iterations):
        calls.append(spec_)
        return real(run, spec_, inner, tol, 1 if len(calls) == 1 else max_iterations)

    monkeypatch.setattr(profiles_module, "fit_moving_boxes", first_weak)
    found, profiles = profiled_fit(spec, data, ["f1", "s2"], result=short, points=4)
    assert found.converged and found.E_fit == pytest.approx(full.E_fit, rel=1e-4)
    for name, p in profiles.items():
        assert not p.below_fit and p.note == "", name
        assert p.fitted_value == found.parameters[name], name
    calls.clear()
    monkeypatch.setattr(profiles_module, "MAX_RECENTRINGS", 0)
    found, profiles = profiled_fit(spec, data, ["f1", "s2"], result=short, points=4)
    assert not found.converged and found.stop == "Fit_Not_Minimum"
    assert "it is not the minimum" in found.message
    assert all(p.below_fit and "found a lower objective (E_fit " in p.note
               for p in profiles.values())


def test_profile_refits_count_on_a_progress_bar(three, monkeypatch):
    """A profile of all 13 parameters takes minutes of refits that showed nothing: a bar
    (console.counter, on a terminal only) plans points refits per profile, is labelled with
    the profile under way and counts each refit."""
    import contextlib
    import types

    import morphoshell.fitting.profiles as profiles_module

    spec, data, result, _ = three
    bars = []

    @contextlib.contextmanager
    def counter(total=None, *, desc="", unit="it", enabled=None):
        bar = types.SimpleNamespace(total=total, unit=unit, n=0, labels=[desc],
                                    refresh=lambda: None)
        bar.update = lambda n=1: setattr(bar, "n", bar.n + n)
        bar.set_description = bar.labels.append
        bars.append(bar)
        yield bar

    monkeypatch.setattr(profiles_module, "counter", counter)
    _, profiles = profiled_fit(spec, data, ["f1", "s2"], result=result, points=4)
    [bar] = bars
    assert (bar.total, bar.unit) == (8, "refit")
    assert bar.labels == ["profiles: the fit refitted", "profile of f1", "profile of s2"]
    # (each refit counts: the grid's, and those from a neighbour's end, profile_retry.settle_side)
    assert bar.n == sum(len(p.values) - 1 + sum(len(r.starts) for r in p.retries if r.reason)
                        for p in profiles.values())


def test_rethresholding_scales_the_interval(three):
    _, _, _, profiles = three
    p = profiles["f1"]
    # 1.2x the noise: 1.2x the interval (the walk went on to STOP_MARGIN = 1.5 times the
    # threshold's height: up to 1.22x the interval of a quadratic profile)
    wide = p.rethreshold(p.sigma2 * 1.2 ** 2)
    for a, b in zip(wide.interval, p.interval):
        assert abs(a - p.fitted_value) == pytest.approx(1.2 * abs(b - p.fitted_value), rel=0.1)
    assert p.rethreshold(p.sigma2 * 1e4).flat      # beyond the grid: open


def test_a_breakpoint_between_equal_curvatures_is_not_determined():
    """s₁ steps κ_s from κ₁ to κ₂: with κ₁ = κ₂ it changes nothing, and its profile is flat
    up to its bounds; f₁ beside it stays determined."""
    truth = TRUE.with_updates(kappa2=0.0)
    hold = {n: truth.params[n] for n in truth.family_obj.parameters
            if n not in ("f1", "s1", "kappa1", "sigma")}
    spec = volvox_spec("flat", truth.with_updates(f1=0.9), hold=hold)
    data = synthetic_midline(truth, spec.base, nodes=40, noise=1e-3, seed=4)
    profiles = profile_intervals(spec, data, ["s1", "f1"], points=4, nodes=40)
    s1 = profiles["s1"]
    assert s1.flat and s1.interval == (-np.inf, np.inf)
    # walked to its bounds (σ from the pole; its box's edge towards s₂) and E_fit hardly
    # changed (the mesh's knots follow s₁: the discretisation error changes, 1 % of E_fit²)
    assert s1.values[0] == pytest.approx(spec.bounds["s1"][0])
    assert np.ptp(s1.objective) <= 0.5 * (s1.threshold - s1.S_min)
    assert "not determined by the data within its bounds" in s1.summary()
    assert s1.open_sides() == ("bound", "bound")
    assert not profiles["f1"].flat and np.isfinite(profiles["f1"].interval).all()
    assert s1.to_dict()["interval"] == [None, None]


def test_a_side_open_at_a_failed_refit_is_not_called_undetermined(monkeypatch):
    """A side open because its refit failed (an audit's f1 at the model's |eta| < 1 limit:
    the best-determined parameter of its fit) was flagged flat, "not determined by the
    data"; it says "open where a refit failed", and flat stays for profiles that stay
    below the threshold to a bound or the grid's end."""
    import morphoshell.fitting.profiles as pr

    truth = TRUE.with_updates(kappa2=0.0)
    hold = {n: truth.params[n] for n in truth.family_obj.parameters
            if n not in ("f1", "s1", "kappa1", "sigma")}
    spec = volvox_spec("flat", truth.with_updates(f1=0.9), hold=hold)
    data = synthetic_midline(truth, spec.base, nodes=40, noise=1e-3, seed=4)
    checked = pr._refit_checked

    def failing_below(opt, name, walked, value, *args):
        if value < opt.theta[opt.spec.fitted.index(name)]:
            return None, "abs(eta) = 1.0392 >= 1 at s = 1.47"
        return checked(opt, name, walked, value, *args)

    monkeypatch.setattr(pr, "_refit_checked", failing_below)
    f1 = profile_intervals(spec, data, ["f1"], points=4, nodes=40)["f1"]
    assert f1.interval[0] == -np.inf and np.isfinite(f1.interval[1])
    assert f1.open_sides() == ("failed", "") and not f1.flat
    assert "open where a refit failed" in f1.summary() and "not determined" not in f1.summary()
    assert f1.to_dict()["open_sides"] == ["failed", None]


def test_noise_from_the_traces_or_the_residual():
    pts = np.column_stack([np.linspace(0, 1, 10), np.zeros(10)])
    spread = np.full(10, 2e-3)
    spread[0] = 0.0                   # (the pole: no spread, not counted)
    avg = Midline(pts[:, 0], pts[:, 1], spread, 4, ("a",))
    assert noise_variance(avg, 1.0, 3) == (pytest.approx(1e-6), "traces")
    assert noise_variance(avg, 1.7, 3, "residual") == (pytest.approx(0.1), "residual")
    assert noise_variance(pts, 1.7, 3) == (pytest.approx(0.1), "residual")
    assert noise_variance(pts, 1.7, 3, 2e-6) == (2e-6, "given")
    with pytest.raises(ValueError, match="traces"):
        noise_variance(pts, 1.0, 3, "traces")


def test_sigma2_from_n_traces_counts_n_minus_1_degrees_of_freedom(three):
    """A traced midline's errors are correlated along each trace: σ² from the spread of five
    traces has 4 degrees of freedom, so the threshold's quantile is F(1, 4) = 7.709, not
    χ²₁ = 3.841, and the interval of a nearly linear problem is √(7.709/3.841) = 1.42× as
    wide (the coverage this buys: docs/fitting.md, "Profile intervals")."""
    spec, data, result, _ = three
    avg = Midline(data[:, 0], data[:, 1], np.full(len(data), np.sqrt(5) * 1e-3), 5, ("a",))
    p = profile(spec, avg, "f1", result=result, points=6, noise="traces")
    assert (p.sigma2_source, p.dof) == ("traces", 4.0)
    assert p.sigma2 == pytest.approx(1e-6)
    assert threshold_quantile(0.95, 4) == pytest.approx(7.7086, abs=1e-4)
    assert threshold_quantile(0.95) == pytest.approx(3.8415, abs=1e-4)
    assert p.threshold == pytest.approx(p.S_min + 7.7086e-6, rel=1e-4)
    known = p.rethreshold(p.sigma2, "traces")            # (as if σ² were known: χ²₁)
    for a, b in zip(p.interval, known.interval):
        assert abs(a - p.fitted_value) == pytest.approx(
            np.sqrt(7.7086 / 3.8415) * abs(b - p.fitted_value), rel=0.05)
    assert p.to_dict()["sigma2_dof"] == 4.0 and known.to_dict()["sigma2_dof"] is None
    assert noise_dof(avg, "residual") == np.inf


def test_bad_options_are_refused_before_any_work(three):
    spec, data, result, _ = three
    with pytest.raises(ValueError, match=r"cannot profile \['kappa1'\]: not fitted in the flat"):
        profile(spec, data, "kappa1", result=result)
    with pytest.raises(ValueError, match="method"):
        profile(spec, data, "f1", result=result, method="nelder-mead")
    with pytest.raises(ValueError, match="points"):
        profile(spec, data, "f1", result=result, points=1)


# --------------------------------------------------------------------------
# morphoshell fit --profile
# --------------------------------------------------------------------------

@pytest.fixture(scope="module")
def midline_csv(tmp_path_factory):
    spec = three_parameter_spec()
    points = synthetic_midline(TRUE, spec.base, nodes=NODES, noise=1e-3, seed=2)
    path = tmp_path_factory.mktemp("profile") / "synthetic_midline.csv"
    Midline(points[:, 0], points[:, 1], None, 1, ("synthetic",)).to_csv(path)
    return path


HELD = [f"--set={n}={TRUE.params[n]}" for n in TRUE.family_obj.parameters
        if n not in THREE and n not in ("kappa1", "sigma")]


@pytest.mark.parametrize("method", ["gradient", "kkt"])
def test_fit_command_writes_profile_intervals(midline_csv, tmp_path, capsys, method):
    """Whatever the fit's method, the profiles' refits are gradient fits (a KKT fit's took
    2.8 times as long for the same intervals: cli._profiles.run_profiles)."""
    out, png = tmp_path / "fit.json", tmp_path / "profiles.png"
    assert main(["fit", str(midline_csv), "--variant", "flat", "--nodes", str(NODES), *HELD,
                 "--method", method, "--profile", "f1,s2", "--profile-points", "4",
                 "--json", str(out), "--profile-plot", str(png)]) == 0
    data = json.loads(out.read_text())
    assert set(data["profile_intervals"]) == {"f1", "s2"}
    for name, (lo, hi) in data["profile_intervals"].items():
        assert lo < data["parameters"][name] < hi, name
        assert len(data["profiles"][name]["values"]) == len(data["profiles"][name]["objective"])
        assert data["profiles"][name]["method"] == "gradient"
    assert png.stat().st_size > 10_000
    printed = capsys.readouterr().out
    assert "profile intervals (95 %, gradient refits" in printed and "GN +-" in printed
    # (units: f1 a stretch, s2 a breakpoint)
    assert re.search(r"\n  f1 .*\] \(dimensionless\)  GN \+-", printed), printed
    assert re.search(r"\n  s2 .*\] R  GN \+-", printed), printed


def test_fit_command_reports_the_lower_fit_its_profile_found(midline_csv, tmp_path, capsys):
    """A fit short of its minimum (here: stopped after 2 evaluations) whose profile's refit
    goes lower: the terminal says so and prints the refit, which is the fit (JSON parameters,
    E_fit and standard errors the refit's, what it replaced under replaced_fit) and decides
    the last line and the exit status."""
    out = tmp_path / "fit.json"
    assert main(["fit", str(midline_csv), "--variant", "flat", "--nodes", str(NODES), *HELD,
                 "--max-evaluations", "2", "--profile", "f1", "--profile-points", "4",
                 "--json", str(out)]) == 0
    data = json.loads(out.read_text())
    p = data["profiles"]["f1"]
    assert data["parameters"]["f1"] == p["fitted_value"] and data["converged"]
    assert data["E_fit"] == pytest.approx(np.sqrt(p["S_min"]), rel=1e-9)
    replaced = data["replaced_fit"]
    assert replaced["E_fit"] > 2 * data["E_fit"] and not replaced["converged"]
    assert replaced["parameters"]["f1"] != data["parameters"]["f1"]
    printed = capsys.readouterr().out
    assert "the profiles' refit went on from the fit's end to a lower E_fit" in printed
    assert printed.count("FitResult(gradient, flat") == 2      # the fit, then the refit
    last = printed.splitlines()[-1]
    assert last.startswith(f"Gradient fit (the profiles' refit from the fit's end at E_fit "
                           f"{replaced['E_fit']:.4g} R) converged after "), last
    assert last.endswith(f" at E_fit {data['E_fit']:.4g} R"), last


def test_fit_command_shows_progress_on_a_terminal_only(midline_csv, monkeypatch, capsys):
    """Nelder-Mead's evaluations and the profiles' refits draw bars on a terminal's standard
    error (a 17 s Nelder-Mead fit on a terminal showed nothing, even with -v), and none where
    standard error is a file or a pipe."""
    import io

    class Terminal(io.StringIO):
        def isatty(self):
            return True

    argv = ["fit", str(midline_csv), "--variant", "flat", "--nodes", str(NODES), *HELD,
            "--method", "nelder-mead", "--max-evaluations", "5", "--profile", "f1",
            "--profile-points", "2"]
    with monkeypatch.context() as patched:
        term = Terminal()
        patched.setattr("sys.stderr", term)
        main(argv)
    shown = term.getvalue()
    assert "Nelder-Mead:" in shown and "/5 [" in shown and "evaluation" in shown
    assert "profile of f1:" in shown and "refit" in shown
    capsys.readouterr()
    main(argv)                                      # (capsys: not a terminal)
    err = capsys.readouterr().err
    assert "Nelder-Mead:" not in err and "refit" not in err and "\r" not in err


@pytest.mark.parametrize("names, said", [
    ("f1,kappa9", "unknown parameter(s) ['kappa9']"),
    ("kappa1", "['kappa1'] not fitted in the flat variant"),
    # audit 17 F7: "unknown parameter(s) []" named nothing
    ("", "--profile '': no parameter named; give one or more of ['f1'"),
    (" , ", "--profile ' , ': no parameter named"),
])
def test_fit_command_refuses_bad_profile_names(midline_csv, tmp_path, capsys, names, said):
    out = tmp_path / "fit.json"
    assert main(["fit", str(midline_csv), "--variant", "flat", "--nodes", str(NODES), *HELD,
                 "--profile", names, "--json", str(out)]) == 2
    err = capsys.readouterr().err
    assert said in err and err.count("\n") == 1
    assert not out.exists()


@pytest.mark.parametrize("argv, said", [
    # a single trace: refused after the fit had run (its result lost), in the library's words
    (["--profile", "f1", "--profile-noise", "traces"],
     "--profile-noise traces: {midline}: the midline holds no spread"),
    # options of the profiles without --profile did nothing, silently
    (["--profile-plot", "{tmp}/p.png"], "--profile-plot {tmp}/p.png without --profile NAMES"),
    (["--profile-points", "4", "--profile-noise", "residual"],
     "--profile-points 4, --profile-noise residual without --profile NAMES"),
])
def test_profile_options_that_cannot_apply_are_refused_before_the_fit(
        midline_csv, tmp_path, capsys, monkeypatch, argv, said):
    """(audit 3, #9 and #14): exit 2, one line naming the options and the file, no fit."""
    import morphoshell.fitting as fitting

    def no_fit(*args, **kwargs):
        raise AssertionError("the fit ran before the refusal")
    monkeypatch.setattr(fitting, "fit", no_fit)
    out = tmp_path / "fit.json"
    argv = [a.replace("{tmp}", str(tmp_path)) for a in argv]
    assert main(["fit", str(midline_csv), "--variant", "flat", "--nodes", str(NODES), *HELD,
                 *argv, "--json", str(out)]) == 2
    err = capsys.readouterr().err
    said = said.replace("{midline}", str(midline_csv)).replace("{tmp}", str(tmp_path))
    assert said in err and err.count("\n") == 1, err
    if "traces:" in said:
        assert "morphoshell average" in err          # (what the file needs to be)
    assert not list(tmp_path.iterdir())


def test_profile_noise_traces_takes_an_average_with_its_spread(tmp_path):
    """The check before the fit lets an average CSV (n_traces > 1, a spread column) through."""
    from argparse import Namespace

    from pathlib import Path

    from morphoshell.cli._profiles import profile_data
    from morphoshell.fitting import volvox_spec
    from morphoshell.io import load_midline

    path = Path(__file__).parents[2] / "data" / "synthetic_inversion" / "t02" / "synthetic_average.csv"
    midline = load_midline(path, n=100)
    args = Namespace(midline=path, profile_noise="traces")
    data = profile_data(args, volvox_spec("free"), midline)
    assert data.n_traces == 5 and data.spread is not None


def test_a_refit_that_jumps_is_tried_again_from_the_optimum(monkeypatch):
    """A refit continued from the last step can end on another branch, far above the profile
    (the synthetic t05's κ₁ at 1.09: 13.8 threshold heights, 1.12 from the optimum).  Above
    JUMP_MARGIN heights, or failed, it is tried again from the optimum and the lower kept;
    below, it is not."""
    import types

    import morphoshell.fitting.profiles as profiles
    from morphoshell.solvers.results import SolverError

    opt = types.SimpleNamespace(spec="opt spec", theta="opt theta", eq="opt eq")
    results = {"walk": 14.0, "opt spec": 1.1}
    calls = []

    def refit(opt_, name, spec, theta, eq, value, method, tol):
        calls.append(spec)
        if results[spec] is None:
            raise SolverError("no", "Continuation_Failed")
        return (spec, theta, eq, results[spec], True)

    monkeypatch.setattr(profiles, "_refit", refit)
    walked = ("walk", "theta", "eq")
    jump = profiles.JUMP_MARGIN        # (S_min 0, threshold 1: heights are objectives)
    out, failure = profiles._refit_checked(opt, "k", walked, 1.0, "gradient", 1e-8, jump)
    assert calls == ["walk", "opt spec"] and out[3] == 1.1 and failure == ""
    calls.clear()
    results["walk"] = 2.0               # (below the jump: no retry)
    out, _ = profiles._refit_checked(opt, "k", walked, 1.0, "gradient", 1e-8, jump)
    assert calls == ["walk"] and out[3] == 2.0
    calls.clear()
    results.update(walk=None, **{"opt spec": 3.0})     # failed: the retry's, even above
    out, _ = profiles._refit_checked(opt, "k", walked, 1.0, "gradient", 1e-8, jump)
    assert calls == ["walk", "opt spec"] and out[3] == 3.0
    results["opt spec"] = None          # both failed: the first failure's message
    out, failure = profiles._refit_checked(opt, "k", walked, 1.0, "gradient", 1e-8, jump)
    assert out is None and failure == "no"


def test_an_unconverged_refit_beyond_the_threshold_says_the_interval_may_reach_further():
    """The refit where a side first exceeds the threshold did not converge: its objective
    bounds the profile from above, so the interval may reach further there (an audit's
    kappa1 read [-0.01, 1.03] where a cold refit put the right end near 1.6, said only in a
    note); the verdict column says so."""
    from morphoshell.fitting.profiles import Profile

    values = np.array([-0.96, -0.09, 0.78, 1.64, 2.5])
    objective = np.array([4.0, 3.5, 3.0, 3.7, 5.0])
    converged = np.array([True, True, True, False, True])
    p = Profile("kappa1", 0.78, values, objective, converged, (-0.3, 1.03), 3.2, 3.0, 1.0,
                "residual", 0.95, False, "gradient")
    assert p.uncertain_sides() == (False, True)
    assert p.verdict() == ("may reach further above (the refit beyond the threshold at "
                           "kappa1 = 1.64 did not converge)")
    assert p.note == ""          # (said once, in the verdict, not again in a note)
    assert "may reach further above" in p.summary()
    converged[3] = True
    assert p.uncertain_sides() == (False, False) and p.verdict() == ""


def test_a_fit_read_back_from_its_json_profiles_as_the_fit(three, tmp_path):
    # audit 12: profiled_fit(result=load_fit(path)) raised AttributeError on the
    # equilibrium a saved fit does not hold; its solves now start afresh, and the
    # profiles are those of the fit in memory (the same optimum, to its refit's tolerance)
    from morphoshell.fitting import load_fit
    from morphoshell.io.problem_files import write_json

    spec, data, result, profiles = three
    back = load_fit(write_json(tmp_path / "fit.json", result.to_dict()))
    name = THREE[0]
    found, again = profiled_fit(spec, data, [name], result=back, points=6, nodes=NODES)
    assert found is back
    assert again[name].interval == pytest.approx(profiles[name].interval, rel=1e-6)


def _cut_line(word: str, json_path, csv_path) -> str:
    """The one line of a ``fit --profile f1,s2`` cut at the start of s2's profile."""
    return (rf"morphoshell: {word} during the profiles \(s2 not profiled\); the fit and the "
            rf"profiles of f1 kept in {re.escape(str(json_path))} and "
            rf"{re.escape(str(csv_path))}, the JSON marked partial\n")


def _check_partial(json_path, csv_path) -> None:
    """The fit and f1's profile written, the JSON marked partial, both read back."""
    from morphoshell.fitting import load_fit
    from morphoshell.fitting.profile_records import load_profiles

    data = json.loads(json_path.read_text())
    assert data["complete"] is False and data["not_done"] == "s2 not profiled"
    assert list(data["profile_intervals"]) == ["f1"]
    assert list(load_profiles(json_path)) == ["f1"]
    assert load_fit(json_path).E_fit == data["E_fit"]
    assert "f1" in csv_path.read_text()


@pytest.mark.parametrize("sig, status, word", [
    ("SIGINT", 130, "interrupted"), ("SIGTERM", 143, r"terminated \(SIGTERM\)")])
def test_an_interrupted_fit_profile_keeps_the_fit_and_the_profiles_finished(
        midline_csv, tmp_path, capsys, monkeypatch, sig, status, word):
    """Audit 23 F6: Ctrl-C or SIGTERM (the real signal) during ``fit --profile`` wrote
    nothing, though the fit had finished (a profile of all the parameters takes minutes
    to an hour).  Cut at the start of the second profile: the fit and the first profile
    are written, the JSON marked partial (complete, not_done) as continue's, one line says
    so, the exit status is the interruption's."""
    import os
    import signal

    from morphoshell.fitting import profiles

    real, calls = profiles._profile, []

    def cut_second(*args, **kwargs):
        calls.append(1)
        if len(calls) == 2:
            os.kill(os.getpid(), getattr(signal, sig))
        return real(*args, **kwargs)

    monkeypatch.setattr(profiles, "_profile", cut_second)
    doc, table = tmp_path / "p.json", tmp_path / "p.csv"
    assert main(["fit", str(midline_csv), "--variant", "flat", "--nodes", str(NODES), *HELD,
                 "--profile", "f1,s2", "--profile-points", "4", "--json", str(doc),
                 "--csv", str(table)]) == status
    err = capsys.readouterr().err
    assert re.fullmatch(_cut_line(word, doc, table), err), err
    _check_partial(doc, table)


#: A `fit --profile` that waits at the start of its second profile (for the SIGTERM of the
#: test that starts it).
_WAITING = """
import sys, time
from morphoshell.cli import main
from morphoshell.fitting import profiles
real, calls = profiles._profile, []
def waiting(*args, **kwargs):
    calls.append(1)
    if len(calls) == 2:
        print("ready", flush=True)
        time.sleep(60)
    return real(*args, **kwargs)
profiles._profile = waiting
sys.exit(main(sys.argv[1:]))
"""


def test_sigterm_to_a_background_fit_profile_keeps_what_was_done(midline_csv, tmp_path):
    """The same in a real process started with Ctrl-C ignored (a script's `cmd &`), sent
    SIGTERM during its second profile."""
    import os
    import signal
    import subprocess
    import sys

    doc, table = tmp_path / "b.json", tmp_path / "b.csv"
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}
    child = subprocess.Popen(
        [sys.executable, "-c", _WAITING, "fit", str(midline_csv), "--variant", "flat",
         "--nodes", str(NODES), *HELD, "--profile", "f1,s2", "--profile-points", "4",
         "--json", str(doc), "--csv", str(table)], env=env, text=True,
        stdout=subprocess.PIPE, stderr=subprocess.PIPE,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_IGN))
    try:
        while (line := child.stdout.readline()) not in ("ready\n", ""):
            pass        # (the fit's summary first)
        assert line == "ready\n"
        child.send_signal(signal.SIGTERM)
        _, err = child.communicate(timeout=120)
    finally:
        child.kill()
    assert child.returncode == 143, err
    assert re.fullmatch(_cut_line(r"terminated \(SIGTERM\)", doc, table), err), err
    _check_partial(doc, table)
