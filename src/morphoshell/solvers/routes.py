"""The one-call front door: :func:`solve` an equilibrium by any route.

``solve(problem)`` picks the route (direct minimisation by default, or the
boundary-value reference), builds or reuses a solver and returns an
:class:`~morphoshell.solvers.results.Equilibrium`.  Direct solvers are kept in a
bounded least-recently-used cache (:data:`SOLVER_CACHE_SIZE` entries) keyed on
the problem's *structure* (geometry, family and theory objects, end types),
the mesh and the options; h, Σ, P and the family's parameters are NLP
parameters, so a sweep over them reuses one solver.  The mesh's grading is
rounded to octaves of the boundary-layer width (:func:`morphoshell.numerics.mesh.mesh_spec`),
so it is rebuilt only when δ/(L − P − Σ) changes by more than a factor 2.

For repeated solves of one structure (continuation, fitting) build a
:class:`~morphoshell.solvers.direct.DirectSolver` yourself and warm-start it.
"""
from __future__ import annotations

import logging
from collections import OrderedDict
from contextlib import contextmanager
from contextvars import ContextVar
from typing import Any, Iterator, Mapping

from dataclasses import replace

from .._runtime.validate import flag
from ..model.problem import Problem
from ..numerics.mesh import mesh_spec
from ..numerics.status import (BRANCH_ENDED, CONTINUATION_FAILED, NOT_A_MINIMUM, SNAP_FAILED,
                               explain)
from .arclength import Arclength
from .contact import warn_if_walls_overlap
from .continuation import continue_to, left_branch
from .direct import BUILDS, MAX_NODES, DirectSolver, check_nodes
from .options import (DIRECT_TOL, check_anchors, check_guess, check_problem, thin_shell_first,
                      thin_shell_note)
from .paths import ParameterLine
from .refinement import half_mesh, refine, solve_from
from .results import Equilibrium, NotAMinimumError, SolverError, SolverStats, unconverged

__all__ = ["solve", "direct_solver", "cache_info", "clear_cache", "SOLVER_CACHE_SIZE",
           "thin_note_once",
           "METHODS", "DIRECT_OPTIONS", "BVP_OPTIONS", "SHOOTING_OPTIONS", "MIN_RTOL",
           # re-exported for convenience
           "DirectSolver", "Equilibrium", "SolverError", "NotAMinimumError", "SolverStats"]

log = logging.getLogger(__name__)

#: Routes of :func:`solve`.
METHODS = ("direct", "bvp", "shooting")

#: Keyword options of :func:`solve` for each route.
DIRECT_OPTIONS = ("stages", "linear_solver", "tol", "max_iter", "stability", "ipopt_options",
                  "max_nodes")
BVP_OPTIONS = ("tol", "bc_tol", "pole_offset", "max_nodes", "homotopy_steps", "max_seconds")
SHOOTING_OPTIONS = ("segments", "integrator", "atol", "tol", "pole_offset", "homotopy_steps",
                    "max_evaluations", "max_growth", "max_segments", "max_condition", "points",
                    "max_seconds")

#: With ``rtol``, meshes twice as fine (up to 8 times the nodes) on which :func:`solve` retries
#: a continuation that failed with a status whose remedy is a finer mesh: on thin shells a
#: free edge's boundary layer that curls over folds on coarse meshes where it does not on
#: fine ones (h = 1e-4: folds at 400 and 800 nodes find no landing, 1600 and 3200 agree).
MESH_RETRIES = 3
#: The smallest ``rtol``: estimates below the solvers' own tolerance (1e-10) are round-off.
MIN_RTOL = 1e-10
RETRIED = (CONTINUATION_FAILED, SNAP_FAILED, BRANCH_ENDED)
#: Coarsest mesh on which :func:`solve` continues a problem whose continuation failed on
#: its own mesh, to solve it there from the coarse solution (:func:`_from_coarser`).
COARSEST = 100
#: ... and whose energy there must agree with the fine mesh's to this (relative): a thin
#: shell's coarse mesh, which does not resolve it, reached another state (a rim curled
#: at 150 nodes, 1.6 % above the 300- and 400-node energy, in a trial of another norm).
COARSE_AGREEMENT = 1e-4

#: Direct solvers kept by :func:`solve` (least recently used dropped first).
#: A solver of 400 nodes holds a few MB.
SOLVER_CACHE_SIZE = 16

_SOLVERS: "OrderedDict[tuple, DirectSolver]" = OrderedDict()

#: The thin-shell notes :func:`solve` logged within :func:`thin_note_once` (None outside).
_NOTED: ContextVar[set | None] = ContextVar("thin_notes_logged", default=None)


@contextmanager
def thin_note_once() -> Iterator[None]:
    """Within the block, :func:`solve` logs its thin-shell note (``thin_shell_note``) once
    for each shell thickness: for a run that solves one shell more than once, as an
    ablation solves it intact and cut (``morphoshell ablate`` logged the same line twice)."""
    token = _NOTED.set(set())
    try:
        yield
    finally:
        _NOTED.reset(token)


def _frozen(value: Any):
    """A hashable version of an option value (mappings and sequences frozen recursively)."""
    if isinstance(value, Mapping):
        return tuple(sorted((str(k), _frozen(v)) for k, v in value.items()))
    if isinstance(value, (list, tuple)):
        return tuple(_frozen(v) for v in value)
    return value


def _check_options(method: str, options: Mapping[str, Any]) -> None:
    valid = {"direct": DIRECT_OPTIONS, "bvp": BVP_OPTIONS, "shooting": SHOOTING_OPTIONS}[method]
    unknown = sorted(set(options) - set(valid))
    if unknown:
        raise ValueError(f"unknown option(s) {unknown} for method {method!r}; valid: {list(valid)}")


def direct_solver(problem: Problem, nodes: int = 200, anchors=(), **options) -> DirectSolver:
    """A cached :class:`DirectSolver` suited to ``problem`` (mesh from :func:`mesh_spec`).

    Parameters
    ----------
    problem : Problem
    nodes : int
        Mesh nodes.
    anchors : sequence of float
        Material points that must be mesh nodes.
    **options
        The direct options of :func:`solve` but ``max_nodes``.

    Returns
    -------
    DirectSolver
        From the cache when one of the same structure, mesh and options is
        there (it then counts as the most recently used).
    """
    _check_options("direct", options)
    stages = options.get("stages", 2)
    spec = mesh_spec(problem, check_nodes(nodes), stages, tuple(anchors))
    key = (problem.structure, spec, _frozen(options))
    if key in _SOLVERS:
        _SOLVERS.move_to_end(key)
        return _SOLVERS[key]
    solver = DirectSolver(problem.structure, mesh=spec, **options)
    _SOLVERS[key] = solver
    while len(_SOLVERS) > SOLVER_CACHE_SIZE:
        _SOLVERS.popitem(last=False)
    return solver


def cache_info() -> dict:
    """Solvers held by :func:`solve`'s cache, its bound, and DirectSolver builds so far."""
    return {"solvers": len(_SOLVERS), "maxsize": SOLVER_CACHE_SIZE, "builds": BUILDS["count"]}


def clear_cache() -> None:
    """Drop every cached solver."""
    _SOLVERS.clear()


def solve(problem: Problem, nodes: int = 200, method: str = "direct",
          warm_start: Equilibrium | None = None, anchors=(), *, continuation: bool = True,
          rtol: float | None = None, **options) -> Equilibrium:
    """Equilibrium of ``problem``.

    Parameters
    ----------
    problem : Problem
    nodes : int
        Mesh nodes (direct; the first mesh when ``rtol`` refines) or initial
        mesh nodes (bvp).
    method : {"direct", "bvp", "shooting"}
        Direct energy minimisation (default), the boundary-value reference of
        :mod:`morphoshell.solvers.bvp` (collocation, ``solve_bvp``), or the
        multiple-shooting reference of :mod:`morphoshell.solvers.shooting`, which
        refuses thin shells (``Shooting_Ill_Conditioned``).
    warm_start : Equilibrium, optional
        A previous solution (same method and mesh) to start from.
    anchors : sequence of float
        direct only: material points s that must be mesh nodes (where the
        solution is to be evaluated exactly), increasing, inside the shell.
    continuation : bool
        direct only, without ``warm_start``: reach the problem by continuation
        from its family's stress-free parameters (default; see
        :mod:`morphoshell.solvers.continuation`) rather than by one cold solve from the
        undeformed shell, which can land on a spurious local minimum.  The
        result says which (``solver.details["path"]``).
    rtol : float, optional
        direct only: refine the mesh (doubling the cells) until the error
        estimate meets this relative tolerance (energy relative to itself,
        edge values in units of R and radians), or raise.  Every direct
        result carries its estimate (``Equilibrium.error``), from the mesh with
        half the cells.  With ``rtol`` a continuation that fails for want of
        a finer mesh is retried on finer ones (:data:`MESH_RETRIES`); one that
        fails so on a fine mesh is continued on a coarser one and solved on its
        own from there (:data:`COARSEST`).
    **options
        direct: ``stages``, ``linear_solver``, ``tol``, ``max_iter``,
        ``stability``, ``ipopt_options`` (see :class:`DirectSolver`), and
        ``max_nodes``, the finest mesh ``rtol`` may refine to;
        bvp: ``tol``, ``bc_tol``, ``pole_offset``, ``max_nodes``,
        ``homotopy_steps``, ``max_seconds`` (see
        :func:`morphoshell.solvers.bvp.solve_bvp`); shooting: the options of
        :func:`morphoshell.solvers.shooting.solve_shooting` but its integrator's
        ``rtol``.

    Returns
    -------
    Equilibrium
        Converged, stable and physical; a direct one with its error estimate
        (``error``) and how it was reached (``solver.details["path"]``).  The
        model has no self-contact: a shape whose walls pass through each other
        is returned with a logged warning (:mod:`morphoshell.solvers.contact`).

    Raises
    ------
    SolverError
        No converged, stable, physical answer (Ipopt's or solve_bvp's status;
        ``"Meridian_Crosses_Axis"``, ``"Continuation_Failed"``,
        ``"Tolerance_Not_Met"``), with the last iterate attached;
        :class:`NotAMinimumError` for a saddle (for the reference routes: by the
        inertia of the direct discretisation there, ``solver.details["minimum"]``).
    ValueError, TypeError
        Bad input, named with its value before any work: an option out of its
        range (:mod:`morphoshell.solvers.options`) or refused by Ipopt, a
        ``problem`` that is not a Problem, a ``warm_start`` that is not an Equilibrium,
        ``anchors`` that are not a sequence of numbers, a ``continuation`` that is not a bool.

    Examples
    --------
    >>> from morphoshell import Problem, solve
    >>> eq = solve(Problem("uniform", {"k": 0.0}, h=0.3, cut=0.3))
    >>> round(float(eq.psi[0]), 6)
    0.821866
    """
    check_problem(problem)
    check_guess(warm_start)
    anchors = check_anchors(anchors)
    continuation = flag("continuation", continuation)
    if method not in METHODS:
        raise ValueError(f"unknown method {method!r}; choose one of {list(METHODS)}")
    _check_options(method, options)
    if method != "direct":
        if len(anchors) or rtol is not None:
            raise ValueError("anchors and rtol are options of the direct method only")
        if method == "shooting":
            from .shooting import solve_shooting
            eq = solve_shooting(problem, guess=warm_start, **options)
        else:
            from .bvp import solve_bvp
            eq = solve_bvp(problem, nodes=nodes, guess=warm_start, **options)
        eq = _minimum(eq, nodes)
        warn_if_walls_overlap(eq)
        return eq
    if rtol is not None and not (isinstance(rtol, (int, float)) and MIN_RTOL <= rtol < 1):
        raise ValueError(f"rtol = {rtol!r} must be a number in [{MIN_RTOL:g}, 1): the error "
                         f"estimate compares solutions converged to the solver's own "
                         f"tolerance, 1e-10")
    max_nodes = check_nodes(options.pop("max_nodes", MAX_NODES))
    thin, noted = thin_shell_note(problem), _NOTED.get()
    if thin and not (noted is not None and thin in noted):
        # (known before any work, which can take 20 s of retries before it fails)
        log.warning("solve of %s: %s; trying the direct route all the same", problem.name
                    or problem.family, thin)
        if noted is not None:
            noted.add(thin)
    try:
        return _direct(problem, nodes, warm_start, anchors, continuation, rtol, max_nodes,
                       options)
    except SolverError as exc:
        first = thin_shell_first(problem, str(exc))
        if first == str(exc) or isinstance(exc, NotAMinimumError):
            raise
        raise SolverError(first, exc.status, exc.last_iterate) from exc


def _direct(problem, nodes, warm_start, anchors, continuation, rtol, max_nodes,
            options) -> Equilibrium:
    """The direct route of :func:`solve`, its arguments checked."""
    solver = direct_solver(problem, nodes, anchors, **options)
    if warm_start is not None:
        eq = _warm(solver, problem, warm_start, anchors)
    elif continuation:
        eq = _continued(solver, problem, anchors, options, rtol, max_nodes)
    else:
        eq = solver.solve(problem, anchors=anchors)
        eq = replace(eq, solver=replace(eq.solver, details={**eq.solver.details, "path": "cold"}))
    eq = refine(eq, lambda n: direct_solver(problem, n, anchors, **options), rtol, anchors,
                max_nodes, _polisher(problem, anchors, options))
    warn_if_walls_overlap(eq)       # (a minimum of the model, but not a physical shape)
    return eq


def _polisher(problem: Problem, anchors, options: dict):
    """For a ``tol`` looser than the default: a solution solved on to the default on its
    own mesh, whose difference is its stopping error in the estimate
    (:func:`~morphoshell.solvers.refinement.estimate`'s ``polished``); None otherwise."""
    if options.get("tol", DIRECT_TOL) <= DIRECT_TOL:
        return None
    tight = {**options, "tol": DIRECT_TOL}
    return lambda eq: direct_solver(problem, eq.solver.nodes, anchors, **tight).solve(
        problem, warm_start=eq, anchors=anchors)


def _warm(solver: DirectSolver, problem: Problem, start: Equilibrium, anchors) -> Equilibrium:
    """``problem`` solved from ``start``, its path "warm start"; where the solve left
    ``start``'s branch (:func:`~morphoshell.solvers.continuation.left_branch`: past a fold
    the warm start's branch ends and the solve lands on another, as a snap-through) the
    path says so, ``details["left_branch"]`` holds the energies before and after (as a
    snap's), and a note is logged, as for the snaps of solve()'s own continuation.
    Before, the fold shell warm-started just past its fold landed 0.0048 C R² lower with
    no word (audit 14)."""
    eq = solver.solve(problem, warm_start=start, anchors=anchors)
    details = {**eq.solver.details, "path": "warm start"}
    if left_branch(solver, start, eq):
        note = (f"left the warm start's branch (energy {start.energy:.6g} -> {eq.energy:.6g} "
                f"C R^2): it ends at a fold or branch point between the warm start's "
                f"parameters and these, and the solve landed on another branch, as a "
                f"snap-through; without warm_start, solve() follows its own route")
        details.update(path=f"warm start; {note}", left_branch={
            "energy_before": float(start.energy), "energy_landed": float(eq.energy)})
        log.info("solve of %s: %s", problem.name or problem.family, note)
    return replace(eq, solver=replace(eq.solver, details=details))


def _minimum(eq: Equilibrium, nodes: int) -> Equilibrium:
    """A reference route's solution ``eq`` if it is a minimum of the energy, else
    NotAMinimumError: the inertia of the direct discretisation (on ``nodes`` nodes) at
    its stationary point next to ``eq``'s shape (:meth:`Arclength.stationary`).

    The Euler–Lagrange equations the reference routes solve hold at every stationary
    shape: on the blister disc past its buckling both returned the flat disc, a saddle
    with four negative eigenvalues and 7.6 times the dome's energy.  The routes' values
    are kept (they are the independent reference); only their stability comes from
    the direct discretisation (``solver.details["minimum"]``).
    """
    problem, route = eq.problem, eq.solver.method
    solver = direct_solver(problem, nodes, ())
    arc = Arclength(solver, ParameterLine.between(problem, problem))
    point = arc.stationary(solver.carried(eq, problem.parameter_vector()), 1.0)
    if point is None:       # undecided: said, not guessed
        note = f"not checked: Newton's iterations of the direct discretisation from it " \
               f"did not converge on {nodes} nodes"
    elif not point.inertia.stable:
        raise NotAMinimumError(
            f"the {route} route converged to a stationary shape that is not a minimum: the "
            f"direct discretisation's reduced Hessian there (on {nodes} nodes) has "
            f"{point.inertia.negative} negative and {point.inertia.zero} zero eigenvalues: "
            f"{explain(NOT_A_MINIMUM)}. The {route} solution is attached (.last_iterate)",
            NOT_A_MINIMUM, unconverged(eq))
    else:
        note = f"certified by the inertia of the direct discretisation on {nodes} nodes"
    return replace(eq, solver=replace(eq.solver, details={**eq.solver.details, "minimum": note}))


def _continued(solver: DirectSolver, problem: Problem, anchors, options: dict,
               rtol: float | None, max_nodes: int) -> Equilibrium:
    """:func:`continue_to` on ``solver``'s mesh; with ``rtol``, a failure in :data:`RETRIED`
    is retried on meshes twice as fine (:data:`MESH_RETRIES`, within ``max_nodes``), and
    the path says where it failed."""
    failed = []
    while True:
        try:
            eq = continue_to(solver, problem, anchors, switch=True)
            break
        except SolverError as exc:
            finer = 2 * (solver.nodes - 1) + 1
            if rtol is None or exc.status not in RETRIED or len(failed) == MESH_RETRIES \
                    or finer > min(max_nodes, MAX_NODES):
                coarse = _from_coarser(solver, problem, anchors, options) \
                    if exc.status in RETRIED and not failed else None
                if coarse is not None:
                    return coarse
                if not failed:
                    raise
                raise SolverError(f"{exc} (on {solver.nodes} nodes; before: "
                                  f"{', '.join(failed)})", exc.status, exc.last_iterate) from exc
            failed.append(f"{exc.status} on {solver.nodes} nodes")
            solver = direct_solver(problem, finer, anchors, **options)
    if failed:
        path = f"{eq.solver.details.get('path', '')}, on {solver.nodes} nodes after " \
               f"{', '.join(failed)} (retried for rtol)"
        eq = replace(eq, solver=replace(eq.solver, details={**eq.solver.details, "path": path}))
    return eq


def _from_coarser(solver: DirectSolver, problem: Problem, anchors,
                  options: dict) -> Equilibrium | None:
    """``problem`` continued on a coarser mesh (half, then a quarter of ``solver``'s cells,
    down to :data:`COARSEST` nodes) and solved from there on ``solver``'s, as a refinement
    does; None if that fails too.

    On fine meshes a branch point's modes crowd together and its crossing can fail where
    it works on coarse ones (the packaged blister continued at 200-800 nodes and failed at
    1600, where a solve refined for rtol reaches 3185 nodes)."""
    coarse = half_mesh(solver.nodes)
    while coarse >= COARSEST:
        try:
            start = continue_to(direct_solver(problem, coarse, anchors, **options), problem,
                                anchors, switch=True)
            eq = solve_from(solver, problem, start, anchors)
        except SolverError:
            coarse = half_mesh(coarse)
            continue
        if abs(eq.energy - start.energy) > COARSE_AGREEMENT * abs(eq.energy):
            return None     # (a coarse mesh that does not resolve the shell: another state)
        path = (f"{start.solver.details.get('path', '')} on {coarse} nodes (on "
                f"{solver.nodes} it failed), then solved on {solver.nodes} nodes from there")
        return replace(eq, solver=replace(eq.solver, details={**eq.solver.details,
                                                             "path": path}))
    return None
