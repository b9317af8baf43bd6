"""The measurement table of laser ablations: one row per embryo, in physical units.

Each row holds an embryo's shell (posterior radius R, sheet thickness H), its
cut (the diameter 2R sin Σ of the ablated cap) and its recoil: the opening o,
rotation ϱ and displacement d of the cut edge, optionally the initial recoil
velocity V and the errors of the measures (paper, main text "Quantitative
estimates of the curvature mismatch during *Volvox* invagination…" and
"Recoil velocity measurements yield a bound on the elastic modulus…",
Fig. 2 J–K).  :func:`read_measurements` reads and checks a table,
:class:`Measurement` is one row; every error names the file, row, embryo and
column.

Units: the table is dimensional (µm, degrees, µm/s); the measures convert
once, in :func:`to_dimensionless` and :func:`to_physical`, to lengths in units
of R and angles in radians, the units of the shell theory
(:mod:`morphoshell.inverse` works in them).
"""
from __future__ import annotations

import csv
import difflib
import logging
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Mapping

import numpy as np

from ..model.problem import MIN_THICKNESS

log = logging.getLogger(__name__)

__all__ = [
    "MEASURES", "REQUIRED_COLUMNS", "OPTIONAL_COLUMNS", "MEASURE_COLUMN", "ERROR_COLUMN", "UNITS",
    "MISSING", "MeasurementError", "Measurement", "read_measurements", "to_dimensionless",
    "to_physical",
]

#: The recoil measures, in the order of every vector of the inverse estimates.
MEASURES = ("opening", "rotation", "displacement")

#: Columns of the measurement table.
REQUIRED_COLUMNS = ("embryo", "R_um", "H_um", "hole_diameter_um", "opening_um", "rotation_deg",
                    "displacement_um")
OPTIONAL_COLUMNS = ("V_um_per_s", "sigma_opening_um", "sigma_rotation_deg",
                    "sigma_displacement_um")
#: Column of each measure and of its error; its physical unit.
MEASURE_COLUMN = {"opening": "opening_um", "rotation": "rotation_deg",
                  "displacement": "displacement_um"}
ERROR_COLUMN = {m: f"sigma_{c}" for m, c in MEASURE_COLUMN.items()}
UNITS = {"opening": "um", "rotation": "deg", "displacement": "um"}

_KNOWN = frozenset(REQUIRED_COLUMNS) | frozenset(OPTIONAL_COLUMNS)

#: The spellings of a missing value in a table's cell (any case), as an empty cell: what
#: spreadsheets, R and pandas write for one (``#N/A`` is Excel's).  Not ``-`` or ``0``,
#: which may be values.
MISSING = frozenset({"", "na", "n/a", "#n/a", "nan", "null", "none"})


# --------------------------------------------------------------------------
# units: the one place where physical and dimensionless values meet
# --------------------------------------------------------------------------

def to_dimensionless(measure: str, value: float, R_um: float) -> float:
    """A measure in its table unit (µm or degrees) → units of R or radians.

    Parameters
    ----------
    measure : {"opening", "rotation", "displacement"}
    value : float
        In the table's unit (:data:`UNITS`).
    R_um : float
        The embryo's posterior radius R (µm).

    Returns
    -------
    float
        ``value / R_um`` for a length, the angle in radians for the rotation.
    """
    return math.radians(value) if measure == "rotation" else value / R_um


def to_physical(measure: str, value: float, R_um: float) -> float:
    """A measure in units of R or radians → its table unit (µm or degrees).

    The inverse of :func:`to_dimensionless`.

    Returns
    -------
    float
        ``value * R_um`` for a length, the angle in degrees for the rotation.
    """
    return math.degrees(value) if measure == "rotation" else value * R_um


# --------------------------------------------------------------------------
# one row
# --------------------------------------------------------------------------

class MeasurementError(ValueError):
    """Bad measurement input; the message names the row (embryo) and column.

    ``column`` and ``why`` hold the column and the reason when a cell is bad.
    """

    def __init__(self, message: str, column: str | None = None, why: str | None = None):
        super().__init__(message)
        self.column, self.why = column, why


#: Largest |opening| or displacement of a recoil, in radii: a cut rim cannot move further.
MAX_RECOIL = 10.0


def _check_cell(column: str, value: float | None) -> str | None:
    """Why ``value`` is not acceptable in ``column`` (None if it is)."""
    if value is None:
        return None
    if not math.isfinite(value):
        return f"{value!r} must be a finite number (leave the cell empty for a missing value)"
    if column in ("R_um", "H_um", "hole_diameter_um") or column.startswith("sigma_"):
        return None if value > 0 else f"{value!r} must be positive"
    if column in ("displacement_um", "V_um_per_s"):
        return None if value >= 0 else f"{value!r} must be non-negative (a distance or speed)"
    if column == "rotation_deg":
        return None if -180 < value < 180 else f"{value!r} must lie in (-180, 180) degrees"
    return None


@dataclass(frozen=True)
class Measurement:
    """One embryo's ablation: shell, cut and recoil, in the table's physical units.

    Parameters
    ----------
    embryo : str
        Label.
    R_um, H_um : float
        Posterior radius R and sheet thickness H (µm), 0 < H < R.
    hole_diameter_um : float
        Diameter 2R sin Σ of the ablated cap on the intact shell (µm), ≤ 2R.
    opening_um, rotation_deg, displacement_um : float or None
        R·o (signed change of the hole's diameter), ϱ (degrees, positive when
        the edge unfurls outwards, in (−180, 180)), R·d (≥ 0); None where the
        table has no value.
    V_um_per_s : float or None
        Initial recoil velocity (µm/s, ≥ 0).
    sigma_opening_um, sigma_rotation_deg, sigma_displacement_um : float or None
        Errors of the measures (one standard deviation, > 0).
    extra : mapping
        Other columns of the row, kept as text and otherwise ignored.
    row : int
        1-based data row of the table (0 when built in code).

    Raises
    ------
    MeasurementError
        Naming the row (if any), embryo and column of a bad value.
    """

    embryo: str
    R_um: float
    H_um: float
    hole_diameter_um: float
    opening_um: float | None = None
    rotation_deg: float | None = None
    displacement_um: float | None = None
    V_um_per_s: float | None = None
    sigma_opening_um: float | None = None
    sigma_rotation_deg: float | None = None
    sigma_displacement_um: float | None = None
    extra: Mapping[str, str] = field(default_factory=dict)
    row: int = 0

    def __post_init__(self):
        if not str(self.embryo).strip():
            self._fail("embryo", "the embryo label is empty")
        for column in (*REQUIRED_COLUMNS[1:], *OPTIONAL_COLUMNS):
            value = getattr(self, column)
            if value is None and column in REQUIRED_COLUMNS[1:4]:
                self._fail(column, "the cell is empty (required)")
            if value is not None:
                if isinstance(value, bool) or not isinstance(value, (int, float, np.number)):
                    self._fail(column, f"{value!r} is not a number")
                object.__setattr__(self, column, float(value))
            why = _check_cell(column, getattr(self, column))
            if why:
                self._fail(column, why)
        if not self.H_um < self.R_um:
            self._fail("H_um", f"the thickness H = {self.H_um!r} um must be smaller than the "
                               f"radius R = {self.R_um!r} um")
        if self.H_um < MIN_THICKNESS * self.R_um:
            self._fail("H_um", f"the thickness H = {self.H_um!r} um is below {MIN_THICKNESS:g} "
                               f"of the radius R = {self.R_um!r} um: thinner than the model "
                               f"resolves (check the units: um)")
        for column in ("opening_um", "displacement_um"):
            value = getattr(self, column)
            if value is not None and abs(value) > MAX_RECOIL * self.R_um:
                self._fail(column, f"{value!r} um is more than {MAX_RECOIL:g} radii (R = "
                                   f"{self.R_um!r} um): not a recoil of this shell (check the "
                                   f"units: um)")
        if self.hole_diameter_um > 2 * self.R_um:
            self._fail("hole_diameter_um", f"the hole ({self.hole_diameter_um!r} um) is larger "
                                           f"than the shell (diameter 2R = {2 * self.R_um!r} um)")

    def _fail(self, column: str, why: str):
        where = f"row {self.row} (embryo {self.embryo!r})" if self.row else \
            f"embryo {self.embryo!r}"
        raise MeasurementError(f"{where}, column {column!r}: {why}", column, why)

    @property
    def h(self) -> float:
        """Relative thickness H/R."""
        return self.H_um / self.R_um

    @property
    def cut(self) -> float:
        """The cut Σ = arcsin(hole diameter / 2R) (radians, = units of R on the sphere)."""
        return math.asin(min(1.0, self.hole_diameter_um / (2 * self.R_um)))

    @property
    def Sigma(self) -> float:
        """Deprecated alias of :attr:`cut` (the one name of the cut)."""
        return self.cut

    def value(self, measure: str) -> float | None:
        """The measure in units of R or radians (None where the table has no value)."""
        v = getattr(self, MEASURE_COLUMN[measure])
        return None if v is None else to_dimensionless(measure, v, self.R_um)

    def error(self, measure: str) -> float | None:
        """Its error in units of R or radians (None if not given)."""
        v = getattr(self, ERROR_COLUMN[measure])
        return None if v is None else to_dimensionless(measure, v, self.R_um)


# --------------------------------------------------------------------------
# the table
# --------------------------------------------------------------------------

def _number(text: str) -> float | None:
    """The number in a cell; None for a missing value (:data:`MISSING`)."""
    if text.lower() in MISSING:
        return None
    try:
        return float(text)
    except ValueError:
        raise ValueError(f"{text!r} is not a number (a missing value is an empty cell or "
                         f"{', '.join(sorted(m.upper() for m in MISSING if m))})") from None


def _read_text(path: Path) -> str:
    """The file's text (a BOM dropped); each way it cannot be read is named."""
    try:
        return path.read_text(encoding="utf-8-sig")
    except FileNotFoundError:
        raise MeasurementError(f"{path}: no such file") from None
    except IsADirectoryError:
        raise MeasurementError(f"{path}: is a folder, not a measurement table") from None
    except UnicodeDecodeError:
        raise MeasurementError(f"{path}: not a UTF-8 text (CSV) file") from None
    except OSError as exc:
        raise MeasurementError(f"{path}: cannot be read ({exc.strerror})") from None


def _data_lines(path: Path, text: str) -> list[tuple[int, str]]:
    """(line number, line) of the header and rows: blank lines and ``#`` comments dropped."""
    lines = [(i, line) for i, line in enumerate(text.splitlines(), 1)
             if line.strip() and not line.lstrip().startswith("#")]
    if not lines:
        raise MeasurementError(f"{path}: empty file (no header row; columns "
                               f"{', '.join(REQUIRED_COLUMNS)} are required)")
    return lines


def _check_header(path: Path, header: list[str], line_no: int) -> None:
    """Every column once, the required ones present."""
    repeated = sorted({c for c in header if header.count(c) > 1})
    if repeated:
        raise MeasurementError(f"{path}: column(s) {repeated} appear more than once")
    missing = [c for c in REQUIRED_COLUMNS if c not in header]
    if missing:
        hint = "; the columns are separated by ';', not ','" if len(header) == 1 \
            and ";" in header[0] else ""
        raise MeasurementError(f"{path}: missing column(s) {missing} (line {line_no} is "
                               f"the header; required: {', '.join(REQUIRED_COLUMNS)}{hint})")
    for column in header:
        if column not in _KNOWN:
            near = difflib.get_close_matches(column, [c for c in OPTIONAL_COLUMNS
                                                      if c not in header], n=1, cutoff=0.7)
            if near:    # kept and ignored, silently, would drop the errors or E/μ it feeds
                log.warning("%s: column %r is not read (did you mean %r?)", path, column,
                            near[0])


def _where(path: Path, n: int, line_no: int, label: str) -> str:
    """How errors name data row ``n``: file, row, line and embryo."""
    return f"{path}: row {n} (line {line_no}, embryo {label!r})"


def _row(path: Path, header: list[str], n: int, line_no: int, cells: list[str]) -> Measurement:
    """Data row ``n`` (on line ``line_no``) as a :class:`Measurement`, its errors placed."""
    cells = [c.strip() for c in cells]
    label = cells[header.index("embryo")] if len(cells) > header.index("embryo") else ""
    where = _where(path, n, line_no, label)
    if len(cells) != len(header):
        raise MeasurementError(f"{where}: {len(cells)} cells, but the header has "
                               f"{len(header)} columns")
    values: dict = {"embryo": label, "row": n,
                    "extra": {c: v for c, v in zip(header, cells) if c not in _KNOWN}}
    for column, cell in zip(header, cells):
        if column in _KNOWN and column != "embryo":
            try:
                values[column] = _number(cell)
            except ValueError as exc:
                raise MeasurementError(f"{where}, column {column!r}: {exc}") from None
    try:
        return Measurement(**values)
    except MeasurementError as exc:
        raise MeasurementError(f"{where}, column {exc.column!r}: {exc.why}", exc.column,
                               exc.why) from None


#: Rows with a rotation from which a table whose every rotation lies within ±π is noted as
#: perhaps in radians (:func:`_note_radians`).
RADIANS_ROWS = 5


def _note_radians(path: Path, rows: tuple[Measurement, ...]) -> None:
    """Warn (a note, not a refusal) when the rotations look like radians in a column of degrees.

    The rule: at least :data:`RADIANS_ROWS` rows hold a rotation and every one lies within
    ±π.  Any rotation in radians does (|ϱ| < 180° is |ϱ| < π rad), so the rule notes every
    such table of that size.  In degrees it needs each embryo's edge to turn by less than
    π° = 0.055 rad, where the leading order ϱ = √(3h/2)(1 − k) (docs, inverse.md) gives
    0.27–0.67 rad (16–38°) at k = 0 for h = H/R between 0.05 and 0.3: every embryo of the
    table would need k within 0.2 of 1 (an edge that hardly recoils) at once.  Fewer rows
    are not noted: one or two such embryos are plausible.
    """
    held = [(m.row or i, m.rotation_deg) for i, m in enumerate(rows, 1)
            if m.rotation_deg is not None]
    if len(held) < RADIANS_ROWS or any(abs(v) > math.pi for _, v in held):
        return
    largest = max(abs(v) for _, v in held)
    log.warning("%s: column 'rotation_deg', rows %s: every rotation lies within ±π (largest "
                "|rotation| %.3g): radians in a column of degrees? So small a recoil in every "
                "embryo is rare (degrees = radians × 57.3); read as degrees", path,
                _row_ranges([n for n, _ in held]), largest)


def _row_ranges(rows: list[int]) -> str:
    """Row numbers as runs: ``1-4, 6, 8-9``."""
    runs: list[list[int]] = []
    for n in rows:
        if runs and n == runs[-1][-1] + 1:
            runs[-1].append(n)
        else:
            runs.append([n])
    return ", ".join(f"{r[0]}-{r[-1]}" if len(r) > 1 else f"{r[0]}" for r in runs)


def read_measurements(path: str | Path) -> tuple[Measurement, ...]:
    """Read a measurement table (CSV, one row per embryo; see :class:`Measurement`).

    The header names the columns (:data:`REQUIRED_COLUMNS`, optionally
    :data:`OPTIONAL_COLUMNS`; others are kept in ``extra``).  Lines starting
    with ``#`` (before or between rows) are comments; an empty cell, and
    ``NA``, ``N/A``, ``#N/A``, ``NaN``, ``null`` or ``None`` in any case
    (:data:`MISSING`, what spreadsheets, R and pandas write), is a missing
    value (allowed for the measures, velocity and errors).  A table of at
    least :data:`RADIANS_ROWS` rotations, all within ±π, is read as it is
    with a warning naming the column and rows: radians in a column of
    degrees? (the rule: :func:`_note_radians`).

    Parameters
    ----------
    path : str or Path
        The CSV file (UTF-8, a byte-order mark allowed).

    Returns
    -------
    tuple of Measurement, length n_rows
        The rows in the order of the file.

    Raises
    ------
    MeasurementError
        Naming the file, row (with its line and embryo) and column: a missing
        or repeated column, a non-numeric, infinite or out-of-range cell, a hole
        larger than the shell, a repeated embryo label, an empty file.
    """
    path = Path(path)
    lines = _data_lines(path, _read_text(path))
    rows = list(csv.reader([line for _, line in lines]))
    header = [c.strip() for c in rows[0]]
    _check_header(path, header, lines[0][0])
    if len(rows) == 1:
        raise MeasurementError(f"{path}: no measurements (only a header)")
    out, seen = [], {}
    for n, ((line_no, _), cells) in enumerate(zip(lines[1:], rows[1:]), 1):
        m = _row(path, header, n, line_no, cells)
        if m.embryo in seen:
            raise MeasurementError(f"{_where(path, n, line_no, m.embryo)}, column 'embryo': "
                                   f"the label {m.embryo!r} is also row {seen[m.embryo]}'s")
        seen[m.embryo] = n
        out.append(m)
    _note_radians(path, tuple(out))
    return tuple(out)
