"""Examples in the package, --verbose/--quiet, the one name of the cut, defaulted parameters."""
import json
import logging
import re
import warnings

import pytest

import morphoshell
from morphoshell.mechanics import asymptotics as A
from morphoshell.cli import main
from morphoshell.io.problem_files import (ProblemFileError, example_path, example_text, examples, load_problem,
                            parse_overrides)

EXAMPLES = ("blister", "fast_relaxation", "toy1_sphere", "toy2_ablation", "toy3_anisotropic",
            "volvox_fold", "volvox_inversion")


# --------------------------------------------------------------------------
# the packaged examples
# --------------------------------------------------------------------------

def test_examples_ship_in_the_package_and_load():
    assert tuple(examples()) == EXAMPLES
    for name, what in examples().items():
        path = example_path(name)
        assert path.parent.name == "examples" and path.parent.parent.name == "morphoshell"
        assert what                                  # every example describes itself
        problem, _ = load_problem(path)
        assert problem.name == name
    with pytest.raises(ValueError, match="unknown example 'nope'; choose one of"):
        example_path("nope")


def test_example_command_prints_a_file_to_start_from(tmp_path, capsys):
    assert main(["example", "toy2_ablation"]) == 0
    text = capsys.readouterr().out
    assert text == example_text("toy2_ablation")
    mine = tmp_path / "mine.toml"
    mine.write_text(text)
    problem, _ = load_problem(mine)
    assert problem.family == "uniform" and problem.cut == 0.3 and problem.name == "mine"
    assert main(["example", "--list"]) == 0
    listing = capsys.readouterr().out
    assert all(name in listing for name in EXAMPLES) and "Toy problem 2" in listing
    assert main(["example", "nope"]) == 2
    assert "unknown example 'nope'" in capsys.readouterr().err


def test_common_entry_points_at_the_top_level():
    for name in ("Problem", "solve", "ablate", "estimate", "load_problem", "ProfileFamily",
                 "register_family", "examples", "example_path", "Equilibrium", "Ablation",
                 "DirectSolver", "Parametric", "SolverError"):
        assert name in morphoshell.__all__ and callable(getattr(morphoshell, name)), name
    assert re.fullmatch(r"\d+\.\d+\.\d+", morphoshell.__version__)


# --------------------------------------------------------------------------
# --verbose / --quiet through logging
# --------------------------------------------------------------------------

def _without_parameters(tmp_path):
    path = tmp_path / "bare.toml"
    path.write_text('[problem]\nfamily = "uniform"\nh = 0.3\ncut = 0.3\n')
    return path


def test_a_file_without_parameters_says_which_defaults_it_uses(tmp_path, caplog):
    with caplog.at_level(logging.INFO, logger="morphoshell"):
        problem, _ = load_problem(_without_parameters(tmp_path))
    assert problem.params == {"k": 0.0}
    [record] = [r for r in caplog.records if r.name == "morphoshell.io.problem_files"]
    assert record.levelno == logging.WARNING
    assert "has no [parameters] table: using the defaults of family 'uniform': k = 0" in \
        record.getMessage()
    # a table that leaves some parameters out: an info note naming them
    part = tmp_path / "part.toml"
    part.write_text('[problem]\nfamily = "local_relaxation"\nh = 0.3\ncut = 0.3\n'
                    '[parameters]\nF0 = 0.2\n')
    caplog.clear()
    with caplog.at_level(logging.INFO, logger="morphoshell"):
        load_problem(part)
    [record] = caplog.records
    assert record.levelno == logging.INFO and "s0 = 0.2" in record.getMessage()


def test_quiet_silences_warnings_and_verbose_shows_notes(tmp_path, capsys):
    bare = _without_parameters(tmp_path)
    assert main(["solve", str(bare), "--nodes", "40"]) == 0
    err = capsys.readouterr().err
    assert "morphoshell: warning: " in err and "no [parameters] table" in err
    for argv in (["-q", "solve", str(bare), "--nodes", "40"],
                 ["solve", str(bare), "--nodes", "40", "--quiet"]):
        assert main(argv) == 0
        captured = capsys.readouterr()
        assert captured.err == "" and "energy" in captured.out
    assert main(["solve", str(bare), "--nodes", "40", "-vv"]) == 0
    err = capsys.readouterr().err
    assert "morphoshell [continuation]: continuation to bare: tau = 1 reached" in err
    assert main(["-v", "-q", "solve", str(bare)]) == 2       # one or the other
    # nothing stays configured after main returns
    logger = logging.getLogger("morphoshell")
    assert logger.level == logging.NOTSET and not logger.handlers


# --------------------------------------------------------------------------
# one name for the cut: cut (Sigma and --cut-angle are deprecated aliases)
# --------------------------------------------------------------------------

def test_sigma_in_problem_files_and_set_is_a_deprecated_alias_of_cut(tmp_path, caplog):
    path = tmp_path / "old.toml"
    path.write_text('[problem]\nfamily = "uniform"\nh = 0.3\nSigma = 0.4\n[parameters]\nk = 0\n')
    with caplog.at_level(logging.WARNING, logger="morphoshell"):
        problem, _ = load_problem(path)
        over = parse_overrides(["Sigma=0.2"])
    assert problem.cut == 0.4 and over == {"cut": 0.2}
    messages = [r.getMessage() for r in caplog.records]
    assert any("'Sigma' is deprecated, call it 'cut'" in m for m in messages)
    assert any("--set Sigma=0.2: 'Sigma' is deprecated, call it 'cut'" in m for m in messages)
    both = tmp_path / "both.toml"
    both.write_text('[problem]\nfamily = "uniform"\nh = 0.3\ncut = 0.1\nSigma = 0.4\n')
    with pytest.raises(ProblemFileError, match="gives both 'cut' and its deprecated alias"):
        load_problem(both)


def test_asymptotics_takes_cut_and_the_deprecated_cut_angle(tmp_path, capsys):
    out = tmp_path / "a.json"
    assert main(["asymptotics", "--h", "0.01", "--k", "0", "--cut", "0.5", "--json", str(out)]) == 0
    text = capsys.readouterr()
    assert "cut Sigma = 0.5 rad" in text.out and text.err == ""
    assert re.search(r"rotation +=.* rad", text.out) and "(dimensionless" in text.out
    assert json.loads(out.read_text())["cut"] == 0.5
    assert main(["asymptotics", "--h", "0.01", "--k", "0", "--cut-angle", "0.5"]) == 0
    assert "--cut-angle is deprecated, use --cut" in capsys.readouterr().err
    assert main(["asymptotics", "--h", "0.01", "--k", "0"]) == 2
    assert "one of the arguments --cut --cut-angle is required" in capsys.readouterr().err


def test_asymptotic_functions_take_cut_and_warn_for_sigma():
    assert A.opening(0.01, 0.0, cut=0.5) == A.opening(0.01, 0.0, 0.5)
    with pytest.warns(DeprecationWarning, match="Sigma=...\\) is deprecated"):
        assert A.predictions(0.01, 0.0, Sigma=0.5) == A.predictions(0.01, 0.0, 0.5)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        A.rotation_small_cut(0.01, 0.0, 0.5)            # no warning for the one name


# --------------------------------------------------------------------------
# units on every printed quantity
# --------------------------------------------------------------------------

_NUMBER = r"[-+]?\d[\d.]*(?:e[-+]?\d+)?"


@pytest.mark.parametrize("argv", [
    ["solve", str(example_path("toy2_ablation")), "--nodes", "40"],
    ["ablate", str(example_path("toy2_ablation")), "--nodes", "40"],
    ["asymptotics", "--h", "0.01", "--k", "0", "--cut", "0.5"],
    ["sphere", "--h", "0.01", "--k", "2"],
], ids=lambda a: a[0])
def test_every_printed_quantity_has_a_unit(argv, capsys):
    assert main(argv) == 0
    for line in capsys.readouterr().out.splitlines():
        for match in re.finditer(rf"= ({_NUMBER})(.?\S*)", line):
            after = line[match.end(1):].strip()
            assert after and not after.startswith(","), f"no unit in {line!r}"


def test_ablate_csv_keeps_the_far_end_opening_apart_from_the_observable(tmp_path):
    import csv

    out = tmp_path / "a.csv"
    assert main(["ablate", str(example_path("toy2_ablation")), "--nodes", "40",
                 "--set", "opening=0.2", "--csv", str(out)]) == 0
    [row] = list(csv.DictReader(out.open()))
    assert float(row["opening_P"]) == 0.2 and float(row["cut"]) == 0.3
    assert 0 < float(row["opening"]) < 0.2 and float(row["rotation"]) > 0


def test_progress_bars_show_on_a_terminal_unless_quiet(monkeypatch):
    import io

    from morphoshell._runtime.console import configure, progress

    class Terminal(io.StringIO):
        def isatty(self):
            return True

    term = Terminal()
    monkeypatch.setattr("sys.stderr", term)
    items = [1, 2, 3]
    assert progress(items) is not items                      # a bar: stderr is a terminal
    assert list(progress(items, desc="cuts")) == items and "cuts" in term.getvalue()
    restore = configure(-1)                                  # --quiet
    try:
        assert progress(items) is items
    finally:
        restore()
    monkeypatch.setattr("sys.stderr", io.StringIO())         # not a terminal: no bar
    assert progress(items) is items
    assert progress(items, enabled=True) is not items


def test_outputs_have_the_permissions_of_a_new_file(tmp_path, capsys):
    """Outputs are written beside their target by mkstemp (mode 0600) and renamed: they kept
    that mode, unreadable to colleagues on a shared disk whatever the umask (user audit)."""
    import os

    old = os.umask(0o022)
    try:
        out = [tmp_path / "eq.json", tmp_path / "eq.csv"]
        assert main(["solve", str(example_path("toy1_sphere")), "--nodes", "20",
                     "--json", str(out[0]), "--csv", str(out[1])]) == 0
        os.umask(0o027)
        out.append(tmp_path / "again.json")
        assert main(["solve", str(example_path("toy1_sphere")), "--nodes", "20",
                     "--json", str(out[2])]) == 0
    finally:
        os.umask(old)
    assert [p.stat().st_mode & 0o777 for p in out] == [0o644, 0o644, 0o640]


def test_counted_progress_bars_show_on_a_terminal_of_the_main_process_only(monkeypatch):
    """counter(): a bar counted by hand (Nelder-Mead's evaluations, the profiles' refits),
    shown when progress() would be, and not in a worker process (a campaign's workers share
    its terminal: one bar each would garble it)."""
    import io
    import multiprocessing

    from morphoshell._runtime.console import configure, counter

    class Terminal(io.StringIO):
        def isatty(self):
            return True

    term = Terminal()
    monkeypatch.setattr("sys.stderr", term)
    with counter(5, desc="fits", unit="fit") as bar:
        bar.update(3)
        assert bar.n == 3                                    # a tqdm bar
    assert "fits:" in term.getvalue() and "/5" in term.getvalue()
    restore = configure(-1)                                  # --quiet
    try:
        with counter(5) as bar:
            assert not hasattr(bar, "n")
    finally:
        restore()
    with monkeypatch.context() as worker:
        worker.setattr(multiprocessing, "parent_process", lambda: object())
        with counter(5) as bar:
            assert not hasattr(bar, "n")
            bar.update(2)                                    # (does nothing)
    monkeypatch.setattr("sys.stderr", io.StringIO())         # not a terminal
    with counter(5) as bar:
        assert not hasattr(bar, "n")


def test_a_fit_without_plots_imports_no_matplotlib(tmp_path):
    # matplotlib's import was a fifth of a command-line gradient fit (0.4 of 1.8 s)
    import subprocess
    import sys
    from pathlib import Path
    data = (Path(__file__).resolve().parents[2] / "data" / "synthetic_inversion" / "t01"
            / "synthetic_average.csv")
    run = (f"from morphoshell.cli import main; main(['fit', {str(data)!r}, '--variant', "
           f"'flat', '--nodes', '40', '--max-evaluations', '2', '--json', "
           f"{str(tmp_path / 'fit.json')!r}])")
    code = f"import sys; {run}; print('matplotlib' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True)
    assert (tmp_path / "fit.json").exists()
    assert out.stdout.strip().splitlines()[-1] == "False"


def test_a_reader_that_leaves_the_pipe_does_not_lose_the_files(tmp_path):
    # `morphoshell sweep ... --csv out.csv | head -1`: the table was printed before the files
    # were written, and the closed pipe's BrokenPipeError ended the command without them
    import subprocess
    import sys
    from pathlib import Path
    toy2 = Path(__file__).resolve().parents[2] / "problems" / "toy2_ablation.toml"
    out = tmp_path / "sweep.csv"
    run = subprocess.Popen([sys.executable, "-c", "from morphoshell.cli import main; "
                            "raise SystemExit(main())", "sweep", str(toy2), "--set",
                            "k=0:1:5", "--nodes", "40", "--csv", str(out)],
                           stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    run.stdout.close()              # the reader left before the first line
    err = run.stderr.read().decode()
    assert run.wait(timeout=120) == 0, err
    assert "Traceback" not in err and "Exception ignored" not in err, err
    assert len(out.read_text().splitlines()) == 6
