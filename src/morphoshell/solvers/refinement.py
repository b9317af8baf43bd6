"""Error estimates of direct solutions and mesh refinement to a tolerance.

:func:`estimate` compares a direct solution with the same problem on the
mesh with half the cells, solved from it (:func:`solve_from`, so the coarse
solution stays on the fine one's branch), and returns an
:class:`~morphoshell.solvers.results.ErrorEstimate`: the difference, a bound for
any order of convergence.  :func:`refine` doubles the
cells until the estimate meets a relative tolerance, as ``solve_bvp``'s
``tol`` does, reusing each level as the next one's reference.  The estimate keeps the
coarser solutions, and :func:`derived_errors` estimates quantities derived from
solutions (an ablation's observables) from those same levels.
"""
from __future__ import annotations

import logging
from dataclasses import replace
from typing import Callable, Mapping

import numpy as np

from ..model.problem import Problem
from ..numerics.mesh import MeshTooCoarse, step_cells
from ..numerics.status import TOLERANCE_NOT_MET, explain
from .continuation import continue_to
from .direct import MAX_NODES, DirectSolver
from .paths import stress_free
from .results import ESTIMATED, Equilibrium, ErrorEstimate, SolverError, energy_floor

__all__ = ["solve_from", "estimate", "error_estimate", "level_errors", "derived_errors",
           "refine", "refine_once", "level_estimate", "half_mesh", "too_coarse", "coarse_why",
           "coarse_level", "unresolved_steps", "warn_unresolved_steps",
           "SAFETY", "COARSE", "STEP_CELLS"]

log = logging.getLogger(__name__)

#: Factor on the differences between mesh levels.  Before the asymptotic
#: range the error can shrink by less than 2 from one level to the next, and
#: |fine − coarse| then under-states it (fuzzing: a Volvox shell's ψ(Σ) off by
#: 7.0e-9 at 200 nodes, 1.2e-8 at 100, difference 5.0e-9).  The factor covers
#: a shrink by 1.5 or more; less still fools it (fuzzing: z_end of a Volvox
#: shell with σ = 0.05 steps, 9.8e-7 off at 100 nodes, 7.9e-7 at 200, estimate
#: 4.7e-7, though 50 -> 100 had shrunk it 5x; asymptotic from about 400
#: nodes; documented in docs/solution.md).
SAFETY = 2.0
#: An estimate above this (relative energy, edge values in R and rad) without ``rtol``
#: is a warning: the mesh does not resolve the shell (a thin shell's energy off by 80 %
#: on 100 nodes at h = 1e-6).
COARSE = 0.1
#: Widest cell (in units of the step's width) within 3 widths of a smoothed step (the
#: Volvox profiles' steps of width σ) on the estimate's half mesh for the estimate to be
#: trusted (:func:`unresolved_steps`).  Measured (audit 22, volvox_fold, σ = 0.001-0.05 at
#: 100-400 nodes against 3200): estimates fell short of the error (by 1x to 48x) where
#: that cell was 25-112 widths, and bounded it (by 5x or more) where it was 17.7 or
#: less; 8 leaves a factor 3 below the first failure.
STEP_CELLS = 8.0


def half_mesh(nodes: int) -> int:
    """Nodes of the mesh with half the cells."""
    return (nodes - 1) // 2 + 1


def solve_from(solver: DirectSolver, problem: Problem, eq: Equilibrium, anchors=()) -> Equilibrium:
    """``problem`` on ``solver``'s mesh, started from a solution ``eq`` on another mesh.

    r, ψ and f_s are interpolated (linearly) from ``eq``'s points; the
    multipliers start at zero.  Newton then converges in a few iterations on
    ``eq``'s branch.

    Returns
    -------
    Equilibrium
        On ``solver``'s mesh.
    """
    x0 = solver.carried(eq, problem.parameter_vector(), anchors)
    return solver.solve(problem, x0=x0, anchors=anchors)


def _finer(solver: DirectSolver, problem: Problem, eq: Equilibrium, anchors) -> tuple:
    """(``eq`` carried onto the finer ``solver`` by :func:`solve_from`, ""), or where that
    fails, (``problem`` by continuation on it, as :func:`~morphoshell.solvers.routes.solve`
    reaches it, a note for the path): a thin sphere's curled rim, interpolated from 1593
    nodes onto 3185, left Ipopt 500 iterations from a solution."""
    try:
        return solve_from(solver, problem, eq, anchors), ""
    except SolverError as exc:
        note = f" ({solver.nodes} nodes by continuation: carried over, {exc.status})"
        return continue_to(solver, problem, anchors, switch=True), note


def level_errors(fine: dict, coarse: dict, coarser: dict | None, order: int) -> dict:
    """SAFETY · max(|fine − coarse|, |coarse − coarser|/(2^order − 1)) for every key of ``fine``.

    The values on the mesh, its half and (optionally) its quarter mesh: the
    error estimate of :func:`estimate`, shared with sweeps.

    Returns
    -------
    dict
        The estimated absolute error of each key of ``fine``.
    """
    out = {}
    for k, v in fine.items():
        err = abs(v - coarse[k])
        if coarser is not None:
            err = max(err, abs(coarse[k] - coarser[k]) / (2**order - 1))
        out[k] = SAFETY * float(err)
    return out


def estimate(fine: Equilibrium, coarse: Equilibrium | None, order: int, note: str = "",
             coarser: Equilibrium | None = None,
             polished: Equilibrium | None = None) -> ErrorEstimate:
    """Error estimate of ``fine`` from the half-mesh solution ``coarse`` (None: unavailable).

    With the quarter-mesh solution ``coarser`` too, each error is
    max(|fine − coarse|, |coarse − coarser|/(2^p − 1)): a fine and a coarse
    solution can agree by luck (the error of one crossing zero between the
    two; fuzzing found a Volvox shell whose energy at 100 and 200 nodes agreed
    to 1.5e-11 while both were 3.6e-10 off), but then the coarser level still
    shows the size of the error, reduced at most by the design order.  Both
    are multiplied by :data:`SAFETY`.  ``polished``: ``fine`` solved on to the
    default ``tol`` on its own mesh, where it was solved to a looser one:
    SAFETY |fine − polished|, its stopping error, is added, since the levels,
    each stopped as far from its own discrete solution, do not show it (audit
    16: a thin shell's ψ at the rim 1.3e-7 off at tol = 1e-6 on 1600 nodes,
    estimated 4.1e-8 by the levels).

    Returns
    -------
    ErrorEstimate
        NaN errors, with ``note`` saying why, when ``coarse`` is None.
    """
    values = fine.estimated_values()
    if coarse is None:
        errors = {k: float("nan") for k in ESTIMATED}
        ref = 0
    else:
        errors = level_errors(values, coarse.estimated_values(),
                              None if coarser is None else coarser.estimated_values(), order)
        ref = coarse.solver.nodes
    if polished is not None:
        errors = _plus_stopping(errors, values, polished.estimated_values())
    levels = tuple(eq for eq in (coarse, coarser) if eq is not None) if coarse else ()
    return error_estimate(fine, errors, ref, order, note, levels, polished)


def _plus_stopping(errors: dict, values: dict, polished: dict) -> dict:
    """``errors`` plus SAFETY |values − polished|: the stopping error of a loose ``tol``."""
    return {k: e + SAFETY * abs(values[k] - polished[k]) for k, e in errors.items()}


def error_estimate(fine: Equilibrium, errors: Mapping[str, float], reference_nodes: int,
                   order: int, note: str = "", levels: tuple = (),
                   polished: Equilibrium | None = None) -> ErrorEstimate:
    """The :class:`~morphoshell.solvers.results.ErrorEstimate` of ``fine`` with absolute
    ``errors``: its values, its nodes and the energy floor of its problem
    (:func:`~morphoshell.solvers.results.energy_floor`, h for a stress-free shell).

    The one place that floor is chosen, so that every relative error
    (:meth:`~morphoshell.solvers.results.ErrorEstimate.relative`, :func:`too_coarse`) is
    ``solve()``'s: a sweep that built its own with the round-off floor called a
    stress-free sphere's energy error 6.6e+02 of its ~0 energy and its mesh too coarse
    (audit 17 F1), where ``solve()`` gives 3e-8 of the scale h.
    """
    return ErrorEstimate(dict(errors), fine.estimated_values(), fine.solver.nodes,
                         reference_nodes, order, note,
                         energy_floor(fine.problem.h, stress_free(fine.problem)), levels,
                         polished)


def derived_errors(measure: Callable[..., dict], *fine: Equilibrium) -> tuple[dict, str]:
    """Error estimates of quantities derived from direct solutions, made as their own.

    ``measure(*fine)`` is evaluated again on the coarser levels that the solutions'
    estimates kept (:attr:`ErrorEstimate.levels`: the half, then the quarter mesh), level
    by level, and the values are differenced by :func:`level_errors`: the estimate
    :func:`estimate` makes of the energy and the edge values, with no further solve.

    Parameters
    ----------
    measure : callable
        ``(*equilibria) -> {name: float}``, e.g. an ablation's observables of its
        pre- and post-ablation states.
    *fine : Equilibrium
        The solutions, each with its estimate (``error``).

    Returns
    -------
    (dict, str)
        The estimated absolute error of each value of ``measure`` (units as its values)
        and "", or NaN errors and why there are none.
    """
    values = measure(*fine)
    for eq in fine:
        if eq.error is None or not eq.error.levels:
            name = eq.problem.name or eq.problem.family
            why = (eq.error.note if eq.error is not None and eq.error.note else
                   f"the {eq.solver.method} route makes no error estimate (the direct one does)"
                   if eq.solver.method != "direct" else
                   f"the solution of {name} carries no coarser levels (one from solve() does)")
            return {k: float("nan") for k in values}, why
    depth = min(len(eq.error.levels) for eq in fine)
    levels = [measure(*(eq.error.levels[i] for eq in fine)) for i in range(depth)]
    errors = level_errors(values, levels[0], levels[1] if depth > 1 else None,
                          fine[0].error.order)
    if any(eq.error.polished is not None for eq in fine):
        polished = measure(*(eq if eq.error.polished is None else eq.error.polished
                             for eq in fine))
        errors = _plus_stopping(errors, values, polished)
    return errors, ""


def too_coarse(est: ErrorEstimate) -> tuple[str, float] | None:
    """(the quantity, its relative error) where an estimate exceeds :data:`COARSE`, the
    largest (:meth:`ErrorEstimate.relative`), else None: the mesh does not resolve the
    shell.  Not for an energy below its floor (round-off, or a stress-free shell's
    discretisation of 0: :func:`~morphoshell.solvers.results.energy_floor`)."""
    rel = est.relative()
    if abs(est.values["energy"]) <= est.energy_floor:
        rel.pop("energy")
    key = max(rel, key=lambda k: rel[k] if np.isfinite(rel[k]) else np.inf)
    return None if rel[key] <= COARSE else (key, rel[key])


def coarse_why(est: ErrorEstimate) -> str | None:
    """Where an estimate exceeds :data:`COARSE` (:func:`too_coarse`), what that says: the
    quantity, its relative error and the nodes, the mesh too coarse; else None."""
    worst = too_coarse(est)
    if worst is None:
        return None
    key, rel = worst
    return (f"the error estimate of {key} is {rel:.2g} "
            f"({'relative' if key == 'energy' else 'R or rad'}) on {est.nodes} nodes: the mesh "
            f"is too coarse for this shell")


def _warn_if_coarse(est: ErrorEstimate) -> None:
    """A warning where an estimate exceeds :data:`COARSE` (:func:`coarse_why`)."""
    why = coarse_why(est)
    if why is not None:
        log.warning("%s; refine it (rtol, --rtol)", why)


def unresolved_steps(problem: Problem, nodes: int, stages: int, anchors=()) -> str | None:
    """Why the error estimate on ``nodes`` nodes is not to be trusted: its half mesh does not
    resolve the family's smoothed steps (:data:`STEP_CELLS`), naming the nodes that do; or
    None.

    Both levels then solve what is, to the scheme, a sharp step at a node: they agree with
    each other and miss the smoothing (audit 22: σ = 0.001 R on 200 nodes, estimate 1.1e-5
    R at the edges, error 5.3e-4).
    """
    cells = step_cells(problem, half_mesh(nodes), stages, anchors)
    if cells is None or cells[0] <= STEP_CELLS:
        return None
    need = min(2 * (nodes - 1) + 1, MAX_NODES)      # (nodes itself: just found short)
    while need < MAX_NODES and _step_cells(problem, half_mesh(need), stages,
                                           anchors) > STEP_CELLS:
        need = min(2 * (need - 1) + 1, MAX_NODES)
    return (f"the mesh does not resolve the profiles' smoothed steps of width {cells[1]:.3g} R "
            f"(cells up to {cells[0]:.3g} widths wide across them on the {half_mesh(nodes)}-node "
            f"half mesh of the error estimates): solutions on such meshes converge to those of a "
            f"sharp step, and the estimates may fall far short of the error; use {need} nodes "
            f"or more")


def _step_cells(problem: Problem, nodes: int, stages: int, anchors) -> float:
    """:func:`~morphoshell.numerics.mesh.step_cells`' widest cell (in widths), 0 without."""
    return (step_cells(problem, nodes, stages, anchors) or (0.0,))[0]


def warn_unresolved_steps(problems, nodes: int, stages: int, anchors=()) -> None:
    """A warning (:func:`unresolved_steps`) for the worst of ``problems`` (the ends of a
    path: the steps' width σ is linear along it, narrowest at an end) on ``nodes`` nodes."""
    worst = max(problems, key=lambda p: _step_cells(p, half_mesh(nodes), stages, anchors))
    why = unresolved_steps(worst, nodes, stages, anchors)
    if why:
        log.warning("%s", why)


def coarse_level(solver_for: Callable[[int], DirectSolver], nodes: int, problem: Problem,
                 eq: Equilibrium, anchors, solve: Callable = solve_from
                 ) -> tuple[Equilibrium | None, str]:
    """(``problem`` on ``nodes`` nodes from ``eq``, "") for the estimate, or (None, why not).

    A level is unavailable where it has too few nodes, does not converge, or cannot hold
    the mesh's knots: a Volvox shell's 4 knots fit 20 nodes but not their quarter mesh of
    5, and the 20-node solve stands with the estimate of the levels there are (user audit).
    ``solve``: how the level is solved from ``eq``, ``(solver, problem, eq, anchors) ->
    Equilibrium`` raising SolverError (:func:`solve_from`, a minimisation, by default).
    """
    if nodes < 5:
        return None, "too few nodes to halve"
    try:
        return solve(solver_for(nodes), problem, eq, anchors), ""
    except SolverError as exc:
        return None, f"the half mesh ({nodes} nodes) did not converge ({exc.status})"
    except MeshTooCoarse:
        return None, f"the half mesh ({nodes} nodes) cannot hold the mesh's knots"


def level_estimate(eq: Equilibrium, solver_for: Callable[[int], DirectSolver], order: int,
                   anchors=(), polish: Callable[[Equilibrium], Equilibrium] | None = None,
                   solve: Callable = solve_from) -> ErrorEstimate:
    """The estimate of :func:`refine` (``solve()``'s) of ``eq``: from its problem on the
    half mesh, solved from ``eq``, and on the quarter mesh, solved from that
    (:func:`coarse_level`, ``solve`` as its), with no warning.

    Parameters
    ----------
    eq : Equilibrium
        A direct solution.
    solver_for : callable
        ``nodes -> DirectSolver`` of ``eq``'s structure and options.
    order : int
        The scheme's order (2 × stages).
    polish : callable, optional
        As :func:`refine`'s.
    solve : callable, optional
        As :func:`coarse_level`'s.

    Returns
    -------
    ErrorEstimate
        With a note (and NaN errors) where the half mesh is unavailable.
    """
    nodes = eq.solver.nodes
    reference, note = coarse_level(solver_for, half_mesh(nodes), eq.problem, eq, anchors, solve)
    coarser = None        # (two levels only where the quarter mesh is unavailable)
    if reference is not None:
        coarser, _ = coarse_level(solver_for, half_mesh(half_mesh(nodes)), eq.problem,
                                  reference, anchors, solve)
    polished, why = _polished(polish, eq)
    return estimate(eq, None if why else reference, order, why or note, coarser, polished)


def refine(eq: Equilibrium, solver_for: Callable[[int], DirectSolver], rtol: float | None,
           anchors=(), max_nodes: int = MAX_NODES,
           polish: Callable[[Equilibrium], Equilibrium] | None = None) -> Equilibrium:
    """``eq`` with its error estimate, refined until it meets ``rtol`` (if given).

    Parameters
    ----------
    eq : Equilibrium
        A direct solution.
    solver_for : callable
        ``nodes -> DirectSolver`` for the same structure and options.
    rtol : float or None
        Relative tolerance (see :meth:`ErrorEstimate.meets`: the energy
        relative to itself, edge values absolutely, in units of R and
        radians); None only estimates.
    max_nodes : int
        Finest mesh allowed (at most :data:`~morphoshell.solvers.direct.MAX_NODES`).
    polish : callable, optional
        ``eq -> eq`` solved on to the default tolerance on its mesh, for solutions
        solved to a looser ``tol``: its stopping error joins the estimate
        (:func:`estimate`'s ``polished``).

    Returns
    -------
    Equilibrium
        The finest solution, with its estimate (``error``); a refined one says
        so in ``solver.details["path"]``.

    Raises
    ------
    SolverError
        Status ``"Tolerance_Not_Met"`` when ``rtol`` needs more than
        ``max_nodes`` nodes; the finest solution is attached.
    """
    problem, nodes = eq.problem, eq.solver.nodes
    order = 2 * solver_for(nodes).stages
    est = level_estimate(eq, solver_for, order, anchors, polish)
    steps = unresolved_steps(problem, nodes, order // 2, anchors)
    if rtol is None and not est.note:
        _warn_if_coarse(est)
        if steps:
            log.warning("%s", steps)
    eq = replace(eq, error=est)
    path, notes = eq.solver.details.get("path", ""), ""
    first = nodes
    # (an estimate that meets rtol on meshes that miss the steps is no sign of it)
    while rtol is not None and (not eq.error.meets(rtol) or steps):
        if 2 * (nodes - 1) + 1 > min(max_nodes, MAX_NODES):
            key, err = eq.error.worst()
            short = (f"the error estimate {err:.3g} of {key} (at {nodes} nodes) does not meet "
                     f"rtol = {rtol:g}" if not eq.error.meets(rtol) else steps)
            raise SolverError(
                f"{short} within {min(max_nodes, MAX_NODES)} nodes: "
                f"{explain(TOLERANCE_NOT_MET)}; the finest solution is the error's "
                f"last_iterate",
                TOLERANCE_NOT_MET, eq)
        eq, how = refine_once(eq, solver_for, anchors, polish)
        notes += how
        nodes = eq.solver.nodes
        steps = unresolved_steps(problem, nodes, order // 2, anchors)
    if nodes != first:
        details = {**eq.solver.details, "path": f"{path}, then refined from {first} to {nodes} "
                                               f"nodes for rtol = {rtol:g}{notes}"}
        eq = replace(eq, solver=replace(eq.solver, details=details))
    return eq


def _polished(polish: Callable[[Equilibrium], Equilibrium] | None,
              eq: Equilibrium) -> tuple[Equilibrium | None, str]:
    """(``polish(eq)``, "") (None without ``polish``), or (None, why) where it fails: the
    stopping error is then unknown, and so is the estimate."""
    if polish is None:
        return None, ""
    try:
        return polish(eq), ""
    except SolverError as exc:
        return None, (f"solved to a looser tol than the default, it did not solve on to it "
                      f"on its own mesh ({exc.status}): its stopping error is unknown")


def refine_once(eq: Equilibrium, solver_for: Callable[[int], DirectSolver],
                anchors=(), polish: Callable[[Equilibrium], Equilibrium] | None = None
                ) -> tuple[Equilibrium, str]:
    """One step of :func:`refine`: ``eq``'s problem on the mesh with twice the cells.

    Parameters
    ----------
    eq : Equilibrium
        A direct solution with its estimate (``error``), whose first level (the half mesh)
        becomes the new solution's quarter mesh.
    solver_for : callable
        ``nodes -> DirectSolver`` for the same structure and options.
    polish : callable, optional
        As :func:`refine`'s.

    Returns
    -------
    (Equilibrium, str)
        The finer solution, carried over from ``eq`` (:func:`solve_from`), with its
        estimate against ``eq``; and a note for the path where carrying over failed and
        continuation reached it ("" otherwise).
    """
    solver = solver_for(2 * (eq.solver.nodes - 1) + 1)
    finer, how = _finer(solver, eq.problem, eq, anchors)
    levels = eq.error.levels if eq.error is not None else ()
    # (the levels without their own estimates: a chain of them would keep every mesh alive)
    polished, why = _polished(polish, finer)
    est = estimate(finer, None if why else replace(eq, error=None), 2 * solver.stages, why,
                   coarser=levels[0] if levels else None, polished=polished)
    return replace(finer, error=est), how
