"""The warm path of a sweep's chunk: one shell followed from point to point.

A chunk's points are solved in order (:mod:`morphoshell.workflows.sweeps`), each
warm-started from the one before: a :class:`Shell` keeps the last solution and
reaches the next point by one warm step, split in halves where the step is hard
(more than :data:`~morphoshell.solvers.continuation.HARD_STEP` Newton iterations or a
failure: at most :data:`MAX_SPLITS` times) or its mesh does not hold, and by
``solve()``'s route (continuation from the stress-free parameters) where the warm
path cannot go on, where it left its branch, or after a snap-through or a switch of
branches.

A warm step that converges past a fold lands on the branch beyond it, as any other:
a sweep of the fold shell's κ₂ from −1 to −8 jumped between −6.5 and −7 (the fold at
−6.5739) and its rows said nothing, while the same rows swept the other way, and
``solve()`` at −7, said ``snapped`` (audit 14).  Every accepted warm step is checked
(:func:`~morphoshell.solvers.continuation.left_branch`); a step that left its branch
is split like a hard one, and where it cannot be split further the point is solved
by ``solve()``'s route, whose row says what that route crossed, and the sweep notes
the point (:attr:`Shell.jumped`).
"""
from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import Any, Mapping

from ..model.problem import Problem
from ..numerics.mesh import mesh_spec
from ..numerics.status import STEP_NOT_SPLITTABLE
from ..solvers.continuation import HARD_STEP, continue_to, left_branch
from ..solvers.direct import DirectSolver, solver_of
from ..solvers.refinement import solve_from
from ..solvers.results import Equilibrium, SolverError
from ..solvers.routes import direct_solver

__all__ = ["Shell", "point_events", "MAX_SPLITS", "SOLVER_CACHE_SIZE"]

log = logging.getLogger("morphoshell.workflows.sweeps")

#: A failing warm step is halved at most this many times (16 sub-steps).
MAX_SPLITS = 4

#: Solvers of this worker process, by (structure, mesh, options): one build per mesh.
_SOLVERS: dict = {}
#: Bound of the worker's solver cache (least recently used dropped first); a
#: sweep over one line needs about 15 (intact shells anchored at 12 knots).
SOLVER_CACHE_SIZE = 48


def _solver(problem: Problem, nodes: int, anchors: tuple, options: Mapping) -> DirectSolver:
    """The worker's solver of the mesh ``solve()`` builds for ``problem``, cached.

    Least recently *used* dropped first: dropping the least recently built dropped the
    solver of the point just solved when its error estimate built the half and quarter
    meshes into a full cache, and the next warm step carried its state onto a new
    solver of the same mesh (path "remesh", other iterations and last bits, depending
    on what earlier sweeps in the process had cached)."""
    spec = mesh_spec(problem, nodes, options.get("stages", 2), anchors)
    key = (problem.structure, spec, tuple(sorted((k, repr(v)) for k, v in options.items())))
    solver = _SOLVERS.pop(key, None)
    if solver is not None:
        _SOLVERS[key] = solver          # (now the most recently used)
    else:
        solver = _SOLVERS[key] = direct_solver(problem, nodes, anchors, **options)
        while len(_SOLVERS) > SOLVER_CACHE_SIZE:
            _SOLVERS.pop(next(iter(_SOLVERS)))
    return solver


@dataclass
class Shell:
    """One shell (intact or cut) followed along a chunk: the last solution reached."""

    nodes: int
    options: Mapping[str, Any]
    last: tuple | None = None       # (problem, anchors, eq)
    iterations: int = 0
    #: Every point by ``solve()``'s route (continuation), none warm: where the warm path
    #: and ``solve()``'s end on different stable states (:func:`_left_solves_branch`).
    verify: bool = False
    #: The last point's continuation snapped or switched branches: the next point's route
    #: may not (its own path from the stress-free parameters has no fold), and a warm step
    #: would stay on the branch the snap landed on.
    crossed: bool = False
    #: The warm path to the last point left its branch (:func:`~morphoshell.solvers.
    #: continuation.left_branch`) and the point was solved by ``solve()``'s route instead.
    jumped: bool = False

    def solver(self, problem: Problem, anchors: tuple, nodes: int | None = None) -> DirectSolver:
        """The worker's solver of ``problem``'s mesh (``nodes``, default the shell's), cached."""
        return _solver(problem, nodes or self.nodes, anchors, self.options)

    def advance(self, problem: Problem, anchors: tuple) -> tuple[Equilibrium, str]:
        """The equilibrium of ``problem``, from the last one if there is one and its branch
        is ``solve()``'s (:attr:`verify`, :attr:`crossed`); (eq, path)."""
        solver = self.solver(problem, anchors)
        last, self.last, self.iterations, self.jumped = self.last, None, 0, False
        eq = None
        if last is not None and last[0].structure == problem.structure and not self.verify \
                and not self.crossed:
            try:
                eq, steps, remeshed = self._step(*last, problem, anchors, 0)
                path = "split" if steps > 1 else "remesh" if remeshed else "warm"
            except SolverError as exc:
                self._count(exc.last_iterate)
                log.debug("sweep: warm steps to %s failed (%s); continuation", problem.params,
                          exc.status)
            except _LeftBranch:
                self.jumped = True
                log.info("sweep: the warm path from %s to %s left its branch (a fold or branch "
                         "point between them); the point by solve()'s route",
                         last[0].name or last[0].params, problem.name or problem.params)
        if eq is None:
            try:
                eq = self._count(continue_to(solver, problem, anchors, switch=True))  # (as solve)
            except SolverError as exc:
                self._count(exc.last_iterate)      # (the row's iterations: not 0 after 53)
                raise
            path = "continuation"
        self.crossed = _crossed(eq)
        self.last = (problem, anchors, eq)
        return eq, path

    def _count(self, eq: Equilibrium | None) -> Equilibrium | None:
        if eq is not None:
            self.iterations += eq.solver.iterations
        return eq

    def _step(self, a: Problem, a_anchors, a_eq, b: Problem, b_anchors,
              depth: int) -> tuple[Equilibrium, int, bool]:
        """From a's solution to b on b's mesh: one warm step, or two halves (recursively),
        each on its own end's mesh; (eq, steps, whether a solution was carried to a new mesh).

        Where b's mesh is not a's, a's solution is carried onto it at a's parameters
        (:func:`~morphoshell.solvers.refinement.solve_from`).  Where that mesh does not hold
        there (a breakpoint moved past the place of its knot: ValueError from the mesh's
        check, a Volvox s2 step of 0.1), the step is split: the first half ends on the
        midpoint's own mesh, from which the second carries on, as ``continue`` rebuilds its
        mesh for the parameters it has reached.
        """
        carried = False
        try:
            # (a midpoint's mesh may not hold its knots: split on, as where it does not hold
            # a's solution)
            solver = self.solver(b, b_anchors)
            carried = solver_of(a_eq) is not solver
            if carried:     # (kept for the halves: usually b's mesh is the midpoint's too)
                a_eq = self._count(solve_from(solver, a, a_eq, a_anchors))
            eq = self._count(solver.solve(b, warm_start=a_eq, anchors=b_anchors))
            taken = eq.solver.iterations <= HARD_STEP or depth >= MAX_SPLITS
        except (SolverError, ValueError) as exc:     # (ValueError: the mesh does not hold)
            if isinstance(exc, SolverError):
                self._count(exc.last_iterate)
            if depth >= MAX_SPLITS:
                raise _unsplittable(exc, b) from exc
            taken = False
        if taken:
            # (a jump halved: a step too long for Newton's basin stays on its branch when
            # shorter; past a fold every half down to the last jumps)
            if not left_branch(solver, a_eq, eq):
                return eq, 1, carried
            if depth >= MAX_SPLITS:
                raise _LeftBranch()
        mid = _midpoint(a, b, a_anchors, b_anchors)
        if mid is None:
            raise SolverError("no midpoint to split the step at", STEP_NOT_SPLITTABLE)
        m_eq, n1, c1 = self._step(a, a_anchors, a_eq, *mid, depth + 1)
        eq, n2, c2 = self._step(*mid, m_eq, b, b_anchors, depth + 1)
        return eq, n1 + n2, carried or c1 or c2


class _LeftBranch(Exception):
    """A warm step of the last split that left its branch (:meth:`Shell._step`)."""


def _unsplittable(exc: Exception, b: Problem) -> SolverError:
    """The failure of a warm step that cannot be split further, as a SolverError."""
    if isinstance(exc, SolverError):
        return exc
    return SolverError(f"warm steps to {b.params}: {exc}", STEP_NOT_SPLITTABLE)


def _crossed(eq: Equilibrium) -> bool:
    """Whether ``eq``'s continuation snapped through a fold or switched branches."""
    return bool(point_events(eq))


def point_events(eq: Equilibrium) -> tuple[str, ...]:
    """What ``eq``'s continuation crossed: ``"snapped"`` (a fold), ``"switched"`` (branches
    at a branch point), both or neither (the row's ``event``)."""
    details = eq.solver.details
    return tuple(word for key, word in (("snaps", "snapped"), ("switches", "switched"))
                 if details.get(key))


def _midpoint(a: Problem, b: Problem, a_anchors, b_anchors):
    """(problem, anchors) halfway between a and b, or None (a word differs, or invalid)."""
    if a.structure != b.structure:
        return None
    try:
        mid = a.with_updates(h=(a.h + b.h) / 2, cut=(a.cut + b.cut) / 2,
                             opening=(a.opening + b.opening) / 2,
                             **{k: (a.params[k] + b.params[k]) / 2 for k in a.params})
    except ValueError:
        return None
    return mid, tuple((x + y) / 2 for x, y in zip(a_anchors, b_anchors))

