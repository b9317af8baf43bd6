"""Meshes of the shell: grading toward edges and poles, and the parametric map to s.

Both solution routes use these meshes: the direct solver's cells and the
boundary-value reference's initial collocation mesh.

A mesh is a fixed, graded set of nodes t_0 = 0 < … < t_N = 1 and the
*parametric map* s = Σ + (L − P − Σ) t (:func:`shell_points`), so that the cut
Σ and the opening P are parameters of one NLP: the nodes are material points
that move with them.  The grading concentrates nodes near free edges, whose
boundary layers have width δ = (h/√12)^(1/2)
(:func:`morphoshell.model.energy.boundary_layer_width`), and near poles, where the
solution behaves like s^β with β not an integer (see
:mod:`morphoshell.solvers.bvp`).

:func:`mesh_spec` chooses the grading of a problem so that solvers can be
shared: δ relative to the shell's length, and a small cut relative to it, are
rounded to the nearest power of two, so a sweep over h and Σ re-meshes only
when one of them moves to another octave (a change by more than a factor 2;
the grading in use is never more than a factor √2 from the exact one).
"""
from __future__ import annotations

import logging
import math
from dataclasses import dataclass, replace
from functools import lru_cache
from typing import NamedTuple

import casadi as ca
import numpy as np

from ..model.energy import boundary_layer_width

log = logging.getLogger(__name__)

__all__ = ["boundary_layer_width", "pole_exponent", "graded_mesh", "shell_points",
           "knot_shapes", "mapped_points", "MeshSpec",
           "mesh_spec", "knot_for", "Knot", "breakpoints", "lower_gamma", "MeshTooCoarse",
           "step_cells"]


class MeshTooCoarse(ValueError):
    """Too few cells for the mesh's knots: every segment between knots needs a cell.

    A ValueError of its own, so that the error estimate can skip a coarse level
    that cannot hold the knots while a user's own mesh is refused.
    """


#: Smallest mean cell (units of R) of a mesh: a shorter shell gets fewer nodes
#: (:func:`mesh_spec`): cells of 1.4e-5 R failed, of 2.5e-5 R solved (docs/benchmarks.md).
MIN_CELL = 2.5e-5
#: Fewest nodes :data:`MIN_CELL` leaves a shell (the shortest, 1e-3 R, gets 41).
MIN_NODES = 20
#: Smallest cell (in t) next to a pole; see :func:`graded_mesh`.
MIN_POLE_CELL = 1e-10
#: Extra node density at a refined knot (3 times finer cells there).
KNOT_REFINEMENT = 2.0
#: Each segment between knots holds at least 2^⌊log₂(cells/SEGMENT_CELLS)⌋
#: cells (and one): a power of two, so that the half mesh of the error estimate
#: holds half as many.  A segment of one cell on a mesh and on its half mesh is
#: not refined between them and the estimate does not see its error (a user
#: audit: ``local_relaxation``'s ramp 0.005 R wide, one cell at 100 and 200
#: nodes, estimate 5e-7 of the energy, error 6e-3; 0.02 R wide at 30 and 60).
SEGMENT_CELLS = 24
#: Least share of the nodes (relative to the interior's) in a free edge's
#: boundary layer, and the decay length of that share in units of the width δ;
#: see :func:`graded_mesh`.
LAYER_SHARE = 0.25
LAYER_DECAY = 8.0


def shell_points(t, cut, end, knots: tuple[float, ...] = (), anchors=()):
    """The parametric map from mesh coordinates t ∈ [0, 1] to material points s.

    s = Σ + (L − P − Σ) t (``end`` = L − P), or, with interior ``knots``
    t_1 < … < t_m that must land on the material points ``anchors``,

        s = Σ + (L − P − Σ) t + Σ_j c_j [t(1 − t)/(t_j(1 − t_j))] B((t − t_j)/w_j),

    B(x) = exp(1 − 1/(1 − x²)) a smooth (C^∞) bump with B(0) = 1 that
    vanishes for |x| ≥ 1, w_j the distance from t_j to its nearest other knot
    (B ≡ 1 for a single knot), and c_j the offset that puts knot j on its
    anchor.  The factor t(1 − t) keeps the ends in place and the bump the
    other knots; each correction spreads over as much of the mesh as it may,
    so that anchors can move far from their knots before the map folds (a
    bump that also had to vanish at the ends folded for an anchor near a pole
    moving by 70 %).  The map stays smooth (a kink in the cell sizes costs the
    scheme its superconvergence there) and is affine in Σ, P and the anchors.
    t is numeric (a float or an array); Σ, L − P and the anchors may be
    floats or CasADi expressions, so derivatives with respect to them come
    from automatic differentiation.
    """
    anchors = [anchors[i] for i in range(len(knots))]
    symbolic = any(isinstance(v, (ca.SX, ca.MX)) for v in (cut, end, *anchors))
    t_arr = np.asarray(t, dtype=float)
    shapes = knot_shapes(t_arr, knots)
    if symbolic:
        t_arr, shapes = ca.DM(np.atleast_1d(t_arr)), [ca.DM(np.atleast_1d(v)) for v in shapes]
    return mapped_points(t_arr, shapes, cut, end, np.asarray(knots, dtype=float), anchors)


def knot_shapes(t: np.ndarray, knots: tuple[float, ...]) -> list[np.ndarray]:
    """The correction of each knot in :func:`shell_points` per unit offset, at ``t`` (as t).

    t(1 − t)/(t_j(1 − t_j)) B((t − t_j)/w_j): numbers, fixed by the mesh.
    """
    t = np.asarray(t, dtype=float)
    k = np.asarray(knots, dtype=float)
    out = []
    for j in range(len(k)):
        others = np.delete(k, j)
        shape = t * (1 - t) / (k[j] * (1 - k[j]))
        if len(others):
            shape = shape * _bump((t - k[j]) / np.min(np.abs(others - k[j])))
        out.append(shape)
    return out


def mapped_points(t, shapes, cut, end, knots, anchors):
    """:func:`shell_points` from t and its :func:`knot_shapes` (numbers or CasADi, e.g. the
    t and shapes of one point as symbols, for a per-point function of the mesh)."""
    s = cut + (end - cut) * t
    for j in range(len(shapes)):
        offset = anchors[j] - cut - (end - cut) * knots[j]
        s = s + shapes[j] * offset
    return s


def _bump(x: np.ndarray) -> np.ndarray:
    """exp(1 − 1/(1 − x²)) for |x| < 1, else 0 (smooth, 1 at 0)."""
    x = np.asarray(x, dtype=float)
    inside = np.abs(x) < 1
    out = np.zeros_like(x)
    out[inside] = np.exp(1 - 1 / (1 - x[inside] ** 2))
    return out


def check_monotone(s: np.ndarray) -> None:
    """ValueError unless the material points ``s`` of a mesh increase."""
    if not np.all(np.diff(s) > 0):
        raise ValueError("the mesh's anchors are too far from its knots: the map to s is not "
                         "monotone; build a solver for these anchors")


def pole_exponent(stages: int) -> float:
    """Grading exponent q (s ∝ t^q) at poles that keeps order 2S.

    With a local solution ~ s^β the first cells cost O(N^(−2qβ)) and the
    others sum to O(N^(−2S)) if qβ > S; β ≥ 0.7 in the problems of the paper
    (the exponents of :func:`morphoshell.solvers.poles.pole_solutions` show it), so q = 2S leaves
    a margin.
    """
    return 2.0 * stages


def graded_mesh(cells: int, length: float, start: str, end: str, width: float,
                ratio: float = 6.0, pole_width: float = 0.05, q: float = 2.0,
                edge_scale: float | None = None, knots: tuple[float, ...] = (),
                knot_widths: tuple[float | None, ...] = (),
                kinks: tuple[float, ...] = (), min_cell: float | None = None) -> np.ndarray:
    """Nodes t_0 = 0 < … < t_N = 1 of a smoothly graded mesh.

    The node density (per unit of t) is

        1 + (ratio − 1) exp(−d/ℓ)              near a free edge, ℓ = 3 width/length,
        + (b/ℓ_b) exp(−d/ℓ_b)                  near a free edge, ℓ_b = 8 width/length,
        + B ℓ_c [1/(d + ℓ_c) − 1/(d + ℓ)]      near a free edge, if ℓ_c < ℓ/3,
        + (d/ℓ_p)^(1/q − 1) exp(−d/ℓ_p)        near a pole, ℓ_p = pole_width,

    with d the distance to that end, so free edges get ``ratio`` times finer
    cells across their boundary layer and near a pole the nodes follow
    s ∝ t^q.  The first term holds a share (ratio − 1) ℓ of the nodes
    (relative to the interior's 1), which vanishes with the width; the second
    tops it up to at least ``LAYER_SHARE`` = 1/4, b = max(0, 1/4 − (ratio − 1) ℓ),
    so that thin shells (h ≲ 0.015) keep their boundary layer resolved.  It
    decays like the error density of an order-2S scheme across a layer
    e^(−x/(√2 δ)) with equidistributed error, |y^(2S+1)|^(1/(2S+1)), on the
    scale (2S + 1)√2 δ ≈ 7–10 δ (``LAYER_DECAY`` = 8).  On thin shells this
    cuts the edge-value error by orders of magnitude at a given number of
    nodes (tests/numerics/test_mesh.py checks it at h = 1e-4).  A free edge closer to the axis than
    the boundary-layer width (a cut Σ smaller than δ: ``edge_scale`` ℓ_c = Σ/length) also varies on
    the scale Σ, like log s between Σ and δ (the (σ + ξ) terms of the
    Supplementary's small-cut equations): the second term spends B ℓ_c = 5 %
    of the density per e-fold of d there.  The map t ↦ s is fixed and smooth,
    so refinement keeps the order of the scheme.

    Parameters
    ----------
    cells : int
    length : float
        Length of the shell in s (sets the free-edge grading in t).
    start, end : {"pole", "free"}
    width : float
        Boundary-layer width in s (see :func:`boundary_layer_width`).
    q : float
        Pole grading exponent (see :func:`pole_exponent`).
    knots : tuple of float
        Interior values of t that must be nodes (anchors of the parametric
        map, see :func:`shell_points`); each segment between them gets its
        share of the cells by the same density.
    knot_widths : tuple of float or None
        Per knot (in units of the length): refine around it on this scale,
        adding KNOT_REFINEMENT exp(−|t − t_j|/w_j) to the density (the
        steps of width σ of the Volvox profiles); None adds nothing.
    kinks : tuple of float
        Knots where a profile kinks (``local_relaxation``'s ramp).  A kink
        needs only the node on a thick shell, but a thin one answers it with a
        layer of width δ on each side, as at a free edge: where the free edge's
        layer gets the top-up b (thin shells), the kink gets b/2 per side,
        (b/2ℓ_b) exp(−|t − t_j|/ℓ_b) (without them a thin sphere's error outgrew
        its estimate; docs/solution.md).
    min_cell : float, optional
        Smallest cell (in s, as ``length``) that the least cells of a segment
        (:data:`SEGMENT_CELLS`) may make: a segment between knots gets at most
        its length over ``min_cell`` of them (and one; the segments at the ends
        are not bounded), where more would be too small for the solvers
        (:data:`MIN_CELL`; two knots 1e-4 R apart got 32 cells of 3e-6 R at
        800 nodes, and Ipopt failed).
    """
    if cells < 2:
        raise ValueError(f"need at least 2 cells, got {cells}")
    bounds = np.concatenate([[0.0], np.sort(np.asarray(knots, dtype=float)), [1.0]])
    if np.any(np.diff(bounds) <= 0):
        raise ValueError(f"mesh knots {knots} must lie strictly inside (0, 1) and differ")
    widths = dict(zip(knots, knot_widths))
    bumps = tuple((k, widths[k] / length, KNOT_REFINEMENT) for k in bounds[1:-1]
                  if widths.get(k) is not None)
    ell_b = LAYER_DECAY * width / length
    layer = _layer_share(ratio, width / length)
    if layer > 0:
        bumps += tuple((k, ell_b, layer / (2 * ell_b)) for k in kinks)
    most = None
    if min_cell is not None:
        # (between knots only: the cells at an end are graded into it, at a pole far below
        # min_cell by design)
        most = np.floor(np.diff(bounds) * length / min_cell)
        most[[0, -1]] = np.inf
    return _equidistribute(cells, length, start, end, width, ratio, pole_width, q, edge_scale,
                           bounds, bumps, most)


def _layer_share(ratio: float, width: float) -> float:
    """The top-up b of a free edge's layer (:func:`graded_mesh`): the share of the nodes
    (relative to the interior's) that ``ratio`` alone leaves below LAYER_SHARE, for the
    layer width ``width`` relative to the length."""
    return max(0.0, LAYER_SHARE - (ratio - 1) * 3 * width)


def lower_gamma(a: float, x) -> np.ndarray:
    """The lower incomplete gamma function γ(a, x) = ∫₀^x t^(a−1) e^(−t) dt, for 0 < a ≤ 1, x ≥ 0.

    The series x^a e^(−x) Σ_n x^n / (a (a+1) … (a+n)) (positive terms: no
    cancellation), summed to round-off in one cumulative product; above
    x = 40, γ(a, x) = Γ(a) to 1e-18.  Agrees with ``scipy.special`` to ~1e-15
    relative.  Here so that building a mesh does not import scipy.special
    (0.1–0.4 s, most of a fresh process's first solve).
    """
    x = np.asarray(x, dtype=float)
    shape, x = x.shape, x.ravel()
    if not x.size:
        return x.reshape(shape)
    # (all at most 40, as in meshes: no mask, 0.85 of the time at 50 points)
    top = float(x.max())
    low = None if top <= 40.0 else x <= 40.0
    xs = x if low is None else x[low]
    if len(xs):
        if low is not None:
            top = float(xs.max())
        # terms peak at n ≈ x and then fall like exp(−(n − x)²/2x): below 1e-17 after 9√x
        n = np.arange(1, int(top + 9 * math.sqrt(top) + 20))
        terms = np.cumprod(xs[:, None] / (a + n[None, :]), axis=1)
        total = (1.0 + terms.sum(axis=1)) / a
        # (x = 0 gives 0; the 1 there only keeps the logarithm finite)
        pos = xs > 0
        series = np.where(pos, total * np.exp(a * np.log(np.where(pos, xs, 1.0)) - xs), 0.0)
    if low is None:
        return series.reshape(shape)
    out = np.full_like(x, math.gamma(a))
    if len(xs):
        out[low] = series
    return out.reshape(shape)


def _equidistribute(cells, length, start, end, width, ratio, pole_width, q, edge_scale, bounds,
                    bumps=(), most=None):
    """Nodes equidistributing the density of :func:`graded_mesh`, with nodes at ``bounds``
    (``most``: the most least cells of each segment, see :func:`_segment_shares`)."""
    ell = 3 * width / length
    ell_b = LAYER_DECAY * width / length
    layer = _layer_share(ratio, width / length)
    ell_c = None if edge_scale is None else edge_scale / length
    small_edge = ell_c is not None and ell_c < ell / 3

    def cumulative(d, kind):
        # ∫₀^d of the extra density of an end of this kind
        if kind == "free":
            out = (ratio - 1) * ell * -np.expm1(-d / ell) + layer * -np.expm1(-d / ell_b)
            if small_edge:
                out = out + 0.05 * (np.log1p(d / ell_c) - np.log1p(d / ell))
            return out
        return _pole_cumulative(d, q, pole_width)

    def density(d, kind):
        # d/dd of cumulative(d, kind)
        if kind == "free":
            out = (ratio - 1) * np.exp(-d / ell) + layer / ell_b * np.exp(-d / ell_b)
            if small_edge:
                out = out + 0.05 * (1 / (ell_c + d) - 1 / (ell + d))
            return out
        return _pole_density(d, q, pole_width)

    def bump(x, c, w, a):
        # ∫₀^x a exp(−|u − c|/w) du
        return a * w * (np.sign(x - c) * -np.expm1(-np.abs(x - c) / w) - np.expm1(-c / w))

    # the far end's whole cumulative density: a constant of W for the current
    # q (q may drop below), computed once per q rather than per evaluation
    end_total = {}

    def W(x, grid=False):
        # (grid: x is _invert's grid, where a pole's share is read from its table)
        if q not in end_total:
            end_total[q] = (_pole_on_grid(q, pole_width)[4] if end == "pole"
                            else cumulative(1.0, end))
        pole = _pole_on_grid(q, pole_width) if grid else None
        out = (x + (pole[0] if grid and start == "pole" else cumulative(x, start)) + end_total[q]
               - (pole[1] if grid and end == "pole" else cumulative(1 - x, end)))
        for c, w, a in bumps:
            out = out + bump(x, c, w, a)
        return out

    def dW(x, grid=False):
        pole = _pole_on_grid(q, pole_width) if grid else None
        out = (1 + (pole[2] if grid and start == "pole" else density(x, start))
               + (pole[3] if grid and end == "pole" else density(1 - x, end)))
        for c, w, a in bumps:
            out = out + a * np.exp(-np.abs(x - c) / w)
        return out

    # Nodes within ~1e-16 of the far end are not representable (s ≈ π there,
    # and sin s loses its digits): with q = 2S the cells at a pole reach 1e-15
    # at N = 12800.  Near a pole the cumulative density is q ℓ_p (t/ℓ_p)^(1/q)
    # to leading order, so the first cell is t_1 ≈ ℓ_p (W(1)/(N q ℓ_p))^q:
    # lower q until it is at least MIN_POLE_CELL.  Meshes fine enough to need
    # this have pole-cell errors far below round-off anyway.
    Wb = W(bounds)                                  # (bounds[-1] = 1: Wb[-1] = W(1))
    while "pole" in (start, end) and q > 1 and \
            pole_width * (Wb[-1] / (cells * q * pole_width)) ** q < MIN_POLE_CELL:
        q = max(1.0, q - 0.5)
        Wb = W(bounds)
    share = _segment_shares(np.diff(Wb) / Wb[-1] * cells, cells, most)
    n = np.maximum(1, np.floor(share).astype(int))
    while n.sum() < cells:
        n[np.argmax(share - n)] += 1
    if n.sum() > cells:
        raise MeshTooCoarse(f"{cells} cells cannot hold {len(bounds) - 2} mesh knots")
    target = np.concatenate([np.linspace(Wb[j], Wb[j + 1], n[j] + 1)[:-1] for j in range(len(n))]
                            + [[Wb[-1]]])
    t = _invert(W, dW, target)
    t[np.concatenate([[0], np.cumsum(n)])] = bounds
    return t


def _least_cells(cells: int) -> float:
    """The least cells of a segment between knots on a mesh of ``cells``
    (:data:`SEGMENT_CELLS`)."""
    return 2.0 ** max(0, math.floor(math.log2(cells / SEGMENT_CELLS)))


def _segment_shares(share: np.ndarray, cells: int, most=None) -> np.ndarray:
    """Cells per segment (fractional): in proportion to its share of the density, but at
    least the power of two of :data:`SEGMENT_CELLS` (or the segment's ``most``, if fewer,
    and one), taken from the others in proportion."""
    least = np.full(len(share), _least_cells(cells))
    if most is not None:
        least = np.maximum(1.0, np.minimum(least, most))
    small = share < least
    if not small.any() or small.all():
        return share
    out = share.copy()
    out[small] = least[small]
    out[~small] *= max(0.0, cells - least[small].sum()) / share[~small].sum()
    return out


def _pole_cumulative(d, q: float, pole_width: float):
    """∫₀^d of a pole's extra density (d/ℓ_p)^(1/q − 1) exp(−d/ℓ_p) (:func:`graded_mesh`)."""
    return pole_width * lower_gamma(1 / q, d / pole_width)


def _pole_density(d, q: float, pole_width: float):
    """A pole's extra density at distance d from it (:func:`graded_mesh`)."""
    with np.errstate(divide="ignore"):
        u = d / pole_width
        return np.exp((1 / q - 1) * np.log(u) - u)


@lru_cache(maxsize=16)
def _pole_on_grid(q: float, pole_width: float) -> tuple:
    """A pole's cumulative density at distance d = g and 1 − g of it, g on :func:`_invert`'s
    bracketing grid, its density there, and its cumulative density at 1 (read-only).

    They depend on q and ℓ_p alone, which the scheme's order fixes (q = 2S, lowered on
    meshes fine enough to need it): kept, a mesh evaluates the incomplete gamma function
    at its own nodes only (on the grid it would be a good part of a small mesh's time).
    """
    g = _BRACKET_GRID
    out = (_pole_cumulative(g, q, pole_width), _pole_cumulative(1 - g, q, pole_width),
           _pole_density(g, q, pole_width), _pole_density(1 - g, q, pole_width))
    for a in out:
        a.flags.writeable = False
    return (*out, _pole_cumulative(1.0, q, pole_width))


def _bracket_grid() -> np.ndarray:
    """The fixed bracketing grid of :func:`_invert`: uniform, and geometric towards both ends."""
    ends = np.logspace(-17, -1, 49)
    return np.unique(np.concatenate([[0.0], ends, np.linspace(0, 1, 129), 1 - ends, [1.0]]))


_BRACKET_GRID = _bracket_grid()


def _invert(W, dW, target: np.ndarray) -> np.ndarray:
    """x in [0, 1] with W(x) = target, for W increasing with derivative dW.

    Brackets from W on a fixed grid (geometric towards both ends, where pole
    densities are singular), then Newton steps from whichever end of the
    bracket lands inside it (from the far side of a convex or concave stretch
    Newton converges monotonically), bisection otherwise, to round-off; the
    first step is to the inverse Hermite interpolant of the bracket.  About
    4 evaluations of W instead of the 60 of plain bisection, so meshing stays
    cheap at N = 12800.  W and dW take a keyword ``grid``, True when x is the
    bracketing grid (they may read parts of it kept from earlier meshes).
    """
    grid = _BRACKET_GRID
    Wg, dg = W(grid, grid=True), dW(grid, grid=True)
    i = np.clip(np.searchsorted(Wg, target, side="right") - 1, 0, len(grid) - 2)
    lo, hi, f_lo, f_hi, d_lo, d_hi = (grid[i], grid[i + 1], Wg[i] - target, Wg[i + 1] - target,
                                      dg[i], dg[i + 1])
    # W's round-off (sums of terms up to ~W(1)): below it Newton only bounces
    tol = 1e-14 * np.abs(target) + 1e-17

    x = np.where(np.abs(f_lo) <= np.abs(f_hi), lo, hi)
    done = _reached(f_lo, lo, d_lo, tol) | _reached(f_hi, hi, d_hi, tol)
    # the first step: x of W = target on the inverse cubic Hermite interpolant of the
    # bracket's ends (W and dW known there), secant where it leaves the bracket: one
    # evaluation of W fewer on every node
    a = np.flatnonzero(~done)
    l, h = lo[a], hi[a]
    span = f_hi[a] - f_lo[a]
    u = -f_lo[a] / span
    with np.errstate(divide="ignore", invalid="ignore"):   # (dW infinite at a pole)
        m0 = np.where(np.isfinite(d_lo[a]) & (d_lo[a] > 0), span / d_lo[a], h - l)
        m1 = np.where(np.isfinite(d_hi[a]) & (d_hi[a] > 0), span / d_hi[a], h - l)
    guess = ((2 * u ** 3 - 3 * u ** 2 + 1) * l + (u ** 3 - 2 * u ** 2 + u) * m0
             + (3 * u ** 2 - 2 * u ** 3) * h + (u ** 3 - u ** 2) * m1)
    x[a] = guess = np.where((guess > l) & (guess < h), guess, l + u * (h - l))
    f, d = W(guess) - target[a], dW(guess)
    done[a] = _reached(f, guess, d, tol[a])
    _shrink(a, guess, f, d, lo, hi, f_lo, f_hi, d_lo, d_hi)
    for _ in range(80):
        a = np.flatnonzero(~done)   # only the unconverged nodes are re-evaluated
        if not len(a):
            break
        l, h = lo[a], hi[a]
        with np.errstate(divide="ignore", invalid="ignore"):
            c_lo, c_hi = l - f_lo[a] / d_lo[a], h - f_hi[a] / d_hi[a]
        in_lo, in_hi = (c_lo > l) & (c_lo < h), (c_hi > l) & (c_hi < h)
        use_lo = in_lo & (~in_hi | (np.abs(f_lo[a]) <= np.abs(f_hi[a])))
        use_hi = ~use_lo & in_hi
        new = np.where(use_lo, c_lo, np.where(use_hi, c_hi, (l + h) / 2))
        start = np.where(use_lo, l, h)
        # converged: a Newton step below round-off of x (relative: nodes at a
        # pole are ~1e-15 and must keep all their digits), or the bracket closed
        stop = (((use_lo | use_hi) & (np.abs(new - start) <= 2.3e-16 * np.abs(start)))
                | (h - l <= 2.3e-16 * h))
        x[a] = np.where(stop & (use_lo | use_hi), new, np.where(stop, x[a], new))
        f, d = W(x[a]) - target[a], dW(x[a])
        done[a] = stop | _reached(f, x[a], d, tol[a])
        _shrink(a, x[a], f, d, lo, hi, f_lo, f_hi, d_lo, d_hi)
    return x


def _shrink(a, x, f, d, lo, hi, f_lo, f_hi, d_lo, d_hi) -> None:
    """Replace the bracket end of nodes ``a`` on the side of x (W(x) − target = f, slope d)."""
    below = f < 0
    lo[a], f_lo[a], d_lo[a] = (np.where(below, x, lo[a]), np.where(below, f, f_lo[a]),
                               np.where(below, d, d_lo[a]))
    hi[a], f_hi[a], d_hi[a] = (np.where(below, hi[a], x), np.where(below, f_hi[a], f),
                               np.where(below, d_hi[a], d))


def _reached(f, x, d, tol) -> np.ndarray:
    """|W(x) − target| = |f| is within W's round-off ``tol`` or within what one ulp of x
    changes W by.

    Next to a pole dW ~ d^(1/q − 1) exceeds 1e3 and the root is not
    representable to ``tol``: bisection then spent ~30 evaluations of W closing
    the bracket.  The slope
    is infinite only at the pole itself, which is never a root.
    """
    return np.abs(f) <= tol + 2.3e-16 * np.abs(x) * np.where(np.isfinite(d), d, 0.0)


class Knot(NamedTuple):
    """A node of the mesh that sits at a given material point.

    ``source`` is ``"anchor"`` (the ``index``-th anchor passed with each
    solve) or ``"breakpoint"`` (the family's ``index``-th breakpoint, an
    expression of the parameters); ``width`` is the refinement scale relative
    to the shell's length, or None.
    """

    t: float
    source: str
    index: int
    width: float | None = None
    #: Indices of the family's breakpoints that sit at this knot's material point too (an
    #: anchor at a breakpoint, e.g. the rim s = Σ of a cut at ``local_relaxation``'s kink
    #: s0): one node holds both roles, placed by this knot's own ``source`` (parameters
    #: that move the breakpoint away from the anchor leave it inside a cell: a solver of
    #: its own for them, as :func:`mesh_spec` builds, has it at a node again).
    also: tuple[int, ...] = ()


@dataclass(frozen=True)
class MeshSpec:
    """Everything that fixes a direct solver's mesh t (hashable: a cache key).

    Attributes
    ----------
    nodes : int
        Mesh nodes N (N − 1 cells).
    start, end : {"pole", "free"}
    width : float
        Boundary-layer width relative to the shell's length, δ/(L − P − Σ).
    edge_scale : float or None
        A free edge's distance from the axis relative to the length, when
        below the boundary-layer width (small cuts), else None.
    q : float
        Pole grading exponent (:func:`pole_exponent`).
    knots : tuple of Knot
        Nodes that sit at given material points: anchors passed with every
        solve (for example the rim s = Σ of a later cut, in the intact shell)
        and the family's breakpoints (kinks and steps of the profiles).
    """

    nodes: int
    start: str
    end: str
    width: float
    edge_scale: float | None
    q: float
    knots: tuple[Knot, ...] = ()
    #: :data:`MIN_CELL` relative to the length: the smallest cell a segment between knots
    #: is forced to (:func:`graded_mesh`'s ``min_cell``), or None (no bound).
    min_cell: float | None = None

    def nodes_t(self) -> np.ndarray:
        """The mesh t_0 = 0 < … < t_N = 1.

        Raises
        ------
        MeshTooCoarse
            Too few nodes for the knots, naming ``nodes`` and the fewest that hold them.
        """
        try:
            return self._graded()
        except MeshTooCoarse:
            raise MeshTooCoarse(
                f"nodes = {self.nodes} is too few for this shell's {len(self.knots)} mesh "
                f"knots (the family's breakpoints and the anchors, each a node with a cell "
                f"between): the fewest nodes that hold them are {self.least_nodes()}") from None

    def least_nodes(self) -> int:
        """The fewest nodes (at least 5) whose mesh holds the knots.

        Each segment between knots needs a cell, but the node density decides how many a
        segment gets, so the least is found by trying (meshes of a few nodes: milliseconds).
        """
        for nodes in range(5, self.nodes + 2 * len(self.knots) + 64):
            try:
                replace(self, nodes=nodes)._graded()
                return nodes
            except MeshTooCoarse:
                continue
        return self.nodes + 1      # (not reached: a cell per segment is enough well before)

    def _graded(self) -> np.ndarray:
        return graded_mesh(self.nodes - 1, 1.0, self.start, self.end, self.width, q=self.q,
                           edge_scale=self.edge_scale, knots=tuple(k.t for k in self.knots),
                           knot_widths=tuple(k.width for k in self.knots),
                           kinks=tuple(k.t for k in self.knots if k.width is None
                                       and (k.source == "breakpoint" or k.also)),
                           min_cell=self.min_cell)


def _octave(x: float) -> float:
    """x rounded to the nearest power of two (in the logarithm)."""
    return 2.0 ** round(math.log2(x))


def knot_for(fraction: float, resolution: int = 2) -> float:
    """A mesh knot near ``fraction`` of the shell, rounded so that solvers can be shared.

    The odds t/(1 − t) are rounded to 1/``resolution`` octaves (half octaves
    by default): knots are dense near the ends, where anchors next to a pole
    or edge must not be stretched far.
    """
    if not 0 < fraction < 1:
        raise ValueError(f"an anchor must lie inside the shell, got the fraction {fraction!r}")
    odds = 2.0 ** (round(resolution * math.log2(fraction / (1 - fraction))) / resolution)
    return odds / (1 + odds)


#: Knots closer than this (units of R) are one node (:func:`_merged`): a lone cell between
#: them of 1e-6 R solved (Ipopt, where Newton failed), of 3e-7 R did not (local_relaxation,
#: 100-1600 nodes).  Merged, a kink sits ε off its node, inside a cell whose Gauss rule does
#: not see it, and the energy and edge values move by about 5 ε² (F0 = 0.35, s0 = 0.2:
#: 4.8e-10 at ε = 1e-5, 2.8e-9 at 2.4e-5, at 100-800 nodes alike), 2e-11 at this bound,
#: below the discretisation error up to 800 nodes.
KNOT_MERGE = 2e-6
#: Breakpoints closer than this (relative to the shell's length) to an end are
#: not given a node: the segment between would be a sliver.
END_MARGIN = 1e-3


def mesh_spec(problem, nodes: int, stages: int, anchors: tuple[float, ...] = ()) -> MeshSpec:
    """The mesh a direct solver uses for ``problem`` (grading rounded to octaves).

    ``anchors`` are material points s that must be nodes (see :class:`MeshSpec`);
    the family's breakpoints inside the shell become nodes too.
    """
    st = problem.structure
    length = problem.end - problem.cut
    nodes = _held_nodes(int(nodes), length)
    width = _octave(boundary_layer_width(problem.h) / length)
    # A free edge near the axis also varies on the scale of its distance from it.
    edges = [v for v in (problem.cut, problem.opening) if v > 0]
    edge = min(edges) / length if edges else None
    # graded_mesh grades for it only below a third of the boundary layer
    edge = _octave(edge) if edge is not None and _octave(edge) < width / 3 else None
    points = []
    for i, s in enumerate(anchors):
        if not problem.cut < s < problem.end:
            raise ValueError(f"anchor s = {s!r} must lie inside the shell "
                             f"({problem.cut:.6g}, {problem.end:.6g})")
        points.append((s, "anchor", i, None))
    for j, (s, w) in enumerate(breakpoints(problem)):
        if END_MARGIN < (s - problem.cut) / length < 1 - END_MARGIN:
            points.append((s, "breakpoint", j, None if w is None else _octave(w / length)))
    points = _merged(sorted(points))
    fractions = [(s - problem.cut) / length for s, *_ in points]
    # (without knots there is nothing to round: the check costs a tenth of a cold solve)
    ts = _knot_places(fractions, points) if points else []
    knots = tuple(Knot(t, src, i, w, also) for t, (_, src, i, w, also) in zip(ts, points))
    # bound the cells between knots only where it binds: a spec of its own per shell length
    # would end the sharing of solvers (a sweep over the cut built every point's)
    close = len(ts) > 1 and np.min(np.diff(ts)) * length < _least_cells(nodes - 1) * MIN_CELL
    return MeshSpec(int(nodes), st.start, st.end, width, edge, pole_exponent(stages), knots,
                    MIN_CELL / length if close else None)


def _merged(points: list[tuple]) -> list[tuple]:
    """The knots of ``points`` (s, source, index, width), sorted by s: an anchor and the
    breakpoints within :data:`KNOT_MERGE` of it (or breakpoints within it of each other)
    are one knot, placed by the anchor (or the first breakpoint), with the others'
    indices in ``also`` and the finest refinement width: (s, source, index, width, also).
    """
    groups: list[list[tuple]] = []
    for point in points:
        group = groups[-1] if groups else []
        if group and point[0] - group[-1][0] < KNOT_MERGE and \
                sum(src == "anchor" for _, src, *_ in (*group, point)) <= 1:
            group.append(point)
        else:
            groups.append([point])
    knots = []
    for group in groups:
        head = next((g for g in group if g[1] == "anchor"), group[0])
        widths = [g[3] for g in group if g[3] is not None]
        knots.append((*head[:3], min(widths) if widths else None,
                      tuple(g[2] for g in group if g is not head)))
    return knots


def _held_nodes(nodes: int, length: float) -> int:
    """``nodes``, or fewer on a shell too short for them: cells of :data:`MIN_CELL` at least.

    A short shell is a narrow annulus: below cells of about 1e-5 R the solvers'
    absolute tolerances exceed what a cell's constraints can resolve, and Ipopt
    stops in its restoration phase (a shell of length 0.0036 R at 400 nodes, of
    0.01 R at 800).  Fewer, larger cells resolve such a shell just as well.
    """
    most = max(MIN_NODES, int(length / MIN_CELL) + 1)
    if nodes > most:
        log.info("a shell of length %.3g R holds at most %d nodes (cells of %.1g R at least): "
                 "solved with %d instead of %d", length, most, MIN_CELL, most, nodes)
        return most
    return nodes


def _knot_places(fractions: list[float], points: list[tuple]) -> list[float]:
    """The knots' places in t for material points at ``fractions`` of the shell (``points``
    as from :func:`_merged`, for the message): the coarsest rounding whose map is monotone
    with a margin (slope at least half the plain one), so that the anchors may still move;
    else the fractions themselves (knots closer than the finest rounding can part: the
    map is the plain one, and the mesh puts cells between them)."""
    probe = np.linspace(0, 1, 2001)
    for resolution in (2, 4, 8, 16, 64, 256):
        ts = [knot_for(f, resolution) for f in fractions]
        if len(set(ts)) == len(ts) and np.all(np.diff(ts) > 0) and \
                np.min(np.diff(shell_points(probe, 0.0, 1.0, tuple(ts), fractions))) > \
                0.5 * (probe[1] - probe[0]):
            return ts
    near = [j for j in range(len(points) - 1) if points[j + 1][0] - points[j][0] < KNOT_MERGE]
    if not near:
        return list(fractions)
    pair = [f"{src} {i} at s = {s!r}" for s, src, i, *_ in points[near[0]:near[0] + 2]]
    raise ValueError(f"mesh knots {pair[0]} and {pair[1]} are closer than {KNOT_MERGE:g} R: "
                     f"two anchors cannot be one node, nor have a cell between them")


def breakpoints(problem) -> list[tuple[float, float | None]]:
    """The family's breakpoints of ``problem`` as numbers: [(s, width or None), ...]."""
    fam = problem.family_obj
    if fam.breakpoints is None:
        return []
    return [(float(s), None if w is None else float(w))
            for s, w in fam.breakpoints(dict(problem.params), problem.cut, problem.end)]


#: Widths either side of a smoothed step within which :func:`step_cells` measures the cells:
#: tanh((s − s_i)/σ) is within 0.25 % of its limits beyond 3σ.
STEP_SPAN = 3.0


def step_cells(problem, nodes: int, stages: int, anchors: tuple[float, ...] = ()
               ) -> tuple[float, float] | None:
    """(the widest cell within :data:`STEP_SPAN` widths of the family's smoothed steps, in
    units of the step's width; that width) on the mesh :func:`mesh_spec` builds, or None
    for a family without them (or a mesh that cannot hold its knots).

    A step narrower than the cells at its node is a jump at a node to the scheme: its
    solutions converge, at the scheme's order, to those of the sharp step, and two such
    meshes agree while both miss the smoothing (audit 22: σ = 0.001 R at 100 and 200
    nodes, z_end 4e-6 apart and 5.3e-4 off).
    """
    steps = [(s, w) for s, w in breakpoints(problem) if w is not None]
    if not steps:
        return None
    spec = mesh_spec(problem, nodes, stages, tuple(anchors))
    try:
        t = spec.nodes_t()
    except MeshTooCoarse:
        return None
    from .parameter_data import knot_positions     # (it imports this module)

    s = shell_points(t, problem.cut, problem.end, tuple(k.t for k in spec.knots), knot_positions(
        problem.structure, tuple((k.source, k.index) for k in spec.knots),
        problem.parameter_vector(), list(anchors)))
    cells, worst = np.diff(s), (0.0, 0.0)
    for at, width in steps:
        near = (s[1:] > at - STEP_SPAN * width) & (s[:-1] < at + STEP_SPAN * width)
        worst = max(worst, (float(np.max(cells[near], initial=0.0)) / width, width))
    return worst
