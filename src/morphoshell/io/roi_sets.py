"""ImageJ ROI Manager sets (``RoiSet.zip``): their line ROIs as traces.

*ROI Manager › More › Save* writes every ROI of the manager into one zip file,
an entry ``NAME.roi`` per ROI, in the order of the manager's list.  A set
often holds the midlines of several embryos of one stage, or one midline
among other selections (the embryo's outline, points).  Which ROIs are
traces is chosen by ``roi``:

``None``     the set's only line ROI (refused, naming them, if it has several);
``NAME``     the ROI of that name, as the ROI Manager lists it (its entry's
             name without ``.roi``);
``INDEX``    the ROI at that position in the list, counting from 1 (a name
             made of digits is taken as a name first);
``"all"``    every line ROI: the traces of one stage, which
             :func:`morphoshell.io.midlines.load_midline` averages.

Line ROIs are segmented (polyline), freehand and straight lines, as for a
single ``.roi`` file (:mod:`morphoshell.io.traces`), each scaled by the
set's radius or by its own, the radii listed in the set's order
(:func:`read_set_traces`; :func:`line_roi_names` counts them before).  Other ROIs (areas,
points) are skipped with a warning on the ``morphoshell`` logger; a set
without a line ROI, or a chosen ROI that is not one, is refused with a message
naming the file and the ROIs.  The entries are read with ``zipfile`` and
``roifile``'s ``ImagejRoi.frombytes``, so the file need not be called ``.zip``.
"""
from __future__ import annotations

import logging
import zipfile
from pathlib import Path
from typing import Sequence

import numpy as np

from .traces import MidlineError, Trace, ZIP_MAGIC, image_scale, pixel_trace, roi_kind, roi_points

__all__ = ["ALL", "is_roi_set", "read_roi_set", "choose_rois", "line_roi_names", "read_set_traces"]

#: The choice of every line ROI of a set.
ALL = "all"

log = logging.getLogger(__name__)


def is_roi_set(path: str | Path) -> bool:
    """Whether the file ``path`` is a zip file (an ImageJ ROI Manager set); False if unreadable."""
    try:
        with open(path, "rb") as fh:
            return fh.read(4) == ZIP_MAGIC
    except OSError:
        return False      # (the trace reader names the file that cannot be read)


def read_roi_set(path: str | Path) -> list[tuple[str, object]]:
    """(name, ``roifile.ImagejRoi``) of every ROI of a set, in the ROI Manager's order.

    Parameters
    ----------
    path : str or Path

    Returns
    -------
    list of (str, ImagejRoi)
        The name is the entry's without ``.roi``, as the ROI Manager lists it
        (entries not ending in ``.roi`` are skipped, as ImageJ does).

    Raises
    ------
    MidlineError
        Not a readable zip file, an entry that is not a readable ROI, or no entries.
    """
    import roifile
    rois = []
    try:
        with zipfile.ZipFile(path) as zf:
            for entry in zf.namelist():
                if not entry.endswith(".roi"):     # (ImageJ reads only these)
                    continue
                try:
                    roi = roifile.ImagejRoi.frombytes(zf.read(entry))
                except Exception as exc:    # (ValueError, struct.error, … on damaged entries)
                    raise MidlineError(f"{path}: entry {entry!r} is not a readable ImageJ ROI "
                                       f"({exc})") from None
                rois.append((entry[:-len(".roi")], roi))
    except (zipfile.BadZipFile, OSError) as exc:
        raise MidlineError(f"{path}: not a readable zip file ({exc})") from None
    if not rois:
        raise MidlineError(f"{path}: a zip file without .roi entries: not an ImageJ ROI set")
    return rois


def choose_rois(path: str | Path, rois: list[tuple[str, object]],
                roi: str | int | None = None) -> list[tuple[str, object]]:
    """The line ROIs of a set that ``roi`` chooses (module docstring), others skipped.

    Parameters
    ----------
    path : str or Path
        The set, for messages.
    rois : list of (str, ImagejRoi)
        As :func:`read_roi_set` returns them.
    roi : str, int or None
        A name, a position from 1, ``"all"``, or None for the only line ROI.

    Returns
    -------
    list of (str, ImagejRoi)
        One, or every line ROI for ``"all"``.

    Raises
    ------
    MidlineError
        No line ROI in the set, a choice that names none of its ROIs or one
        that is not a line, or several line ROIs and no choice.
    """
    chosen = _chosen(path, rois, roi)
    if roi is None or roi == ALL:
        _note_skipped(path, rois)
    return chosen


def line_roi_names(path: str | Path, roi: str | int | None = None) -> list[str]:
    """The names of the line ROIs of the set ``path`` that ``roi`` chooses, in its order, the
    others skipped silently: how many traces it holds, to match radii to them before reading
    (``morphoshell average --radius-um``).  MidlineError as :func:`choose_rois`."""
    return [name for name, _ in _chosen(path, read_roi_set(path), roi)]


def _chosen(path, rois: list[tuple[str, object]], roi) -> list[tuple[str, object]]:
    """:func:`choose_rois` without its warning of the ROIs skipped."""
    lines = [(name, r) for name, r in rois if roi_kind(r) is None]
    if not lines:
        raise MidlineError(f"{path}: no line ROI among its {len(rois)} ROIs ({_listing(rois)}): "
                           f"trace the midline with the segmented, freehand or straight line tool")
    if roi is None or roi == ALL:
        if roi is None and len(lines) > 1:
            raise MidlineError(f"{path}: {len(lines)} line ROIs ({_listing(rois, True)}): "
                               f"choose one with roi=NAME or INDEX (from 1), or roi='all' to "
                               f"average them")
        return lines
    name, chosen = _lookup(path, rois, roi)
    kind = roi_kind(chosen)
    if kind is not None:
        raise MidlineError(f"{path}: ROI {name!r} is {kind}, not a line; its line ROIs: "
                           f"{_listing(rois, True)}")
    return [(name, chosen)]


def _lookup(path, rois: list[tuple[str, object]], roi: str | int) -> tuple[str, object]:
    """The ROI named ``roi``, else at position ``roi`` (from 1); MidlineError naming them."""
    for name, r in rois:
        if name == str(roi):
            return name, r
    text = str(roi).strip()
    if text.isdigit() and 1 <= int(text) <= len(rois):
        return rois[int(text) - 1]
    raise MidlineError(f"{path}: no ROI named {roi!r}, nor at that position (1 to {len(rois)}); "
                       f"its ROIs: {_listing(rois)}")


def _listing(rois: list[tuple[str, object]], lines: bool | None = None, most: int = 8) -> str:
    """"k: 'name' (kind), ..." of the set's ROIs (only its lines, or only others), for messages.

    k is the position in the whole set, as ``roi=INDEX`` takes it; at most ``most``.
    """
    shown = [f"{k}: {name!r}" + ("" if roi_kind(r) is None else f" ({roi_kind(r)})")
             for k, (name, r) in enumerate(rois, 1)
             if lines is None or (roi_kind(r) is None) == lines]
    more = f", … {len(shown) - most} more" if len(shown) > most else ""
    return ", ".join(shown[:most]) + more


def _note_skipped(path, rois: list[tuple[str, object]]) -> None:
    skipped = sum(roi_kind(r) is not None for _, r in rois)
    if skipped:
        log.warning("%s: skipped %d ROI(s) that are not lines: %s", path, skipped,
                    _listing(rois, lines=False))


def read_set_traces(path: str | Path, roi: str | int | None = None, *,
                    pixel_size_um: float | None = None,
                    radius_um: float | Sequence[float] | None = None) -> list[Trace]:
    """The traces of the line ROIs of a set that ``roi`` chooses, in units of R.

    Parameters
    ----------
    path : str or Path
    roi : str, int or None
        See :func:`choose_rois`.
    pixel_size_um : float
        µm per pixel (required: ROIs are in pixels).
    radius_um : float or sequence of float
        The embryo radius R in µm (required): one for every ROI chosen, or one
        per ROI chosen, in the set's order (several embryos in one image; one
        radius for embryos of R = 35-42 µm put the traces' mean spread at 10
        times that of the right radii, audit 25).

    Returns
    -------
    list of Trace
        Format ``"roi"``, source ``"PATH, ROI 'NAME'"``.

    Raises
    ------
    MidlineError
        A missing scale (checked first), an unreadable set or choice
        (:func:`read_roi_set`, :func:`choose_rois`), a ROI that is not one
        simple curve (:func:`morphoshell.io.traces.pixel_trace`).
    """
    radii = [radius_um] if radius_um is None or np.ndim(radius_um) == 0 else list(radius_um)
    if not radii:
        raise MidlineError(f"{path}: radius_um is empty: give one radius R in µm for all its "
                           f"line ROIs, or one per line ROI")
    scales = [image_scale(path, "roi", pixel_size_um, radius) for radius in radii]
    chosen = choose_rois(path, read_roi_set(path), roi)
    if len(scales) not in (1, len(chosen)):
        raise MidlineError(f"{path}: radius_um has {len(radii)} radii for the {len(chosen)} line "
                           f"ROIs chosen ({', '.join(repr(name) for name, _ in chosen)}): give "
                           f"one for all or one per line ROI, in the set's order")
    traces = []
    for (name, r), scale in zip(chosen, scales * len(chosen) if len(scales) == 1 else scales):
        source = f"{path}, ROI {name!r}"
        pixels, where, spline = roi_points(source, r)
        traces.append(pixel_trace(source, "roi", pixels, where, scale, spline))
    return traces
