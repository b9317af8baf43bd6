"""Profiles read back from a fit's JSON (fitting.profile_records): the same profile to the
bit where the record holds it, and every bad entry refused in one line naming it."""
import json
import math

import numpy as np
import pytest

from morphoshell.fitting import (fit, load_profiles, profile_from_dict, profiled_fit,
                                 synthetic_midline)
from morphoshell.fitting.profile_retry import Retry
from morphoshell.io.problem_files import write_json

from fitting_cases import NODES, THREE, TRUE, three_parameter_spec


@pytest.fixture(scope="module")
def saved(tmp_path_factory):
    spec = three_parameter_spec()
    data = synthetic_midline(TRUE, spec.base, nodes=NODES, noise=1e-3, seed=3)
    result = fit(spec, data, "gradient", nodes=NODES)
    _, profiles = profiled_fit(spec, data, THREE[:2], result=result, points=4)
    # an open side and a retry, which this fit's profiles do not have, on a copy
    name = THREE[0]
    retry = Retry(0.5, 2e-5, "optimum", 1.5e-5, True,
                  ({"from": "optimum", "E_fit": 0.0039, "converged": True},), 0.25, "")
    profiles[name] = profiles[name].__class__(**{
        **profiles[name].__dict__, "interval": (-math.inf, profiles[name].interval[1]),
        "side_ends": ("bound", "grid"), "retries": (retry,)})
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
    (lambda d: d.update(objective=d["objective"][1:]), "objective = "),
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
    assert "\n" not in message


def test_a_record_that_is_not_an_object_is_refused():
    with pytest.raises(ValueError, match="here: expected an object"):
        profile_from_dict([1, 2], "here")
