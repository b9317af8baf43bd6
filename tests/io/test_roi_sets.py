"""ImageJ ROI Manager sets (RoiSet.zip): one line ROI by name or position, or all averaged.

Before issue 41 a set was read as text: "line 1: not UTF-8 text (byte 11)".  The sets here
are written with roifile (``ImagejRoi.tofile`` appends an entry NAME.roi to a zip), as the
ROI Manager's More > Save writes them.
"""
import logging

import numpy as np
import pytest
import roifile

from morphoshell.io import MidlineError, average, load_midline, read_trace
from reference_midline import SCALE, write


def _roi_set(tmp_path, lines=3, others=True, name="RoiSet.zip"):
    """A set of `lines` noisy traces of the reference midline (embryo1...), an oval and a point."""
    path = tmp_path / name
    for k in range(lines):
        single = write(tmp_path, "roi", name=f"single{k + 1}", angle_deg=20.0 * k,
                       offset_px=(300.0, 300.0), noise_px=0.3, seed=k)
        roifile.ImagejRoi.fromfile(single).tofile(path, name=f"embryo{k + 1}")
    if others:
        roifile.ImagejRoi(roitype=roifile.ROI_TYPE.OVAL, left=10, top=10, right=200,
                          bottom=200).tofile(path, name="outline")
        point = roifile.ImagejRoi.frompoints([[5.0, 5.0]])
        point.roitype = roifile.ROI_TYPE.POINT
        point.tofile(path, name="pole")
    return path


def test_one_line_roi_by_name_or_position_is_the_single_roi_file(tmp_path):
    path = _roi_set(tmp_path)
    single = load_midline(tmp_path / "single2.roi", **SCALE)
    for choice in ("embryo2", 2, "2"):
        m = load_midline(path, roi=choice, **SCALE)
        assert np.array_equal(m.points, single.points) and m.n_traces == 1
        assert m.source == (f"{path}, ROI 'embryo2'",)


def test_all_line_rois_are_averaged_as_one_stage_and_the_others_skipped(tmp_path, caplog):
    path = _roi_set(tmp_path)
    with caplog.at_level(logging.WARNING, logger="morphoshell"):
        m = load_midline(path, roi="all", **SCALE)
    assert "skipped 2 ROI(s) that are not lines: 4: 'outline' (an area selection (oval)), " \
           "5: 'pole' (a point ROI)" in caplog.text
    singles = [load_midline(tmp_path / f"single{k}.roi", **SCALE) for k in (1, 2, 3)]
    expected = average(singles)
    assert m.n_traces == 3 and np.allclose(m.points, expected.points, atol=1e-12)
    assert np.allclose(m.spread, expected.spread, atol=1e-12)


def test_a_set_with_one_line_roi_needs_no_choice(tmp_path):
    path = _roi_set(tmp_path, lines=1)
    assert np.array_equal(load_midline(path, **SCALE).points,
                          load_midline(tmp_path / "single1.roi", **SCALE).points)


@pytest.mark.parametrize("lines, others, roi, message", [
    (3, True, None, "RoiSet.zip: 3 line ROIs (1: 'embryo1', 2: 'embryo2', 3: 'embryo3'): choose "
                    "one with roi=NAME or INDEX (from 1), or roi='all' to average them"),
    (3, True, "outline", "RoiSet.zip: ROI 'outline' is an area selection (oval), not a line; its "
                         "line ROIs: 1: 'embryo1', 2: 'embryo2', 3: 'embryo3'"),
    (3, True, 5, "RoiSet.zip: ROI 'pole' is a point ROI, not a line"),
    (3, True, "embryo9", "RoiSet.zip: no ROI named 'embryo9', nor at that position (1 to 5); its "
                         "ROIs: 1: 'embryo1'"),
    (0, True, None, "RoiSet.zip: no line ROI among its 2 ROIs (1: 'outline' (an area selection "
                    "(oval)), 2: 'pole' (a point ROI)): trace the midline with the segmented"),
])
def test_bad_choices_name_the_file_and_the_rois(tmp_path, lines, others, roi, message):
    path = _roi_set(tmp_path, lines, others)
    with pytest.raises(MidlineError) as exc:
        load_midline(path, roi=roi, **SCALE)
    assert message in str(exc.value)


def test_bad_sets_and_options(tmp_path):
    path = _roi_set(tmp_path)
    with pytest.raises(MidlineError, match="roi coordinates are in pixels: pass pixel_size_um"):
        load_midline(path, roi=1)
    with pytest.raises(MidlineError, match=r"a zip file \(an ImageJ ROI Manager set\?\): "
                                           r"load_midline reads it"):
        read_trace(path, **SCALE)
    with pytest.raises(MidlineError, match=r"RoiSet\.zip: a zip file \(an ImageJ ROI Manager "
                                           r"set\?\), not text"):      # was "not UTF-8 text"
        read_trace(path, "xy", **SCALE)
    with pytest.raises(MidlineError, match=r"single1\.roi: roi=1 applies to an ImageJ ROI "
                                           r"Manager set \(zip\), not to this file"):
        load_midline(tmp_path / "single1.roi", roi=1, **SCALE)
    import zipfile
    broken = tmp_path / "broken.zip"
    with zipfile.ZipFile(broken, "w") as zf:
        zf.writestr("a.roi", b"Iout\x00\x01")
    with pytest.raises(MidlineError, match=r"broken\.zip: entry 'a\.roi' is not a readable "
                                           r"ImageJ ROI"):
        load_midline(broken, roi=1, **SCALE)
    other = tmp_path / "notes.zip"
    with zipfile.ZipFile(other, "w") as zf:
        zf.writestr("notes.txt", "hello")
    with pytest.raises(MidlineError, match=r"notes\.zip: a zip file without \.roi entries"):
        load_midline(other, **SCALE)


def test_load_midlines_gives_a_sets_traces_one_by_one(tmp_path):
    """load_midlines: the single traces that load_midline averages, each its own ROI's."""
    from morphoshell.io import load_midlines

    path = _roi_set(tmp_path)
    singles = load_midlines(path, roi="all", **SCALE)
    assert [m.source for m in singles] == [(f"{path}, ROI 'embryo{k}'",) for k in (1, 2, 3)]
    for k, m in enumerate(singles, start=1):
        assert np.array_equal(m.points, load_midline(tmp_path / f"single{k}.roi", **SCALE).points)
    assert np.array_equal(average(singles).points, load_midline(path, roi="all", **SCALE).points)


#: Radii (µm) of the embryos of a set of several embryos in one image (audit 25: R = 35-42 µm).
RADII = (45.0, 50.0, 56.0)


def _set_of_radii(tmp_path, radii=RADII):
    """A set of the reference midline traced in embryos of `radii` (µm) at SCALE's pixel size,
    each also written as its own .roi (single1...)."""
    from morphoshell.io import write_trace

    from reference_midline import half

    path = tmp_path / "RoiSet.zip"
    for k, radius in enumerate(radii):
        single = tmp_path / f"single{k + 1}.roi"
        write_trace(single, half(), "roi", pixel_size_um=SCALE["pixel_size_um"], radius_um=radius,
                    angle_deg=20.0 * k, offset_px=(300.0, 300.0), noise_px=0.3, seed=k)
        roifile.ImagejRoi.fromfile(single).tofile(path, name=f"embryo{k + 1}")
    return path


def test_each_line_roi_of_a_set_takes_its_own_radius(tmp_path):
    """Several embryos in one image: one radius per line ROI, in the set's order, reads each
    ROI as its own file at its radius (audit 25: one radius for all put the traces' mean
    spread at 10 times that of the right radii)."""
    from morphoshell.io import load_midlines

    path = _set_of_radii(tmp_path)
    pixel = {"pixel_size_um": SCALE["pixel_size_um"]}
    each = load_midlines(path, roi="all", radius_um=list(RADII), **pixel)
    for k, (m, radius) in enumerate(zip(each, RADII), start=1):
        single = load_midline(tmp_path / f"single{k}.roi", radius_um=radius, **pixel)
        assert np.array_equal(m.points, single.points)
    shared = load_midlines(path, roi="all", radius_um=RADII[1], **pixel)
    assert not np.allclose(shared[0].points, each[0].points, atol=1e-3)
    assert np.array_equal(shared[1].points, each[1].points)        # (its own radius)


def test_radii_that_do_not_match_the_line_rois_are_refused(tmp_path):
    path = _set_of_radii(tmp_path)
    with pytest.raises(MidlineError) as exc:
        load_midline(path, roi="all", pixel_size_um=0.25, radius_um=[45.0, 50.0])
    assert str(exc.value) == (f"{path}: radius_um has 2 radii for the 3 line ROIs chosen "
                              f"('embryo1', 'embryo2', 'embryo3'): give one for all or one per "
                              f"line ROI, in the set's order")
    with pytest.raises(MidlineError, match="radius_um = -1.0 must be positive"):
        load_midline(path, roi="all", pixel_size_um=0.25, radius_um=[45.0, -1.0, 50.0])
    with pytest.raises(MidlineError, match="radius_um is empty"):
        load_midline(path, roi="all", pixel_size_um=0.25, radius_um=[])
    with pytest.raises(MidlineError, match=r"single1\.roi: radius_um lists radii, one per line "
                                           r"ROI of a ROI Manager set: this file holds one"):
        load_midline(tmp_path / "single1.roi", pixel_size_um=0.25, radius_um=[45.0])


def test_line_roi_names_counts_the_chosen_without_a_warning(tmp_path, caplog):
    from morphoshell.io.roi_sets import line_roi_names

    path = _roi_set(tmp_path)
    with caplog.at_level(logging.WARNING, logger="morphoshell"):
        assert line_roi_names(path, "all") == ["embryo1", "embryo2", "embryo3"]
        assert line_roi_names(path, 2) == ["embryo2"]
    assert caplog.text == ""
