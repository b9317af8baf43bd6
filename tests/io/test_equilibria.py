"""Saved equilibria read back (io.equilibria)."""
import json

import numpy as np
import pytest

from morphoshell import Problem, solve
from morphoshell.io.equilibria import equilibrium_of_record, load_equilibrium
from morphoshell.solvers.results import FIELDS

SHELL = Problem("uniform", {"k": 1.5}, h=0.1, cut=0.3)


@pytest.fixture(scope="module")
def saved():
    eq = solve(SHELL, nodes=60)
    return eq, json.loads(json.dumps(eq.to_dict()))      # (through JSON text, as a file)


def test_a_saved_solution_reads_back_field_for_field(saved):
    """Every field, the energy and the solver record come back as written (a user audit:
    to_dict had no inverse, so a saved result could not be re-analysed or restarted)."""
    eq, record = saved
    back = equilibrium_of_record(record)
    assert back.problem == eq.problem and back.energy == eq.energy
    for key in FIELDS:
        assert np.array_equal(getattr(back, key), getattr(eq, key)), key
    assert back.solver.status == eq.solver.status and back.solver.nodes == eq.solver.nodes
    assert back.x is None                                     # not saved: said in the docs
    assert back.error == eq.error and back.to_dict() == eq.to_dict()


def test_a_saved_error_estimate_is_kept_also_one_that_was_unavailable(saved):
    """to_dict writes error_estimate, which the reader dropped (a user audit): it is
    rebuilt as written, also an unavailable one (NaN errors, null in a file, and its note),
    and on a stress-free shell with that shell's energy floor."""
    import math
    from dataclasses import replace

    from morphoshell.io.problem_files import to_jsonable
    from morphoshell.solvers.refinement import estimate

    eq = saved[0]
    none = replace(eq, error=estimate(eq, None, 4, "the half mesh failed"))
    back = equilibrium_of_record(json.loads(json.dumps(to_jsonable(none.to_dict()))))
    assert back.error.note == "the half mesh failed"
    assert all(map(math.isnan, back.error.errors.values()))
    flat = solve(SHELL.with_updates(k=1.0), nodes=40)             # (stress free: floor h)
    back = equilibrium_of_record(json.loads(json.dumps(flat.to_dict())))
    assert back.error == flat.error and back.error.energy_floor == SHELL.h


def test_a_saved_solution_starts_a_solve_on_its_branch(saved):
    """As a warm start it is carried onto the mesh (another route's result): the same
    minimum to the solver's tolerance (energy 1e-12 relative) in a few Newton steps."""
    eq, record = saved
    again = solve(SHELL, nodes=60, warm_start=equilibrium_of_record(record))
    assert again.energy == pytest.approx(eq.energy, rel=1e-12)
    assert again.solver.iterations <= 3


def test_the_command_lines_json_reads_back(tmp_path):
    from morphoshell.cli import main
    from morphoshell.io.problem_files import example_path

    path = tmp_path / "toy2.json"
    assert main(["solve", str(example_path("toy2_ablation")), "--nodes", "40",
                 "--json", str(path)]) == 0
    back = load_equilibrium(path)
    assert back.problem.name == "toy2_ablation" and back.energy == json.loads(
        path.read_text())["energy"]


@pytest.mark.parametrize("change, said", [
    (lambda r: r.pop("psi"), "no psi: a result saved without its arrays"),
    (lambda r: r.update(r=r["r"][:-1]), "the fields have different lengths"),
    (lambda r: r.update(s=r["s"][::-1]), "s must increase"),
    (lambda r: r.update(z="abc"), "z is not a list of numbers"),
])
def test_a_broken_record_is_refused_naming_the_entry(saved, change, said):
    record = json.loads(json.dumps(saved[1]))
    change(record)
    with pytest.raises(ValueError, match=said):
        equilibrium_of_record(record, "x.json")


def test_a_fits_record_is_named_as_one(tmp_path):
    """A user audit: a fit's JSON was refused as "a result saved without its arrays
    (to_dict(arrays=False))", which points the wrong way."""
    path = tmp_path / "fit.json"
    path.write_text(json.dumps({"problem": SHELL.describe(), "parameters": {"k": 1.5},
                                "E_fit": 1e-3, "fitted": ["k"]}))
    with pytest.raises(ValueError, match=r"fit.json is a fit's record \(keys parameters, "
                                         r"E_fit\).*load_fit.*fitted_problem"):
        load_equilibrium(path)


def test_a_file_that_is_not_a_result_is_named(tmp_path):
    path = tmp_path / "bad.json"
    path.write_text("{not json")
    with pytest.raises(ValueError, match="bad.json: not valid JSON"):
        load_equilibrium(path)


@pytest.mark.parametrize("command, said", [
    (["sweep", "--set", "k=1.5,2"],
     r"x.json is a sweep's JSON \(keys axes, rows\), not an equilibrium's: .*morphoshell solve "
     r"PROBLEM --set KEY=VALUE --json"),
    (["continue", "--param", "k", "--to", "1.55"],
     r"x.json is a branch's JSON \(keys parameter, points\), not an equilibrium's: .*"
     r"follow_branch\(\.\.\.\)\.points\[i\]\.equilibrium"),
])
def test_a_sweeps_or_a_branchs_json_is_named_as_one(tmp_path, command, said):
    """Audit 17 F5: the JSON of sweep and continue was refused as "a result saved without
    its arrays (to_dict(arrays=False))"; it is a table of values, and the message says so
    and where a shape comes from instead, as it does for a fit's."""
    from morphoshell.cli import main
    from morphoshell.io.problem_files import example_path

    path = tmp_path / "x.json"
    main([command[0], str(example_path("toy2_ablation")), *command[1:], "--nodes", "40",
          "--json", str(path)])
    with pytest.raises(ValueError, match=said):
        load_equilibrium(path)


@pytest.fixture(scope="module")
def ablation_file(tmp_path_factory):
    """``ablate --json`` of SHELL: both states (the Ablation's to_dict, as the CLI writes)."""
    from morphoshell.cli import main
    from morphoshell.io.problem_files import example_path

    path = tmp_path_factory.mktemp("abl") / "abl.json"
    assert main(["ablate", str(example_path("toy2_ablation")), "--nodes", "40", "--json",
                 str(path), "-q"]) == 0
    return path


@pytest.mark.parametrize("which", ["pre", "post"])
def test_either_state_of_an_ablations_json_reads_back(ablation_file, which):
    """Audit 27 F8: an ablation's JSON holds both equilibria with their arrays, but was
    refused as "saved without its arrays"; ``which`` reads either back as written."""
    record = json.loads(ablation_file.read_text())[which]
    back = load_equilibrium(ablation_file, which)
    assert back.to_dict() == record
    assert back.energy == record["energy"] and len(back.s) == len(record["s"])


@pytest.mark.parametrize("which, said", [
    (None, r"abl.json is an ablation's JSON \(keys pre, post\), not an equilibrium's: .*"
           r"which='pre'.*which='post'"),
    ("intact", r"which='intact': the state of an ablation's JSON is one of 'pre', 'post'"),
])
def test_an_ablations_json_needs_which_state(ablation_file, which, said):
    with pytest.raises(ValueError, match=said):
        load_equilibrium(ablation_file, which)


def test_which_is_refused_for_a_file_of_one_equilibrium(saved, tmp_path):
    path = tmp_path / "one.json"
    path.write_text(json.dumps(saved[1]))
    with pytest.raises(ValueError, match=r"one.json: which='pre' reads a state of an "
                                         r"ablation's JSON .*leave which out"):
        load_equilibrium(path, "pre")


def test_an_entry_the_reader_does_not_know_is_warned_of(tmp_path, ablation_file, caplog):
    """Audit 27 F5: an entry added by hand (or by a newer version) was ignored silently;
    the files solve and ablate write have none."""
    import logging

    from morphoshell.cli import main
    from morphoshell.io.problem_files import example_path

    solved = tmp_path / "s.json"
    assert main(["solve", str(example_path("toy2_ablation")), "--nodes", "20", "--json",
                 str(solved), "-q"]) == 0
    with caplog.at_level(logging.WARNING, logger="morphoshell"):
        load_equilibrium(solved)
        load_equilibrium(ablation_file, "pre")
        load_equilibrium(ablation_file, "post")
    assert "not read by" not in caplog.text
    record = json.loads(solved.read_text())
    edited = tmp_path / "edited.json"
    edited.write_text(json.dumps({**record, "zz_energy_note": "doubled"}))
    with caplog.at_level(logging.WARNING, logger="morphoshell"):
        load_equilibrium(edited)
    assert "edited.json: entries 'zz_energy_note' are not read by load_equilibrium" in \
        caplog.text
