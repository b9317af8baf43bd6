"""A branch's points checked as :func:`~morphoshell.solvers.routes.solve` checks its results.

:func:`~morphoshell.solvers.branches.follow_branch` steps through states that ``solve()``
would judge twice over: it refuses a meridian that crosses the axis, and it estimates
the error of what it reports from the mesh with half the cells.  A branch is held to
both:

* *physicality*: :func:`crossing_end` finds where the walk's meridian starts to cross
  the axis (:func:`~morphoshell.solvers.direct.axis_crossing`, the check ``solve()``
  makes), and the branch ends there with an :class:`Ending` (``solve()`` refuses the
  states beyond: a uniform cap continued in k crossed by 1.9e-3 R, labelled stable);
* *resolution*: :func:`event_errors` re-locates each fold and branch point on the half
  mesh, walking that mesh's branch from the fine one's point before the event, and
  estimates the event's λ error as ``solve()`` estimates its values (:data:`SAFETY` times
  the difference); an event the half mesh does not reproduce within :data:`COARSE` in λ
  is not resolved, and a warning names it (the anisotropic toy shell continued in f0
  showed three pairs of folds on 200 nodes, one on 100 and none on 400 or 800); and
  :func:`end_error` estimates the error of the branch's end (its energy and edge values,
  the state asked for) as ``solve()`` estimates its result, from the end's problem on the
  half and quarter meshes solved from it (:func:`~.refinement.level_estimate`), with
  ``solve()``'s warning where it exceeds :data:`COARSE` (:func:`end_warning`; the toy
  shell continued in f0 to 4.5 on 100 nodes ended 0.78 R off in z_end without a word,
  where ``solve()`` warned of 0.42).  The points between are not estimated (two solves
  each): a branch's values are resolved where its end and events are, on the same mesh.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass, replace

import numpy as np

from ..numerics.mesh import MeshTooCoarse
from ..numerics.status import MERIDIAN_CROSSES_AXIS
from ..numerics.status import MAXIMUM_ITERATIONS_EXCEEDED
from .arclength import EVENT_TOL, GROWTH, MIN_STEP, ArcPoint, Arclength
from .direct import DirectSolver, axis_crossing, crossing_why, solver_of
from .refinement import COARSE, SAFETY, coarse_why, half_mesh, level_estimate, solve_from
from .results import Equilibrium, ErrorEstimate, SolverError
from .routes import direct_solver

__all__ = ["Ending", "crossing_end", "event_errors", "unresolved", "unresolved_warning",
           "end_error", "end_warning", "end_columns", "where", "END_ERRORS", "REACH",
           "MAX_CHECK_STEPS"]

log = logging.getLogger(__name__)

#: How far in λ past a fine mesh's event the half mesh's branch is searched for it: an
#: event found farther off has an estimate SAFETY · REACH above COARSE anyway.
REACH = COARSE / SAFETY
#: Most pseudo-arclength steps of the half mesh's walk to an event.
MAX_CHECK_STEPS = 60
#: The values of a branch's table whose error :func:`end_error` estimates at its end: a
#: column ``<value>_error`` each (:func:`end_columns`).
END_ERRORS = ("energy", "r_end", "z_end", "psi_end")


@dataclass(frozen=True)
class Ending:
    """Why a branch ends before the path's end: a status and where.

    Attributes
    ----------
    status : str
        ``"Meridian_Crosses_Axis"`` (:mod:`morphoshell.numerics.status`): the branch ends
        at its last physical state; or why the walk stopped early (its SolverError's
        status, ``"Branch_Ended"``, or ``"Interrupted"``): the part followed.
    tau : float
        The λ of the branch's last point.
    why : str
        What lies beyond and what helps (``solve()``'s message for the state beyond), or
        why the walk stopped (its error's first line, "interrupted"...).
    """

    status: str
    tau: float
    why: str

    @property
    def stopped(self) -> bool:
        """Whether the walk stopped early (the branch goes on), not at an unphysical state."""
        return self.status != MERIDIAN_CROSSES_AXIS

    def describe(self) -> str:
        """One line for a summary."""
        if self.stopped:
            return f"the walk stopped early at lambda = {self.tau:.10g} ({self.status}): {self.why}"
        return f"the branch ends at lambda = {self.tau:.10g} ({self.status}): past it {self.why}"

    def to_dict(self) -> dict:
        """Plain data (JSON)."""
        return {"status": self.status, "lambda": self.tau, "why": self.why}


def crossing_end(arc: Arclength, prev: ArcPoint, new: ArcPoint, ds: float,
                 beyond=None) -> tuple[ArcPoint, float, Ending] | None:
    """Where the step from ``prev`` to ``new`` (arclength ``ds``) starts to cross the axis.

    ``beyond``, ``new``'s equilibrium if at hand, saves building it again.

    Returns
    -------
    (ArcPoint, float, Ending) or None
        None if ``new`` does not cross (:func:`axis_crossing`); else the last point of
        the step that does not, by bisection on the arclength to :data:`EVENT_TOL` (``prev``
        where none does), its arclength from ``prev``, and the ending there, with
        ``solve()``'s message for the state beyond.
    """
    beyond = beyond if beyond is not None else arc.equilibrium(new)
    crossing, tau = axis_crossing(beyond), new.tau
    if crossing is None:
        return None
    lo, hi, last = 0.0, ds, prev
    while hi - lo > EVENT_TOL:
        mid = 0.5 * (lo + hi)
        trial = arc.correct(prev, mid)
        if trial is None:
            break
        eq = arc.equilibrium(trial)
        found = axis_crossing(eq)
        if found is None:
            lo, last = mid, trial
        else:
            hi, beyond, crossing, tau = mid, eq, found, trial.tau
    why = (f"r = {crossing[0]:.3g} R at s = {crossing[1]:.6g} (lambda = {tau:.10g}), which "
           f"solve() refuses: {crossing_why(beyond, crossing)}")
    return last, lo, Ending(MERIDIAN_CROSSES_AXIS, float(last.tau), why)


def event_errors(points: list, line, max_step: float, coarse: dict | None = None) -> list:
    """``points`` with each fold's and branch point's λ error estimated on the half mesh.

    Parameters
    ----------
    points : list of BranchPoint
        A branch's points in order along it.
    line : ParameterLine
    max_step : float
        The walk's largest step (the half mesh's walk takes the same).
    coarse : dict, optional
        The half-mesh solvers built so far, by fine mesh, used and added to (for
        :func:`end_error`, which solves the end there too).

    Returns
    -------
    list of BranchPoint
        As ``points``, ``lambda_error`` set at folds and branch points: SAFETY times the
        distance in λ to the same event on the half mesh, ``inf`` where that mesh has
        none within :data:`REACH`, NaN where it could not be checked (a point before the
        event that the half mesh cannot hold, or its walk failing).
    """
    coarse = {} if coarse is None else coarse
    out = list(points)
    for i, pt in enumerate(points):
        if pt.event not in ("fold", "branch_point") or i == 0:
            continue
        tau = _relocate(points, i, line, coarse, max_step)
        out[i] = replace(pt, lambda_error=SAFETY * abs(tau - pt.tau))
    return out


def unresolved(points: list) -> list:
    """The events of ``points`` whose λ error estimate exceeds :data:`COARSE` (or that the
    half mesh does not have)."""
    return [pt for pt in points if pt.event and pt.lambda_error > COARSE]


def where(line, tau: float) -> str:
    """``lambda = τ``, with the parameter's value where one moves."""
    values = line.values(tau)
    return f"lambda = {tau:.6g}" + "".join(f" ({k} = {v:.6g})" for k, v in values.items()
                                           if len(values) == 1)


def unresolved_warning(points: list, line) -> str:
    """What the mesh does not resolve (:func:`unresolved` of a branch's ``points``), and
    what helps."""
    nodes = points[0].equilibrium.solver.nodes
    events = "; ".join(f"{pt.event.replace('_', ' ')} at {where(line, pt.tau)}"
                       for pt in unresolved(points))
    return (f"the mesh ({nodes} nodes) does not resolve the branch's {events}: on the mesh "
            f"with half the cells each lies more than {COARSE / SAFETY:g} away in lambda or is "
            f"not there, so it (and the unstable parts and snap-throughs it bounds) may be an "
            f"artefact of the discretisation; follow the branch on a finer mesh (nodes, "
            f"--nodes {2 * (nodes - 1) + 1} or more)")


def end_error(end, line, coarse: dict | None = None) -> ErrorEstimate:
    """The error estimate of a branch's ``end`` (a BranchPoint) as ``solve()`` makes that of
    its result (:func:`~.refinement.level_estimate`): its problem on the half and quarter
    meshes of the end's own mesh, solved from the end's state.  ``coarse``: the half-mesh
    solvers built so far, by fine mesh (:func:`event_errors`'), used and added to.

    A stable end is minimised there, as ``solve()`` does (:func:`~.refinement.solve_from`);
    an unstable one (or an event) is found by Newton's iterations, which leave a saddle a
    saddle (:meth:`Arclength.stationary`), where a minimisation would slide off it.

    Returns
    -------
    ErrorEstimate
        With NaN errors and a note where a level is unavailable.
    """
    eq = end.equilibrium
    fine = solver_of(eq)
    coarse = {} if coarse is None else coarse

    def solver_for(nodes: int) -> DirectSolver:
        return fine if nodes == fine.nodes else _coarser(fine, nodes, eq, coarse)

    def stationary_from(solver, problem, start: Equilibrium, anchors) -> Equilibrium:
        arc = Arclength(solver, line, anchors, at=end.tau)
        point = arc.stationary(solver.carried(start, arc.parameters(end.tau), arc.q), end.tau)
        if point is None:
            raise SolverError(f"Newton's iterations on {solver.nodes} nodes from the "
                              f"{start.solver.nodes}-node state did not converge",
                              MAXIMUM_ITERATIONS_EXCEEDED)
        return arc.equilibrium(point)
    return level_estimate(eq, solver_for, 2 * fine.stages, eq.anchors,
                          solve=solve_from if end.stable else stationary_from)


def _coarser(fine: DirectSolver, nodes: int, eq: Equilibrium, coarse: dict) -> DirectSolver:
    """``fine``'s mesh with ``nodes`` nodes (the half mesh from ``coarse``, as
    :func:`_coarse_solver`), or where ``eq``'s knots have moved too far for it (a walk kept
    on its first mesh: ``REMESH`` in :mod:`.branches`), the mesh built for ``eq``'s problem
    (as :func:`_coarse_arc`; MeshTooCoarse where that cannot hold them)."""
    solver = _coarse_solver(fine, coarse) if nodes == half_mesh(fine.nodes) else \
        DirectSolver(fine.structure, mesh=replace(fine.mesh, nodes=nodes), stages=fine.stages)
    if solver is None:          # (a half mesh below 5 nodes: callers check, this says so)
        raise MeshTooCoarse(f"the half mesh of {fine.nodes} nodes is below 5 nodes")
    try:
        solver.disc.check_anchors(eq.problem.parameter_vector(), eq.anchors)
        return solver
    except ValueError:
        return direct_solver(eq.problem, nodes, eq.anchors, stages=fine.stages)


def end_columns(rows: int, error: ErrorEstimate | None) -> dict[str, list]:
    """A branch's table's columns ``<value>_error`` (:data:`END_ERRORS`): the estimated
    absolute error of its end's ``error`` in the last of ``rows`` rows, NaN in the others
    (not estimated) and throughout without an estimate."""
    return {f"{k}_error": [float("nan")] * (rows - 1) +
            [float("nan") if error is None else float(error.errors[k])] for k in END_ERRORS}


def end_warning(end, error: ErrorEstimate, line) -> str | None:
    """``solve()``'s warning of a mesh too coarse (:func:`~.refinement.coarse_why`) for a
    branch's ``end`` with its estimate ``error``, and what helps; None where it holds."""
    why = None if error.note else coarse_why(error)
    if why is None:
        return None
    return (f"at the branch's end, {where(line, end.tau)}, {why}, and likely for the branch's "
            f"other values; follow the branch on a finer mesh (nodes, --nodes "
            f"{2 * (error.nodes - 1) + 1} or more)")


def _coarse_solver(fine: DirectSolver, cache: dict) -> DirectSolver | None:
    """The solver of ``fine``'s mesh with half the cells (one per fine mesh), or None
    where that mesh is too small."""
    key = (fine.mesh, fine.stages)
    if key not in cache:
        nodes = half_mesh(fine.nodes)
        cache[key] = None if nodes < 5 else DirectSolver(
            fine.structure, mesh=replace(fine.mesh, nodes=nodes), stages=fine.stages)
    return cache[key]


def _coarse_arc(fine: DirectSolver, line, start, cache: dict) -> Arclength | None:
    """The half mesh's :class:`Arclength` at ``start``: of ``fine``'s mesh with half the
    cells, or where its knots have moved too far for that (a walk on rebuilt meshes:
    ``REMESH`` in :mod:`.branches`), of the half mesh built for the parameters there;
    None where neither holds."""
    anchors = start.equilibrium.anchors
    solver = _coarse_solver(fine, cache)
    if solver is None:
        return None
    try:
        return Arclength(solver, line, anchors, at=start.tau)
    except (ValueError, MeshTooCoarse):
        pass
    try:
        solver = direct_solver(line.at(start.tau), solver.nodes, anchors, stages=fine.stages)
        return Arclength(solver, line, anchors, at=start.tau)
    except (ValueError, MeshTooCoarse):
        return None


def _relocate(points: list, i: int, line, cache: dict, max_step: float) -> float:
    """The λ of the event ``points[i]`` on the half mesh: from the nearest ordinary point
    before it that the half mesh holds (a stationary point there by Newton's steps), its
    branch walked toward the event until the same kind of event has happened as often as
    on the fine mesh since that point; ``inf`` past :data:`REACH`, NaN where it fails."""
    event = points[i]
    for j in range(i - 1, max(i - 4, -1), -1):
        start = points[j]
        if start.event:
            continue
        arc = _coarse_arc(solver_of(start.equilibrium), line, start, cache)
        if arc is None:
            return float("nan")
        solver = arc.solver
        x = solver.carried(start.equilibrium, arc.parameters(start.tau), arc.q)
        point = arc.stationary(x, start.tau)
        if point is None and start.stable:
            point = _minimised(arc, start)
        if point is None:
            log.debug("half mesh: no stationary point at lambda = %.6g", start.tau)
            continue
        if point.inertia.negative != start.negative_eigenvalues:
            # (the half mesh's state there is another part of the branch, or another branch)
            log.debug("half mesh at lambda = %.6g: %d negative eigenvalues, not %d", start.tau,
                      point.inertia.negative, start.negative_eigenvalues)
            return float("inf")
        # the fine walk's way on from start, not toward the event's λ: a fold between them
        # turns back (the fold shell's second fold on 60 nodes, walked away from at --max-step
        # 0.2, was reported not resolved)
        if (points[j + 1].tau - start.tau) * point.t_tau < 0:
            point = replace(point, t=-point.t, t_tau=-point.t_tau)
        count = sum(pt.event == event.event for pt in points[j + 1:i + 1])
        return _walk_to(arc, point, event, count, min(max_step, _way(arc, points[j:i + 1])))
    return float("nan")


def _way(arc: Arclength, points: list) -> float:
    """The length of the fine walk through ``points`` (from the half mesh's start to the
    event): its chords in the continuation's norm, the states carried onto ``arc``'s mesh.

    The half mesh's steps are held to it, as the fine walk's were (the half mesh's walk
    starts afresh at a quarter of the largest step): at ``max_step`` 0.2 and 0.5 its first
    step, 0.05, crossed the whole of the fold shell's loop of 5.8e-4 in λ (two folds, t_τ
    and the tangent as before: no sign of them), where the fine walk had come with 0.019,
    and its fold at 0.54653, 1.8e-7 from the 400-node mesh's, was reported not resolved
    (audit 22 F7)."""
    zero = np.zeros(arc.kkt.m)
    u = [arc.kkt.free(arc.kkt.pack(arc.solver.carried(pt.equilibrium, arc.parameters(pt.tau),
                                                      arc.q), zero)) for pt in points]
    return sum(arc.norm(b - a, q.tau - p.tau)
               for a, b, p, q in zip(u, u[1:], points, points[1:]))


def _minimised(arc: Arclength, start) -> ArcPoint | None:
    """The stable ``start`` on ``arc``'s mesh as ``solve()``'s estimate finds it (minimised
    from it: :func:`~.refinement.solve_from`), where Newton's steps from it do not converge
    (the toy shell's fold region on 100 nodes, 0.14 R from the 200-node state); None if
    that fails too."""
    try:
        eq = solve_from(arc.solver, arc.line.at(start.tau), start.equilibrium, arc.q)
    except SolverError:
        return None
    return arc.start(eq, start.tau)


def _walk_to(arc: Arclength, point: ArcPoint, event, count: int, max_step: float) -> float:
    """The λ of the ``count``-th event of ``event``'s kind along ``arc``'s branch from
    ``point`` (:func:`_relocate`), by the walk's steps up to ``max_step``: retried at half
    where they fail, turn or may hide a pair of folds (:meth:`Arclength.folds_within`,
    as the walk's: at ``max_step`` 0.3 one step here crossed the fold shell's loop of
    5.8e-4 in λ without it)."""
    ds = max_step / 4
    for _ in range(MAX_CHECK_STEPS):
        new = arc.correct(point, ds)
        if new is None or arc.turned(point, new) or arc.folds_within(point, new, ds, max_step):
            ds /= 2
            if ds < MIN_STEP:
                log.debug("half mesh: the walk to the %s at lambda = %.6g stalled at %.6g",
                          event.event, event.tau, point.tau)
                return float("nan")
            continue
        found = _events(arc, point, new, ds, event.event)
        if len(found) >= count:
            return float(found[count - 1].tau)
        count -= len(found)
        if abs(new.tau - event.tau) > REACH and abs(new.tau - event.tau) > abs(point.tau -
                                                                               event.tau):
            return float("inf")
        point, ds = new, min(GROWTH * ds, max_step)
    return float("inf")


def _events(arc: Arclength, point: ArcPoint, new: ArcPoint, ds: float, kind: str) -> list:
    """The located events of ``kind`` between ``point`` and ``new`` (as the walk finds them)."""
    if kind == "fold":
        return [arc.locate_fold(point, ds)] if np.sign(new.t_tau) != np.sign(point.t_tau) \
            else []
    if new.inertia.negative != point.inertia.negative:
        return arc.locate_changes(point, new, ds)
    return []
