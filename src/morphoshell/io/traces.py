"""Trace files of embryos' midlines: reading them, and writing synthetic ones.

Biologists trace the cell sheet of an embryo's mid-sagittal section in
Fiji/ImageJ (paper, Materials and Methods, "Analysis of experimental data").
A fit (documentation: "Problems and families", Volvox) needs it as a *half
midline in the model gauge*: points (r_i, z_i) equally spaced in arclength
from the posterior pole, at the origin, to the rim; the axis of symmetry
along z, z growing toward the anterior, r ≥ 0 the distance from the axis;
lengths in units of the embryo radius R.  This module is the file side of
getting there:

``read_trace``   a file → :class:`Trace` (points in units of R, as traced);
``write_trace``  a model-gauge midline → a trace file (synthetic microscope
                 data, tests), through ``to_image``, which places it in an image;
``Midline``      the result, with its own csv (:meth:`Midline.to_csv`).

The geometry side, a :class:`Trace` brought to the model gauge, resampled
and averaged, is :mod:`morphoshell.io.midlines`
(:func:`morphoshell.io.midlines.load_midline` chains both sides).

Formats
-------
``csv``      header ``r,z`` (or ``r,z,spread``; in any order, read by name),
             units of R, model gauge,
             posterior pole first; lines starting with ``#`` are comments.
             :meth:`Midline.to_csv` writes it, with a ``# n_traces``
             comment that marks its rows as a midline's, equally spaced in
             arclength (:attr:`Trace.written`: read back as they are, not
             resampled, :func:`morphoshell.io.midlines.load_midline`).
``xy``       image pixels x, y, y pointing down: a header ``x,y`` (any case
             and order;
             after a row-number column, as Fiji's Results table and pandas
             write it) or none, cells separated by commas, tabs or spaces.
``fiji-xy``  Fiji's *File › Save As › XY Coordinates…* of a line selection:
             no header, ``x<TAB>y`` per line, y pointing down; read as xy
             (the name says where it comes from).  Fiji writes
             calibrated units if the image is spatially calibrated: then pass
             ``pixel_size_um=1`` (for µm).  The three-column file of
             *Analyze › Tools › Save XY Coordinates…* lists the pixels of an
             image, not a line, and is refused.
``roi``      an ImageJ ``.roi`` file (via ``roifile``) of a segmented, freehand
             or straight line, y pointing down.

The text forms accepted and refused (semicolons, decimal commas, images,
UTF-16) are :mod:`morphoshell.io.trace_text`'s.  The format is inferred from
the content when not given: the ROI magic ``Iout``, else the header line
(``r,z`` → csv, ``x,y`` → xy, numbers → fiji-xy).  Image coordinates need
``pixel_size_um`` (µm per pixel) and ``radius_um`` (R in µm): a pixel (x, y)
becomes (x, −y)·pixel_size_um/radius_um.  y is flipped so that the trace's
frame is right-handed; the aligned midline does not depend on it (a mirror
image of a section aligns to the same half).

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

Errors
------
Bad files and options raise :class:`~morphoshell.io.trace_checks.MidlineError`
(a ``ValueError``) with one line naming the file and the line, point or
option, before any fitting; the checks of curves and options are
:mod:`morphoshell.io.trace_checks`.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

import numpy as np

from .._runtime.validate import real
from .trace_checks import (MidlineError, check_average, check_axis, check_choice, check_extent,
                           check_positive, image_scale, one_curve)
from .trace_text import ZIP_MAGIC, read_bytes, read_table, text_format

__all__ = ["FORMATS", "MidlineError", "Trace", "Midline", "read_trace", "to_image", "write_trace",
           "pixel_trace", "roi_kind", "roi_points", "image_scale", "text_coordinates", "ZIP_MAGIC"]

#: Trace file formats (see the module docstring).
FORMATS = ("csv", "xy", "fiji-xy", "roi")
#: Points per control interval at which a spline-fit ROI is evaluated.
SPLINE_SUBDIVISIONS = 32


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
    spread : ndarray, shape (rows,), or None
        csv ``r,z,spread`` only (an average, as :meth:`Midline.to_csv` writes
        it): the spread column, one value per row of the file, row i at the
        fraction i/(rows − 1) of the average's arclength.
    n_traces : int
        The ``# n_traces`` comment of a csv (1 without one): traces averaged.
    scale : float
        Image formats: units of R per pixel (for messages in pixels); nan for csv.
    written : bool
        A csv with a ``# n_traces`` comment, which :meth:`Midline.to_csv`
        writes in every midline, and no row repeated: the rows of a
        :class:`Midline`, equally spaced in arclength, row i at the fraction
        i/(rows − 1) (:func:`morphoshell.io.midlines.load_midline` reads them
        so).  False for any other trace.
    """

    points: np.ndarray
    source: str
    format: str
    where: tuple[str, ...]
    spread: np.ndarray | None = None
    n_traces: int = 1
    scale: float = math.nan
    written: bool = False


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
    noise : float
        A single image trace's noise per coordinate, units of R, as alignment
        estimated it (:attr:`morphoshell.io.midlines.Alignment.noise`): what
        the spread of an average of traces is compared with
        (:func:`~morphoshell.io.trace_checks.spread_warning`); nan if unknown
        (csv, averages, segmented lines).  Not written by :meth:`to_csv`.
    """

    r: np.ndarray
    z: np.ndarray
    spread: np.ndarray | None = None
    n_traces: int = 1
    source: tuple[str, ...] = ()
    noise: float = math.nan

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

    def __repr__(self) -> str:
        """One line: points, traces, length (units of R) and source (the default repr held
        every point: 62 lines)."""
        length = float(np.sum(np.hypot(np.diff(self.r), np.diff(self.z))))
        traces = f"{self.n_traces} trace{'' if self.n_traces == 1 else 's'}"
        more = f" and {len(self.source) - 1} more" if len(self.source) > 1 else ""
        source = f", source={self.source[0]!r}{more}" if self.source else ""
        return (f"Midline({len(self.r)} points, {traces}, length {length:.3g} R"
                f"{', with spread' if self.spread is not None else ''}{source})")

    @property
    def points(self) -> np.ndarray:
        """(r, z) as an array of shape (N, 2)."""
        return np.column_stack([self.r, self.z])

    def to_csv(self, path: str | Path, comments: Sequence[str] = ()) -> None:
        """Write the ``csv`` format, with n_traces, sources and ``comments`` (``key = value``
        lines that :meth:`from_csv` skips: how the midline was made) as ``#`` comments."""
        columns = [self.r, self.z] + ([self.spread] if self.spread is not None else [])
        # (the n_traces comment marks the rows as a midline's, equally spaced in arclength:
        # Trace.written)
        _write_csv(path, [f"n_traces = {self.n_traces}", *(f"source = {s}" for s in self.source),
                          *comments], ("r", "z", "spread")[:len(columns)], columns)

    @classmethod
    def from_csv(cls, path: str | Path) -> "Midline":
        """Read what :meth:`to_csv` wrote (points as they are, not resampled)."""
        path = Path(path)
        header, values, where, comments = read_table(path, read_bytes(path), "csv")
        if len(values) < 4:         # (as a trace: read_trace)
            raise MidlineError(f"{path}: {len(values)} points; a midline needs at least 4")
        check_extent(str(path), values[:, :2], where, _OTHER_UNITS)
        check_axis(str(path), values[:, :2], where, _SWAPPED)
        spread, n_traces, sources, _ = _csv_average(path, header, values, where, comments)
        return cls(values[:, 0], values[:, 1], spread, n_traces, sources or (str(path),))


def _write_csv(path, comments: Sequence[str], names: Sequence[str], columns) -> None:
    """``comments`` as ``#`` lines, a header of ``names`` and the ``columns`` in 17 digits."""
    lines = [*(f"# {c}" for c in comments), ",".join(names)]
    lines += [",".join(f"{v:.17g}" for v in row) for row in zip(*columns)]
    Path(path).write_text("\n".join(lines) + "\n", encoding="utf-8")


def _csv_average(path: Path, header, values: np.ndarray, where,
                 comments) -> tuple[np.ndarray | None, int, tuple[str, ...], bool]:
    """What a csv midline holds beside its points: the spread column (None without one), the
    ``# n_traces`` comment (1 without one), the ``# source`` comments, as
    :meth:`Midline.to_csv` writes them, and whether it has an n_traces comment (MidlineError:
    an n_traces that is not an integer, or that or a spread an average cannot have,
    :func:`check_average`; ``where`` names the rows)."""
    meta = [tuple(part.strip() for part in c.partition("=")[::2]) for c in comments]
    sources = tuple(value for key, value in meta if key == "source")
    counts = [value for key, value in meta if key == "n_traces"]
    try:
        n_traces = int((counts or ["1"])[-1])
    except ValueError:
        raise MidlineError(f"{path}: comment 'n_traces = {counts[-1]}' is not an "
                           f"integer") from None
    spread = values[:, 2] if len(header) == 3 else None
    check_average(str(path), n_traces, sources, spread, where)
    return spread, n_traces, sources, bool(counts)


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
        Repeated consecutive points dropped; a csv average's spread and
        n_traces kept (:attr:`Trace.spread`).

    Raises
    ------
    MidlineError
        Unreadable or malformed file (non-numbers, ragged rows, NaN, not
        UTF-8, fewer than 4 points), a pixel list, an area selection, a trace
        that is not one simple curve, missing or bad scale options, points
        more than 20 R from the first (other units, or a wrong scale).
    """
    path = Path(path)
    fmt = None if format is None else check_choice(format, FORMATS, "format")
    data = read_bytes(path)
    fmt = _format_of(path, data, fmt)
    if fmt == "csv":
        for name, value in (("pixel_size_um", pixel_size_um), ("radius_um", radius_um)):
            if value is not None:
                raise MidlineError(f"{path}: csv traces are in units of R: {name} does not apply")
        header, values, where, comments = read_table(path, data, fmt)
        check_extent(str(path), values[:, :2], where, _OTHER_UNITS)
        # (an average's spread and n_traces are read here, so that every loader keeps them:
        # a loader that dropped them took a fit's noise from its residual, silently)
        spread, n_traces, _, written = _csv_average(path, header, values, where, comments)
        points, where = one_curve(path, values[:, :2], where, "R")
        check_axis(str(path), points, where, _SWAPPED)
        # (a repeated row, dropped, would shift the fractions of arclength of the rows after it)
        return Trace(points, str(path), fmt, tuple(where), spread, n_traces,
                     written=written and len(points) == len(values))
    scale = image_scale(path, fmt, pixel_size_um, radius_um)
    spline = False
    if fmt == "roi":
        pixels, where, spline = roi_points(str(path), _roi_of(path, data))
    else:
        _, pixels, where, _ = read_table(path, data, fmt)
    return pixel_trace(str(path), fmt, pixels, where, scale, spline)


def _format_of(path: Path, data: bytes, fmt: str | None) -> str:
    """``fmt``, or when None the format of the file's bytes ``data`` (module docstring)."""
    if fmt is not None:
        return fmt
    return "roi" if data[:4] in (b"Iout", ZIP_MAGIC) else text_format(path, data)


def text_coordinates(path: str | Path, format: str | None = None) -> np.ndarray | None:
    """The coordinates of an image trace in a text file as written, unscaled.

    Pixels, or µm where Fiji exported the XY coordinates of a spatially
    calibrated image: a command's message of a wrong scale reads them to tell
    (their decimals).  A ROI is in pixels whatever the image's calibration.

    Parameters
    ----------
    path : str or Path
    format : str, optional
        One of :data:`FORMATS`; inferred from the content when None.

    Returns
    -------
    ndarray, shape (n, 2), or None
        The rows of an ``xy`` or ``fiji-xy`` file; None for csv and roi.

    Raises
    ------
    MidlineError
        As :func:`read_trace`.
    """
    path = Path(path)
    fmt = None if format is None else check_choice(format, FORMATS, "format")
    data = read_bytes(path)
    fmt = _format_of(path, data, fmt)
    return read_table(path, data, fmt)[1] if fmt in ("xy", "fiji-xy") else None


def pixel_trace(source: str, fmt: str, pixels: np.ndarray, where: Sequence[str], scale: float,
                spline: bool = False) -> Trace:
    """The :class:`Trace` of a curve in image pixels (y down), checked and scaled to units of R.

    Parameters
    ----------
    source : str
        The file (and ROI), for messages and ``Trace.source``.
    fmt : str
        Its format, one of :data:`FORMATS` but csv.
    pixels : ndarray, shape (n, 2)
        The points (x, y) in pixels.
    where : sequence of str, length n
        Where each point is in the file, for messages.
    scale : float
        Units of R per pixel (:func:`image_scale`).
    spline : bool
        The points are the control points of an ImageJ spline fit.

    Returns
    -------
    Trace

    Raises
    ------
    MidlineError
        Not one simple curve of at least 4 distinct points, or points more
        than 20 R from the first (a wrong scale).
    """
    pixels, where = one_curve(source, pixels, list(where), "px")
    # (relative to the first point: the image origin is anywhere)
    check_extent(source, (pixels - pixels[0]) * scale, where,
                  "check the pixel size and the radius R")
    if spline:
        pixels = _imagej_spline(pixels)     # each point labelled by the control point before it
        where = [where[min(k // SPLINE_SUBDIVISIONS, len(where) - 1)] for k in range(len(pixels))]
    return Trace(pixels * [scale, -scale], source, fmt, tuple(where), scale=scale)


def _roi_of(path: Path, data: bytes):
    """The ImageJ ROI in the bytes ``data`` of the file ``path``."""
    import roifile
    if data[:4] == ZIP_MAGIC:
        raise MidlineError(f"{path}: a zip file (an ImageJ ROI Manager set?): load_midline reads "
                           f"it, one line ROI chosen by roi=NAME or INDEX, or roi='all'")
    try:
        return roifile.ImagejRoi.frombytes(data)
    except Exception as exc:    # roifile raises ValueError, struct.error, … on damaged files
        raise MidlineError(f"{path}: not a readable ImageJ ROI file ({exc})") from None


def roi_kind(roi) -> str | None:
    """None for a line ROI (a trace), else what it is ("an oval", "a composite ROI", ...)."""
    import roifile
    kind = roifile.ROI_TYPE(roi.roitype)
    if roi.multi_coordinates is not None:
        return "a composite ROI (several shapes)"
    if kind in (roifile.ROI_TYPE.POLYGON, roifile.ROI_TYPE.FREEHAND, roifile.ROI_TYPE.TRACED,
                roifile.ROI_TYPE.RECT, roifile.ROI_TYPE.OVAL):
        return f"an area selection ({kind.name.lower()})"
    if kind not in (roifile.ROI_TYPE.POLYLINE, roifile.ROI_TYPE.FREELINE, roifile.ROI_TYPE.LINE):
        return f"a {kind.name.lower()} ROI"
    return None


def roi_points(source: str, roi) -> tuple[np.ndarray, list[str], bool]:
    """Pixel coordinates, labels and the spline-fit flag of an ImageJ line ROI.

    Parameters
    ----------
    source : str
        The file (and ROI), for messages.
    roi : roifile.ImagejRoi

    Returns
    -------
    pixels : ndarray, shape (n, 2)
    where : list of str
        "point k", k from 1.
    spline : bool
        Flagged as the control points of a spline fit.

    Raises
    ------
    MidlineError
        Not a line selection (:func:`roi_kind`).
    """
    import roifile
    kind = roi_kind(roi)
    if kind is not None:
        hint = (": trace the midline with the segmented, freehand or straight line tool"
                if kind.startswith("an area") else " selection")
        raise MidlineError(f"{source}: {kind}, not a line{hint}")
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


#: The likely cause of a csv midline that crosses the axis: a column z from the pole runs
#: along the axis, where a column r may not.  Of one that reaches too far: other units (an
#: audit's r,z in µm was told only of pixels).
_SWAPPED = ": are its columns r and z swapped?"
_OTHER_UNITS = ("r,z csv traces are in units of R, the embryo's radius: divide r and z in µm by "
              "the radius in µm; a trace in pixels is read with format 'xy', 'fiji-xy' or "
              "'roi' and a scale")


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
    radius_px = check_positive("radius_px", radius_px)
    if check_choice(section, ("whole", "half"), "section") == "whole":
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
        One of :data:`FORMATS`.  csv writes the points as they are: a
        :class:`Midline` by :meth:`Midline.to_csv` (read back as a midline's
        rows, :attr:`Trace.written`), an array as a trace (header ``r,z``
        only, resampled when read).
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
    path, fmt = Path(path), check_choice(format, FORMATS, "format")
    points = midline.points if isinstance(midline, Midline) else np.asarray(midline, dtype=float)
    if spline_fit and fmt != "roi":
        raise MidlineError(f"{path}: spline_fit applies to the roi format only")
    if fmt == "csv":
        if section not in (None, "half"):
            raise MidlineError(f"{path}: csv holds half midlines in the model gauge: section "
                               f"{section!r} does not apply")
        if isinstance(midline, Midline):
            midline.to_csv(path)
        else:       # a trace, not a midline's rows: no n_traces comment (Trace.written)
            trace = Midline(*points.T)      # (its checks of the shape)
            _write_csv(path, (), ("r", "z"), (trace.r, trace.z))
        return
    scale = image_scale(path, fmt, pixel_size_um, radius_um)
    pixels = to_image(points, radius_px=1.0 / scale, angle_deg=angle_deg, offset_px=offset_px,
                      section=section or "whole")
    if noise_px:
        noise = check_positive("noise_px", noise_px)
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