"""The direct route: minimise the discretised energy with Ipopt.

:class:`DirectSolver` joins a transcription (:mod:`morphoshell.numerics.discretisation`,
on a mesh of :mod:`morphoshell.numerics.mesh`) and a back end (:mod:`morphoshell.numerics.ipopt`)
for one structure and mesh, built once, and re-solves it for new parameter
values, warm-started from a previous :class:`~morphoshell.solvers.results.Equilibrium`:
continuation and fitting call it thousands of times.

Nothing unconverged is returned: an Ipopt failure raises
:class:`~morphoshell.numerics.status.SolverError` naming Ipopt's status, a converged
stationary point that is not a local minimum (a saddle, which interior-point
methods can report as success) raises
:class:`~morphoshell.numerics.status.NotAMinimumError`; both carry the last iterate.
"""
from __future__ import annotations

import logging
import time
import weakref
from contextlib import contextmanager
from typing import Any, Iterator, Mapping

import numpy as np

from ..model.energy import boundary_layer_width, intrinsic_values, kinematics
from ..model.problem import Problem, Structure
from ..numerics import Discretisation
from ..numerics.ipopt import IpoptBackend
from ..numerics.mesh import MeshSpec, pole_exponent
from ..numerics.newton import NewtonBackend
from ..numerics.status import MERIDIAN_CROSSES_AXIS, NOT_A_MINIMUM, explain
from .options import DIRECT_TOL, check_direct_options, thin_shell_first
from .poles import weakly_singular
from .results import (FIELDS, Equilibrium, NotAMinimumError, Quadrature, SolverError, SolverStats,
                      unconverged)

__all__ = ["DirectSolver", "default_mesh", "solver_of", "check_nodes", "MAX_NODES", "POLE_ZONE",
           "pole_crossing", "axis_crossing", "crossing_why"]

log = logging.getLogger(__name__)

#: Most mesh nodes a direct solver accepts.  ``solve()``'s peak memory and time grow about
#: linearly with the nodes, so this many fit in memory for the toy problems and the Volvox
#: shells alike; a Volvox shell's continuation takes minutes (docs/benchmarks.md,
#: "solvers/direct.py").
MAX_NODES = 102400

#: Largest tolerance of Ipopt's iterative refinement (``residual_ratio_max``;
#: Ipopt's default 1e-10 grows with the square of the points, as ``tol``).
#: The backward error of the KKT solves has a round-off floor that grows
#: with the mesh: above it refinement fails, and Ipopt then re-factorises the
#: same matrix with a larger pivot tolerance and refines again, every
#: iteration (tuned on toy problem 3 and the Volvox shell, 12 800 to 102 400
#: nodes).  An inexact step only slows Newton's convergence (by a factor ~ the ratio
#: per iteration); the solution is judged on the KKT error.  The cap stays
#: two decades below ``residual_ratio_singular`` (1e-5), where Ipopt would
#: take the matrix for singular.
RESIDUAL_RATIO_CAP = 1e-7

#: Distance from a weakly singular pole (units of R) within which r < 0 is the model's own
#: local solution and not refused (:meth:`DirectSolver._axis_crossing`): the reference
#: routes' default pole offset ε, inside which they too take the local solution as it is.
#: The thick spheres' crossings lie far inside it (docs/benchmarks.md, "solvers/direct.py");
#: elsewhere r < 0 is refused.
POLE_ZONE = 1e-4

#: Counts every DirectSolver built in this process (see ``morphoshell.solvers.routes.cache_info``).
BUILDS = {"count": 0}


def check_nodes(nodes) -> int:
    """``nodes`` as an int, or ValueError unless it is an integer in [5, MAX_NODES]."""
    if isinstance(nodes, bool) or not isinstance(nodes, (int, np.integer)) or \
            not 5 <= nodes <= MAX_NODES:
        raise ValueError(f"nodes = {nodes!r} must be an integer in [5, {MAX_NODES}]")
    return int(nodes)


def default_mesh(structure: Structure, nodes: int, stages: int = 2,
                 grading_width: float | None = None, domain_length: float | None = None,
                 edge_scale: float | None = None) -> MeshSpec:
    """Mesh of a solver built without a problem at hand.

    Grading for the boundary layer of ``grading_width`` (default δ of
    h = 0.1) on a shell of ``domain_length`` (default the whole meridian);
    ``edge_scale``, a free edge's distance from the axis, adds logarithmic
    grading there when below the width.

    Returns
    -------
    MeshSpec
    """
    width = boundary_layer_width(0.1) if grading_width is None else float(grading_width)
    length = structure.geometry.length if domain_length is None else float(domain_length)
    return MeshSpec(int(nodes), structure.start, structure.end, width / length,
                    None if edge_scale is None else float(edge_scale) / length,
                    pole_exponent(stages))


def _closing(eq: Equilibrium, crossing: tuple[float, float]) -> str:
    """What a crossing at the cut edge means: the hole closes (the edge reaches the axis),
    which the model, having no contact with the axis, cannot follow; "" elsewhere."""
    if eq.s[0] <= 0 or crossing[1] > eq.s[0] + 1e-9 * (eq.s[-1] - eq.s[0]):
        return ""
    return (f"; here the cut edge (s = {eq.s[0]:.6g}) reaches the axis: the hole closes, "
            f"which the model (no contact with the axis) cannot follow: a wider cut, a thinner "
            f"shell or a smaller intrinsic stretch or curvature keeps it open")


def _singular_pole(eq: Equilibrium, crossing: tuple[float, float]) -> str:
    """What a crossing near a weakly singular pole but beyond :data:`POLE_ZONE` may mean: the
    model's own local solution crossing the axis that far out (h = 0.9, k = 2: out to
    5e-4 R), which the reference routes, starting ε from the pole, do not look at; "" else.

    A finer mesh does not help there: it resolves the model's own crossing, which stays
    where it is (toy 2 at h = 0.3, k = 6: 1.2e-4 R from the far pole on 200 nodes, 1.03e-4
    on 800), and a wider zone only moves the failure (kept out to 1e-3 R, the continuation
    stopped at 0.984 instead of 0.938 of the way, the crossing growing to 8.5e-4 R).  So the
    text leads with the route that solves such shells.
    """
    problem, s = eq.problem, crossing[1]
    for where, beta in weakly_singular(problem).items():
        d = s - problem.cut if where == "start" else problem.end - s
        if d <= 100 * POLE_ZONE:
            return (f"{d:.3g} R from the {where} pole, whose local solution ~ s^{beta:.3g} is "
                    f"weakly singular and may itself cross the axis that far out on a shell "
                    f"this thick (h = {problem.h:g}), beyond the {POLE_ZONE:g} R where the "
                    f"direct route keeps such a crossing: use method=\"bvp\" (--method bvp), "
                    f"which starts {POLE_ZONE:g} R off the pole and solves such shells (a "
                    f"finer mesh resolves the model's own crossing and does not help)")
    return ""


def axis_crossing(eq: Equilibrium) -> tuple[float, float] | None:
    """(r, s) where ``eq``'s meridian crosses the axis as the direct route refuses it (the
    most negative r outside :data:`POLE_ZONE` of a weakly singular pole), else None: the
    check :meth:`DirectSolver.solve` makes of every solution, for other routes' states
    (the points of a branch)."""
    return DirectSolver._axis_crossing(eq)


def crossing_why(eq: Equilibrium, crossing: tuple[float, float]) -> str:
    """Why ``eq``, crossing the axis at ``crossing`` (:func:`axis_crossing`), is refused, and
    what helps: the message :meth:`DirectSolver.solve` gives (next to a weakly singular pole
    the generic remedies do not help: bvp first)."""
    pole = _singular_pole(eq, crossing)
    return (f"the meridian crosses the axis {pole}" if pole else
            f"{explain(MERIDIAN_CROSSES_AXIS)}{_closing(eq, crossing)}")


def pole_crossing(eq: Equilibrium) -> str:
    """Where ``eq`` crosses the axis next to a weakly singular pole, beyond
    :data:`POLE_ZONE`, and what to do (the direct route refuses it; a finer mesh does not
    help); "" if it does not.  For the messages of a continuation stopped by such a
    crossing."""
    crossing = DirectSolver._axis_crossing(eq)
    return "" if crossing is None else _singular_pole(eq, crossing)


class DirectSolver:
    """Direct energy minimisation for one structure and mesh, built once.

    Parameters
    ----------
    structure : Structure
        Geometry, profile family, theory and end types (``Problem.structure``).
    nodes : int
        Number of mesh nodes N (N − 1 cells).
    stages : int
        Gauss points per cell S: the scheme has order 2S (see
        :mod:`morphoshell.numerics.discretisation`).  1 is the staggered midpoint
        scheme (second order); 2 (default) is fourth order; 3 sixth order.
    mesh : MeshSpec, optional
        The mesh (see :func:`morphoshell.numerics.mesh.mesh_spec`); overrides ``nodes``
        and the grading arguments.
    grading_width, domain_length, edge_scale : float, optional
        Grading when no ``mesh`` is given (see :func:`default_mesh`).  The
        mesh stays valid for any h, Σ and P: they are NLP parameters.
    linear_solver, max_iter, stability, ipopt_options
        Passed to :class:`morphoshell.numerics.ipopt.IpoptBackend`: a linear solver of
        :data:`~morphoshell.numerics.ipopt_options.LINEAR_SOLVERS` that Ipopt can load,
        ``max_iter`` ≥ 1 (Ipopt's iterations, not the Newton back end's, below), and
        options that Ipopt accepts, all checked before the build
        (:func:`~morphoshell.numerics.ipopt_options.check_ipopt_options`).
    newton : bool
        Solves first try :class:`morphoshell.numerics.newton.NewtonBackend`: Newton
        steps certified by their own factorisation, several times faster than
        an Ipopt call; whatever it cannot certify within a few steps goes to Ipopt.
        From a warm start (``warm_start`` or ``lam_g0`` given) only with
        ``stability = "auto"``; from the undeformed shell (cold) also only
        with the default ``linear_solver`` and no ``ipopt_options``, and
        only while every step is one Ipopt would take unmodified (see
        :mod:`morphoshell.numerics.newton`, "Cold starts"), so Ipopt is set up only
        when needed.
    tol : float
        In (0, 1e-4] (:data:`~morphoshell.solvers.options.MAX_DIRECT_TOL`, which says why):
        Ipopt's convergence tolerance (on the scaled KKT error) at N = 800;
        it grows like the square of the number of points on finer meshes, as
        does the round-off floor of the discrete gradient.  So does the tolerance of Ipopt's
        iterative refinement of each linear solve (``residual_ratio_max``,
        Ipopt's 1e-10 up to 800 points, at most :data:`RESIDUAL_RATIO_CAP`).
        The status is kept in ``Equilibrium.solver.status``.

    Raises
    ------
    ValueError
        An option out of its range, or one that Ipopt refuses, named with its
        value (:func:`~morphoshell.solvers.options.check_direct_options`).
    TypeError
        A ``structure`` that is not a Structure (a Problem, say).
    """

    def __init__(self, structure: Structure, nodes: int = 200, *, stages: int = 2,
                 mesh: MeshSpec | None = None, grading_width: float | None = None,
                 domain_length: float | None = None, edge_scale: float | None = None,
                 linear_solver: str = "mumps", tol: float = DIRECT_TOL, max_iter: int = 500,
                 stability: str = "auto", ipopt_options: Mapping[str, Any] | None = None,
                 newton: bool = True):
        # every option before the mesh and the transcription are built
        if not isinstance(structure, Structure):
            raise TypeError(f"structure must be a Structure, a Problem's .structure (pass "
                            f"problem.structure), not a {type(structure).__name__}")
        check_direct_options(stages=stages, linear_solver=linear_solver, tol=tol,
                             max_iter=max_iter, stability=stability, ipopt_options=ipopt_options)
        if mesh is None:
            check_nodes(nodes)
            mesh = default_mesh(structure, int(nodes), stages, grading_width, domain_length,
                                edge_scale)
        t0 = time.perf_counter()
        self.structure = structure
        self.mesh = mesh
        self.nodes = mesh.nodes
        self.stages = int(stages)
        self.linear_solver = linear_solver
        self.t = mesh.nodes_t()
        self.disc = d = Discretisation(structure, self.t, self.stages, mesh.knots)
        growth = max(1.0, (d.layout.points / 800) ** 2)
        self.backend = IpoptBackend(
            d, tol=float(tol) * growth, max_iter=max_iter, linear_solver=linear_solver,
            stability=stability, ipopt_options={
                "residual_ratio_max": min(RESIDUAL_RATIO_CAP, 1e-10 * growth),
                **(ipopt_options or {})})
        self.tol = self.backend.tol
        self.stability = stability
        # Newton needs the minimum certificate it provides: with stability
        # "off" or "exact" the caller asked for Ipopt's own handling; so does
        # a cold solve with a linear solver or options of the caller's choice
        self.newton = bool(newton) and stability == "auto"
        self._cold_newton = self.newton and linear_solver == "mumps" and not ipopt_options
        self._newton = None
        self.build_seconds = time.perf_counter() - t0
        BUILDS["count"] += 1

    # ------------------------------------------------------------------
    def check(self, problem: Problem) -> None:
        """Raise ValueError unless ``problem`` has this solver's structure."""
        if problem.structure != self.structure:
            raise ValueError(f"this solver is built for {self.structure}, "
                             f"not for {problem.structure}")

    def solve(self, problem: Problem, warm_start: Equilibrium | None = None,
              x0: np.ndarray | None = None, lam_g0: np.ndarray | None = None,
              anchors=()) -> Equilibrium:
        """Equilibrium of ``problem``, optionally warm-started.

        Parameters
        ----------
        problem : Problem
            Must have this solver's structure; any parameter values.
        warm_start : Equilibrium, optional
            A previous solution on this solver (continuation, fitting).  One of
            another mesh or route is carried onto this mesh by interpolation
            (:meth:`carried`), without its multipliers.
        x0, lam_g0 : ndarray, optional
            Raw initial iterate and multipliers (override ``warm_start``).
        anchors : sequence of float
            Material points of the mesh's knots (``mesh.knots``), increasing.

        Returns
        -------
        Equilibrium
            A certified strict local minimum whose meridian stays off the axis;
            ``solver.status`` says which back end converged.

        Raises
        ------
        SolverError
            Ipopt did not converge (``.status`` is Ipopt's return status), or
            converged to a meridian that crosses the axis
            (``"Meridian_Crosses_Axis"``).
        NotAMinimumError
            Ipopt converged to a saddle (``"Not_A_Minimum"``).
        """
        self.check(problem)
        p = problem.parameter_vector()
        q = self.disc.check_anchors(p, anchors)
        origin = None
        if warm_start is not None and x0 is None:
            x0, lam_g0, origin = self._warm(warm_start, p, q)
        if x0 is None:
            x0 = self.disc.initial_guess(p, q)
        D = self.disc.cell_data(p, q)
        cold = lam_g0 is None
        lam0 = np.zeros(self.disc.constraints) if cold else lam_g0
        res = None
        if self._cold_newton if cold else self.newton:      # Newton first
            if self._newton is None:
                self._newton = NewtonBackend(self.disc, tol=self.tol,
                                             acceptable_tol=self.backend.acceptable_tol)
            res = self._newton.solve(x0, self.disc.pre_numeric(p, q), lam0, at=(p, q),
                                     origin=origin, cold=cold)
        if res is None:
            res = self.backend.solve(x0, D, lam0, data=lambda: self.disc.pre_numeric(p, q))
        stats = SolverStats("direct", res.iterations, res.seconds, res.status, self.nodes,
                            self.build_seconds, res.details)
        eq = self.equilibrium(problem, res.x, res.lam_g, p, q, D, stats, converged=res.converged)
        if not res.converged:
            raise SolverError(thin_shell_first(problem, self.backend.failure_message(
                problem.name or problem.family, res)), res.status, eq)
        crossing = self._axis_crossing(eq)
        if crossing is not None:
            raise SolverError(
                f"Ipopt converged ({res.status}) to r = {crossing[0]:.3g} at s = "
                f"{crossing[1]:.6g}: {crossing_why(eq, crossing)}. The iterate is attached "
                f"(.last_iterate)",
                MERIDIAN_CROSSES_AXIS, unconverged(eq))
        if not res.is_minimum:
            raise NotAMinimumError(
                f"Ipopt converged ({res.status}) to a stationary point where Ipopt needs an "
                f"inertia correction {res.details['inertia_correction']:.3g}: "
                f"{explain(NOT_A_MINIMUM)}. The saddle is attached (.last_iterate)",
                NOT_A_MINIMUM, unconverged(eq))
        return eq

    @contextmanager
    def aside(self) -> Iterator[None]:
        """Solves within leave this solver as they found it: the Newton back end's systems
        kept for chord steps (:meth:`NewtonBackend.unchanged`), so that a check's solve
        does not change the next solve's iterations or last bits."""
        newton = self._newton
        if newton is None:
            try:
                yield
            finally:
                self._newton = None
            return
        with newton.unchanged():
            yield

    def _warm(self, eq: Equilibrium, p: np.ndarray, q: np.ndarray) -> tuple:
        """(x₀, λ₀, origin) of the warm start ``eq``: its unknowns and multipliers, and its
        parameters for Newton's chord step; a state of another mesh is carried onto this
        one (read through this mesh, its x would put each node's r and ψ at another s)."""
        if not self.made(eq):
            return self.carried(eq, p, q), None, None
        origin = None
        if eq.problem.structure == self.structure and len(eq.anchors) == self.disc.anchors:
            p_w = eq.problem.parameter_vector()
            q_w = np.asarray(eq.anchors, dtype=float)
            origin = (p_w, q_w, lambda: self.disc.pre_numeric(p_w, q_w))
        return eq.x, eq.lam_g, origin

    def made(self, eq: Equilibrium) -> bool:
        """Whether ``eq`` is a state of this solver's mesh: solved by it or by a solver of
        the same mesh (a direct solution; False for other routes' results)."""
        source = eq.source
        return source is not None and eq.x is not None and (
            source[0]() is self or source[1] == self.mesh and source[2] == self.stages)

    def carried(self, eq: Equilibrium, p: np.ndarray, q=()) -> np.ndarray:
        """The unknowns x of this mesh at the parameters ``p`` (anchors ``q``) interpolated
        (linearly in s) from the fields of ``eq``, a solution on any mesh or by any route.

        Returns
        -------
        ndarray, shape (layout.size,)
        """
        d = self.disc
        s = d.points(p, q)
        nodes = s[::d.stages]
        s_g = (nodes[:-1, None] + np.diff(nodes)[:, None] * d.tau[None, :]).ravel()
        return d.layout.pack(np.interp(s, eq.s, eq.r), np.interp(s, eq.s, eq.psi),
                             np.interp(s_g, eq.s, eq.f_s))

    @staticmethod
    def _axis_crossing(eq: Equilibrium) -> tuple[float, float] | None:
        """(r, s) of the most negative r at the points or Gauss points, if any is negative
        outside :data:`POLE_ZONE` of a weakly singular pole.

        r < 0 puts material on the far side of the axis: the discrete energy,
        which sees r only through f_φ = r/ρ, does not forbid it, but the shell
        cannot do it.  Next to a pole whose local solution is weakly singular
        (an exponent β₁ < 1: :func:`~morphoshell.solvers.poles.weakly_singular`)
        the model's own solution r = c s + C₁ s^β₁ crosses the axis for s below
        (|C₁|/c)^(1/(1 − β₁)) when C₁ < 0, and a mesh graded into the pole resolves
        that (thick spheres: r = −1.1e-8 R at s ≤ 1.7e-7 R for h = 0.8, k = 0.8; the
        reference routes, which start ε = 1e-4 from the pole, find the same energy
        to 1e-10).  Such a crossing, far below any length the shell theory
        describes, is kept (a note in the log); elsewhere, and next to a regular
        pole, r < 0 is refused.
        """
        s_g, r_g = eq.quadrature_points()
        s = np.concatenate([eq.s, s_g])
        r = np.concatenate([eq.r, r_g])
        bad = r < 0
        if not bad.any():
            return None
        problem = eq.problem
        for where, beta in weakly_singular(problem).items():
            d = s - problem.cut if where == "start" else problem.end - s
            kept = bad & (d <= POLE_ZONE)
            if kept.any():
                log.info("r < 0 (down to %.2g R) within %.2g R of the %s pole: its local "
                         "solution ~ s^%.3g is weakly singular and crosses the axis there; kept",
                         r[kept].min(), d[kept].max(), where, beta)
            bad &= ~kept
        if not bad.any():
            return None
        i = int(np.argmin(np.where(bad, r, np.inf)))
        return float(r[i]), float(s[i])

    def equilibrium(self, problem: Problem, x: np.ndarray, lam: np.ndarray, p: np.ndarray,
                    q: np.ndarray, D: np.ndarray, stats: SolverStats,
                    converged: bool) -> Equilibrium:
        """The :class:`Equilibrium` of the NLP point (x, λ) at parameters p, anchors q (data D).

        The fields (stretches, curvatures, strains and resultants of Materials and
        Methods, Eqs. 5-7) at the nodes follow pointwise from the nodal state and
        costates (:meth:`~morphoshell.numerics.discretisation.Discretisation.node_fields`:
        order 2S, as r, ψ), at a cell's interior points from the polynomial through its
        nodal and Gauss-point values
        (:meth:`~morphoshell.numerics.discretisation.Discretisation.to_points`: order 2S − 1), f_φ
        and κ_φ exactly from r, ψ off the axis; the energy is the Gauss rule of 2π ∫ e ρ ds.

        Parameters
        ----------
        problem : Problem
        x : ndarray, shape (n,)
            The NLP's unknowns.
        lam : ndarray, shape (m,)
            Its multipliers.
        p, q : ndarray
            Parameter vector and anchor positions.
        D : ndarray
            The cell data at (p, q).
        stats : SolverStats
        converged : bool

        Returns
        -------
        Equilibrium
            On the N = (nodes − 1) × stages + 1 points of the mesh.
        """
        d, S = self.disc, self.stages
        gf = d.gauss_fields(x, D)
        pts = d.point_data(p, q)
        s, off = pts.s.copy(), pts.off
        # z(s_0) = z₀(s_0), then ∫ f_s sin ψ ds (the symbolic shape's formula, in numbers)
        z = pts.z0[0] + d.integrate_to_points(gf["f_s"] * np.sin(gf["psi"]), ds=gf["ds"])
        r, psi, _ = d.layout.split(x)
        prof = problem.profiles(s)     # parameter-only: exact at the points
        nodal = d.node_fields(x, lam, D, r[::S], psi[::S], intrinsic_values(
            problem.theory_obj, pts.rho[::S], {k: v[::S] for k, v in prof.items()}), problem.h)
        names = [k for k in FIELDS if k not in ("s", "r", "z", "psi", "eta")]
        fields = dict(zip(names, d.to_points(np.array([gf[k] for k in names]),
                                             np.array([nodal[k] for k in names]))))
        # Exact values off the axis from r, ψ there (the same at the nodes; at a pole
        # the stretches and curvatures are the cell's extrapolation).
        exact = kinematics(pts.rho[off], r[off], psi[off], fields["f_s"][off],
                           fields["kappa_s"][off] * fields["f_s"][off])
        fields["f_phi"][off], fields["kappa_phi"][off] = exact["f_phi"], exact["kappa_phi"]
        fields["eta"] = prof["eta"]
        energy = float(np.sum(gf["weight"] * gf["ds"] * gf["L"]))
        return Equilibrium(problem=problem, s=s, r=r, z=z, psi=psi, **fields, energy=energy,
                           solver=stats, converged=converged, x=x, lam_g=lam,
                           quadrature=Quadrature(gf["s"], gf["weight"] * gf["ds"], gf["L"],
                                                 d.stages, gf["r"]),
                           anchors=tuple(float(v) for v in q),
                           source=(weakref.ref(self), self.mesh, self.stages))


def solver_of(eq: Equilibrium) -> DirectSolver | None:
    """The :class:`DirectSolver` (or an equivalent one) that produced ``eq``; None for other routes.

    Results hold only a weak reference to their solver; if it is gone, a
    solver of the same structure and mesh is built (its discretisation, and so
    every observable of ``eq``, is the same).
    """
    if eq.source is None:
        return None
    ref, mesh, stages = eq.source
    solver = ref()
    return solver if solver is not None else DirectSolver(eq.problem.structure, mesh=mesh,
                                                          stages=stages)
