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
  quarter of its size; so is a first step (none before it to compare with)
  that strays from the branch's tangent at its start by more than the
  tangent's prediction itself;
* easy steps double the next one.

Parameters that the family does not list in ``neutral`` (the thickness, the
cut, the opening and, for Volvox, the breakpoints) keep their target values
throughout: the undeformed shell is stress-free for any of them.
"""
from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field, replace

import numpy as np

from ..model.problem import Problem
from ..numerics.status import CONTINUATION_FAILED, MERIDIAN_CROSSES_AXIS, SNAP_FAILED, explain
from .arclength import Arclength, Switch
from .crossings import cross_fold
from .direct import DirectSolver, pole_crossing
from .paths import ParameterLine, neutral_problem
from .results import Equilibrium, SolverError

__all__ = ["continue_to", "continue_between", "Path", "neutral_problem", "MAX_SNAPS",
           "left_branch", "SAME_STATE"]

log = logging.getLogger(__name__)

#: A step that needs more Newton iterations than this is retried smaller.
HARD_STEP = 15
#: ... and one that needs at most this many lets the next step grow.
EASY_STEP = 5
#: A step whose solution moves more than this many times the previous rate
#: (change per unit of the path parameter) is taken for a branch jump.  The
#: rate is kept for x and for the tangent ψ apart: x mixes angles with
#: stretches, and a stretch moving with the parameter can hide a jump of the
#: shape (fuzzing: a cap 1e-3 R wide, h = 1e-4, flat until it buckles at
#: f0 ≈ 0.013, whose step from 0.011 to 0.026 turned ψ by 0.2 rad to the
#: mirror side, 0.15 % higher in energy, at 4× the rate of x before).
JUMP_FACTOR = 8.0
#: ... but a turn of ψ below this (radians) is not taken for a jump whatever
#: its rate (ψ at rest to round-off has no rate to compare with).
JUMP_TURN = 0.05
#: Smallest step of the path parameter τ ∈ [0, 1] before giving up.
MIN_STEP = 1e-4
#: A step that turns the tangent ψ at some point by more than this (radians)
#: is retried smaller.  The jump test needs a previous step; thin shells can
#: snap into loops on the first one (the tangent winding by 2π over a few
#: cells, cheap in bending: fuzzing found an anisotropic sphere, h = 1e-3,
#: f0 = −0.29, whose first step of a quarter turned ψ by 7 rad and ended 17 %
#: above the physical energy, its error estimate covering neither).
MAX_TURN = np.pi / 2
#: Snap-throughs :func:`continue_to` crosses on one path before it gives up.
MAX_SNAPS = 8
#: Largest change of x (max norm) between two solutions of one state: warm solves and
#: solve()'s route agree to 1e-10 on one branch (docs/sweeps.md).
SAME_STATE = 1e-6
#: A warm solve whose change strays from its start's tangent by more than this fraction
#: of the tangent's prediction is checked by a solve back (:func:`left_branch`): ordinary
#: warm steps stray by 3-6 % (the fold shell's κ₂ steps of 0.5 on 200 nodes, 6 % next
#: to its fold), the step past the fold by 106 %.
STRAY = 0.25
#: ... and left its start's branch where that solve back ends farther from the start than
#: this fraction of the solve's own change: along one branch it returns to 1e-10 of the
#: start; past the fold shell's fold it stays on the other branch, 2.2 from the start
#: against a change of 2.2 (max norms of x).
NOT_BACK = 0.5
#: A warm step that converged in this many Newton iterations or fewer is not checked by
#: :func:`left_branch`: a jump past a fold is a long Newton path (12 and 17 iterations on
#: the fold shell's κ₂ sweep, its ordinary steps 3-5), and checking every step cost a
#: sweep of ablations about a third more (docs/benchmarks.md, "Sweeps").
QUICK_STEP = 3


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
    snaps : tuple of Snap
        The snap-throughs crossed on the way (:func:`morphoshell.solvers.crossings.snap_through`).
    origin : str
        Where a continuation started.
    switches : tuple of Switch
        The switches of branches at branch points where the branch lost its
        stability (:func:`morphoshell.solvers.crossings.cross_fold`).
    """

    kind: str
    steps: int = 1
    rejected: int = 0
    iterations: int = 0
    snaps: tuple = ()
    origin: str = "the stress-free parameters"
    switches: tuple = ()

    def describe(self) -> str:
        """One line saying how the solution was reached (stored in ``solver.details["path"]``)."""
        if self.kind != "continuation":
            return self.kind
        line = (f"continuation from {self.origin} in {self.steps} steps "
                f"({self.rejected} retried, {self.iterations} Newton iterations)")
        return "; ".join([line, *(event.describe() for event in (*self.snaps, *self.switches))])


def continue_to(solver: DirectSolver, problem: Problem, anchors=(), *, first_step: float = 0.25,
                max_steps: int = 200, switch: bool = False) -> Equilibrium:
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
    switch : bool
        Where the branch loses its stability at a branch point, go on along
        the stable half of the other branch through it (``solve``'s choice;
        a fit's inner solves stay on their branch and fail there).

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
    run, eq = _follow(solver, eq, problem, anchors, first_step, max_steps,
                      "the stress-free parameters", snap=True, switch=switch)
    return _with_path(eq, Path("continuation", run.steps, run.rejected,
                               run.iterations + eq.solver.iterations, tuple(run.snaps),
                               switches=tuple(run.switches)), t0)


def continue_between(solver: DirectSolver, start: Equilibrium, problem: Problem, anchors=(), *,
                     first_step: float = 1.0, max_steps: int = 200,
                     snap: bool = False) -> Equilibrium:
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
    snap : bool
        Cross a fold where the branch ends as the shell would, by its
        snap-through (as :func:`continue_to` does; a fit's inner solves), instead
        of stopping there.

    Returns
    -------
    Equilibrium
        With ``solver.details["path"]`` the :class:`Path` taken (and its
        ``snaps``).

    Raises
    ------
    SolverError
        Status ``"Continuation_Failed"``, as :func:`continue_to`;
        ``"Snap_Through_Failed"``.
    """
    t0, origin = time.perf_counter(), "a previous solution"
    run, eq = _follow(solver, start, problem, anchors, first_step, max_steps, origin, snap=snap)
    return _with_path(eq, Path("continuation", run.steps, run.rejected, run.iterations,
                               tuple(run.snaps), origin), t0)


@dataclass
class _Progress:
    """Where a continuation is: τ reached, the next step, the largest rate and the counts."""

    step: float
    tau: float = 0.0
    rate: np.ndarray | None = None  # largest (max |Δx|, max |Δψ|) per unit of τ so far
    steps: int = 0
    rejected: int = 0
    iterations: int = 0
    snaps: list = field(default_factory=list)
    switches: list = field(default_factory=list)
    stuck: str = ""        # why crossing a stall failed, once it has (if not in remedy)
    remedy: str = ""       # what to do instead, when that is not the generic remedy

    def exhausted(self, max_steps: int) -> bool:
        """Whether the steps ran out or the step fell below :data:`MIN_STEP`."""
        return self.steps + self.rejected >= max_steps or self.step < MIN_STEP

    def reject(self) -> None:
        """A step retried at a quarter of its size."""
        self.rejected += 1
        self.step /= 4

    def accept(self, trial: float, change: np.ndarray, iterations: int) -> None:
        """A step to τ = ``trial``; an easy one doubles the next."""
        self.steps += 1
        self.iterations += iterations
        self.rate = change if self.rate is None else np.maximum(self.rate, change)
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


def _tangent(solver: DirectSolver, eq: Equilibrium, line: ParameterLine, tau: float,
             anchors) -> np.ndarray | None:
    """The branch's direction in x at the solution ``eq`` (at ``tau`` on ``line``): K⁻¹ F_τ
    (:meth:`BorderedKKT.iterate_around`, one call), or None where it is not finite.

    The jump test of later steps compares each with the steps before; the first has only
    this: a tiny cap near a pole, nearly flat, bends one way from the stress-free shell
    and as stably the other, 1 % higher in energy, and a first step of a quarter landed on
    the other (fuzzing: an anisotropic shell, h = 1e-3, 0.005 R wide)."""
    arc = Arclength(solver, line, anchors)
    u = arc.kkt.pack(eq.x, eq.lam_g)
    Z = arc.kkt.iterate_around(u, arc.parameters(tau), arc.q, arc.around_parameters(tau))[0]
    dx = arc.kkt.unpack(arc.kkt.moved(np.zeros_like(u), Z[:, 1]))[0]
    # (x at rest to first order: nothing to judge by)
    return dx if np.all(np.isfinite(dx)) and np.any(dx) else None


def _off_tangent(dx: np.ndarray, tangent: np.ndarray, fraction: float = 1.0) -> bool:
    """Whether the step dx strayed from the tangent's prediction (the tangent times the
    least-squares factor) by more than ``fraction`` of the prediction's own size (max
    norms): its branch bends within the step, or it is another branch."""
    dtau = (dx @ tangent) / (tangent @ tangent)
    return bool(np.max(np.abs(dx - dtau * tangent)) > fraction * np.max(np.abs(dtau * tangent)))


def left_branch(solver: DirectSolver, start: Equilibrium, new: Equilibrium) -> bool:
    """Whether the warm solve from ``start`` to ``new`` (both on ``solver``'s mesh) left
    ``start``'s branch: jumped past a fold or branch point to another stable state.

    A warm solve just past a fold converges, to the branch beyond it, as any other
    (the fold shell at λ = 0.8722622 + 10⁻⁶: Solve_Succeeded, 0.0048 C R² below the fold
    state; a sweep's κ₂ step from −6.5 to −7, audit 14).  The test: a change that strays
    from ``start``'s tangent by more than :data:`STRAY` of its prediction, or that took
    more than :data:`HARD_STEP` iterations, is solved back at ``start``'s parameters from
    ``new``; one branch's solve returns to ``start``, a jump stays on the other branch
    (farther than :data:`NOT_BACK` of the change; a solve back that fails counts as not
    returning).  A change below :data:`SAME_STATE`, a step of at most :data:`QUICK_STEP`
    Newton iterations, or states of another mesh, are not judged (False).  Costs one linear solve,
    and a warm solve where the change strays, which leaves ``solver`` as it was
    (:meth:`DirectSolver.aside`).
    """
    if not (solver.made(start) and solver.made(new)):
        return False
    dx = new.x - start.x
    moved = float(np.max(np.abs(dx)))
    if moved <= SAME_STATE or new.solver.iterations <= QUICK_STEP:
        return False
    if new.solver.iterations <= HARD_STEP:
        try:
            line = ParameterLine.between(start.problem, new.problem)
        except ValueError:          # (another structure: nothing to compare along)
            return False
        tangent = _tangent(solver, start, line, 0.0, start.anchors) if line.names else None
        if tangent is not None and not _off_tangent(dx, tangent, STRAY):
            return False
    try:
        with solver.aside():        # (the next solve's chord step as without the check)
            back = solver.solve(start.problem, warm_start=new, anchors=start.anchors)
    except (SolverError, ValueError):
        return True
    return float(np.max(np.abs(back.x - start.x))) > NOT_BACK * moved


def _change(new: Equilibrium, eq: Equilibrium, dtau: float) -> np.ndarray:
    """(max |Δx|, max |Δψ|) from ``eq`` to ``new`` per unit of τ (the jump test's rates)."""
    return np.array([np.max(np.abs(new.x - eq.x)), np.max(np.abs(new.psi - eq.psi))]) / dtau


def _rejection(new: Equilibrium | None, eq: Equilibrium, change, rate,
               tangent: np.ndarray | None = None) -> str:
    """Why the step from ``eq`` to ``new`` is retried smaller ("" if it is taken).

    ``change`` is the step's (max |Δx|, max |Δψ|) per unit of τ (:func:`_change`),
    ``rate`` the largest of the steps before (None before the first); a turn of ψ
    below :data:`JUMP_TURN` does not count.  Before the first, ``tangent`` is
    the branch's direction at ``eq`` (:func:`_tangent`), and a step that strays from
    it (:func:`_off_tangent`) jumped.
    """
    if new is None:
        return "failed"
    turn = np.max(np.abs(new.psi - eq.psi))
    jumped = rate is None and tangent is not None and _off_tangent(new.x - eq.x, tangent) \
        or rate is not None and (change[0] > JUMP_FACTOR * rate[0]
                                 or turn > JUMP_TURN and change[1] > JUMP_FACTOR * rate[1]) \
        or turn > MAX_TURN
    if jumped:
        return "jumped"
    if new.solver.iterations > HARD_STEP:
        return f"{new.solver.iterations} iterations"
    return ""


def _follow(solver, eq, problem, anchors, first_step, max_steps, origin, snap=False,
            switch=False):
    """Continue from the solution ``eq`` to ``problem``: (progress, solution).

    With ``snap``, a stall of the step (a fold of the branch, where natural
    continuation cannot go on) is crossed as the shell would cross it
    (:func:`morphoshell.solvers.crossings.cross_fold`; with ``switch`` also a
    branch point where the branch loses its stability).
    """
    line = ParameterLine.between(eq.problem, problem)
    run = _Progress(float(first_step))
    name = problem.name or problem.family
    # the first step's only jump test (:func:`_tangent`); after a crossing the shell is next to
    # a fold or branch point, where K is nearly singular and the tangent says little
    tangent = _tangent(solver, eq, line, run.tau, anchors)
    while run.tau < 1:
        if snap and run.step < MIN_STEP and len(run.snaps) < MAX_SNAPS \
                and run.steps + run.rejected < max_steps and not run.stuck:
            try:
                eq, tangent = _crossed(solver, eq, line, run, anchors, first_step, switch), None
                continue
            except SolverError as exc:
                if exc.status == SNAP_FAILED:
                    raise
                run.remedy = _remedy(exc)       # (which says what exc says, shorter)
                run.stuck = "" if run.remedy else f"; past it by arclength steps: {exc}"
        if run.exhausted(max_steps):
            raise SolverError(
                f"continuation from {origin} stopped at {run.tau:.4g} of the way to {name!r} "
                f"({run.steps} steps, {run.rejected} retried, step {run.step:.2g}): "
                f"{run.remedy or explain(CONTINUATION_FAILED)}; the last solution reached is "
                f"attached{run.stuck}", CONTINUATION_FAILED, eq)
        trial = min(1.0, run.tau + run.step)
        new = _solve_at(solver, line.at(trial), eq, anchors)
        change = None if new is None else _change(new, eq, trial - run.tau)
        why = _rejection(new, eq, change, run.rate, tangent)
        if why:
            log.debug("continuation to %s: step to tau = %.4g retried smaller (%s)", name, trial,
                      why)
            run.reject()
            continue
        log.debug("continuation to %s: tau = %.4g reached in %d iterations", name, trial,
                  new.solver.iterations)
        run.accept(trial, change, new.solver.iterations)
        eq, tangent = new, None
    return run, eq


def _remedy(exc: SolverError) -> str:
    """What to do when the way past a stall failed with ``exc``, if not the generic remedy
    (a finer mesh): past it the meridian crosses the axis next to a weakly singular pole,
    where a finer mesh does not help and the bvp route solves the shell (toy 2 at h = 0.3,
    k = 6, at every mesh)."""
    if exc.status != MERIDIAN_CROSSES_AXIS or exc.last_iterate is None:
        return ""
    where = pole_crossing(exc.last_iterate)
    return f"past it, by arclength steps, the meridian crosses the axis {where}" if where else ""


def _crossed(solver, eq, line, run: _Progress, anchors, first_step, switch) -> Equilibrium:
    """Past a stall of natural continuation: the fold's snap-through, the switch of branches
    (or the stable way on), certified by a warm solve; ``run`` restarts there (a new branch:
    no jump rate yet)."""
    eq, tau, event = cross_fold(solver, eq, line, run.tau, anchors, switch=switch)
    # a landing just past the target (a fold or branch point within its overshoot before
    # τ = 1) is at extrapolated parameters: its branch is solved at the target itself
    tau = min(tau, 1.0)
    eq = solver.solve(line.at(tau), warm_start=eq, anchors=anchors)
    if event is not None:
        log.info("continuation to %s: %s", line.problem.name or line.problem.family,
                 event.describe())
        (run.switches if isinstance(event, Switch) else run.snaps).append(event)
    run.tau, run.rate, run.step = tau, None, float(first_step)
    return eq


def _with_path(eq: Equilibrium, path: Path, t0: float) -> Equilibrium:
    details = {**eq.solver.details, "path": path.describe(), "continuation_steps": path.steps}
    if path.snaps:
        details["snaps"] = [snap.to_dict() for snap in path.snaps]
    if path.switches:
        details["switches"] = [switch.to_dict() for switch in path.switches]
    stats = replace(eq.solver, iterations=path.iterations, seconds=time.perf_counter() - t0,
                    details=details)
    return replace(eq, solver=stats)
