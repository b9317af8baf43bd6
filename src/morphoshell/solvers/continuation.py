"""Parameter continuation: reach a problem along its physical branch.

A cold solve starts Ipopt from the undeformed shell and lets it find *a*
minimum; for thin anisotropic or Volvox shells that can be a spurious local
minimum with several times the energy (found in about 2 % of such problems,
edge values sometimes right to 3e-7 so that edge checks miss it).  The
physical branch is the one that grows continuously out of the stress-free
shell.  :func:`continue_to` follows it: it solves the problem at the family's
*neutral* parameters (the undeformed sphere is the exact solution there) and
moves the parameters linearly to the target, each step warm-started from the
previous solution, with adaptive step sizes:

* a step that fails, needs many Newton iterations, or moves the solution far
  more than the previous steps, or turns the tangent somewhere by more than a
  quarter turn (a jump to another branch, or into a loop) is retried at a
  quarter of its size;
* easy steps double the next one.

Parameters that the family does not list in ``neutral`` (the thickness, the
cut, the opening and, for Volvox, the breakpoints) keep their target values
throughout: the undeformed shell is stress-free for any of them.
"""
from __future__ import annotations

import logging
import time
from dataclasses import dataclass, replace

import numpy as np

from ..model.problem import Problem
from ..numerics.status import CONTINUATION_FAILED, explain
from .direct import DirectSolver
from .results import Equilibrium, SolverError

__all__ = ["continue_to", "continue_between", "Path", "neutral_problem"]

log = logging.getLogger(__name__)

#: A step that needs more Newton iterations than this is retried smaller.
HARD_STEP = 15
#: ... and one that needs at most this many lets the next step grow.
EASY_STEP = 5
#: A step whose solution moves more than this many times the previous rate
#: (change per unit of the path parameter) is taken for a branch jump.
JUMP_FACTOR = 8.0
#: Smallest step of the path parameter τ ∈ [0, 1] before giving up.
MIN_STEP = 1e-4
#: A step that turns the tangent ψ at some point by more than this (radians)
#: is retried smaller.  The jump test needs a previous step; thin shells can
#: snap into loops on the first one (the tangent winding by 2π over a few
#: cells, cheap in bending: fuzzing found an anisotropic sphere, h = 1e-3,
#: f0 = −0.29, whose first step of a quarter turned ψ by 7 rad and ended 17 %
#: above the physical energy, its error estimate covering neither).
MAX_TURN = np.pi / 2


@dataclass(frozen=True)
class Path:
    """How a solution was reached (``Equilibrium.solver.details["path"]``).

    Attributes
    ----------
    kind : {"continuation", "cold", "warm start"}
    steps, rejected : int
        Continuation steps taken and retried smaller.
    iterations : int
        Newton (or Ipopt) iterations of every step.
    """

    kind: str
    steps: int = 1
    rejected: int = 0
    iterations: int = 0

    def describe(self) -> str:
        """One line saying how the solution was reached (stored in ``solver.details["path"]``)."""
        if self.kind != "continuation":
            return self.kind
        return (f"continuation from the stress-free parameters in {self.steps} steps "
                f"({self.rejected} retried, {self.iterations} Newton iterations)")


def neutral_problem(problem: Problem) -> Problem | None:
    """``problem`` at its family's stress-free parameters, or None if it has none to move.

    The family's ``neutral`` values (:class:`morphoshell.model.profiles.ProfileFamily`)
    make the undeformed shell stress-free: the start of :func:`continue_to`.
    """
    neutral = {n: v for n, v in problem.family_obj.neutral.items() if n in problem.params}
    if not neutral or all(problem.params[n] == v for n, v in neutral.items()):
        return None
    return problem.with_updates(**neutral)


def continue_to(solver: DirectSolver, problem: Problem, anchors=(), *, first_step: float = 0.25,
                max_steps: int = 200) -> Equilibrium:
    """Solve ``problem`` by continuation from its family's neutral parameters.

    Parameters
    ----------
    solver : DirectSolver
        Built for ``problem.structure``.
    problem : Problem
    anchors : sequence of float
        Mesh anchors, as for :meth:`DirectSolver.solve`.
    first_step : float
        First step of the path parameter τ ∈ (0, 1].
    max_steps : int
        Accepted and rejected steps together.

    Returns
    -------
    Equilibrium
        With ``solver.details["path"]`` the :class:`Path` taken and
        ``solver.iterations`` the Newton iterations of all steps.

    Raises
    ------
    SolverError
        Status ``"Continuation_Failed"`` when the step falls below
        :data:`MIN_STEP` or the steps run out; the last solution reached is
        attached.
    """
    t0 = time.perf_counter()
    start = neutral_problem(problem)
    if start is None:
        eq = solver.solve(problem, anchors=anchors)
        return _with_path(eq, Path("cold", 1, 0, eq.solver.iterations), t0)
    eq = solver.solve(start, anchors=anchors)
    steps, rejected, iterations, eq = _follow(solver, eq, problem, anchors, first_step, max_steps,
                                              "the stress-free parameters")
    return _with_path(eq, Path("continuation", steps, rejected, iterations + eq.solver.iterations),
                      t0)


def continue_between(solver: DirectSolver, start: Equilibrium, problem: Problem, anchors=(), *,
                     first_step: float = 1.0, max_steps: int = 200) -> Equilibrium:
    """Solve ``problem`` by continuation from a solution ``start`` on the same solver.

    The parameters that differ move linearly from ``start``'s to
    ``problem``'s, with the adaptive steps of :func:`continue_to` (a first
    full step: a nearby start is usually one warm solve away).  This keeps a
    sequence of solves on one branch of equilibria when the parameters jump
    (a derivative-free fit's simplex does): the Volvox shell has several
    stable equilibria, nearly equal in energy but of different shapes, and
    a warm start from a distant state can land on another.

    Parameters
    ----------
    solver : DirectSolver
        Built for ``problem.structure``; ``start`` is a solution on it.
    start : Equilibrium
        The solution to continue from.
    problem : Problem
        The target.
    anchors : sequence of float
        Mesh anchors, as for :meth:`DirectSolver.solve`.
    first_step : float
        First step of the path parameter τ ∈ (0, 1].
    max_steps : int
        Accepted and rejected steps together.

    Returns
    -------
    Equilibrium
        With ``solver.details["path"]`` the :class:`Path` taken.

    Raises
    ------
    SolverError
        Status ``"Continuation_Failed"``, as :func:`continue_to`.
    """
    t0 = time.perf_counter()
    steps, rejected, iterations, eq = _follow(solver, start, problem, anchors, first_step,
                                              max_steps, "a previous solution")
    return _with_path(eq, Path("continuation", steps, rejected, iterations), t0)


@dataclass(frozen=True)
class _Line:
    """The straight path from a solution's parameters to a problem's: the ones that differ."""

    problem: Problem
    names: tuple
    a: np.ndarray
    b: np.ndarray

    @classmethod
    def between(cls, source: Problem, problem: Problem) -> "_Line":
        """From ``source``'s values of the parameters that differ to ``problem``'s."""
        names = [n for n in problem.params if problem.params[n] != source.params.get(n)]
        names += [n for n in ("h", "cut", "opening") if getattr(problem, n) != getattr(source, n)]
        a = np.array([source.params[n] if n in source.params else getattr(source, n)
                      for n in names])
        b = np.array([problem.params[n] if n in problem.params else getattr(problem, n)
                      for n in names])
        return cls(problem, tuple(names), a, b)

    def at(self, tau: float) -> Problem:
        """The problem at τ of the way (τ = 1: the target itself)."""
        if tau == 1:
            return self.problem
        return self.problem.with_updates(**dict(zip(self.names, self.a + tau * (self.b - self.a))))


@dataclass
class _Progress:
    """Where a continuation is: τ reached, the next step, the largest rate and the counts."""

    step: float
    tau: float = 0.0
    rate: float | None = None      # largest change of x per unit of τ so far
    steps: int = 0
    rejected: int = 0
    iterations: int = 0

    def exhausted(self, max_steps: int) -> bool:
        """Whether the steps ran out or the step fell below :data:`MIN_STEP`."""
        return self.steps + self.rejected >= max_steps or self.step < MIN_STEP

    def reject(self) -> None:
        """A step retried at a quarter of its size."""
        self.rejected += 1
        self.step /= 4

    def accept(self, trial: float, change: float, iterations: int) -> None:
        """A step to τ = ``trial``; an easy one doubles the next."""
        self.steps += 1
        self.iterations += iterations
        self.rate = change if self.rate is None else max(self.rate, change)
        self.tau = trial
        if iterations <= EASY_STEP:
            self.step *= 2


def _solve_at(solver: DirectSolver, problem: Problem, eq: Equilibrium,
              anchors) -> Equilibrium | None:
    """``problem`` warm-started from ``eq``, or None if that fails."""
    try:
        return solver.solve(problem, warm_start=eq, anchors=anchors)
    except (SolverError, ValueError):    # ValueError: a breakpoint left its mesh's range
        return None


def _rejection(new: Equilibrium | None, eq: Equilibrium, change, rate) -> str:
    """Why the step from ``eq`` to ``new`` is retried smaller ("" if it is taken).

    ``change`` is the step's max |Δx| per unit of τ, ``rate`` the largest of
    the steps before (None before the first).
    """
    if new is None:
        return "failed"
    jumped = rate is not None and change > JUMP_FACTOR * rate \
        or np.max(np.abs(new.psi - eq.psi)) > MAX_TURN
    if jumped:
        return "jumped"
    if new.solver.iterations > HARD_STEP:
        return f"{new.solver.iterations} iterations"
    return ""


def _follow(solver, eq, problem, anchors, first_step, max_steps, origin):
    """Continue from the solution ``eq`` to ``problem``: (steps, rejected, iterations, solution)."""
    line = _Line.between(eq.problem, problem)
    run = _Progress(float(first_step))
    name = problem.name or problem.family
    while run.tau < 1:
        if run.exhausted(max_steps):
            raise SolverError(
                f"continuation from {origin} stopped at {run.tau:.4g} of the way to {name!r} "
                f"({run.steps} steps, {run.rejected} retried, step {run.step:.2g}): "
                f"{explain(CONTINUATION_FAILED)}; the last solution reached is attached",
                CONTINUATION_FAILED, eq)
        trial = min(1.0, run.tau + run.step)
        new = _solve_at(solver, line.at(trial), eq, anchors)
        change = None if new is None else np.max(np.abs(new.x - eq.x)) / (trial - run.tau)
        why = _rejection(new, eq, change, run.rate)
        if why:
            log.debug("continuation to %s: step to tau = %.4g retried smaller (%s)", name, trial,
                      why)
            run.reject()
            continue
        log.debug("continuation to %s: tau = %.4g reached in %d iterations", name, trial,
                  new.solver.iterations)
        run.accept(trial, change, new.solver.iterations)
        eq = new
    return run.steps, run.rejected, run.iterations, eq


def _with_path(eq: Equilibrium, path: Path, t0: float) -> Equilibrium:
    stats = replace(eq.solver, iterations=path.iterations, seconds=time.perf_counter() - t0,
                    details={**eq.solver.details, "path": path.describe(),
                             "continuation_steps": path.steps})
    return replace(eq, solver=stats)
