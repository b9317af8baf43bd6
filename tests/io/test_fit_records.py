"""One source of truth in a fit's JSON: its two copies of the parameters are read and must
agree (io.problem_files.problem_of_record), for `ablate FIT.json` and fitted_problem()."""
import json

import pytest

from morphoshell import Problem
from morphoshell.cli import main
from morphoshell.io.problem_files import problem_of_record
from morphoshell.workflows import fitted_problem

FITTED = Problem("volvox", {"kappa2": -7.5, "s1": 1.2}, h=0.15, opening=0.3)


def _record(**changes) -> dict:
    """A fit's record as `morphoshell fit --json` writes it (FitResult.to_dict's keys)."""
    p = FITTED
    parameters = {**p.params, "h": p.h, "cut": p.cut, "opening": p.opening}
    rec = {"problem": p.describe(), "parameters": parameters, "variant": "free"}
    rec.update(changes)
    return json.loads(json.dumps(rec))


def test_the_two_copies_agree_and_give_the_problem():
    assert problem_of_record(_record()) == FITTED
    # a campaign's record: named after its timepoint and variant
    named = fitted_problem({**_record(), "timepoint": "t05", "status": "ok"})
    assert named.name == "t05_free" and named.params == FITTED.params
    # a single fit's record (`fit --json`) works as well
    assert fitted_problem(_record()).params == FITTED.params


@pytest.mark.parametrize("edit, entry", [
    (lambda r: r["parameters"].update(kappa2=-7.0), "parameters.kappa2 = -7.0 but "
                                                    "problem.params.kappa2 = -7.5"),
    (lambda r: r["problem"]["params"].update(s1=1.3), "parameters.s1 = 1.2 but "
                                                      "problem.params.s1 = 1.3"),
    (lambda r: r["parameters"].update(h=0.2), "parameters.h = 0.2 but problem.h = 0.15"),
])
def test_an_edit_of_one_copy_is_refused_naming_the_entry(edit, entry):
    rec = _record()
    edit(rec)
    with pytest.raises(ValueError, match=entry.replace(".", r"\.")):
        problem_of_record(rec, "fit.json")


def test_a_parameter_missing_from_both_is_refused_not_defaulted():
    rec = _record()
    del rec["parameters"]["kappa2"], rec["problem"]["params"]["kappa2"]
    with pytest.raises(ValueError, match="no value of kappa2"):
        problem_of_record(rec, "fit.json")
    # in one copy only: taken from it
    rec = _record()
    del rec["problem"]["params"]["kappa2"]
    assert problem_of_record(rec).params["kappa2"] == -7.5


def test_ablate_refuses_a_fit_json_whose_copies_disagree(tmp_path, capsys):
    rec = _record()
    rec["parameters"]["kappa2"] = -7.0
    path = tmp_path / "fit.json"
    path.write_text(json.dumps(rec))
    out = tmp_path / "ablation.json"
    assert main(["ablate", str(path), "--set", "cut=0.15", "--json", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "parameters.kappa2 = -7.0" in err and str(path) in err
    assert not out.exists()


def test_a_failed_fit_has_no_fitted_shell():
    with pytest.raises(ValueError, match="the fit failed"):
        fitted_problem({"status": "failed", "message": "FitError: x"}, "t05_free.json")


def test_a_fit_json_re_solves_at_the_fits_nodes(tmp_path):
    """`morphoshell solve fit.json` solved a shape fitted at 100 nodes at the default 200
    (audit 3, #11): a fit's JSON records its [solver] table, a campaign's record its nodes;
    a solve's JSON reports its solve (not settings) and keeps the defaults."""
    from morphoshell.io.problem_files import ProblemFileError, Settings, load_problem

    cases = {"fit": ({"fitted": ["kappa2"], "solver": {"nodes": 100, "stages": 2,
                                                       "method": "direct"}}, 100),
             "campaign": ({"fitted": ["kappa2"], "nodes": 60}, 60),
             "old_fit": ({"fitted": ["kappa2"]}, 200),
             "solve": ({"solver": {"method": "direct", "nodes": 80, "iterations": 5}}, 200)}
    for name, (entries, nodes) in cases.items():
        path = tmp_path / f"{name}.json"
        path.write_text(json.dumps(_record(**entries)))
        problem, settings = load_problem(path)
        assert problem == FITTED and settings == Settings(nodes=nodes), name
    path = tmp_path / "tampered.json"
    path.write_text(json.dumps(_record(fitted=[], solver={"nodes": 3})))
    with pytest.raises(ProblemFileError, match=r"tampered\.json: solver: nodes = 3"):
        load_problem(path)
    path.write_text(json.dumps(_record(fitted=[], solver={"nodes": 100, "tol": 1})))
    with pytest.raises(ProblemFileError, match=r"unknown key\(s\) \['tol'\] in 'solver'"):
        load_problem(path)


def test_an_unconverged_fit_is_read_with_a_warning(caplog):
    """A fit that stopped short was ablated as if it were the fitted shell (user audit 5)."""
    import logging

    with caplog.at_level(logging.WARNING, logger="morphoshell"):
        fitted_problem(_record(fitted=["kappa2"], converged=True, E_fit=0.005), "good.json")
    assert not caplog.records
    with caplog.at_level(logging.WARNING, logger="morphoshell"):
        fitted_problem(_record(fitted=["kappa2"], converged=False, E_fit=11.26,
                               message="stopped"), "t07_flat.json")
    assert "t07_flat.json: the fit did not converge (E_fit = 11.26 R: stopped)" in caplog.text


def test_the_warning_of_a_campaigns_fit_names_it(caplog):
    """A campaign's record read with no file named: the warning says which fit it is about
    (Fig. 3's driver printed "the fit's record: the fit did not converge", audit 19, F1)."""
    import logging

    with caplog.at_level(logging.WARNING, logger="morphoshell"):
        fitted_problem(_record(fitted=["kappa2"], converged=False, E_fit=0.0853, status="ok",
                               timepoint="t07", variant="flat", message="near a fold"))
    assert "t07_flat: the fit did not converge (E_fit = 0.0853 R: near a fold)" in caplog.text


def test_ablate_of_an_unconverged_fit_warns_and_its_json_names_the_source(tmp_path, capsys):
    path = tmp_path / "short.json"
    path.write_text(json.dumps(_record(fitted=["kappa2"], converged=False, E_fit=0.0134,
                                       message="out of evaluations")))
    out = tmp_path / "ablation.json"
    assert main(["ablate", str(path), "--set", "cut=0.15", "--nodes", "40",
                 "--json", str(out)]) == 0
    captured = capsys.readouterr()
    assert f"{path}: the fit did not converge" in captured.err
    assert "E_fit = 0.0134 R, NOT converged" in captured.out
    assert json.loads(out.read_text())["source"] == {
        "file": str(path), "E_fit": 0.0134, "converged": False, "message": "out of evaluations"}


def test_a_problem_that_an_override_makes_invalid_names_the_file_too():
    """The t07 fit's curvature with a cut failed as '--set: abs(eta) = 1 ...', blaming the
    command line for the file's value."""
    from morphoshell.io.problem_files import ProblemFileError, apply_overrides

    with pytest.raises(ProblemFileError, match=r"^t07_flat\.json with --set h=5\.0: "):
        apply_overrides(FITTED, {"h": 5.0}, "t07_flat.json")
