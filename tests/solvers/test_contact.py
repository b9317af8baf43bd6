"""Self-contact (solvers/contact.py): the model has none, so a solved shape whose walls pass
through each other is flagged — the documented inverted Volvox (user audit 6, finding 8) —
and ordinary shapes, tight bends included, are not."""
import logging
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from morphoshell.io.problem_files import example_path, load_problem
from morphoshell.solvers.contact import FAR, wall_contact
from morphoshell.solvers.routes import solve

FOLD = Path(__file__).resolve().parents[1] / "data" / "volvox_fold.toml"


def _hairpin(h: float, gap: float, legs: float, f_s: float = 1.0, n: int = 200,
             tilt: float = 0.0):
    """A midline of two straight legs ``gap`` apart (length ``legs``) joined by a half circle,
    as the fields wall_contact reads: stretched f_s along it, f_φ = 1 (the walls are h/f_s
    thick; unstretched by default); ``n`` points on the bend, 2 n on each leg, the second
    leg rising ``tilt`` per unit length towards the first (0: parallel)."""
    radius = gap / 2
    t = np.linspace(0, np.pi, n)
    bend = np.column_stack([radius * np.sin(t), radius * np.cos(t)])
    leg = np.linspace(0, legs, 2 * n)[::-1]
    points = np.vstack([np.column_stack([-leg, np.full_like(leg, radius)]), bend,
                        np.column_stack([-leg[::-1], tilt * leg[::-1] - radius])])
    s = np.r_[0, np.cumsum(np.hypot(*np.diff(points, axis=0).T))] / f_s
    ones = np.ones(len(s))
    return SimpleNamespace(r=points[:, 0] + legs + 1, z=points[:, 1], s=s, f_s=f_s * ones,
                           f_phi=ones, problem=SimpleNamespace(h=h))


def test_walls_closer_than_h_overlap_and_a_bend_alone_does_not():
    """Legs 0.8 h apart overlap (by 0.2 h, exactly: the points of the legs face each
    other); 1.2 h apart they do not; a tight half circle alone (radius 0.4 h, π 0.4 h of
    midline, less than FAR h) is one bend, not two walls, though its ends are 0.8 h apart."""
    h = 0.1
    contact = wall_contact(_hairpin(h, 0.8 * h, legs=1.0))
    assert contact is not None and contact.overlaps
    assert contact.distance == pytest.approx(0.8 * h) and contact.thickness == pytest.approx(h)
    assert contact.s[1] - contact.s[0] > FAR * h
    assert wall_contact(_hairpin(h, 1.2 * h, legs=1.0)) is None
    assert wall_contact(_hairpin(h, 0.8 * h, legs=0.0)) is None


def test_a_compressed_thickened_bend_alone_is_not_two_walls():
    """Compressed to f_s = 0.5, the walls are 2 h thick: a half circle of radius 0.4 of that
    (its ends 0.8 of the thickness apart) spans 5 h of s but 1.3 thicknesses of deformed
    midline, one bend.  Measured in the undeformed h and s it was taken for two walls, as
    were the thickened bends of fitted Volvox shells (audit 19: 5 of Fig. 3's 9 panels
    flagged, walls 0.28 R apart, 0.29 R thick, over 0.32 R of midline)."""
    h, f_s = 0.1, 0.5
    thick = h / f_s
    assert wall_contact(_hairpin(h, 0.8 * thick, legs=0.0, f_s=f_s)) is None
    # its legs, long enough, are two walls 0.8 of their thickness apart
    contact = wall_contact(_hairpin(h, 0.8 * thick, legs=1.0, f_s=f_s))
    assert contact.overlaps and contact.thickness == pytest.approx(thick)


def test_the_inverted_volvox_shell_is_flagged(caplog):
    """The docs' fold shell at lambda = 1 (100 nodes): points about 1.6 R apart along s
    (0.96 and 2.57 at 200 nodes, audit) come within about 0.06 R, less than h = 0.15;
    solve() logs it once, naming the missing self-contact."""
    problem, _ = load_problem(FOLD)
    with caplog.at_level(logging.WARNING, logger="morphoshell.solvers.contact"):
        eq = solve(problem, nodes=100)
    contact = wall_contact(eq)
    assert contact.overlaps and contact.distance < 0.1 < problem.h
    assert contact.s[0] == pytest.approx(0.96, abs=0.05) and contact.s[1] == pytest.approx(
        2.57, abs=0.05)
    warnings = [r.getMessage() for r in caplog.records if r.name.endswith("contact")]
    assert len(warnings) == 1 and "no self-contact" in warnings[0]


def test_an_ablations_two_shells_are_told_apart_in_their_warnings(caplog):
    """An ablation solves one problem intact and cut: both warnings began with the same name
    and read as one line twice (audit 20); the cut shell's names its cut."""
    from morphoshell.mechanics.ablation import ablate

    problem, _ = load_problem(FOLD)
    with caplog.at_level(logging.WARNING, logger="morphoshell.solvers.contact"):
        ablate(problem.with_updates(cut=0.15), nodes=100)
    warnings = [r.getMessage() for r in caplog.records if r.name.endswith("contact")]
    name = problem.name
    assert len(warnings) == 2 and warnings[0].startswith(f"{name}: the shell's walls")
    assert warnings[1].startswith(f"{name} (cut at Sigma = 0.15): the shell's walls")


@pytest.mark.parametrize("name", ["toy2_ablation", "volvox_inversion", "blister"])
def test_ordinary_examples_are_not_flagged(name, caplog):
    """Packaged examples whose walls stay apart (100 nodes): no contact, no warning."""
    problem, _ = load_problem(example_path(name))
    with caplog.at_level(logging.WARNING, logger="morphoshell.solvers.contact"):
        eq = solve(problem, nodes=100)
    assert wall_contact(eq) is None
    assert not [r for r in caplog.records if r.name.endswith("contact")]


def test_many_points_find_the_closest_pair_in_the_memory_of_a_window_pair(monkeypatch):
    """Above BRUTE_POINTS the closest pair is found window by window: the pair that all
    distances give, in little memory.  A search by distance alone (a k-d tree, before)
    listed every pair closer than the walls' thickness, ~N² of them (here 1.4e7 pairs,
    0.2 GB; 2.1e7 and 0.9 GB at 12 799 points of the Volvox fold shell, out of memory at
    10^5 nodes); the windows' peak is about 1 MB here, so 20 MB fails only such a list."""
    import tracemalloc

    from morphoshell.solvers import contact as module

    h = 0.1     # legs 0.8 h apart at the bend, 0.78 h at their tips: one closest pair
    eq = _hairpin(h, 0.8 * h, legs=1.0, n=2500, tilt=0.02 * h)
    assert len(eq.s) > module.BRUTE_POINTS
    tracemalloc.start()
    try:
        contact = wall_contact(eq)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 20e6
    assert contact.s == (0.0, eq.s[-1]) and contact.distance == pytest.approx(0.78 * h)
    monkeypatch.setattr(module, "BRUTE_POINTS", len(eq.s))
    assert wall_contact(eq) == contact
    # and an ordinary solved shell, cut into windows: the pair of all distances
    fold, _ = load_problem(FOLD)
    eq = solve(fold, nodes=200)
    monkeypatch.setattr(module, "BRUTE_POINTS", 0)
    monkeypatch.setattr(module, "WINDOW", 16)
    assert wall_contact(eq) == contact_of_all_distances(eq, monkeypatch, module)


def contact_of_all_distances(eq, monkeypatch, module):
    """``eq``'s contact from all distances (BRUTE_POINTS above its points)."""
    monkeypatch.setattr(module, "BRUTE_POINTS", len(eq.s))
    return wall_contact(eq)
