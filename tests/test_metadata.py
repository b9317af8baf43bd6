"""Package metadata that users and tools read: licence, typing, URLs, citation, one version."""
import re
import sys
from pathlib import Path

import morphoshell

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

ROOT = Path(__file__).resolve().parents[1]
PYPROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text())


def test_spdx_licence_and_licence_file():
    project = PYPROJECT["project"]
    assert project["license"] == "MIT" and project["license-files"] == ["LICENSE"]
    assert not any("License ::" in c for c in project.get("classifiers", []))   # SPDX only
    assert "MIT License" in (ROOT / "LICENSE").read_text()
    assert any(re.fullmatch(r"setuptools>=(\d+)", r) and int(r.split(">=")[1]) >= 77
               for r in PYPROJECT["build-system"]["requires"])


def test_one_version_source():
    assert PYPROJECT["project"]["dynamic"] == ["version"] and "version" not in PYPROJECT["project"]
    assert PYPROJECT["tool"]["setuptools"]["dynamic"]["version"] == {"attr": "morphoshell.__version__"}
    assert not re.search(r"^version:", (ROOT / "CITATION.cff").read_text(), re.M)


def test_typed_with_examples_and_urls():
    assert (Path(morphoshell.__file__).parent / "py.typed").exists()
    data = PYPROJECT["tool"]["setuptools"]["package-data"]["morphoshell"]
    assert "py.typed" in data and "examples/*.toml" in data
    urls = PYPROJECT["project"]["urls"]
    assert set(urls) >= {"Homepage", "Documentation", "Issues"}
    from morphoshell.cli import ISSUES_URL
    assert urls["Issues"] == ISSUES_URL
    assert set(PYPROJECT["project"]["optional-dependencies"]) >= {"xarray", "docs", "test"}


def test_citation_cites_the_software_and_the_paper():
    text = (ROOT / "CITATION.cff").read_text()
    assert text.startswith("#") and "cff-version: 1.2.0" in text and "type: software" in text
    assert "license: MIT" in text
    assert 'title: "Cut it out: Out-of-plane stresses in cell sheet folding of Volvox embryos"' in text
    assert "family-names: Haas" in text and "family-names: Höhn" in text
    try:
        import yaml
    except ImportError:   # the docs extra brings PyYAML; without it the text checks stand
        return
    data = yaml.safe_load(text)
    assert data["references"][0]["authors"][1]["given-names"] == "Stephanie S. M. H."
