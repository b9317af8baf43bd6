"""Fits of the morphoelastic model to traced midlines: a bilevel problem, three ways.

The paper (Supplementary, "Fitting of the morphoelastic theory to the average
cell sheet midlines of Volvox inversion") fits the 13-parameter Volvox model
(documentation: "Problems and families") to the average midline of an inversion stage by
minimising the fit energy

    E_fit = { Σᵢ [(rᵢ − Rᵢ)² + (zᵢ − Zᵢ)²] }^½,   i = 1 … N_fit = 100,

over points equally spaced in arclength along the data (Rᵢ, Zᵢ) and along the
model's midline (rᵢ, zᵢ), posterior pole at the origin, axis along z.  The
model midline is an *equilibrium*: the outer least-squares problem has the
inner energy minimisation as a constraint.  Three methods, one interface:

``nelder-mead``  the paper's baseline: ``fminsearch``-like adaptive Nelder–Mead
                 (scipy, Gao & Han coefficients) around warm-started inner solves;
``gradient``     bounded least squares (``scipy.optimize.least_squares``, trust
                 region) with the exact Jacobian of the residuals through the
                 parametric inner solve (implicit function theorem,
                 :mod:`morphoshell.solvers.parametric`);
``kkt``          one NLP in (parameters, shape, multipliers): minimise ½E_fit²
                 subject to the inner KKT conditions F(x, λ; p) = 0
                 (:attr:`Parametric.kkt_residual`), parameter bounds, the
                 ordering of the breakpoints and |η| < 1 as constraints.  The
                 KKT conditions hold at saddles too: the fitted state is then
                 checked to be a minimum of the inner energy (the inertia of
                 its KKT matrix) and rejected otherwise.

The Gauss–Newton covariance of the fitted parameters comes from the exact
Jacobian: σ² (JᵀJ)⁻¹ with σ² = E_fit²/(2N − n).  The residuals of a traced
midline are correlated along it (one tracing, one smooth curve), so these
standard errors are *lower bounds*.  Small singular values of the Jacobian
scaled by the parameters' magnitudes flag poorly identified directions.
A fitted state near a **fold** of the inner equilibrium branch shows as one
singular value that dwarfs all others (the inner Hessian is nearly singular,
so ∂x/∂p ~ 1/λ_min blows up along one direction): a least-squares fit can
creep onto a fold, where a tiny E_fit gain buys a large change of shape and the
standard errors collapse.  Such a fit is reported as not converged
(:data:`FOLD_RATIO`).

Variants of the Volvox fit (the paper's four hypotheses on the posterior
intrinsic curvature κ₁): ``flat`` κ₁ = 0, ``undeformed`` κ₁ = 1,
``unstressed`` κ₁ = 1/f₁ (the contracted posterior is stress-free; a relation
between parameters, not a value), ``free`` κ₁ fitted.  σ, h and P are never
fitted; any other parameter can be held (``hold``).

Lengths in units of R; E_fit in units of R.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field, replace
from functools import lru_cache
from typing import Callable, Mapping, Sequence

import casadi as ca
import numpy as np

from .._runtime.compiled import LARGE, compiled_point_function
from .._runtime.validate import real
from ..model.problem import Problem
from ..numerics.ipopt import load_ipopt
from ..numerics.mesh import mesh_spec
from ..solvers.continuation import continue_between, continue_to
from ..solvers.direct import DirectSolver
from ..solvers.observables import midline, midline_cells
from ..solvers.parametric import parametric
from ..solvers.refinement import solve_from
from ..solvers.results import Equilibrium, SolverError

__all__ = ["FitSpec", "FitResult", "FitError", "fit", "volvox_spec", "breakpoint_bounds",
           "model_midline", "synthetic_midline", "intrinsic_lengths", "check_midline",
           "METHODS", "VARIANTS", "N_FIT", "FIT_NODES", "BOUNDS", "LENGTH_SLACK", "MAX_TURN",
           "TURN_LENGTH", "POLE_SLACK"]

#: Fit methods (see the module docstring).
METHODS = ("nelder-mead", "gradient", "kkt")
#: Hypotheses on the posterior intrinsic curvature κ₁ (see the module docstring).
VARIANTS = ("flat", "undeformed", "unstressed", "free")
#: Points of the fit energy (documentation: "Problems and families", Volvox).
N_FIT = 100
#: Mesh nodes a fit accepts (the command line's --nodes too): fewer cells cannot hold the
#: Volvox model's breakpoints and steps.
FIT_NODES = (20, 3200)
#: Bounds of fitted Volvox parameters: stretches, curvatures (1/R).  Breakpoints
#: are bounded by the shell and kept apart by at least the smoothing width σ.
BOUNDS = {"f": (0.5, 2.0), "kappa": (-15.0, 15.0)}
#: A data midline whose length lies further than this factor outside the Volvox model's
#: intrinsic lengths (:func:`intrinsic_lengths`) is refused before a fit: its units or scale
#: are wrong (a factor 2 means elastic strains of 100 %, far beyond the theory's).  Measured:
#: a 0.36 R midline "converged" to E_fit 8.9 R, the model's midline nowhere near it.
LENGTH_SLACK = 2.0
#: A data midline that turns by more than MAX_TURN (radians) within TURN_LENGTH (units of R)
#: of its arclength is refused before a fit: a line that retraces its way (measured: a trace
#: out to the rim and back "converged" to E_fit 4.3 R).  That is a mean radius of curvature
#: below 0.042 R, a fraction of the cell sheet's thickness (h = 0.15 R in the paper's fits);
#: the shipped synthetic midlines turn by at most 0.73 rad within 0.1 R.  Caught: hairpins
#: with out and back up to 0.05 R apart (measured).
MAX_TURN, TURN_LENGTH = 0.75 * np.pi, 0.1
#: A data midline of an intact shell (no cut) starts at the posterior pole, the origin of the
#: model gauge, within this distance (units of R) or is refused before a fit: one listed rim
#: first "converged" to E_fit 9.8 R (measured).  Image traces are aligned with their pole
#: there exactly; a CSV of r, z is taken as it is.
POLE_SLACK = 0.1
PRINT_LEVEL = 0
#: The KKT fit lets a fit point move this many cells either way within one NLP.
WINDOW = 2
#: A solved state this near (max over θ of |Δθ|/bound width) is warm-started from;
#: farther, the inner solve continues from it (one branch of equilibria).
NEAR = 0.02
#: Inner states kept as starting points.
ARCHIVE = 64
#: The gradient fit stops (not converged, at its best point) after this many
#: consecutive trial points whose inner solve failed (each is one failed warm
#: solve: the trust region has shrunk 4⁸-fold by then).
MAX_FAILED_TRIALS = 8
#: Largest gradient, relative to the residual's norm, at which the gradient method's end is
#: a stationary point (first-order optimality over ‖r‖, scaled variables; see ``_gradient``).
STATIONARY = 1e-2
#: Residual norm (units of R) below which a fit is exact and its gradient is measured against
#: this instead (noiseless data: E_fit ~ 1e-14 R).
RESIDUAL_FLOOR = 1e-8
#: Nelder–Mead runs at most this many simplices (restarts around the best point).
NM_RESTARTS = 8
#: Overlap (in cell widths) over which the KKT fit blends neighbouring cells.
BLEND = 0.05
#: Mesh of the KKT fit's first, coarse stage (see ``_kkt``): 40 nodes against 60 took the
#: bench_fit fit with noise 1.23 s instead of 1.59 s (medians of 5 interleaved, 2026-11-24),
#: 1.1-2.8 s instead of 1.5-2.9 s on seeds 2-7, noiseless alike (1.61 and 1.57 s); 30: slower.
COARSE_NODES = 40
#: Ipopt iterations of each of the KKT fit's NLPs (converging ones took 5-60,
#: measured; a failing one costs about 0.1 s an iteration at 200 nodes).
KKT_ITERATIONS = 60
#: Largest Hessian perturbation (inertia correction) of the KKT fit's NLPs.
KKT_MAX_PERTURBATION = 1e6
#: Tolerance (relative on E_fit²) and evaluations of the Gauss-Newton steps that
#: start a KKT fit from a given state (``_kkt``).
KKT_GN_TOL = 1e-4
KKT_GN_ITERATIONS = 30
#: Tolerance (relative on E_fit²) of the Gauss-Newton steps between the KKT fit's coarse and
#: fine NLPs (``_kkt_from_coarse``).
KKT_FINE_GN_TOL = 1e-6
#: Ipopt tolerance of the KKT fit's coarse NLP (at most; ``_kkt_from_coarse``): its optimum
#: only starts the fine mesh's Gauss-Newton steps to KKT_FINE_GN_TOL.  At 1e-6 it spent 2-5
#: iterations more on bench_fit's seeds, and on seed 2 went on past its optimum to another
#: one it did not reach (60 iterations, then route B: 108 in all against 37), measured.
KKT_COARSE_TOL = 1e-5
#: |η| stays below this in the KKT fit (the theory needs |η| < 1).
ETA_MAX = 0.98
#: A fit whose scaled Jacobian has its second singular value below this fraction of the
#: first sits near a fold of the inner branch (module docstring) and is not converged.
#: Measured on the synthetic inversion fits (2026-11-23): 0.02-0.3 on the branch, 5e-7
#: on a fold that a free fit of t07 crept onto, its largest singular value 5e4x larger.
FOLD_RATIO = 1e-4
#: A fitted breakpoint within this fraction of its box's width from an edge rests on it
#: (:meth:`FitSpec.on_box_edges`).
EDGE_RTOL = 1e-4
#: :func:`fit` moves the breakpoints' boxes at most this many times.  Each move lets a
#: breakpoint go PUSH_SHARE of the way to its neighbour or halfway.
MAX_RECENTRES = 12
#: The share of the room between two breakpoints that a moved box gives the one that pushed
#: against its edge, when the other did not (:meth:`FitSpec.recentred`).
PUSH_SHARE = 0.75


class FitError(SolverError):
    """A fit that did not deliver (status names why; the last state is attached)."""


# --------------------------------------------------------------------------
# what is fitted
# --------------------------------------------------------------------------

@dataclass(frozen=True)
class FitSpec:
    """The fitted parameters of a problem and how the others follow.

    Attributes
    ----------
    base : Problem
        Everything not fitted (h, Σ, P, theory, held parameters) and the start
        values of the fitted ones.
    fitted : tuple of str
        Family parameters varied by the fit, in the order of θ.
    tied : mapping
        Parameters given by a function of the others,
        ``{name: (function, derivative)}`` with ``function(params) -> value`` and
        ``derivative(params) -> {other: d value/d other}`` (the ``unstressed``
        variant: κ₁ = 1/f₁).
    bounds : mapping
        (low, high) for every fitted parameter.
    variant : str
        A label (the Volvox hypothesis, or ``"custom"``).
    ordered : tuple of str
        Breakpoints, in order along the shell, that the bounds keep ordered
        and at least σ apart (:func:`breakpoint_bounds`): boxes around their
        start values, which :func:`fit` moves when a fit ends on one of
        their edges.
    """

    base: Problem
    fitted: tuple[str, ...]
    tied: Mapping[str, tuple[Callable, Callable]] = field(default_factory=dict)
    bounds: Mapping[str, tuple[float, float]] = field(default_factory=dict)
    variant: str = "custom"
    ordered: tuple[str, ...] = ()

    def __post_init__(self):
        unknown = [n for n in self.fitted if n not in self.base.params]
        if unknown:
            raise ValueError(f"cannot fit {unknown}: not parameters of family "
                             f"{self.base.family!r} ({list(self.base.params)})")
        for n in self.fitted:
            lo, hi = self.bounds.get(n, (-np.inf, np.inf))
            # (on an edge is inside: a fit that ended there starts the next one)
            if not lo <= self.base.params[n] <= hi:
                raise ValueError(f"the start {n} = {self.base.params[n]!r} lies outside its "
                                 f"bounds ({lo:g}, {hi:g})")

    @property
    def theta0(self) -> np.ndarray:
        """Starting values of the fitted parameters (from the base problem), in ``fitted`` order."""
        return np.array([self.base.params[n] for n in self.fitted])

    def params(self, theta) -> dict:
        """All family parameters at θ (numbers or CasADi expressions)."""
        out = dict(self.base.params)
        out.update(zip(self.fitted, [theta[i] for i in range(len(self.fitted))]))
        for name, (function, _) in self.tied.items():
            out[name] = function(out)
        return out

    def problem(self, theta) -> Problem:
        """The problem at θ (validated: a ValueError names an infeasible value)."""
        return self.base.with_updates(**{k: float(v) for k, v in self.params(theta).items()})

    def chain(self, theta, names: Sequence[str]) -> np.ndarray:
        """d(params ``names``)/dθ, with the tied parameters' dependence."""
        values = self.params(theta)
        out = np.zeros((len(names), len(self.fitted)))
        for i, n in enumerate(names):
            if n in self.fitted:
                out[i, self.fitted.index(n)] = 1.0
            elif n in self.tied:
                for other, d in self.tied[n][1](values).items():
                    if other in self.fitted:
                        out[i, self.fitted.index(other)] += d
        return out

    def box(self) -> tuple[np.ndarray, np.ndarray]:
        """Lower and upper bounds of the fitted parameters (±inf where unbounded)."""
        lo = np.array([self.bounds.get(n, (-np.inf, np.inf))[0] for n in self.fitted])
        hi = np.array([self.bounds.get(n, (-np.inf, np.inf))[1] for n in self.fitted])
        return lo, hi

    def _pushing(self, theta) -> tuple[list, list, list, float]:
        """Which ordered breakpoints push against the lower (upper) edge of their box at θ.

        A fitted breakpoint pushes when it rests on an edge (within
        :data:`EDGE_RTOL` of the box's width) where the fit has no constraint: its neighbour
        (or the pole, or the shell's end) lies more than σ beyond it.
        Returns (values, down, up, σ).
        """
        values = self.params(theta)
        s, sigma = [float(values[n]) for n in self.ordered], float(values["sigma"])
        near, far = [0.0, *s], [*s[1:], self.base.end]      # each one's neighbours
        down, up = [False] * len(s), [False] * len(s)
        for i, n in enumerate(self.ordered):
            if n in self.fitted:
                lo, hi = self.bounds[n]
                tol = EDGE_RTOL * (hi - lo)
                down[i] = s[i] - lo <= tol and lo > near[i] + sigma + tol
                up[i] = hi - s[i] <= tol and hi < far[i] - sigma - tol
        return s, down, up, sigma

    def on_box_edges(self, theta) -> list[str]:
        """The fitted breakpoints that rest on an edge of their box at θ where the fit has no
        constraint (another breakpoint more than σ away, the pole or the shell's end farther
        than σ): their optimum may lie beyond it (:data:`EDGE_RTOL`)."""
        if not self.ordered:
            return []
        _, down, up, _ = self._pushing(theta)
        return [n for n, d, u in zip(self.ordered, down, up) if d or u]

    def on_constraints(self, theta) -> list[tuple[str, tuple[str, ...]]]:
        """The hard constraints that hold at θ: (description, the fitted parameters in it).

        Ordered breakpoints σ apart, the first σ from the pole, the last σ
        from the shell's end (the ordering that :func:`breakpoint_bounds`
        keeps, within :data:`EDGE_RTOL` of the shell's length), and fitted
        parameters on their bounds (:data:`BOUNDS`, within EDGE_RTOL of their
        width; not the breakpoints' movable boxes).  An optimum there is a
        constrained one: the Gauss–Newton errors of a free optimum do not
        describe it, and refits of resampled data pin to the same constraint
        (measured: replicate t02 data sets whose fits ended with s₃ − s₂ = σ
        had jackknife errors of s₂ of 0.001–0.002 against misses of 0.018).
        """
        values = self.params(theta)
        out = []
        if self.ordered:
            s, sigma = [float(values[n]) for n in self.ordered], float(values["sigma"])
            tol = EDGE_RTOL * self.base.end
            names = list(self.ordered)
            if s[0] - sigma <= tol and names[0] in self.fitted:
                out.append((f"{names[0]} = sigma (from the pole)", (names[0],)))
            for a, b, sa, sb in zip(names, names[1:], s, s[1:]):
                both = tuple(n for n in (a, b) if n in self.fitted)
                if sb - sa - sigma <= tol and both:
                    out.append((f"{b} - {a} = sigma", both))
            if self.base.end - sigma - s[-1] <= tol and names[-1] in self.fitted:
                out.append((f"{names[-1]} = L - P - sigma (the shell's end)", (names[-1],)))
        for n in self.fitted:
            if n in self.ordered or n not in self.bounds:
                continue
            lo, hi = self.bounds[n]
            tol = EDGE_RTOL * (hi - lo)
            v = float(values[n])
            if v - lo <= tol or hi - v <= tol:
                out.append((f"{n} = {lo if v - lo <= tol else hi:g} (its bound)", (n,)))
        return out

    def recentred(self, theta) -> "FitSpec":
        """This spec started at θ, with the ordered breakpoints' boxes around their values there.

        The boxes of :func:`breakpoint_bounds`; between a breakpoint that
        pushes against its box's edge and a neighbour that does not, the
        pusher gets :data:`PUSH_SHARE` of the room between them.  (Halves: a
        breakpoint with far to go took 10 moves, measured; all of it, pinning
        the neighbour: neighbours that both had to move took turns, 12 moves
        and not there, flat t08 of the synthetic campaign.)
        """
        s, down, up, sigma = self._pushing(theta)
        share = [PUSH_SHARE if up[i] and not down[i + 1] else
                 1 - PUSH_SHARE if down[i + 1] and not up[i] else 0.5 for i in range(len(s) - 1)]
        boxes = breakpoint_bounds(s, sigma, self.base.end, share)
        return replace(self, base=self.problem(theta),
                       bounds={**self.bounds, **{n: b for n, b in zip(self.ordered, boxes)
                                                 if n in self.fitted}})


def breakpoint_bounds(s: Sequence[float], sigma: float, end: float,
                      share: Sequence[float] | None = None) -> list[tuple[float, float]]:
    """Disjoint boxes around ordered breakpoints 0 < s₁ < … < s_m < ``end`` that keep them σ apart.

    Of the room between neighbours s_i and s_{i+1} (their gap less σ), s_i's
    box takes the fraction ``share[i]`` (default ½: each box stops σ/2 short
    of the midpoint) and s_{i+1}'s the rest; the first and last boxes reach
    to σ from the pole and the shell's end.  So any point of the boxes keeps
    the breakpoints at least σ apart (the fit's constraint; the ``kkt``
    method's ordering constraints say the same).  A pair already closer than
    σ is pinned at its gap (it can only widen).  Least-squares methods take
    bounds, not the ordering itself: these boxes order the breakpoints for
    them, and :func:`fit` moves them when a fit ends on an edge
    (:meth:`FitSpec.on_box_edges`).
    """
    s = list(s)
    share = [0.5] * (len(s) - 1) if share is None else list(share)
    # the boundaries of the room between neighbours: s_i's box ends at a, s_{i+1}'s begins at b
    room = [max(b - a - sigma, 0.0) for a, b in zip(s, s[1:])]
    below = [sigma] + [a + w * r + sigma for a, w, r in zip(s, share, room)]
    above = [a + w * r for a, w, r in zip(s, share, room)] + [end - sigma]
    return [(min(lo, b), max(hi, b)) for lo, b, hi in zip(below, s, above)]   # (b when pinned)


def volvox_spec(variant: str, start: Problem | None = None, hold: Mapping[str, float] = (),
                breakpoint_boxes: bool = True) -> FitSpec:
    """The fit of the Volvox model for one of :data:`VARIANTS`.

    Parameters
    ----------
    variant : {"flat", "undeformed", "unstressed", "free"}
    start : Problem, optional
        A ``volvox`` problem with the start values (default: the family's
        illustrative defaults, h = 0.15, P = 0.3: "Problems and families").
    hold : mapping
        Parameters held at the given values (not fitted).
    breakpoint_boxes : bool
        Bound each breakpoint to a disjoint interval around its start
        (:func:`breakpoint_bounds`), so that methods without constraints keep
        them ordered; :func:`fit` moves the intervals when a fit ends on one
        of their edges.  Without them each breakpoint lies within σ of the
        shell only: the ``kkt`` method imposes the ordering as constraints
        and does not need them.
    """
    if variant not in VARIANTS:
        raise ValueError(f"variant = {variant!r} must be one of {list(VARIANTS)}")
    start = start or Problem("volvox", h=0.15, opening=0.3)
    if start.family != "volvox":
        raise ValueError(f"the Volvox fit needs a 'volvox' problem, got {start.family!r}")
    hold = dict(hold)
    tied: dict = {}
    fixed = {"flat": 0.0, "undeformed": 1.0}.get(variant)
    if fixed is not None:
        # a fit labelled flat with kappa1 = 0.5 would be silently another hypothesis
        if hold.setdefault("kappa1", fixed) != fixed:
            raise ValueError(f"the {variant} variant holds kappa1 = {fixed:g}, not "
                             f"{hold['kappa1']:g}: hold kappa1 in the free variant instead")
    elif variant == "unstressed":
        if "kappa1" in hold:
            raise ValueError("the unstressed variant ties kappa1 = 1/f1: it cannot be held")
        tied["kappa1"] = (lambda p: 1 / p["f1"], lambda p: {"f1": -1 / p["f1"] ** 2})
    params = {**start.params, **hold}
    if variant == "unstressed":
        params["kappa1"] = 1 / params["f1"]
    base = start.with_updates(**params)
    fitted = tuple(n for n in base.family_obj.parameters
                   if n not in hold and n not in tied and n != "sigma")
    bounds = {}
    for n in fitted:
        if n.startswith("f"):
            bounds[n] = BOUNDS["f"]
        elif n.startswith("kappa"):
            bounds[n] = BOUNDS["kappa"]
    names = tuple(f"s{i}" for i in range(1, 5))
    sigma = base.params["sigma"]
    boxes = breakpoint_bounds([base.params[n] for n in names], sigma, base.end)
    for name, box in zip(names, boxes):
        if name in fitted:
            bounds[name] = box if breakpoint_boxes else (sigma, base.end - sigma)
    return FitSpec(base, fitted, tied, bounds, variant, names if breakpoint_boxes else ())


# --------------------------------------------------------------------------
# the model's midline and the inner solves
# --------------------------------------------------------------------------

def model_midline(eq: Equilibrium, n: int = N_FIT) -> np.ndarray:
    """(n, 2) points (r, z) of a direct solution, equally spaced in deformed arclength.

    z is measured from the first point (the posterior pole): the gauge of
    traced midlines.
    """
    from ..solvers.direct import solver_of
    solver = solver_of(eq)
    if solver is None:
        raise ValueError("model_midline needs a direct solution")
    y = midline(solver.disc, n).at(eq)
    return np.column_stack([y[:n], y[n:]])


def synthetic_midline(problem: Problem, like: Problem | None = None, *, nodes: int = 200,
                      n: int = N_FIT, noise: float = 0.0, seed: int | None = None) -> np.ndarray:
    """The (n, 2) midline of the forward model, with Gaussian noise of std ``noise`` (units of R).

    Solved on the mesh a fit starting from ``like`` (default ``problem``)
    uses, so that noiseless data can be fitted exactly: a test of the fit,
    not of the discretisation.
    """
    solver = DirectSolver(problem.structure, mesh=mesh_spec(like or problem, nodes, 2))
    points = model_midline(continue_to(solver, problem), n)
    if noise:
        points = points + np.random.default_rng(seed).normal(0.0, noise, points.shape)
        points[0] = 0.0      # the pole is the origin of the gauge
    return points


class _Inner:
    """The inner problem of a fit: warm-started solves, residuals and their Jacobian."""

    def __init__(self, spec: FitSpec, data: np.ndarray, nodes: int,
                 start: Equilibrium | None = None):
        self.spec, self.data, self.nodes = spec, np.asarray(data, dtype=float), nodes
        self.n = len(self.data)
        self.solves = 0
        self._build(spec.base)
        if start is not None:
            if start.x is None or len(start.x) != self.solver.disc.layout.size:
                raise ValueError(f"the start state must be a direct solution on {nodes} nodes "
                                 f"of this mesh")
            self.eq = start
        else:
            self.eq = continue_to(self.solver, spec.base)
            self.solves += 1
        self._cache: dict = {}
        self._archive = [(spec.theta0, self.eq)]
        #: whether the fit started from a given state (a previous fit's)
        self.warm = start is not None

    def _build(self, problem: Problem) -> None:
        self.solver = DirectSolver(problem.structure, mesh=mesh_spec(problem, self.nodes, 2))
        self.midline = midline(self.solver.disc, self.n)

    def solve(self, theta, trial: bool = False) -> Equilibrium:
        """The inner solution at θ, on the branch of the fit's start.

        From the nearest state solved so far (θ scaled by its bounds' widths):
        one warm solve if it is near, else continuation from it, so that the
        solves follow one branch of equilibria even when θ jumps.  A ``trial``
        point (a least-squares step, which the outer loop rejects and
        shortens when its solve fails) gets no continuation after a failed
        warm solve: it raises at once.
        """
        theta = np.asarray(theta, dtype=float)
        key = tuple(theta)
        if key in self._cache:
            return self._cache[key]
        problem = self.spec.problem(theta)
        near = min(self._archive, key=lambda item: self._distance(item[0], theta))
        try:
            if self._distance(near[0], theta) < NEAR:
                eq = self.solver.solve(problem, warm_start=near[1])
            else:
                eq = continue_between(self.solver, near[1], problem)
        except ValueError:           # the mesh's breakpoints moved too far: a new mesh
            self._build(problem)
            self._archive = []
            eq = solve_from(self.solver, problem, near[1])
        except SolverError:
            if trial:
                raise
            eq = continue_between(self.solver, near[1], problem, first_step=0.25)
        return self._keep(theta, eq)

    def keep(self, theta, eq: Equilibrium) -> None:
        """Make ``eq``, solved before at θ, the state of θ again (without a solve)."""
        self.eq = eq
        self._cache = {tuple(np.asarray(theta, dtype=float)): eq}
        self._archive = (self._archive + [(np.asarray(theta, dtype=float), eq)])[-ARCHIVE:]

    def _keep(self, theta, eq: Equilibrium) -> Equilibrium:
        self.solves += 1
        self.keep(theta, eq)
        return eq

    def transfer(self, theta, eq: Equilibrium) -> Equilibrium:
        """The inner solution at θ on the branch of ``eq``, a solution at θ on another mesh.

        Interpolated and solved (:func:`morphoshell.solvers.refinement.solve_from`); if
        that fails, by :meth:`solve`.  A coarse mesh's state can lie near a fold
        of the branch that the fine mesh has a little earlier: continuation
        from the fit's start then stops short of θ (measured: flat variant, t02
        of the synthetic inversion), while the coarse state's branch continues.
        """
        theta = np.asarray(theta, dtype=float)
        problem = self.spec.problem(theta)
        try:
            try:
                eq = solve_from(self.solver, problem, eq)
            except ValueError:           # the breakpoints moved too far: a new mesh
                self._build(problem)
                self._archive = []
                eq = solve_from(self.solver, problem, eq)
        except SolverError:
            return self.solve(theta)
        return self._keep(theta, eq)

    def _distance(self, a, b) -> float:
        lo, hi = self.spec.box()
        width = np.where(np.isfinite(hi - lo), hi - lo, np.maximum(np.abs(a), 1.0))
        return float(np.max(np.abs(a - b) / width))

    def residuals(self, eq: Equilibrium) -> np.ndarray:
        y = self.midline.at(eq)
        return np.concatenate([y[:self.n] - self.data[:, 0], y[self.n:] - self.data[:, 1]])

    def jacobian(self, eq: Equilibrium, theta) -> np.ndarray:
        """d residuals / dθ, exact (implicit function theorem)."""
        names = tuple(self.spec.fitted) + tuple(self.spec.tied)
        _, J = parametric(self.solver).jacobian(eq, self.midline, names)
        return J @ self.spec.chain(theta, names)


# --------------------------------------------------------------------------
# results
# --------------------------------------------------------------------------

@dataclass(frozen=True, eq=False)
class FitResult:
    """A fitted equilibrium and how it was found.

    Attributes
    ----------
    parameters : dict
        Every family parameter by name, plus ``h``, ``cut``, ``opening``.
    standard_errors : dict
        Gauss–Newton standard errors of the fitted parameters (lower bounds:
        the residuals of a traced midline are correlated).
    correlation : ndarray (n, n)
        Their correlation matrix, in the order of ``fitted``.
    poorly_identified : list of dict
        Directions of θ (scaled by the parameters' magnitudes) with singular
        values below 1e-3 of the largest: ``{"singular_value", "direction"}``.
    constrained : tuple of str
        The hard constraints the fit ends on (:meth:`FitSpec.on_constraints`,
        e.g. ``"s3 - s2 = sigma"``); the standard errors of the parameters in
        them are NaN (a constrained optimum has none of a free one's).
    E_fit : float
        The fit energy (units of R).
    residuals : ndarray (2N,)
        r − R then z − Z at the N points.
    equilibrium : Equilibrium
        The fitted shape.
    data, model : ndarray (N, 2)
        The data midline and the fitted midline (r, z).
    """

    method: str
    variant: str
    fitted: tuple[str, ...]
    parameters: dict
    standard_errors: dict
    correlation: np.ndarray
    poorly_identified: list
    E_fit: float
    residuals: np.ndarray
    equilibrium: Equilibrium
    data: np.ndarray
    model: np.ndarray
    outer_iterations: int
    inner_solves: int
    seconds: float
    converged: bool
    message: str = ""
    constrained: tuple[str, ...] = ()

    def __repr__(self) -> str:
        return (f"FitResult({self.method}, {self.variant}, E_fit={self.E_fit:.6g} R, "
                f"{len(self.fitted)} parameters, {self.outer_iterations} iterations, "
                f"{self.inner_solves} inner solves, {self.seconds:.2f} s, "
                f"converged={self.converged})")

    def summary(self) -> str:
        """A few lines: the result, every fitted parameter with its standard error, the
        constraints it ends on and the poorly identified directions."""
        lines = [repr(self)]
        for n in self.fitted:
            e = self.standard_errors[n]
            lines.append(f"  {n:8s} = {self.parameters[n]: .6g} "
                         + (f"± {e:.2g}" if np.isfinite(e) else "(on a constraint)"))
        for c in self.constrained:
            lines.append(f"  on the constraint {c}")
        for d in self.poorly_identified:
            lines.append(f"  poorly identified: {d['direction']} (singular value "
                         f"{d['singular_value']:.2g})")
        return "\n".join(lines)

    @property
    def pinned(self) -> tuple[str, ...]:
        """The fitted parameters in the constraints the fit ends on (no standard error)."""
        return tuple(n for n in self.fitted if not np.isfinite(self.standard_errors[n]))

    @property
    def near_fold(self) -> bool:
        """Whether the fitted state is near a fold of the inner branch (:data:`FOLD_RATIO`).

        All singular values of the scaled Jacobian but the largest are below
        FOLD_RATIO of it; such a fit is reported as not converged.
        """
        # poorly_identified keeps every singular value below 1e-3 of the largest, so with
        # FOLD_RATIO < 1e-3 it holds all k - 1 of them exactly when the fit is near a fold
        k = len(self.fitted)
        return k > 1 and len(self.poorly_identified) == k - 1 and all(
            d["singular_value"] < FOLD_RATIO for d in self.poorly_identified)

    def to_dict(self) -> dict:
        """JSON-ready: the problem, the fitted parameters with standard errors and
        correlations, the fit energy E_fit (units of R) and the solver's report."""
        p = self.equilibrium.problem
        return {"problem": p.describe(), "parameters": dict(self.parameters),
                "fitted": list(self.fitted),
                # (none on a constraint: JSON has no NaN)
                "standard_errors": {n: (float(e) if np.isfinite(e) else None)
                                    for n, e in self.standard_errors.items()},
                "correlation": self.correlation.tolist(),
                "poorly_identified": self.poorly_identified, "E_fit": self.E_fit,
                "E_fit_units": "R", "method": self.method, "variant": self.variant,
                "converged": self.converged, "message": self.message, "seconds": self.seconds,
                "constrained": list(self.constrained),
                "outer_iterations": self.outer_iterations, "inner_solves": self.inner_solves,
                "data_midline": {"r": self.data[:, 0].tolist(), "z": self.data[:, 1].tolist()},
                "fitted_midline": {"r": self.model[:, 0].tolist(), "z": self.model[:, 1].tolist()},
                "note": "standard errors are Gauss-Newton lower bounds: the residuals of a "
                        "traced midline are correlated"}


def _result(method, spec, inner, theta, iterations, seconds, converged, message) -> FitResult:
    eq = inner.solve(theta)
    res = inner.residuals(eq)
    J = inner.jacobian(eq, theta)
    n, k = len(res), len(theta)
    sigma2 = float(res @ res) / max(n - k, 1)
    JTJ = J.T @ J
    cov = sigma2 * np.linalg.pinv(JTJ)
    se = np.sqrt(np.maximum(np.diag(cov), 0))
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = cov / np.outer(se, se)
    scale = np.maximum(np.abs(theta), 1e-2)
    _, sv, vt = np.linalg.svd(J * scale, full_matrices=False)
    poor = [{"singular_value": float(s / sv[0]),
             "direction": {spec.fitted[j]: round(float(v[j]), 3) for j in np.argsort(-np.abs(v))[:3]}}
            for s, v in zip(sv, vt) if s < 1e-3 * sv[0]]
    params = {**eq.problem.params, "h": eq.problem.h, "cut": eq.problem.cut,
              "opening": eq.problem.opening}
    errors = dict(zip(spec.fitted, se.tolist()))
    active = spec.on_constraints(theta)
    if active:
        pinned = sorted({n for _, names in active for n in names}, key=spec.fitted.index)
        errors.update({n: float("nan") for n in pinned})
        message = (f"{message}; it ends on the constraint {', '.join(d for d, _ in active)}: a "
                   f"constrained optimum, so {', '.join(pinned)} have no standard errors (NaN)"
                   ).lstrip("; ")
    result = FitResult(method, spec.variant, spec.fitted, params, errors, corr, poor,
                       float(np.sqrt(res @ res)), res, eq, inner.data,
                       inner.data + np.column_stack([res[:inner.n], res[inner.n:]]),
                       iterations, inner.solves, seconds, converged, message,
                       tuple(d for d, _ in active))
    if not result.near_fold:
        return result
    return replace(result, converged=False, message=(
        f"{message}; but the fitted state is near a fold of the equilibrium branch: the "
        f"midline's sensitivity to the parameters is {sv[0] / sv[1]:.2g}x larger along one "
        f"direction than along any other (FOLD_RATIO), so the shape is nearly unstable and the "
        f"standard errors are meaningless").lstrip("; "))


# --------------------------------------------------------------------------
# the three methods
# --------------------------------------------------------------------------

def fit(spec: FitSpec, data, method: str = "gradient", *, nodes: int = 200,
        tol: float = 1e-10, max_iterations: int | None = None,
        start: Equilibrium | None = None) -> FitResult:
    """Fit ``spec`` to a midline.

    Parameters
    ----------
    spec : FitSpec
        What is fitted (:func:`volvox_spec` for the paper's variants).
    data : array_like (N, 2) or Midline
        The target midline (r, z) in the model gauge, N points equally spaced
        in arclength (:func:`morphoshell.io.traces.resample`); N = 100 in the
        paper.
    method : {"nelder-mead", "gradient", "kkt"}
    nodes : int
        Mesh nodes of the inner solves, from 20 to 3200 (:data:`FIT_NODES`).
    tol : float
        Relative tolerance on E_fit² of the outer iteration, in [1e-15, 1).
    max_iterations : int, optional
        Outer iterations (function evaluations for Nelder–Mead; Ipopt
        iterations of each NLP for KKT, default :data:`KKT_ITERATIONS`).
    start : Equilibrium, optional
        The inner state to start from (a direct solution of ``spec.base`` on
        the fit's mesh, e.g. a previous fit's); by default the physical branch
        by continuation from the stress-free parameters.

    Returns
    -------
    FitResult

    Raises
    ------
    ValueError
        An option out of range, data that are not N >= 3 finite points, or
        a midline that does not start at the pole, turns back on itself or,
        of a Volvox fit, is far too short or long for the model
        (:func:`check_midline`), before any work.
    FitError
        KKT only: status ``"Fit_Saddle"`` when the fit ends on a state that is
        not a minimum of the inner energy, ``"Fit_Not_Reproduced"`` when the
        inner solve at the fitted parameters leaves that state, else Ipopt's
        status of the failed NLP; the last iterate is attached.  The other
        methods return ``converged=False`` and a message when their outer
        iteration stops short.
    """
    if method not in METHODS:
        raise ValueError(f"method = {method!r} must be one of {list(METHODS)}")
    _check_options(nodes, tol, max_iterations)
    data = _points(data)
    check_midline(spec, data)
    t0 = time.perf_counter()
    inner = _Inner(spec, data, nodes, start)
    run = {"nelder-mead": _nelder_mead, "gradient": _gradient, "kkt": _kkt}[method]
    iterations, moved = 0, []
    while True:
        try:
            theta, its, ok, msg = run(spec, inner, tol, max_iterations)
        except FitError as exc:
            if not moved:
                raise
            # the fit within the last boxes stands, reported as unconverged
            # (measured: a KKT NLP from moved boxes ran out of iterations,
            # undeformed t05 of the synthetic campaign)
            iterations += int(getattr(exc, "iterations", 0) or 0)
            spec = inner.spec = last
            ok, msg = False, (f"{msg}; but {moved[-1]} rested on the edge of their boxes, and "
                              f"the fit from moved boxes failed: {exc}")
            break
        iterations += its
        # The breakpoints' boxes order them for methods that take bounds, not
        # constraints; their edges are not the fit's.  Measured on the
        # synthetic campaign (2026-11-23), before the boxes moved: 20 of the 44
        # fits that ran ended with a breakpoint on an edge, "converged" (undeformed s3
        # at every timepoint, each one box lower than the last).
        edges = spec.on_box_edges(theta)
        if not edges:
            break
        if len(moved) == MAX_RECENTRES:
            ok, msg = False, (f"{msg}; but {', '.join(edges)} still rest on the edge of their "
                              f"boxes after {MAX_RECENTRES} moves (FitSpec.on_box_edges): the "
                              f"optimum may lie beyond")
            break
        moved.append(", ".join(edges))
        inner.eq, last = inner.solve(theta), spec
        spec = inner.spec = spec.recentred(theta)
        inner.warm = True            # (the KKT fit goes on from this state)
    if moved:
        msg = f"{msg} (after moving the breakpoints' boxes {len(moved)} times: {'; '.join(moved)})"
    return _result(method, spec, inner, theta, iterations, time.perf_counter() - t0, ok, msg)


def _check_options(nodes, tol, max_iterations) -> None:
    """ValueError naming the first of :func:`fit`'s options that is out of range."""
    def integer(value) -> bool:
        return isinstance(value, (int, np.integer)) and not isinstance(value, bool)

    lo, hi = FIT_NODES
    if not (integer(nodes) and lo <= nodes <= hi):     # (5 nodes: "4 cells cannot hold ...")
        raise ValueError(f"nodes = {nodes!r} must be an integer from {lo} to {hi}")
    if real("tol", tol) < 1e-15 or tol >= 1:     # (scipy: below eps ends no iteration)
        raise ValueError(f"tol = {tol!r} must lie in [1e-15, 1)")
    if max_iterations is not None and not (integer(max_iterations) and max_iterations >= 1):
        raise ValueError(f"max_iterations = {max_iterations!r} must be a positive integer")


def intrinsic_lengths(spec: FitSpec) -> tuple[float, float] | None:
    """(shortest, longest) intrinsic length ∫ f_s0 ds of the fitted Volvox shell, in R.

    f_s0 blends f₁, f₂ and f₃ with smoothed steps (documentation: "Problems
    and families"), so over the shell's length L − P the intrinsic midline is
    about as long as the smallest of their lower bounds (held values for held
    stretches) times L − P, at least, and the largest of their upper bounds
    times L − P, at most.  ``None`` for other families.
    """
    if spec.base.family != "volvox":
        return None
    lo, hi = spec.box()
    lows, highs = [], []
    for name in ("f1", "f2", "f3"):
        if name in spec.fitted:
            i = spec.fitted.index(name)
            lows.append(lo[i]), highs.append(hi[i])
        else:
            lows.append(spec.base.params[name]), highs.append(spec.base.params[name])
    return min(lows) * spec.base.end, max(highs) * spec.base.end


def check_midline(spec: FitSpec, data, name: str = "the data midline") -> None:
    """ValueError if the midline ``data`` (N, 2) cannot be a midline of ``spec``'s shell.

    It does not start at the posterior pole of an intact shell (further than
    :data:`POLE_SLACK` from the origin of the model gauge: listed rim first?),
    it turns back on itself (more than :data:`MAX_TURN` within
    :data:`TURN_LENGTH`: a retraced line), or its polygon length lies outside
    :func:`intrinsic_lengths` by more than :data:`LENGTH_SLACK` either way
    (the wrong units or scale).
    """
    points = _points(data)
    off = float(np.hypot(*points[0]))
    if spec.base.cut == 0 and off > POLE_SLACK:
        raise ValueError(
            f"{name} starts at (r, z) = ({points[0, 0]:.3g}, {points[0, 1]:.3g}), {off:.3g} R "
            f"from the posterior pole at the origin of the model gauge, where a midline "
            f"starts: is it listed rim first (reverse it), or not in the model gauge?")
    step = np.diff(points, axis=0)
    step = step[np.any(step != 0, axis=1)]       # (a repeated point has no direction)
    seg = np.hypot(*step.T)
    length = float(seg.sum())
    middle = np.cumsum(seg) - seg / 2
    # the tangent's angle, unwrapped: a U-turn adds up to pi however many segments it spans
    angle = np.unwrap(np.arctan2(step[:, 1], step[:, 0]))
    for i in range(len(step)):
        j = np.searchsorted(middle, middle[i] + TURN_LENGTH, side="right")
        turn = np.abs(angle[i:j] - angle[i])
        if turn.max() > MAX_TURN:
            raise ValueError(
                f"{name} turns back on itself {middle[i]:.3g} R along it (by "
                f"{np.degrees(turn.max()):.0f} degrees within {TURN_LENGTH:g} R): a traced "
                f"line that retraces its way?")
    lengths = intrinsic_lengths(spec)
    if lengths is None:
        return
    shortest, longest = lengths
    if not shortest / LENGTH_SLACK <= length <= longest * LENGTH_SLACK:
        raise ValueError(
            f"{name} is {length:.3g} R long, but the model's midlines are about "
            f"{shortest:.3g}-{longest:.3g} R long (stretches f1-f3 within their bounds over "
            f"the shell's {spec.base.end:.3g} R): are its units R and its scale right?")


def _points(data) -> np.ndarray:
    if hasattr(data, "r") and hasattr(data, "z"):
        data = np.column_stack([data.r, data.z])
    data = np.asarray(data, dtype=float)
    if data.ndim != 2 or data.shape[1] != 2 or len(data) < 3 or not np.all(np.isfinite(data)):
        raise ValueError(f"the data must be N >= 3 finite points (r, z), got shape {data.shape}")
    return data


def _feasible(spec, theta) -> bool:
    lo, hi = spec.box()
    if np.any(theta < lo) or np.any(theta > hi):
        return False
    try:
        spec.problem(theta)
    except ValueError:
        return False
    return True


def _nelder_mead(spec, inner, tol, max_iterations):
    from scipy.optimize import minimize

    worst = [1.0]

    def E(theta):
        if not _feasible(spec, theta):
            return 10 * worst[0]
        try:
            res = inner.residuals(inner.solve(theta))
        except SolverError:
            return 10 * worst[0]
        value = float(np.sqrt(res @ res))
        worst[0] = max(worst[0], value)
        return value

    lo, hi = spec.box()
    bounds = list(zip(np.where(np.isfinite(lo), lo, None), np.where(np.isfinite(hi), hi, None)))
    budget = max_iterations or 20000
    theta, evaluations, best = spec.theta0, 0, np.inf
    start = E(theta)
    # A simplex can collapse before the minimum: restart around the best point,
    # as careful fminsearch users do, while a restart still improves E_fit by
    # 1 % and E_fit is not negligible (1e-6 of the start's).
    for _ in range(NM_RESTARTS):
        out = minimize(E, theta, method="Nelder-Mead", bounds=bounds,
                       options={"adaptive": True, "xatol": 1e-8,
                                "fatol": tol * max(start, 1e-12),
                                "maxfev": budget - evaluations})
        evaluations += int(out.nfev)
        improved = out.fun < 0.99 * best
        theta, best = out.x, min(best, float(out.fun))
        if not improved or best < 1e-6 * start or evaluations >= budget:
            break
    return theta, evaluations, bool(out.success), str(out.message)


class _Stalled(Exception):
    """Raised inside the gradient fit's residuals when trial points keep failing."""


def _gradient(spec, inner, tol, max_iterations, theta0=None):
    from scipy.optimize import least_squares

    failures, evaluations = [0], [0]
    best = [spec.theta0, np.inf, None]      # θ, cost, its state

    def fun(theta):
        # A trial point whose inner solve fails (the continuation cannot reach
        # it: measured from the default start of the unstressed variant) or
        # that is infeasible (|eta| >= 1: measured on campaign steps) is
        # rejected like a bad step: the trust region shrinks on non-finite
        # residuals instead of the fit aborting.  When every trial fails (a
        # state at a fold of the branch: measured, each failed trial cost ~15 s
        # of continuation and the trust region shrank ~20 times per iteration,
        # for many minutes), the fit stops at its best point, not converged.
        evaluations[0] += 1
        try:
            # a trial whose warm solve fails is rejected without continuation: continuing
            # to such trials cost 1.6 s each, 14 of the 20 s of a campaign fit (t09, flat)
            eq = inner.solve(theta, trial=True)
            res = inner.residuals(eq)
        except (SolverError, ValueError):
            failures[0] += 1
            if failures[0] >= MAX_FAILED_TRIALS:
                raise _Stalled from None
            return np.full(2 * inner.n, np.inf)
        failures[0] = 0
        cost = float(res @ res)
        if cost < best[1]:
            best[:] = [np.array(theta, dtype=float), cost, eq]
        return res

    def jac(theta):
        return inner.jacobian(inner.solve(theta), theta)

    lo, hi = spec.box()
    try:
        out = least_squares(fun, spec.theta0 if theta0 is None else theta0, jac=jac,
                            bounds=(lo, hi), method="trf",
                            x_scale="jac", ftol=tol, xtol=1e-12, gtol=1e-12,
                            max_nfev=max_iterations or 200)
    except _Stalled:
        if best[2] is not None:
            # (its state may have left the archive: a solve from another one there failed,
            # and with it the whole fit; measured, unstressed on the synthetic t06 from
            # the family's defaults)
            inner.keep(best[0], best[2])
        return (best[0], evaluations[0], False,
                f"stopped at the best point reached, after {MAX_FAILED_TRIALS} consecutive "
                f"trial points whose inner solve failed (a fold of the branch?)")
    # least_squares also stops when its trust region has shrunk below xtol or its cost
    # no longer falls (ftol), which a stall does too: near a fold trial points jump
    # between states of the inner branch and are all rejected, whatever the Jacobian
    # promises.  Measured over the synthetic campaign's 134 least-squares runs
    # (2026-11-24): 123 ends have a gradient below 1.7e-4 of the residual's norm (the
    # cosine of r with J's scaled columns, x_scale="jac"); 11 had 6e-3 to 600.  Of those,
    # the 4 below 1e-2 went on by 0.2 % of E_fit or less (at 60 nodes stationary ends reach
    # 8e-3); the 7 above include unstressed t09 "converged" by xtol at E_fit 0.32 R, which
    # a second fit from there took to 0.038 R.
    # (gtol, status 1, is stationarity itself; a misfit below RESIDUAL_FLOOR is exact data's)
    cos = float(out.optimality) / max(np.sqrt(2 * float(out.cost)), RESIDUAL_FLOOR)
    if out.status > 1 and cos > STATIONARY:
        return out.x, int(out.nfev), False, (
            f"{out.message} But it is not a stationary point: the gradient there is "
            f"{cos:.2g} of the residual's norm (STATIONARY = {STATIONARY:g}), so trial "
            f"points near it were rejected for a reason the Jacobian does not see (the inner "
            f"state jumping between branches near a fold?)")
    return out.x, int(out.nfev), bool(out.status > 0), str(out.message)


def _kkt(spec, inner, tol, max_iterations):
    """One NLP in (θ, x, λ) with the inner KKT conditions as constraints.

    Route A to its start: from a given start state (``inner.warm``: a
    previous fit's) loose Gauss–Newton steps of the reduced problem
    (:data:`KKT_GN_TOL`, :data:`KKT_GN_ITERATIONS`); otherwise, on fine
    meshes, a KKT fit on a coarse mesh (:data:`COARSE_NODES`): a change of
    the model's length moves the fit points by many short cells, beyond the
    window one NLP lets them move (measured: stalls at 200 nodes from the
    start shape), while on the coarse mesh's long cells it does not; then
    Gauss–Newton steps on the fine mesh (:data:`KKT_FINE_GN_TOL`) and the
    fine NLP from their end.  Route B, when A fails (its NLP, or its end is
    a saddle or not reproduced): Gauss–Newton steps to the fit's tolerance,
    then the NLP from their end.  Each NLP stops after :data:`KKT_ITERATIONS`.
    """
    theta0, eq, spent, its = spec.theta0, inner.eq, 0, 0
    try:
        if inner.warm:
            # From a previous fit's state (a campaign step) the NLP alone failed:
            # its path crossed a nearly singular stretch of the branch (flat t03
            # at 200 nodes), while from loose Gauss-Newton steps (flat t03-t05:
            # 17, 9, 9 of them) it converged in 8, 8, 5 iterations.
            theta0, eq, spent = _gauss_newton_steps(spec, inner, KKT_GN_TOL, KKT_GN_ITERATIONS,
                                                    theta0, eq)
            theta, x, lam, its, status = _kkt_nlp(spec, inner, tol, max_iterations, theta0, eq)
        else:
            theta, x, lam, its, status = _kkt_from_coarse(spec, inner, tol, max_iterations)
        return _kkt_checked(inner, theta, x, lam, spent + its, status)
    except FitError as exc:
        # Measured on the synthetic campaign (200 nodes): from the previous
        # fit's state the NLP failed or ended on a saddle at unstressed t06-t09
        # and free t02, and the data homotopy that then shortened its steps
        # cost 90-830 s, mostly to fail; from the reduced optimum the NLP
        # converged in 6-19 iterations (unstressed t06: 6 s in all).
        spent += its or int(getattr(exc, "iterations", 0) or 0)
        first = exc
    try:
        theta0, eq, steps = _gauss_newton_steps(spec, inner, tol, max_iterations, theta0, eq,
                                                required=True)
    except FitError as exc:         # what failed first, and why it was not tried again
        raise FitError(f"{first}; {exc}", first.status, first.last_iterate) from None
    theta, x, lam, its, status = _kkt_nlp(spec, inner, tol, max_iterations, theta0, eq)
    return _kkt_checked(inner, theta, x, lam, spent + steps + its, status)


def _gauss_newton_steps(spec, inner, ftol, max_evaluations, theta0, eq,
                        required: bool = False) -> tuple:
    """(θ, its inner state, evaluations): Gauss–Newton steps from θ₀ and its state ``eq``.

    The reduced problem's (:func:`_gradient`).  From a start that no solve
    reproduces (a saddle: rejected after the NLP) there are none.  When
    ``required``, steps that stop short of ``ftol`` raise FitError: an NLP
    from there went wild (synthetic campaign, unstressed t09 from t07's
    fit: the steps stopped at a fold of the branch, and 60 Ipopt iterations
    with Hessian perturbations up to 1e10 took 356 s).
    """
    evaluations = 0
    try:
        theta, evaluations, converged, message = _gradient(spec, inner, ftol, max_evaluations,
                                                           theta0)
        if converged or not required:
            return theta, inner.solve(theta), evaluations
    except SolverError as exc:
        if not required:
            return theta0, eq, 0
        message = str(exc)
    exc = FitError(f"the Gauss-Newton steps to start again from stopped short: {message}",
                   "Gauss_Newton_Stopped", eq)
    exc.iterations = evaluations
    raise exc


def _kkt_nlp(spec, inner, tol, max_iterations, theta0, eq, near: bool = True) -> tuple:
    """(θ, x, λ, iterations, status) of the KKT NLP from θ₀ and its inner state ``eq``.

    ``near``: θ₀ is close to the optimum (Gauss–Newton steps' end), and the
    NLP starts from the reduced problem's adjoints; from a far start, from
    zero multipliers (adjoints there took as many iterations or more: 17-32
    against 19-26 on bench_fit's coarse stage, measured).
    """
    inner.eq = eq         # (the NLP's objective is scaled by the misfit there)
    return _kkt_cells(_KKTProblem(spec, inner, tol, max_iterations, adjoint_duals=near),
                      inner, theta0, eq.x, eq.lam_g, inner.data)


def _kkt_from_coarse(spec, inner, tol, max_iterations) -> tuple:
    """Route A of :func:`_kkt` without a start state: coarse mesh first, then this one."""
    if inner.nodes <= 2 * COARSE_NODES:
        return _kkt_nlp(spec, inner, tol, max_iterations, spec.theta0, inner.eq, near=False)
    coarse = _Inner(spec, inner.data, COARSE_NODES)
    theta0, spent, _, _ = _kkt(spec, coarse, max(tol, KKT_COARSE_TOL), max_iterations)
    # From a coarse fit the start is close: a tiny initial barrier (from 1e-6
    # the fine stage took 34 iterations, wandering while mu fell) and the
    # adjoints as multipliers (_KKTProblem._adjoint_duals): from zero ones the
    # exact Hessian lacks the constraints' curvature, and the fine stage stalled
    # in line searches (38 + 56 + 12 iterations with noisy data; 16 from Ipopt's
    # least-squares estimate, measured before the window edges were flagged;
    # from that estimate 5-23 on bench_fit's noisy seeds, one failing after 60,
    # and 16 noiseless; from the adjoints 5-17 and 6, measured 2026-11-23).
    #   And Gauss-Newton steps on this mesh first: the coarse optimum lies
    # along the poorly identified directions from this mesh's (0.4 standard
    # errors, bench_fit's noisy data), across a curved valley (the misfit rises
    # 2 % between the two on the straight line), where the NLP's steps crawled
    # and moved fit points out of their windows (NLPs rebuilt): 15-92 iterations
    # at 200 nodes over seven noise seeds, 4-9 from the steps' end (one seed 32),
    # the fits 2.1-4.6 s instead of 2.9-11.3 s (measured 2026-11-23).
    eq = inner.transfer(theta0, coarse.eq)      # the fine state on the coarse fit's branch
    theta0, eq, steps = _gauss_newton_steps(spec, inner, KKT_FINE_GN_TOL, KKT_GN_ITERATIONS,
                                            theta0, eq)
    spent += steps
    nlp = _KKTProblem(spec, inner, tol, max_iterations, mu_init=1e-9, adjoint_duals=True)
    try:
        theta, x, lam, its, status = _kkt_cells(nlp, inner, theta0, eq.x, eq.lam_g,
                                                inner.data)
    except FitError as exc:
        exc.iterations = getattr(exc, "iterations", 0) + spent
        raise
    return theta, x, lam, its + spent, status


def _kkt_checked(inner, theta, x, lam, iterations, status) -> tuple:
    """:func:`_kkt`'s result at the NLP's end, after checking that it is the inner minimum.

    Raises FitError at a saddle of the inner energy, or when the inner solve
    at the fitted θ does not stay at x.
    """
    spec = inner.spec
    problem = spec.problem(theta)
    p = problem.parameter_vector()
    d = inner.solver.disc
    D = d.cell_data(p)
    fitted = inner.solver.equilibrium(problem, x, lam, p, np.zeros(0), D, inner.eq.solver, True)
    if inner.solver.backend.inertia_correction(x, D, lam) > 0:
        raise FitError(
            "the KKT fit ended on a stationary state of the inner energy that is not a "
            "minimum (a saddle: the reduced Hessian is not positive definite); start from "
            "another point or use the gradient method", "Fit_Saddle", fitted)
    # the fitted state must be what the inner problem gives there: re-solve from it
    check = inner.solver.solve(problem, warm_start=fitted)
    inner.solves += 1
    if np.max(np.abs(check.x - x)) > 1e-6:
        raise FitError("the KKT fit's state is not reproduced by the inner solve at the "
                       "fitted parameters", "Fit_Not_Reproduced", fitted)
    inner.eq = check
    inner._cache = {tuple(theta): check}
    return theta, iterations, True, status


def _kkt_cells(nlp, inner, theta, x, lam, data) -> tuple:
    """NLPs to ``data`` from (θ, x, λ), rebuilt while the fit points leave their cells' windows."""
    iterations, status = 0, ""
    spec, d = inner.spec, inner.solver.disc
    for _ in range(8):
        cells = midline_cells(d, x, spec.problem(theta).parameter_vector(), inner.n)
        try:
            theta, x, lam, its, status = nlp.solve(cells, theta, x, lam, data)
        except FitError as exc:
            exc.iterations = iterations + int(nlp.nlp.stats().get("iter_count", 0))
            raise
        iterations += its
        # the NLP chose each point's cell within a window around the assigned
        # one: exact as long as every point stayed inside its window
        now = midline_cells(d, x, spec.problem(theta).parameter_vector(), inner.n)
        if max(abs(a - b) for a, b in zip(now, cells)) <= WINDOW:
            break
    return theta, x, lam, iterations, status


def _ramp(x):
    """C¹ smoothstep: 0 for x ≤ 0, 3x² − 2x³ between, 1 for x ≥ 1 (CasADi)."""
    x = ca.fmin(ca.fmax(x, 0), 1)
    return x * x * (3 - 2 * x)


@lru_cache(maxsize=4)
def _blended_point(stages: int) -> ca.Function:
    """``(u, t, first, last, keep) -> (r, z)``: one fit point blended over its window (SX).

    u holds, for the 2 WINDOW + 1 cells of the window, their unknowns
    (``cell_unknowns``), then their first and last nodes in s, z and the
    deformed arclength S at their first nodes, then the shell's total S; the
    point sits at S = t S_total.  Each cell's evaluation has a C¹ weight that
    is 1 inside the cell and falls to 0 across an overlap of BLEND cell widths
    around its boundaries: the midline is only continuous across cell
    boundaries (the cell polynomials agree in value, to O(Δs^(S+1)), not in
    slope), and a fit point resting on a node made E_fit(θ) kinked there,
    where stationarity stalled (1.7e-3 with noisy data, measured).  Cells
    flagged ``first`` (``last``) keep their weight below (above) themselves:
    the shell's first and last cells, for targets beyond its ends, and the
    window's outermost ones (:meth:`_KKTProblem._window_indices`).  A clipped
    window repeats a cell, counted once (``keep``).
    """
    from ..numerics import arclength_point, collocation

    n_w, n_z = 2 * WINDOW + 1, 3 * stages + 2
    u = ca.SX.sym("u", n_w * (n_z + 4) + 1)
    t, first, last, keep = (ca.SX.sym(nm, n) for nm, n in
                            (("t", 1), ("first", n_w), ("last", n_w), ("keep", n_w)))
    Z = ca.reshape(u[:n_w * n_z], n_z, n_w)
    lo, hi, z0, S0 = (u[n_w * (n_z + i):n_w * (n_z + i + 1)] for i in range(4))
    target = u[-1] * t
    point = arclength_point(stages)
    gauss = ca.DM(collocation(stages)[1])
    num_r = num_z = den = 0
    for o in range(n_w):
        _, r_o, _, z_o = point(Z[:, o], lo[o], hi[o] - lo[o], z0[o], S0[o], target)
        # where the point lies in the cell, from the linear interpolant of S:
        # for a target cells away, Newton's iteration can end inside the cell
        # on a wrong root, which then had weight (a point at r = 0.767 came
        # out at 1.238, measured on the synthetic campaign's t03)
        S1 = S0[o] + (hi[o] - lo[o]) * ca.dot(gauss, Z[2 * stages + 2:, o])
        tau = (target - S0[o]) / (S1 - S0[o])
        weight = (ca.fmax(_ramp((tau + BLEND) / (2 * BLEND)), first[o])
                  * ca.fmax(_ramp((1 + BLEND - tau) / (2 * BLEND)), last[o]) * keep[o])
        num_r, num_z, den = num_r + weight * r_o, num_z + weight * z_o, den + weight
    return ca.Function("blended_point", [u, t, first, last, keep],
                       [ca.vertcat(num_r / den, num_z / den)])


@lru_cache(maxsize=4)
def _point_misfit(stages: int) -> ca.Function:
    """``(u, t, first, last, keep, (R, Z)) -> (∂e/∂u, triu ∂²e/∂u²)`` (SX).

    e = ½|(r, z) − (R, Z)|² for one fit point: the exact Hessian of its
    squared misfit in its local unknowns (:func:`_blended_point`); the MX
    Hessian of the assembled misfit cost 0.24 s per evaluation at 60 nodes
    (measured).
    """
    f = _blended_point(stages)
    args = [f.sx_in(i) for i in range(f.n_in())]
    data = ca.SX.sym("data", 2)
    e = 0.5 * ca.sumsqr(f(*args) - data)
    u = args[0]
    H = ca.hessian(e, u)[0]
    ku, lu = np.triu_indices(u.shape[0])
    return ca.Function("point_misfit", [*args, data],
                       [ca.gradient(e, u), ca.vertcat(*[H[int(i), int(j)]
                                                        for i, j in zip(ku, lu)])])


@lru_cache(maxsize=4)
def _compiled_misfit(stages: int) -> ca.Function:
    """:func:`_point_misfit` compiled for evaluation (at ``-O1``: gcc's -O2 took over 5 min)."""
    return compiled_point_function(_point_misfit(stages), LARGE)


class _KKTProblem:
    """The fit as one NLP, solved by Newton's method (Ipopt, exact Hessian).

    Unknowns w = (θ, x, λ, Z, Σ): the fitted parameters, the inner unknowns
    and multipliers, and z and the deformed arclength at the cell boundaries,
    lifted into variables with one constraint per cell (so that each fit
    point depends on its own cell only and every matrix stays sparse).
    Constraints: the inner KKT conditions F(x, λ; p(θ)) = 0, the cell
    integrals of z' = f_s sin ψ and S' = f_s, the breakpoints ordered at least
    σ apart inside the shell, |η| ≤ ETA_MAX; bounds on θ.  The Hessian of
    the Lagrangian is exact (:meth:`_hessian`: Gauss–Newton approximations
    of it made the reduced Hessian indefinite or its steps diverge).  Which
    cell holds each fit point is structural: the NLP is rebuilt (in a
    fraction of a second) when points change cells.
    """

    def __init__(self, spec, inner, tol, max_iterations, mu_init: float = 1e-6,
                 adjoint_duals: bool = False):
        self.spec, self.inner, self.tol = spec, inner, tol
        self.max_iter = max_iterations or KKT_ITERATIONS
        self.mu_init = mu_init
        # The first NLP starts from zero multipliers, or from the reduced
        # problem's adjoints (``adjoint_duals``; later NLPs carry theirs over).
        self.from_adjoints = adjoint_duals
        self.scale = 1.0
        self.cells: tuple | None = None
        self._duals: tuple | None = None

    def _build(self, cells: tuple, scale: float = 1.0) -> None:
        from ..model.layouts import CELL_DATA

        spec, inner = self.spec, self.inner
        solver = inner.solver
        d = solver.disc
        k, nc, n = len(spec.fitted), d.layout.cells, inner.n
        th = ca.MX.sym("theta", k)
        x = ca.MX.sym("x", d.layout.size)
        lam = ca.MX.sym("lam", d.g.shape[0])
        zc, sc = ca.MX.sym("z_cells", nc + 1), ca.MX.sym("S_cells", nc + 1)
        values = spec.params(th)
        layout = spec.base.parameter_layout
        base = spec.base.parameter_vector()
        p = ca.vertcat(*[values[nm] if nm in values else float(base[i])
                         for i, nm in enumerate(layout.names)])
        q = ca.DM.zeros(0, 1)
        P = parametric(solver)
        F = P.kkt_residual(x, lam, p, q)
        sh = d.shape(x, p, q)
        dz, dS = sh.increments()
        lifted = ca.vertcat(zc[0], zc[1:] - zc[:nc] - dz, sc[0], sc[1:] - sc[:nc] - dS)
        # Each point may lie in a window of cells around its assigned one, the
        # cells' evaluations blended (:func:`_blended_point`).
        t_fit = np.linspace(0, 1, n)
        u_idx, flags = self._window_indices(cells, nc, d.layout.size, d._idx)
        U = ca.vertcat(sh.s_nodes, x, zc, sc)           # what the residuals depend on
        Uext = ca.vertcat(U, ca.DM([0.0, 0.0, np.pi]))   # the pole's constant r, ψ
        local = ca.reshape(Uext[u_idx.ravel(order="F").tolist()], u_idx.shape[0], n)
        blended = _blended_point(d.stages).map(n)
        rz = blended(local, ca.DM(t_fit).T, *(ca.DM(f) for f in flags))
        # the data are the NLP's parameter, not constants in its graph
        target = ca.MX.sym("data", 2 * n)         # (r, z) point by point
        res = ca.vec((rz - ca.reshape(target, 2, n)).T)
        ineq, glo, ghi = [], [], []
        if spec.base.family == "volvox":
            named = layout.unpack(p)
            s = [named[f"s{i}"] for i in range(1, 5)]
            for a, b in zip([0.0, *s], [*s, spec.base.end]):
                ineq.append(b - a)
                glo.append(float(spec.base.params["sigma"])), ghi.append(np.inf)
        eta = ca.reshape(d.pre(p, q), len(CELL_DATA), -1)[CELL_DATA.index("eta"), :].T
        g = ca.vertcat(F, lifted, *ineq, eta)
        self.lbg = np.concatenate([np.zeros(F.shape[0] + lifted.shape[0]), glo,
                                   -ETA_MAX * np.ones(eta.shape[0])])
        self.ubg = np.concatenate([np.zeros(F.shape[0] + lifted.shape[0]), ghi,
                                   ETA_MAX * np.ones(eta.shape[0])])
        w = ca.vertcat(th, x, lam, zc, sc)
        jac_g = ca.Function("jac_g", [w, target],
                            [g, self._constraint_jacobian(d, th, x, lam, p, q, w, lifted, ineq)],
                            ["x", "p"], ["g", "jac_g_x"])
        box_lo, box_hi = spec.box()
        free = np.inf * np.ones(w.shape[0] - k)
        self.lbw, self.ubw = np.concatenate([box_lo, -free]), np.concatenate([box_hi, free])
        sigma, mult = ca.MX.sym("lam_f"), ca.MX.sym("lam_g", g.shape[0])
        H = self._hessian(d, P, th, x, lam, p, q, sh, local, t_fit, flags, u_idx, w, sigma, mult,
                          F.shape[0], ineq, target)
        hess = ca.Function("hess_lag", [w, target, sigma, mult], [H],
                           ["x", "p", "lam_f", "lam_g"], ["triu_hess_gamma_x_x"])
        problem = {"x": w, "p": target, "f": 0.5 * ca.sumsqr(res), "g": g}
        self.lagrangian = (w, target, sigma, mult, problem["f"], g, hess, jac_g)  # (for tests)
        self._jac_g, self._n_eq = jac_g, F.shape[0] + lifted.shape[0]     # (rows of g first)
        load_ipopt()      # (solvers no longer load it on construction: Newton may do without)
        self.nlp = ca.nlpsol("kkt_fit", "ipopt", problem, {
            # the start is an equilibrium, feasible and usually close: a small
            # initial barrier keeps the inactive |eta| bounds from slowing it
            # down (the adaptive update raised it again after warm starts)
            # The midline is only continuous across cell boundaries (the cell
            # polynomials agree in value, not slope): a fit point resting on a
            # node sits on a kink of E_fit(θ), where stationarity stalls (at
            # 1.7e-3 with noisy data, measured).  Stop when the misfit no longer
            # changes (relative to the start's: the objective is scaled to 1
            # there) over 3 iterations while the equilibrium holds to 1e-9.  (1e-8
            # saved bench_fit's noiseless fit 10 iterations, where excursions of the
            # violation to 4e-9 restarted the count, but on the KKT campaign free t02
            # then failed and the campaign took 280 s instead of 230 s, measured.
            # 5 iterations at 1e-10 cost the noiseless fit's fine NLP 8 iterations
            # where 4 do: 1.29 s against 1.04 s, the noisy fits alike; 2026-11-24.)
            "ipopt": {"print_level": PRINT_LEVEL, "sb": "yes", "tol": self.tol,
                      "max_iter": self.max_iter, "mu_init": self.mu_init,
                      "acceptable_tol": 1e-2, "acceptable_iter": 3,
                      "acceptable_obj_change_tol": 1e-9, "obj_scaling_factor": self.scale,
                      "acceptable_constr_viol_tol": 1e-9,
                      "warm_start_init_point": "yes",
                      # A start on a bound of θ (Gauss-Newton steps that ended on a
                      # breakpoint's box) was pushed 1e-3 inside it, off the
                      # equilibrium: violation 4 at the first iterate, and 60
                      # iterations of restoration phases (synthetic KKT campaign,
                      # undeformed t03; converges in 7 from the start as it is).
                      # Starts farther inside are not moved either way.
                      "warm_start_bound_push": 1e-9, "warm_start_bound_frac": 1e-9,
                      "mumps_scaling": 0, "mumps_permuting_scaling": 0, "mumps_pivot_order": 0,
                      # An NLP that needs a large Hessian perturbation has gone wild
                      # (converging ones needed at most 1; unstressed t09 of the synthetic
                      # campaign from t07's fit: up to 1e10, 60 iterations in 347 s, and
                      # MUMPS reallocating; 8 s to fail with this cap): fail, and let
                      # _kkt start again from the reduced optimum.
                      "max_hessian_perturbation": KKT_MAX_PERTURBATION},
            "hess_lag": hess, "jac_g": jac_g, "print_time": False, "error_on_fail": False,
            # (the data's multipliers are never used: CasADi computed them after
            # every solve through the whole graph, and on the KKT campaign warned
            # "Failed to calculate multipliers" where that evaluation failed)
            "calc_lam_p": False,
            # a trial point outside the energy's domain evaluates to NaN and
            # Ipopt backtracks: CasADi's "NaN detected" lines said nothing to act on
            "show_eval_warnings": False})
        self.sizes = (k, d.layout.size, d.g.shape[0])
        self.cells = cells

    @staticmethod
    def _window_indices(cells, nc: int, n: int, idx: np.ndarray) -> tuple:
        """Where each fit point's local unknowns (:func:`_blended_point`) sit in U.

        U = (s at the nodes, x, z and S at the cell boundaries) then the
        pole's three constants; returns the (local × points) indices and the
        points' first/last/keep flags (windows × points).  A point that moves
        beyond its window is evaluated on the window's outermost cell (flagged
        first/last), not on weights that vanish there: with the exact Hessian
        the fine stage stalled at that edge (noisy data: 97 + 165 + 9
        iterations; 30 + 16 with the flags, measured).  It is then rebuilt
        with the point's new cell, as whenever a point leaves its window.
        """
        n_U = (nc + 1) + n + 2 * (nc + 1)
        x_at = np.where(idx < n, (nc + 1) + idx, n_U + idx - n)     # constants after U
        cols, first, last, keep = [], [], [], []
        offsets = range(-WINDOW, WINDOW + 1)
        for c in cells:
            window = [min(max(c + o, 0), nc - 1) for o in offsets]
            cols.append(np.concatenate([x_at[:, window].ravel(order="F"), window,
                                        [i + 1 for i in window],
                                        [(nc + 1) + n + i for i in window],
                                        [2 * (nc + 1) + n + i for i in window],
                                        [2 * (nc + 1) + n + nc]]))
            first.append([float(i == 0 or o == -WINDOW) for o, i in zip(offsets, window)])
            last.append([float(i == nc - 1 or o == WINDOW) for o, i in zip(offsets, window)])
            keep.append([float(o == 0 or i != min(max(c, 0), nc - 1))
                         for o, i in zip(offsets, window)])
        return (np.array(cols, dtype=np.int64).T,
                tuple(np.array(f).T for f in (first, last, keep)))

    def _hessian(self, d, P, th, x, lam, p, q, sh, local, t_fit, flags, u_idx, w, sigma, mult,
                 nF: int, ineq, target) -> ca.MX:
        """Upper triangle of the exact Hessian of the Lagrangian σ ½|res|² + μ·g.

        Gauss–Newton for the misfit plus the inner KKT conditions' curvature
        in (x, λ) only needed 121 + 61 iterations with noisy data (1e-3, 60
        then 200 nodes): its reduced Hessian had an eigenvalue of −2e-3 where
        the exact one has +1.6e-6 (measured at the coarse optimum), the
        misfit's and the constraints' second-order terms, each large, cancel
        (Gauss–Newton alone: +7.6e-7, but 2.7x too small in other weak
        directions, and its steps diverged).  Exact: 25 + 30 + 16 iterations.
        Assembled from per-point and per-cell kernels and the chain rule
        through s_nodes(θ) and D(θ), the kernels compiled (the misfit's, the
        cells' second derivatives in D, and D's in p): 30-40 ms an evaluation
        at 200 nodes, where the same kernels in CasADi's virtual machine and
        the MX Hessian of D(θ) took 160 ms (the MX Hessian of the whole
        Lagrangian: 0.5 s at 60 nodes).
        """
        from ..model.layouts import CELL_DATA

        k, n, m = th.shape[0], x.shape[0], lam.shape[0]
        nc = d.layout.cells
        n_w, n_U, n_pt = w.shape[0], (nc + 1) + n + 2 * (nc + 1), local.shape[1]
        grad, tri = _compiled_misfit(d.stages).map(n_pt)(
            local, ca.DM(t_fit).T, *(ca.DM(f) for f in flags), ca.reshape(target, 2, n_pt))
        # the misfit's Hessian in U (local duplicates of one unknown: a local
        # off-diagonal pair on U's diagonal counts twice)
        n_loc = u_idx.shape[0]
        ku, lu = np.triu_indices(n_loc)
        I, J = np.minimum(u_idx[ku], u_idx[lu]), np.maximum(u_idx[ku], u_idx[lu])
        src = np.arange(len(ku))[:, None] + len(ku) * np.arange(n_pt)[None, :]
        ok = J < n_U
        twice = (I == J) & (ku != lu)[:, None]
        sp, B = d._scatter((n_U, n_U), I[ok], J[ok], src[ok], len(ku) * n_pt,
                           np.where(twice, 2.0, 1.0)[ok])
        Hu = ca.MX(sp, ca.mtimes(B, ca.vec(tri)))
        Hu = Hu + Hu.T - ca.diag(ca.diag(Hu))
        # U in terms of w = (θ, x, λ, z, S): s_nodes(θ), the rest selected
        E = ca.vertcat(ca.horzcat(ca.jacobian(sh.s_nodes, th), ca.MX(nc + 1, n_w - k)),
                       ca.horzcat(ca.MX(n, k), ca.MX.eye(n), ca.MX(n, n_w - k - n)),
                       ca.horzcat(ca.MX(2 * nc + 2, k + n + m), ca.MX.eye(2 * nc + 2)))
        on_s = u_idx < nc + 1
        sp_s, Bs = d._scatter((nc + 1, 1), u_idx[on_s], np.zeros(on_s.sum()),
                              (np.arange(n_loc)[:, None] + n_loc * np.arange(n_pt))[on_s],
                              n_loc * n_pt)
        g_nodes = ca.densify(ca.MX(sp_s, ca.mtimes(Bs, ca.vec(grad))))
        # the constraints: F and the lifted integrals through D(θ) per cell
        D, T, Jp, D_p = self._cell_data_theta(d, th, p, q)
        C, tt, gD = d.kkt_curvature_theta(x, lam, D, T, mult[:nF], mult[nF + 1:nF + 1 + nc],
                                          mult[nF + nc + 2:nF + 2 * nc + 2])
        H_xl = d.kkt_curvature(x, lam, D, mult[:nF], mult[nF + 1:nF + 1 + nc],
                               mult[nF + nc + 2:nF + 2 * nc + 2],
                               sh.s_nodes[1:] - sh.s_nodes[:nc])
        n_eta, n_D = D.shape[0] // len(CELL_DATA), len(CELL_DATA)
        eta_at = CELL_DATA.index("eta") + n_D * np.arange(n_eta)
        mu_ineq = mult[nF + 2 * nc + 2:mult.shape[0] - n_eta]
        # ... and the second derivatives of D, s_nodes and the breakpoint gaps
        # in θ: D's through p (Discretisation.pre_hessian), p's, s_nodes' and
        # the gaps' by an MX Hessian with D's gradient in p (g_p) held fixed
        ci, cs, g_p = (ca.MX.sym(nm, size) for nm, size in
                       (("c_i", len(ineq)), ("c_s", nc + 1), ("g_p", p.shape[0])))
        omega = (ca.dot(g_p, p) + ca.dot(cs, sh.s_nodes)
                 + (ca.dot(ci, ca.vertcat(*ineq)) if ineq else 0))
        rest = ca.Function("theta_curvature", [th, g_p, ci, cs], [ca.hessian(omega, th)[0]])
        c_D = gD + ca.MX(ca.Sparsity.triplet(D.shape[0], 1, eta_at.tolist(), [0] * n_eta),
                         mult[mult.shape[0] - n_eta:])
        H_tt = (tt + ca.mtimes(Jp.T, ca.mtimes(d.pre_hessian(p, q, c_D), Jp))
                + rest(th, ca.mtimes(D_p.T, c_D), mu_ineq, sigma * g_nodes))
        Hw = sigma * ca.mtimes(E.T, ca.mtimes(Hu, E))
        top = ca.horzcat(ca.triu(H_tt), C.T, ca.MX(k, n_w - k - n - m))
        rest = ca.diagcat(H_xl, ca.MX(n_w - k - n - m, n_w - k - n - m))
        return ca.triu(Hw) + ca.vertcat(top, ca.horzcat(ca.MX(n_w - k, k), rest))

    @staticmethod
    def _constraint_jacobian(d, th, x, lam, p, q, w, lifted, ineq):
        """∂g/∂w for g = (F, lifted integrals, breakpoint gaps, η), from local pieces.

        The inner KKT block K = ∂F/∂(x, λ) and ∂F/∂θ = (∂F/∂D) T come from the
        cell kernels, η's rows from T = ∂D/∂θ (computed once); the lifted
        integrals and the gaps are differentiated as they are, each on its own
        (a slice of the assembled g drags all of g into its derivative: 37 ms
        at 200 nodes, and differentiating F through its graph cost ~90 ms,
        measured).
        """
        from ..model.layouts import CELL_DATA

        D, T, *_ = _KKTProblem._cell_data_theta(d, th, p, q)
        Ht = d.hess_lag(x, D, 1, lam)
        J = d.jac_g(x, D)[1]
        K = ca.blockcat([[Ht + Ht.T - ca.diag(ca.diag(Ht)), J.T],
                         [J, ca.MX(J.shape[0], J.shape[0])]])
        k, nxl = th.shape[0], x.shape[0] + lam.shape[0]
        n_rest = w.shape[0] - k - nxl
        top = ca.horzcat(d.kkt_residual_theta(x, lam, D, T), K, ca.MX(nxl, n_rest))
        n_D = len(CELL_DATA)
        eta_rows = (CELL_DATA.index("eta") + n_D * np.arange(D.shape[0] // n_D)).tolist()
        eta = ca.horzcat(T[eta_rows, :], ca.MX(len(eta_rows), w.shape[0] - k))
        return ca.vertcat(top, ca.jacobian(ca.vertcat(lifted, *ineq), w), eta)

    @staticmethod
    def _cell_data_theta(d, th, p, q) -> tuple:
        """D(p(θ)), T = ∂D/∂θ, ∂p/∂θ and ∂D/∂p, for evaluation (no derivatives).

        D and ∂D/∂p from compiled per-point kernels (Discretisation.pre_numeric
        and pre_jacobian): the MX Jacobian of D in θ cost 16 ms an evaluation
        at 200 nodes, twice per iteration (Hessian and constraint Jacobian).
        """
        Jp, D_p = ca.jacobian(p, th), d.pre_jacobian(p, q)
        return d.pre_numeric(p, q), ca.mtimes(D_p, Jp), Jp, D_p

    def _lifted_start(self, theta, x) -> np.ndarray:
        """z and S at the cell boundaries of the state x (gauge: 0 at the first node)."""
        d = self.inner.solver.disc
        p = self.spec.problem(theta).parameter_vector()
        if not hasattr(self, "_points"):
            pts = d.symbolic_points(d.x, d.p, d.q)
            self._points = ca.Function("zS", [d.x, d.p, d.q], [pts["z"], pts["S"]])
        z, S = (np.asarray(v).ravel()[::d.stages] for v in self._points(x, p, np.zeros(0)))
        return np.concatenate([z - z[0], S])

    def _adjoint_duals(self, w0, data) -> tuple | None:
        """The multipliers at w₀ of the reduced problem: its adjoints, (λ_g, λ_x).

        At an equilibrium the equality constraints (F and the lifted
        integrals) are square in the unknowns other than θ: their multipliers
        make the Lagrangian stationary there, ∂f/∂u + (∂g/∂u)ᵀλ = 0, which
        leaves the reduced gradient in θ as the only dual infeasibility.  The
        inequalities (breakpoint gaps, |η|) and θ's bounds start inactive.
        Ipopt's least-squares estimate instead spread the misfit's gradient
        over all rows: from the Gauss–Newton end its first step left the
        equilibrium (violation 2e-12 to 2e-5), and 22 backtracks and the
        restoration phase followed (bench_fit's noisy data, measured).
        """
        from scipy.sparse.linalg import splu

        k, n_eq = self.sizes[0], self._n_eq
        _, grad = self.nlp.get_function("nlp_grad_f")(w0, data)
        J = self._jac_g(w0, data)[1].sparse().tocsc()
        lam_g = np.zeros(J.shape[0])
        try:
            lam_g[:n_eq] = splu(J[:n_eq, k:].T.tocsc()).solve(-np.asarray(grad).ravel()[k:])
        except RuntimeError:        # singular (a fold of the branch): from zero multipliers
            return None
        return (lam_g, np.zeros(J.shape[1])) if np.all(np.isfinite(lam_g)) else None

    def solve(self, cells, theta, x, lam, data=None):
        """One NLP from (θ, x, λ) with the fit points in ``cells``, to ``data`` (default: the fit's)."""
        warm = {}
        if cells != self.cells:
            if self.cells is None:       # the misfit at the start sets the objective's scale
                res = self.inner.residuals(self.inner.eq)
                # (floored: from the Gauss-Newton steps' exact fit of noiseless data,
                # E_fit 2e-8 R, the NLP so scaled failed in restoration; measured)
                self.scale = 1.0 / max(0.5 * float(res @ res), 1e-8)
            self._build(cells)
        w0 = np.concatenate([theta, x, lam, self._lifted_start(theta, x)])
        data = np.asarray(self.inner.data if data is None else data, dtype=float).ravel()
        if self._duals is None and self.from_adjoints:
            self._duals = self._adjoint_duals(w0, data)
        if self._duals is not None:
            # the constraints do not depend on the cells: their multipliers
            # carry over (a cold dual start took wild first steps, measured)
            warm = {"lam_g0": self._duals[0], "lam_x0": self._duals[1]}
        sol = self.nlp(x0=w0, p=data, lbx=self.lbw,
                       ubx=self.ubw, lbg=self.lbg, ubg=self.ubg, **warm)
        self._duals = (np.asarray(sol["lam_g"]).ravel(), np.asarray(sol["lam_x"]).ravel())
        stats = self.nlp.stats()
        status = stats.get("return_status", "unknown")
        if status not in ("Solve_Succeeded", "Solved_To_Acceptable_Level"):
            raise FitError(f"the KKT fit's NLP failed with Ipopt status {status!r} after "
                           f"{stats.get('iter_count')} iterations", status, self.inner.eq)
        w = np.asarray(sol["x"]).ravel()
        k, nx, nl = self.sizes
        return (w[:k], w[k:k + nx], w[k + nx:k + nx + nl], int(stats.get("iter_count", 0)),
                status)
