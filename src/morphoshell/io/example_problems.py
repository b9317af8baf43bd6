"""The packaged example problems (``morphoshell example NAME``): their names, descriptions
and text.

Apart from :mod:`.problem_files` (which re-exports them), so that listing or printing
an example imports neither NumPy nor the solvers.
"""
from __future__ import annotations

from pathlib import Path

__all__ = ["examples", "example_path", "example_text", "EXAMPLES_DIR"]

#: The packaged example problem files (``morphoshell example NAME``).
EXAMPLES_DIR = Path(__file__).resolve().parent.parent / "examples"


def examples() -> dict[str, str]:
    """The packaged example problems: name → description (the file's leading comment)."""
    out = {}
    for path in sorted(EXAMPLES_DIR.glob("*.toml")):
        lines = []
        for line in path.read_text(encoding="utf-8").splitlines():
            if not line.startswith("#"):
                break
            lines.append(line.lstrip("#").strip())
        out[path.stem] = " ".join(lines)
    return out


def example_path(name: str) -> Path:
    """Path of the packaged example problem ``name`` (e.g. ``"toy2_ablation"``).

    Raises
    ------
    ValueError
        No such example (the message lists them).
    """
    names = examples()
    if name not in names:
        raise ValueError(f"unknown example {name!r}; choose one of {sorted(names)}")
    return EXAMPLES_DIR / f"{name}.toml"


def example_text(name: str) -> str:
    """The text of the packaged example problem ``name``: a problem file to start from."""
    return example_path(name).read_text(encoding="utf-8")
