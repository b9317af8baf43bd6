"""Packaging: ``pip install .`` into a clean virtual environment, then use it outside the repository.

One slow test; it stays in ``make test``.  The clean environment gets the
package from its wheel and nothing else: the dependencies (casadi, numpy,
scipy, ...) are the test environment's, on ``PYTHONPATH`` (installing them
again took over a minute of a ten-minute CI budget; set
``MORPHOSHELL_PACKAGING_DEPS=1`` to install them too).  A path on
``PYTHONPATH`` does not run its ``.pth`` files, so the repository's editable
install stays out of the way (asserted: morphoshell is imported from the new
environment).  It
checks the wheel (SPDX licence and LICENSE, py.typed, the example problems,
project URLs, one version), that building it prints no deprecation warning,
that ``morphoshell example toy2_ablation > p.toml && morphoshell solve p.toml``
works in a folder outside the repository, and that a throwaway plugin package
installed next to it makes its family solvable from a problem file.
"""
import importlib.util
import os
import re
import subprocess
import sys
import sysconfig
import venv
import zipfile
from pathlib import Path

import pytest

import morphoshell

ROOT = Path(__file__).resolve().parents[1]
# the plugin module of the family tutorial, shared with tests/model/test_plugins.py
_spec = importlib.util.spec_from_file_location("test_plugins",
                                               ROOT / "tests" / "model" / "test_plugins.py")
_plugins = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(_plugins)
tutorial_module = _plugins.tutorial_module

pytestmark = pytest.mark.slow


def _run(args, cwd, env):
    run = subprocess.run([str(a) for a in args], cwd=cwd, env=env, capture_output=True,
                         text=True, timeout=1200)
    assert run.returncode == 0, f"{args} failed:\n{run.stdout[-3000:]}\n{run.stderr[-3000:]}"
    return run


def test_clean_venv_install_example_and_plugin(tmp_path):
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    env["PIP_DISABLE_PIP_VERSION_CHECK"] = "1"
    install = ["install", "--quiet"]
    if os.environ.get("MORPHOSHELL_PACKAGING_DEPS") != "1":
        env["PYTHONPATH"] = sysconfig.get_paths()["purelib"]
        # --ignore-installed: never touch the test environment's own morphoshell
        install += ["--no-deps", "--ignore-installed"]
    home = tmp_path / "venv"
    venv.EnvBuilder(with_pip=True).create(home)
    python = home / "bin" / "python"
    bindir = home / "bin"
    env["PATH"] = os.pathsep.join([str(bindir), env.get("PATH", "")])

    # the wheel, built verbosely to see the backend's warnings
    dist = tmp_path / "dist"
    build = _run([python, "-m", "pip", "wheel", "--no-deps", "-v", "-w", dist, ROOT], tmp_path, env)
    log = build.stdout + build.stderr
    assert not re.search(r"(?i)deprecat\w*.{0,200}licen[cs]e|licen[cs]e.{0,200}deprecat", log), \
        "the build warns about the licence metadata"
    [wheel] = dist.glob("morphoshell-*.whl")
    assert wheel.name.startswith(f"morphoshell-{morphoshell.__version__}-")
    with zipfile.ZipFile(wheel) as z:
        names = set(z.namelist())
        info = next(n for n in names if n.endswith(".dist-info/METADATA"))
        metadata = z.read(info).decode()
    assert "morphoshell/py.typed" in names
    for example in ("toy1_sphere", "toy2_ablation", "toy3_anisotropic", "fast_relaxation",
                    "volvox_inversion", "volvox_fold", "blister"):
        assert f"morphoshell/examples/{example}.toml" in names
    assert any(n.endswith(".dist-info/licenses/LICENSE") for n in names)
    assert "License-Expression: MIT" in metadata
    assert f"Version: {morphoshell.__version__}" in metadata
    assert "Project-URL: Homepage, https://github.com/morphoshell/morphoshell" in metadata
    assert "Provides-Extra: xarray" in metadata and "Requires-Dist: pandas" in metadata

    _run([python, "-m", "pip", *install, wheel], tmp_path, env)

    # outside the repository: the example, solved
    work = tmp_path / "elsewhere"
    work.mkdir()
    where = _run([python, "-c", "import morphoshell; print(morphoshell.__file__)"], work, env)
    assert str(ROOT) not in where.stdout and str(home) in where.stdout
    solved = _run(["sh", "-c", "morphoshell example toy2_ablation > p.toml && "
                               "morphoshell solve p.toml --csv p.csv"], work, env)
    assert "p: direct solution" in solved.stdout and "C R^2" in solved.stdout
    assert (work / "p.csv").exists()

    # a throwaway plugin package: its family from a problem file
    plugin = tmp_path / "bump-family"
    plugin.mkdir()
    (plugin / "bump_family.py").write_text(tutorial_module())
    (plugin / "pyproject.toml").write_text(
        '[build-system]\nrequires = ["setuptools>=77"]\nbuild-backend = "setuptools.build_meta"\n'
        '[project]\nname = "bump-family"\nversion = "0.1.0"\ndependencies = ["morphoshell"]\n'
        '[tool.setuptools]\npy-modules = ["bump_family"]\n'
        '[project.entry-points."morphoshell.families"]\nbump = "bump_family:BUMP"\n')
    _run([python, "-m", "pip", *install, plugin], tmp_path, env)
    (work / "ring.toml").write_text('[problem]\nfamily = "bump"\nh = 0.1\ncut = 0.3\n'
                                    '[parameters]\nA = 3.0\ns_c = 1.2\nw = 0.1\n')
    ring = _run([bindir / "morphoshell", "solve", "ring.toml", "--nodes", "60"], work, env)
    assert "ring: direct solution" in ring.stdout
    ablated = _run([bindir / "morphoshell", "ablate", "ring.toml", "--nodes", "60",
                    "--set", "A=2"], work, env)
    assert re.search(r"rotation += .* rad", ablated.stdout)
