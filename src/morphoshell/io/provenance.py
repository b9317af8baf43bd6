"""Where a written result came from: the code that made it and the files it read.

Every JSON file the package writes ends with a ``provenance`` entry
(:func:`provenance`): the versions of morphoshell and of the numeric libraries, the time,
and, when the package runs from a git checkout, the commit and whether the package's
source differs from it (``git_commit``, ``git_modified``).  The version string alone does
not identify the code: it stayed "0.1.0" while commits changed the numbers (audit 27: one
fit's kappa1 moved by 0.2 1/R between two files with equal provenance).  Commands that read
a problem or data file add it under ``inputs``: its absolute path and SHA-256
(:func:`input_record`), the checksum that campaign records keep for their data.

``provenance["format"]`` is the version of the files' format (:data:`FORMAT`): a reader
refuses a file of a newer format in one line (:func:`check_format`), and the readers that
know their records' entries warn once of entries they do not know (:func:`note_unknown`).
A file without it was written before it was recorded (format 0) and is read as before.
"""
from __future__ import annotations

import datetime as _dt
import functools
import hashlib
import logging
import subprocess
import sys
from pathlib import Path
from typing import Any, Iterable, Mapping

__all__ = ["FORMAT", "provenance", "code_commit", "input_record", "sha256_of", "check_format",
           "note_unknown"]

#: The format of the files the package writes: raised when a reader of this version would
#: misread a file of the next (a meaning changed, an entry renamed), with a CHANGELOG entry.
#: Added entries that older readers may ignore do not raise it.
FORMAT = 1

log = logging.getLogger(__name__)
#: The (reader, entry) pairs already warned of: once per process.
_WARNED: set[tuple[str, str]] = set()

#: The package's folder (``src/morphoshell`` in a checkout).
_PACKAGE = Path(__file__).resolve().parent.parent


def sha256_of(path: str | Path) -> str:
    """The SHA-256 of a file's bytes, as hexadecimal."""
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def input_record(path: str | Path) -> dict[str, str]:
    """``{"path": absolute path, "sha256": checksum}`` of an input file (the path as typed
    is relative to a working directory that no file records)."""
    return {"path": str(Path(path).resolve()), "sha256": sha256_of(path)}


def _git(*args: str) -> str:
    """The output of ``git -C <package folder> ARGS`` (CalledProcessError, OSError on
    failure; a timeout, not a hang, if git waits for something)."""
    return subprocess.run(["git", "-C", str(_PACKAGE), *args], capture_output=True,
                          text=True, check=True, timeout=10).stdout


@functools.lru_cache(maxsize=1)
def code_commit() -> dict[str, object]:
    """``{"git_commit": hash, "git_modified": bool}`` of the checkout the package runs from,
    or ``{}`` (installed from a wheel, git missing): once per process.

    ``git_modified`` is whether the package's source folder (``src/`` in a checkout) differs
    from the commit, untracked files included.  A package installed inside some other
    repository (a virtual environment in a checkout) is not that repository's commit: its
    ``__init__.py`` must be a tracked file.
    """
    try:
        _git("ls-files", "--error-unmatch", "__init__.py")
        commit = _git("rev-parse", "HEAD").strip()
        changed = _git("status", "--porcelain", "--", str(_PACKAGE.parent)).strip()
    except (OSError, subprocess.SubprocessError):
        return {}
    return {"git_commit": commit, "git_modified": bool(changed)}


def provenance(inputs: Iterable[str | Path] = ()) -> dict[str, object]:
    """Versions, the git commit (:func:`code_commit`), the time and the ``inputs`` files
    (:func:`input_record`, absent when there are none), for reproducibility of written
    results."""
    import casadi
    import numpy
    import scipy

    from .. import __version__
    files = [input_record(p) for p in inputs]
    return {"morphoshell": __version__, "format": FORMAT, **code_commit(),
            "casadi": casadi.__version__,
            "numpy": numpy.__version__, "scipy": scipy.__version__,
            "python": sys.version.split()[0],
            "written": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
            **({"inputs": files} if files else {})}


def check_format(record: Any, where: str) -> None:
    """Refuse (ValueError, one line naming ``where``) a record of a newer format than
    :data:`FORMAT` or one whose ``provenance.format`` is not a format number; a record
    without one (older, or not a mapping) passes."""
    stamp = record.get("provenance") if isinstance(record, Mapping) else None
    found = stamp.get("format") if isinstance(stamp, Mapping) else None
    if found is None:
        return
    if isinstance(found, bool) or not isinstance(found, int) or found < 0:
        raise ValueError(f"{where}: provenance.format = {found!r} is not a format number")
    if found > FORMAT:
        made = stamp.get("morphoshell", "a newer morphoshell")
        raise ValueError(f"{where}: written in file format {found} (by morphoshell {made}); "
                         f"this morphoshell reads format {FORMAT} and older: update it")


def note_unknown(record: Mapping[str, Any], known: Iterable[str], where: str,
                 reader: str) -> None:
    """Warn, once per process and ``reader``, of the entries of ``record`` that ``known``
    does not hold: they are not read (a file edited by hand, or of a newer version that
    added them)."""
    unknown = [k for k in record if k not in set(known) and (reader, k) not in _WARNED]
    if unknown:
        _WARNED.update((reader, k) for k in unknown)
        log.warning("%s: entries %s are not read by %s (edited by hand, or written by a newer "
                    "morphoshell?)", where, ", ".join(map(repr, unknown)), reader)
