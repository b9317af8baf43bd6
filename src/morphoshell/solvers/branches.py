"""Branches of equilibria: bifurcation diagrams with stability, folds and snap-throughs.

:func:`follow_branch` follows the equilibria of a problem along a straight path
in parameter space (:class:`~morphoshell.solvers.paths.ParameterLine`): from
the family's stress-free parameters to the problem's (the path τ = λ ∈ [0, 1]
that :func:`~morphoshell.solvers.routes.solve` takes), or one parameter from
its value to another.  Pseudo-arclength steps (:mod:`morphoshell.solvers.arclength`)
go through folds; every point carries its stability (the inertia of the
reduced Hessian), and folds and branch points are located on the way.

Two ways to follow:

``"branch"``  the connected branch, through its folds and unstable parts:
              the bifurcation diagram;
``"stable"``  what a shell loaded quasi-statically does: the stable branch up
              to a fold, a snap-through to the stable equilibrium beyond it,
              and on (hysteresis when the path is reversed); where it loses
              its stability at a branch point, on along the stable half of
              the other branch through it (a buckling disc).

:func:`switch_branch` follows the other branch through one of a branch's
branch points (:meth:`~morphoshell.solvers.arclength.Arclength.switch`): the
buckled shells beside a symmetric one, say.  :func:`continuation_path` returns
a branch as a table.
"""
from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from .._runtime.interrupts import interrupted, reason
from .._runtime.validate import integer, within
from ..model.problem import Problem
from .arclength import EASY, GROWTH, MAX_STEP, MIN_STEP, ArcPoint, Arclength, Snap, Switch
from .branch_checks import (Ending, crossing_end, end_columns, end_error, end_warning,
                            event_errors, unresolved, unresolved_warning, where)
from .contact import wall_contact
from .continuation import continue_to
from .crossings import branch_ended, snap_through, switch_stable
from .options import check_direct_options, check_problem
from .refinement import warn_unresolved_steps
from .paths import ParameterLine, neutral_problem
from .results import Equilibrium, ErrorEstimate, SolverError
from .routes import direct_solver

log = logging.getLogger(__name__)

__all__ = ["Branch", "BranchPoint", "Ending", "follow_branch", "switch_branch",
           "continuation_path", "EVENTS", "FOLLOW", "COLUMNS", "MAX_POINTS", "UNITS",
           "PARAMETER_UNITS"]

#: What a point of a branch can be besides an ordinary one.
EVENTS = ("fold", "branch_point", "snap")
#: The ways of following a path.
FOLLOW = ("branch", "stable")
#: The columns of a branch's table after the parameter's (units: docs, "Branches").
COLUMNS = ("energy", "r_end", "z_end", "psi_end", "stable", "negative_eigenvalues", "event",
           "lambda_error")
#: The path parameter may leave [0, 1] by this much before the branch counts as lost.
TAU_MARGIN = 0.5
#: A step that stretches or squeezes a cell of its mesh by more than this factor
#: (relative to the mesh as a whole) is taken on a mesh rebuilt at the step's start.
#: Breakpoints and the opening move the knots of the mesh with the parameters while
#: the nodes between stay: continued far enough, a knot passes its neighbour and the
#: discrete energy is that of a folded mesh, whose inertia is no stability (a user
#: audit: s1 continued from 0.65 to 1 reported three branch points and an end with 12
#: negative eigenvalues, a strict minimum on its own mesh).
REMESH = 2.0
#: Most points a branch may be given (``max_points``; the command line's --max-points).
MAX_POINTS = 100_000
#: Units of a branch's columns (its table's ``attrs`` and its JSON), the parameter's aside.
UNITS = {"lambda": "1", "energy": "C R^2", "r_end": "R", "z_end": "R", "psi_end": "rad",
         "negative_eigenvalues": "1", "lambda_error": "1", "energy_error": "C R^2",
         "r_end_error": "R", "z_end_error": "R", "psi_end_error": "rad"}
#: Units of the parameters continued in whose unit is known (as a sweep's columns).
PARAMETER_UNITS = {"h": "R", "cut": "R", "opening": "R", "k": "1/R"}


@dataclass(frozen=True)
class BranchPoint:
    """One equilibrium of a branch.

    Attributes
    ----------
    tau : float
        The path fraction λ ∈ [0, 1] (0: the path's start, 1: its end).
    values : dict
        The moving parameters' values there.
    energy : float
        Total energy (C R²).
    r_end, z_end, psi_end : float
        The far end's r and height above the first point (units of R; as
        ``Equilibrium.estimated_values`` and a sweep's ``z_end``) and ψ (rad).
    negative_eigenvalues : int
        Of the reduced Hessian: 0 for a stable equilibrium; at a fold or
        branch point, the fewer of its two sides'.
    stable : bool
        A strict local minimum (no negative or zero eigenvalue); False at a
        fold or branch point, where an eigenvalue crosses zero.
    event : str
        "" or one of :data:`EVENTS`.
    equilibrium : Equilibrium
        The whole solution.
    lambda_error : float
        At a fold or branch point, the estimated error of its λ from the mesh with half
        the cells (:func:`~morphoshell.solvers.branch_checks.event_errors`; ``inf``: not
        there within reach, an artefact of the mesh); NaN elsewhere or not checked.
    """

    tau: float
    values: dict
    energy: float
    r_end: float
    z_end: float
    psi_end: float
    negative_eigenvalues: int
    stable: bool
    event: str
    equilibrium: Equilibrium = field(repr=False, compare=False)
    lambda_error: float = float("nan")


@dataclass(frozen=True)
class Branch:
    """A followed branch: its points in order along it, with events and snap-throughs.

    Attributes
    ----------
    problem : Problem
        The path's end (τ = 1).
    line : ParameterLine
    parameter : str or None
        The one parameter continued in, or None for the path from the
        stress-free parameters.
    follow : {"branch", "stable"}
    points : tuple of BranchPoint
    snaps : tuple of Snap
    seconds : float
    origin : float or None
        For a branch that :func:`switch_branch` followed: the λ of the branch
        point it starts from (its first point); None for one from the path's start.
    direction : float
        For such a branch: which half (+1 or −1) of the branch through that point.
    switches : tuple of Switch
        ``follow="stable"``: where the branch lost its stability at a branch
        point and the walk went on along the stable half of the other branch.
    remeshed : tuple of float
        The λ where the walk went on on a mesh rebuilt for the parameters there
        (:data:`REMESH`); the points after each are on the new mesh.
    ended : Ending or None
        Why the branch ends before the path's end: where its meridian would cross the
        axis (its last point the last physical state, which ``solve()`` refuses past), or
        where the walk stopped early (the branch ended, ``max_points``, Ctrl-C or SIGTERM:
        the part followed, the exception's ``branch``); None where it reaches the end.
    end_error : ErrorEstimate or None
        The estimated error of the end's energy and edge values, as ``solve()``'s of its
        result (:func:`~morphoshell.solvers.branch_checks.end_error`; a warning where it
        exceeds ``solve()``'s threshold); None where the walk stopped before its check.
    """

    problem: Problem
    line: ParameterLine
    parameter: str | None
    follow: str
    points: tuple
    snaps: tuple
    seconds: float
    origin: float | None = None
    direction: float = 1.0
    switches: tuple = ()
    remeshed: tuple = ()
    ended: Ending | None = None
    end_error: ErrorEstimate | None = None

    def __repr__(self) -> str:
        """One line: the problem, the path, how many points over which λ (and parameter) range,
        the events and snaps (the default repr listed every point: 12-80 kB)."""
        taus = [pt.tau for pt in self.points]
        parts = [repr(self.problem.name or self.problem.family),
                 f"{self.parameter}: {self.line.a[0]:g} -> {self.line.b[0]:g}"
                 if self.parameter is not None else "from the stress-free parameters",
                 f"follow={self.follow!r}", f"{len(self.points)} points",
                 f"lambda in [{min(taus, default=0):.6g}, {max(taus, default=0):.6g}]"]
        if self.parameter is not None:
            values = [pt.values[self.parameter] for pt in self.points]
            parts.append(f"{self.parameter} in [{min(values):.6g}, {max(values):.6g}]")
        counts = {e: sum(pt.event == e for pt in self.points) for e in EVENTS}
        parts.append("events: " + (", ".join(f"{n} {e}" for e, n in counts.items() if n)
                                   or "none"))
        parts.append(f"{len(self.snaps)} snaps")
        if self.origin is not None:
            parts.append(f"switched at lambda = {self.origin:.6g}, direction {self.direction:+g}")
        if self.remeshed:
            parts.append(f"mesh rebuilt at lambda = {', '.join(f'{t:.6g}' for t in self.remeshed)}")
        if self.ended is not None:
            parts.append(f"ended at lambda = {self.ended.tau:.6g}: {self.ended.status}")
        return f"Branch({', '.join(parts)})"

    def units(self) -> dict[str, str]:
        """The columns' units (:data:`UNITS`; the parameter's from :data:`PARAMETER_UNITS` or,
        a family's, as the family declares it: ``ProfileFamily.units``, as a sweep's)."""
        declared = {**PARAMETER_UNITS, **self.problem.family_obj.units}
        known = {self.parameter: declared[self.parameter]} \
            if self.parameter in declared else {}
        return {"lambda": UNITS["lambda"], **known, **{k: v for k, v in UNITS.items()
                                                      if k != "lambda"}}

    @property
    def events(self) -> list[BranchPoint]:
        """The points that are events (folds, branch points, snaps), in order."""
        return [pt for pt in self.points if pt.event]

    @property
    def unresolved(self) -> list[BranchPoint]:
        """The events that the mesh does not resolve (λ error estimate above
        :data:`~morphoshell.solvers.refinement.COARSE`, or none on the half mesh)."""
        return unresolved(self.points)

    @property
    def end(self) -> BranchPoint:
        """The last point (at τ = 1 when the branch reached the path's end)."""
        return self.points[-1]

    def columns(self) -> dict[str, list]:
        """The table's columns: ``lambda``, the parameter's own (if one), :data:`COLUMNS`, then
        the end's error estimate (:func:`~.branch_checks.end_columns`: its last row)."""
        out: dict[str, list] = {"lambda": [pt.tau for pt in self.points]}
        if self.parameter is not None:
            out[self.parameter] = [pt.values[self.parameter] for pt in self.points]
        for name in COLUMNS:
            out[name] = [getattr(pt, name) for pt in self.points]
        return {**out, **end_columns(len(self.points), self.end_error)}

    def to_dataframe(self, equilibria: bool = False):
        """The branch as a pandas DataFrame, one row per point (units in ``df.attrs``).

        Parameters
        ----------
        equilibria : bool
            Add a column ``equilibrium`` with each point's :class:`Equilibrium`.

        Returns
        -------
        pandas.DataFrame
        """
        import pandas as pd

        df = pd.DataFrame(self.columns())
        if equilibria:
            df["equilibrium"] = [pt.equilibrium for pt in self.points]
        df.attrs.update(units=self.units(), problem=self.problem.describe(), follow=self.follow,
                        end_error=None if self.end_error is None else self.end_error.to_dict(),
                        path=dict(zip(self.line.names, zip(self.line.a.tolist(),
                                                           self.line.b.tolist()))))
        return df

    def to_dict(self) -> dict[str, Any]:
        """Plain data (JSON): the problem, the path, the points' table, its units and the snaps."""
        return {"problem": self.problem.describe(), "parameter": self.parameter,
                "follow": self.follow, "units": self.units(),
                "path": {n: [float(a), float(b)] for n, a, b in zip(self.line.names, self.line.a,
                                                                    self.line.b)},
                "points": self.columns(), "snaps": [s.to_dict() for s in self.snaps],
                "seconds": self.seconds,
                **({"origin": self.origin, "direction": self.direction}
                   if self.origin is not None else {}),
                **({"switches": [s.to_dict() for s in self.switches]} if self.switches else {}),
                **({"remeshed": list(self.remeshed)} if self.remeshed else {}),
                **({"ended": self.ended.to_dict()} if self.ended is not None else {}),
                **({"complete": False} if self.ended is not None and self.ended.stopped
                   else {}),
                **({"unresolved": [pt.tau for pt in self.unresolved]}
                   if self.unresolved else {}),
                **({"end_error": self.end_error.to_dict()} if self.end_error else {})}


def follow_branch(problem: Problem, param: str | None = None, to: float | None = None, *,
                  nodes: int = 200, stages: int = 2, follow: str = "branch",
                  max_step: float = MAX_STEP, max_points: int = 2000, anchors=()) -> Branch:
    """Follow the equilibria of ``problem`` along a path, with their stability and events.

    Parameters
    ----------
    problem : Problem
    param, to : str and float, optional
        Continue the one parameter ``param`` (h, cut, opening or one of the
        family's) from ``problem``'s value to ``to``; without them, follow the
        path from the family's stress-free parameters to ``problem``'s.
    nodes, stages : int
        The direct solver's mesh (as :func:`solve`).
    follow : {"branch", "stable"}
        The connected branch through its folds, or the quasi-static path with
        snap-throughs (module docstring).
    max_step : float
        Largest pseudo-arclength step (norm of (x, τ), x by its root mean square), in (0, 1].
    max_points : int
        Most points before giving up, in [2, :data:`MAX_POINTS`].
    anchors : sequence of float
        Mesh anchors (as :func:`solve`).

    Returns
    -------
    Branch
        From τ = 0 to the first point at τ = 1.

    Raises
    ------
    ValueError
        An unknown parameter or ``follow``, ``max_step`` or ``max_points`` out of
        its range, or a family without stress-free parameters to start from
        (before any work).
    TypeError
        ``problem`` not a Problem.
    SolverError
        ``"Branch_Ended"`` when the steps fail or leave the path, with the
        last point attached; ``"Snap_Through_Failed"``.  Its ``branch`` (and that of
        a ``KeyboardInterrupt``: Ctrl-C, SIGTERM) is the branch followed up to there,
        its :attr:`Branch.ended` saying why it stopped (:func:`_walked`).
    """
    check_problem(problem)
    if follow not in FOLLOW:
        raise ValueError(f"follow = {follow!r} must be one of {list(FOLLOW)}")
    _check_walk(max_step, max_points)
    check_direct_options(stages=stages)
    t0 = time.perf_counter()
    solver = direct_solver(problem, nodes, anchors, stages=stages)
    line, start = _path(solver, problem, param, to, anchors)
    warn_unresolved_steps((line.source, line.problem), nodes, stages, anchors)
    walk = _Walk(Arclength(solver, line, anchors), follow, max_step, max_points)

    def branch(ended: Ending | None = None) -> Branch:
        return Branch(line.problem, line, param, follow, tuple(walk.points), tuple(walk.snaps),
                      0.0, switches=tuple(walk.switches), remeshed=tuple(walk.remeshed),
                      ended=ended if ended is not None else walk.ended)
    return _walked(walk, lambda: walk.run(start), branch, max_step, t0)


def switch_branch(branch: Branch, at: int, direction: float = 1.0, *,
                  max_step: float = MAX_STEP, max_points: int = 2000) -> Branch:
    """Follow the other branch through a branch point of ``branch``.

    From the branch point, along the null direction of its KKT matrix
    orthogonal to ``branch`` (:meth:`Arclength.switch`), by the same
    pseudo-arclength steps as :func:`follow_branch` (``follow="branch"``:
    through folds, unstable parts included), until the branch reaches either
    end of the path (λ = 1 or λ = 0).

    Parameters
    ----------
    branch : Branch
        From :func:`follow_branch` (on its mesh the new one is followed).
    at : int
        Which of its branch points: 0 for the first along it, 1 for the next...
    direction : float
        +1 or −1: the two halves of the other branch (at a pitchfork, mirror
        images; :meth:`Arclength.switch` says which is which).
    max_step, max_points : float and int
        As for :func:`follow_branch`.

    Returns
    -------
    Branch
        Its first point the branch point (event ``"branch_point"``), its last
        at λ = 1 or 0; ``origin`` that point's λ, ``direction`` as given.

    Raises
    ------
    ValueError
        ``at`` beyond the branch's branch points, ``direction`` not ±1 (a bool
        is not), ``max_step`` or ``max_points`` out of range (all before any
        work), or the point not a simple branch point (:meth:`Arclength.switch`).
    TypeError
        ``branch`` not a Branch, or ``at`` not an integer.
    SolverError
        ``"Branch_Ended"`` when the steps fail or leave the path.
    """
    from .direct import solver_of

    if not isinstance(branch, Branch):
        raise TypeError(f"branch must be a Branch (from follow_branch), "
                        f"got {type(branch).__name__}")
    if isinstance(at, (bool, np.bool_)) or not isinstance(at, (int, np.integer)):
        raise TypeError(f"at = {at!r} must be an integer: which branch point (0 for the first)")
    points = [pt for pt in branch.points if pt.event == "branch_point"]
    if not -len(points) <= at < len(points):
        raise ValueError(f"at = {at!r}: the branch has {len(points)} branch point(s)")
    # (True == 1: a bool would pass for a direction)
    if isinstance(direction, (bool, np.bool_)) or direction not in (1, -1):
        raise ValueError(f"direction = {direction!r} must be +1 or -1")
    _check_walk(max_step, max_points)
    t0 = time.perf_counter()
    origin = points[at]
    arc = Arclength(solver_of(origin.equilibrium), branch.line, origin.equilibrium.anchors,
                    at=origin.tau)
    walk = _Walk(arc, "branch", max_step, max_points, ends=(0.0, 1.0))

    def switched(ended: Ending | None = None) -> Branch:
        return Branch(branch.problem, branch.line, branch.parameter, "branch",
                      tuple(walk.points), (), 0.0, origin.tau, float(direction),
                      remeshed=tuple(walk.remeshed),
                      ended=ended if ended is not None else walk.ended)
    return _walked(walk, lambda: walk.switched(origin, direction), switched, max_step, t0)


def _checked(branch: Branch, max_step: float, t0: float) -> Branch:
    """``branch`` with its events' λ errors from the half mesh
    (:func:`~.branch_checks.event_errors`), its end's error estimate
    (:func:`~.branch_checks.end_error`) and its time since ``t0``; a warning names the
    events the mesh does not resolve, one an end it does not (``solve()``'s), one where it
    ended early (:class:`Ending`), and one
    where the shapes it shows (its start, its events and its end: the plot's panels) have
    walls that pass through each other (:mod:`.contact`; checking every point would cost a
    third of the walk: docs/benchmarks.md, "solvers/branches.py").  The start too: the plot
    draws it, and a file's own state (the fold shell at κ₂ = −8) was drawn crossed without a
    word (audit 14)."""
    coarse: dict = {}       # (the half-mesh solvers, built once for both)
    branch = replace(branch, points=tuple(event_errors(list(branch.points), branch.line,
                                                       max_step, coarse)))
    branch = replace(branch, end_error=end_error(branch.end, branch.line, coarse))
    shown = [branch.points[0]] + [pt for pt in branch.points if pt.event] + [branch.end]
    crossed = sorted({pt.tau for pt in shown if wall_contact(pt.equilibrium) is not None})
    if crossed:
        log.warning("the shapes of the branch at lambda = %s have walls that pass through "
                    "each other: the model has no self-contact, so they are equilibria of the "
                    "model but not physical shapes", ", ".join(f"{t:.6g}" for t in crossed))
    if branch.unresolved:
        log.warning("%s", unresolved_warning(list(branch.points), branch.line))
    coarse = end_warning(branch.end, branch.end_error, branch.line)
    if coarse:
        log.warning("%s", coarse)
    if branch.ended is not None:
        log.warning("%s", branch.ended.describe())
    return replace(branch, seconds=time.perf_counter() - t0)


def _walked(walk: "_Walk", run, branch, max_step: float, t0: float) -> Branch:
    """``run()`` the walk, then :func:`_checked` its branch (``branch()``); where either stops
    early, the branch followed so far goes with the exception as its ``branch``
    (``branch(ending)``, :attr:`Branch.ended` an :class:`Ending` whose ``why`` is the first
    line of the SolverError, or "interrupted" / "terminated (SIGTERM)", during the check
    said so; its ``seconds`` the time to there), so that the command line writes it: an
    early stop's branch is a result (its folds located), and it had been lost, 2000 points
    of it (audit 14); one stopped in the check after a complete walk too (audit 17)."""
    checking = False
    try:
        run()
        checking = True
        return _checked(branch(), max_step, t0)
    except BaseException as exc:
        if walk.points and (isinstance(exc, SolverError) or interrupted(exc)):
            failed = isinstance(exc, SolverError)
            why = str(exc).splitlines()[0] if failed else reason()
            if checking:
                why += (" during the half-mesh check of the branch's events (its points "
                        "complete, their lambda_error not estimated)")
            exc.branch = replace(branch(Ending(exc.status if failed else "Interrupted",
                                               walk.points[-1].tau, why)),
                                 seconds=time.perf_counter() - t0)
        raise


def _check_walk(max_step, max_points) -> None:
    """ValueError unless ``max_step`` ∈ (0, 1] and ``max_points`` ∈ [2, :data:`MAX_POINTS`]
    (a branch has its start and one more point at least)."""
    within("max_step", max_step, 0.0, 1.0, open_lo=True)
    integer("max_points", max_points, 2, MAX_POINTS)


def continuation_path(problem: Problem, param: str | None = None, to: float | None = None,
                      **options):
    """:func:`follow_branch` as a table: one row per point, with its ``equilibrium``.

    Returns
    -------
    pandas.DataFrame
        Columns ``lambda``, the parameter (if one), ``energy``, ``r_end``,
        ``z_end``, ``psi_end``, ``stable``, ``negative_eigenvalues``, ``event``
        and ``equilibrium``.
    """
    return follow_branch(problem, param, to, **options).to_dataframe(equilibria=True)


def _path(solver, problem: Problem, param, to, anchors) -> tuple[ParameterLine, Equilibrium]:
    """The path and the solution at its start (along a parameter: ``problem``'s, as solve()
    finds it, switching where its path from the stress-free parameters loses stability at a
    branch point)."""
    if (param is None) != (to is None):
        raise ValueError("give both param and to (one parameter from problem's value to "
                         "another), or neither (the path from the stress-free parameters)")
    if param is not None:
        line = ParameterLine.along(problem, param, to)
        return line, continue_to(solver, problem, anchors, switch=True)
    source = neutral_problem(problem)
    if source is None:
        raise ValueError(f"{problem.family!r} at these parameters is stress-free already: "
                         f"continue one parameter instead (param=..., to=...)")
    return ParameterLine.between(source, problem), solver.solve(source, anchors=anchors)


class _Walk:
    """The steps of one branch: points, events and snaps as they are found."""

    def __init__(self, arc: Arclength, follow: str, max_step: float, max_points: int,
                 ends: tuple[float, ...] = (1.0,)):
        self.arc, self.follow, self.max_step, self.max_points = arc, follow, max_step, max_points
        # where the walk ends: λ = 1 going up; a switched branch also at λ = 0 going down
        self.ends = ends
        self.points: list[BranchPoint] = []
        self.snaps: list[Snap] = []
        self.switches: list[Switch] = []
        self.remeshed: list[float] = []
        self.ended: Ending | None = None
        self._cells: np.ndarray | None = None     # widths where the mesh was built (first point)

    def record(self, point: ArcPoint, event: str = "", eq: Equilibrium | None = None,
               negative: int | None = None) -> None:
        """Add ``point`` (its equilibrium ``eq`` if at hand) as a :class:`BranchPoint`.

        At a fold or branch point (``negative`` given: the fewer negative
        eigenvalues of its two sides) the reduced Hessian is singular, so the
        point is marginal, not stable, whichever side the located point fell on.
        """
        eq = eq if eq is not None else self.arc.equilibrium(point)
        tau = float(point.tau)
        stable = bool(point.inertia.stable) if negative is None else False
        negative = int(point.inertia.negative) if negative is None else int(negative)
        self.points.append(BranchPoint(
            tau, self.arc.line.values(tau), float(eq.energy), float(eq.r[-1]),
            float(eq.z[-1] - eq.z[0]),
            float(eq.psi[-1]), negative, stable, event, eq))

    def run(self, start: Equilibrium) -> None:
        """Step from ``start`` (τ = 0) until τ = 1."""
        point = self.arc.start(start, 0.0, 1.0)
        self.record(point)
        self._steps(point)

    def switched(self, origin: BranchPoint, direction: float) -> None:
        """Step from the branch point ``origin`` onto the other branch through it, to an end.

        The first step leaves the point along the switched tangent (its τ
        component near 0 at a pitchfork: no fold is looked for between the
        two); its step is halved until the corrector converges.
        """
        at = self.arc.start(origin.equilibrium, origin.tau)
        # (origin holds the fewer negative eigenvalues of its two sides)
        sign = -1.0 if at.inertia.negative > origin.negative_eigenvalues else 1.0
        at = self.arc.switch(at, direction, sign)
        self.record(at, "branch_point", origin.equilibrium, origin.negative_eigenvalues)
        first = self.arc.first_step(at, self.max_step / 4)
        if first is None:
            raise self._ended(at, "no step left the branch point")
        self.record(first)
        self._steps(first)

    def _steps(self, point: ArcPoint) -> None:
        """Step on from ``point`` until an end (:attr:`ends`)."""
        ds = self.max_step / 4
        while True:
            if len(self.points) >= self.max_points:
                raise self._ended(point, f"{self.max_points} points", "the points ran out: "
                                  "raise max_points (--max-points) or max_step (--max-step)")
            new, step = self._step(point, ds)
            failed = new is None or self.arc.turned(point, new)      # (turned: a jump?)
            if not failed and not self._holds(new):
                moved = self._remeshed(point)
                if moved is not None:           # (the step again, on the new mesh)
                    log.debug("mesh rebuilt for the parameters at lambda = %.6g", point.tau)
                    point = moved
                    continue
                failed = True                   # (its mesh does not hold, and stays)
            rejected = failed or self.arc.folds_within(point, new, step, self.max_step)
            self._log_step(point, new, step, rejected)
            if rejected:
                ds /= 2
                if ds < MIN_STEP:
                    raise self._ended(point, "the step fell below its minimum")
                continue
            self._on_path(point, new)
            point, done = self._physical(point, new, step)
            if done:
                return
            ds = min(GROWTH * ds, self.max_step) if new.iterations <= EASY else ds

    def _step(self, point: ArcPoint, ds: float) -> tuple[ArcPoint | None, float]:
        """(the point at arclength ``ds`` from ``point``, or None where the corrector fails;
        the step's arclength): a step that passes an end of the walk (:meth:`_end_within`)
        to parameters out of their ranges is shortened to land on the end (τ fixed there:
        :meth:`Arclength.at_tau`; None where that fails, and the step is retried at half).
        A path to an end of a parameter's range leaves it one step past (``--param sigma
        --to 0.001``, its bound, failed after the walk as bad input naming sigma =
        0.000985: audit 17).  Within the ranges the step past the end stays as it was, its
        events located over the whole step (shortened, they move within their tolerance, and
        a thin blister's switch 1e-4 before the end landed 8e-8 of its energy away)."""
        new = self.arc.correct(point, ds)
        end = None if new is None else self._end_within(point, new)
        if end is None or self.arc.line.invalid(new.tau) is None:
            return new, ds
        last = self.arc.at_tau(point, end)
        return (None, ds) if last is None else (last, self.arc.distance(point, last))

    def _end_within(self, point: ArcPoint, new: ArcPoint,
                    rising: bool | None = None) -> float | None:
        """The end of the walk (:attr:`ends`) that the step from ``point`` to ``new`` passes
        or reaches going toward it (τ growing at ``new``, or as ``rising`` says), or None."""
        rising = new.t_tau > 0 if rising is None else rising
        for end in self.ends:
            if min(point.tau, new.tau) < end <= max(point.tau, new.tau) and \
                    rising == (end > point.tau):
                return end
        return None

    def _end_at(self, point: ArcPoint, end: float) -> tuple[ArcPoint, bool]:
        """The walk's last point: its branch at the end ``end`` next to ``point``, recorded
        (a fold just past a path's end, located beyond it, had been recorded there, the
        quasi-static walk snapping from it although the shell never reaches it; and
        where the parameters there leave their ranges, its ValueError ended the walk as
        bad input)."""
        last = self.arc.at_tau(point, end)
        if last is None:
            raise self._ended(point, f"no state found at its end, lambda = {end:g}, "
                                     f"just before a fold")
        self.record(last)
        return last, True

    def _on_path(self, point: ArcPoint, new: ArcPoint) -> None:
        """The branch's end (a SolverError, ``"Branch_Ended"``) where the step from ``point``
        leaves the path: to parameters out of their ranges (a branch that turns back past
        its start; the last point within them is the last), or beyond :data:`TAU_MARGIN`
        past an end."""
        why = self.arc.line.invalid(new.tau)
        if why is not None:
            raise self._ended(point, f"it left the parameters' ranges at lambda = "
                                     f"{new.tau:.6g}", f"{why}: the branch goes on "
                                     f"beyond them, where the model does not hold")
        if not -TAU_MARGIN <= new.tau <= 1 + TAU_MARGIN:
            raise self._ended(new, "it left the path", self._left(new))

    def _physical(self, point: ArcPoint, new: ArcPoint, ds: float) -> tuple[ArcPoint, bool]:
        """:meth:`_advance` to ``new``, or where its meridian crosses the axis, which
        ``solve()`` refuses (:func:`~.branch_checks.crossing_end`), to the last point of the
        step that does not, where the branch ends (:attr:`ended`) unless a snap or switch
        within the step leaves it first."""
        eq = self.arc.equilibrium(new)
        cut = crossing_end(self.arc, point, new, ds, eq)
        if cut is None:
            return self._advance(point, new, ds, eq)
        last, s, self.ended = cut
        if s <= 0:                              # (``point``, recorded, is the last)
            return point, True
        onward, done = self._advance(point, last, s)
        if done or onward is not last:          # (the end reached, or a snap or switch first)
            self.ended = None
        return onward, done or onward is last

    def _left(self, new: ArcPoint) -> str:
        """What happened to a branch that left the path (beyond :data:`TAU_MARGIN` past an
        end), and what helps: neither a smaller step nor a finer mesh."""
        folds = [pt.tau for pt in self.points if pt.event == "fold"]
        turned = (f"it turned back at the fold{'s' * (len(folds) > 1)} at "
                  f"{', '.join(where(self.arc.line, t) for t in folds)} and " if folds else "")
        side = -TAU_MARGIN if new.tau < 0 else 1 + TAU_MARGIN
        return (f"{turned}went on beyond lambda = {side:g}"
                f" without reaching the path's end (lambda = 1): the branch does not reach it "
                f"within {TAU_MARGIN:g} of the path's ends (a smaller step or a finer mesh does "
                f"not change that); follow='stable' (--follow stable) snaps through at its "
                f"folds, or continue to a value the branch reaches (beyond its turning points)")

    def _widths(self, tau: float) -> np.ndarray:
        """The cells' widths in s of the walk's mesh at ``tau``."""
        return np.diff(self.arc.solver.disc.nodes(self.arc.parameters(tau), self.arc.q))

    def _holds(self, new: ArcPoint) -> bool:
        """Whether the mesh at ``new`` has no cell stretched or squeezed by :data:`REMESH`
        from where it was built (scaled as a whole: a longer shell's cells all grow)."""
        if self._cells is None:
            self._cells = self._widths(self.points[0].tau)
        ratio = self._widths(new.tau) / self._cells
        ratio = ratio / np.median(ratio)
        return bool(ratio.min() > 1 / REMESH and ratio.max() < REMESH)

    def _remeshed(self, point: ArcPoint) -> ArcPoint | None:
        """``point`` carried onto a mesh rebuilt for the parameters there (its stationary
        point by Newton's iterations, a saddle staying a saddle), the walk's arc that
        mesh's; None where it stays there already or the iterations fail."""
        if self.remeshed and self.remeshed[-1] == point.tau:
            return None
        solver, line = self.arc.solver, self.arc.line
        problem = line.at(point.tau)
        fresh = direct_solver(problem, solver.nodes, tuple(self.arc.q), stages=solver.stages)
        arc = Arclength(fresh, line, self.arc.q, at=point.tau)
        x = fresh.carried(self.arc.equilibrium(point), problem.parameter_vector(), arc.q)
        found = arc.stationary(x, point.tau)
        if found is None:
            return None
        moved = arc.start(arc.equilibrium(found), point.tau, 1.0 if point.t_tau >= 0 else -1.0)
        self.arc, self.remeshed = arc, [*self.remeshed, point.tau]
        self._cells = self._widths(point.tau)
        return moved

    def _log_step(self, point: ArcPoint, new: ArcPoint | None, ds: float,
                  rejected: bool) -> None:
        """Each pseudo-arclength step at DEBUG (``-vv``): where it went, its size, the
        corrector's Newton iterations and the inertia, or why it is retried halved, to
        follow a walk that misses an event or crawls (user audit)."""
        if not log.isEnabledFor(logging.DEBUG):
            return
        if rejected:
            log.debug("step %.3g from lambda = %.6g %s: halved", ds, point.tau,
                      "did not converge" if new is None
                      else "turned, went back in lambda or left its mesh")
            return
        values = self.arc.line.values(new.tau)
        # (one parameter's value; the path from the stress-free parameters moves many)
        where = "".join(f" ({k} = {v:.6g})" for k, v in values.items() if len(values) == 1)
        log.debug("lambda = %.6g%s: step %.3g, %d Newton iterations, %d negative and %d "
                  "zero eigenvalues", new.tau, where, ds, new.iterations,
                  new.inertia.negative, new.inertia.zero)

    def _advance(self, point: ArcPoint, new: ArcPoint, ds: float,
                 eq: Equilibrium | None = None) -> tuple[ArcPoint, bool]:
        """Record the events between ``point`` and ``new`` and ``new`` itself (its
        equilibrium ``eq`` if at hand), or the end at τ = 1, or the snap-through: (the next
        point to step from, whether done)."""
        if np.sign(new.t_tau) != np.sign(point.t_tau):
            fold = self.arc.locate_fold(point, ds)
            end = self._end_within(point, fold, point.t_tau > 0)
            if end is not None:    # (past the end, before the fold: the walk ends first)
                return self._end_at(point, end)
            self.record(fold, "fold", negative=min(point.inertia.negative, new.inertia.negative))
            if self.follow == "stable" and point.inertia.stable:
                return self._snap(fold)
        elif new.inertia.negative != point.inertia.negative:
            before = point
            for change in self.arc.locate_changes(point, new, ds):
                # one past the path's end (the last step overshoots τ = 1) is not on the
                # branch returned, which ends at τ = 1: recorded, it would precede the end
                if change.tau > 1 and point.tau < 1:
                    break
                self.record(change, "branch_point",
                            negative=min(before.inertia.negative, change.inertia.negative))
                if self.follow == "stable" and before.inertia.stable and change.tau < 1:
                    return self._switch(change, ds)
                before = change
        end = self._end_within(point, new)
        if end is not None:        # (at it: :meth:`_step` shortened the step to land there)
            last = new if new.tau == end else self.arc.at_tau(point, end) or new
            self.record(last, eq=eq if last is new else None)
            return last, True
        self.record(new, eq=eq)
        return new, False

    def _switch(self, bp: ArcPoint, ds: float) -> tuple[ArcPoint, bool]:
        """Where the branch loses its stability at ``bp``: on along the stable half of the
        other branch through it (a shell loaded slowly follows it), from its first point
        (:meth:`_landing`)."""
        eq, tau, switch = switch_stable(self.arc, bp, ds)
        self.switches.append(switch)
        return self._landing(eq, tau, "")

    def _snap(self, fold: ArcPoint) -> tuple[ArcPoint, bool]:
        """Snap through at ``fold``; the walk goes on from the snapped equilibrium
        (:meth:`_landing`)."""
        eq, snap = snap_through(self.arc, fold, 1.0)
        self.snaps.append(snap)
        return self._landing(eq, snap.tau_after, "snap")

    def _landing(self, eq: Equilibrium, tau: float, event: str) -> tuple[ArcPoint, bool]:
        """(the point the walk goes on from, whether done): ``eq`` at ``tau``, recorded; a
        landing past the path's end (a fold or branch point within the overshoot before
        τ = 1) is at extrapolated parameters, so its branch is solved at τ = 1 and ends
        the walk (one at 1 itself, where the parameters past it leave their ranges, is
        there: :func:`~.crossings._descend`)."""
        done = tau >= 1.0
        if tau > 1.0:
            eq, tau = self.arc.solver.solve(self.arc.line.at(1.0), warm_start=eq,
                                            anchors=self.arc.q), 1.0
        start = self.arc.start(eq, tau, 1.0)
        self.record(start, event, eq)
        return start, done

    def _ended(self, point: ArcPoint, why: str, remedy: str | None = None):
        return branch_ended(point.tau, why, self.arc.equilibrium(point), remedy)
