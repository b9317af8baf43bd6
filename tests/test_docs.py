"""The documentation: it builds without warnings, its examples run, it stands alone.

* ``mkdocs build --strict`` (the API reference from the docstrings included);
* the ``>>>`` examples of README.md and docs/*.md run as doctests;
* every option of every command is in the command-line reference;
* no page or docstring points at files users do not have (``../shared/...``)
  or cites the paper by LaTeX labels (``eq:...``);
* every public function, class and method has a docstring.
"""
import doctest
import importlib
import inspect
import os
import pkgutil
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

import morphoshell

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
PAGES = sorted(DOCS.glob("*.md"))
_FENCE = re.compile(r"^```python\n(.*?)^```", re.S | re.M)


# --------------------------------------------------------------------------
# the build
# --------------------------------------------------------------------------

def test_docs_build_strictly_without_warnings(tmp_path):
    pytest.importorskip("mkdocs")
    pytest.importorskip("mkdocstrings_handlers.python")
    mkdocs = shutil.which("mkdocs", path=str(Path(sys.executable).parent)) or shutil.which("mkdocs")
    assert mkdocs, "the docs extra is installed but its mkdocs command is not on the PATH"
    # the notebook page without running the notebook (tests/test_notebooks.py runs it)
    env = {**os.environ, "NO_MKDOCS_2_WARNING": "1", "MORPHOSHELL_DOCS_EXECUTE": "false",
           "PYTHONPATH": os.pathsep.join([str(ROOT / "src"), os.environ.get("PYTHONPATH", "")])}
    run = subprocess.run([mkdocs, "build", "--strict", "--site-dir", str(tmp_path / "site")],
                         cwd=ROOT, env=env, capture_output=True, text=True, timeout=600)
    log = run.stdout + run.stderr
    assert run.returncode == 0, log
    assert "WARNING" not in log, log
    api = tmp_path / "site" / "api"
    for page in ("model", "solvers", "mechanics", "io", "inverse", "fitting", "workflows"):
        html = (api / page / "index.html").read_text()
        for module in re.findall(r"^::: (\S+)", (DOCS / "api" / f"{page}.md").read_text(), re.M):
            assert module in html, (page, module)
    html = (api / "solvers" / "index.html").read_text()
    assert "to_dataframe" in html and "to_xarray" in html
    assert ":func:" not in html and ":class:" not in html          # roles became links
    assert (tmp_path / "site" / "tutorial_family" / "index.html").exists()
    # the tutorial notebook is a page (executed by `make docs`, which shows its outputs) and
    # a download
    notebook = tmp_path / "site" / "notebooks" / "tutorial"
    assert "Fit a traced midline" in (notebook / "index.html").read_text()
    assert (notebook / "tutorial.ipynb").exists()
    assert "execute: !ENV [MORPHOSHELL_DOCS_EXECUTE, true]" in (ROOT / "mkdocs.yml").read_text()


def test_every_public_module_has_a_place_in_the_api_reference():
    documented = {m for page in (DOCS / "api").glob("*.md")
                  for m in re.findall(r"^::: (\S+)", page.read_text(), re.M)}
    public = {m.name for m in pkgutil.walk_packages(morphoshell.__path__, "morphoshell.")
              if not any(p.startswith("_") for p in m.name.split("."))}
    # modules that only re-export names documented elsewhere
    public -= {"morphoshell.inverse.measurements", "morphoshell.cli.__main__"}
    missing = sorted(m for m in public if m not in documented
                     and not any(m.startswith(d + ".") for d in documented if d.endswith("cli")))
    assert not missing, f"modules without an API block: {missing}"


def test_every_page_is_in_the_navigation():
    nav = (ROOT / "mkdocs.yml").read_text()
    for page in PAGES:
        assert f" {page.name}" in nav, page.name
    for page in sorted((DOCS / "api").glob("*.md")):
        assert f"api/{page.name}" in nav, page.name


# --------------------------------------------------------------------------
# examples that run
# --------------------------------------------------------------------------

def _doctest_blocks(path: Path) -> str:
    """The ``>>>`` examples of a Markdown file's ```python blocks, as one doctest text."""
    blocks = [b for b in _FENCE.findall(path.read_text()) if ">>>" in b]
    return "\n".join(blocks)


def _run_doctests(path: Path, globs: dict) -> doctest.TestResults:
    text = _doctest_blocks(path)
    test = doctest.DocTestParser().get_doctest(text, globs, path.name, str(path), 0)
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    runner.run(test)
    return runner.summarize(verbose=False)


def _tutorial_module(tmp_path: Path) -> Path:
    """The tutorial's plugin module (the ```python block starting ``# bump_family.py``)."""
    [source] = [b for b in _FENCE.findall((DOCS / "tutorial_family.md").read_text())
                if b.startswith("# bump_family.py")]
    path = tmp_path / "bump_family.py"
    path.write_text(source)
    return path


@pytest.mark.parametrize("page", [ROOT / "README.md", *PAGES], ids=lambda p: p.name)
def test_examples_run_as_doctests(page, tmp_path, monkeypatch):
    if not _doctest_blocks(page):
        pytest.skip("no >>> examples")
    from morphoshell.model.profiles import FAMILIES

    monkeypatch.chdir(ROOT)                       # the README reads data/ relative to the root
    monkeypatch.syspath_prepend(str(_tutorial_module(tmp_path).parent))
    monkeypatch.setattr("morphoshell.model.profiles.FAMILIES", dict(FAMILIES))   # no leftovers
    result = _run_doctests(page, {})
    assert result.failed == 0, f"{result.failed} of {result.attempted} examples of {page.name} failed"
    assert result.attempted > 0


def test_readme_and_quick_start_have_examples():
    assert len(re.findall(r"^>>> ", _doctest_blocks(ROOT / "README.md"), re.M)) >= 10
    assert ">>> " in _doctest_blocks(DOCS / "index.md")
    assert ">>> " in _doctest_blocks(DOCS / "tutorial_family.md")


_SHELL = re.compile(r"^```(?:sh|bash|console)\n(.*?)^```", re.S | re.M)
#: The options that name an output, and a placeholder for one (a synopsis: OUT.csv, DIR).
_WRITES = {"--json", "--csv", "--plot", "--profile-plot", "--out", ">"}
_PLACEHOLDER = re.compile(r"^[A-Z_]+(\.\w+)?$")


def _outputs_outside_out(text: str) -> list[str]:
    """The outputs that the ``morphoshell`` commands of ``text``'s shell blocks write
    anywhere but into ``out/``."""
    import shlex

    bad = []
    for block in _SHELL.findall(text):
        for line in block.replace("\\\n", " ").splitlines():
            words = shlex.split(line.removeprefix("$ "), comments=True)
            for option, value in zip(words, words[1:]):
                if (option in _WRITES and "morphoshell" in line and not value.startswith("out/")
                        and not _PLACEHOLDER.match(value)):
                    bad.append(f"{option} {value}")
            if "campaign" in words and "morphoshell" in line and "--out" not in words:
                bad.append("campaign without --out (./campaign)")
    return bad


@pytest.mark.parametrize("page", [ROOT / "README.md", *PAGES], ids=lambda p: p.name)
def test_documented_commands_write_into_out(page):
    """Copied from the README or the docs, a command writes into out/ (ignored by git), not
    into the clone (the quick tour wrote out.json, toy2.toml, ... into the repository)."""
    assert not _outputs_outside_out(page.read_text()), page.name
    assert _outputs_outside_out("```sh\nmorphoshell solve a.toml --json a.json > b.toml\n"
                                "morphoshell campaign data\n```\n") \
        == ["--json a.json", "> b.toml", "campaign without --out (./campaign)"]


# --------------------------------------------------------------------------
# the command-line reference
# --------------------------------------------------------------------------

def test_cli_reference_documents_every_command_and_option():
    import argparse

    from morphoshell.cli import build_parser

    text = (DOCS / "cli.md").read_text()
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    for name, command in sub.choices.items():
        assert f"## `morphoshell {name}`" in text, f"{name}: run scripts/cli_reference.py"
        for action in command._actions:
            for option in action.option_strings:
                assert re.search(rf"(?<![\w-]){re.escape(option)}(?![\w-])", text), \
                    f"morphoshell {name} {option} is not in docs/cli.md: run scripts/cli_reference.py"


# --------------------------------------------------------------------------
# standing alone
# --------------------------------------------------------------------------

_SOURCES = [ROOT / "README.md", *PAGES, *sorted((ROOT / "src" / "morphoshell").rglob("*.py"))]


@pytest.mark.parametrize("pattern", [r"\.\./shared", r"shared/docs", r"shared/reference",
                                     r"\beq:[A-Za-z]", r"volvox_model\.md",
                                     r"large_bending_theory\.md", r"\.tex\b"])
def test_nothing_points_at_files_users_do_not_have(pattern):
    hits = [f"{p.relative_to(ROOT)}:{i}" for p in _SOURCES
            for i, line in enumerate(p.read_text().splitlines(), 1) if re.search(pattern, line)]
    assert not hits, f"{pattern!r} in {hits}"


def _public_modules():
    names = ["morphoshell"]
    names += [m.name for m in pkgutil.walk_packages(morphoshell.__path__, "morphoshell.")
              if not any(part.startswith("_") for part in m.name.split("."))]
    return [importlib.import_module(n) for n in names]


def test_every_public_function_class_and_method_has_a_docstring():
    missing = []
    for module in _public_modules():
        assert (module.__doc__ or "").strip(), module.__name__
        for name in getattr(module, "__all__", ()):
            obj = getattr(module, name)
            if not (inspect.isfunction(obj) or inspect.isclass(obj)):
                continue
            if not (obj.__doc__ or "").strip():
                missing.append(f"{module.__name__}.{name}")
            if inspect.isclass(obj):
                for attr, member in vars(obj).items():
                    f = member.fget if isinstance(member, property) else member
                    if attr.startswith("_") or not inspect.isfunction(f) \
                            or f.__name__ == "<lambda>":
                        continue
                    if not (f.__doc__ or "").strip():
                        missing.append(f"{module.__name__}.{name}.{attr}")
    assert not missing, f"no docstring: {sorted(set(missing))}"


def test_docstring_examples_run():
    """The ``>>>`` examples in the package's docstrings give the output they show."""
    import doctest

    failed = attempted = 0
    for module in _public_modules():
        result = doctest.testmod(module, optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
        failed += result.failed
        attempted += result.attempted
    assert attempted >= 3
    assert failed == 0, f"{failed} of {attempted} docstring examples failed (output above)"


# --------------------------------------------------------------------------
# names that point into the package
# --------------------------------------------------------------------------

_DOTTED = re.compile(r"\bmorphoshell(?:\.[A-Za-z_]\w*)+")
#: Dotted strings that are not names in the package: the plugins' entry-point group, and
#: the label of a campaign's JSON records (kept as written when the module was named so).
_FROM_IMPORT = re.compile(r"from (morphoshell(?:\.\w+)*) import ([\w, ]+)")
_NOT_NAMES = {"morphoshell.families", "morphoshell.campaign"}


def _resolves(name: str) -> bool:
    """Whether ``name`` is a module, or an attribute of one (instance attributes included)."""
    parts = name.split(".")
    for i in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:i]))
        except ImportError:
            continue
        for attr in parts[i:]:
            if hasattr(obj, attr):
                obj = getattr(obj, attr)
            elif inspect.isclass(obj):     # set in __init__ or a dataclass field
                source = inspect.getsource(obj)
                return bool(re.search(rf"self\.{attr}\b\s*[:=]|^\s+{attr}\s*:", source, re.M))
            else:
                return False
        return True
    return False


def test_every_dotted_name_of_the_package_resolves():
    """Docstrings, pages and scripts name objects by their module: after a move they must
    still resolve (mkdocs shows a broken cross-reference as plain text, without a warning)."""
    files = [*sorted((ROOT / "src" / "morphoshell").rglob("*.py")), ROOT / "README.md",
             *sorted(DOCS.rglob("*.md")), *sorted((ROOT / "scripts").glob("*.py"))]
    broken = []
    for path in files:
        # (the architecture page's table of old module paths names them on purpose)
        text = path.read_text().split("## Where things moved")[0]
        for i, line in enumerate(text.splitlines(), 1):
            names = _DOTTED.findall(line)
            for module, imported in _FROM_IMPORT.findall(line):     # names in examples
                names += [f"{module}.{n.split(' as ')[0].strip()}" for n in imported.split(",")
                          if n.strip().isidentifier() or " as " in n]
            for name in names:
                if name in _NOT_NAMES or name.endswith((".md", ".py", ".toml", ".json")):
                    continue
                if not _resolves(name):
                    broken.append(f"{path.relative_to(ROOT)}:{i}: {name}")
    assert not broken, "\n".join(broken)


def test_the_readme_is_a_front_page():
    """At most 15 000 bytes; its first screen holds the two set-up commands and an example."""
    text = (ROOT / "README.md").read_text()
    first = "\n".join(text.splitlines()[:40])
    assert len(text.encode()) <= 15_000
    assert "make run" in first and "make test" in first and ">>> " in first
