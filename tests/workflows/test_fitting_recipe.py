"""docs/fitting.md as a new user reads it: the recipe's fit and the Python example that
ablates the fit's JSON (``fitted_problem`` → ``numerical_ablation``) run exactly as written.

Both are taken from the page, not copied here, so that an edit of the page is what is tested.
They run in a temporary folder (``data`` linked to the repository's) in fresh processes, with
this checkout's ``src`` first on the path.
"""
import ast
import os
import re
import subprocess
import sys
from pathlib import Path

import morphoshell

ROOT = Path(__file__).resolve().parents[2]
PAGE = ROOT / "docs" / "fitting.md"
SRC = Path(morphoshell.__file__).resolve().parents[1]


def _blocks(text: str, language: str) -> list[str]:
    return re.findall(rf"^```{language}\n(.*?)^```", text, re.S | re.M)


def _section(title: str) -> str:
    text = PAGE.read_text()
    start = text.index(f"\n## {title}\n")
    end = text.find("\n## ", start + 1)
    return text[start:end if end > 0 else None]


def _env() -> dict:
    return {**os.environ, "MPLBACKEND": "Agg",
            "PATH": os.pathsep.join([str(Path(sys.executable).parent), os.environ["PATH"]]),
            "PYTHONPATH": os.pathsep.join(filter(None, [str(SRC), os.environ.get("PYTHONPATH")]))}


def test_the_recipes_fit_and_the_json_example_run_as_written(tmp_path):
    (tmp_path / "data").symlink_to(ROOT / "data")
    [fit] = [b for b in _blocks(_section("From Fiji to figures in five steps"), "sh")
             if "morphoshell fit" in b and "--variant free" in b]
    run = subprocess.run(["bash", "-e", "-c", fit], cwd=tmp_path, env=_env(),
                         capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stdout + run.stderr
    for name in ("embryo1_free.json", "embryo1_free.csv", "embryo1_free.png"):
        assert (tmp_path / "out" / name).stat().st_size > 0, name

    [example] = [b for b in _blocks(PAGE.read_text(), "python")
                 if "fitted_problem" in b and "numerical_ablation" in b]
    assert "out/embryo1_free.json" in example         # the JSON the recipe's fit wrote
    run = subprocess.run([sys.executable, "-c", example], cwd=tmp_path, env=_env(),
                         capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stdout + run.stderr
    observables, errors, cold_difference, fit_errors, _ = run.stdout.strip().splitlines()
    observables, errors = ast.literal_eval(observables), ast.literal_eval(errors)
    # (the fit's errors carried into the recoil: the lengths and the angle, each positive)
    fit_errors = ast.literal_eval(fit_errors)
    assert {"opening", "rotation", "displacement"} <= set(fit_errors) <= set(observables)
    assert all(0 < v < float("inf") for v in fit_errors.values()), fit_errors
    # (an estimate for every observable, each a bound well below the value on 200 nodes)
    assert set(errors) == set(observables), errors
    assert all(0 <= errors[k] < 0.03 * abs(v) for k, v in observables.items() if v), errors
    assert {"opening", "rotation", "displacement", "energy_released"} <= set(observables)
    assert observables["opening"] > 0
    assert float(cold_difference) < 1e-6            # the continuation and a cold solve agree
