"""What a fit returns (fitting.results): standard errors, constraints and folds."""
import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from morphoshell import Problem
from morphoshell.fitting import N_FIT, fit, volvox_spec


@pytest.mark.parametrize("blowup, converged", [(1.0, True), (1e2, True), (1e6, False)])
def test_a_fit_near_a_fold_of_the_branch_is_not_converged(blowup, converged):
    """Near a fold dx/dp ~ 1/lambda_min blows up along one direction: the Jacobian is a
    rank-one term that dwarfs the rest (a free fit of the synthetic t07 crept onto one:
    second singular value 5e-7 of the first).  Random J + blowup * u v^T: the singular
    value ratio is ~0.5, ~0.1 and ~1e-6."""
    from types import SimpleNamespace

    from morphoshell.fitting import volvox_spec
    from morphoshell.fitting.results import FOLD_RATIO, fit_result

    spec = volvox_spec("free")
    k = len(spec.fitted)
    rng = np.random.default_rng(1)
    J = rng.normal(size=(200, k)) + blowup * np.outer(rng.normal(size=200), rng.normal(size=k))
    # (one point of a shell: no walls to cross, fit_result checks them)
    eq = SimpleNamespace(problem=spec.base, **dict.fromkeys(("s", "r", "z", "f_s", "f_phi"),
                                                            np.ones(1)))
    inner = SimpleNamespace(solve=lambda theta: eq, residuals=lambda eq: np.full(200, 1e-3),
                            jacobian=lambda eq, theta: J, data=np.zeros((100, 2)), n=100,
                            solves=1)
    r = fit_result("gradient", spec, inner, np.ones(k), 5, 0.1, True, "ftol reached")
    sv = np.linalg.svd(J, compute_uv=False)
    assert (sv[1] >= FOLD_RATIO * sv[0]) == converged
    assert r.converged is converged and r.near_fold is not converged
    assert ("near a fold" in r.message) is not converged and r.message.startswith("ftol")
    assert r.stop == ("Fit_Converged" if converged else "Fit_Near_Fold")


def test_the_summary_gives_every_parameter_its_unit_and_directions_as_sums():
    """Fitted values printed without units ('kappa1 = 1.37765 ± 0.12', though every printed
    quantity carries its unit) and poorly identified directions as a Python dict ("{'f2':
    0.695, ...}"): now the family's units (stretches dimensionless, curvatures 1/R,
    breakpoints R) and a sum of the parameters."""
    import re
    from types import SimpleNamespace

    from morphoshell.fitting.results import fit_result

    spec = volvox_spec("free")
    k = len(spec.fitted)
    rng = np.random.default_rng(2)
    u, sv, vt = np.linalg.svd(rng.normal(size=(200, k)), full_matrices=False)
    sv[-1] = 1e-5 * sv[0]                       # one direction the data hardly see
    theta = spec.theta0                         # (off every constraint)
    J = u @ np.diag(sv) @ vt / np.maximum(np.abs(theta), 1e-2)   # (fit_result scales by θ)
    # (one point of a shell: no walls to cross, fit_result checks them)
    eq = SimpleNamespace(problem=spec.base, **dict.fromkeys(("s", "r", "z", "f_s", "f_phi"),
                                                            np.ones(1)))
    inner = SimpleNamespace(solve=lambda theta: eq, residuals=lambda eq: np.full(200, 1e-3),
                            jacobian=lambda eq, theta: J, data=np.zeros((100, 2)), n=100,
                            solves=1)
    lines = fit_result("gradient", spec, inner, theta, 5, 0.1, True, "").summary().split("\n")
    units = {"f": "(dimensionless)", "kappa": "1/R", "s": "R"}
    for name in spec.fitted:
        [line] = [x for x in lines if x.startswith(f"  {name} ")]
        assert line.endswith(" " + units[name.rstrip("12345")]) and " ± " in line, line
    [poor] = [x for x in lines if "poorly identified" in x]
    assert "{" not in poor and "'" not in poor, poor
    assert re.search(r"poorly identified: -?\d\.\d+ \w+ [+-] \d\.\d+ \w+ [+-] \d\.\d+ \w+ "
                     r"\+ \.\.\. \(parameters relative to their size; singular value 1e-05 of "
                     r"the largest\)$", poor), poor


@pytest.fixture(scope="module")
def pinned_fit():
    """(spec, base, fit) of data whose s3 lies 0.6 sigma above s2: a fit that ends on the
    constraint s3 - s2 = sigma (NaN standard errors and correlations)."""
    from morphoshell.fitting import synthetic_midline

    base = Problem("volvox", h=0.15, opening=0.3)
    p = base.params
    hold = {k: v for k, v in p.items() if k not in ("s2", "s3")}
    spec = volvox_spec("free", start=base, hold=hold)
    return spec, base, fit(spec, synthetic_midline(
        base.with_updates(s3=p["s2"] + 0.6 * p["sigma"]), nodes=60), "gradient", nodes=60)


def test_a_fit_that_ends_on_a_constraint_says_so_and_gives_no_errors_there(pinned_fit):
    """Data whose s3 lies 0.6 sigma above s2: the fit (gaps of at least sigma) ends on
    s3 - s2 = sigma, a constrained optimum, and says so; s2 and s3 get no standard errors
    (Gauss-Newton errors of a free optimum; on replicate t02 data sets the jackknife
    errors of fits pinned there were 0.001-0.002 against misses of 0.018).  The
    same fit of data with the default gap (6 sigma) ends inside, with finite errors."""
    from morphoshell.fitting import synthetic_midline

    spec, base, pinned = pinned_fit
    p = base.params
    assert pinned.converged and pinned.constrained == ("s3 - s2 = sigma",)
    assert pinned.parameters["s3"] - pinned.parameters["s2"] == pytest.approx(p["sigma"],
                                                                              abs=1e-4)
    assert all(np.isnan(pinned.standard_errors[n]) for n in ("s2", "s3"))
    assert pinned.pinned == ("s2", "s3")
    assert "ends on the constraint s3 - s2 = sigma" in pinned.message
    d = pinned.to_dict()
    assert d["standard_errors"] == {"s2": None, "s3": None}
    assert d["constrained"] == ["s3 - s2 = sigma"]
    assert "(on a constraint)" in pinned.summary()
    inside = fit(spec, synthetic_midline(base, nodes=60), "gradient", nodes=60)
    assert inside.constrained == () and all(np.isfinite(list(inside.standard_errors.values())))
    assert inside.pinned == ()


def test_a_fit_pickles_with_its_equilibrium(pinned_fit):
    """A user audit: pickle.dumps(fit(...)) failed on the equilibrium's problem (t26.py)."""
    import pickle

    res = pinned_fit[2]
    back = pickle.loads(pickle.dumps(res))
    assert back.problem == res.problem and back.summary() == res.summary()
    assert back.equilibrium.energy == res.equilibrium.energy
    assert np.array_equal(back.equilibrium.r, res.equilibrium.r)
    assert np.array_equal(back.residuals, res.residuals) and back.stop == res.stop


def test_a_saved_fit_reads_back_as_the_fit(pinned_fit, tmp_path):
    """A user audit: a fit's JSON had no reader, so its standard errors, constraints and
    midlines were read from the raw dict.  Saved as fit --json saves it (null for the NaN
    of a constraint), it reads back to the same record and summary, without its
    equilibrium.  The residuals are the midlines' difference: to round-off (1e-15 R)."""
    from morphoshell.fitting import load_fit
    from morphoshell.io.problem_files import to_jsonable, write_json

    res = pinned_fit[2]
    back = load_fit(write_json(tmp_path / "fit.json", res.to_dict()))
    assert to_jsonable(back.to_dict()) == to_jsonable(res.to_dict())
    assert back.summary() == res.summary() and back.problem == res.problem
    assert back.pinned == ("s2", "s3") and back.constrained == res.constrained
    assert back.equilibrium is None and back.stop == res.stop == "Fit_Converged"
    assert np.array_equal(back.data, res.data) and np.array_equal(back.model, res.model)
    assert np.allclose(back.residuals, res.residuals, rtol=0, atol=1e-15)


def test_a_campaigns_record_and_an_unconverged_fits_read_back(pinned_fit):
    """A campaign's record names the fit's method fitted_by (its method is the campaign's
    setting) and drops seconds; one written before records kept ``stop``, of a fit that did
    not converge, reads back with stop 'Unknown'."""
    from morphoshell.fitting import FitResult

    record = {**pinned_fit[2].to_dict(), "method": "kkt", "fitted_by": "gradient",
              "converged": False, "status": "ok"}
    del record["seconds"], record["stop"]
    back = FitResult.from_dict(record)
    assert back.method == "gradient" and math.isnan(back.seconds)     # (not recorded)
    assert "time not recorded" in repr(back)
    assert not back.converged and back.stop == "Unknown"


@pytest.mark.parametrize("change, said", [
    (lambda r: r.update(status="failed", message="no start solved"),
     r"x.json: the fit failed \(no start solved\)"),
    (lambda r: r.pop("E_fit"), r"x.json: no E_fit: not a fit's record"),
    (lambda r: r.update(fitted_midline={"r": [1.0], "z": "abc"}),
     r"x.json: fitted_midline must hold lists of numbers"),
])
def test_a_broken_fit_record_is_refused_naming_the_entry(pinned_fit, change, said):
    from morphoshell.fitting import FitResult

    record = pinned_fit[2].to_dict()
    change(record)
    with pytest.raises(ValueError, match=said):
        FitResult.from_dict(record, "x.json")


#: What an edit may put in place of an entry of a fit's JSON: other types, non-finite and
#: negative numbers, ragged lists, a midline-like mapping.
_JUNK = ["x", None, True, 5, -1.0, math.nan, math.inf, [], [1, 2], [[1, 2], [3]], {},
         {"r": [1.0], "z": [1.0, 2.0]}]


def _paths(value, path=()):
    """Every path into a JSON value (keys; the first two and the last items of a list)."""
    yield path
    items = (value.items() if isinstance(value, dict) else
             [(i, value[i]) for i in sorted({0, 1, len(value) - 1} & set(range(len(value))))]
             if isinstance(value, list) else ())
    for key, item in items:
        yield from _paths(item, (*path, key))


def _edited(record, edits):
    """A deep copy of ``record`` with each (path, edit) of ``edits`` applied in turn: the
    entry at the path dropped, shortened by its last item, lengthened by a copy of it
    ("drop", "short", "long"), or replaced by the edit (an earlier edit may have removed
    the path: then nothing)."""
    import copy

    record = copy.deepcopy(record)
    for path, edit in edits:
        if not path:
            record = record if edit in ("drop", "short", "long") else copy.deepcopy(edit)
            continue
        parent = record
        for key in path[:-1]:
            parent = parent[key] if isinstance(parent, (dict, list)) and _has(parent, key) else None
        if isinstance(parent, (dict, list)) and _has(parent, path[-1]):
            _edit(parent, path[-1], edit)
    return record


def _has(container, key):
    """Whether ``container`` (a dict or list) has the key or index."""
    return key in container if isinstance(container, dict) else (
        isinstance(key, int) and key < len(container))


def _edit(parent, key, edit):
    """Drop, shorten, lengthen or replace ``parent[key]`` (:func:`_edited`)."""
    import copy

    value = parent[key]
    if edit == "drop":
        del parent[key]
    elif edit in ("short", "long"):
        if isinstance(value, list) and value:
            parent[key] = value[:-1] if edit == "short" else [*value, value[-1]]
    else:
        parent[key] = copy.deepcopy(edit)


def _loads_or_names_the_file(file, record):
    """Write ``record`` to ``file`` and read it with load_fit: it loads, or a ValueError of
    one line starting with the file's name (no other exception, no warning)."""
    import json
    import warnings

    from morphoshell.fitting import load_fit

    file.write_text(json.dumps(record))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        try:
            load_fit(file)
        except ValueError as exc:
            assert str(exc).startswith(f"{file}: ") and "\n" not in str(exc), str(exc)


@pytest.fixture(scope="module")
def saved_fit(pinned_fit, tmp_path_factory):
    """(record, paths, folder): a small fit's JSON record (60 nodes; null errors and
    correlations on its constraint), every path into it, and a folder for edited copies."""
    from morphoshell.io.problem_files import to_jsonable

    record = to_jsonable(pinned_fit[2].to_dict())
    return record, list(_paths(record)), tmp_path_factory.mktemp("edited")


_EDITS = ["drop", "short", "long", *_JUNK]


def test_every_single_edit_of_a_fit_json_loads_or_is_refused_naming_the_file(saved_fit):
    """Audit 17 F5: edits of a fit's JSON (a list for parameters, a string for E_fit, a
    ragged correlation) gave raw TypeError/ValueError messages naming neither the file nor
    the entry, and a bogus variant or method was read without complaint.  Each entry (86
    paths) dropped, replaced by another type, NaN or inf, or cut or lengthened by one item
    (1290 files): the fit loads, or a ValueError of one line names the file."""
    record, paths, folder = saved_fit
    for path in paths:
        for edit in _EDITS:
            _loads_or_names_the_file(folder / "edited fit.json", _edited(record, [(path, edit)]))


@given(data=st.data())
@settings(max_examples=300, deadline=None, derandomize=True, database=None)
def test_several_edits_of_a_fit_json_load_or_are_refused_naming_the_file(saved_fit, data):
    """One to three of those edits at once (:func:`test_every_single_edit_of_a_fit_json_
    loads_or_is_refused_naming_the_file`), as a hand edit may make them."""
    record, paths, folder = saved_fit
    edits = data.draw(st.lists(st.tuples(st.sampled_from(paths), st.sampled_from(_EDITS)),
                               min_size=1, max_size=3))
    _loads_or_names_the_file(folder / "edited fit.json", _edited(record, edits))


@pytest.mark.parametrize("edits, said", [
    ([(("parameters",), [1, 2])], "parameters = [1, 2] must map names to numbers"),
    ([(("E_fit",), "x")], "E_fit = 'x' must be a real number"),
    ([(("standard_errors", "s2"), "x")], "standard_errors.s2 = 'x' must be a real number"),
    ([(("correlation",), [[1, 2], [3]])], "correlation must be a 2 x 2 matrix"),
    ([(("variant",), "bogus")], "variant = 'bogus' must be one of"),
    ([(("method",), 5)], "method = 5 must be one of"),
    ([(("fitted",), ["s2", "nope"])], "fitted = ['s2', 'nope'] must be a list of distinct names"),
    ([(("converged",), "yes")], "converged = 'yes' must be True or False"),
    ([(("stop",), "Done")], "stop = 'Done' is not a status"),
    ([(("problem", "params"), [1, 2])], "problem.params = [1, 2] must map names to numbers"),
    ([(("correlation", 0, 1), 5)], "correlation[0][1] = 5 must lie in [-1, 1]"),
    ([(("fitted_midline", "r"), [0.0])], "fitted_midline must hold lists of numbers r and z"),
    ([(("data_midline", "r"), "short"), (("data_midline", "z"), "short")],
     f"fitted_midline has {N_FIT} points, data_midline {N_FIT - 1}: expected one fitted point"),
    # a stop that contradicts converged (audit 23 F2): both entries named
    ([(("stop",), "Maximum_Evaluations_Exceeded")],
     "stop = 'Maximum_Evaluations_Exceeded' disagrees with converged = true: a converged "
     "fit's stop is one of Fit_Converged, Solve_Succeeded, Solved_To_Acceptable_Level"),
    ([(("stop",), "Infeasible_Problem_Detected")], "stop = 'Infeasible_Problem_Detected' "
                                                    "disagrees with converged = true"),
    ([(("converged",), False)], "stop = 'Fit_Converged' disagrees with converged = false"),
    # a walls_cross that is not a crossing of this shell, s in [0, pi - 0.3] (audit 23 F3)
    ([(("walls_cross",), {"s": [1.0, 2.0], "distance": 0.5, "thickness": 0.1})],
     "walls_cross.distance = 0.5 must be less than walls_cross.thickness = 0.1"),
    ([(("walls_cross",), {"s": [1.0, 2.0], "distance": 0.1, "thickness": 0.1})],
     "walls_cross.distance = 0.1 must be less than"),
    ([(("walls_cross",), {"s": [2.0, 1.0], "distance": 0.05, "thickness": 0.1})],
     "walls_cross.s = [2.0, 1.0] must be two increasing material points of the shell, in "
     "[0, 2.84159]"),
    ([(("walls_cross",), {"s": [1.0, 1.0], "distance": 0.05, "thickness": 0.1})],
     "walls_cross.s = [1.0, 1.0] must be two increasing"),
    ([(("walls_cross",), {"s": [-5.0, 1.0], "distance": 0.05, "thickness": 0.1})],
     "walls_cross.s = [-5.0, 1.0] must be two increasing"),
    ([(("walls_cross",), {"s": [1.0, 2.85], "distance": 0.05, "thickness": 0.1})],
     "walls_cross.s = [1.0, 2.85] must be two increasing"),
    ([(("walls_cross",), {"s": [1.0, 2.0], "distance": 0.0, "thickness": 0.0})],
     "walls_cross.thickness = 0.0 must lie in (0, inf]"),
    ([(("walls_cross",), {"s": [1.0, 2.0], "distance": 0.05, "thickness": 0.1, "x": 1})],
     "walls_cross = {'s': [1.0, 2.0], 'distance': 0.05, 'thickness': 0.1, 'x': 1} must be"),
])
def test_an_edited_fit_json_is_refused_naming_the_file_and_entry(saved_fit, edits, said):
    """The messages of the audit's edits (and a few more): the file, the entry, what it must
    be."""
    import json

    from morphoshell.fitting import load_fit

    record, _, folder = saved_fit
    file = folder / "fit.json"
    file.write_text(json.dumps(_edited({**record, "stop": "Fit_Converged"}, edits)))
    with pytest.raises(ValueError) as exc:
        load_fit(file)
    assert str(exc.value).startswith(f"{file}: {said}"), str(exc.value)


def test_a_fit_json_loads_with_the_kkt_fits_stops_and_a_crossing_at_the_shells_ends(
        saved_fit):
    """What the checks of stop and walls_cross let pass: converged with Ipopt's successes
    (the KKT fit's stop), a contact at the shell's ends, s = 0 and L - P."""
    import json

    from morphoshell.fitting import load_fit

    record, _, folder = saved_fit
    file = folder / "fit.json"
    contact = {"s": [0.0, np.pi - 0.3], "distance": 0.0, "thickness": 0.1}
    for stop in ("Solve_Succeeded", "Solved_To_Acceptable_Level"):
        file.write_text(json.dumps({**record, "stop": stop, "converged": True,
                                    "walls_cross": contact}))
        back = load_fit(file)
        assert back.stop == stop and back.contact.to_dict() == contact


@pytest.mark.parametrize("entry", ["E_fit", "parameters", "fitted", "method", "stop",
                                   "converged", "walls_cross", "message", "constrained"])
def test_a_long_value_is_cut_in_the_message(saved_fit, entry):
    """Audit 23 F4: an entry replaced by a 3000-item list gave a message of 17 000
    characters; one line, the value cut to 80 characters (validate.short)."""
    import json

    from morphoshell.fitting import load_fit

    record, _, folder = saved_fit
    file = folder / "fit.json"
    file.write_text(json.dumps({**record, entry: list(range(3000))}))
    with pytest.raises(ValueError) as exc:
        load_fit(file)
    message = str(exc.value)
    assert message.startswith(f"{file}: ") and "[0, 1, 2, 3," in message, message
    assert len(message) < len(str(file)) + 300 and "\n" not in message, message


def test_a_spec_has_a_label_its_record_reads_back_with():
    """A fit's record is read back with a variant of LABELS only: a spec refuses others."""
    import dataclasses

    spec = volvox_spec("free")
    assert dataclasses.replace(spec, variant="custom").variant == "custom"
    with pytest.raises(ValueError, match=r"variant = 'bogus' must be one of \['flat'"):
        dataclasses.replace(spec, variant="bogus")


FOLD = Path(__file__).resolve().parents[1] / "data" / "volvox_fold.toml"


@pytest.fixture(scope="module")
def fold_fit(tmp_path_factory):
    """(midline CSV, fit) of the documented fold shell's midline (tests/data/volvox_fold.toml:
    a folded Volvox whose walls pass through each other, tests/solvers/test_contact.py),
    fitted by its own variant (unstressed, κ₁ = 1/f₁) from its parameters, 60 nodes: a fit
    that converges onto a shape whose walls cross (E_fit 0)."""
    from morphoshell.fitting import synthetic_midline
    from morphoshell.io import Midline
    from morphoshell.io.problem_files import load_problem

    problem, _ = load_problem(FOLD)
    points = synthetic_midline(problem, nodes=60)
    path = tmp_path_factory.mktemp("fold") / "fold.csv"
    Midline(points[:, 0], points[:, 1], None, 1, ("synthetic",)).to_csv(path)
    return path, fit(volvox_spec("unstressed", start=problem), points, "gradient", nodes=60)


def test_a_fit_whose_walls_cross_says_where_and_its_record_keeps_it(fold_fit, pinned_fit):
    """No fit was looked at for crossing walls (audit 20: only solve(), sweeps, branches and
    ablations were): the fold shell's fit has them 0.065 R apart against a thickness of
    0.166 R, at material points near s = 0.94 and 2.58 (as its solve,
    tests/solvers/test_contact.py); its record keeps the contact and reads back with it; a
    record without the entry (written before it) reads back without one, and one of a fit
    whose walls stay apart has null."""
    import json

    from morphoshell.fitting import FitResult
    from morphoshell.io.problem_files import to_jsonable

    res = fold_fit[1]
    assert res.converged and res.walls_cross and res.contact.overlaps
    assert res.contact.distance < 0.1 < res.contact.thickness
    # (the mesh moves the closest points by about a cell: 0.05 R at 60 nodes)
    assert res.contact.s == pytest.approx((0.94, 2.58), abs=0.05)
    record = json.loads(json.dumps(to_jsonable(res.to_dict())))
    assert record["walls_cross"] == {"s": list(res.contact.s), "distance": res.contact.distance,
                                     "thickness": res.contact.thickness}
    assert FitResult.from_dict(record).contact == res.contact
    # a record written before the check (audit 24 F1: it read back as "checked, clean"):
    # not known, in the table too, and saved again without the entry
    del record["walls_cross"]
    old = FitResult.from_dict(record)
    assert old.walls_cross is None and not old.contact_checked
    assert old.to_dataframe()["walls_cross"].isna().all()
    assert "walls_cross" not in old.to_dict()
    assert pinned_fit[2].to_dict()["walls_cross"] is None and pinned_fit[2].walls_cross is False
    with pytest.raises(ValueError, match=r"^x.json: walls_cross = \{'s': \[1.0\]\} must be null"):
        FitResult.from_dict({**record, "walls_cross": {"s": [1.0]}}, "x.json")


def test_morphoshell_fit_warns_of_a_fitted_shape_whose_walls_cross(fold_fit, tmp_path, caplog):
    """One warning line naming the midline and the variant, in solve()'s words; the JSON's
    walls_cross and the CSV's column say it; the fit converged, so exit status 0."""
    import json
    import logging

    import pandas as pd

    from morphoshell.cli import main

    j, c = tmp_path / "fit.json", tmp_path / "fit.csv"
    with caplog.at_level(logging.WARNING, logger="morphoshell"):
        assert main(["fit", str(midline := fold_fit[0]), "--variant", "unstressed", "--start",
                     str(FOLD), "--nodes", "60", "--json", str(j), "--csv", str(c)]) == 0
    warned = [r.getMessage() for r in caplog.records if "walls pass through" in r.getMessage()]
    assert len(warned) == 1 and warned[0].startswith(
        f"{midline.name}, fitted unstressed shell: the shell's walls pass through each other: "
        f"material points s = "), warned
    assert "no self-contact" in warned[0]
    assert json.loads(j.read_text())["walls_cross"]["distance"] < 0.1
    assert pd.read_csv(c)["walls_cross"].tolist() == [True] * len(fold_fit[1].parameters)


def test_a_fit_that_stopped_short_reads_back_with_how_it_ended(pinned_fit, tmp_path):
    """Audit 21 F15: load_fit of a fit that ran out of evaluations gave stop 'Unknown' (the
    record did not keep it), so a script reading a campaign's records back could not branch
    on it; the record keeps it now.  A record written before (no ``stop``) still loads:
    ``Unknown`` if it did not converge, ``Fit_Converged`` if it did."""
    import json

    from morphoshell.fitting import load_fit
    from morphoshell.io.problem_files import write_json

    spec = pinned_fit[0]
    short = fit(spec, pinned_fit[2].data, "gradient", nodes=60, max_iterations=2)
    assert not short.converged and short.stop == "Maximum_Evaluations_Exceeded"
    for result in (short, pinned_fit[2]):
        write_json(path := tmp_path / "fit.json", result.to_dict())
        assert load_fit(path).stop == result.stop
        record = json.loads(path.read_text())
        del record["stop"]
        path.write_text(json.dumps(record))
        assert load_fit(path).stop == ("Fit_Converged" if result.converged else "Unknown")


def test_a_fit_is_a_table_of_its_parameters_as_fit_csv_writes_it(pinned_fit, tmp_path):
    """Audit 21 F14: the docs said every result converts to a DataFrame and an xarray
    Dataset; a fit had neither.  to_dataframe() is the table of fit --csv (one function,
    FitResult.table): a row per parameter, the fitted first; its unit; fitted or not; on a
    constraint (s2, s3 of this fit: no error); how the fit ended on every row.  to_xarray()
    holds it along `parameter`, with the correlations and both midlines, and survives
    netCDF; the record read back gives the same table."""
    import pandas as pd
    import xarray as xr

    from morphoshell.fitting import load_fit
    from morphoshell.io.problem_files import write_csv, write_json

    res = pinned_fit[2]
    df = res.to_dataframe()
    assert df.parameter.tolist() == [*res.fitted, *(n for n in res.parameters
                                                    if n not in res.fitted)]
    assert df.value.tolist() == [res.parameters[n] for n in df.parameter]
    assert df.fitted.tolist() == [n in res.fitted for n in df.parameter]
    assert df.on_constraint.tolist() == [n in ("s2", "s3") for n in df.parameter]
    assert df.standard_error.isna().tolist() == [n not in res.fitted or n in ("s2", "s3")
                                                 for n in df.parameter]
    units = dict(zip(df.parameter, df.unit))
    assert units["kappa2"] == "1/R" and units["f1"] == "1" and units["s2"] == units["h"] == "R"
    assert (df.E_fit == res.E_fit).all() and df.stop.eq("Fit_Converged").all()
    assert df.converged.all() and not df.walls_cross.any()
    assert df.attrs["units"]["E_fit"] == "R" and df.attrs["variant"] == "free"
    # what fit --csv writes, read back
    written = pd.read_csv(write_csv(tmp_path / "fit.csv", res.table()), keep_default_na=False,
                          na_values=[""])
    pd.testing.assert_frame_equal(written, df, check_dtype=False)
    back = load_fit(write_json(tmp_path / "fit.json", res.to_dict()))
    assert back.to_dataframe().equals(df)
    ds = res.to_xarray()
    assert ds.value.sel(parameter="kappa2") == res.parameters["kappa2"]
    assert ds.unit.sel(parameter="kappa2") == "1/R" and bool(ds.on_constraint.sel(parameter="s3"))
    assert np.array_equal(ds.correlation.values, res.correlation, equal_nan=True)
    assert list(ds.fitted_i.values) == list(res.fitted)
    assert np.array_equal(ds.r_fit.values, res.model[:, 0]) and ds.z_data.attrs["units"] == "R"
    assert ds.attrs["E_fit"] == res.E_fit and ds.attrs["stop"] == "Fit_Converged"
    ds.to_netcdf(tmp_path / "fit.nc")
    assert xr.load_dataset(tmp_path / "fit.nc").identical(ds)


@pytest.fixture(scope="module")
def two_fit():
    """A fit of f1 and kappa1 alone (the rest held) to a synthetic midline, 60 nodes: free
    standard errors, unlike :func:`pinned_fit`'s."""
    from morphoshell.fitting import synthetic_midline

    base = Problem("volvox", h=0.15, opening=0.3)
    hold = {k: v for k, v in base.params.items() if k not in ("f1", "kappa1")}
    data = synthetic_midline(base.with_updates(f1=base.params["f1"] + 0.02), nodes=60)
    return fit(volvox_spec("free", start=base, hold=hold), data, "gradient", nodes=60)


@pytest.fixture(scope="module")
def retraced_fit(two_fit):
    """:func:`two_fit` with the errors of 30 stand-in re-tracings (white noise of 1e-3 R on
    the data midline; one more refused), as morphoshell fit gives a fit of one image trace."""
    from morphoshell.fitting.trace_errors import ReaderErrors, with_trace_errors

    rows = np.random.default_rng(3).normal(0.0, 1e-3, (30, 2 * len(two_fit.data)))
    return with_trace_errors(two_fit, ReaderErrors(rows, 1e-3, ("halves differ",), 3, 0.4))


def test_a_fits_record_says_which_standard_errors_it_holds(two_fit, retraced_fit, tmp_path):
    """Audit 27 F1: morphoshell fit of one image trace wrote its re-tracings' standard errors
    (kappa1 0.24) under the note "standard errors are Gauss-Newton lower bounds", as the API
    fit of the same file wrote its Gauss–Newton ones (0.10): the record, the table, the
    summary and the note now say which (with the re-tracings' count, refused, σ, seed and the
    Gauss–Newton errors they replaced), and read back so."""
    from morphoshell.fitting import load_fit
    from morphoshell.io.problem_files import to_jsonable, write_json

    res = two_fit
    plain, traced = res.to_dict(), retraced_fit.to_dict()
    assert plain["standard_errors_source"] == "gauss-newton" and "re_tracings" not in plain
    assert plain["note"].startswith("standard errors are Gauss-Newton lower bounds")
    assert traced["standard_errors_source"] == "re-tracings"
    assert traced["re_tracings"] == {
        "replicates": 31, "refused": 1, "sigma": 1e-3, "sigma_units": "R", "sigma_px": 0.4,
        "seed": 3, "gauss_newton_errors": plain["standard_errors"]}
    assert "sandwich of 31 re-tracings" in traced["note"] and "seed 3" in traced["note"]
    assert "Gauss-Newton lower bounds" not in traced["note"]
    # (the noiseless data's Gauss–Newton errors are tiny; 1e-3 R of noise gives more)
    assert all(traced["standard_errors"][n] > 10 * plain["standard_errors"][n]
               for n in ("f1", "kappa1")), (traced["standard_errors"], plain["standard_errors"])
    for fit_, source in ((res, "gauss-newton"), (retraced_fit, "re-tracings")):
        assert set(fit_.table()["standard_errors_source"]) == {source}
        assert fit_.to_dataframe().attrs["note"] == fit_.to_dict()["note"]
        assert fit_.to_xarray().attrs["standard_errors_source"] == source
    assert res.summary().splitlines()[1].startswith("  ± Gauss–Newton (lower bounds")
    assert "± from 31 re-tracings (pixel noise 0.001 R = 0.4 px per coordinate, seed 3; 1 " \
           "refused by the reader) of the image trace" in retraced_fit.summary()
    back = load_fit(write_json(tmp_path / "fit.json", traced))
    assert to_jsonable(back.to_dict()) == to_jsonable(traced)
    assert back.standard_errors_source == "re-tracings" and back.summary() == retraced_fit.summary()


def test_a_record_from_before_says_its_standard_errors_source_is_not_known(pinned_fit,
                                                                            retraced_fit):
    """A record without standard_errors_source (written before records said) reads back with
    the source not known (None, empty in the table, a summary line saying so) and writes
    the entry out again, as walls_cross; one whose source disagrees with its re_tracings
    (too many refused for their errors, or none made) is refused naming the entry."""
    from morphoshell.fitting import FitResult

    record = pinned_fit[2].to_dict()
    del record["standard_errors_source"]
    back = FitResult.from_dict(record)
    assert back.standard_errors_source is None and "standard_errors_source" not in back.to_dict()
    assert back.table()["standard_errors_source"][0] is None
    assert "not known to be Gauss–Newton's or the re-tracings'" in back.summary()
    assert back.to_dict()["note"] == record["note"]         # (as the record said)
    with pytest.raises(ValueError, match=r"x.json: standard_errors_source = 're-tracings' "
                                         r"disagrees with no re_tracings entry"):
        FitResult.from_dict({**pinned_fit[2].to_dict(), "standard_errors_source": "re-tracings"},
                            "x.json")
    traced = retraced_fit.to_dict()
    traced["re_tracings"]["refused"] = 20
    with pytest.raises(ValueError, match=r"x.json: standard_errors_source = 're-tracings' "
                                         r"disagrees with re_tracings has 20 of 31 refused"):
        FitResult.from_dict(traced, "x.json")


def test_every_single_edit_of_a_retraced_fit_json_loads_or_is_refused_naming_the_file(
        retraced_fit, tmp_path):
    """The re_tracings entry and standard_errors_source, edited as
    :func:`test_every_single_edit_of_a_fit_json_loads_or_is_refused_naming_the_file` edits
    every entry: the fit loads, or a ValueError of one line names the file."""
    from morphoshell.io.problem_files import to_jsonable

    record = to_jsonable(retraced_fit.to_dict())
    paths = [p for p in _paths(record) if p[:1] in (("re_tracings",), ("standard_errors_source",))]
    assert len(paths) > 10
    for path in paths:
        for edit in _EDITS:
            _loads_or_names_the_file(tmp_path / "edited fit.json", _edited(record, [(path, edit)]))


def test_a_fits_json_has_each_parameters_unit_and_no_nan(pinned_fit):
    """Audit 27 F7: a fit's JSON had no unit per parameter (its CSV had them): ``units`` is
    the table's ``unit`` column (one source).  F11: a campaign's record (no seconds) read back
    wrote ``"seconds": NaN``, which strict JSON readers refuse: null."""
    import json

    from morphoshell.fitting import FitResult

    res = pinned_fit[2]
    table = res.table()
    assert res.to_dict()["units"] == dict(zip(table["parameter"], table["unit"]))
    assert res.to_dict()["units"]["kappa1"] == "1/R" and res.to_dict()["units"]["f1"] == "1"
    record = res.to_dict()
    del record["seconds"]
    back = FitResult.from_dict(record).to_dict()
    assert back["seconds"] is None
    json.dumps(back["seconds"], allow_nan=False)


def test_load_fit_warns_once_of_entries_it_does_not_read(pinned_fit, tmp_path, caplog):
    """As load_equilibrium does (io.provenance.note_unknown, one helper): an entry not in
    results.KNOWN (a hand edit, a newer version's) is named once; every entry to_dict and
    a campaign's record write is known (no warning)."""
    import logging

    from morphoshell.fitting import load_fit
    from morphoshell.fitting.results import KNOWN
    from morphoshell.io.problem_files import write_json

    record = pinned_fit[2].to_dict()
    campaign = {**record, "status": "ok", "fitted_by": "gradient", "timepoint": "t01",
                "state": {}, "held": {}, "previous": None, "embryo_t95": 2.78}
    assert set(campaign) <= set(KNOWN)
    with caplog.at_level(logging.WARNING, logger="morphoshell"):
        load_fit(write_json(tmp_path / "plain.json", campaign))
        assert "not read" not in caplog.text
        for name in ("a.json", "b.json"):
            load_fit(write_json(tmp_path / name, {**record, "zz_load_fit_entry": 1}))
    assert caplog.text.count("zz_load_fit_entry") == 1
    assert "a.json: entries 'zz_load_fit_entry' are not read by load_fit" in caplog.text
