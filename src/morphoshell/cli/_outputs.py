"""Output files of the command line: checked before any work, written all or nothing.

Every output option is validated when the arguments are parsed (its format
follows its extension; the folder must exist and be writable; the path must
not be a folder), so a bad path fails before a solve starts.  Results are
staged and committed together: each is written to a temporary file in its
target folder and only when all are written are they renamed into place, so
a failure leaves no output file behind (a rename within one folder is atomic).
"""
from __future__ import annotations

import argparse
import os
from pathlib import Path
from typing import Callable

__all__ = ["output_path", "Outputs", "FORMATS", "kept_in"]

#: Output kinds and the extensions each accepts.
FORMATS = {"json": (".json",), "csv": (".csv",), "plot": (".png", ".pdf", ".svg")}


def output_path(kind: str) -> Callable[[str], Path]:
    """An argparse ``type`` that validates an output path of ``kind`` (see :data:`FORMATS`)."""
    extensions = FORMATS[kind]

    def check(text: str) -> Path:
        if not text or not text.strip():
            raise argparse.ArgumentTypeError("the output path is empty")
        path = Path(text)
        if path.is_dir():
            raise argparse.ArgumentTypeError(f"{text!r} is a folder, not a file")
        if path.suffix.lower() not in extensions:
            raise argparse.ArgumentTypeError(
                f"{text!r}: the format follows the extension; use one of {', '.join(extensions)}")
        parent = path.parent if str(path.parent) else Path(".")
        if not parent.is_dir():
            what = "is a file" if parent.exists() else "does not exist"
            raise argparse.ArgumentTypeError(f"{text!r}: the folder {str(parent)!r} {what}")
        if not os.access(parent, os.W_OK | os.X_OK):
            raise argparse.ArgumentTypeError(
                f"{text!r}: the folder {str(parent)!r} is not writable")
        if path.exists() and not os.access(path, os.W_OK):
            raise argparse.ArgumentTypeError(f"{text!r} exists and is not writable")
        return path
    check.__name__ = f"{kind} file"
    return check


class Outputs:
    """Outputs staged during a command and written together by :meth:`commit`.

    ``add(path, write)`` registers ``write(tmp_path)``, which must write the
    file at ``tmp_path`` (in the same folder, with the same extension).
    """

    def __init__(self):
        self._staged: list[tuple[Path, Callable[[Path], None]]] = []

    def add(self, path: Path | None, write: Callable[[Path], None]) -> None:
        """Stage ``write`` for ``path`` (nothing when the option was not given: None)."""
        if path is not None:
            self._staged.append((Path(path), write))

    def commit(self) -> list[Path]:
        """Write every staged output; on any failure remove what was written and re-raise.

        A Ctrl-C that CasADi dropped during the work (:mod:`morphoshell._runtime.interrupts`)
        is raised first: the results of a cut run are not written.
        """
        from .._runtime.interrupts import check

        check()
        if not self._staged:
            return []
        import tempfile     # here only: a run without outputs needs none of its imports

        from .._runtime.files import as_new_file, replace_named

        temps: list[tuple[Path, Path]] = []
        try:
            for path, write in self._staged:
                fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=path.suffix,
                                           dir=path.parent if str(path.parent) else ".")
                os.close(fd)
                temps.append((Path(tmp), path))
                write(Path(tmp))
            for tmp, path in temps:
                as_new_file(tmp)
                replace_named(tmp, path)
        except BaseException:
            for tmp, _ in temps:
                tmp.unlink(missing_ok=True)
            raise
        return [path for _, path in temps]


def kept_in(paths: list[Path], what: str = "", mark: str = ", marked partial",
            unkept: str = "") -> str:
    """The part of a stopped run's line that says where its results are: "; ``what`` kept in
    A and B``mark``" where ``paths`` were written, ``unkept`` where none was."""
    if not paths:
        return unkept
    return f"; {what + ' ' if what else ''}kept in {' and '.join(map(str, paths))}{mark}"
