"""Multiple shooting: a third route to the equilibrium, from the same Pontryagin system.

The Euler–Lagrange (Pontryagin) equations of :mod:`morphoshell.solvers.bvp`,
derived from the energy of :mod:`morphoshell.model.energy`, are integrated as
initial-value problems on M segments of the shell

    a = t_0 < t_1 < … < t_M = b,   a = Σ (+ ε at a pole),  b = L − P (− ε at a pole),

and the unknown initial values are found by Newton-type iterations on the
continuity conditions (Stoer & Bulirsch, *Introduction to Numerical
Analysis*, 3rd ed., §7.3.5; Ascher, Mattheij & Russell, *Numerical Solution
of Boundary Value Problems for ODEs*, 1995, ch. 4).  The state is
:data:`~morphoshell.model.layouts.BVP_STATE`; only its core x = (r, ψ, λ_r, λ_ψ)
is shot: z and the energy are quadratures that do not feed back.

Unknowns and conditions
-----------------------
* start: a free edge has x(a) = (r, ψ, 0, 0), r and ψ unknown; a pole has
  x(a) on the regular local solution with 2 unknown amplitudes C
  (:func:`~morphoshell.solvers.bvp.pole_state`,
  :func:`~morphoshell.solvers.bvp.pole_costates`), exactly as the BVP route;
* the core state at each interior segment start (4 unknowns each);
* end: a free edge demands λ_r = λ_ψ = 0 at b.  A pole puts x(b) on its
  local solution (2 amplitudes); the last segment is then integrated
  *backward* from b and matched at t_{M−1}: integrated toward a pole, the
  singular modes (distance)^(−β) would grow without bound.

The system is square.  ``scipy.optimize.least_squares`` (trust-region
reflective, Jacobian scaling) solves it with the exact Jacobian: the
sensitivities Φ = ∂x(s)/∂x(t_j) follow from the variational equations
Φ' = (∂x'/∂x) Φ, integrated with the states.  Trial points where an
integration fails get non-finite residuals, which shrink the trust region.
From the undeformed shell, Newton's basin can be too small (toy problem 3
with f0 = 0.1 stalls at a residual of 0.09); the route then continues from
the family's stress-free parameters, as ``solve_bvp``'s ``homotopy_steps``
does.

Integrator
----------
``solve_ivp(method="LSODA")`` with the exact Jacobian of the augmented
system.  The equations are stiff near poles (the Euler modes decay like
s^(−β): eigenvalue −β/s, 10⁴ at s = ε) and, on thin shells, through the
decaying partner of each boundary-layer mode exp(±s/δ); elsewhere they are
smooth and non-stiff.  LSODA switches between Adams (order ≤ 12) and BDF
with the exact Jacobian where it detects stiffness, and so takes several
times fewer steps and evaluations than Radau (L-stable, order 5) or BDF on
the toy problems' segments, for the same end state.
``integrator="Radau"`` remains available.

Conditioning
------------
Besides the slow membrane solution, the Hamiltonian system carries the
bending boundary-layer modes exp(±s/δ), δ = (h/√12)^(1/2)
(:func:`~morphoshell.model.energy.boundary_layer_width`).  Over a segment of
length Δs the growing one is amplified by up to exp(Δs/δ) (on the sphere the
largest real part of an eigenvalue of ∂x'/∂x is ≈ 0.66/δ, so the bound is
conservative).  The shooting matrix inherits that factor in its condition
number, integration errors are amplified by it, and, worse, Newton's basin
of attraction shrinks with it: the shooting map is nonlinear on the scale
1/growth.  On toy problem 2 (classical, Σ = 0.5, h = 0.1 … 1e-3, 8 … 64
segments) solves with a growth of a few tens per segment converge from the
undeformed shell, a few hundred need homotopy steps or stall, and ten
thousand fail; the converged solves agree with the direct route to 1e-10.
Hence the number of segments is chosen so that the growth stays below ``max_growth``
(default :data:`MAX_GROWTH` = 20 ≈ e³), and the route *refuses*, with status
:data:`ILL_CONDITIONED`, when

* that takes more than ``max_segments`` segments (default 64: on the unit
  sphere every h < 6.6e-4 with Σ = 0.5, every h < 7.6e-4 with Σ = 0.3), or
  explicit ``segments`` leave a growth above ``max_growth`` (both checked
  before any integration, so a thin shell is refused in milliseconds), or
* the condition number of the row- and column-equilibrated shooting
  Jacobian at the solution exceeds ``max_condition``.

Both messages name the estimate and suggest more segments, or the direct
(:mod:`morphoshell.solvers.direct`) or BVP (:mod:`morphoshell.solvers.bvp`) routes,
whose collocation has no such limit.

Units: lengths in units of R, energies in units of C R² (see
:mod:`morphoshell.model.problem`).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, replace
from functools import lru_cache

import casadi as ca
import numpy as np
import scipy.integrate
import scipy.optimize

from .._runtime.buffered import Buffered
from ..model.energy import CACHE_SIZE, boundary_layer_width
from ..model.layouts import BVP_STATE
from ..model.problem import Problem, Structure
from .bvp import (initial_state, neutral_path, pole_caps, pole_costates, pole_solutions, pole_state,
                  pontryagin_functions, to_equilibrium)
from ..numerics.status import (SHOOTING_ILL_CONDITIONED, SHOOTING_INTEGRATION_FAILED,
                               SHOOTING_NOT_CONVERGED, SHOOTING_SUCCEEDED, TIME_LIMIT_EXCEEDED,
                               explain)
from .options import check_shooting_options
from .results import Equilibrium, SolverError, SolverStats, unconverged

__all__ = ["solve_shooting", "ILL_CONDITIONED", "NOT_CONVERGED", "INTEGRATION_FAILED",
           "MAX_GROWTH", "MAX_SEGMENTS", "MIN_SEGMENTS", "MAX_CONDITION", "MAX_SECONDS"]

#: Status of a refusal: the shooting matrix is (or would be) too ill-conditioned.
ILL_CONDITIONED = SHOOTING_ILL_CONDITIONED
#: Status when the iterations stop short of the tolerance.
NOT_CONVERGED = SHOOTING_NOT_CONVERGED
#: Status when the integration from the initial guess fails.
INTEGRATION_FAILED = SHOOTING_INTEGRATION_FAILED

#: Default bound on exp(Δs/δ), the growth of the boundary-layer mode over one
#: segment (tuned on toy problem 2: the module doc, "Conditioning").
MAX_GROWTH = 20.0

#: Default bound on the number of segments chosen automatically.
MAX_SEGMENTS = 64

#: Fewest segments chosen automatically (they also bound the nonlinearity of
#: each segment's map on thick shells).
MIN_SEGMENTS = 8

#: Default bound on the condition number of the equilibrated shooting
#: Jacobian at the solution.  The residuals are reproducible to ~1e-12
#: (rtol = 1e-10), which this condition could amplify to ~1e-4 in the
#: unknowns at worst; the accurate solves of the toy problems stay well below it.
MAX_CONDITION = 1e8
#: Wall-clock limit of a shooting solve (s; ``max_seconds``): a thin shell's many stiff
#: segments can take minutes to fail, a reference route should say so in seconds.
MAX_SECONDS = 8.0

#: The shot part of the state (z and the energy are quadratures); starts with (r, ψ).
_CORE = ("r", "psi", "lam_r", "lam_psi")
_C = BVP_STATE.indices(_CORE)
_QUAD = BVP_STATE.indices(("z", "energy"))
_LAM = [_CORE.index("lam_r"), _CORE.index("lam_psi")]
_N, _NC = len(BVP_STATE), len(_CORE)

#: Evaluations without halving the residual after which the iterations stop.
_STALL_WINDOW = 10


@dataclass(frozen=True)
class _Settings:
    segments: int
    integrator: str
    rtol: float
    atol: float
    tol: float
    eps: float
    max_evaluations: int
    max_condition: float
    points: int
    deadline: float = math.inf      # time.perf_counter() at which the solve gives up
    seconds: float = math.inf       # (max_seconds, for the message)


def solve_shooting(problem: Problem, *, segments: int | None = None, integrator: str = "LSODA",
                   rtol: float = 1e-10, atol: float = 1e-12, tol: float = 1e-9,
                   pole_offset: float = 1e-4, guess: Equilibrium | None = None,
                   homotopy_steps: int | None = None, max_evaluations: int = 50,
                   max_growth: float = MAX_GROWTH, max_segments: int = MAX_SEGMENTS,
                   max_condition: float = MAX_CONDITION, points: int = 200,
                   max_seconds: float = MAX_SECONDS) -> Equilibrium:
    """Equilibrium of ``problem`` by multiple shooting.

    Parameters
    ----------
    problem : Problem
    segments : int, optional
        M, the number of shooting segments, of equal length in s.  Default:
        the smallest M ≥ 8 whose growth exp(Δs/δ) per segment is at most
        ``max_growth``, i.e. M ≥ (b − a)/(δ ln ``max_growth``).  At least 2
        when the far end is a pole (one segment is shot from each end).
    integrator : {"LSODA", "Radau", "BDF"}
        The ``solve_ivp`` method (stiff-capable; see the module doc).  Not
        called ``method``, which names the route in :func:`morphoshell.solve`.
    rtol, atol : float
        ``solve_ivp`` tolerances on the states and sensitivities.
    tol : float
        Convergence: the largest continuity or boundary residual, relative
        to max(1, the largest core state at the segment starts).
    pole_offset : float
        ε, the distance from a pole at which the integration starts (units of
        R; as in :func:`~morphoshell.solvers.bvp.solve_bvp`).
    guess : Equilibrium, optional
        A solution of any route, interpolated at the segment starts
        (costates from its controls).  Default: the undeformed shell with
        zero costates.
    homotopy_steps : int, optional
        Without a ``guess``: solve along this many steps from the family's
        stress-free parameters, each warm-started from the previous one.
        Default: 1, and if that does not converge 2, 4 and 8.
    max_evaluations : int
        Shooting evaluations (each integrates every segment) per solve; a
        solve also stops when 10 evaluations have not halved the residual.
    max_growth : float
        Bound on the a-priori growth exp(Δs/δ) over a segment: refuse
        explicit ``segments`` above it.
    max_segments : int
        Refuse when the default ``segments`` would exceed it (explicit
        ``segments`` are not bounded).
    max_condition : float
        Refuse when the condition number of the equilibrated shooting
        Jacobian at the solution exceeds it.
    points : int
        The result has at least about this many points: the final
        integration limits its steps to (b − a)/``points``.
    max_seconds : float
        Wall-clock limit of the whole solve (homotopy ladder included):
        beyond it ``Time_Limit_Exceeded`` (:data:`MAX_SECONDS`).

    Returns
    -------
    Equilibrium
        On the integrator's steps, s ∈ [a, b] (a pole's ε excluded, as for
        the BVP route); ``energy`` includes the poles' caps.
        ``solver.method == "shooting"``; ``solver.iterations`` counts the
        shooting evaluations of every attempt and homotopy step;
        ``solver.details`` holds ``residual``, ``condition``,
        ``growth_estimate``, ``segments``, ``homotopy_steps``, ``pole_offset``
        and ``least_squares`` (its message).

    Raises
    ------
    SolverError
        ``.status`` is :data:`ILL_CONDITIONED` when the problem is refused
        (a priori, without a last iterate; or at the solution);
        :data:`NOT_CONVERGED` when the iterations stop short of ``tol``;
        :data:`INTEGRATION_FAILED` when the integration from the initial
        guess fails; ``Time_Limit_Exceeded`` past ``max_seconds`` (whenever
        it passes, the first evaluation of a homotopy step included).
        ``.last_iterate`` (``converged=False``) is attached
        whenever there is one, i.e. except for the a-priori refusal and an
        integration failure; within a homotopy it belongs to that step's
        parameters (see its ``problem``); past the time limit it is the best
        iterate so far (or the step's initial guess), integrated once more.
    ValueError
        ``segments`` too small or not an integer; ``max_growth`` ≤ 1; a tolerance
        or ``pole_offset`` out of its range (``tol`` in [1e-11, 1e-3], ``atol`` in
        [1e-16, 1e-6], ``rtol`` in [1e-14, 1e-6], ``pole_offset`` in [1e-6, 0.1]:
        :mod:`morphoshell.solvers.options`), before any work.
    """
    check_shooting_options(problem, segments=segments, integrator=integrator, rtol=rtol, atol=atol,
                           tol=tol, pole_offset=pole_offset, guess=guess,
                           homotopy_steps=homotopy_steps, max_evaluations=max_evaluations,
                           max_growth=max_growth, max_segments=max_segments,
                           max_condition=max_condition, points=points, max_seconds=max_seconds)
    t0 = time.perf_counter()
    end_pole = problem.structure.end == "pole"
    a, b = _interval(problem, pole_offset)
    delta = boundary_layer_width(problem.h)
    need = max(math.ceil((b - a) / (delta * math.log(max_growth))), 1 + end_pole)
    name = problem.name or problem.family
    if segments is None:
        segments = max(need, MIN_SEGMENTS)
        if segments > max_segments:
            raise SolverError(
                f"shooting refused on {name!r}: the boundary-layer width δ = {delta:.3g} "
                f"(h = {problem.h:g}) needs {segments} segments to keep the growth exp(Δs/δ) "
                f"per segment below max_growth = {max_growth:g}, more than max_segments = "
                f"{max_segments}; the shooting matrix would be ill-conditioned and Newton's "
                f"basin tiny: use the direct or bvp route, or raise max_segments",
                ILL_CONDITIONED)
    elif isinstance(segments, bool) or int(segments) != segments or segments < 1 + end_pole:
        raise ValueError(f"segments = {segments!r} must be an integer >= {1 + end_pole}"
                         + (" (the far end is a pole)" if end_pole else ""))
    growth = _growth_estimate(problem.h, (b - a) / segments)
    if growth > max_growth:
        raise SolverError(
            f"shooting refused on {name!r}: the boundary-layer mode grows by exp(Δs/δ) = "
            f"{growth:.3g} over a segment (Δs = {(b - a) / segments:.4g}, δ = {delta:.4g}), "
            f"above max_growth = {max_growth:g}; use segments >= {need}, or the direct or bvp "
            f"route", ILL_CONDITIONED)
    opts = _Settings(int(segments), integrator, rtol, atol, tol, float(pole_offset),
                     int(max_evaluations), max_condition, int(points), t0 + float(max_seconds),
                     float(max_seconds))

    if guess is not None:
        ladder = [1]
    elif homotopy_steps is not None:
        ladder = [max(1, int(homotopy_steps))]
    else:
        ladder = [1, 2, 4, 8] if problem.family_obj.neutral else [1]
    evaluations = 0   # over every attempt, failed ones included
    for steps in ladder:
        current = guess
        try:
            path = neutral_path(problem, steps)
            for sub in path[:-1] + [problem]:   # the last step is the problem itself
                current = _solve_one(sub, current, opts)
                evaluations += current.solver.iterations
            break
        except SolverError as err:
            if err.last_iterate is not None:
                evaluations += err.last_iterate.solver.iterations
            if err.status in (ILL_CONDITIONED, TIME_LIMIT_EXCEEDED) or steps == ladder[-1]:
                raise
    stats = replace(current.solver, iterations=evaluations, seconds=time.perf_counter() - t0,
                    details={**current.solver.details, "growth_estimate": growth,
                             "homotopy_steps": steps})
    return replace(current, problem=problem, solver=stats)


def _interval(problem: Problem, eps: float) -> tuple[float, float]:
    """[a, b]: the shell less ε next to each pole."""
    st = problem.structure
    return (problem.cut + (eps if st.start == "pole" else 0.0),
            problem.end - (eps if st.end == "pole" else 0.0))


def _growth_estimate(h: float, length: float) -> float:
    """exp(Δs/δ): the a-priori growth of the boundary-layer mode over ``length``."""
    return math.exp(min(length / boundary_layer_width(h), 700.0))


def _equilibrated_condition(J: np.ndarray) -> float:
    """2-norm condition number of ``J`` after scaling rows, then columns, to unit max-norm.

    Unknowns and residuals mix lengths, angles and costates of different
    sizes (λ ∝ h); equilibration removes that artificial part of cond(J).
    """
    if not np.all(np.isfinite(J)):
        return math.inf
    rows = np.max(np.abs(J), axis=1, keepdims=True)
    J = J / np.where(rows > 0, rows, 1.0)
    cols = np.max(np.abs(J), axis=0, keepdims=True)
    return float(np.linalg.cond(J / np.where(cols > 0, cols, 1.0)))


@lru_cache(maxsize=CACHE_SIZE)
def _variational_functions(structure: Structure) -> tuple[ca.Function, ca.Function]:
    """``(f, J)`` of the augmented state X = (y, vec Φ), y ∈ BVP_STATE, Φ (4 × 4).

    X' = f(s, X, p) = (y', (∂x'/∂x) Φ), x the core of y, and J = ∂f/∂X
    (dense), both from :func:`~morphoshell.solvers.bvp.pontryagin_functions`.
    """
    F = pontryagin_functions(structure)
    s = ca.SX.sym("s")
    p = ca.SX.sym("p", len(structure.parameters))
    y = ca.SX.sym("y", _N)
    Phi = ca.SX.sym("Phi", _NC, _NC)
    dy = F["rhs"](s, y, p)
    if ca.depends_on(dy[_C], y[_QUAD]):   # shooting only the core assumes this
        raise AssertionError("the core equations depend on z or the energy")
    f = ca.vertcat(dy, ca.vec(F["jac"](s, y, p)[_C, _C] @ Phi))
    X = ca.vertcat(y, ca.vec(Phi))
    return (ca.Function("shooting_rhs", [s, X, p], [f]),
            ca.Function("shooting_jac", [s, X, p], [ca.densify(ca.jacobian(f, X))]))


class _IntegrationFailed(RuntimeError):
    pass


class _Stalled(RuntimeError):
    pass


class _TimeUp(RuntimeError):
    pass


@dataclass
class _Segment:
    """One integration from an anchor: points s (m), states Y (6 × m), far-end Φ (4 × 4)."""

    s: np.ndarray
    Y: np.ndarray
    Phi: np.ndarray

    @property
    def end(self) -> np.ndarray:
        """The core state (4,) where the integration ended."""
        return self.Y[_C, -1]


class _Shooting:
    """The shooting equations of one problem: unknowns, residual, Jacobian, result.

    Unknowns u = [q_start (2), x_1 … x_{n−1} (4 each), q_end (2, far pole only)],
    n the number of forward segments (M, or M − 1 before a far pole).
    """

    def __init__(self, problem: Problem, opts: _Settings):
        st = problem.structure
        self.problem, self.opts = problem, opts
        self.start_pole, self.end_pole = st.start == "pole", st.end == "pole"
        self.a, self.b = _interval(problem, opts.eps)
        self.nodes = np.linspace(self.a, self.b, opts.segments + 1)
        self.n_forward = opts.segments - self.end_pole
        self.n = 2 + _NC * (self.n_forward - 1) + 2 * self.end_pole
        self.p = problem.parameter_vector()
        self.poles = pole_solutions(problem)
        self.F = pontryagin_functions(st)
        # Bound to preallocated arrays: a plain CasADi call spends most of its time converting.
        f, J = (Buffered(g) for g in _variational_functions(st))
        n_aug = _N + _NC * _NC
        self._fun = lambda s, X: f(s, X, self.p)[0]
        self._jac = lambda s, X: J(s, X, self.p)[0].reshape(n_aug, n_aug, order="F")

    # -- anchors ------------------------------------------------------------------------
    def anchor(self, where: str, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Core state at a (``"start"``) or b (``"end"``) from q, and ∂x/∂q (4 × 2)."""
        if where == "start" and not self.start_pole:
            x = np.zeros(_NC)
            x[:2] = q   # free edge: (r, ψ) unknown, λ_r = λ_ψ = 0
            return x, np.eye(_NC, 2)
        pole, eps = self.poles[where], self.opts.eps

        def on_pole(C):
            r, psi = pole_state(pole, where, C, eps)[:2]
            return np.concatenate([[r, psi], pole_costates(self.problem, pole, where, C, eps)])

        # A closed form: central differences are accurate to ~1e-10, plenty for a Jacobian.
        h = 1e-6 * np.maximum(1.0, np.abs(q))
        D = np.column_stack([(on_pole(q + h[k] * e) - on_pole(q - h[k] * e)) / (2 * h[k])
                             for k, e in enumerate(np.eye(2))])
        return on_pole(q), D

    def initial(self, guess: Equilibrium | None) -> np.ndarray:
        """u from ``guess`` (or the undeformed shell) interpolated at the segment starts."""
        Y = initial_state(self.nodes, self.problem.geometry_obj, guess, self.F["costates"], self.p)
        r, psi = Y[_C[0]], Y[_C[1]]
        eps = self.opts.eps
        u = [self.poles["start"].fit(eps, r[0], psi[0]) if self.start_pole else [r[0], psi[0]]]
        u += [Y[_C, j] for j in range(1, self.n_forward)]
        if self.end_pole:
            u.append(self.poles["end"].fit(eps, r[-1], np.pi - psi[-1]))
        return np.concatenate(u)

    # -- integration ----------------------------------------------------------------------
    def integrate(self, s0: float, s1: float, x0: np.ndarray, max_step: float) -> _Segment:
        """From core state ``x0`` at s0 (z = 𝓔 = 0, Φ = I) to s1 (either direction)."""
        y0 = np.zeros(_N)
        y0[_C] = x0
        X0 = np.concatenate([y0, np.eye(_NC).ravel(order="F")])
        o = self.opts
        sol = scipy.integrate.solve_ivp(self._fun, (s0, s1), X0, method=o.integrator,
                                        jac=self._jac, rtol=o.rtol, atol=o.atol,
                                        max_step=max_step)
        if sol.status != 0 or not np.all(np.isfinite(sol.y[:, -1])):
            raise _IntegrationFailed(f"on [{s0:.6g}, {s1:.6g}]: {sol.message}")
        return _Segment(sol.t, sol.y[:_N], sol.y[_N:, -1].reshape(_NC, _NC, order="F"))

    def shoot(self, u: np.ndarray, max_step: float = np.inf):
        """Residual (n), Jacobian (n × n) and segments (forward, then the backward one)."""
        nf, n = self.n_forward, self.n
        x0, D0 = self.anchor("start", u[:2])
        starts = [x0, *u[2:2 + _NC * (nf - 1)].reshape(nf - 1, _NC)]
        segs = [self.integrate(self.nodes[j], self.nodes[j + 1], starts[j], max_step)
                for j in range(nf)]
        res, J = np.zeros(n), np.zeros((n, n))

        def columns(j):   # unknowns of anchor j, and ∂(anchor state)/∂(unknowns)
            return (slice(0, 2), D0) if j == 0 else \
                (slice(2 + _NC * (j - 1), 2 + _NC * j), np.eye(_NC))

        for j in range(nf - 1):               # continuity at t_{j+1}
            rows = slice(_NC * j, _NC * (j + 1))
            res[rows] = segs[j].end - starts[j + 1]
            cols, D = columns(j)
            J[rows, cols] = segs[j].Phi @ D
            J[rows, columns(j + 1)[0]] = -np.eye(_NC)
        rows = slice(_NC * (nf - 1), n)
        cols, D = columns(nf - 1)
        if self.end_pole:                     # match the backward segment at t_{M−1}
            xb, Db = self.anchor("end", u[-2:])
            back = self.integrate(self.b, self.nodes[-2], xb, max_step)
            segs.append(back)
            res[rows] = segs[nf - 1].end - back.end
            J[rows, cols] = segs[nf - 1].Phi @ D
            J[rows, n - 2:] = -back.Phi @ Db
        else:                                 # free far edge: λ_r = λ_ψ = 0
            res[rows] = segs[-1].end[_LAM]
            J[rows, cols] = (segs[-1].Phi @ D)[_LAM]
        return res, J, segs

    # -- result -----------------------------------------------------------------------------
    def assemble(self, segs: list[_Segment], u: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
        """Points (increasing), states (6 × m) and the far cap's energy.

        Each segment carries z and 𝓔 from zero at its anchor; they are offset
        so that z(Σ) = z₀(Σ) (the start cap's rise included at a pole) and 𝓔
        starts with the start cap's energy, as in the BVP route.  The backward
        segment is reversed and joined at its matching point.
        """
        pr, eps = self.problem, self.opts.eps
        z0 = float(pr.geometry_obj.numeric(pr.cut)[1])
        if self.start_pole:
            cap_energy, cap_dz = pole_caps(pr, self.poles["start"], "start", u[:2], eps)
            offset = np.array([z0 + cap_dz, cap_energy])
        else:
            offset = np.array([z0, 0.0])
        forward = segs[:self.n_forward]
        s_parts, Y_parts = [], []
        for k, seg in enumerate(forward):
            Y = seg.Y.copy()
            Y[_QUAD] += offset[:, None]
            offset = Y[_QUAD, -1]
            last = k == len(forward) - 1 and not self.end_pole
            s_parts.append(seg.s if last else seg.s[:-1])   # the next segment starts there
            Y_parts.append(Y if last else Y[:, :-1])
        end_energy = 0.0
        if self.end_pole:
            back = segs[-1]
            Y = back.Y[:, ::-1].copy()
            Y[_QUAD] += (offset - Y[_QUAD, 0])[:, None]
            Y[_C, 0] = forward[-1].end   # the matching point, from the forward side
            s_parts.append(back.s[::-1])
            Y_parts.append(Y)
            end_energy = pole_caps(pr, self.poles["end"], "end", u[-2:], eps)[0]
        return np.concatenate(s_parts), np.concatenate(Y_parts, axis=1), end_energy


def _evaluator(sh: "_Shooting", opts: _Settings, cache: dict):
    """The residual and Jacobian at u, cached (least_squares asks for them separately);
    raises :class:`_TimeUp` past the deadline and :class:`_Stalled` when stalled."""
    def evaluate(u):
        if time.perf_counter() > opts.deadline:
            raise _TimeUp
        if cache.get("u") is None or not np.array_equal(cache["u"], u):
            try:
                res, J, _ = sh.shoot(u)
            except _IntegrationFailed:
                res, J = np.full(sh.n, np.nan), np.full((sh.n, sh.n), np.nan)
            cache.update(u=u.copy(), res=res, J=J)
            norm = float(np.linalg.norm(res)) if np.all(np.isfinite(res)) else math.inf
            history = cache["history"]
            if not history or norm < min(history):
                cache["best"] = u.copy()
            history.append(norm)
            # Stalled in a local minimum of |F|: STALL_WINDOW evaluations without
            # halving the residual (Newton's convergence would be quadratic).
            if (len(history) > _STALL_WINDOW and norm > opts.tol
                    and min(history[-_STALL_WINDOW:]) > 0.5 * min(history[:-_STALL_WINDOW])):
                raise _Stalled
        return cache
    return evaluate


def _iterate(evaluate, u0: np.ndarray, opts: _Settings, cache: dict,
             name: str) -> tuple[np.ndarray, str]:
    """Newton's (trust-region) iterations from ``u0``: the last iterate and how they ended."""
    if not np.all(np.isfinite(evaluate(u0)["res"])):
        raise SolverError(f"shooting on {name!r}: the integration from the initial guess failed: "
                          f"{explain(INTEGRATION_FAILED)}", INTEGRATION_FAILED)
    try:
        # xtol ends the iterations once Newton's steps reach the integration
        # noise (smaller values only add rejected steps); tol is checked below.
        sol = scipy.optimize.least_squares(lambda u: evaluate(u)["res"], u0,
                                           jac=lambda u: evaluate(u)["J"], method="trf",
                                           x_scale="jac", xtol=1e-10, ftol=1e-15, gtol=1e-15,
                                           max_nfev=opts.max_evaluations)
        return sol.x, sol.message
    except _Stalled:
        return cache["best"], (f"stalled at residual {min(cache['history']):.3g} for "
                               f"{_STALL_WINDOW} evaluations (a local minimum of the residual "
                               f"norm)")


def _time_up(problem: Problem, sh: "_Shooting", opts: _Settings, cache: dict, u0: np.ndarray,
             t0: float) -> SolverError:
    """The error of a solve past its deadline, with the best iterate so far (or the initial
    guess) as its last iterate when one more integration there succeeds."""
    name = problem.name or problem.family
    evaluations = len(cache["history"])
    try:
        last = unconverged(_result(problem, sh, cache.get("best", u0), opts, "time limit",
                                   evaluations, t0, dense=False)[0])
    except SolverError:
        last = None
    return SolverError(
        f"shooting on {name!r} stopped at its time limit (max_seconds = {opts.seconds:g} s) "
        f"after {evaluations} evaluations of its {opts.segments} segments: a thin shell's "
        f"stiff boundary layer makes every integration slow, and a loaded machine too; use "
        f"the direct or bvp route, or raise max_seconds (solve(..., method='shooting', "
        f"max_seconds=...))", TIME_LIMIT_EXCEEDED, last)


def _result(problem: Problem, sh: "_Shooting", u: np.ndarray, opts: _Settings, message: str,
            evaluations: int, t0: float, dense: bool = True) -> tuple[Equilibrium, str, float]:
    """The equilibrium at the unknowns ``u`` (converged or not, see its status), its status
    and its residual; integrated once more, densely (``dense``) for a result."""
    name = problem.name or problem.family
    max_step = (sh.b - sh.a) / max(opts.points, 1) if dense else np.inf
    try:
        res, J, segs = sh.shoot(u, max_step=max_step)
    except _IntegrationFailed as err:
        raise SolverError(f"shooting on {name!r}: the integration at the last iterate failed "
                          f"({err}): {explain(INTEGRATION_FAILED)}", INTEGRATION_FAILED) from None
    scale = max(1.0, float(np.max(np.abs([seg.Y[_C, 0] for seg in segs]))))
    residual = float(np.max(np.abs(res))) / scale
    condition = _equilibrated_condition(J)
    converged = residual <= opts.tol
    status = (SHOOTING_SUCCEEDED if converged and condition <= opts.max_condition
              else ILL_CONDITIONED if converged else NOT_CONVERGED)
    s, Y, end_energy = sh.assemble(segs, u)
    details = {"residual": residual, "condition": condition, "segments": opts.segments,
               "pole_offset": opts.eps, "least_squares": message}
    stats = SolverStats("shooting", evaluations, time.perf_counter() - t0, status, len(s),
                        0.0, details)
    eq = to_equilibrium(problem, s, Y, sh.p, sh.F["controls_vec"], sh.F["local"], end_energy,
                        stats, status == SHOOTING_SUCCEEDED)
    return eq, status, residual


def _solve_one(problem: Problem, guess: Equilibrium | None, opts: _Settings) -> Equilibrium:
    """One shooting solve from ``guess``; raises SolverError (with the last iterate)."""
    t0 = time.perf_counter()
    sh = _Shooting(problem, opts)
    name = problem.name or problem.family
    cache: dict = {"history": []}
    u0 = sh.initial(guess)
    try:     # (the deadline may pass at the first evaluation, at u0, too)
        u, message = _iterate(_evaluator(sh, opts, cache), u0, opts, cache, name)
    except _TimeUp:
        raise _time_up(problem, sh, opts, cache, u0, t0) from None
    evaluations = len(cache["history"])
    eq, status, residual = _result(problem, sh, u, opts, message, evaluations, t0)
    if status == NOT_CONVERGED:
        raise SolverError(
            f"shooting did not converge on {name!r}: residual {residual:.3g} > tol = "
            f"{opts.tol:.3g} after {evaluations} evaluations ({message}); status {status}: "
            f"{explain(status)}; the last iterate is attached (.last_iterate)", status,
            unconverged(eq))
    if status == ILL_CONDITIONED:
        raise SolverError(
            f"shooting refused on {name!r}: the equilibrated shooting Jacobian has condition "
            f"number {eq.solver.details['condition']:.3g} > max_condition = "
            f"{opts.max_condition:.3g}; use more segments, or the direct or bvp route; status "
            f"{status}; the last iterate is attached (.last_iterate)", status, unconverged(eq))
    return eq
