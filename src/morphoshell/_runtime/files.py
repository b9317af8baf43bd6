"""Files written all or nothing: a temporary file beside the target, then a rename."""
from __future__ import annotations

import os
from pathlib import Path

__all__ = ["as_new_file", "replace_named"]


def as_new_file(tmp: str | Path) -> None:
    """Give ``tmp``, a temporary file from :func:`tempfile.mkstemp` (private: mode 0600),
    the permissions of a new file under the umask, before it is renamed to its target:
    results on a shared disk are readable by the colleagues the umask admits."""
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(tmp, 0o666 & ~umask)


def replace_named(tmp: str | Path, path: str | Path) -> None:
    """Rename ``tmp`` to ``path`` (:func:`os.replace`); an error names ``path``, the file
    the user asked for, not the hidden temporary one (``.t01_free.t3l5exwr.tmp``)."""
    try:
        os.replace(tmp, path)
    except OSError as exc:
        raise OSError(exc.errno, f"cannot write it: {exc.strerror}", str(path)) from None
