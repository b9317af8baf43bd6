"""Bad input fails before any work starts, with a message naming the value."""
import math

import pytest

from morphoshell import Problem
from morphoshell.solvers.routes import DirectSolver, solve
from morphoshell.io.problem_files import ProblemFileError, apply_overrides, load_problem, parse_overrides


@pytest.mark.parametrize("kwargs, message", [
    ({"h": -0.1}, "thickness h = -0.1"),
    ({"h": 0.0}, "thickness h = 0.0"),
    ({"h": 1.5}, "thickness h = 1.5"),
    ({"h": math.nan}, "thickness h = nan"),
    ({"h": "thin"}, "thickness h = 'thin'"),
    ({"cut": 3.5}, "cut (Sigma) = 3.5 is larger than the shell"),
    ({"cut": 2.0, "opening": 1.2}, "cut (Sigma) = 2.0 is larger than the shell"),
    ({"cut": -0.1}, "cut (Sigma) = -0.1 must be non-negative"),
    ({"opening": -0.3}, "opening (P) = -0.3 must be non-negative"),
    # was "cut (Sigma) = 0.0 is larger than the shell" (audit 3, #14)
    ({"opening": 3.2}, "opening (P) = 3.2 is larger than the shell: the sphere's meridian is"),
    ({"cut": math.inf}, "cut (Sigma) = inf must be finite"),
    ({"theory": "kirchhoff"}, "unknown theory 'kirchhoff'"),
    ({"family": "nonesuch"}, "unknown profile family 'nonesuch'"),
    ({"geometry": "torus"}, "unknown geometry 'torus'"),
    ({"params": {"k": math.nan}}, "parameter k = nan must be finite"),
    ({"params": {"kappa": 1.0}}, "unknown parameter(s) ['kappa'] for family 'uniform'"),
])
def test_problem_rejects(kwargs, message):
    kwargs = {"family": "uniform", "h": 0.1, **kwargs}
    with pytest.raises(ValueError) as exc:
        Problem(**kwargs)
    assert message in str(exc.value)


def test_eta_at_least_one_is_rejected():
    # eta = k h / 2 = 10 * 0.3 / 2 = 1.5
    with pytest.raises(ValueError, match=r"abs\(eta\) = 1.5 >= 1 at s = "):
        Problem("uniform", {"k": 10.0}, h=0.3)
    # exactly at the limit: eta = 1
    with pytest.raises(ValueError, match=r"abs\(eta\) = 1 >= 1"):
        Problem("uniform", {"k": 4.0}, h=0.5)


def test_unordered_breakpoints_are_rejected():
    with pytest.raises(ValueError, match=r"got s2 = 1.5 >= s3 = 1.4"):
        Problem("volvox", {"s2": 1.5, "s3": 1.4}, h=0.15, opening=0.3)
    with pytest.raises(ValueError, match=r"s4 = 2.9 must lie before the shell's end"):
        Problem("volvox", {"s4": 2.9}, h=0.15, opening=0.3)
    with pytest.raises(ValueError, match=r"breakpoint s1 = -0.1 must be positive"):
        Problem("volvox", {"s1": -0.1}, h=0.15, opening=0.3)


def test_family_specific_values_are_rejected():
    # (audit: f0 = -1 was told "must exceed -1", f0 = -0.99 "must lie in [-0.9, 9]"; s0 = 0
    # "must be positive", s0 = 100 "must lie in [0, 6.28319]": one bound each, 0 excluded)
    for f0 in (-1.0, -0.99):
        with pytest.raises(ValueError, match=rf"f0 = {f0!r} must lie in \[-0.9, 9\] "):
            Problem("anisotropic", {"f0": f0}, h=0.1)
    for s0 in (0.0, -0.1, 100.0):
        with pytest.raises(ValueError, match=rf"parameter s0 = {s0!r} must lie in "
                                             rf"\(0, 6.28319\] \(width"):
            Problem("local_relaxation", {"s0": s0}, h=0.1, cut=0.3)
    with pytest.raises(ValueError, match=r"F0 = -1.0 must lie in \[-0.9, 9\] "):
        Problem("local_relaxation", {"F0": -1.0}, h=0.1, cut=0.3)
    with pytest.raises(ValueError, match=r"parameter f3 = -0.2 must be positive"):
        Problem("volvox", {"f3": -0.2}, h=0.15, opening=0.3)


def test_solver_arguments_are_checked():
    problem = Problem("uniform", h=0.1)
    with pytest.raises(ValueError, match=r"nodes = 3 must be an integer in \[5, 102400\]"):
        DirectSolver(problem.structure, nodes=3)
    with pytest.raises(ValueError, match=r"unknown method 'shoot'"):
        solve(problem, method="shoot")
    solver = DirectSolver(problem.structure, nodes=50)
    with pytest.raises(ValueError, match=r"this solver is built for"):
        solver.solve(Problem("uniform", h=0.1, cut=0.2))


def _write(tmp_path, text, name="p.toml"):
    path = tmp_path / name
    path.write_text(text)
    return path


GOOD = """
[problem]
family = "uniform"
h = 0.3
cut = 0.3
[parameters]
k = 0.0
"""


@pytest.mark.parametrize("text, message", [
    ("[problem\nfamily = 1", "not valid TOML"),
    ("[parameters]\nk = 0.0\n", "missing the [problem] table"),
    ("[problem]\nh = 0.3\n", "[problem] needs 'family'"),
    ("[problem]\nfamily = 'uniform'\nh = 0.3\nthickness = 2\n", "unknown key(s) ['thickness'] in [problem]"),
    ("[problem]\nfamily = 'uniform'\nh = 0.3\n[mesh]\nnodes = 3\n", "unknown table(s) ['mesh']"),
    ("family = 'uniform'\nh = 0.3\n[parameters]\nk = 0.0\n",
     "key(s) ['family', 'h'] outside any table; is the [problem] line above them missing?"),
    ("[problem]\nfamily = 'uniform'\nh = '0.3'\n", "thickness h = '0.3' must be a real number"),
    ("[problem]\nfamily = 3\nh = 0.3\n", "family = 3 must be a string"),
    (GOOD + "[solver]\nnodes = 2\n", "nodes = 2 must be an integer in [5, 102400]"),
    (GOOD + "[solver]\nmethod = 'magic'\n", "method = 'magic' must be one of"),
    (GOOD + "[solver]\ntolerance = 1\n", "unknown key(s) ['tolerance'] in [solver]"),
    (GOOD.replace("k = 0.0", "k = 0.0\nf0 = 1"), "unknown parameter(s) ['f0']"),
    ("problem = 3\n", "'problem' must be a table"),
])
def test_malformed_files(tmp_path, text, message):
    path = _write(tmp_path, text)
    with pytest.raises(ProblemFileError) as exc:
        load_problem(path)
    assert message in str(exc.value) and str(path) in str(exc.value)


def test_missing_file(tmp_path):
    with pytest.raises(ProblemFileError, match="cannot read problem file"):
        load_problem(tmp_path / "nope.toml")


def test_overrides(tmp_path):
    problem, _ = load_problem(_write(tmp_path, GOOD))
    assert apply_overrides(problem, parse_overrides(["k=0.5", "theory=classical"])).params["k"] == 0.5
    with pytest.raises(ProblemFileError, match=r"unknown key\(s\) \['f0'\] for family 'uniform'"):
        apply_overrides(problem, parse_overrides(["f0=0.1"]))
    with pytest.raises(ProblemFileError, match=r"k needs a number, got 'big'"):
        parse_overrides(["k=big"])
    with pytest.raises(ProblemFileError, match=r"expected KEY=VALUE"):
        parse_overrides(["k"])
    with pytest.raises(ProblemFileError, match=r"thickness h = -1.0"):
        apply_overrides(problem, parse_overrides(["h=-1"]))
