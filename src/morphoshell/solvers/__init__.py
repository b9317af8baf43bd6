"""Routes to an equilibrium and what comes out of them.

Direct minimisation (:mod:`.direct`), the boundary-value reference (:mod:`.bvp`)
and multiple shooting (:mod:`.shooting`), all from the same symbolic energy;
continuation along a branch, mesh refinement to a tolerance, observables and
parametric derivatives; :func:`~morphoshell.solvers.routes.solve` is the
one-call front door, :mod:`.results` what every route returns.
"""

import lazy_loader

# Every public name of the subpackage, imported from its module on first use.
__getattr__, __dir__, __all__ = lazy_loader.attach(__name__, submod_attrs={
    "bvp": ["solve_bvp", "pontryagin_functions", "pole_state", "pole_costates",
        "pole_caps", "initial_state", "to_equilibrium", "neutral_path"],
    "poles": ["pole_solutions", "PoleSolution", "weakly_singular"],
    "continuation": ["continue_to", "continue_between", "Path"],
    "paths": ["ParameterLine", "neutral_problem", "stress_free"],
    "arclength": ["Arclength", "ArcPoint", "Snap"],
    "crossings": ["snap_through", "cross_fold"],
    "branches": ["Branch", "BranchPoint", "follow_branch", "switch_branch", "continuation_path",
        "MAX_POINTS"],
    "direct": ["DirectSolver", "default_mesh", "solver_of", "check_nodes", "MAX_NODES"],
    "observables": ["Observable", "GAUGES", "shape_points", "energy", "state_at", "midline",
        "midline_cells", "recoil", "RECOIL"],
    "options": ["check_problem", "check_guess", "check_direct_options", "check_bvp_options",
        "check_shooting_options", "MAX_DIRECT_TOL", "REFERENCE_TOL", "ATOL", "RTOL",
        "POLE_OFFSET", "STABILITY", "INTEGRATORS", "MIN_DIRECT_THICKNESS",
        "thin_shell_note", "thin_shell_first"],
    "parametric": ["Parametric", "Sensitivities", "SolutionDerivative", "parametric"],
    "refinement": ["solve_from", "estimate", "level_errors", "derived_errors", "refine",
        "refine_once", "half_mesh", "SAFETY", "COARSE"],
    "results": ["Equilibrium", "SolverStats", "SolverError", "NotAMinimumError", "FIELDS",
        "unconverged", "Quadrature", "ErrorEstimate", "ESTIMATED", "ENERGY_FLOOR", "energy_floor",
        "FIELD_UNITS", "FIELD_NAMES", "JSON_UNITS"],
    "routes": ["solve", "direct_solver", "cache_info", "clear_cache", "SOLVER_CACHE_SIZE",
        "METHODS", "DIRECT_OPTIONS", "BVP_OPTIONS", "SHOOTING_OPTIONS", "MIN_RTOL"],
    "shooting": ["solve_shooting", "ILL_CONDITIONED", "NOT_CONVERGED", "INTEGRATION_FAILED",
        "MAX_GROWTH", "MAX_SEGMENTS", "MIN_SEGMENTS", "MAX_CONDITION"],
})
