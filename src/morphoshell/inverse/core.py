"""Inverse estimates from laser-ablation recoils: intrinsic curvature k and E/μ.

Paper, main text "Quantitative estimates of the curvature mismatch during
*Volvox* invagination…" and "Recoil velocity measurements yield a bound on the
elastic modulus…", Fig. 2 J–K; Supplementary, toy problem 2 and "Recoil
velocity: scaling argument".

Each embryo's recoil (opening o, rotation ϱ, displacement d of the cut edge)
is turned into an estimate of its intrinsic curvature k by every method below,
with the shell's own h = H/R and cut Σ = arcsin(hole diameter / 2R).  The
observables are exactly those of :func:`morphoshell.mechanics.ablation.ablate`: the
post-ablation minus the intact (Σ = 0) equilibrium of the same shell at the
material point s = Σ, z in the far-end gauge; ϱ > 0 when the edge unfurls
outwards (k < 1), d ≥ 0 a distance, o the signed change of the hole's
diameter.

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
                   theory at the embryo's h and Σ (:class:`RecoilModel`);
``asymptotic``     the paper's open markers in Fig. 2 J: ``leading_order`` for o
                   (Fig. 2 D) and ``kelvin`` for ϱ and d (Fig. 2 E, F).

Inversion (every method alike, :func:`_invert`): the forward map
m(k) = (o, ϱ, d_±) is evaluated with its exact derivative dm/dk (for the
numerical model by the implicit function theorem,
:func:`morphoshell.mechanics.ablation.recoil_jacobian`'s route) at k = 1 (the
stress-free shell, no recoil) and on a grid of the k-range with spacing at
most :data:`GRID_STEP`, walked outwards from k = 1 so that every solve starts
from a neighbour on the physical branch (tangent predictor).  Between nodes
the map is its cubic Hermite interpolant.  The roots of m(k) = measure in the
range are counted: none gives "outside the range", more than one "not
monotonic", one is refined by a safeguarded Newton iteration (bisection when a
step leaves the bracket) until the estimated error of the last Newton update
s, |m''/(2m')| s² (quadratic convergence), is below :data:`K_TOL` = 1e-9;
that update is applied without a further solve.  d = |d_±| is handled through its
signed version d_± (positive for k < 1), which is smooth through k = 1: a
range containing k = 1 in its interior gives two k for every small d.

The k-range defaults to [−1, 1] (:data:`DEFAULT_K_RANGE`): k = 1 is the
stress-free curvature (no recoil) and every embryo at early invagination
unfurls outwards (ϱ > 0, k < 1); on this side all three maps are monotonic
(for the synthetic table's shells, one sign of the exact derivative at every
sample).  k = −1, an intrinsic curvature reversed relative to the sphere,
bounds what toy problem 2 is asked to explain.  Every Newton iterate checks
the sign of dm/dk against its bracket ("not monotonic" otherwise).

Measurement errors (optional, per row) are propagated to first order with the
exact derivative: σ_k = σ_m / |dm/dk|.

Units: the measurement table (:mod:`morphoshell.io.measurements`) is
dimensional (µm, degrees, µm/s); everything converts once, in its
:func:`~morphoshell.io.measurements.to_dimensionless` and
:func:`~morphoshell.io.measurements.to_physical`, to lengths in units of R and
angles in radians.  E/μ is in 1/s, μ in Pa s, E in Pa, the
bending modulus E H³ in J.
"""
from __future__ import annotations

import json
import logging
import math
import multiprocessing
import os
import time
import weakref
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Iterable, Mapping, Sequence

import numpy as np

from .._runtime.console import progress as _progress_bar
from ..io.measurements import (MEASURES, OPTIONAL_COLUMNS, REQUIRED_COLUMNS, UNITS, Measurement,
                               MeasurementError, read_measurements, to_dimensionless,
                               to_physical)
from ..mechanics import asymptotics
from ..mechanics.ablation import recoil_function, intact_problem
from ..model.problem import Problem
from ..numerics.mesh import mesh_spec
from ..solvers.continuation import continue_to
from ..solvers.direct import DirectSolver
from ..solvers.observables import Observable, state_at
from ..solvers.parametric import parametric
from ..solvers.results import Equilibrium, SolverError
from ..solvers.routes import cache_info, direct_solver

log = logging.getLogger(__name__)

__all__ = [
    "MEASURES", "METHODS", "ASYMPTOTIC", "DEFAULT_K_RANGE", "GRID_STEP", "K_TOL", "NODES",
    "MU_MIN", "REQUIRED_COLUMNS", "OPTIONAL_COLUMNS", "UNITS",
    "MeasurementError", "Measurement", "read_measurements", "to_dimensionless", "to_physical",
    "RecoilModel", "RecoilPoint", "Estimate", "EmbryoEstimate", "Spread", "VelocityFit",
    "InverseResult", "estimate", "estimate_embryo", "summarise", "fit_velocity",
    "velocity_scale", "elastic_bounds",
]

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
#: Mesh nodes of the numerical model (fourth order): over the synthetic table's
#: shells k differs from 800 nodes by at most 4e-5 (measured; 4e-6 with 100
#: nodes, at 1.3 times the cost), thousands of times below the noise.
NODES = 60
#: Default lower bound of the effective viscosity: algal growth medium (Pa s).
MU_MIN = 0.8e-3
#: Default bootstrap resamples and seed.
BOOTSTRAP, SEED = 2000, 0

#: Symbols used in notes and printed tables.
SYMBOL = {"opening": "o", "rotation": "rho", "displacement": "d"}

_MICRON = 1e-6  # m


# --------------------------------------------------------------------------
# the numerical forward model: toy problem 2 with exact d/dk
# --------------------------------------------------------------------------

@dataclass(frozen=True, eq=False)
class RecoilPoint:
    """The recoil of toy problem 2 at one (h, Σ, k), with its derivatives in k.

    ``opening``, ``rotation``, ``displacement`` and the ``radial_displacement``
    and ``axial_displacement`` of the rim are those of
    :func:`morphoshell.mechanics.ablation.ablate` (units of R, radians);
    ``derivative[name]`` is d(name)/dk, exact (implicit function theorem).
    """

    h: float
    cut: float
    k: float
    opening: float
    rotation: float
    displacement: float
    radial_displacement: float
    axial_displacement: float
    derivative: Mapping[str, float]
    pre: Equilibrium
    post: Equilibrium
    _tangents: tuple = field(repr=False, default=())
    _solvers: tuple = field(repr=False, default=())

    def __repr__(self) -> str:
        return (f"RecoilPoint(h={self.h:g}, cut={self.cut:g} rad, k={self.k:g}/R, "
                f"opening={self.opening:.6g} R, rotation={self.rotation:.6g} rad, "
                f"displacement={self.displacement:.6g} R)")

    @property
    def Sigma(self) -> float:
        """Deprecated alias of ``cut`` (the one name of the cut)."""
        return self.cut

    @property
    def signed_displacement(self) -> float:
        """d with the sign of 1 − k: smooth through k = 1, where d = |·| has a kink."""
        return math.copysign(self.displacement, 1 - self.k) if self.k != 1 else 0.0

    @property
    def d_signed_displacement(self) -> float:
        """d(signed_displacement)/dk: ±dd/dk, and −|(dΔr/dk, dΔz/dk)| where d = 0."""
        dr, dz = self.derivative["radial_displacement"], self.derivative["axial_displacement"]
        if self.displacement < 1e-12:
            return -math.hypot(dr, dz)
        return (1.0 if self.k < 1 else -1.0) * self.derivative["displacement"]


_RIM: "weakref.WeakKeyDictionary[DirectSolver, Observable]" = weakref.WeakKeyDictionary()


def _rim(solver: DirectSolver) -> Observable:
    """(r, z, ψ) at the rim's material point s = Σ, far-end gauge, built once per solver.

    The rim is the first node of a cut shell (s = ``cut``, a parameter) and
    the anchor node of the intact one (s = q₀, the anchor's position), so one
    observable serves every Σ the solver is used for.
    """
    if solver not in _RIM:
        d = solver.disc
        if solver.structure.start == "free":
            obs = state_at(d, lambda prm: prm["cut"], 0, gauge="far_end")
        else:
            node = int(np.argmin(np.abs(solver.t - solver.mesh.knots[0].t)))
            obs = state_at(d, lambda prm: d.q[0], min(node, d.layout.cells - 1),
                           gauge="far_end")
        _RIM[solver] = obs
    return _RIM[solver]


class RecoilModel:
    """Toy problem 2 (uniform intrinsic curvature k, sphere, circular cut) as a map k ↦ recoil.

    Parameters
    ----------
    theory : {"large_bending", "classical"}
    nodes, stages : int
        Mesh of both direct solvers (see :class:`morphoshell.solvers.direct.DirectSolver`).
    mesh_for : (h, Σ), optional
        Build one pair of solvers, meshed for this shell, and use it for every
        (h, Σ): they are NLP parameters, and the intact shell's anchor (the
        node at s = Σ) moves with Σ.  For the synthetic table's range (h in
        0.2–0.37, Σ in 0.067–0.17) a mesh of 60 nodes for its median shell
        changes k by at most 4.4e-5 against 800 nodes (6e-6 with 100 nodes;
        measured), no more than the shells' own meshes do.  Without it, each shell gets the solvers
        :func:`morphoshell.mechanics.ablation.ablate` would use
        (:func:`morphoshell.solvers.routes.direct_solver`, meshes quantised in
        h and Σ), so that a table needs a few builds.

    Attributes
    ----------
    builds : int
        The number of direct solvers this model built.
    """

    def __init__(self, theory: str = "large_bending", nodes: int = NODES, stages: int = 2,
                 mesh_for: tuple[float, float] | None = None):
        Problem("uniform", theory=theory)   # validates the theory
        self.theory, self.nodes, self.stages = theory, int(nodes), int(stages)
        self.builds = 0
        self._fixed = None
        if mesh_for is not None:
            post_p = self.problem(mesh_for[0], mesh_for[1], 0.0)
            pre_p = intact_problem(post_p)
            self._fixed = tuple(DirectSolver(p.structure, stages=self.stages,
                                             mesh=mesh_spec(p, self.nodes, self.stages, a))
                                for p, a in ((pre_p, (post_p.cut,)), (post_p, ())))
            self.builds = 2

    def problem(self, h: float, cut: float, k: float) -> Problem:
        """The cut shell (toy problem 2): thickness h = H/R, the cut Σ (radians),
        intrinsic curvature k (units of 1/R)."""
        return Problem("uniform", {"k": float(k)}, h=float(h), cut=float(cut),
                       theory=self.theory, name="toy2")

    def _solvers(self, post_p: Problem, pre_p: Problem) -> tuple[DirectSolver, DirectSolver]:
        if self._fixed is not None:
            try:   # the anchor's map t -> s must stay monotone
                self._fixed[0].disc.check_anchors(pre_p.parameter_vector(), (post_p.cut,))
                return self._fixed
            except ValueError:
                pass
        before = cache_info()["builds"]
        pre_s = direct_solver(pre_p, self.nodes, anchors=(post_p.cut,), stages=self.stages)
        post_s = direct_solver(post_p, self.nodes, stages=self.stages)
        self.builds += cache_info()["builds"] - before
        return pre_s, post_s

    def evaluate(self, h: float, cut: float, k: float,
                 start: RecoilPoint | None = None) -> RecoilPoint:
        """The recoil at (h, Σ = ``cut``, k) and its exact k-derivatives.

        Parameters
        ----------
        start : RecoilPoint, optional
            A solution on the same solvers: the solve starts from its tangent
            predictor x + (dx/dk)(k − k_start); a failing step is split in two
            (recursively), and the last resort is continuation from the
            stress-free k = 1 (:func:`morphoshell.solvers.continuation.continue_to`).
            Without ``start`` the solve is that continuation: the physical
            branch.

        Raises
        ------
        SolverError
            No converged, stable solution.
        """
        post_p = self.problem(h, cut, k)
        pre_p = intact_problem(post_p)
        solvers = self._solvers(post_p, pre_p)
        if start is not None and start._solvers == solvers:
            try:
                return self._step(start, pre_p, post_p, solvers, depth=0)
            except SolverError:
                pass
        eqs = [continue_to(s, p, a) for s, p, a in zip(solvers, (pre_p, post_p), ((cut,), ()))]
        return self._point(post_p, *eqs, solvers)

    def _step(self, start: RecoilPoint, pre_p: Problem, post_p: Problem, solvers,
              depth: int) -> RecoilPoint:
        """From ``start`` by the tangent predictor; a failing step is halved (at most 4 times)."""
        dk = post_p.params["k"] - start.k
        try:
            eqs = [s.solve(p, x0=eq.x + tangent * dk, lam_g0=eq.lam_g, anchors=a)
                   for s, p, a, eq, tangent in zip(solvers, (pre_p, post_p), ((post_p.cut,), ()),
                                                   (start.pre, start.post), start._tangents)]
        except SolverError:
            if depth >= 4:
                raise
            half = post_p.with_updates(k=start.k + dk / 2)
            mid = self._step(start, intact_problem(half), half, solvers, depth + 1)
            return self._step(mid, pre_p, post_p, solvers, depth + 1)
        return self._point(post_p, *eqs, solvers)

    def _point(self, post_p: Problem, pre: Equilibrium, post: Equilibrium,
               solvers) -> RecoilPoint:
        values, jacobians, tangents = [], [], []
        for eq, solver in zip((pre, post), solvers):
            par = parametric(solver)
            y, J = par.jacobian(eq, _rim(solver), ["k"])
            values.append(y)
            jacobians.append(J)
            tangents.append(par.derivative(eq, ["k"]).dx[:, 0])
        y, dy = recoil_function()(*values)
        y = np.asarray(y).ravel()
        dydk = (np.asarray(dy) @ np.vstack(jacobians)).ravel()
        names = ("opening", "rotation", "displacement", "radial_displacement",
                 "axial_displacement")
        return RecoilPoint(post_p.h, post_p.cut, post_p.params["k"],
                           **{n: float(v) for n, v in zip(names, y)},
                           derivative={n: float(v) for n, v in zip(names, dydk)},
                           pre=pre, post=post, _tangents=tuple(tangents), _solvers=solvers)


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


class _Curve:
    """A forward map sampled where it has been evaluated (sorted in k), grown on demand."""

    def __init__(self, evaluate: Callable[[float, _Point | None], _Point]):
        self._evaluate = evaluate
        self.points: list[_Point] = []
        self.evaluations = 0

    def at(self, k: float) -> _Point:
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


@dataclass(frozen=True)
class Estimate:
    """The estimate of k from one measure by one method.

    Attributes
    ----------
    measure, method : str
    k : float or None
        None when no k in the range gives the measure (``status`` says why).
    error : float or None
        First-order propagated measurement error σ_m/|dm/dk| (None without σ_m).
    status : str
        ``ok``, ``missing`` (not measured), ``no_formula`` (Kelvin form of o),
        ``outside_range``, ``not_monotonic`` or ``failed`` (a solver).
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


def _newton_update(curve: _Curve, pt: _Point, i: int, step: float) -> tuple[float, float]:
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


def _invert(curve: _Curve, measure: str, method: str, value: float, error: float | None,
            k_range, fmt: Callable[[float], str]) -> Estimate:
    """k with m(k) = ``value`` in ``k_range`` (see the module docstring)."""
    i = MEASURES.index(measure)
    lo, hi = k_range
    found = []   # (root, target, bracket)
    for target, a, b in _targets(measure, value, k_range):
        pts = [p for p in curve.points if a <= p.k <= b]
        for p, q in zip(pts[:-1], pts[1:]):
            for r in _hermite_roots(p, q, i, target):
                if not any(abs(r - f[0]) < 1e-9 for f in found):
                    found.append((r, target, (p, q)))
    label = f"{SYMBOL[measure]} = {fmt(value)}"
    if not found:
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
    if len(found) > 1:
        ks = ", ".join(f"{r:.3g}" for r, _, _ in sorted(found))
        return Estimate(measure, method, None, status="not_monotonic",
                        note=f"not monotonic: {len(found)} values of k in [{lo:g}, {hi:g}] give "
                             f"{label} (k = {ks}); narrow the k-range")
    k, target, (p, q) = found[0]
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


# --------------------------------------------------------------------------
# one embryo
# --------------------------------------------------------------------------

@dataclass(frozen=True, eq=False)
class EmbryoEstimate:
    """Every estimate of one embryo, and the combined estimate from ϱ and d.

    ``estimates[(measure, method)]`` for every measure and method (``asymptotic``
    included, see :data:`ASYMPTOTIC`); ``combined`` is the numerical ϱ and d
    estimates' inverse-variance weighted mean when both errors are given, else
    their mean (the paper's per-embryo k).
    """

    measurement: Measurement
    estimates: Mapping[tuple[str, str], Estimate]
    combined: Estimate
    seconds: Mapping[str, float] = field(default_factory=dict)

    def __repr__(self) -> str:
        ks = ", ".join(f"k_{SYMBOL[m]}={_fmt_k(self.k(m))}" for m in MEASURES)
        return (f"EmbryoEstimate({self.measurement.embryo!r}, numerical {ks}, "
                f"combined={_fmt_k(self.combined.k)})")

    def k(self, measure: str, method: str = "numerical") -> float | None:
        """The estimate of k (units of 1/R) from ``measure`` by ``method``; None if there is none."""
        return self.estimates[(measure, method)].k

    @property
    def notes(self) -> list[str]:
        """Why estimates are missing (``measure, method: reason``)."""
        out = [f"{m}, {meth}: {e.note}" for (m, meth), e in self.estimates.items()
               if e.note and meth != "asymptotic" and e.note != "method not requested"]
        return out + ([f"combined: {self.combined.note}"] if self.combined.note else [])

    def to_dict(self) -> dict:
        """The JSON object of the embryo (keys ``k_<measure>_<method>`` …, ``notes``)."""
        m = self.measurement
        out: dict = {"embryo": m.embryo, "row": m.row, "h": m.h, "cut_rad": m.cut,
                     "sigma_inner": m.cut / asymptotics.delta(m.h)}
        for (measure, method), e in self.estimates.items():
            out[f"k_{measure}_{method}"] = e.k
            if m.error(measure) is not None:
                out[f"k_{measure}_{method}_error"] = e.error
        out["k_combined"] = self.combined.k
        out["k_combined_error"] = self.combined.error
        out["notes"] = self.notes
        if m.extra:
            out["extra"] = dict(m.extra)
        return out


def _fmt_k(k: float | None) -> str:
    return "null" if k is None else f"{k:+.3f}"


def _combine(estimates: Sequence[Estimate]) -> Estimate:
    ok = [e for e in estimates if e.k is not None]
    if not ok:
        return Estimate("combined", "numerical", None, status="missing",
                        note="no numerical estimate from the rotation or the displacement")
    if all(e.error for e in ok):
        w = np.array([1 / e.error**2 for e in ok])
        k = float(np.dot(w, [e.k for e in ok]) / w.sum())
        return Estimate("combined", "numerical", k, float(1 / math.sqrt(w.sum())))
    return Estimate("combined", "numerical", float(np.mean([e.k for e in ok])))


def estimate_embryo(m: Measurement, model: RecoilModel | None = None,
                    k_range: tuple[float, float] = DEFAULT_K_RANGE,
                    methods: Sequence[str] = METHODS) -> EmbryoEstimate:
    """Estimates of k for one embryo by every method and measure (see :func:`estimate`)."""
    if model is None and "numerical" in methods:
        model = RecoilModel()
    k_range = _check_k_range(k_range)
    h, Sigma = m.h, m.cut
    out: dict[tuple[str, str], Estimate] = {}
    seconds: dict[str, float] = {}
    for method in METHODS:
        t0 = time.perf_counter()
        if method not in methods:
            for measure in MEASURES:
                out[(measure, method)] = Estimate(measure, method, None, status="missing",
                                                  note="method not requested")
            continue
        curve = _Curve(_closed_form(h, Sigma, method) if method in ("leading_order", "kelvin")
                       else _inner_map(h, Sigma) if method == "inner"
                       else _numerical_map(model, h, Sigma))
        failure = None
        for measure in MEASURES:
            value = m.value(measure)
            if value is None:
                out[(measure, method)] = Estimate(measure, method, None, status="missing",
                                                  note=f"no {measure} measured")
                continue
            if method == "kelvin" and measure == "opening":
                out[(measure, method)] = Estimate(
                    measure, method, None, status="no_formula",
                    note="no small-cut closed form for the opening (the equation for u is not integrable "
                         "in closed form; the inner method solves it)")
                continue
            if failure is None:
                try:
                    if not curve.points:
                        curve.sample(k_range)
                    out[(measure, method)] = _invert(curve, measure, method, value,
                                                     m.error(measure), k_range,
                                                     _formatter(measure, m.R_um))
                    continue
                except (RuntimeError, ValueError) as exc:   # SolverError, solve_bvp, a shell
                    failure = exc                             # the k-range makes invalid
            out[(measure, method)] = Estimate(measure, method, None, status="failed",
                                              note=f"solver failed: {failure}")
        seconds[method] = time.perf_counter() - t0
    for measure in MEASURES:
        out[(measure, "asymptotic")] = out[(measure, ASYMPTOTIC[measure])]
    combined = _combine([out[("rotation", "numerical")], out[("displacement", "numerical")]])
    return EmbryoEstimate(m, out, combined, seconds)


def _formatter(measure: str, R_um: float) -> Callable[[float], str]:
    """Values in units of R or radians, printed in the table's unit (µm to 1 nm, 0.01°)."""
    def fmt(v: float) -> str:
        return f"{to_physical(measure, float(v), R_um):.{2 if measure == 'rotation' else 3}f} " \
               f"{UNITS[measure]}"
    return fmt


def _check_k_range(k_range) -> tuple[float, float]:
    try:
        lo, hi = (float(v) for v in k_range)
    except (TypeError, ValueError):
        raise ValueError(f"k_range = {k_range!r} must be two numbers (lo, hi)") from None
    if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
        raise ValueError(f"k_range = ({lo!r}, {hi!r}) must be finite with lo < hi")
    return lo, hi


# --------------------------------------------------------------------------
# summaries over embryos
# --------------------------------------------------------------------------

@dataclass(frozen=True)
class Spread:
    """Mean, standard deviation and bootstrap 95 % interval of the mean over embryos.

    ``weighted_mean`` and ``weighted_error``: inverse-variance weighted mean
    and its standard error, when every value has an error.
    """

    n: int
    mean: float | None
    std: float | None
    interval: tuple[float, float] | None
    weighted_mean: float | None = None
    weighted_error: float | None = None

    def __str__(self) -> str:
        if not self.n:
            return "no estimates"
        iv = f" [{self.interval[0]:.3f}, {self.interval[1]:.3f}]" if self.interval else ""
        std = "" if self.std is None else f" +- {self.std:.3f}"
        return f"{self.mean:.3f}{std}{iv} (n = {self.n})"

    def to_dict(self) -> dict:
        """JSON-ready: n, mean, std and the 95 % interval (units of the estimates)."""
        out = {"n": self.n, "mean": self.mean, "std": self.std,
               "interval_95": None if self.interval is None else list(self.interval)}
        if self.weighted_mean is not None:
            out |= {"weighted_mean": self.weighted_mean, "weighted_error": self.weighted_error}
        return out


def summarise(values: Sequence[float], errors: Sequence[float | None] | None = None,
              bootstrap: int = BOOTSTRAP, rng: np.random.Generator | None = None) -> Spread:
    """:class:`Spread` of ``values`` (std with n − 1; percentile bootstrap of the mean).

    ValueError for a value that is not finite (it would turn every statistic into NaN).
    """
    x = np.asarray(values, dtype=float)
    n = x.size
    if n == 0:
        return Spread(0, None, None, None)
    if not np.all(np.isfinite(x)):        # (a NaN made every statistic NaN, without a word)
        i = int(np.flatnonzero(~np.isfinite(x))[0])
        raise ValueError(f"summarise: value {i} is {float(x[i])!r}, not a finite number")
    interval = None
    if bootstrap and n >= 2:
        rng = rng or np.random.default_rng(SEED)
        means = x[rng.integers(0, n, size=(int(bootstrap), n))].mean(axis=1)
        interval = tuple(float(v) for v in np.percentile(means, [2.5, 97.5]))
    wm = we = None
    if errors is not None and len(errors) == n and all(e for e in errors):
        w = 1 / np.asarray(errors, dtype=float) ** 2
        wm, we = float(np.dot(w, x) / w.sum()), float(1 / math.sqrt(w.sum()))
    return Spread(n, float(x.mean()), float(x.std(ddof=1)) if n >= 2 else None, interval, wm, we)


# --------------------------------------------------------------------------
# recoil velocities: E/μ (Fig. 2 K)
# --------------------------------------------------------------------------

def velocity_scale(H_um, R_um, k):
    """H^{5/2} R^{−3/2} |1 − k| (µm): the recoil velocity per unit E/μ (main text, Fig. 2 K)."""
    return asymptotics.recoil_velocity(1.0, H_um, R_um, k)


def elastic_bounds(E_over_mu: float, mu_min: float = MU_MIN, H_um: float = 11.0) -> dict:
    """E ≥ (E/μ) μ_min (Pa) and the bending modulus E H³ ≥ … (J), H in µm."""
    E = float(E_over_mu) * float(mu_min)
    return {"E_lower_bound_Pa": E, "bending_modulus_lower_bound_J": E * (H_um * _MICRON) ** 3}


@dataclass(frozen=True)
class VelocityFit:
    """Least squares through the origin of V against its scaling X = H^{5/2}R^{−3/2}|1 − k|.

    E/μ = ΣXV/ΣX² (1/s), standard error √(Σr²/(n − 1)/ΣX²), bootstrap 95 %
    interval over embryos; the bounds E ≥ (E/μ) μ_min and E H³ with the mean
    H of the table.
    """

    E_over_mu: float
    standard_error: float | None
    interval: tuple[float, float] | None
    embryos: tuple[str, ...]
    X_um: tuple[float, ...]
    V_um_per_s: tuple[float, ...]
    mu_min_Pa_s: float
    H_mean_um: float
    E_lower_bound_Pa: float
    bending_modulus_lower_bound_J: float
    excluded: tuple[str, ...] = ()

    def __str__(self) -> str:
        se = "" if self.standard_error is None else f" +- {self.standard_error:.3f}"
        return (f"E/mu = {self.E_over_mu:.3f}{se} 1/s ({len(self.embryos)} embryos) => "
                f"E >= {self.E_lower_bound_Pa * 1e3:.3g} mPa (mu >= {self.mu_min_Pa_s * 1e3:g} "
                f"mPa s), E H^3 >= {self.bending_modulus_lower_bound_J:.3g} J "
                f"(H = {self.H_mean_um:.3g} um)")

    def to_dict(self) -> dict:
        """JSON-ready: E/μ (1/s) with its error and interval, the bounds on E (Pa) and E H³ (J)."""
        return {"E_over_mu": self.E_over_mu, "E_over_mu_standard_error": self.standard_error,
                "E_over_mu_interval_95": None if self.interval is None else list(self.interval),
                "E_lower_bound_Pa": self.E_lower_bound_Pa,
                "bending_modulus_lower_bound_J": self.bending_modulus_lower_bound_J,
                "mu_min_Pa_s": self.mu_min_Pa_s, "H_mean_um": self.H_mean_um,
                "embryos": list(self.embryos), "X_um": list(self.X_um),
                "V_um_per_s": list(self.V_um_per_s), "excluded": list(self.excluded)}


def fit_velocity(V: Sequence[float], X: Sequence[float], *, mu_min: float = MU_MIN,
                 H_mean_um: float = 11.0, embryos: Sequence[str] | None = None,
                 bootstrap: int = BOOTSTRAP, rng: np.random.Generator | None = None,
                 excluded: Sequence[str] = ()) -> VelocityFit:
    """Fit V = (E/μ) X through the origin (V in µm/s, X in µm; see :class:`VelocityFit`).

    ValueError for unequal lengths, all-zero X, or a value that is not finite
    (named by its embryo).
    """
    V, X = np.asarray(V, dtype=float), np.asarray(X, dtype=float)
    if V.size == 0 or V.size != X.size or not np.any(X):
        raise ValueError("fit_velocity needs equally many velocities and scales, not all zero")
    for name, values in (("velocity", V), ("velocity scale", X)):
        bad = np.flatnonzero(~np.isfinite(values))
        if len(bad):         # (a NaN gave E/mu = nan, without a word)
            who = embryos[bad[0]] if embryos is not None else int(bad[0])
            raise ValueError(f"fit_velocity: the {name} of embryo {who!r} is "
                             f"{float(values[bad[0]])!r}, not a finite number")
    sxx = float(X @ X)
    slope = float(X @ V / sxx)
    n = V.size
    se = float(math.sqrt(np.sum((V - slope * X) ** 2) / (n - 1) / sxx)) if n >= 2 else None
    interval = None
    if bootstrap and n >= 2:
        rng = rng or np.random.default_rng(SEED)
        idx = rng.integers(0, n, size=(int(bootstrap), n))
        den = np.einsum("ij,ij->i", X[idx], X[idx])
        ok = den > 0
        slopes = np.einsum("ij,ij->i", X[idx], V[idx])[ok] / den[ok]
        interval = tuple(float(v) for v in np.percentile(slopes, [2.5, 97.5]))
    bounds = elastic_bounds(slope, mu_min, H_mean_um)
    return VelocityFit(slope, se, interval, tuple(embryos or [str(i) for i in range(n)]),
                       tuple(map(float, X)), tuple(map(float, V)), float(mu_min),
                       float(H_mean_um), **bounds, excluded=tuple(excluded))


# --------------------------------------------------------------------------
# the whole table
# --------------------------------------------------------------------------

def _column_unit(column: str) -> str:
    """Unit of a column of :meth:`InverseResult.table`."""
    if column.startswith("k_"):
        return "1/R"
    return {"h": "H/R", "cut_rad": "rad", "sigma_inner": "1 (Sigma/delta)"}.get(column, "")


def _keys() -> list[str]:
    return [f"{m}_{meth}" for m in MEASURES for meth in ("asymptotic", *METHODS)] + ["combined"]


@dataclass(frozen=True, eq=False)
class InverseResult:
    """Estimates for a measurement table (:func:`estimate`); ``print`` it for a summary."""

    embryos: tuple[EmbryoEstimate, ...]
    summary: Mapping[str, Spread]
    velocity: VelocityFit | None
    settings: Mapping[str, object]
    timing: Mapping[str, float]

    def __repr__(self) -> str:
        c = self.summary["combined"]
        v = "" if self.velocity is None else f", E_over_mu={self.velocity.E_over_mu:.4g}"
        return (f"InverseResult({len(self.embryos)} embryos, <k> = "
                f"{_fmt_k(c.mean)} (rotation + displacement, numerical){v})")

    def __str__(self) -> str:
        s = self.settings
        lines = [f"{len(self.embryos)} embryos; toy problem 2, {s['theory']} theory, "
                 f"k in [{s['k_range'][0]:g}, {s['k_range'][1]:g}]",
                 "k per embryo, in units of 1/R (numerical; asymptotic in parentheses: "
                 "leading order for o, Kelvin for rho and d):",
                 f"  {'embryo':10s} {'h':>6s} {'cut':>6s} "
                 + " ".join(f"{'k_' + SYMBOL[m]:>16s}" for m in MEASURES) + f" {'k_combined':>11s}"]
        lines.append(f"  {'':10s} {'H/R':>6s} {'rad':>6s}")
        for e in self.embryos:
            cells = [f"{_fmt_k(e.k(m)):>6s} ({_fmt_k(e.k(m, 'asymptotic')):>6s})"
                     for m in MEASURES]
            lines.append(f"  {e.measurement.embryo:10s} {e.measurement.h:6.3f} "
                         f"{e.measurement.cut:6.3f} " + " ".join(cells)
                         + f" {_fmt_k(e.combined.k):>11s}")
        lines.append("summary over embryos (k in units of 1/R): mean +- std [bootstrap 95% "
                     "interval of the mean]:")
        for m in MEASURES:
            for meth in ("numerical", "asymptotic", "inner"):
                lines.append(f"  k from {m:12s} {meth:10s}  {self.summary[f'{m}_{meth}']}")
        c = self.summary["combined"]
        lines.append(f"  <k> from rotation + displacement (numerical): {c}")
        if c.weighted_mean is not None:
            lines.append(f"      inverse-variance weighted: {c.weighted_mean:.4f} +- "
                         f"{c.weighted_error:.4f}")
        if self.velocity is not None:
            lines.append(f"recoil velocities: {self.velocity}")
        notes = [f"  {e.measurement.embryo}: {m}, {meth}: {est.note}" for e in self.embryos
                 for (m, meth), est in e.estimates.items()
                 if meth != "asymptotic" and est.status in ("outside_range", "not_monotonic",
                                                            "failed")]
        if notes:
            lines += ["no estimate (measures that no k in the range produces, or failures):",
                      *notes]
        return "\n".join(lines)

    def to_dict(self) -> dict:
        """The JSON document (see ``morphoshell estimate --help``)."""
        out = {"description": "Inverse estimates of the intrinsic curvature k from laser-"
                              "ablation recoils (toy problem 2) and of E/mu from recoil "
                              "velocities: paper Fig. 2 J-K",
               "units": {"k": "1/R (each embryo's own R)", "h": "H/R", "cut_rad": "rad",
                         "sigma_inner": "Sigma/delta", "E_over_mu": "1/s",
                         "E_lower_bound_Pa": "Pa", "bending_modulus_lower_bound_J": "J"},
               "settings": dict(self.settings),
               "embryos": [e.to_dict() for e in self.embryos],
               "summary": {k: v.to_dict() for k, v in self.summary.items()}}
        if self.velocity is not None:
            out |= {k: v for k, v in self.velocity.to_dict().items()
                    if k in ("E_over_mu", "E_over_mu_standard_error", "E_over_mu_interval_95",
                             "E_lower_bound_Pa", "bending_modulus_lower_bound_J")}
            out["velocity_fit"] = self.velocity.to_dict()
        out["timing_seconds"] = dict(self.timing)
        return out

    def to_dataframe(self):
        """The per-embryo estimates as a table (the columns of :meth:`table`).

        Returns
        -------
        pandas.DataFrame
            One row per embryo: ``embryo``, ``row``, ``h`` (H/R), ``cut_rad``,
            ``sigma_inner`` (Σ/δ), ``k_<measure>_<method>`` [``_error``]
            (units of the embryo's 1/R; NaN where there is no estimate),
            ``k_combined`` [``_error``], ``notes``.  ``df.attrs`` holds
            ``units`` (column → unit), ``settings``, ``summary`` (per
            estimate: n, mean, std, interval) and, with velocities,
            ``E_over_mu`` (1/s).
        """
        import pandas as pd

        df = pd.DataFrame(self.table())
        doc = self.to_dict()
        df.attrs.update(units={c: _column_unit(c) for c in df.columns},
                        settings=doc["settings"], summary=doc["summary"])
        if self.velocity is not None:
            df.attrs["E_over_mu"] = self.velocity.E_over_mu
        return df

    def to_xarray(self):
        """The per-embryo estimates as an xarray Dataset along the coordinate ``embryo``.

        Needs the optional extra ``xarray`` (``pip install 'morphoshell[xarray]'``).
        Variables as the columns of :meth:`to_dataframe`, each with ``units``;
        attributes: the settings (strings and numbers).
        """
        from .._runtime.tables import xarray_module

        xr = xarray_module()
        df = self.to_dataframe()
        ds = xr.Dataset.from_dataframe(df.set_index("embryo"))
        for c in ds.data_vars:
            ds[c].attrs["units"] = _column_unit(str(c))
        ds.attrs.update({k: (v if isinstance(v, (str, int, float)) else json.dumps(v))
                         for k, v in self.settings.items() if v is not None})
        return ds

    def table(self) -> dict[str, list]:
        """Per-embryo columns for CSV (null → NaN, written as an empty cell)."""
        rows = [e.to_dict() for e in self.embryos]
        keys = [k for k in rows[0] if k not in ("notes", "extra")]
        for r in rows[1:]:
            keys += [k for k in r if k not in keys and k not in ("notes", "extra")]
        cols = {k: [math.nan if r.get(k) is None else r.get(k) for r in rows] for k in keys}
        cols["notes"] = ["; ".join(r["notes"]) for r in rows]
        return cols


#: What forked workers of :func:`estimate` inherit.
_WORKER: dict = {}


def _estimate_in_worker(m: Measurement) -> EmbryoEstimate:
    return estimate_embryo(m, _WORKER["model"], _WORKER["k_range"], _WORKER["methods"])


def _check_workers(workers, n: int) -> int:
    """Worker processes: default one per core (at most one per embryo); fork only (POSIX)."""
    if workers is None:
        workers = os.cpu_count() or 1
    if isinstance(workers, bool) or not isinstance(workers, (int, np.integer)) or workers < 1:
        raise ValueError(f"workers = {workers!r} must be a positive integer")
    if "fork" not in multiprocessing.get_all_start_methods():
        return 1
    return int(min(workers, n))


def estimate(measurements: str | Path | Iterable[Measurement], *,
             theory: str = "large_bending", k_range: tuple[float, float] = DEFAULT_K_RANGE,
             mu_min: float = MU_MIN, bootstrap: int = BOOTSTRAP, seed: int = SEED,
             nodes: int = NODES, methods: Sequence[str] = METHODS,
             workers: int | None = None, progress: bool | None = None) -> InverseResult:
    """Estimate k for every embryo and measure, summarise, and fit E/μ.

    Parameters
    ----------
    measurements : path or iterable of Measurement
        A table (:func:`read_measurements`) or measurements.
    theory : {"large_bending", "classical"}
        Shell theory of the numerical model.
    k_range : (float, float)
        Range of k searched (default :data:`DEFAULT_K_RANGE`).
    mu_min : float
        Lower bound of the effective viscosity (Pa s).
    bootstrap : int
        Resamples of the bootstrap intervals (0: none).
    seed : int
        Seed of the bootstrap.
    nodes : int
        Mesh nodes of the numerical model.
    methods : sequence of str
        Subset of :data:`METHODS` to compute (the others are null).
    workers : int, optional
        Processes sharing the embryos (default: one per core; 1: this one).
        The estimates do not depend on it.
    progress : bool, optional
        A progress bar over the embryos on standard error (default: when it
        is a terminal and the ``morphoshell`` logger shows warnings).

    Returns
    -------
    InverseResult
    """
    t0 = time.perf_counter()
    data = read_measurements(measurements) if isinstance(measurements, (str, Path)) \
        else tuple(measurements)
    if not data:
        raise ValueError("no measurements")
    if not all(isinstance(m, Measurement) for m in data):
        raise ValueError("measurements must be Measurement objects or a table's path")
    unknown = sorted(set(methods) - set(METHODS))
    if unknown:
        raise ValueError(f"unknown method(s) {unknown}; valid: {list(METHODS)}")
    k_range = _check_k_range(k_range)
    if not (isinstance(mu_min, (int, float)) and math.isfinite(mu_min) and mu_min > 0):
        raise ValueError(f"mu_min = {mu_min!r} must be a positive number (Pa s)")
    if isinstance(bootstrap, bool) or not isinstance(bootstrap, (int, np.integer)) \
            or bootstrap < 0:
        raise ValueError(f"bootstrap = {bootstrap!r} must be a non-negative integer")
    model = None
    if "numerical" in methods:
        model = RecoilModel(theory, nodes, mesh_for=(float(np.median([m.h for m in data])),
                                                      float(np.median([m.cut for m in data]))))
    workers = _check_workers(workers, len(data))
    log.info("estimating k of %d embryos (methods %s, %d worker%s)", len(data),
             ", ".join(methods), workers, "s" * (workers != 1))
    bar = dict(total=len(data), desc="embryos", unit="embryo", enabled=progress)
    if workers == 1:
        embryos = tuple(estimate_embryo(m, model, k_range, methods)
                        for m in _progress_bar(data, **bar))
    else:
        # Embryos are independent (each starts from k = 1), so the result does not
        # depend on how they are shared.  Forked workers inherit the built solvers.
        _WORKER.update(model=model, k_range=k_range, methods=tuple(methods))
        try:
            with multiprocessing.get_context("fork").Pool(workers) as pool:
                embryos = tuple(_progress_bar(pool.imap(_estimate_in_worker, data, chunksize=1),
                                              **bar))
        finally:
            _WORKER.clear()
    t1 = time.perf_counter()
    keys = _keys()
    summary: dict[str, Spread] = {}
    for j, key in enumerate(keys):
        if key == "combined":
            ests = [e.combined for e in embryos]
        else:
            measure, method = key.split("_", 1)
            ests = [e.estimates[(measure, method)] for e in embryos]
        ok = [e for e in ests if e.k is not None]
        summary[key] = summarise([e.k for e in ok], [e.error for e in ok], bootstrap,
                                 np.random.default_rng([seed, j]))
    velocity = None
    with_v = [e for e in embryos if e.measurement.V_um_per_s is not None]
    fitted = [e for e in with_v if e.combined.k is not None]
    if fitted:
        velocity = fit_velocity(
            [e.measurement.V_um_per_s for e in fitted],
            [velocity_scale(e.measurement.H_um, e.measurement.R_um, e.combined.k) for e in fitted],
            mu_min=mu_min, H_mean_um=float(np.mean([m.H_um for m in data])),
            embryos=[e.measurement.embryo for e in fitted], bootstrap=bootstrap,
            rng=np.random.default_rng([seed, len(keys)]),
            excluded=[e.measurement.embryo for e in with_v if e.combined.k is None])
    per_method = {f"{meth}_seconds": sum(e.seconds.get(meth, 0.0) for e in embryos)
                  for meth in METHODS}
    timing = {"total": time.perf_counter() - t0, "estimates": t1 - t0, **per_method,
              "numerical_solver_builds": 0 if model is None else model.builds,
              "workers": workers}
    settings = {"theory": theory, "k_range": list(k_range), "mu_min_Pa_s": mu_min,
                "bootstrap": bootstrap, "seed": seed, "nodes": nodes, "methods": list(methods),
                "workers": workers,
                "grid_step": GRID_STEP, "k_tol": K_TOL,
                "asymptotic": dict(ASYMPTOTIC)}
    if isinstance(measurements, (str, Path)):
        settings["input"] = str(measurements)
    return InverseResult(embryos, summary, velocity, settings, timing)
