"""A solve's or ablation's JSON records its solver settings, and is solved again on them."""
import json

import pytest

from morphoshell.cli import main
from morphoshell.io import Settings, load_problem
from morphoshell.io.problem_files import example_path

TOY2 = example_path("toy2_ablation")


@pytest.fixture(scope="module")
def solved(tmp_path_factory):
    """toy2 at 40 nodes, stages 3, --rtol and no continuation (not the defaults)."""
    path = tmp_path_factory.mktemp("solve") / "s.json"
    assert main(["solve", str(TOY2), "--nodes", "40", "--stages", "3", "--rtol", "0.5",
                 "--no-continuation", "--json", str(path), "-q"]) == 0
    return path


def test_the_settings_that_change_the_numbers_are_recorded(solved):
    """Audit 27 F2: stages, rtol and the linear solver were not in the solve JSON."""
    assert json.loads(solved.read_text())["settings"] == {
        "nodes": 40, "method": "direct", "stages": 3, "rtol": 0.5, "max_nodes": None,
        "linear_solver": "mumps", "continuation": False}
    assert load_problem(solved)[1] == Settings(nodes=40, method="direct", stages=3)


def test_solving_the_json_again_uses_its_nodes_and_stages(solved, tmp_path, capsys):
    """Audit 27 F2: it was solved at 200 nodes, stages 2 (other numbers, no note)."""
    again = tmp_path / "again.json"
    assert main(["solve", str(solved), "--json", str(again)]) == 0
    assert f"{solved}: solved on 40 nodes (as recorded), stages 3 (as recorded)" in \
        capsys.readouterr().out
    first, second = json.loads(solved.read_text()), json.loads(again.read_text())
    assert len(second["s"]) == len(first["s"]) == 3 * 39 + 1
    assert second["error_estimate"]["order"] == 6
    assert main(["solve", str(solved), "--nodes", "30"]) == 0
    assert "solved on 30 nodes (--nodes), stages 3 (as recorded)" in capsys.readouterr().out


def test_a_json_without_settings_is_said_to_be_solved_by_the_defaults(solved, tmp_path,
                                                                       capsys):
    record = json.loads(solved.read_text())
    del record["settings"]
    old = tmp_path / "old.json"
    old.write_text(json.dumps(record))
    assert load_problem(old)[1] == Settings()
    assert main(["solve", str(old), "--nodes", "20"]) == 0
    out = capsys.readouterr().out
    assert "solved on 20 nodes (--nodes), stages 2 (the default); the file records no " \
           "solver settings" in out


def test_an_ablations_json_records_them_too(tmp_path):
    path = tmp_path / "a.json"
    assert main(["ablate", str(TOY2), "--nodes", "30", "--stages", "1", "--json", str(path),
                 "-q"]) == 0
    assert json.loads(path.read_text())["settings"]["stages"] == 1
    assert load_problem(path)[1] == Settings(nodes=30, stages=1)
