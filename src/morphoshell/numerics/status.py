"""How a solve ended: the table of statuses, and the errors every route raises.

:data:`STATUSES` maps every status a route can report (in
``Equilibrium.solver.status``, in :attr:`SolverError.status` and so in the
``status`` columns of sweeps and campaigns) to one line saying what it means
and, for a failure, what to try; routes name statuses by the constants below
and build their failure messages from the table (:func:`explain`).  The
table is in the manner of ``TERMINATION_MESSAGES`` in scipy's
``integrate/_bvp.py``, keyed by names rather than numbers, because the
names are what users see.

A status is one of

* Ipopt's return statuses (``ApplicationReturnStatus``, as CasADi names
  them), from the direct route and the KKT fit;
* the Newton back end's and the routes' own (``Newton_Converged``,
  ``Not_A_Minimum``, ``Meridian_Crosses_Axis``, ``Continuation_Failed``, ...);
* ``solve_bvp``'s four outcomes, named as the others (:data:`BVP_STATUSES`
  maps its integer status to them; scipy's own message goes into the error's
  text);
* the shooting route's, the fits' and the sweeps'.

:class:`SolverError` carries a status of the table (any other is a bug:
``ValueError``) and the last iterate; a solver's free text (scipy's
messages, Ipopt's log) goes into the message.  :class:`NotAMinimumError` is a
converged stationary point that is not a strict minimum.  They sit with the
back ends, the lowest layer that raises them.
"""
from __future__ import annotations

from types import MappingProxyType
from typing import Any, Mapping

__all__ = ["STATUSES", "BVP_STATUSES", "SolverError", "NotAMinimumError", "explain",
           "check_status", "SOLVE_SUCCEEDED", "SOLVED_TO_ACCEPTABLE_LEVEL",
           "SEARCH_DIRECTION_BECOMES_TOO_SMALL", "MAXIMUM_ITERATIONS_EXCEEDED", "INVALID_OPTION",
           "IPOPT_UNKNOWN", "NEWTON_CONVERGED", "NOT_A_MINIMUM", "STABILITY_CHECK_FAILED",
           "MERIDIAN_CROSSES_AXIS", "CONTINUATION_FAILED", "TOLERANCE_NOT_MET",
           "ARCLENGTH_CONVERGED", "SNAP_FAILED", "BRANCH_ENDED",
           "POLE_ANALYSIS_FAILED", "TIME_LIMIT_EXCEEDED", "BVP_CONVERGED", "BVP_MAX_NODES",
           "BVP_SINGULAR_JACOBIAN", "BVP_BOUNDARY_CONDITIONS", "SHOOTING_SUCCEEDED",
           "SHOOTING_ILL_CONDITIONED", "SHOOTING_NOT_CONVERGED", "SHOOTING_INTEGRATION_FAILED",
           "FIT_SADDLE", "FIT_NOT_REPRODUCED", "GAUSS_NEWTON_STOPPED", "FIT_CONVERGED",
           "FIT_CONVERGED_STOPS",
           "MAXIMUM_EVALUATIONS_EXCEEDED", "FIT_STALLED", "NOT_COMPUTED", "FIT_NOT_STATIONARY",
           "FIT_NEAR_FOLD",
           "FIT_ON_BOX_EDGES", "FIT_MOVED_BOXES_FAILED", "FIT_NOT_MINIMUM", "STEP_NOT_SPLITTABLE",
           "RETRY_FINER", "NO_STATIONARY_RADIUS"]

# -- Ipopt (morphoshell.numerics.ipopt; the KKT fit's NLP) ------------------------------
SOLVE_SUCCEEDED = "Solve_Succeeded"
SOLVED_TO_ACCEPTABLE_LEVEL = "Solved_To_Acceptable_Level"
SEARCH_DIRECTION_BECOMES_TOO_SMALL = "Search_Direction_Becomes_Too_Small"
MAXIMUM_ITERATIONS_EXCEEDED = "Maximum_Iterations_Exceeded"
INVALID_OPTION = "Invalid_Option"
#: CasADi's name for an Ipopt status it does not know.
IPOPT_UNKNOWN = "Unknown"
# -- the direct route's own (morphoshell.numerics.newton, .ipopt; morphoshell.solvers) ---
NEWTON_CONVERGED = "Newton_Converged"
NOT_A_MINIMUM = "Not_A_Minimum"
STABILITY_CHECK_FAILED = "Stability_Check_Failed"
MERIDIAN_CROSSES_AXIS = "Meridian_Crosses_Axis"
CONTINUATION_FAILED = "Continuation_Failed"
TOLERANCE_NOT_MET = "Tolerance_Not_Met"
ARCLENGTH_CONVERGED = "Arclength_Converged"
SNAP_FAILED = "Snap_Through_Failed"
BRANCH_ENDED = "Branch_Ended"
# -- the boundary-value reference (morphoshell.solvers.bvp): scipy's solve_bvp ----------
POLE_ANALYSIS_FAILED = "Pole_Analysis_Failed"
TIME_LIMIT_EXCEEDED = "Time_Limit_Exceeded"
# (scipy's messages were the keys until audit 26: a status shown as "The maximum number of
# mesh nodes is exceeded." beside the direct route's Continuation_Failed, and scipy's integer)
BVP_CONVERGED = "Bvp_Converged"
BVP_MAX_NODES = "Bvp_Max_Nodes_Exceeded"
BVP_SINGULAR_JACOBIAN = "Bvp_Singular_Jacobian"
BVP_BOUNDARY_CONDITIONS = "Bvp_Boundary_Tolerance_Not_Met"
# -- multiple shooting (morphoshell.solvers.shooting) ------------------------------------
SHOOTING_SUCCEEDED = "Shooting_Succeeded"
SHOOTING_ILL_CONDITIONED = "Shooting_Ill_Conditioned"
SHOOTING_NOT_CONVERGED = "Shooting_Not_Converged"
SHOOTING_INTEGRATION_FAILED = "Shooting_Integration_Failed"
# -- toy problem 1 in bulk elasticity (morphoshell.mechanics.bulk.f_bulk) ----------------
NO_STATIONARY_RADIUS = "No_Stationary_Radius"
# -- fits (morphoshell.fitting) and sweeps (morphoshell.workflows.sweeps) ----------------
FIT_SADDLE = "Fit_Saddle"
FIT_NOT_REPRODUCED = "Fit_Not_Reproduced"
GAUSS_NEWTON_STOPPED = "Gauss_Newton_Stopped"
# how a fit that returns a result ended (FitResult.stop; the KKT fit's is Ipopt's status)
FIT_CONVERGED = "Fit_Converged"
MAXIMUM_EVALUATIONS_EXCEEDED = "Maximum_Evaluations_Exceeded"
FIT_STALLED = "Fit_Stalled"
FIT_NOT_STATIONARY = "Fit_Not_Stationary"
FIT_NEAR_FOLD = "Fit_Near_Fold"
FIT_ON_BOX_EDGES = "Fit_On_Box_Edges"
FIT_MOVED_BOXES_FAILED = "Fit_Moved_Boxes_Failed"
FIT_NOT_MINIMUM = "Fit_Not_Minimum"
STEP_NOT_SPLITTABLE = "Step_Not_Splittable"
# a sweep's row that an interrupt left out (a partial file)
NOT_COMPUTED = "Not_Computed"
#: The stops of a converged fit (FitResult.converged true): the outer iteration's own, and the
#: KKT fit's Ipopt successes (any other Ipopt status raises FitError; every stop that makes a
#: fit unconverged is another: morphoshell.fitting.bilevel, .nested, .results).
FIT_CONVERGED_STOPS = (FIT_CONVERGED, SOLVE_SUCCEEDED, SOLVED_TO_ACCEPTABLE_LEVEL)

#: The advice of a finer mesh in solve()'s terms (a sweep words it its way).
RETRY_FINER = "rtol, --rtol: retried on finer ones"

#: Every status a route can report, and what it means (for a failure, what to try).  Each
#: line reads after the facts of a failure message: "... after 7 iterations: <line>".
STATUSES: Mapping[str, str] = MappingProxyType({
    # Ipopt's return statuses.  The first three can count as converged
    # (morphoshell.numerics.ipopt.converged); the others fail the solve.
    SOLVE_SUCCEEDED: "Ipopt met its tolerance on the scaled KKT error",
    SOLVED_TO_ACCEPTABLE_LEVEL:
        "Ipopt stopped at the round-off floor (three iterations in a row within its "
        "acceptable tolerance, constraints met to 1e-10): accepted as converged",
    SEARCH_DIRECTION_BECOMES_TOO_SMALL:
        "Ipopt's steps reached machine precision: converged if the scaled primal and dual "
        "infeasibilities are below 1e-9 and 1e-6; if not, start closer or refine the mesh",
    MAXIMUM_ITERATIONS_EXCEEDED:
        "the iterations ran out (max_iter): start closer (continuation, a warm start) or "
        "raise max_iter",
    "Restoration_Failed":
        "Ipopt's feasibility restoration failed, the constraints could not be met from there: "
        "start closer (continuation from the stress-free parameters) or refine the mesh",
    "Infeasible_Problem_Detected":
        "Ipopt found the constraints locally infeasible: start closer, or check the anchors "
        "and breakpoints (inside the shell, increasing)",
    "Diverging_Iterates":
        "the iterates grew without bound: start closer (continuation from the stress-free "
        "parameters)",
    "Error_In_Step_Computation":
        "Ipopt could not compute a step (a singular KKT matrix): perturb the start or refine "
        "the mesh",
    "Invalid_Number_Detected":
        "NaN or Inf in the energy or its derivatives at an iterate (a meridian outside the "
        "physical range): start closer or refine the mesh",
    INVALID_OPTION:
        "Ipopt rejected its options: check ipopt_options and linear_solver (the HSL solvers "
        "load only if libhsl.so is on the library path; 'mumps' is bundled)",
    "Not_Enough_Degrees_Of_Freedom":
        "more equality constraints than unknowns: a bug in the transcription, please report it",
    "Invalid_Problem_Definition": "Ipopt rejected the NLP's definition: a bug, please report it",
    "Unrecoverable_Exception": "Ipopt failed with an exception it could not recover from",
    "NonIpopt_Exception_Thrown": "a function Ipopt called raised an exception (the log names it)",
    "Insufficient_Memory": "Ipopt ran out of memory: use fewer nodes",
    "Internal_Error": "Ipopt's internal error: please report it with the problem",
    "User_Requested_Stop": "a callback asked Ipopt to stop",
    "Maximum_CpuTime_Exceeded": "Ipopt ran out of CPU time (its option max_cpu_time)",
    "Maximum_WallTime_Exceeded": "Ipopt ran out of wall-clock time (its option max_wall_time)",
    "Feasible_Point_Found": "Ipopt found a feasible point of a feasibility problem, not a minimum",
    IPOPT_UNKNOWN: "Ipopt ended with a status CasADi does not name",
    # the direct route's own
    NEWTON_CONVERGED:
        "Newton's steps converged and their own factorisation certified a strict minimum "
        "(Ipopt was not needed)",
    NOT_A_MINIMUM:
        "a saddle, not a strict minimum (the reduced Hessian is not positive definite): "
        "perturb the start or continue from a stable solution",
    STABILITY_CHECK_FAILED:
        "the minimum certificate needs that factorisation; stability='off' skips the check "
        "(the result is then not certified a minimum)",
    MERIDIAN_CROSSES_AXIS:
        "the meridian crosses the axis (r < 0), which the shell cannot do: not an equilibrium "
        "of the shell; continue from the stress-free parameters (solve(..., "
        "continuation=True)) or refine the mesh",
    CONTINUATION_FAILED:
        "the step fell below its minimum or the steps ran out (a fold of the branch?): try a "
        f"finer mesh ({RETRY_FINER}), or continue from a nearer solution",
    TOLERANCE_NOT_MET:
        "raise max_nodes (--max-nodes on the command line), loosen rtol, or use more stages "
        "(a higher order)",
    # branches (morphoshell.solvers.arclength)
    ARCLENGTH_CONVERGED:
        "a point of a branch, F = 0 to tol by the bordered Newton corrector; stable or not as "
        "its inertia says",
    SNAP_FAILED:
        "the shell snaps through at a fold, but no stable equilibrium of lower energy was found "
        f"past it: try a finer mesh ({RETRY_FINER}), or follow the branch "
        "(morphoshell continue) to see where it goes",
    BRANCH_ENDED:
        "the pseudo-arclength step fell below its minimum or the points ran out before the end "
        "of the path: a cusp or a branch point? try a smaller --max-step or a finer mesh (a "
        "solve: rtol, --rtol, retries on finer ones)",
    # the boundary-value reference: solve_bvp's four outcomes (its status 0 to 3), then the
    # route's own
    BVP_CONVERGED: "solve_bvp met tol on the collocation residuals and bc_tol at the ends",
    BVP_MAX_NODES:
        "solve_bvp refined its mesh up to max_nodes without meeting tol (a thin boundary layer, "
        "a kinked profile?): raise max_nodes, or use the direct method",
    BVP_SINGULAR_JACOBIAN:
        "solve_bvp met a singular collocation Jacobian: start closer (more homotopy_steps, or "
        "a guess from the direct method)",
    BVP_BOUNDARY_CONDITIONS:
        "solve_bvp could not meet bc_tol at the ends: start closer or loosen bc_tol",
    POLE_ANALYSIS_FAILED:
        "the pole is not regular (its local solution needs two); use the direct method",
    TIME_LIMIT_EXCEEDED:
        "it keeps refining a solution it cannot resolve (a thin boundary layer or a kink of "
        "the profiles?); the direct method handles both",
    # multiple shooting
    SHOOTING_SUCCEEDED:
        "the shooting residuals met tol and the equilibrated shooting Jacobian is well "
        "conditioned",
    SHOOTING_ILL_CONDITIONED:
        "the shooting matrix is, or would be, too ill-conditioned (a thin shell's boundary "
        "layer): use more segments, or the direct or bvp route",
    SHOOTING_NOT_CONVERGED:
        "the iterations stopped short of tol: try more homotopy_steps, a guess from another "
        "route, or the direct method",
    SHOOTING_INTEGRATION_FAILED:
        "an initial-value integration failed: start closer (a guess from another route) or "
        "use the direct method",
    # the bulk sphere of toy problem 1
    NO_STATIONARY_RADIUS:
        "the energy has no local minimum over those radii (with C01 < 0 it falls without "
        "bound as the sphere grows): check the moduli, or take a thinner shell, whose "
        "minimum lies near f = 1",
    # fits (morphoshell.fitting)
    FIT_SADDLE:
        "the KKT fit ended on a state that is not a minimum of the inner energy: start from "
        "another point or use the gradient method",
    FIT_NOT_REPRODUCED:
        "the inner solve at the fitted parameters does not return the KKT fit's state: start "
        "from another point or use the gradient method",
    GAUSS_NEWTON_STOPPED:
        "the Gauss-Newton steps that restart the KKT fit stopped short: start nearer the data "
        "or use the gradient method",
    FIT_CONVERGED:
        "the outer iteration met its tolerance (Nelder-Mead's simplex; the gradient fit at a "
        "stationary point)",
    MAXIMUM_EVALUATIONS_EXCEEDED:
        "the evaluations ran out (max_iterations) before the tolerance was met: raise "
        "max_iterations, or start nearer the optimum (from a gradient fit's parameters)",
    NOT_COMPUTED:
        "not computed: the sweep was interrupted before this point (its partial file keeps the "
        "rest; the same sweep with --resume computes it)",
    FIT_STALLED:
        "the gradient fit stopped at its best point: trial points in a row failed their inner "
        "solve (a fold of the branch?): start nearer the data, or use Nelder-Mead",
    FIT_NOT_STATIONARY:
        "the gradient fit stalled where its gradient is not zero (trial points rejected near a "
        "fold of the branch?): start nearer the data, or use Nelder-Mead",
    FIT_NEAR_FOLD:
        "the fitted state is near a fold of the equilibrium branch (nearly unstable; standard "
        "errors meaningless): start from another point, or hold a poorly identified parameter",
    FIT_ON_BOX_EDGES:
        "a breakpoint still rests on the edge of its box after the last move of the boxes: "
        "the optimum may lie beyond; hold it, or start nearer the data",
    FIT_MOVED_BOXES_FAILED:
        "the fit from moved boxes failed, so the fit within the last boxes stands, "
        "unconverged: start again from it, or use another method",
    FIT_NOT_MINIMUM:
        "a profile's refit (one parameter held) lies lower than the fit, and the fits from "
        "there did not settle it: the fit is not the minimum; fit again from it, or use "
        "another method",
    # sweeps (morphoshell.workflows.sweeps)
    STEP_NOT_SPLITTABLE:
        "a failed sweep step has no midpoint to split it at (breakpoints keep their order)",
})

#: ``scipy.integrate.solve_bvp``'s integer status -> its status in :data:`STATUSES`.
BVP_STATUSES: Mapping[int, str] = MappingProxyType({
    0: BVP_CONVERGED, 1: BVP_MAX_NODES, 2: BVP_SINGULAR_JACOBIAN, 3: BVP_BOUNDARY_CONDITIONS})


def check_status(status: str) -> str:
    """``status`` if :data:`STATUSES` has it; ValueError otherwise (a route's bug)."""
    if status not in STATUSES:
        raise ValueError(f"status {status!r} is not in morphoshell.numerics.status.STATUSES: "
                         f"name it there, with what it means")
    return status


def explain(status: str) -> str:
    """What ``status`` means and, for a failure, what to try: its line of :data:`STATUSES`.

    Parameters
    ----------
    status : str
        A key of :data:`STATUSES`.

    Returns
    -------
    str
        A clause to go into a message (no full stop; lower case unless it
        starts with a name).
    """
    return STATUSES[check_status(status)]


class SolverError(RuntimeError):
    """The solver did not deliver a (stable) equilibrium.

    Parameters
    ----------
    message : str
        What failed, with the facts (where, after how many iterations) and
        the solver's own free text, if any.
    status : str
        A key of :data:`STATUSES`; ValueError otherwise.
    last_iterate : Equilibrium, optional
        The last iterate.

    Attributes
    ----------
    status : str
        Ipopt's return status, the Newton back end's, ``solve_bvp``'s
        (:data:`BVP_STATUSES`) or a route's own: a key of
        :data:`STATUSES`, whose line :func:`explain` gives.
    last_iterate : Equilibrium or None
        The last iterate, with ``converged=False``, for inspection
        (a :class:`morphoshell.solvers.results.Equilibrium`, defined a layer up).
    """

    def __init__(self, message: str, status: str, last_iterate: Any = None):
        super().__init__(message)
        self.status = check_status(status)
        self.last_iterate = last_iterate

    def __reduce__(self):
        # pickled with its status (worker processes): RuntimeError's reduce passes the message only
        return type(self), (self.args[0], self.status, self.last_iterate), self.__dict__


class NotAMinimumError(SolverError):
    """Ipopt converged to a stationary point whose reduced Hessian is not positive definite."""
