"""Traced midlines of embryos: reading, alignment, resampling and averaging.

Biologists trace the cell sheet of an embryo's mid-sagittal section in
Fiji/ImageJ.  A fit (documentation: "Problems and families", Volvox) needs it as a *half midline in the
model gauge*: points (r_i, z_i) equally spaced in arclength from the posterior
pole, at the origin, to the rim; the axis of symmetry along z, z growing
toward the anterior, r ≥ 0 the distance from the axis; lengths in units of
the embryo radius R.  Four functions get there:

``read_trace``  a file → :class:`Trace` (points in units of R);
``align``       a trace → :class:`Alignment` (half midline in the model gauge);
``resample``    points → N points equally spaced in arclength, ends included;
``average``     midlines of one stage → :class:`Midline` with a pointwise spread.

:func:`load_midline` chains the first three; :func:`write_trace` writes a
model-gauge midline as an image trace (synthetic microscope data, tests).

Formats
-------
``csv``      header ``r,z`` (or ``r,z,spread``), units of R, model gauge,
             posterior pole first; lines starting with ``#`` are comments.
             :meth:`Midline.to_csv` writes it.
``xy``       header ``x,y``, comma-separated image pixels, y pointing down.
``fiji-xy``  Fiji's *File › Save As › XY Coordinates…* of a line selection:
             no header, ``x<TAB>y`` per line, y pointing down.  Fiji writes
             calibrated units if the image is spatially calibrated: then pass
             ``pixel_size_um=1`` (for µm).  The three-column file of
             *Analyze › Tools › Save XY Coordinates…* lists the pixels of an
             image, not a line, and is refused.
``roi``      an ImageJ ``.roi`` file (via ``roifile``) of a segmented, freehand
             or straight line, y pointing down.

The format is inferred from the content when not given: the ROI magic
``Iout``, else the header line (``r,z`` → csv, ``x,y`` → xy, numbers →
fiji-xy).  Image coordinates need ``pixel_size_um`` (µm per pixel) and
``radius_um`` (R in µm): a pixel (x, y) becomes (x, −y)·pixel_size_um/radius_um.
y is flipped so that the trace's frame is right-handed; the aligned midline
does not depend on it (a mirror image of a section aligns to the same half).

Spline-fit ROIs
---------------
A line that was *Edit › Selection › Fit Spline*-ed is stored as its control
points with the SPLINE_FIT flag; ImageJ redraws the spline when it reads
it.  This module does the same: the curve is ImageJ's (``PolygonRoi``, since
1.52): natural cubic splines x(t), y(t) through the control points, the
parameter t advancing by the square root of the distance between
consecutive points, evaluated at :data:`SPLINE_SUBDIVISIONS` points per
control interval.  (Older ImageJ versions advanced t by 1 per point; their
curves differ slightly between control points.)

Alignment
---------
*csv* traces are already in the model gauge and are taken as they are.
Image traces have an arbitrary rotation and offset; ``section`` says what was
traced:

``"whole"``  rim to rim through the posterior pole.  The pole is taken at
             mid-arclength (a section traced from rim to rim has halves of
             equal length), and the axis is the line that best maps the point
             at arclength L/2 + σ onto the mirror image of the one at L/2 − σ,
             0 < σ ≤ L/2: least squares of the mismatch across the curve,
             with the mismatch along it weighted 1/100 (noise makes the
             arclengths of the halves fluctuate, shifting partners along the
             curve, which says nothing about the axis; the small weight keeps
             a circular arc, symmetric about any diameter, determined by where
             its rims are); then again with a soft-L1 loss scaled to the
             residuals, so that a few stray points do not pull the axis.
             The pole is where the axis crosses the curve; the two halves,
             each from the pole to its rim, are mirrored onto r ≥ 0 and
             averaged at equal fractions of their lengths.  The pole's height
             along the axis is then that of a least-squares fit
             z = z₀ + a s² + b s⁴ of the average within 0.3 R of arclength s
             from it, not that of the one noisy point where the axis crosses
             the trace: that point's error would shift the whole midline
             along z.  A section whose
             halves differ by more than ``max_asymmetry`` (rms, units of R)
             is refused.
``"half"``   pole to rim, the pole first.  A regular pole of an axisymmetric
             surface has its tangent perpendicular to the axis, so the axis
             is the normal to the trace at its first point and r grows along
             the trace's first tangent.  That tangent is the end slope of the
             interpolating spline: exact for clean (synthetic) data, but it
             rests on the first few points, so noise σ at point spacing h
             tilts the axis by ~σ/h radians (tens of degrees for pixel noise
             on a dense trace).  Trace whole sections from real images.
``"auto"``   csv → half; image formats → whole.  Shape alone cannot tell: a
             circular arc traced from pole to rim is mirror-symmetric about
             its middle exactly as a whole section of a cup is, so a half
             image trace must be declared (a non-symmetric one passed as
             whole fails the asymmetry check with a message that says so).

The axis points toward the anterior, taken to be the side of the pole where
the rims are (z_rim > 0, true until late inversion); ``flip=True`` reverses it.

Noise and arclength
-------------------
Noise σ on points at spacing h lengthens a curve through them by a fraction
~(σ/h)² (80 % for half-pixel noise on a one-pixel freehand trace), and
unevenly, which moves equally spaced points along the curve.  So alignment
first estimates σ (fourth differences across the curve) and, if σ/h exceeds
1/20, averages the interior points in bins of k consecutive ones, the least
k that brings the ratio below 1/20 (noise σ/√k at spacing kh); the end
points are kept.  A bin's mean lies inside a curved line, by ½κ(k² − 1)h²/12,
so each mean is moved back out by that amount, with the curvature from its
neighbouring means.  Clean traces are left as they are.  What noise still
leaves along the curve, :func:`average` removes by resampling the mean of the
traces in its own arclength.

Errors
------
Bad files and options raise :class:`MidlineError` (a ``ValueError``) with one
line naming the file and the line, point or option, before any fitting.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

import numpy as np

from .._runtime.validate import real

__all__ = ["FORMATS", "SECTIONS", "MidlineError", "Trace", "Alignment", "Midline", "read_trace",
           "align", "resample", "load_midline", "average", "to_image", "write_trace"]

#: Trace file formats (see the module docstring).
FORMATS = ("csv", "xy", "fiji-xy", "roi")
#: What a trace covers (see the module docstring).
SECTIONS = ("auto", "whole", "half")
#: Points per control interval at which a spline-fit ROI is evaluated.
SPLINE_SUBDIVISIONS = 32

_CSV_HEADERS = (("r", "z"), ("r", "z", "spread"))
_XY_HEADER = ("x", "y")
_PIXEL_DUMP = ("this is a pixel list (x, y, value) from Analyze › Tools › Save XY Coordinates, "
               "not a line: save the line selection with File › Save As › XY Coordinates")
#: A step longer than _GAP_STEPS median steps and _GAP_FRACTION of the trace joins two curves.
_GAP_STEPS, _GAP_FRACTION = 10.0, 0.05
#: How far (units of R) an aligned midline may stray to r < 0: noise near the pole, no more.
_AXIS_SLACK = 0.05
#: How far (units of R) a trace may reach from its first point: a Volvox midline lies within
#: about 2 R of its pole; farther is a trace in other units (at 1e300 the spline overflowed).
_MAX_EXTENT = 20.0
#: Samples of σ in the mirror fit of a whole section, and the weight of the mismatch along the
#: curve relative to across it (module docstring).
_MIRROR_SAMPLES, _ALONG_WEIGHT = 200, 0.01
#: Arclength (units of R) from the pole of a whole section over which its height is fitted,
#: and the even powers of arclength fitted there: 1, s², s⁴ (:func:`_pole_height`).
_POLE_WINDOW, _POLE_TERMS = 0.3, 3
#: Largest ratio of point noise to point spacing that alignment leaves as it is (module docstring).
_NOISE_PER_STEP = 0.05
_GAUSS_X, _GAUSS_W = np.polynomial.legendre.leggauss(8)


class MidlineError(ValueError):
    """A trace file or option that cannot be used; the message names the file and line or option."""


@dataclass(frozen=True, eq=False)
class Trace:
    """A traced curve as read from a file, in units of R.

    Attributes
    ----------
    points : ndarray, shape (n, 2)
        csv: (r, z) in the model gauge.  Image formats: (x, y) in the image
        with y up, scaled to units of R (rotation and offset arbitrary).
    source : str
        The file.
    format : str
        One of :data:`FORMATS`.
    where : tuple of str, length n
        Where each point is in the file ("line 7", "point 3"), for messages.
    """

    points: np.ndarray
    source: str
    format: str
    where: tuple[str, ...]


@dataclass(frozen=True, eq=False)
class Alignment:
    """A trace brought to the model gauge (:func:`align`).

    Attributes
    ----------
    points : ndarray, shape (m, 2)
        The half midline (r, z), units of R, pole first at the origin; for a
        whole section the mirror average of its halves.
    section : str
        "whole" or "half".
    axis_angle : float
        Direction of +z (anterior) in the trace's frame (y up), radians
        counter-clockwise from +y; nan for csv.
    pole : ndarray, shape (2,)
        The pole in the trace's frame (units of R).
    asymmetry : float
        Rms distance of each half from the mirror average (units of R); 0
        for a half section.
    """

    points: np.ndarray
    section: str
    axis_angle: float
    pole: np.ndarray
    asymmetry: float


@dataclass(frozen=True, eq=False)
class Midline:
    """A half midline in the model gauge at N points equally spaced in arclength.

    Attributes
    ----------
    r, z : ndarray, shape (N,)
        Distance from the axis and height above the posterior pole, units of
        R, pole first.  For an average, point i is the mean of the traces'
        points i (each at the fraction i/(N − 1) of its own arclength).
    spread : ndarray, shape (N,), or None
        Per-coordinate sample standard deviation of the traces' points,
        √((var r + var z)/2) with ddof = 1, units of R; the standard error of
        the mean point is ``spread/√n_traces`` per coordinate.  None for a
        single trace.
    n_traces : int
        Number of traces averaged.
    source : tuple of str
        Their files.
    """

    r: np.ndarray
    z: np.ndarray
    spread: np.ndarray | None = None
    n_traces: int = 1
    source: tuple[str, ...] = ()

    def __post_init__(self):
        r, z = np.asarray(self.r, dtype=float), np.asarray(self.z, dtype=float)
        if r.ndim != 1 or r.shape != z.shape or len(r) < 2:
            raise MidlineError(f"Midline: r and z must be 1-D of one length >= 2, not {r.shape} "
                               f"and {z.shape}")
        object.__setattr__(self, "r", r)
        object.__setattr__(self, "z", z)
        if self.spread is not None:
            spread = np.asarray(self.spread, dtype=float)
            if spread.shape != r.shape:
                raise MidlineError(f"Midline: spread has shape {spread.shape}, r has {r.shape}")
            object.__setattr__(self, "spread", spread)
        object.__setattr__(self, "source", tuple(str(s) for s in self.source))

    @property
    def points(self) -> np.ndarray:
        """(r, z) as an array of shape (N, 2)."""
        return np.column_stack([self.r, self.z])

    def to_csv(self, path: str | Path) -> None:
        """Write the ``csv`` format, with n_traces and sources as ``#`` comments."""
        columns = [self.r, self.z] + ([self.spread] if self.spread is not None else [])
        lines = [f"# n_traces = {self.n_traces}", *(f"# source = {s}" for s in self.source),
                 ",".join(("r", "z", "spread")[:len(columns)])]
        lines += [",".join(f"{v:.17g}" for v in row) for row in zip(*columns)]
        Path(path).write_text("\n".join(lines) + "\n", encoding="utf-8")

    @classmethod
    def from_csv(cls, path: str | Path) -> "Midline":
        """Read what :meth:`to_csv` wrote (points as they are, not resampled)."""
        path = Path(path)
        header, values, where, comments = _table(path, _read_bytes(path), "csv")
        _check_extent(str(path), values[:, :2], where, _IN_PIXELS)
        _check_axis(str(path), values[:, :2], where)
        meta = [tuple(part.strip() for part in c.partition("=")[::2]) for c in comments]
        sources = tuple(value for key, value in meta if key == "source")
        counts = [value for key, value in meta if key == "n_traces"] or ["1"]
        try:
            n_traces = int(counts[-1])
        except ValueError:
            raise MidlineError(f"{path}: comment 'n_traces = {counts[-1]}' is not an "
                               f"integer") from None
        spread = values[:, 2] if len(header) == 3 else None
        return cls(values[:, 0], values[:, 1], spread, n_traces, sources or (str(path),))


# --------------------------------------------------------------------------- reading

def read_trace(path: str | Path, format: str | None = None, *, pixel_size_um: float | None = None,
               radius_um: float | None = None) -> Trace:
    """Read a traced midline (see the module docstring for the formats).

    Parameters
    ----------
    path : str or Path
    format : str, optional
        One of :data:`FORMATS`; inferred from the content when None.
    pixel_size_um, radius_um : float
        µm per pixel and the embryo radius R in µm; required by the image
        formats, refused by csv (already in units of R).

    Returns
    -------
    Trace
        Repeated consecutive points dropped.

    Raises
    ------
    MidlineError
        Unreadable or malformed file (non-numbers, ragged rows, NaN, not
        UTF-8, fewer than 4 points), a pixel list, an area selection, a trace
        that is not one simple curve, missing or bad scale options, points
        more than 20 R from the first (other units, or a wrong scale).
    """
    path = Path(path)
    fmt = None if format is None else _choice(format, FORMATS, "format")
    data = _read_bytes(path)
    fmt = fmt or _sniff(path, data)
    if fmt == "csv":
        for name, value in (("pixel_size_um", pixel_size_um), ("radius_um", radius_um)):
            if value is not None:
                raise MidlineError(f"{path}: csv traces are in units of R: {name} does not apply")
        _, values, where, _ = _table(path, data, fmt)
        _check_extent(str(path), values[:, :2], where, _IN_PIXELS)
        points, where = _one_curve(path, values[:, :2], where, "R")
        _check_axis(str(path), points, where)
        return Trace(points, str(path), fmt, tuple(where))
    scale = _scale(path, fmt, pixel_size_um, radius_um)
    spline = False
    if fmt == "roi":
        pixels, where, spline = _read_roi(path, data)
    else:
        _, pixels, where, _ = _table(path, data, fmt)
    pixels, where = _one_curve(path, pixels, where, "px")
    # (relative to the first point: the image origin is anywhere)
    _check_extent(str(path), (pixels - pixels[0]) * scale, where,
                  "check the pixel size and the radius R")
    if spline:
        pixels = _imagej_spline(pixels)     # each point labelled by the control point before it
        where = [where[min(k // SPLINE_SUBDIVISIONS, len(where) - 1)] for k in range(len(pixels))]
    return Trace(pixels * [scale, -scale], str(path), fmt, tuple(where))


def _read_bytes(path: Path) -> bytes:
    try:
        return path.read_bytes()
    except OSError as exc:
        raise MidlineError(f"{path}: cannot read: {exc.strerror}") from None


def _choice(value, choices: Sequence[str], what: str) -> str:
    if value not in choices:
        raise MidlineError(f"unknown {what} {value!r}; choose one of {list(choices)}")
    return value


def _text(path: Path, data: bytes) -> list[tuple[int, str]]:
    """(line number, stripped text) of every line; MidlineError if not UTF-8."""
    try:
        text = data.decode("utf-8-sig")     # Excel writes a byte-order mark
    except UnicodeDecodeError as exc:
        line = data[:exc.start].count(b"\n") + 1
        raise MidlineError(f"{path}: line {line}: not UTF-8 text (byte {exc.start})") from None
    return [(i, line.strip()) for i, line in enumerate(text.splitlines(), 1)]


def _cells(line: str) -> list[str]:
    return line.split(",") if "," in line else line.split()


def _is_number(cell: str) -> bool:
    try:
        float(cell)
    except ValueError:
        return False
    return True


def _sniff(path: Path, data: bytes) -> str:
    """The format of a file from its content."""
    if data[:4] == b"Iout":
        return "roi"
    content = [(i, s) for i, s in _text(path, data) if s and not s.startswith("#")]
    if not content:
        raise MidlineError(f"{path}: empty file: no points")
    i, first = content[0]
    names = tuple(c.strip().lower() for c in _cells(first))
    if names in _CSV_HEADERS:
        return "csv"
    if names == _XY_HEADER:
        return "xy"
    if all(_is_number(c) for c in names):
        return "fiji-xy"
    if {"x", "y"} <= set(names):
        raise MidlineError(f"{path}: line {i}: columns {first!r}: {_PIXEL_DUMP}")
    raise MidlineError(f"{path}: line {i}: unrecognised header {first!r}; expected 'r,z' (csv), "
                       f"'x,y' (xy) or no header with x<TAB>y (fiji-xy)")


def _table(path: Path, data: bytes, fmt: str):
    """Header, values (n, k), where (n,) and ``#`` comments of a text trace."""
    lines = _text(path, data)
    comments = [s[1:].strip() for _, s in lines if s.startswith("#")]
    body = [(i, s) for i, s in lines if s and not s.startswith("#")]
    if not body:
        raise MidlineError(f"{path}: empty file: no points")
    if fmt == "fiji-xy":
        header, separator = ("x", "y"), None
        width = len(body[0][1].split())
        if width >= 3 and all(_is_number(c) for c in body[0][1].split()):
            raise MidlineError(f"{path}: line {body[0][0]}: {width} columns: {_PIXEL_DUMP}")
    else:
        (i, text), body = body[0], body[1:]
        header = tuple(c.strip().lower() for c in text.split(","))
        expected = _CSV_HEADERS if fmt == "csv" else (_XY_HEADER,)
        if header not in expected:
            if {"x", "y"} <= set(header) and len(header) > 2:
                raise MidlineError(f"{path}: line {i}: columns {text!r}: {_PIXEL_DUMP}")
            raise MidlineError(f"{path}: line {i}: header {text!r} is not "
                               f"{' or '.join(repr(','.join(h)) for h in expected)} (format {fmt!r})")
        separator = ","
    values = np.empty((len(body), len(header)))
    for k, (i, text) in enumerate(body):
        cells = text.split(separator)
        if len(cells) != len(header):
            raise MidlineError(f"{path}: line {i}: {len(cells)} values, expected {len(header)} "
                               f"({', '.join(header)})")
        for j, cell in enumerate(cells):
            where = f"{path}: line {i}, column {j + 1} ({header[j]})"
            try:
                values[k, j] = float(cell)
            except ValueError:
                raise MidlineError(f"{where}: {cell.strip()!r} is not a number") from None
            if not math.isfinite(values[k, j]):
                raise MidlineError(f"{where}: {cell.strip()} is not finite")
    return header, values, [f"line {i}" for i, _ in body], comments


def _read_roi(path: Path, data: bytes) -> tuple[np.ndarray, list[str], bool]:
    """Pixel coordinates, labels and the spline-fit flag of an ImageJ line ROI."""
    import roifile
    try:
        roi = roifile.ImagejRoi.frombytes(data)
    except Exception as exc:    # roifile raises ValueError, struct.error, … on damaged files
        raise MidlineError(f"{path}: not a readable ImageJ ROI file ({exc})") from None
    kind = roifile.ROI_TYPE(roi.roitype)
    if roi.multi_coordinates is not None:
        raise MidlineError(f"{path}: a composite ROI (several shapes), not one line")
    if kind in (roifile.ROI_TYPE.POLYGON, roifile.ROI_TYPE.FREEHAND, roifile.ROI_TYPE.TRACED,
                roifile.ROI_TYPE.RECT, roifile.ROI_TYPE.OVAL):
        raise MidlineError(f"{path}: an area selection ({kind.name.lower()}), not a line: trace "
                           f"the midline with the segmented, freehand or straight line tool")
    if kind not in (roifile.ROI_TYPE.POLYLINE, roifile.ROI_TYPE.FREELINE, roifile.ROI_TYPE.LINE):
        raise MidlineError(f"{path}: a {kind.name.lower()} ROI, not a line selection")
    pixels = np.asarray(roi.coordinates(), dtype=float)
    spline = bool(roi.options & roifile.ROI_OPTIONS.SPLINE_FIT)
    return pixels, [f"point {k + 1}" for k in range(len(pixels))], spline


def _imagej_spline(control: np.ndarray) -> np.ndarray:
    """Points of the curve ImageJ draws for a spline-fit line (module docstring).

    Shape (SPLINE_SUBDIVISIONS·(n − 1) + 1, 2), the control points among them.
    """
    # ImageJ clamps the increment at 0.001 for repeated points; those were dropped.
    t = np.r_[0.0, np.cumsum(np.sqrt(np.hypot(*np.diff(control, axis=0).T)))]
    fraction = np.arange(SPLINE_SUBDIVISIONS) / SPLINE_SUBDIVISIONS
    fine = np.r_[(t[:-1, None] + np.diff(t)[:, None] * fraction).ravel(), t[-1]]
    from scipy.interpolate import CubicSpline   # scipy and roifile: imported on use (CLI start-up)
    return CubicSpline(t, control, bc_type="natural")(fine)


def _scale(path: Path, fmt: str, pixel_size_um, radius_um) -> float:
    """Units of R per pixel, from the two scale options."""
    options = {"pixel_size_um": (pixel_size_um, "µm per pixel"),
               "radius_um": (radius_um, "the embryo radius R in µm")}
    missing = [f"{name} ({meaning})" for name, (value, meaning) in options.items() if value is None]
    if missing:
        raise MidlineError(f"{path}: {fmt} coordinates are in pixels: pass "
                           f"{' and '.join(missing)} to convert them to units of R")
    pixel_size, radius = (_positive(name, value, f"{path}: ")
                          for name, (value, _) in options.items())
    return pixel_size / radius


def _positive(name: str, value, prefix: str = "") -> float:
    try:
        value = real(name, value)
    except ValueError as exc:
        raise MidlineError(f"{prefix}{exc}") from None
    if value <= 0:
        raise MidlineError(f"{prefix}{name} = {value!r} must be positive")
    return value


def _one_curve(path: Path, points: np.ndarray, where: list[str], unit: str):
    """Points without repeats and their labels; MidlineError unless they make one simple curve."""
    keep = np.r_[True, np.any(np.diff(points, axis=0) != 0, axis=1)]
    points, where = points[keep], [w for w, k in zip(where, keep) if k]
    if len(points) < 4:
        raise MidlineError(f"{path}: {len(points)} distinct points; a midline needs at least 4")
    steps = np.hypot(*np.diff(points, axis=0).T)
    median = float(np.median(steps))
    gaps = np.flatnonzero(steps > max(_GAP_STEPS * median, _GAP_FRACTION * steps.sum()))
    if len(gaps):
        i = gaps[0]
        raise MidlineError(f"{path}: {where[i]} to {where[i + 1]}: a step of {steps[i]:.4g} {unit} "
                           f"({steps[i] / median:.0f} median steps): the trace is not one curve "
                           f"(two pieces, or points out of order)")
    with np.errstate(over="ignore", invalid="ignore"):     # (coordinates near 1e300)
        crossing = _first_crossing(points, _GAP_STEPS * median)
    if crossing is not None:
        i, j = crossing
        raise MidlineError(f"{path}: the segment {where[i]} to {where[i + 1]} crosses the segment "
                           f"{where[j]} to {where[j + 1]}: the trace intersects itself")
    return points, where


def _first_crossing(points: np.ndarray, apart: float, chunk: int = 32) -> tuple[int, int] | None:
    """(i, j), i < j, of two segments of the polyline that cross, ``apart`` along it; i smallest.

    Segments closer than ``apart`` along the polyline may cross: noise at the
    scale of the point spacing makes such small loops.  Only chunks of
    consecutive segments whose bounding boxes overlap are compared, which
    makes the check about linear in the number of points for a curve.
    """
    a, d = points[:-1], np.diff(points, axis=0)
    along = np.r_[0.0, np.cumsum(np.hypot(*d.T))]             # polyline length at each point
    starts = np.arange(0, len(a), chunk)
    lo = np.minimum.reduceat(np.minimum(a, a + d), starts)
    hi = np.maximum.reduceat(np.maximum(a, a + d), starts)
    boxes_meet = np.all((lo[:, None] <= hi[None]) & (lo[None] <= hi[:, None]), axis=-1)

    def cross(u, v):
        return u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0]

    found = []
    for p, q in np.argwhere(np.triu(boxes_meet)):
        i = np.arange(starts[p], min(starts[p] + chunk, len(a)))[:, None]
        j = np.arange(starts[q], min(starts[q] + chunk, len(a)))[None, :]
        # ends of segment j on opposite sides of segment i, and vice versa (touching is not crossing)
        hit = ((cross(d[i], a[j] - a[i]) * cross(d[i], a[j] + d[j] - a[i]) < 0)
               & (cross(d[j], a[i] - a[j]) * cross(d[j], a[i] + d[i] - a[j]) < 0)
               & (along[j] - along[i + 1] >= apart))
        if hit.any():
            k, m = np.argwhere(hit)[0]
            found.append((int(i[k, 0]), int(j[0, m])))
    return min(found) if found else None


_IN_PIXELS = "a trace in pixels is read with format 'xy', 'fiji-xy' or 'roi' and a scale"


def _check_extent(source: str, points: np.ndarray, where, hint: str) -> None:
    """MidlineError if a point lies more than _MAX_EXTENT R from the first (wrong units)."""
    reach = np.hypot(*(points - points[0]).T)
    if len(points) and reach.max() > _MAX_EXTENT:
        i = int(np.argmax(reach > _MAX_EXTENT))
        raise MidlineError(f"{source}: {where[i]}: {reach[i]:.4g} R from the first point; a "
                           f"midline lies within {_MAX_EXTENT:g} R of its pole ({hint})")


def _check_axis(source: str, points: np.ndarray, where) -> None:
    """MidlineError if a model-gauge midline goes to r < 0 by more than noise."""
    bad = np.flatnonzero(points[:, 0] < -_AXIS_SLACK)
    if len(bad):
        raise MidlineError(f"{source}: {where[bad[0]]}: r = {points[bad[0], 0]:.4g} < 0: the "
                           f"midline crosses the axis (the model gauge has r >= 0)")


# --------------------------------------------------------------------------- arclength

def _speed_integral(spline, a, b):
    """∫ₐᵇ |C′(u)| du for arrays a, b within one knot interval each (8-point Gauss–Legendre)."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    u = ((a + b) / 2)[..., None] + ((b - a) / 2)[..., None] * _GAUSS_X
    return (b - a) / 2 * (np.linalg.norm(spline(u, 1), axis=-1) @ _GAUSS_W)


@dataclass(frozen=True, eq=False)
class _Curve:
    """The cubic spline through a trace's points, addressed by arclength.

    The spline is not-a-knot in the chord-length parameter u (error O(h⁴)
    for points of a smooth curve at spacing h); ``knots`` holds the arclength
    at each knot u_j.
    """

    spline: "CubicSpline"
    knots: np.ndarray

    @classmethod
    def through(cls, points: np.ndarray) -> "_Curve":
        u = np.r_[0.0, np.cumsum(np.hypot(*np.diff(points, axis=0).T))]
        from scipy.interpolate import CubicSpline
        spline = CubicSpline(u, points)
        return cls(spline, np.r_[0.0, np.cumsum(_speed_integral(spline, u[:-1], u[1:]))])

    @property
    def length(self) -> float:
        return float(self.knots[-1])

    def __call__(self, s, tangent: bool = False) -> np.ndarray:
        """Points, or unit tangents, at arclengths s; shape s.shape + (2,)."""
        s = np.clip(np.asarray(s, dtype=float), 0.0, self.length)
        u_knots = self.spline.x
        j = np.clip(np.searchsorted(self.knots, s, side="right") - 1, 0, len(u_knots) - 2)
        lo, hi, s_lo = u_knots[j], u_knots[j + 1], self.knots[j]
        u = lo + (s - s_lo) / (self.knots[j + 1] - s_lo) * (hi - lo)
        for _ in range(10):     # Newton on s(u) = s within the interval; converges in 2–3
            excess = s_lo + _speed_integral(self.spline, lo, u) - s
            u = np.clip(u - excess / np.linalg.norm(self.spline(u, 1), axis=-1), lo, hi)
            if np.all(np.abs(excess) <= 1e-14 * self.length):
                break
        if not tangent:
            return self.spline(u)
        d = self.spline(u, 1)
        return d / np.linalg.norm(d, axis=-1, keepdims=True)


def resample(points, n: int = 100) -> np.ndarray:
    """n points equally spaced in arclength along a curve, both ends included.

    Parameters
    ----------
    points : array_like, shape (m, 2)
        At least 4 finite points, consecutive ones distinct.
    n : int
        At least 2.

    Returns
    -------
    ndarray, shape (n, 2)
        On the not-a-knot cubic spline through ``points`` (chord-length
        parameter), at arclengths k L/(n − 1) computed by Gauss–Legendre
        quadrature and Newton's method: error O(h⁴) for a smooth curve
        sampled at spacing h (below 1e-8 R at h = 0.01 R for curvatures of
        order 1/R).
    """
    n = _count("n", n, 2)
    points = np.asarray(points, dtype=float)
    if points.ndim != 2 or points.shape[1] != 2 or len(points) < 4:
        raise MidlineError(f"resample: points must have shape (m >= 4, 2), not {points.shape}")
    if not np.all(np.isfinite(points)):     # (scipy said "`x` must contain only finite values")
        i = int(np.flatnonzero(~np.all(np.isfinite(points), axis=1))[0])
        raise MidlineError(f"resample: point {i} is {points[i].tolist()}, not finite")
    if np.any(np.all(np.diff(points, axis=0) == 0, axis=1)):
        raise MidlineError("resample: two consecutive points coincide")
    curve = _Curve.through(points)
    return curve(np.linspace(0.0, curve.length, n))


def _count(name: str, value, minimum: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < minimum:
        raise MidlineError(f"{name} = {value!r} must be an integer >= {minimum}")
    return int(value)


# --------------------------------------------------------------------------- alignment

def align(trace: Trace, section: str = "auto", *, flip: bool = False,
          max_asymmetry: float = 0.05) -> Alignment:
    """Bring a trace to the model gauge (rules in the module docstring).

    Parameters
    ----------
    trace : Trace
    section : {"auto", "whole", "half"}
    flip : bool
        Point +z the other way (when the rims are posterior of the pole).
    max_asymmetry : float
        Largest rms distance (units of R) of the halves of a whole section
        from their mirror average.

    Returns
    -------
    Alignment
        ``points`` of shape (m, 2): the trace's own points for a half
        section, max(1024, 2n) mirror-averaged points for a whole one.
    """
    section = _choice(section, SECTIONS, "section")
    max_asymmetry = _positive("max_asymmetry", max_asymmetry)
    if trace.format == "csv":
        if section == "whole" or flip:
            raise MidlineError(f"{trace.source}: csv traces are half midlines in the model gauge: "
                               f"section='whole' and flip do not apply")
        return Alignment(trace.points, "half", math.nan, trace.points[0], 0.0)
    points = _bin_noisy(trace.points)
    curve = _Curve.through(points)
    if section == "half":
        pole, e_r = curve(0.0), curve(0.0, tangent=True)
        e_z = _anterior(np.array([-e_r[1], e_r[0]]), pole, [curve(curve.length)], flip)
        points, asymmetry = _gauge(points, pole, e_r, e_z), 0.0
        where = trace.where if len(points) == len(trace.where) else [
            f"point {k + 1} after binning" for k in range(len(points))]
    else:
        pole, e_r, e_z, points, asymmetry = _whole(curve, len(points), flip)
        if asymmetry > max_asymmetry:
            raise MidlineError(f"{trace.source}: the halves of this whole section differ by "
                               f"{asymmetry:.3g} R rms from their mirror average (max_asymmetry = "
                               f"{max_asymmetry:g}): if it is a half section, pole first, pass "
                               f"section='half'")
        where = [f"{f:.0%} of the way from the pole" for f in np.linspace(0, 1, len(points))]
    _check_axis(trace.source, points, where)
    return Alignment(points, "half" if section == "half" else "whole",
                     math.atan2(-e_z[0], e_z[1]), pole, asymmetry)


def _bin_noisy(points: np.ndarray) -> np.ndarray:
    """The points, or, if noisy for their spacing, their interior averaged in bins of k.

    σ is estimated from the fourth differences across the curve (their
    median; Gaussian noise gives them variance 70 σ², a smooth curve O(h⁴));
    k is the least making σ/√k ≤ _NOISE_PER_STEP·k·h.  The means are moved out by
    the curvature bias of averaging along a curve.  Shape (m, 2), m ≤ n.
    """
    if len(points) < 12:
        return points
    chord = points[4:] - points[:-4]
    across = chord[:, ::-1] * [1.0, -1.0] / np.linalg.norm(chord, axis=1, keepdims=True)
    wiggle = np.abs(np.sum(np.diff(points, n=4, axis=0) * across, axis=1))
    sigma = float(np.median(wiggle)) / (0.6745 * math.sqrt(70.0))
    step = float(np.median(np.hypot(*np.diff(points, axis=0).T)))
    k = math.ceil((sigma / (_NOISE_PER_STEP * step)) ** (2 / 3))
    bins = (len(points) - 2) // k
    if k <= 1 or bins < 4:
        return points
    groups = np.array_split(points[1:-1], bins)
    out = np.vstack([points[:1], [b.mean(axis=0) for b in groups], points[-1:]])
    # A bin's mean lies inside the curve: by ½ c''(s̄) (k² − 1) h²/12, c'' = κ n the
    # curvature vector (Taylor: the positions s̄ + (i − (k − 1)/2) h average c(s̄) and
    # half the variance times c'').  At the folds of the synthetic inversion data (κ ≈ 8/R,
    # k = 4, h = 0.011 R) that is 6e-4 R, as large as the noise of a 5-trace average, and
    # the same in every data set: it biased the free fit's κ₁ (+0.09/R at t08).  Remove it,
    # with c'' from the three-point difference of the means (it adds ~10 % to their noise).
    c2 = _second_derivative(out)
    # the spacing from chords of 4 steps: the noise lengthens single steps (by 11 % there,
    # which made the correction 23 % too large)
    h = float(np.median(np.linalg.norm(chord, axis=1))) / 4
    var = (np.array([len(b) for b in groups]) ** 2 - 1) * h ** 2 / 12
    out[1:-1] -= 0.5 * var[:, None] * c2
    return out


def _second_derivative(points: np.ndarray) -> np.ndarray:
    """c'' with respect to arclength at the interior points (m − 2, 2), from chords to their neighbours."""
    a, b = points[1:-1] - points[:-2], points[2:] - points[1:-1]
    d1, d2 = np.linalg.norm(a, axis=1)[:, None], np.linalg.norm(b, axis=1)[:, None]
    return 2 * (b / d2 - a / d1) / (d1 + d2)


def _gauge(points, pole, e_r, e_z) -> np.ndarray:
    """(r, z) of points of the trace's frame, for the pole and axes given."""
    return (points - pole) @ np.column_stack([e_r, e_z])


def _anterior(e_z, pole, rims, flip: bool) -> np.ndarray:
    """±e_z, pointing to the side of the pole where the rims are (or away, if ``flip``)."""
    sign = 1.0 if np.mean([(rim - pole) @ e_z for rim in rims]) >= 0 else -1.0
    return -sign * e_z if flip else sign * e_z


def _whole(curve: _Curve, n_points: int, flip: bool):
    """Pole, e_r, e_z, mirror-averaged half (m, 2) and asymmetry of a whole section."""
    length = curve.length
    sigma = length / 2 * np.arange(1, _MIRROR_SAMPLES + 1) / _MIRROR_SAMPLES
    right, left = curve(length / 2 + sigma), curve(length / 2 - sigma)
    # directions along and across the left half, from chords long enough to average noise out
    chord = curve(length / 2 - sigma + length / 30) - curve(length / 2 - sigma - length / 30)
    along = chord / np.linalg.norm(chord, axis=1, keepdims=True)
    across = along @ [[0.0, 1.0], [-1.0, 0.0]]

    def mismatch(p):      # reflection of the right half in the line n·X = c, minus the left half
        normal = np.array([math.cos(p[0]), math.sin(p[0])])
        d = right - 2 * (right @ normal - p[1])[:, None] * normal - left
        return np.r_[np.sum(d * across, axis=1),
                     _ALONG_WEIGHT * np.sum(d * along, axis=1)]

    from scipy.optimize import least_squares
    t = curve(length / 2, tangent=True)       # the axis is normal to the curve at the pole
    fit = least_squares(mismatch, [math.atan2(t[1], t[0]), t @ curve(length / 2)],
                        xtol=1e-15, ftol=1e-15, gtol=1e-15)
    scale = 1.4826 * float(np.median(np.abs(fit.fun)))      # MAD: the noise of the points
    if scale > 1e-9 * length:
        fit = least_squares(mismatch, fit.x, loss="soft_l1", f_scale=scale,
                            xtol=1e-15, ftol=1e-15, gtol=1e-15)
    normal, c = np.array([math.cos(fit.x[0]), math.sin(fit.x[0])]), fit.x[1]
    s_pole = _crossing(curve, normal, c)
    pole = curve(s_pole)
    fraction = np.linspace(0.0, 1.0, max(1024, 2 * n_points))
    right, left = curve(s_pole + fraction * (length - s_pole)), curve(s_pole - fraction * s_pole)
    e_r = normal if np.mean((right - pole) @ normal) >= 0 else -normal
    e_z = _anterior(np.array([-normal[1], normal[0]]), pole, [right[-1], left[-1]], flip)
    right, left = _gauge(right, pole, e_r, e_z), _gauge(left, pole, -e_r, e_z)    # left mirrored
    asymmetry = float(np.sqrt(np.mean(np.sum((right - left) ** 2, axis=1)))) / 2
    half = (right + left) / 2
    z0 = _pole_height(half)
    half[:, 1] -= z0
    half[0] = 0.0
    return pole + z0 * e_z, e_r, e_z, half, asymmetry


def _pole_height(half: np.ndarray) -> float:
    """Height z₀ of the pole of a mirror-averaged half (m, 2): least squares of z = z₀ + a s² + b s⁴.

    Over the points within :data:`_POLE_WINDOW` of arclength s from the pole
    (z is even in s through a regular pole).  The crossing of the axis with
    the trace is one point of the noisy curve, and its height error shifts
    the whole midline along z, which the fit, its pole pinned at the origin,
    can only absorb by bending the posterior: on the synthetic inversion data
    (pixel noise 0.5 px, 5 traces) the free fit's κ₁ moved by 250/R per R of
    shift, and the crossing's height scattered by 1.9e-3 R from trace to trace,
    the fitted one by 1.3e-3 R (t02, 100 traces; t12: 2.0e-3 and 1.0e-3 R).
    Without noise the truncated series errs by up to 8e-5 R (t12; 4e-5 with
    s⁶ too, but a scatter of 1.2e-3 R; 4e-6 at t01-t05); the crossing by 1e-5 R.
    """
    s = np.r_[0.0, np.cumsum(np.hypot(*np.diff(half, axis=0).T))]
    near = s <= _POLE_WINDOW
    if np.count_nonzero(near) < 6:
        return 0.0
    A = np.column_stack([s[near] ** (2 * j) for j in range(_POLE_TERMS)])
    return float(np.linalg.lstsq(A, half[near, 1], rcond=None)[0][0])


def _crossing(curve: _Curve, normal: np.ndarray, c: float) -> float:
    """Arclength, nearest mid-length, where the curve crosses the line normal·X = c."""
    s = np.linspace(0.0, curve.length, 4 * len(curve.knots) + 1)
    side = curve(s) @ normal - c
    changes = np.flatnonzero(np.sign(side[:-1]) != np.sign(side[1:]))
    if not len(changes):
        raise MidlineError("the fitted axis of symmetry does not cross the trace")
    k = changes[np.argmin(np.abs(s[changes] - curve.length / 2))]
    if side[k] == 0:
        return float(s[k])
    from scipy.optimize import brentq
    return brentq(lambda x: float(curve(x) @ normal) - c, s[k], s[k + 1], xtol=1e-15)


# --------------------------------------------------------------------------- midlines

def load_midline(path: str | Path, format: str | None = None, *, n: int = 100,
                 section: str = "auto", flip: bool = False, pixel_size_um: float | None = None,
                 radius_um: float | None = None, max_asymmetry: float = 0.05) -> Midline:
    """Read, align and resample one trace: :func:`read_trace`, :func:`align`, :func:`resample`.

    Returns
    -------
    Midline
        n points, spread None, n_traces 1.
    """
    n = _count("n", n, 2)
    _choice(section, SECTIONS, "section")
    _positive("max_asymmetry", max_asymmetry)
    trace = read_trace(path, format, pixel_size_um=pixel_size_um, radius_um=radius_um)
    half = align(trace, section, flip=flip, max_asymmetry=max_asymmetry).points
    r, z = resample(half, n).T
    return Midline(r, z, None, 1, (trace.source,))


def average(midlines: Sequence[Midline]) -> Midline:
    """Mean and spread of single-trace midlines of one stage, point by point.

    The mean of the points i, resampled equally spaced in its own arclength
    (:func:`resample`); the spread is that of the points i.  Without the
    resampling the mean kept a bias along the curve: pixel noise lengthens
    each trace's arclength unevenly (most where the noise is large for the
    point spacing), so a fraction of the length falls at a slightly other
    material point in every trace alike.  On the synthetic inversion data at
    t08 (pixel noise 0.5 px, 400 traces in averages of 5) that bias was
    2.2e-4 R rms, 24 of its standard errors squared per point; resampled
    (and with the bins of :func:`align` moved back onto the curve), 0.4e-4 R
    (0.3), with the same spread.

    Raises
    ------
    MidlineError
        No midlines, different numbers of points, or an input that is
        itself an average.
    """
    midlines = list(midlines)
    if not midlines:
        raise MidlineError("average: no midlines given")
    sizes = sorted({len(m.r) for m in midlines})
    if len(sizes) > 1:
        raise MidlineError(f"average: the midlines have different numbers of points {sizes}; "
                           f"resample them to one n")
    for m in midlines:
        if m.n_traces != 1:
            raise MidlineError(f"average: {', '.join(m.source) or 'a midline'} is already an "
                               f"average of {m.n_traces} traces; average the single traces")
    points = np.stack([m.points for m in midlines])            # (traces, N, 2)
    mean = points.mean(axis=0)
    if len(midlines) > 1 and len(mean) >= 4:
        mean = resample(mean, len(mean))
    spread = np.sqrt(points.var(axis=0, ddof=1).mean(axis=1)) if len(midlines) > 1 else None
    return Midline(mean[:, 0], mean[:, 1], spread, len(midlines),
                   tuple(s for m in midlines for s in m.source))


# --------------------------------------------------------------------------- writing

def to_image(points, *, radius_px: float, angle_deg: float = 0.0, offset_px=(0.0, 0.0),
             section: str = "whole") -> np.ndarray:
    """Pixel coordinates (x, y down) of a model-gauge half midline, as if traced in an image.

    Parameters
    ----------
    points : array_like, shape (n, 2), or Midline
        (r, z) in units of R, pole first.
    radius_px : float
        R in pixels.
    angle_deg : float
        Direction of +z on screen, degrees counter-clockwise from up.
    offset_px : (float, float)
        Where the pole lands, pixels.
    section : {"whole", "half"}
        Whole: rim to rim through the pole (the half and its mirror image,
        2n − 1 points); half: pole to rim.

    Returns
    -------
    ndarray, shape (2n − 1, 2) or (n, 2)
    """
    points = points.points if isinstance(points, Midline) else np.asarray(points, dtype=float)
    radius_px = _positive("radius_px", radius_px)
    if _choice(section, ("whole", "half"), "section") == "whole":
        points = np.vstack([points[:0:-1] * [-1.0, 1.0], points])
    a = math.radians(real("angle_deg", angle_deg))
    e_r, e_z = np.array([math.cos(a), math.sin(a)]), np.array([-math.sin(a), math.cos(a)])
    up = radius_px * (points[:, :1] * e_r + points[:, 1:] * e_z)       # y up
    return np.asarray(offset_px, dtype=float) + up * [1.0, -1.0]


def write_trace(path: str | Path, midline, format: str, *, pixel_size_um: float | None = None,
                radius_um: float | None = None, angle_deg: float = 0.0, offset_px=(0.0, 0.0),
                section: str | None = None, noise_px: float = 0.0, seed=None,
                spline_fit: bool = False) -> None:
    """Write a model-gauge half midline as a trace file in ``format``.

    Parameters
    ----------
    path : str or Path
    midline : array_like, shape (n, 2), or Midline
        (r, z) in units of R, pole first.
    format : str
        One of :data:`FORMATS`.  csv writes the points as they are.
    pixel_size_um, radius_um : float
        Scale of the image formats (R = radius_um/pixel_size_um pixels).
    angle_deg, offset_px, section
        Placement in the image (:func:`to_image`); section defaults to
        "whole" (image formats) or "half" (csv, which has no other).
    noise_px : float
        Standard deviation of Gaussian noise added to each pixel coordinate.
    seed : int or numpy Generator, optional
        For the noise.
    spline_fit : bool
        roi only: flag the points as control points of an ImageJ spline fit.
    """
    path, fmt = Path(path), _choice(format, FORMATS, "format")
    points = midline.points if isinstance(midline, Midline) else np.asarray(midline, dtype=float)
    if spline_fit and fmt != "roi":
        raise MidlineError(f"{path}: spline_fit applies to the roi format only")
    if fmt == "csv":
        if section not in (None, "half"):
            raise MidlineError(f"{path}: csv holds half midlines in the model gauge: section "
                               f"{section!r} does not apply")
        (midline if isinstance(midline, Midline) else Midline(*points.T)).to_csv(path)
        return
    scale = _scale(path, fmt, pixel_size_um, radius_um)
    pixels = to_image(points, radius_px=1.0 / scale, angle_deg=angle_deg, offset_px=offset_px,
                      section=section or "whole")
    if noise_px:
        noise = _positive("noise_px", noise_px)
        pixels = pixels + np.random.default_rng(seed).normal(0.0, noise, pixels.shape)
    if fmt == "roi":
        import roifile
        roi = roifile.ImagejRoi.frompoints(pixels, name=path.stem)
        roi.roitype = roifile.ROI_TYPE.POLYLINE
        roi.options = roifile.ROI_OPTIONS.SUB_PIXEL_RESOLUTION | (
            roifile.ROI_OPTIONS.SPLINE_FIT if spline_fit else roifile.ROI_OPTIONS.NONE)
        roi.tofile(path)
        return
    # 9 decimals (Fiji writes 4) so that clean synthetic traces stay exact, even half sections,
    # whose axis rests on the first points
    separator = "," if fmt == "xy" else "\t"
    rows = "".join(f"{x:.9f}{separator}{y:.9f}\n" for x, y in pixels)
    path.write_text(("x,y\n" if fmt == "xy" else "") + rows, encoding="utf-8")
