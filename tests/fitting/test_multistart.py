"""A fit from several starts (fitting.multistart): the lowest E_fit of the user's start, the
family's defaults and the multi-start, each with the fit's held values; the table of every
start; and the sign of a poor local minimum that ``morphoshell fit`` notes without it."""
import dataclasses
import json
import re


import pytest

from morphoshell.cli import main
from morphoshell.fitting import FitResult, fit, multistart, synthetic_midline, volvox_spec
from morphoshell.fitting.multistart import MULTI_STARTS, local_minimum_signs, multi_start_fit
from morphoshell.io import Midline
from morphoshell.solvers.results import SolverError

from fitting_cases import NODES, START, THREE, TRUE, three_parameter_spec

HELD = {n: TRUE.params[n] for n in TRUE.family_obj.parameters
        if n not in THREE and n not in ("kappa1", "sigma")}


@pytest.fixture(scope="module")
def data():
    return synthetic_midline(TRUE, three_parameter_spec().base, nodes=NODES, noise=5e-4, seed=2)


@pytest.fixture(scope="module")
def real(data):
    """One real fit, which the stubs below hand out with other E_fit."""
    return fit(three_parameter_spec(), data, nodes=NODES)


def _stub(monkeypatch, real, e_fits, calls=None):
    """multistart.fit returning ``real`` with the next of ``e_fits`` (an exception: raised)."""
    queue = list(e_fits)

    def stub(spec, data, method, **kw):
        if calls is not None:
            calls.append(spec)
        e = queue.pop(0)
        if isinstance(e, Exception):
            raise e
        return dataclasses.replace(real, E_fit=e)
    monkeypatch.setattr(multistart, "fit", stub)


def test_the_lowest_e_fit_wins_and_every_start_is_in_the_table(monkeypatch, data, real):
    spec = volvox_spec("unstressed", START)
    # (the fourth ends in the third's minimum, lower by rounding only: 1e-9 < SAME_MINIMUM)
    e_fits = [0.04, 0.03, 0.02, 0.02 * (1 - 1e-9), 0.05]
    _stub(monkeypatch, real, e_fits)
    got = multi_start_fit(spec, data, nodes=NODES)
    labels = [row["from"] for row in got.starts]
    assert labels[:2] == ["start", "family defaults"] and len(labels) == 2 + len(MULTI_STARTS)
    assert [row["E_fit"] for row in got.starts] == e_fits
    # the lowest wins, the first of equals (deterministic)
    assert got.winner == labels[2] and got.result.E_fit == 0.02
    assert got.to_dict()["started_from"] == labels[2]
    assert [line.startswith(" *") for line in got.table().splitlines()] == \
        [False, False, True, False, False]
    _stub(monkeypatch, real, [0.04, 0.03, 0.02, 0.0199, 0.05])      # (a lower minimum wins)
    assert multi_start_fit(spec, data, nodes=NODES).winner == labels[3]


def test_a_start_that_fails_is_recorded_and_the_others_go_on(monkeypatch, data, real):
    spec = volvox_spec("free")          # (the defaults: fitted once, not twice)
    error = SolverError("no step", "Maximum_Iterations_Exceeded")
    _stub(monkeypatch, real, [error, 0.03, 0.02, 0.05])
    got = multi_start_fit(spec, data, nodes=NODES)
    assert got.starts[0] == {"from": "family defaults", "E_fit": None,
                             "failed": "SolverError: no step"}
    assert got.result.E_fit == 0.02 and len(got.starts) == 1 + len(MULTI_STARTS)
    _stub(monkeypatch, real, [error] * 4)          # every start failed: the last error
    with pytest.raises(SolverError, match="no step"):
        multi_start_fit(spec, data, nodes=NODES)


def test_every_start_holds_the_held_values_h_and_opening(monkeypatch, data, real):
    calls = []
    hold = {"f1": 0.9, "kappa4": 2.0}
    spec = volvox_spec("undeformed", TRUE.with_updates(h=0.12, opening=0.25), hold=hold)
    _stub(monkeypatch, real, [0.05] * 5, calls)
    multi_start_fit(spec, data, nodes=NODES)
    assert calls[0] is spec and len(calls) == 2 + len(MULTI_STARTS)
    for s in calls:
        assert (s.base.h, s.base.opening, s.base.params["kappa1"]) == (0.12, 0.25, 1.0)
        assert all(s.base.params[n] == v and n not in s.fitted for n, v in hold.items())
    assert calls[-1].base.params["s4"] == MULTI_STARTS[-1]["s4"]


def test_a_start_that_stops_short_is_continued_once(monkeypatch, data, real):
    short = dataclasses.replace(real, converged=False, E_fit=0.05)
    results = iter([short, dataclasses.replace(real, E_fit=0.001)] + [real] * 5)
    monkeypatch.setattr(multistart, "fit", lambda *a, **k: next(results))
    got = multi_start_fit(volvox_spec("free"), data, nodes=NODES)
    assert got.starts[0]["continued"] and got.starts[0]["E_fit"] == 0.001
    assert got.winner == "family defaults" and not got.starts[1]["continued"]


def test_a_spec_that_is_not_a_volvox_variant_or_bad_data_is_refused(data):
    custom = dataclasses.replace(volvox_spec("free"), variant="custom")
    with pytest.raises(ValueError, match="Volvox variant"):
        multi_start_fit(custom, data)
    with pytest.raises(ValueError, match="nodes"):
        multi_start_fit(volvox_spec("free"), data, nodes=5)


def _pinned(real, variant, names):
    errors = {n: (float("nan") if n in names else 0.1) for n in real.fitted}
    return dataclasses.replace(real, variant=variant, standard_errors=errors)


@pytest.mark.parametrize("variant, pinned, signs", [
    ("unstressed", ("kappa2", "s2"), (["kappa2"], ["s2"])),
    ("flat", ("kappa2", "s2"), (["kappa2"], ["s2"])),
    ("free", ("kappa2", "s2"), ([], [])),            # the free fit is the reference
    ("flat", ("s2",), ([], [])),                     # breakpoints alone: common, no sign
    ("flat", ("kappa2",), ([], [])),
])
def test_a_bound_and_a_breakpoint_constraint_are_the_sign(real, variant, pinned, signs):
    assert local_minimum_signs(_pinned(real, variant, pinned)) == signs


def _csv(tmp_path, data):
    path = tmp_path / "midline.csv"
    Midline(data[:, 0], data[:, 1], None, 1, ("synthetic",)).to_csv(path)
    return path


def test_the_command_line_prints_and_records_every_start(tmp_path, data, capsys):
    held = [f"--set={n}={v}" for n, v in HELD.items()]
    out = tmp_path / "fit.json"
    assert main(["fit", str(_csv(tmp_path, data)), "--variant", "flat", "--nodes", str(NODES),
                 *held, "--multi-start", "--json", str(out)]) == 0
    text = capsys.readouterr().out
    assert "starts (--multi-start" in text and "may be a local minimum" not in text
    rec = json.loads(out.read_text())
    # the time of all the starts, not the winner's alone (which the line above it gives)
    every = re.search(r"--multi-start, (\d+) fits in ([0-9.]+) s", text)
    assert every and int(every.group(1)) == len(rec["starts"])
    assert float(every.group(2)) >= rec["seconds"]
    assert rec["settings"]["multi_start"] is True
    assert [row["from"] for row in rec["starts"]][0] == "family defaults"
    assert rec["started_from"] in [row["from"] for row in rec["starts"]]
    won = {row["from"]: row["E_fit"] for row in rec["starts"]}[rec["started_from"]]
    # (the winner: the lowest, or the first start within SAME_MINIMUM of it)
    assert rec["E_fit"] == won <= (1 + 1e-6) * min(row["E_fit"] for row in rec["starts"])
    assert all(set(row) == {"from", "E_fit", "converged", "constrained", "continued"}
               for row in rec["starts"])


def test_a_fixed_variant_on_a_bound_and_a_constraint_gets_a_note(tmp_path, data, capsys,
                                                                 monkeypatch, real):
    import morphoshell.fitting as fitting

    monkeypatch.setattr(fitting, "fit", lambda *a, **k: _pinned(real, "flat", ("kappa2", "s2")),
                        raising=False)
    held = [f"--set={n}={v}" for n, v in HELD.items()]
    main(["fit", str(_csv(tmp_path, data)), "--variant", "flat", "--nodes", str(NODES), *held])
    lines = capsys.readouterr().out.splitlines()
    notes = [line for line in lines if "local minimum" in line]
    assert len(notes) == 1 and "--multi-start" in notes[0] and "kappa2" in notes[0]
    assert lines[-1].startswith("Gradient fit")
