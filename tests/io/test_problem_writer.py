"""A Problem written back as a problem file (io.problem_files.write_problem)."""
import json
import math
from pathlib import Path

import pytest

from morphoshell import Problem
from morphoshell.cli import main
from morphoshell.io import (Settings, example_path, examples, load_problem, problem_toml,
                            write_problem)
from morphoshell.workflows import fitted_problem

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.parametrize("name", examples())
def test_every_example_reads_back_equal(name, tmp_path):
    """Audit 27 F3: no writer existed; a paper's supplementary problem files were hand-made."""
    problem, settings = load_problem(example_path(name))
    back = load_problem(write_problem(tmp_path / f"{name}.toml", problem, settings))
    assert back == (problem, settings)


def test_a_fitted_problem_reads_back_to_the_bit(tmp_path):
    """A fit's parameters are doubles with every digit significant: written by repr, read
    back as the same doubles."""
    fit = tmp_path / "fit.json"
    midline = ROOT / "data" / "synthetic_inversion" / "t01" / "synthetic_average.csv"
    assert main(["fit", str(midline), "--variant", "flat", "--nodes", "20", "--json",
                 str(fit), "-q"]) == 0
    problem = fitted_problem(json.loads(fit.read_text()))
    settings = Settings(nodes=20, stages=3)
    back, back_settings = load_problem(write_problem(tmp_path / "fit.toml", problem, settings))
    assert back == problem and back_settings == settings
    assert all(back.params[k].hex() == float(v).hex() for k, v in problem.params.items())


def test_awkward_numbers_and_words_read_back(tmp_path):
    """Shortest-repr floats (1/3, one ulp above 0.1, an exponent) and a name with quotes,
    a backslash, a non-ASCII letter and control characters."""
    problem = Problem("uniform", {"k": -1 / 3 * 1e-7}, h=math.nextafter(0.1, 1),
                      cut=0.30000000000000004, name='a "b" \\ é\t\x7f')
    back, _ = load_problem(write_problem(tmp_path / "x.toml", problem))
    assert back == problem
    assert back.params["k"] == problem.params["k"] and back.name == problem.name


def test_default_settings_are_written():
    text = problem_toml(Problem("uniform", {"k": 0.5}))
    assert "[solver]\nnodes = 200\nmethod = \"direct\"\nstages = 2\n" in text
    assert math.isclose(float(text.split("k = ")[1].split()[0]), 0.5)
