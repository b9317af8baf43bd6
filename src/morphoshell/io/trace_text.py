"""The text forms of trace files: bytes to lines, cells, a header and numbers.

A text trace is one point per line, two numbers (x, y in pixels, or r, z in
units of R), as Fiji, a spreadsheet or a script writes them.  Accepted:

* cells separated by commas, or by tabs or spaces (runs of them count as one);
* a header line ``x,y`` (pixels) or ``r,z`` / ``r,z,spread`` (units of R), in
  any case and quoted or not, its columns in any order (``y,x``, ``z,r,spread``:
  read by name); pixels may also come without a header, as Fiji's
  *File › Save As › XY Coordinates…* writes them;
* a first column of row numbers 1, 2, 3, … (or 0, 1, 2, …) under an empty
  header cell, as Fiji's Results table and pandas write it (``" ,X,Y"``);
* a delimiter at the end of lines (``X,Y,``), a byte-order mark, CRLF line
  ends, blank lines and ``#`` comment lines.

Refused with a message naming the file, the line and the forms above: cells
separated by semicolons (a spreadsheet with decimal commas), a pixel list
(x, y, value), another header, a header without points, a ragged or
non-numeric row; and files that are not text: an image or a PDF (by their
first bytes), UTF-16 text (save as UTF-8), a zip (an ImageJ ROI Manager set, read by
:mod:`morphoshell.io.roi_sets`).
"""
from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np

from .trace_checks import MidlineError

__all__ = ["ZIP_MAGIC", "read_bytes", "text_format", "read_table"]

#: The first bytes of a zip file (an ImageJ ROI Manager set, :mod:`morphoshell.io.roi_sets`).
ZIP_MAGIC = b"PK\x03\x04"
#: The first bytes of files often passed by mistake, and what they are.
_MAGIC = ((b"\x89PNG", "an image (PNG)"), (b"\xff\xd8\xff", "an image (JPEG)"),
          (b"II*\x00", "an image (TIFF)"), (b"MM\x00*", "an image (TIFF)"),
          (b"GIF8", "an image (GIF)"), (b"%PDF", "a PDF document"))
_CSV_HEADERS = (("r", "z"), ("r", "z", "spread"))
_XY_HEADER = ("x", "y")
_PIXEL_DUMP = ("this is a pixel list (x, y, value) from Analyze › Tools › Save XY Coordinates, "
               "not a line: save the line selection with File › Save As › XY Coordinates")
#: A number written with a decimal comma (European spreadsheet settings).
_DECIMAL_COMMA = re.compile(r"[-+]?\d*,\d+([eE][-+]?\d+)?")
#: The accepted forms, for messages.
_FORMS = ("a trace file has a header 'x,y' (pixels) or 'r,z' (units of R), in any order, or none, "
          "and two numbers x, y per line, separated by commas, tabs or spaces")


def read_bytes(path: Path) -> bytes:
    """The bytes of the file ``path``; MidlineError naming it if it cannot be read."""
    try:
        return path.read_bytes()
    except OSError as exc:
        raise MidlineError(f"{path}: cannot read: {exc.strerror}") from None


def _lines(path: Path, data: bytes) -> list[tuple[int, str]]:
    """(line number, stripped text) of every line; MidlineError if not UTF-8 text."""
    if data[:4] == ZIP_MAGIC:       # (was "line 1: not UTF-8 text (byte 11)")
        raise MidlineError(f"{path}: a zip file (an ImageJ ROI Manager set?), not text: read it "
                           f"with format 'roi' or none")
    for magic, what in _MAGIC:      # (was "line 1: not UTF-8 text (byte 0)")
        if data.startswith(magic):
            raise MidlineError(f"{path}: {what}, not a trace: trace the midline on it in Fiji and "
                               f"save the line (File › Save As › XY Coordinates… or Selection…)")
    if _utf16(data):
        raise MidlineError(f"{path}: UTF-16 text: save it as UTF-8 (a spreadsheet's 'CSV UTF-8', "
                           f"a text editor's encoding UTF-8)")
    try:
        text = data.decode("utf-8-sig")     # Excel writes a byte-order mark
    except UnicodeDecodeError as exc:
        line = data[:exc.start].count(b"\n") + 1
        raise MidlineError(f"{path}: line {line}: not UTF-8 text (byte {exc.start})") from None
    return [(i, line.strip()) for i, line in enumerate(text.splitlines(), 1)]


def _utf16(data: bytes) -> bool:
    """UTF-16 by its byte-order mark, or by every other byte of its first ones being zero."""
    if data[:2] in (b"\xff\xfe", b"\xfe\xff"):
        return True
    head = data[:64]
    return len(head) >= 4 and (not any(head[1::2]) or not any(head[0::2]))


def _content(path: Path, data: bytes):
    """The ``#`` comments and the other non-blank lines (number, text) of a text trace."""
    lines = _lines(path, data)
    comments = [s[1:].strip() for _, s in lines if s.startswith("#")]
    body = [(i, s) for i, s in lines if s and not s.startswith("#")]
    if not body:
        raise MidlineError(f"{path}: empty file: no points")
    return comments, body


def _delimiter(path: Path, line: int, text: str) -> str | None:
    """"," or None (runs of whitespace) from one line; MidlineError for semicolons and
    decimal commas (a spreadsheet of European settings writes both)."""
    if ";" in text:
        raise MidlineError(f"{path}: line {line}: cells separated by ';' (a spreadsheet with "
                           f"decimal commas?): save it with ',' between cells and '.' in numbers, "
                           f"or with tabs; {_FORMS}")
    words = text.split()
    if len(words) >= 2 and all(_DECIMAL_COMMA.fullmatch(w) for w in words):
        raise MidlineError(f"{path}: line {line}: numbers with decimal commas ({words[0]!r}): "
                           f"save them with '.' (a spreadsheet's language settings); {_FORMS}")
    return "," if "," in text else None


def _cells(text: str, delimiter: str | None) -> list[str]:
    """The cells of a line, unquoted, without an empty one after a final delimiter."""
    cells = [c.strip().strip('"').strip() for c in text.split(delimiter)]
    return cells[:-1] if delimiter and len(cells) > 1 and not cells[-1] else cells


def _is_number(cell: str) -> bool:
    try:
        float(cell)
    except ValueError:
        return False
    return True


def text_format(path: Path, data: bytes) -> str:
    """The format of a text trace from its first line: csv (``r,z``), xy (``x,y``) or fiji-xy.

    Parameters
    ----------
    path : Path
        The file, for messages.
    data : bytes
        Its content.

    Returns
    -------
    str
        "csv", "xy", or "fiji-xy" for a file without a header.

    Raises
    ------
    MidlineError
        Not text, empty, a pixel list, semicolons, or an unrecognised header.
    """
    _, body = _content(path, data)
    i, first = body[0]
    names = tuple(c.lower() for c in _cells(first, _delimiter(path, i, first)))
    if _named(names, _CSV_HEADERS):
        return "csv"
    if _named(names[1:] if names[:1] == ("",) else names, (_XY_HEADER,)):
        return "xy"
    if all(_is_number(c) for c in names):
        return "fiji-xy"
    if {"x", "y"} <= set(names):
        raise MidlineError(f"{path}: line {i}: columns {first!r}: {_PIXEL_DUMP}")
    raise MidlineError(f"{path}: line {i}: unrecognised header {first!r}; {_FORMS}")


def read_table(path: Path, data: bytes, fmt: str):
    """The columns and numbers of a text trace in the format ``fmt``.

    Parameters
    ----------
    path : Path
        The file, for messages.
    data : bytes
        Its content.
    fmt : str
        "csv" (a header ``r,z`` or ``r,z,spread`` required), "xy" or "fiji-xy"
        (pixels; a header ``x,y`` optional; the two read alike).

    Returns
    -------
    header : tuple of str
        The column names, lower case, in the order of :data:`_CSV_HEADERS` or
        ("x", "y") whatever their order in the file ("x", "y" for a file
        without a header).
    values : ndarray, shape (n, len(header))
        The numbers, their columns in the order of ``header``.
    where : list of str
        "line i" of each row.
    comments : list of str
        The ``#`` comment lines, without the ``#``.

    Raises
    ------
    MidlineError
        Naming the file and line: see the module docstring.
    """
    comments, body = _content(path, data)
    first = body[0]
    names, delimiter, index, body = _header(path, body, fmt)
    if not body:            # (a header alone: the readers' checks would index no points)
        raise MidlineError(f"{path}: no points: only the header {first[1]!r} (line {first[0]})")
    values = np.empty((len(body), len(names) + index))
    for k, (i, text) in enumerate(body):     # (messages name the columns as the file does)
        values[k] = _row(path, i, _cells(text, delimiter), ("row number",) * index + names)
    if index:
        _check_row_numbers(path, values[:, 0], body)
    header = _named(names, _CSV_HEADERS + (_XY_HEADER,))
    order = [names.index(c) for c in header]
    return header, values[:, index:][:, order], [f"line {i}" for i, _ in body], comments


def _named(names: tuple[str, ...], headers) -> tuple[str, ...] | None:
    """The header of ``headers`` whose columns ``names`` are, in any order (None if none is):
    an honest header is read by its names, so that ``y,x`` is not taken for ``x,y``."""
    for header in headers:
        if len(names) == len(header) and sorted(names) == sorted(header):
            return header
    return None


def _header(path: Path, body: list[tuple[int, str]], fmt: str):
    """Column names, delimiter, whether a row-number column leads, and the data lines."""
    (i, text), rows = body[0], body[1:]
    delimiter = _delimiter(path, i, text)
    cells = _cells(text, delimiter)
    if all(_is_number(c) for c in cells):
        if fmt == "csv":
            raise MidlineError(f"{path}: line {i}: no header: a csv trace starts with the line "
                               f"'r,z' (units of R); a trace in pixels is read with format 'xy' "
                               f"and a scale")
        if len(cells) >= 3:
            raise MidlineError(f"{path}: line {i}: {len(cells)} columns: {_PIXEL_DUMP}")
        return _XY_HEADER, delimiter, False, body
    names = tuple(c.lower() for c in cells)
    # a row-number column under an empty header cell, or none (whitespace between cells
    # swallows an empty one): the data lines have a cell more than the names
    index = names[:1] == ("",) or (bool(rows) and
                                   len(_cells(rows[0][1], delimiter)) == len(names) + 1)
    names = names[1:] if names[:1] == ("",) else names
    expected = _CSV_HEADERS if fmt == "csv" else (_XY_HEADER,)
    if not _named(names, expected):
        if {"x", "y"} <= set(names) and len(names) > 2:
            raise MidlineError(f"{path}: line {i}: columns {text!r}: {_PIXEL_DUMP}")
        if _named(names, (_XY_HEADER,)) and fmt == "csv":  # (a campaign's folder lists midlines)
            raise MidlineError(f"{path}: line {i}: a trace in image pixels (header {text!r}), "
                               f"where a midline in units of R (header 'r,z') is read: "
                               f"`morphoshell average TRACE... --pixel-size ... --radius-um "
                               f"... --csv MIDLINE.csv` writes one")
        raise MidlineError(f"{path}: line {i}: header {text!r} is not "
                           f"{' or '.join(repr(','.join(h)) for h in expected)} in any order "
                           f"(format {fmt!r}); {_FORMS}")
    return names, delimiter, index, rows


def _row(path: Path, line: int, cells: list[str], header: tuple[str, ...]) -> list[float]:
    """The finite numbers of one data line, one per column of ``header``."""
    if len(cells) != len(header):
        raise MidlineError(f"{path}: line {line}: {len(cells)} values, expected {len(header)} "
                           f"({', '.join(header)}); {_FORMS}")
    row = []
    for j, cell in enumerate(cells):
        where = f"{path}: line {line}, column {j + 1} ({header[j]})"
        try:
            value = float(cell)
        except ValueError:
            hint = (": a decimal comma? save numbers with '.'" if _DECIMAL_COMMA.fullmatch(cell)
                    else "")
            raise MidlineError(f"{where}: {cell!r} is not a number{hint}") from None
        if not math.isfinite(value):
            raise MidlineError(f"{where}: {cell} is not finite")
        row.append(value)
    return row


def _check_row_numbers(path: Path, numbers: np.ndarray, body) -> None:
    """MidlineError unless a first column without a name counts the rows from 0 or 1."""
    start = numbers[0] if numbers[0] in (0.0, 1.0) else 1.0
    wrong = np.flatnonzero(numbers != start + np.arange(len(numbers)))
    if len(wrong):
        k = wrong[0]
        raise MidlineError(f"{path}: line {body[k][0]}: the first column, without a name, holds "
                           f"{numbers[k]:g} where a row number would be {start + k:g}: delete "
                           f"that column, or name the columns (x,y)")
