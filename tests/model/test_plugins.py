"""Plugin families: the entry-point group ``morphoshell.families``.

A throwaway distribution is put on the path as an installed package would be
(a ``*.dist-info`` folder with its ``entry_points.txt`` next to the module),
so that ``importlib.metadata`` finds it.  ``tests/test_packaging.py`` does the
same with ``pip install`` in a clean virtual environment.
"""
import os
import subprocess
import sys
from pathlib import Path

import pytest

from morphoshell import Problem, solve
from morphoshell.model import profiles
from morphoshell.io.problem_files import load_problem

ROOT = Path(__file__).resolve().parents[2]
DOCS = ROOT / "docs"


def tutorial_module() -> str:
    """The plugin module of the tutorial (docs/tutorial_family.md), so the tutorial is tested."""
    import re

    blocks = re.findall(r"^```python\n(.*?)^```", (DOCS / "tutorial_family.md").read_text(),
                        re.S | re.M)
    [source] = [b for b in blocks if b.startswith("# bump_family.py")]
    return source


def fake_install(where: Path, module: str, source: str, entry_points: str) -> Path:
    """``module`` and a dist-info declaring ``entry_points`` in the folder ``where``."""
    (where / f"{module}.py").write_text(source)
    info = where / f"{module.replace('_', '-')}-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {module}\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text(entry_points)
    return where


@pytest.fixture
def plugin_path(tmp_path, monkeypatch):
    """The tutorial's ``bump`` family installed (on sys.path) as an entry point."""
    fake_install(tmp_path, "bump_family", tutorial_module(),
                 "[morphoshell.families]\nbump = bump_family:BUMP\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setattr(profiles, "FAMILIES", dict(profiles.FAMILIES))   # forget it afterwards
    monkeypatch.delitem(sys.modules, "bump_family", raising=False)
    return tmp_path


def test_an_entry_point_family_is_found_by_name(plugin_path):
    assert "bump" not in profiles.FAMILIES
    assert profiles.available_families()["bump"] == "bump_family:BUMP"     # listed, not loaded
    family = profiles.get_family("bump")
    assert family.name == "bump" and profiles.FAMILIES["bump"] is family
    assert profiles.get_family("bump") is family                            # loaded once
    eq = solve(Problem("bump", {"A": 2.0}, h=0.1, cut=0.3), nodes=60)
    assert eq.converged and eq.solver.details["path"].startswith("continuation")


def test_a_problem_file_names_a_plugin_family(plugin_path, tmp_path):
    path = tmp_path / "ring.toml"
    path.write_text('[problem]\nfamily = "bump"\nh = 0.1\ncut = 0.3\n'
                    '[parameters]\nA = 3.0\ns_c = 1.2\nw = 0.1\n')
    problem, _ = load_problem(path)
    assert problem.family == "bump" and problem.params == {"A": 3.0, "s_c": 1.2, "w": 0.1}


def test_the_command_line_solves_a_plugin_family(plugin_path, tmp_path):
    path = tmp_path / "ring.toml"
    path.write_text('[problem]\nfamily = "bump"\nh = 0.1\ncut = 0.3\n[parameters]\nA = 3.0\n')
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(plugin_path), str(ROOT / "src")])}
    run = subprocess.run([sys.executable, "-m", "morphoshell.cli", "solve", str(path),
                          "--nodes", "60", "--set", "A=2", "--csv", str(tmp_path / "r.csv"), "-v"],
                         capture_output=True, text=True, env=env, timeout=300)
    assert run.returncode == 0, run.stderr
    assert "ring: direct solution" in run.stdout and "C R^2" in run.stdout
    # -v: the note on the parameters the file leaves at their defaults
    assert "leaves them at the defaults of family 'bump': s_c = 1.2, w = 0.1" in run.stderr
    assert (tmp_path / "r.csv").read_text().startswith("s,r,z,psi")


def test_unknown_and_broken_plugins_are_named(tmp_path, monkeypatch):
    fake_install(tmp_path, "broken_family", "raise RuntimeError('no luck')\n",
                 "[morphoshell.families]\nbroken = broken_family:FAMILY\n"
                 "wrongname = good_family:FAMILY\nnotafamily = good_family:other\n")
    (tmp_path / "good_family.py").write_text(
        "from morphoshell.model.profiles import FAMILIES\nFAMILY = FAMILIES['uniform']\nother = 42\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setattr(profiles, "FAMILIES", dict(profiles.FAMILIES))
    with pytest.raises(ValueError, match=r"plugin family 'broken' \(entry point "
                                         r"'broken_family:FAMILY' of 'morphoshell.families'\) "
                                         r"failed to load: RuntimeError: no luck"):
        profiles.get_family("broken")
    with pytest.raises(ValueError, match="gives a family called 'uniform'"):
        profiles.get_family("wrongname")
    with pytest.raises(ValueError, match="gives 42, not a ProfileFamily"):
        profiles.get_family("notafamily")
    with pytest.raises(ValueError, match=r"unknown profile family 'nope'; choose one of "
                                         r"\['anisotropic', 'broken', "):
        Problem("nope")


def test_a_callable_entry_point_returns_the_family(tmp_path, monkeypatch):
    fake_install(tmp_path, "made_family",
                 "from morphoshell.model.profiles import FAMILIES, ProfileFamily\n"
                 "def make():\n"
                 "    u = FAMILIES['uniform']\n"
                 "    return ProfileFamily('made', u.parameters, u.defaults, u.build,\n"
                 "                         neutral=u.neutral)\n",
                 "[morphoshell.families]\nmade = made_family:make\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setattr(profiles, "FAMILIES", dict(profiles.FAMILIES))
    assert Problem("made", {"k": 0.5}).family_obj.name == "made"


def test_a_plugins_own_error_is_its_own(tmp_path, monkeypatch, capsys):
    """An exception raised in a plugin family's code is reported as the plugin's, naming its
    entry point, not as a bug of morphoshell (user audit); exit status 1 as for a bug."""
    from morphoshell.cli import main

    fake_install(tmp_path, "oops_family",
                 "from morphoshell.model.profiles import FAMILIES, ProfileFamily\n"
                 "def _validate(v, cut, end):\n"
                 "    return v['ww']\n"
                 "u = FAMILIES['uniform']\n"
                 "FAMILY = ProfileFamily('oops', u.parameters, u.defaults, u.build, _validate,\n"
                 "                       neutral=u.neutral)\n",
                 "[morphoshell.families]\noops = oops_family:FAMILY\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setattr(profiles, "FAMILIES", dict(profiles.FAMILIES))
    monkeypatch.delitem(sys.modules, "oops_family", raising=False)
    path = tmp_path / "oops.toml"
    path.write_text('[problem]\nfamily = "oops"\nh = 0.1\ncut = 0.3\n')
    assert main(["solve", str(path), "--nodes", "20"]) == 1
    err = capsys.readouterr().err
    assert err.startswith("morphoshell: internal error in the plugin family 'oops' (entry point "
                          "'oops_family:FAMILY' of 'morphoshell.families'): KeyError: 'ww'"), err
    assert "a bug in morphoshell" not in err
