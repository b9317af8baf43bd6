"""Profiles read back from a fit's JSON (fitting.profile_records): the same profile to the
bit where the record holds it, and every bad entry refused in one line naming it."""
import json
import math

import numpy as np
import pytest

from morphoshell.fitting import (fit, load_profiles, profile_from_dict, profiled_fit,
                                 synthetic_midline)
from morphoshell.fitting.profile_noise import threshold_quantile
from morphoshell.fitting.profile_retry import Retry, crossings
from morphoshell.fitting.profiles import LOWER
from morphoshell.io.problem_files import write_json

from fitting_cases import NODES, THREE, TRUE, three_parameter_spec


@pytest.fixture(scope="module")
def saved(tmp_path_factory):
    spec = three_parameter_spec()
    data = synthetic_midline(TRUE, spec.base, nodes=NODES, noise=1e-3, seed=3)
    result = fit(spec, data, "gradient", nodes=NODES)
    _, profiles = profiled_fit(spec, data, THREE[:2], result=result, points=4)
    # an open side and a retry, which this fit's profiles do not have, on a copy: a σ²
    # whose threshold lies between the two sides' highest objectives opens the lower one
    # (a record's interval must be its threshold's crossings: _check_derived)
    name = THREE[0]
    retry = Retry(0.5, 2e-5, "optimum", 1.5e-5, True,
                  ({"from": "optimum", "E_fit": 0.0039, "converged": True},), 0.25, "")
    p = profiles[name]
    j = int(np.searchsorted(p.values, p.fitted_value))
    lower, upper = np.max(p.objective[:j]), np.max(p.objective[j + 1:])
    assert lower < upper     # (this fit's: else open the upper side)
    sigma2 = ((lower + upper) / 2 - p.S_min) / threshold_quantile(p.confidence, p.dof)
    profiles[name] = p.__class__(**{**p.__dict__, "side_ends": ("bound", "grid"),
                                    "retries": (retry,)}).rethreshold(sigma2, "given", p.dof)
    assert profiles[name].open_sides() == ("bound", "")
    # and a failed refit (objective NaN, written null) at the other's end
    other = profiles[THREE[1]]
    profiles[THREE[1]] = other.__class__(**{
        **other.__dict__, "objective": np.append(other.objective[:-1], np.nan),
        "converged": np.append(other.converged[:-1], False)})
    path = tmp_path_factory.mktemp("records") / "fit.json"
    write_json(path, {**result.to_dict(), "profiles": {n: p.to_dict()
                                                       for n, p in profiles.items()}})
    return path, profiles


def test_profiles_come_back_from_the_json_as_they_were(saved):
    path, profiles = saved
    back = load_profiles(path)
    assert list(back) == list(profiles)
    for name, p in profiles.items():
        q = back[name]
        for field in ("values", "objective", "converged"):
            assert np.array_equal(getattr(q, field), getattr(p, field), equal_nan=True), field
        for field in ("name", "fitted_value", "interval", "threshold", "S_min", "sigma2",
                      "sigma2_source", "confidence", "flat", "method", "note", "dof"):
            assert getattr(q, field) == getattr(p, field), (name, field)
        # what the readers of a profile see: its open sides, verdict and summary
        assert q.open_sides() == p.open_sides() and q.verdict() == p.verdict(), name
        assert q.summary() == p.summary(), name
        assert q.rethreshold(2 * p.sigma2).interval == p.rethreshold(2 * p.sigma2).interval
    r, s = back[THREE[0]].retries[0], profiles[THREE[0]].retries[0]
    # (stored as E_fit in R: the objectives come back squared, to round-off)
    assert (r.value, r.winner, r.converged, r.starts, r.seconds) == (
        s.value, s.winner, s.converged, s.starts, s.seconds)
    assert r.S == pytest.approx(s.S, rel=1e-15) and r.S_before == pytest.approx(s.S_before,
                                                                               rel=1e-15)


def test_a_fit_without_profiles_has_none(tmp_path):
    path = write_json(tmp_path / "fit.json", {"parameters": {}})
    assert load_profiles(path) == {}


@pytest.mark.parametrize("edit, said", [
    (lambda d: d.pop("threshold"), "the entry 'threshold' is missing"),
    (lambda d: d.update(values=d["values"][::-1]), "values must be a non-empty list of increasing"),
    # (either list may be the one edited: both named, with their lengths; 9 values: the
    # 4-point grid, the fit, and two refinements of each side's crossing at its first step)
    (lambda d: d.update(objective=d["objective"][1:]), "objective has 8 items, values 9"),
    (lambda d: d.update(values=d["values"][1:]), "objective has 9 items, values 8"),
    (lambda d: d["objective"].__setitem__(0, -1.0), "objective[0] = -1.0 must lie in"),
    (lambda d: d["converged"].__setitem__(1, "yes"), "converged[1] = 'yes' must be True or"),
    (lambda d: d.update(interval=[0.1]), "interval = [0.1] must be a list of 2 items"),
    (lambda d: d.update(fitted_value=123.0), "fitted_value = 123.0 must be one of the grid"),
    (lambda d: d.update(sigma2_source="guess"), "sigma2_source = 'guess' must be one of"),
    (lambda d: d.update(method="newton"), "method = 'newton' must be one of"),
    (lambda d: d.update(open_sides=["wall", None]), "open_sides[0] = 'wall' must be one of"),
    (lambda d: d.update(confidence=95), "confidence = 95 must lie in (0, 1]"),
    (lambda d: d.update(name="kappa9"), "name = 'kappa9' must be"),
    (lambda d: d["retries"][0].update(E_fit="x"), "retries[0].E_fit = 'x' must be a real"),
    # entries derived from others that disagree with them (audit 23 F1)
    (lambda d: d.update(interval=d["interval"][::-1]), "must be where the objective cross"),
    (lambda d: d.update(interval=[d["values"][0], d["values"][1]]), "must be where the "
                                                                    "objective crosses"),
    (lambda d: d.update(threshold=1.0), "threshold = 1.0 must be S_min + sigma2 * q = "),
    (lambda d: d.update(threshold=d["threshold"] * (1 + 1e-6)), "must be S_min + sigma2 * q"),
    (lambda d: d.update(S_min=1.0), "S_min = 1.0 must be the least objective of the profile"),
    (lambda d: d.update(S_min=d["S_min"] * (1 - 1e-15)), "must be the least objective"),
    (lambda d: d.update(sigma2=0), "sigma2 = 0 must lie in (0, inf]"),
    (lambda d: d.update(sigma2=d["sigma2"] * 2), "threshold = "),
    (lambda d: d.update(confidence=1.0), "confidence = 1.0 must lie in (0, 1): at 1"),
    (lambda d: d.update(flat=not d["flat"]), "flat = False disagrees with the interval"),
    # a value too long to print is cut (audit 23 F4: 17 000 characters)
    (lambda d: d["values"].__setitem__(0, list(range(3000))), "values[0] = [0, 1, 2,"),
    (lambda d: d.update(method=list(range(3000))), "method = [0, 1, 2,"),
    (lambda d: d.update(interval=list(range(3000))), "interval = [0, 1, 2,"),
])
def test_a_bad_entry_is_named_with_its_file(saved, tmp_path, edit, said):
    path, profiles = saved
    record = json.loads(path.read_text())
    name = THREE[0]
    edit(record["profiles"][name])
    bad = write_json(tmp_path / "edited.json", record)
    with pytest.raises(ValueError) as err:
        load_profiles(bad)
    message = str(err.value)
    assert message.startswith(f"{bad}: profiles.{name}: ") and said in message, message
    assert "\n" not in message and len(message) < len(str(bad)) + 300, message


def test_a_rethresholded_profile_and_a_threshold_from_the_fit_load(saved, tmp_path):
    """What the checks of derived entries must let pass: a profile rethresholded (S_min +
    σ² q) and one whose least refit lies below the fit by less than LOWER (its threshold
    the fit's objective + σ² q, as fitting.profiles sets it), each to the bit; and a
    threshold off by round-off only."""
    path, profiles = saved
    p = profiles[THREE[1]].rethreshold(3 * profiles[THREE[1]].sigma2, "given")
    j = int(np.searchsorted(p.values, p.fitted_value))
    S_fit = p.objective[j]
    objective = p.objective.copy()
    objective[j + 1] = S_fit * (1 - LOWER / 2)      # (a refit lower, by less than LOWER)
    threshold = S_fit + p.sigma2 * threshold_quantile(p.confidence, p.dof)
    S_min = float(np.nanmin(objective))
    lower = p.__class__(**{**p.__dict__, "objective": objective, "S_min": S_min,
                           "threshold": threshold, "interval": crossings(
                               p.values, objective, p.fitted_value, threshold, S_min)})
    for q in (p, lower):
        back = profile_from_dict(json.loads(json.dumps(q.to_dict())), "here", q.name)
        assert back.to_dict() == q.to_dict()
    record = p.to_dict()
    record["threshold"] *= 1 + 1e-12         # (another SciPy's quantile: DERIVED_RTOL)
    assert profile_from_dict(record, "here").threshold == record["threshold"]


def test_a_record_that_is_not_an_object_is_refused():
    with pytest.raises(ValueError, match="here: expected an object"):
        profile_from_dict([1, 2], "here")


def test_a_partial_files_profiles_load_with_a_warning_naming_those_not_done(saved, tmp_path,
                                                                            caplog):
    """Audit 27 F11: the profiles of a run cut short (``complete: false``) loaded silently,
    as if they were all that was asked for."""
    import logging

    path, profiles = saved
    record = json.loads(path.read_text())
    kept = THREE[0]
    record["profiles"] = {kept: record["profiles"][kept]}
    partial = tmp_path / "partial.json"
    partial.write_text(json.dumps({**record, "complete": False,
                                   "not_done": f"{THREE[1]}, {THREE[2]} not profiled"}))
    with caplog.at_level(logging.WARNING, logger="morphoshell"):
        assert list(load_profiles(partial)) == [kept]
    assert (f"partial.json: a run cut short (complete: false): {THREE[1]}, {THREE[2]} not "
            f"profiled; read the profiles it finished: {kept}") in caplog.text
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="morphoshell"):
        load_profiles(path)
    assert "cut short" not in caplog.text
