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
    assert back.x is None and back.error is None              # not saved: said in the docs


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


def test_a_file_that_is_not_a_result_is_named(tmp_path):
    path = tmp_path / "bad.json"
    path.write_text("{not json")
    with pytest.raises(ValueError, match="bad.json: not valid JSON"):
        load_equilibrium(path)
