"""Self-contact: where a solved shell's walls come closer than their thickness.

The model has no self-contact: its energy is that of the sheet alone, and
nothing keeps two parts of the sheet apart.  A shell that folds far enough
(an inverting Volvox, a deep invagination) can therefore reach minima whose
walls pass through each other — the midlines need not cross, only come
closer than the sheet's thickness.  Such a shape is a true minimum of the
model but not a physical shape; :func:`wall_contact` finds the closest
approach of the walls and :func:`warn_if_walls_overlap` says so (documentation:
"Solution", self-contact).

Distances are between the solution's points (nodes and Gauss points) in the
meridian half-plane (r, z): the closest points of two rings of a surface of
revolution lie at the same azimuth.  Lengths in units of R.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import Any

import numpy as np

from .._runtime.validate import real, short, within
from .results import Equilibrium

__all__ = ["WallContact", "wall_contact", "warn_if_walls_overlap", "warn_of_contact",
           "half_thickness", "FAR"]

log = logging.getLogger(__name__)

#: Points more than this many of their walls' thicknesses apart along the deformed
#: midline are on different walls.  Within one bend the walls cannot touch unless the
#: bend's radius is below half the thickness (its inner face then folds into itself,
#: which is not contact), and such a U-turn spans π/2 ≈ 1.6 thicknesses of midline; 3
#: leaves a margin.  Both measured deformed: in units of the undeformed h and s, the
#: thickened, compressed bends of fitted Volvox shells (walls 0.29 R thick, h = 0.15, a
#: 90° turn over 0.32 R of midline, 0.45 R of s) were taken for two walls.
FAR = 3.0

#: Up to this many points the close pairs are found from all distances, above window by
#: window (:func:`_closest_by_windows`).
BRUTE_POINTS = 8000
#: Consecutive points (along the midline) of a window of :func:`_closest_by_windows`.
WINDOW = 128

@dataclass(frozen=True)
class WallContact:
    """The closest approach of two walls of a shell.

    Attributes
    ----------
    s : (float, float)
        The two material points (s, undeformed arclength, R), more than
        :data:`FAR` times their walls' thickness apart along the deformed midline.
    distance : float
        Between their midline points (R).
    thickness : float
        The sum of the two walls' half deformed thicknesses h/(2 f_s f_φ) (R):
        the distance below which the walls overlap.
    """

    s: tuple[float, float]
    distance: float
    thickness: float

    @property
    def overlaps(self) -> bool:
        """The walls pass through each other: closer than their thickness."""
        return self.distance < self.thickness

    def describe(self) -> str:
        """One line: where, how close, and against what thickness."""
        a, b = self.s
        return (f"material points s = {a:.4g} and {b:.4g} ({b - a:.3g} R apart along s) are "
                f"{self.distance:.3g} R apart, less than the walls' thickness there "
                f"({self.thickness:.3g} R)")

    def to_dict(self) -> dict:
        """JSON-ready: ``s`` (the two material points), ``distance`` and ``thickness`` (R)."""
        return {"s": list(self.s), "distance": self.distance, "thickness": self.thickness}

    @classmethod
    def from_dict(cls, value: Any, key: str = "walls_cross",
                  shell: tuple[float, float] | None = None) -> "WallContact":
        """The contact :meth:`to_dict` wrote (a fit's record's ``walls_cross``); ValueError
        naming ``key``'s entry and what it must be.

        What :func:`wall_contact` returns and nothing else: two material points, ``s``
        increasing (it sorts them; equal ones are one point, not two walls), within
        ``shell`` (the problem's s range [cut, L − P], where known; else s >= 0), closer
        than a positive ``thickness`` (it returns None for walls that do not overlap), and
        no other keys.  A record that says otherwise is not a crossing (an audit: distance 5
        times the thickness was read, and reported, as walls that cross).
        """
        keys = {"s", "distance", "thickness"}
        if not (isinstance(value, dict) and set(value) == keys and isinstance(value["s"], list)
                and len(value["s"]) == 2):
            raise ValueError(f"{key} = {short(value)} must be null or {{'s': [s1, s2], "
                             f"'distance': number, 'thickness': number}}")
        a, b = (real(f"{key}.s[{i}]", v) for i, v in enumerate(value["s"]))
        lo, hi = (0.0, np.inf) if shell is None else shell
        if not lo <= a < b <= hi:
            raise ValueError(f"{key}.s = {short(value['s'])} must be two increasing material "
                             f"points of the shell, in [{lo:.6g}, {hi:.6g}]")
        thickness = within(f"{key}.thickness", value["thickness"], 0.0, np.inf, open_lo=True)
        distance = within(f"{key}.distance", value["distance"], 0.0, np.inf)
        if not distance < thickness:
            raise ValueError(f"{key}.distance = {distance!r} must be less than "
                             f"{key}.thickness = {thickness!r}: walls that far apart do not "
                             f"cross")
        return cls((a, b), distance, thickness)


def wall_contact(eq: Equilibrium) -> WallContact | None:
    """The closest approach of points of ``eq`` more than :data:`FAR` of their walls'
    thickness apart along the deformed midline, compared with that thickness; None if no
    such points are within it.

    Parameters
    ----------
    eq : Equilibrium

    Returns
    -------
    WallContact or None
        The pair whose distance is the smallest fraction of their walls'
        thickness (an overlap, :attr:`WallContact.overlaps`), or None where
        the walls stay at least their thickness apart.
    """
    points = np.column_stack([eq.r, eq.z])
    half = half_thickness(eq)
    if not (np.all(np.isfinite(points)) and np.all(np.isfinite(half))):
        return None
    arc = _deformed_arclength(eq)
    if len(points) > BRUTE_POINTS:
        pair = _closest_by_windows(points, arc, half)
    else:
        pairs = _far_apart(_close_pairs(points, 2 * float(np.max(half))), arc, half)
        pair = _closest(pairs, points, half)[1:] if len(pairs) else None
    if pair is None:
        return None
    i, j = pair
    distance, thickness = float(np.hypot(*(points[i] - points[j]))), float(half[i] + half[j])
    if distance >= thickness:
        return None
    a, b = sorted((float(eq.s[i]), float(eq.s[j])))
    return WallContact((a, b), distance, thickness)


def _deformed_arclength(eq: Equilibrium) -> np.ndarray:
    """Arclength of the deformed midline at the points of ``eq``, ∫ f_s ds from its first
    point (trapezoidal, in the points' order along s), shape (N,), units of R."""
    order = np.argsort(eq.s, kind="stable")
    s, f = np.asarray(eq.s, float)[order], np.asarray(eq.f_s, float)[order]
    arc = np.empty(len(s))
    arc[order] = np.r_[0.0, np.cumsum(np.diff(s) * (f[1:] + f[:-1]) / 2)]
    return arc


def half_thickness(eq: Equilibrium) -> np.ndarray:
    """Half the deformed thickness at the points of ``eq``, h/(2 f_s f_φ) (an
    incompressible sheet keeps its volume h ds·r), shape (N,), units of R: the band the
    plots draw and the walls whose contact is looked for."""
    return eq.problem.h / (eq.f_s * eq.f_phi) / 2


def _far_apart(pairs: np.ndarray, arc: np.ndarray, half: np.ndarray) -> np.ndarray:
    """The ``pairs`` (shape (k, 2)) more than :data:`FAR` of their walls' thickness apart
    along the deformed midline ``arc``: on two walls, not one."""
    i, j = pairs.T
    return pairs[np.abs(arc[i] - arc[j]) > FAR * (half[i] + half[j])]


def _close_pairs(points: np.ndarray, radius: float) -> np.ndarray:
    """The pairs (i, j), i < j, of ``points`` (shape (n, 2)) closer than ``radius``, shape
    (k, 2): all distances in blocks of 512 rows."""
    found = []
    for lo in range(0, len(points), 512):
        block = np.hypot(*(points[lo:lo + 512, None, :] - points[None, :, :]).transpose(2, 0, 1))
        i, j = np.nonzero(block < radius)
        keep = j > i + lo
        found.append(np.column_stack([i[keep] + lo, j[keep]]))
    return np.concatenate(found) if found else np.zeros((0, 2), dtype=int)


def _closest(pairs: np.ndarray, points: np.ndarray, half: np.ndarray) -> tuple[float, int, int]:
    """(distance / thickness, i, j) of the pair of ``pairs`` (shape (k, 2), k > 0) whose
    distance is the smallest fraction of their walls' thickness."""
    i, j = pairs.T
    ratio = np.hypot(*(points[i] - points[j]).T) / (half[i] + half[j])
    k = int(np.argmin(ratio))
    return float(ratio[k]), int(i[k]), int(j[k])


def _closest_by_windows(points: np.ndarray, arc: np.ndarray,
                        half: np.ndarray) -> tuple[int, int] | None:
    """The pair (i, j) of :func:`_closest` among the pairs :func:`_far_apart` that overlap,
    None if none does, found between windows of :data:`WINDOW` points consecutive along the
    midline: window pairs in the order of the least fraction of their walls' thickness
    their bounding circles allow, up to the best pair found, and only those whose farthest
    points along the midline are more than :data:`FAR` of their thinnest walls apart.

    A search by distance alone lists every pair closer than the thickest walls, whose number
    grows as the square of the points (the thickness is fixed in R while the points grow
    denser), along each wall and where two walls run close: a k-d tree's list ran a Volvox
    shell out of memory long before :data:`~morphoshell.solvers.direct.MAX_NODES`
    (docs/benchmarks.md, "solvers/contact.py").  Here the memory is that of one window
    pair and the work that of the window pairs near the closest approach.
    """
    order = np.argsort(arc, kind="stable")
    windows = [order[lo:lo + WINDOW] for lo in range(0, len(order), WINDOW)]
    centre = np.array([points[w].mean(axis=0) for w in windows])
    reach = np.array([np.hypot(*(points[w] - c).T).max() for w, c in zip(windows, centre)])
    first, last, thin, thick = (np.array([f(v[w]) for w in windows]) for f, v in
                                ((np.min, arc), (np.max, arc), (np.min, half), (np.max, half)))
    a, b = np.triu_indices(len(windows))
    bound = np.maximum(np.hypot(*(centre[a] - centre[b]).T) - reach[a] - reach[b], 0) / (
        thick[a] + thick[b])
    apart = np.maximum(last[b] - first[a], last[a] - first[b]) > FAR * (thin[a] + thin[b])
    best: tuple[float, int, int] = (1.0, -1, -1)        # (only overlaps count)
    candidates = np.flatnonzero(apart & (bound < 1))
    for k in candidates[np.argsort(bound[candidates], kind="stable")]:
        if bound[k] >= best[0]:
            break
        i, j = np.meshgrid(windows[a[k]], windows[b[k]], indexing="ij")
        pairs = np.column_stack([i.ravel(), j.ravel()])
        pairs = _far_apart(pairs[pairs[:, 0] < pairs[:, 1]] if a[k] == b[k] else pairs, arc,
                           half)
        if len(pairs):
            best = min(best, _closest(pairs, points, half))
    return None if best[1] < 0 else best[1:]


def warn_if_walls_overlap(eq: Equilibrium, what: str = "") -> WallContact | None:
    """A warning where the walls of ``eq`` overlap (:func:`wall_contact`); returns the contact.

    Parameters
    ----------
    eq : Equilibrium
    what : str
        Which shell, to begin the warning with (default: the problem's name, if it has
        one, and its cut, if it has one: an ablation's two shells are one problem's): a
        script that checks many (a campaign's fits and their ablations) must say which of
        them passes through itself.
    """
    contact = wall_contact(eq)
    if contact is not None:
        cut = float(getattr(eq.problem, "cut", 0.0) or 0.0)
        warn_of_contact(contact, what or " ".join(filter(None, [
            eq.problem.name, f"(cut at Sigma = {cut:g})" if cut else ""])))
    return contact


def warn_of_contact(contact: WallContact, who: str = "") -> None:
    """The warning of :func:`warn_if_walls_overlap` for a contact already found (a fit's,
    which its record keeps: :attr:`morphoshell.fitting.results.FitResult.contact`), the
    line beginning with ``who``."""
    log.warning("%sthe shell's walls pass through each other: %s; the model has no "
                "self-contact, so this shape is a minimum of the model but not a physical "
                "one", f"{who}: " if who else "", contact.describe())
