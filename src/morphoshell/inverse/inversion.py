"""One measure of one embryo → its intrinsic curvature k, by each estimation method.

Paper, main text "Quantitative estimates of the curvature mismatch during
*Volvox* invagination…", Fig. 2 J; Supplementary, toy problem 2.  Every method
is a forward map m(k) = (o, ϱ, d_±) with its exact derivative dm/dk, at the
embryo's own h = H/R and cut Σ; inverting it is the same for all.

Estimation methods
------------------
``leading_order``  Σ = O(1): o = h(1 − k) sin Σ, ϱ = √(3h/2)(1 − k),
                   d = (h/2)|1 − k| (Supplementary, toy problem 2, "Cut
                   opening", "Cut rotation and cut displacement");
``kelvin``         Σ = O(δ): the Kelvin-function forms of ϱ and d
                   (Supplementary, "Approximate solution for small ablations");
                   there is none for o;
``inner``          the nonlinear inner problem that the Kelvin forms linearise
                   ("Asymptotic governing equations for small ablations"), with
                   o from its equation for u ("Approximate solution for small ablations")
                   (:func:`morphoshell.mechanics.asymptotics.inner_solution`);
``numerical``      toy problem 2 in the large-bending (or classical) shell
                   theory at the embryo's h and Σ
                   (:class:`morphoshell.inverse.recoil_model.RecoilModel`);
``asymptotic``     the paper's open markers in Fig. 2 J: ``leading_order`` for o
                   (Fig. 2 D) and ``kelvin`` for ϱ and d (Fig. 2 E, F).

Inversion (every method alike, :func:`invert`): the forward map is evaluated
at k = 1 (the stress-free shell, no recoil) and on a grid of the k-range with
spacing at most :data:`GRID_STEP`, walked outwards from k = 1 so that every
solve starts from a neighbour on the physical branch (tangent predictor;
:class:`Curve`).  Between nodes the map is its cubic Hermite interpolant.  The
roots of m(k) = measure in the range are counted: none gives "outside the
range", more than one "not monotonic", one is refined by a safeguarded Newton
iteration (bisection when a step leaves the bracket) until the estimated error
of the last Newton update s, |m''/(2m')| s² (quadratic convergence), is below
:data:`K_TOL` = 1e-9; that update is applied without a further solve.
d = |d_±| is handled through its signed version d_± (positive for k < 1),
which is smooth through k = 1: a range containing k = 1 in its interior gives
two k for every small d.

The k-range defaults to [−1, 1] (:data:`DEFAULT_K_RANGE`): k = 1 is the
stress-free curvature (no recoil) and every embryo at early invagination
unfurls outwards (ϱ > 0, k < 1); on this side all three maps are monotonic
(for the synthetic table's shells, one sign of the exact derivative at every
sample).  k = −1, an intrinsic curvature reversed relative to the sphere,
bounds what toy problem 2 is asked to explain.  Every Newton iterate checks
the sign of dm/dk against its bracket ("not monotonic" otherwise).

The errors of the measures (optional, per row) are propagated to first order
with the exact derivative: σ_k = σ_m / |dm/dk|.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Callable

import numpy as np

from ..io.measurements import MEASURES
from ..mechanics import asymptotics

if TYPE_CHECKING:
    from .recoil_model import RecoilModel

__all__ = ["METHODS", "ASYMPTOTIC", "DEFAULT_K_RANGE", "GRID_STEP", "K_TOL", "MAX_STEPS",
           "K_STRESS_FREE", "SYMBOL", "Estimate", "Curve", "forward_map", "invert",
           "check_k_range"]

#: Estimation methods (see the module docstring); ``asymptotic`` is an alias.
METHODS = ("leading_order", "kelvin", "inner", "numerical")
#: The paper's asymptotic estimate of each measure (open markers of Fig. 2 J).
ASYMPTOTIC = {"opening": "leading_order", "rotation": "kelvin", "displacement": "kelvin"}
#: Default range of k searched (see the module docstring).
DEFAULT_K_RANGE = (-1.0, 1.0)
#: Largest spacing of the grid of k on which the forward map is sampled.
GRID_STEP = 1.0
#: The Newton iteration ends when the estimated error of its last update is below this.
K_TOL = 1e-9
#: Most Newton/bisection steps per estimate.
MAX_STEPS = 40
#: Largest error in k the recoil of the stress-free shell (k = 1: none) may imply,
#: |m(1)/m'(1)|, before a model is said not to resolve the shell (250 times the
#: numerical model's accuracy on the synthetic table; 60 nodes reach 2 at h = 1e-5).
K_STRESS_FREE = 1e-2
#: Symbols used in notes and printed tables.
SYMBOL = {"opening": "o", "rotation": "rho", "displacement": "d"}


# --------------------------------------------------------------------------
# forward maps of every method, as m(k) = (o, ϱ, d_±) with dm/dk
# --------------------------------------------------------------------------

@dataclass(frozen=True, eq=False)
class _Point:
    k: float
    values: np.ndarray       # (o, ϱ, d_±) in units of R, radians
    derivative: np.ndarray   # d/dk of each
    state: object = None     # what the next evaluation starts from


def _closed_form(h: float, Sigma: float, method: str) -> Callable:
    """m(k) = c (1 − k) of the leading-order or Kelvin formulas (c = NaN: no formula)."""
    A = asymptotics
    c = np.array([A.opening(h, 0.0, Sigma), A.rotation(h, 0.0), A.displacement(h, 0.0)]
                 if method == "leading_order" else
                 [math.nan, A.rotation_small_cut(h, 0.0, Sigma),
                  A.displacement_small_cut(h, 0.0, Sigma)])

    def evaluate(k: float, near: _Point | None) -> _Point:
        return _Point(k, c * (1 - k), -c)
    return evaluate


def _inner_map(h: float, Sigma: float) -> Callable:
    def evaluate(k: float, near: _Point | None) -> _Point:
        sol = asymptotics.inner_recoil(h, k, Sigma, guess=None if near is None else near.state)
        r = sol.recoil(h)
        keys = ("opening", "rotation", "signed_displacement")
        return _Point(k, np.array([r[n] for n in keys]), np.array([r[f"d_{n}"] for n in keys]),
                      sol)
    return evaluate


def _numerical_map(model: RecoilModel, h: float, Sigma: float) -> Callable:
    def evaluate(k: float, near: _Point | None) -> _Point:
        p = model.evaluate(h, Sigma, k, None if near is None else near.state)
        return _Point(k, np.array([p.opening, p.rotation, p.signed_displacement]),
                      np.array([p.derivative["opening"], p.derivative["rotation"],
                                p.d_signed_displacement]), p)
    return evaluate


def forward_map(method: str, h: float, Sigma: float,
                model: RecoilModel | None = None) -> Callable:
    """The forward map of ``method`` at the shell (h, Σ), for a :class:`Curve`.

    Parameters
    ----------
    method : str
        One of :data:`METHODS`.
    h, Sigma : float
        Relative thickness H/R and the cut Σ (radians).
    model : RecoilModel, optional
        The numerical model (``method == "numerical"`` only).

    Returns
    -------
    callable
        ``evaluate(k, near)``: the recoil (o, ϱ, d_±), shape (3,), and its
        k-derivative, shape (3,), at ``k``, starting from the sample ``near``.
    """
    if method in ("leading_order", "kelvin"):
        return _closed_form(h, Sigma, method)
    if method == "inner":
        return _inner_map(h, Sigma)
    return _numerical_map(model, h, Sigma)


class Curve:
    """A forward map sampled where it has been evaluated (sorted in k), grown on demand.

    Parameters
    ----------
    evaluate : callable
        The map, as :func:`forward_map` returns it.

    Attributes
    ----------
    points : list
        The samples, sorted in k: each with ``k``, ``values`` and
        ``derivative`` (shape (3,): o, ϱ, d_± and their k-derivatives).
    evaluations : int
        The number of evaluations of the map so far.
    """

    def __init__(self, evaluate: Callable[[float, _Point | None], _Point]):
        self._evaluate = evaluate
        self.points: list[_Point] = []
        self.evaluations = 0

    def at(self, k: float) -> _Point:
        """The sample at ``k``, evaluated from its nearest sample if it is new."""
        for p in self.points:
            if p.k == k:
                return p
        near = min(self.points, key=lambda p: abs(p.k - k)) if self.points else None
        point = self._evaluate(float(k), near)
        self.evaluations += 1
        self.points.append(point)
        self.points.sort(key=lambda p: p.k)
        return point

    def sample(self, k_range: tuple[float, float]) -> None:
        """k = 1 first (the stress-free shell), then the grid outwards from it."""
        lo, hi = k_range
        nodes = {lo, hi}
        edges = sorted({lo, hi} | ({1.0} if lo < 1 < hi else set()))
        for a, b in zip(edges[:-1], edges[1:]):
            n = max(1, math.ceil((b - a) / GRID_STEP - 1e-12))
            nodes |= {a + (b - a) * i / n for i in range(n + 1)}
        for k in [1.0, *sorted(nodes, key=lambda v: (abs(v - 1), v))]:
            self.at(k)


# --------------------------------------------------------------------------
# the inversion
# --------------------------------------------------------------------------

@dataclass(frozen=True)
class Estimate:
    """The estimate of k from one measure by one method.

    Attributes
    ----------
    measure, method : str
    k : float or None
        None when no k in the range gives the measure (``status`` says why).
    error : float or None
        First-order propagated error σ_m/|dm/dk| (None without σ_m).
    status : str
        ``ok``, ``missing`` (no value in the table), ``no_formula`` (Kelvin
        form of o), ``outside_range``, ``not_monotonic`` or ``failed`` (a solver).
    note : str
        Why there is no k, in words and physical units.
    slope : float or None
        dm/dk at k (units of R or radians per unit k).
    side : str or None
        For ``outside_range``: ``"below"`` or ``"above"`` the k-range.
    evaluations : int
        Forward solves this estimate needed beyond the shared grid.
    """

    measure: str
    method: str
    k: float | None
    error: float | None = None
    status: str = "ok"
    note: str = ""
    slope: float | None = None
    side: str | None = None
    evaluations: int = 0


def check_k_range(k_range) -> tuple[float, float]:
    """The k-range as two floats (lo, hi), finite with lo < hi; ValueError otherwise."""
    try:
        lo, hi = (float(v) for v in k_range)
    except (TypeError, ValueError):
        raise ValueError(f"k_range = {k_range!r} must be two numbers (lo, hi)") from None
    if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
        raise ValueError(f"k_range = ({lo!r}, {hi!r}) must be finite with lo < hi")
    return lo, hi


def _hermite_roots(p: _Point, q: _Point, i: int, target: float) -> list[float]:
    """Roots in [p.k, q.k] of the cubic Hermite interpolant of measure i, minus ``target``."""
    dk = q.k - p.k
    fa, fb = p.values[i] - target, q.values[i] - target
    ga, gb = dk * p.derivative[i], dk * q.derivative[i]
    coefficients = [2 * fa + ga - 2 * fb + gb, -3 * fa - 2 * ga + 3 * fb - gb, ga, fa]
    if not np.any(coefficients):
        return [p.k]
    t = [r.real for r in np.roots(coefficients)
         if abs(r.imag) <= 1e-9 and -1e-12 <= r.real <= 1 + 1e-12]
    return [p.k + dk * min(max(v, 0.0), 1.0) for v in t]


def _newton_update(curve: Curve, pt: _Point, i: int, step: float) -> tuple[float, float]:
    """(estimated error |m''/(2m')| s², slope m' at k + s) of the Newton update from ``pt``.

    m'' is the difference quotient of the exact derivatives at ``pt`` and its
    nearest other sample; the error is trusted only for |s| ≤ 1e-2 (else inf).
    """
    q = min((p for p in curve.points if p is not pt), key=lambda p: abs(p.k - pt.k))
    curvature = (pt.derivative[i] - q.derivative[i]) / (pt.k - q.k)
    error = abs(curvature / (2 * pt.derivative[i])) * step**2 if abs(step) <= 1e-2 else math.inf
    return error, pt.derivative[i] + curvature * step


def _targets(measure: str, value: float, k_range) -> list[tuple[float, float, float]]:
    """(target of m(k), lo, hi): d = |d_±| is d_± = +d for k ≤ 1 and −d for k ≥ 1."""
    lo, hi = k_range
    if measure != "displacement":
        return [(value, lo, hi)]
    out = [(value, lo, min(hi, 1.0))] if lo < 1 else []
    return out + ([(-value, max(lo, 1.0), hi)] if hi > 1 else [])


def _roots(curve: Curve, i: int, measure: str, value: float, k_range) -> list[tuple]:
    """(root, target, bracket (p, q)) of every distinct root of the interpolated map."""
    found = []
    for target, a, b in _targets(measure, value, k_range):
        pts = [p for p in curve.points if a <= p.k <= b]
        for p, q in zip(pts[:-1], pts[1:]):
            for r in _hermite_roots(p, q, i, target):
                if not any(abs(r - f[0]) < 1e-9 for f in found):
                    found.append((r, target, (p, q)))
    return found


def _outside_range(curve: Curve, i: int, measure: str, method: str, value: float, k_range,
                   label: str, fmt: Callable[[float], str]) -> Estimate:
    """No root: the values the range gives, and on which side of it k would lie."""
    lo, hi = k_range
    inside = [p for p in curve.points if lo <= p.k <= hi]
    vals = np.array([abs(p.values[i]) if measure == "displacement" else p.values[i]
                     for p in inside])
    extreme = inside[int(np.argmax(vals) if value > vals.max() else np.argmin(vals))]
    side = "below" if extreme.k == lo else "above" if extreme.k == hi else None
    where = {"below": f" (it needs k < {lo:g})", "above": f" (it needs k > {hi:g})",
             None: ""}[side]
    return Estimate(measure, method, None, status="outside_range", side=side,
                    note=f"outside the range: {label}, but k in [{lo:g}, {hi:g}] gives "
                         f"{fmt(vals.min())} to {fmt(vals.max())}{where}")


def _several_roots(found: list[tuple], measure: str, method: str, k_range,
                   label: str) -> Estimate:
    """More than one root: the values of k, and the advice to narrow the range."""
    lo, hi = k_range
    ks = ", ".join(f"{r:.3g}" for r, _, _ in sorted(found))
    return Estimate(measure, method, None, status="not_monotonic",
                    note=f"not monotonic: {len(found)} values of k in [{lo:g}, {hi:g}] give "
                         f"{label} (k = {ks}); narrow the k-range")


def _refine(curve: Curve, i: int, measure: str, method: str, root: tuple,
            error: float | None, k_range) -> Estimate:
    """The one root, by safeguarded Newton from its interpolated value (module docstring)."""
    lo, hi = k_range
    k, target, (p, q) = root
    a, b, fa = p.k, q.k, p.values[i] - target
    sign = np.sign(q.values[i] - p.values[i])
    before = curve.evaluations
    for _ in range(MAX_STEPS):
        pt = curve.at(k)
        r, g = pt.values[i] - target, pt.derivative[i]
        if np.sign(g) != sign:
            return Estimate(measure, method, None, status="not_monotonic",
                            evaluations=curve.evaluations - before,
                            note=f"not monotonic: d{SYMBOL[measure]}/dk = {g:.3g} at k = {k:.4g}"
                                 f" has the wrong sign; narrow the k-range")
        if r == 0:
            step = 0.0
        else:
            if np.sign(r) == np.sign(fa):
                a, fa = k, r
            else:
                b = k
            step = -r / g
        new = k + step
        accuracy, slope = _newton_update(curve, pt, i, step) if step else (0.0, g)
        # a root at a sample may sit a round-off outside the bracket found for it
        if accuracy <= K_TOL and lo - 1e-9 <= new <= hi + 1e-9:
            return Estimate(measure, method, float(min(max(new, lo), hi)),
                            None if error is None else float(error / abs(slope)),
                            slope=float(slope), evaluations=curve.evaluations - before)
        k = new if a < new < b else 0.5 * (a + b)
    return Estimate(measure, method, None, status="failed", evaluations=curve.evaluations - before,
                    note=f"no convergence in {MAX_STEPS} Newton steps (last k = {k:.6g})")


def _unresolved(curve: Curve, i: int, measure: str, method: str,
                fmt: Callable[[float], str]) -> Estimate | None:
    """A failed estimate when the model's stress-free shell recoils (else None).

    At k = 1 the shell is stress-free and a cut releases nothing: m(1) = 0.  A
    model off by more than :data:`K_STRESS_FREE` in k there does not resolve
    the shell (a mesh too coarse for its boundary layer, width ~0.54√h), and
    every k it gives would carry that error.
    """
    p = next((p for p in curve.points if p.k == 1.0), None)
    if p is None or p.derivative[i] == 0:
        return None
    offset = abs(p.values[i] / p.derivative[i])
    if not offset > K_STRESS_FREE:
        return None
    return Estimate(measure, method, None, status="failed",
                    note=f"the {method} model does not resolve this shell: at the stress-free "
                         f"k = 1 it gives {SYMBOL[measure]} = {fmt(p.values[i])} instead of 0, "
                         f"an error of {offset:.2g} in k (a finer mesh: --nodes)")


def invert(curve: Curve, measure: str, method: str, value: float, error: float | None,
           k_range: tuple[float, float], fmt: Callable[[float], str]) -> Estimate:
    """k with m(k) = ``value`` in ``k_range`` (see the module docstring).

    Parameters
    ----------
    curve : Curve
        The method's forward map, sampled on the grid of ``k_range``
        (:meth:`Curve.sample`); the Newton iteration adds samples.
    measure : {"opening", "rotation", "displacement"}
    method : str
        Recorded in the estimate.
    value, error : float
        The measure and its error (None: none given), in units of R or radians.
    k_range : (float, float)
        The range searched.
    fmt : callable
        Prints a value of the measure in the table's unit, for the notes.

    Returns
    -------
    Estimate
        ``ok`` with k, its propagated error and the slope dm/dk; or no k with
        ``outside_range``, ``not_monotonic`` or ``failed`` and a note (``failed``
        also when the model's stress-free shell recoils by more than
        :data:`K_STRESS_FREE` in k: it does not resolve the shell).
    """
    i = MEASURES.index(measure)
    unresolved = _unresolved(curve, i, measure, method, fmt)
    if unresolved is not None:
        return unresolved
    found = _roots(curve, i, measure, value, k_range)
    label = f"{SYMBOL[measure]} = {fmt(value)}"
    if not found:
        return _outside_range(curve, i, measure, method, value, k_range, label, fmt)
    if len(found) > 1:
        return _several_roots(found, measure, method, k_range, label)
    return _refine(curve, i, measure, method, found[0], error, k_range)
