"""The command line, as scripts and users call it."""
import json
import math
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from morphoshell.cli import main
from morphoshell.io.problem_files import example_path

ROOT = Path(__file__).resolve().parents[2]
TOY2 = example_path("toy2_ablation")


def test_solve_writes_json_and_plot(tmp_path, capsys):
    out, png = tmp_path / "r.json", tmp_path / "r.png"
    assert main(["solve", str(TOY2), "--set", "k=0.5", "--nodes", "400",
                 "--json", str(out), "--plot", str(png)]) == 0
    data = json.loads(out.read_text())
    assert data["converged"] is True
    assert data["problem"]["params"] == {"k": 0.5}
    assert set(data["solver"]) >= {"method", "iterations", "seconds"}
    assert data["solver"]["method"] == "direct" and data["solver"]["iterations"] > 0
    s = np.array(data["s"])
    assert len(s) == 2 * 399 + 1 and np.all(np.diff(s) > 0)   # nodes and cell midpoints and abs(s[0] - 0.3) < 1e-12
    for key in ("r", "z", "psi"):
        assert len(data[key]) == len(s)
    assert np.isfinite(data["energy"]) and data["energy"] > 0
    # units, as a sweep's JSON has them: every field's (also at the edges), the energy's
    assert set(data["units"]) >= set(data["edge_start"]) | {"energy", "h", "cut", "opening"}
    assert data["units"]["M_s"] == "C R" and data["units"]["energy"] == "C R^2"
    assert png.stat().st_size > 10_000
    assert "energy" in capsys.readouterr().out


def test_bvp_method_from_the_command_line(tmp_path):
    out = tmp_path / "b.json"
    assert main(["solve", str(TOY2), "--method", "bvp", "--json", str(out)]) == 0
    direct = tmp_path / "d.json"
    assert main(["solve", str(TOY2), "--nodes", "400", "--json", str(direct)]) == 0
    b, d = json.loads(out.read_text()), json.loads(direct.read_text())
    assert b["solver"]["method"] == "bvp"
    # same problem by two routes: 3200 nodes give ~2e-7 relative (order 2)
    assert abs(b["energy"] / d["energy"] - 1) < 1e-6


@pytest.mark.parametrize("args, message", [
    (["--set", "kappa=1"], "unknown key(s) ['kappa']"),
    (["--set", "k=abc"], "k needs a number, got 'abc'"),
    (["--set", "h=-0.2"], "thickness h = -0.2"),
    (["--set", "cut=4"], "cut (Sigma) = 4.0 is larger than the shell"),
    (["--nodes", "2"], "argument --nodes: 2 must lie in [5, 102400]"),
])
def test_bad_arguments_exit_nonzero_naming_them(args, message, capsys):
    assert main(["solve", str(TOY2), *args]) == 2
    assert message in capsys.readouterr().err


def test_missing_file_exits_2(tmp_path, capsys):
    assert main(["solve", str(tmp_path / "none.toml")]) == 2
    assert "cannot read problem file" in capsys.readouterr().err


def test_help_documents_every_option():
    proc = subprocess.run([sys.executable, "-m", "morphoshell.cli", "solve", "--help"],
                          capture_output=True, text=True, check=True)
    for option in ("--set", "--nodes", "--stages", "--method", "--linear-solver", "--json",
                   "--plot", "KEY=VALUE", "direct", "bvp", "mumps"):
        assert option in proc.stdout


def test_metavars_say_what_a_value_is():
    """Not the option's name again (``--h H``, ``--k K``) nor a letter of no meaning
    (``--c10 A``): the help reads ``--h THICKNESS``, ``--c10 MODULUS``."""
    import argparse

    from morphoshell.cli import build_parser

    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    echoes = [f"{name} {option} {action.metavar}" for name, command in sub.choices.items()
              for action in command._actions for option in action.option_strings
              if action.metavar == option.lstrip("-").upper().replace("-", "_")]
    assert not echoes
    help_text = sub.choices["sphere"].format_help()
    assert "--h THICKNESS" in help_text and "--k CURVATURE" in help_text
    assert "--c10 MODULUS" in help_text and "--c01 MODULUS" in help_text


def test_console_script_runs(tmp_path):
    exe = Path(sys.executable).with_name("morphoshell")
    proc = subprocess.run([str(exe), "solve", str(TOY2), "--nodes", "200"],
                          capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    assert "Solve_Succeeded" in proc.stdout or "Newton_Converged" in proc.stdout


def test_ablate_reports_observables(tmp_path, capsys):
    out, png = tmp_path / "a.json", tmp_path / "a.png"
    assert main(["ablate", str(TOY2), "--json", str(out), "--plot", str(png)]) == 0
    assert png.stat().st_size > 10_000      # the pre/post cross-section pair
    data = json.loads(out.read_text())
    for key in ("opening", "rotation", "displacement", "energy_released"):
        assert np.isfinite(data[key])
    # k = 0: the rim curls outward and the cut releases energy
    assert data["opening"] > 0 and data["rotation"] > 0 and data["energy_released"] < 0
    assert data["pre"]["problem"]["cut"] == 0.0 and data["post"]["problem"]["cut"] == 0.3
    assert len(data["pre"]["s"]) > 0 and len(data["post"]["r"]) == len(data["post"]["s"])
    printed = capsys.readouterr().out
    assert "rotation" in printed
    # both states' energies beside energy_released, and its sign convention in words
    values = dict(re.findall(r"^  (energy_\w+) += (\S+) C R\^2", printed, re.M))
    assert float(values["energy_pre"]) == pytest.approx(data["pre"]["energy"], rel=1e-9)
    assert float(values["energy_post"]) == pytest.approx(data["post"]["energy"], rel=1e-9)
    assert float(values["energy_post"]) - (float(values["energy_pre"])
                                           - float(values["energy_removed"])) \
        == pytest.approx(float(values["energy_released"]), rel=1e-6)
    assert "(energy_post - (energy_pre - energy_removed), negative: the cut released " in printed


def test_ablate_prints_and_writes_each_observables_error(tmp_path, capsys):
    """Audit 8, F5: the observables had no estimate of their own.  Each is printed with its
    estimated error (+- absolute, relative) and written to the JSON and CSV, equal to
    Ablation.errors (printed to 2 digits)."""
    import csv

    from morphoshell.mechanics.ablation import OBSERVABLES

    out, table = tmp_path / "a.json", tmp_path / "a.csv"
    assert main(["ablate", str(TOY2), "--nodes", "100", "--json", str(out),
                 "--csv", str(table)]) == 0
    data = json.loads(out.read_text())
    assert set(data["errors"]) == set(data["relative_errors"]) == set(OBSERVABLES)
    assert data["error_note"] == ""
    printed = dict(re.findall(r"^  (\w+) += \S+ [^+\n]*\+- (\S+) ",
                              capsys.readouterr().out, re.M))
    assert set(printed) == set(OBSERVABLES)
    for k in OBSERVABLES:
        assert data["relative_errors"][k] < 1e-4          # (toy problem 2 on 100 nodes: 1e-5)
        assert float(printed[k]) == pytest.approx(data["errors"][k], rel=0.05)
    with open(table, newline="") as f:
        row = next(csv.DictReader(f))
    assert all(float(row[f"{k}_error"]) == data["errors"][k] for k in OBSERVABLES)


@pytest.mark.parametrize("method", ["bvp", "shooting"])
def test_ablate_by_a_reference_route_prints_the_observables_without_errors(method, tmp_path,
                                                                           capsys):
    """Audit 26, F4: ``ablate --method bvp`` (or shooting) crashed with an internal error
    after its first lines: the reference routes' states carry no error estimate.  Their
    observables are printed without +-, one note saying why, and the files written."""
    out = tmp_path / "a.json"
    assert main(["ablate", str(TOY2), "--method", method, "--json", str(out)]) == 0
    printed, err = capsys.readouterr()
    assert err == ""
    assert "+-" not in printed and "pre-ablation" not in printed
    assert printed.count(f"error estimates unavailable: the {method} route makes no error "
                         f"estimate") == 1
    data = json.loads(out.read_text())
    values = dict(re.findall(r"^  (\w+) += (\S+) ", printed, re.M))
    assert float(values["opening"]) == pytest.approx(data["opening"], rel=1e-9)
    # the direct route's opening on 200 nodes, 0.0824373563 +- 4.5e-8 R: the routes agree
    # to its error and the reference routes' tolerances (~1e-8 R)
    assert data["opening"] == pytest.approx(0.0824373563, abs=1e-7)


def test_ablate_needs_a_cut(capsys):
    assert main(["ablate", str(TOY2), "--set", "cut=0"]) == 2
    err = capsys.readouterr().err
    assert f"{TOY2}: cut (Sigma) = 0.0: an ablation needs a cut > 0" in err      # the file,
    assert "--set cut=" in err                                                  # and the remedy


def test_asymptotics_command(tmp_path):
    from morphoshell.mechanics import asymptotics as A

    out = tmp_path / "p.json"
    assert main(["asymptotics", "--h", "0.01", "--k", "0.5", "--cut-angle", "0.4",
                 "--json", str(out)]) == 0
    data = json.loads(out.read_text())
    assert set(data) >= {"opening", "rotation", "displacement", "rotation_small_cut",
                         "displacement_small_cut", "energy_released"}
    assert data["opening"] == pytest.approx(0.01 * 0.5 * np.sin(0.4), rel=1e-14)
    assert data["rotation"] == pytest.approx(A.rotation(0.01, 0.5), rel=1e-14)
    # (audit: sphere's JSON had no units; the text output says them)
    assert data["units"]["energy_released"] == "C R^2" and data["units"]["sigma"] == "1"
    assert set(data["units"]) == set(data) - {"units", "provenance"}


def test_asymptotics_prints_no_negative_zero(tmp_path, capsys):
    """Audit: k = 1 (no release) printed "energy_released = -0 C R^2" (-(...) * 0)."""
    out = tmp_path / "p.json"
    assert main(["asymptotics", "--h", "0.01", "--k", "1", "--cut", "0.5",
                 "--json", str(out)]) == 0
    assert "-0 " not in capsys.readouterr().out
    assert math.copysign(1, json.loads(out.read_text())["energy_released"]) == 1


def test_asymptotics_rejects_bad_values(capsys):
    assert main(["asymptotics", "--h", "0.01", "--k", "0", "--cut-angle", "4"]) == 2
    assert "argument --cut-angle: 4 must be a finite number in (0, 3.14159) rad" in capsys.readouterr().err


@pytest.mark.parametrize("command, k", [(["asymptotics", "--cut", "0.3"], "1000"),
                                        (["asymptotics", "--cut", "0.3"], "20"),
                                        (["asymptotics", "--cut", "0.3"], "-1000"),
                                        (["sphere"], "1000")])
def test_asymptotics_refuses_a_curvature_beyond_the_thickness(command, k, capsys):
    """Audit 26, F2: |k| >= 2/h (the intrinsic wedge closes) gave rotation = -387 rad and
    exit 0.  Refused in one line as estimate --k-range refuses it (the same check); sphere
    too, before its work (it had been refused by the bulk's own geometry, after f_shell)."""
    assert main([*command, "--h", "0.1", "--k", k]) == 2
    out, err = capsys.readouterr()
    assert out == "" and len(err.strip().splitlines()) == 1
    assert (f"--k: k = {k} is beyond the curvature of the shell of --h 0.1 (h = H/R = 0.1): "
            f"|k| must stay below 2/h = 20") in err
    assert err.rstrip().endswith("give a --k within (-20, 20)")


def test_sphere_command(tmp_path):
    out = tmp_path / "s.json"
    assert main(["sphere", "--h", "0.01", "--k", "0", "--c10", "1", "--c01", "0.5",
                 "--json", str(out)]) == 0
    data = json.loads(out.read_text())
    # f_bulk - f_asymptotic = O(h^4) (measured coefficient ~0.5), f_shell likewise
    assert abs(data["f_bulk"] - data["f_asymptotic"]) < 1e-7
    assert abs(data["f_shell"] - data["f_shell_asymptotic"]) < 1e-8
    assert data["k_star"] == pytest.approx((11 + 3.5) / (5 + 0.5), rel=1e-14)
    assert data["units"] == {"h": "R", "k": "1/R", "c10": "1", "c01": "1", "f_shell": "R",
                             "f_shell_asymptotic": "R", "f_bulk": "R", "f_asymptotic": "R",
                             "k_star": "1/R"}


def test_sphere_of_a_thick_shell(capfd):
    """Audit 26, F1: ``sphere --h 0.9 --k 0`` printed a raw RuntimeWarning and "no stationary
    radius found" (exit 2); f_bulk is printed, nothing on standard error."""
    assert main(["sphere", "--h", "0.9", "--k", "0"]) == 0
    out, err = capfd.readouterr()
    assert err == ""
    # the audit's independent Brent solve of the stationarity: 1.23520 (6 digits)
    assert float(re.search(r"f_bulk += (\S+) R", out)[1]) == pytest.approx(1.23520, abs=5e-6)
    # C01 < 0: a minimum the search missed ("no stationary radius", exit 2), f - 1 in
    # (0.4873, 0.5261) by the audit's scan of S; and where there is none, a solver failure
    assert main(["sphere", "--c01", "-0.5", "--h", "0.9", "--k", "-0.5"]) == 0
    out, err = capfd.readouterr()
    assert err == "" and 1.4873 < float(re.search(r"f_bulk += (\S+) R", out)[1]) < 1.5261
    assert main(["sphere", "--c01", "-0.7", "--h", "0.9", "--k", "0"]) == 3
    out, err = capfd.readouterr()
    assert out == "" and err.startswith("morphoshell: solver failed (status "
                                        "No_Stationary_Radius): no stationary radius found")


def test_missing_hsl_solver_is_explained(capfd):
    # the PyPI wheel has no HSL library: refused when parsed (bad input, exit 2), saying why,
    # with nothing of Ipopt's on standard output (its option table was dumped there)
    assert main(["solve", str(TOY2), "--linear-solver", "ma27"]) == 2
    out, err = capfd.readouterr()
    assert "--linear-solver: 'ma27': Ipopt cannot load it" in err and "libhsl.so" in err
    assert out == ""
    assert main(["solve", str(TOY2), "--linear-solver", "ma27x"]) == 2
    assert "'ma27x': choose one of ['mumps'" in capfd.readouterr().err


def test_the_command_listing_is_the_full_parsers():
    """``morphoshell --help`` (and a missing or mistyped command) is answered by a parser
    holding each command's name and one-line help only: the same text as the parser with
    every command registered, in the same order."""
    from morphoshell.cli import build_parser, listing_parser
    assert listing_parser().format_help() == build_parser().format_help()


def _imported(args: list[str]) -> set[str]:
    """The top-level packages and morphoshell's subpackages a fresh ``morphoshell ARGS``
    imports (after it returned)."""
    code = ("import sys; from morphoshell.cli import main; main(sys.argv[1:]); "
            "print(' '.join(sorted({m if m.startswith('morphoshell') else m.split('.')[0] "
            "for m in sys.modules})))")
    out = subprocess.run([sys.executable, "-c", code, *args], capture_output=True, text=True,
                         check=True)
    return set(out.stdout.split("\n")[-2].split())


@pytest.mark.parametrize("args", [["--version"], ["--help"], ["example", "--list"],
                                  ["example", "toy1_sphere"], ["bogus"]])
def test_help_version_and_example_import_no_numpy(args):
    # they imported NumPy, CasADi and the solvers before reading the arguments (0.2-0.35 s,
    # 90 % of `--version`: audit 18 F1)
    assert not _imported(args) & {"numpy", "casadi", "scipy", "morphoshell.solvers"}


@pytest.mark.parametrize("args, unused", [
    (["asymptotics", "--h", "0.01", "--k", "0", "--cut", "0.5"],
     ("scipy.integrate", "scipy.optimize")),
    (["sphere", "--h", "0.1", "--k", "2"], ("scipy.integrate",))])     # (its radius: brentq)
def test_closed_forms_import_no_solver(args, unused):
    # the closed forms need scipy.special (and the sphere's radius scipy.optimize's brentq),
    # not scipy.integrate's solve_bvp, nor the solvers (io.problem_files) before the
    # arguments (F1, F5)
    imported = _imported(args)
    assert "scipy" in imported
    assert not {m for m in imported if m.startswith("morphoshell.solvers")}
    code = (f"import sys; from morphoshell.cli import main; main({args!r}); "
            f"print([m for m in sys.modules if m.startswith({unused!r})])")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True)
    assert out.stdout.strip().splitlines()[-1] == "[]"
