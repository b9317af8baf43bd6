"""The routes' arguments checked before any work: a ValueError naming the option and its
value (a TypeError for an argument of the wrong kind), instead of a late solver status
that blames something else, or a tolerance ignored.

The ranges of the tolerances, and why (the runs: docs/benchmarks.md, "solvers/options.py"):

* direct ``tol`` ∈ (0, :data:`MAX_DIRECT_TOL`]: at 1e-3 the solver stops as far from the
  equilibrium as the discretisation error of 200 nodes, at 1 it may accept the undeformed
  start; tiny values are harmless (the back ends stop at their round-off floor).
* bvp ``tol``, ``bc_tol`` and shooting ``tol`` ∈ :data:`REFERENCE_TOL`: solve_bvp at 1e-2
  put an energy 19 % off; below 1e-11 it refines to ``max_nodes`` for a minute and fails
  (scipy floors tol at 100 ε anyway), and shooting stalls above it.
* shooting ``atol`` ∈ :data:`ATOL` and ``rtol`` ∈ :data:`RTOL` (solve_ivp's): looser ones
  leave residuals above the default ``tol``; a tighter atol only takes longer.
* ``pole_offset`` ε ∈ :data:`POLE_OFFSET`: the leading-order series at a pole covers
  s < ε, 3e-5 of the energy off at 0.1; at 1e-8 solve_bvp runs out of time.
"""
from __future__ import annotations

from numbers import Real
from typing import Any

from .._runtime.validate import integer, real, within
from .._runtime.validate import short as _short
from ..model.problem import Problem
from ..numerics.ipopt_options import check_ipopt_options
from .results import Equilibrium

__all__ = ["check_problem", "check_guess", "check_anchors", "check_direct_options",
           "check_bvp_options", "check_shooting_options", "MAX_DIRECT_TOL", "REFERENCE_TOL",
           "ATOL", "RTOL", "POLE_OFFSET", "STABILITY", "INTEGRATORS", "MIN_DIRECT_THICKNESS",
           "DIRECT_TOL", "thin_shell_note", "thin_shell_first", "BVP_ADVICE"]

#: Default ``tol`` of the direct route (Ipopt's and Newton's, at 800 points).
DIRECT_TOL = 1e-10
#: Largest ``tol`` of the direct route (Ipopt's and Newton's, at 800 points).
MAX_DIRECT_TOL = 1e-4
#: Range of the reference routes' tolerances: bvp ``tol`` and ``bc_tol``, shooting ``tol``.
REFERENCE_TOL = (1e-11, 1e-3)
#: Range of the shooting integrator's absolute tolerance ``atol``.
ATOL = (1e-16, 1e-6)
#: Range of the shooting integrator's relative tolerance ``rtol``.
RTOL = (1e-14, 1e-6)
#: Range of ε, the distance from a pole at which the reference routes start (units of R).
POLE_OFFSET = (1e-6, 0.1)
#: Thinnest shell the direct route solves from its default start (h = H/R).  Its objective
#: is the energy over h³, so stretching weighs 1/h² against bending (4e9 at h = 1.5e-5):
#: below this Ipopt stops with Restoration_Failed or Error_In_Step_Computation on the
#: meshes of 200 nodes and up, from continuation and cold (uniform k = 0, cut 0.5 and
#: closed: 2e-5 solved at 200, 800 and 1600 nodes, with rtol and cold; 1.5e-5 failed
#: closed at 800 nodes; 1e-5 on every mesh), while 100 nodes refined by warm starts
#: (rtol) still solve a classical shell at 1e-6.  ``solve()`` warns before it starts, and
#: a failure below it says so first (:func:`thin_shell_note`, :func:`thin_shell_first`).  The BVP
#: route solves down to :data:`~morphoshell.model.problem.MIN_THICKNESS`.
MIN_DIRECT_THICKNESS = 2e-5
#: How the direct route certifies a minimum (:class:`morphoshell.numerics.ipopt.IpoptBackend`).
STABILITY = ("auto", "exact", "off")
#: The shooting route's integrators (stiff-capable methods of ``solve_ivp``).
INTEGRATORS = ("LSODA", "Radau", "BDF")


def check_problem(problem: Any, name: str = "problem") -> Problem:
    """``problem``, or TypeError unless it is a :class:`Problem`."""
    if not isinstance(problem, Problem):
        raise TypeError(f"{name} = {_short(problem)} must be a morphoshell Problem, e.g. "
                        f"Problem('uniform', {{'k': 0.5}}, h=0.1)")
    return problem


#: The advice of the boundary-value route in solve()'s terms (a sweep words it its way).
BVP_ADVICE = 'method="bvp" (--method bvp)'


def thin_shell_note(problem: Problem) -> str:
    """Why a direct solve of a shell thinner than :data:`MIN_DIRECT_THICKNESS` is likely
    to fail, and the route that solves it ("" for thicker shells).  Not a refusal: a
    coarse mesh refined by warm starts (``nodes=100, rtol=1e-3``) solves a classical
    shell at h = 1e-6 (tests/solvers/test_right_minimum.py)."""
    if problem.h >= MIN_DIRECT_THICKNESS:
        return ""
    return (f"the shell is thinner (h = {problem.h:g}) than {MIN_DIRECT_THICKNESS:g}, below "
            f"which the direct route fails on most meshes (stretching outweighs bending by "
            f"1/h^2): {BVP_ADVICE} solves shells down to h = 1e-6")


def thin_shell_first(problem: Problem, message: str) -> str:
    """A direct failure's ``message`` led by :func:`thin_shell_note` (once), for a shell
    thinner than :data:`MIN_DIRECT_THICKNESS`; ``message`` itself otherwise.  The note,
    known before any work, is the advice that applies: it came last, after 800
    characters of a continuation's advice (finer mesh, smaller steps) that does not
    (audit 21).  A note already inside ``message`` (a direct solve's failure that a
    continuation quotes) is moved, not repeated."""
    note = thin_shell_note(problem)
    if not note:
        return message
    lead = f"{note}. The direct route's failure: "
    return lead + message.replace(lead, "")


def check_guess(guess: Any, name: str = "warm_start") -> None:
    """TypeError unless ``guess`` is None or an :class:`Equilibrium`."""
    if guess is not None and not isinstance(guess, Equilibrium):
        raise TypeError(f"{name} = {_short(guess)} must be an Equilibrium (a previous "
                        f"solution) or None")


def check_anchors(anchors: Any) -> tuple:
    """``anchors`` as a tuple, or TypeError unless it is a sequence of real numbers (a single
    number is not: ``anchors=1.0`` raised "'float' object is not iterable")."""
    if isinstance(anchors, (str, bytes)) or not hasattr(anchors, "__len__") or \
            any(isinstance(s, bool) or not isinstance(s, Real) for s in anchors):
        raise TypeError(f"anchors = {_short(anchors)} must be a sequence of material points s "
                        f"(numbers), e.g. (0.5,)")
    return tuple(anchors)


def check_direct_options(*, stages: Any = 2, linear_solver: Any = "mumps", tol: Any = DIRECT_TOL,
                         max_iter: Any = 500, stability: Any = "auto",
                         ipopt_options: Any = None) -> None:
    """The direct route's options (:class:`~morphoshell.solvers.direct.DirectSolver`), or a
    ValueError (TypeError) naming the first bad one; Ipopt's through
    :func:`~morphoshell.numerics.ipopt_options.check_ipopt_options`."""
    if isinstance(stages, bool) or stages not in (1, 2, 3):
        raise ValueError(f"stages = {stages!r} must be 1, 2 or 3")
    within("tol", tol, 0.0, MAX_DIRECT_TOL, open_lo=True,
           why="at 1e-3 the solver stops as far from the equilibrium as the discretisation "
               "error of 200 nodes")
    integer("max_iter", max_iter, 1)
    if not isinstance(stability, str) or stability not in STABILITY:
        raise ValueError(f"stability = {stability!r} must be one of {list(STABILITY)}")
    check_ipopt_options(linear_solver, ipopt_options)


def check_bvp_options(problem: Any, nodes: Any, *, tol: Any, bc_tol: Any, guess: Any,
                      pole_offset: Any, max_nodes: Any, homotopy_steps: Any,
                      max_seconds: Any) -> None:
    """The options of :func:`~morphoshell.solvers.bvp.solve_bvp`, or a ValueError (TypeError)
    naming the first bad one."""
    check_problem(problem)
    check_guess(guess, "guess")
    _reference_tol("tol", tol)
    if bc_tol is not None:
        _reference_tol("bc_tol", bc_tol)
    integer("nodes", nodes, 5)
    integer("max_nodes", max_nodes, 1)      # (below the first mesh's nodes: a named failure)
    integer("homotopy_steps", homotopy_steps, 1)
    _pole_offset(problem, pole_offset)
    _positive("max_seconds", max_seconds)


def check_shooting_options(problem: Any, *, segments: Any, integrator: Any, rtol: Any,
                           atol: Any, tol: Any, pole_offset: Any, guess: Any,
                           homotopy_steps: Any, max_evaluations: Any, max_growth: Any,
                           max_segments: Any, max_condition: Any, points: Any,
                           max_seconds: Any) -> None:
    """The options of :func:`~morphoshell.solvers.shooting.solve_shooting`, or a ValueError
    (TypeError) naming the first bad one (``segments`` against the problem is checked there,
    with the growth it allows)."""
    check_problem(problem)
    check_guess(guess, "guess")
    if segments is not None and (isinstance(segments, bool) or real("segments", segments) < 1):
        raise ValueError(f"segments = {segments!r} must be an integer >= 1")
    if not isinstance(integrator, str) or integrator not in INTEGRATORS:
        raise ValueError(f"integrator = {integrator!r} must be one of {list(INTEGRATORS)}")
    within("rtol", rtol, *RTOL)
    within("atol", atol, *ATOL)
    _reference_tol("tol", tol)
    _pole_offset(problem, pole_offset)
    if homotopy_steps is not None:
        integer("homotopy_steps", homotopy_steps, 1)
    integer("max_evaluations", max_evaluations, 1)
    if real("max_growth", max_growth) <= 1:
        raise ValueError(f"max_growth = {max_growth!r} must exceed 1")
    integer("max_segments", max_segments, 1)
    if real("max_condition", max_condition) <= 1:
        raise ValueError(f"max_condition = {max_condition!r} must exceed 1 (a condition number)")
    integer("points", points, 2)
    _positive("max_seconds", max_seconds)


def _reference_tol(name: str, value: Any) -> None:
    within(name, value, *REFERENCE_TOL, why="at 1e-2 an energy came out 19 % off, below 1e-11 "
                                             "round-off keeps the tolerance out of reach")


def _positive(name: str, value: Any) -> None:
    if real(name, value) <= 0:
        raise ValueError(f"{name} = {value!r} must be positive")


def _pole_offset(problem: Problem, value: Any) -> None:
    """ε in :data:`POLE_OFFSET`, and next to a pole within a tenth of the shell's length."""
    eps = within("pole_offset", value, *POLE_OFFSET,
                 why="the leading-order series at the pole covers its first pole_offset (0.1: "
                     "3e-5 of the energy off; 1e-8: solve_bvp runs out of time)")
    st = problem.structure
    length = problem.end - problem.cut
    if "pole" in (st.start, st.end) and eps > 0.1 * length:
        raise ValueError(f"pole_offset = {value!r} must be at most a tenth of the shell's "
                         f"length {length:.6g} (units of R)")
