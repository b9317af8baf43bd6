"""How a fit stops (FitResult.stop) and the last line of ``morphoshell fit`` that says so:
the method, why it stopped, after how many evaluations, at which E_fit, and what to try;
``--max-evaluations`` sets the limit each method stops at."""
from types import SimpleNamespace

import pytest

from morphoshell.cli import main
from morphoshell.cli._fit_stops import stop_line
from morphoshell.fitting import synthetic_midline
from morphoshell.io import Midline

from fitting_cases import NODES, THREE, TRUE, three_parameter_spec

#: The held parameters of the three-parameter fit, on the command line.
HELD = [f"--set={n}={TRUE.params[n]}" for n in TRUE.family_obj.parameters
        if n not in THREE and n not in ("kappa1", "sigma")]


@pytest.fixture(scope="module")
def midline_csv(tmp_path_factory):
    spec = three_parameter_spec()
    points = synthetic_midline(TRUE, spec.base, nodes=NODES, noise=5e-4, seed=2)
    path = tmp_path_factory.mktemp("stops") / "synthetic_midline.csv"
    Midline(points[:, 0], points[:, 1], None, 1, ("synthetic",)).to_csv(path)
    return path


def _fit(midline_csv, *options):
    return main(["fit", str(midline_csv), "--variant", "flat", "--nodes", str(NODES), *HELD,
                 *options])


@pytest.mark.parametrize("method, name, then", [
    ("nelder-mead", "Nelder-Mead", "start from a gradient fit with --start FIT.json"),
    ("gradient", "Gradient fit", "go on from this fit with --start FIT.json"),
])
def test_a_fit_stopped_by_max_evaluations_says_so_on_its_last_line(midline_csv, tmp_path,
                                                                  capsys, method, name, then):
    """The limit is the method's (Nelder-Mead's function evaluations, least_squares'
    max_nfev): the fit stops there, exits 3 and writes its result, its last line naming
    the limit and what to try (Nelder-Mead used to stop after 20 000 evaluations saying
    only converged=False)."""
    out = tmp_path / "fit.json"
    assert _fit(midline_csv, "--method", method, "--max-evaluations", "3",
                "--json", str(out)) == 3
    last = capsys.readouterr().out.splitlines()[-1]
    assert last.startswith(f"{name} stopped after 3 evaluations (the limit) at E_fit "), last
    assert last.endswith(f" R, not converged: raise --max-evaluations above 3, or {then}"
                         + ("" if method == "nelder-mead" else " (its --json output)")), last
    assert out.exists()


@pytest.mark.parametrize("method", ["nelder-mead", "gradient"])
def test_a_fit_out_of_evaluations_says_in_its_message_how_to_go_on(method):
    """Audit 21 F12: the message of a fit that ran out of evaluations was SciPy's alone;
    it names max_iterations with its value and what to try, as the command line's last line
    does (one source, fitting.bilevel.more_evaluations), and its fit call, run as written,
    goes on from where the fit stopped: started there, it ends no higher."""
    from morphoshell.fitting import fit, volvox_spec

    data = synthetic_midline(TRUE, three_parameter_spec().base, nodes=NODES, noise=5e-4,
                             seed=2)
    result = fit(three_parameter_spec(), data, method, nodes=NODES, max_iterations=3)
    assert not result.converged and result.stop == "Maximum_Evaluations_Exceeded"
    unit = "function" if method == "nelder-mead" else "residual"
    then = "start from a gradient fit" if method == "nelder-mead" else "go on from this fit"
    head, _, call = result.message.partition(f"): raise max_iterations above 3, or {then} with ")
    assert head.endswith(f" (max_iterations = 3 {unit} evaluations"), result.message
    held = tuple(n for n in TRUE.family_obj.parameters if n not in THREE + ("kappa1", "sigma"))
    assert call == (f"fit(volvox_spec('flat', result.problem, hold={{n: result.parameters[n] "
                    f"for n in {held!r}}}), data, "
                    f"{'gradient' if unit == 'function' else method!r}, "
                    f"nodes={NODES}, start=result.equilibrium)"), call
    # (one namespace: the call's comprehension does not see eval's locals)
    again = eval(call, {"fit": fit, "volvox_spec": volvox_spec, "result": result, "data": data})
    assert sorted(again.fitted) == sorted(THREE) and again.E_fit <= result.E_fit
    assert again.converged and again.stop == "Fit_Converged"


def test_a_converged_fit_says_so_on_its_last_line(midline_csv, capsys):
    assert _fit(midline_csv, "--method", "gradient") == 0
    last = capsys.readouterr().out.splitlines()[-1]
    assert last.startswith("Gradient fit converged after ") and " evaluations at E_fit " in last
    assert last.endswith(" R"), last


def test_a_kkt_fit_out_of_iterations_fails_naming_the_limit(midline_csv, tmp_path, capsys):
    """The KKT fit's limit is Ipopt's max_iter of each NLP (and the evaluations of its
    fallback Gauss-Newton steps): out of them it fails, exit 3, on one error line."""
    out = tmp_path / "fit.json"
    assert _fit(midline_csv, "--method", "kkt", "--max-evaluations", "1",
                "--json", str(out)) == 3
    captured = capsys.readouterr()
    assert captured.err.count("\n") == 1 and "Maximum_Iterations_Exceeded" in captured.err
    assert "raise --max-evaluations above 1 (Ipopt iterations per NLP)" in captured.err
    assert ".." not in captured.err and not out.exists()


@pytest.mark.parametrize("value, named", [("0", "0 must lie in [1, "), ("-5", "-5 must lie"),
                                          ("2.5", "'2.5' is not an integer"),
                                          ("many", "'many' is not an integer")])
def test_max_evaluations_refuses_what_is_not_a_positive_integer(midline_csv, tmp_path, capsys,
                                                                value, named):
    out = tmp_path / "fit.json"
    assert _fit(midline_csv, "--max-evaluations", value, "--json", str(out)) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "argument --max-evaluations: " + named in err, err
    assert not out.exists()


def _ended(method="gradient", stop="Fit_Converged", converged=False, its=42, E_fit=0.0123):
    return SimpleNamespace(method=method, stop=stop, converged=converged, outer_iterations=its,
                           E_fit=E_fit)


@pytest.mark.parametrize("result, limit, line", [
    (_ended("nelder-mead", converged=True, its=812), 20000,
     "Nelder-Mead converged after 812 evaluations at E_fit 0.0123 R"),
    (_ended("kkt", "Solved_To_Acceptable_Level", True, 69), 60,
     "KKT fit converged after 69 iterations at E_fit 0.0123 R (Ipopt: Solved_To_Acceptable_Level)"),
    (_ended("nelder-mead", "Maximum_Evaluations_Exceeded", its=20000), 20000,
     "Nelder-Mead stopped after 20000 evaluations (the limit) at E_fit 0.0123 R, not converged: "
     "raise --max-evaluations above 20000, or start from a gradient fit with --start FIT.json"),
    (_ended("gradient", "Maximum_Evaluations_Exceeded", its=260), 200,
     "Gradient fit stopped after 260 evaluations (the limit of 200 in its last run) at E_fit "
     "0.0123 R, not converged: raise --max-evaluations above 200, or go on from this fit with "
     "--start FIT.json (its --json output)"),
    (_ended("gradient", "Fit_Stalled"), 200,
     "Gradient fit stopped at its best point after 42 evaluations at E_fit 0.0123 R, not "
     "converged: trial points in a row failed their inner solve (a fold of the branch?); start "
     "nearer the data with --start FIT.json (a fit of a neighbouring stage), or --method "
     "nelder-mead"),
    (_ended("gradient", "Fit_Not_Stationary"), 200,
     "Gradient fit stalled short of a stationary point after 42 evaluations at E_fit 0.0123 R, "
     "not converged: trial points near it were rejected (a fold of the branch?); start nearer "
     "the data with --start FIT.json (a fit of a neighbouring stage), or --method nelder-mead"),
    (_ended("kkt", "Fit_Near_Fold"), 60,
     "KKT fit ended near a fold of the equilibrium branch after 42 iterations at E_fit 0.0123 R, "
     "not converged: the shape is nearly unstable, its standard errors meaningless; start from "
     "another point with --start FIT.json, or hold a poorly identified parameter with "
     "--set NAME=VALUE"),
    (_ended("gradient", "Fit_On_Box_Edges"), 200,
     "Gradient fit ended with a breakpoint on the edge of its box after 42 evaluations at E_fit "
     "0.0123 R, not converged: the optimum may lie beyond the boxes' last move; hold it with "
     "--set NAME=VALUE, or start nearer the data with --start FIT.json (a fit of a "
     "neighbouring stage)"),
    (_ended("kkt", "Fit_Moved_Boxes_Failed"), 60,
     "KKT fit failed from moved boxes after 42 iterations at E_fit 0.0123 R, not converged: "
     "the fit within the last boxes stands; go on from it with --start FIT.json (its --json "
     "output), or another --method"),
    (_ended("gradient", "Fit_Not_Minimum"), 200,
     "Gradient fit ended short of its minimum after 42 evaluations at E_fit 0.0123 R, not "
     "converged: a profile's refit lies lower (the profiles' notes say where); fit again from "
     "it with --start FIT.json (its --json output), or another --method"),
])
def test_the_last_line_names_every_way_a_fit_ends(result, limit, line):
    assert stop_line(result, limit) == line


def test_the_last_line_names_the_fit_a_profiles_refit_went_on_from():
    refit, fit = _ended(converged=True, its=12, E_fit=0.01215), _ended(E_fit=0.01236)
    assert stop_line(refit, 200, fit) == (
        "Gradient fit (the profiles' refit from the fit's end at E_fit 0.01236 R) converged "
        "after 12 evaluations at E_fit 0.01215 R")


@pytest.mark.parametrize("result, line", [
    (_ended("gradient", "Fit_Stalled", its=54, E_fit=10.19),
     "Gradient fit stopped at its best point after 54 evaluations at E_fit 10.19 R, not "
     "converged: E_fit is far above what the model leaves of a traced midline (0.005-0.03 R): "
     "check the input: its orientation (pole first? z flipped?), its scale (--pixel-size and "
     "--radius-um; a CSV's r, z in units of R), its axis (--section) and any --set values "
     "first; if it is right, trial points in a row failed their inner solve (a fold of the "
     "branch?); start nearer the data with --start FIT.json (a fit of a neighbouring stage), "
     "or --method nelder-mead"),
    (_ended("gradient", converged=True, its=64, E_fit=0.217),
     "Gradient fit converged after 64 evaluations at E_fit 0.217 R; E_fit is far above what "
     "the model leaves of a traced midline (0.005-0.03 R): check the input: its orientation "
     "(pole first? z flipped?), its scale (--pixel-size and --radius-um; a CSV's r, z in units "
     "of R), its axis (--section) and any --set values; if it is right, the model may not "
     "describe this shape (see the parameters on bounds and constraints)"),
    (_ended("gradient", "Fit_Not_Stationary", E_fit=0.099),
     "Gradient fit stalled short of a stationary point after 42 evaluations at E_fit 0.099 R, "
     "not converged: trial points near it were rejected (a fold of the branch?); start nearer "
     "the data with --start FIT.json (a fit of a neighbouring stage), or --method nelder-mead"),
])
def test_a_fit_far_above_traced_midlines_points_at_the_input(result, line):
    """A z-flipped CSV (10.2 R), a radius 10 % off (0.69 R), f1 held at 5 (16.5 R) ended
    blaming "a fold of the branch?" alone (audit 3, #10); above IMPLAUSIBLE_E_FIT = 0.1 R the
    line names the input's orientation, scale and axis first, and keeps the fold's remedy
    (stalls at folds on right data reach 0.24-0.67 R)."""
    assert stop_line(result, 200) == line


def test_the_outputs_say_how_the_fit_was_made_and_how_it_ended(midline_csv, tmp_path, capsys):
    """`fit --json` recorded neither nodes nor the start nor the limit, and `solve` re-solved
    it at 200 nodes; `fit --csv` of a fit stopped short looked like a converged one's (audit
    3, #11).  The CSV stays one table pandas reads as it is."""
    import json

    import pandas as pd

    out, table = tmp_path / "fit.json", tmp_path / "fit.csv"
    assert _fit(midline_csv, "--max-evaluations", "2", "--json", str(out),
                "--csv", str(table)) == 3
    record = json.loads(out.read_text())
    assert record["solver"] == {"nodes": NODES, "stages": 2, "method": "direct"}
    settings = record["settings"]
    assert settings["nodes"] == NODES and settings["max_evaluations"] == 2
    assert settings["evaluation_limit"] == 2 and settings["start"] is None
    assert settings["section"] == "auto" and settings["pixel_size_um"] is None
    assert settings["set"] == {n: TRUE.params[n] for n in TRUE.family_obj.parameters
                               if n not in THREE and n not in ("kappa1", "sigma")}
    assert settings["midline_file"] == str(midline_csv) and settings["method"] == "gradient"
    assert record["input_check"] is None               # (E_fit below IMPLAUSIBLE_E_FIT)
    assert record["walls_cross"] is None
    df = pd.read_csv(table)
    assert list(df.columns) == ["parameter", "value", "standard_error", "unit", "fitted",
                                "on_constraint", "E_fit", "converged", "stop", "walls_cross",
                                "standard_errors_source"]
    assert sorted(df.parameter[:3]) == sorted(THREE) and df.converged.dtype == bool
    assert df.fitted.tolist() == [True] * 3 + [False] * (len(df) - 3)
    assert df.walls_cross.dtype == bool and not df.walls_cross.any()
    assert not df.converged.any() and set(df.stop) == {"Maximum_Evaluations_Exceeded"}
    assert (df.E_fit == record["E_fit"]).all()
    capsys.readouterr()
    assert main(["solve", str(out)]) == 0               # (the JSON as a problem file)
    assert f"direct solution, {NODES} nodes" in capsys.readouterr().out


def test_the_json_says_when_e_fit_is_far_above_traced_midlines(midline_csv, tmp_path,
                                                                monkeypatch):
    """The terminal's "check the input" verdict was only on the terminal: a script reading
    the JSON saw a converged fit (audit 10, F8).  The JSON's input_check holds it."""
    import json

    import morphoshell.fitting.midline_checks as checks
    monkeypatch.setattr(checks, "IMPLAUSIBLE_E_FIT", 0.0)   # (every fit is far above now)
    out = tmp_path / "fit.json"
    _fit(midline_csv, "--max-evaluations", "2", "--json", str(out))
    check = json.loads(out.read_text())["input_check"]
    assert check.startswith("E_fit is far above what the model leaves of a traced midline")
    assert check.endswith("the model may not describe this shape (see the parameters on "
                          "bounds and constraints)")
