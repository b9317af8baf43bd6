"""The physics, without numerics: undeformed geometry, intrinsic profiles, energy.

A :class:`~morphoshell.model.problem.Problem` names a shell (geometry, profile
family and its parameters, thickness, ends, theory); :mod:`.energy` turns it
into strains and the energy density of the paper's Materials and Methods,
Eqs. (5)-(7), as CasADi expressions.  Everything above derives from these.
"""

import lazy_loader

# Every public name of the subpackage, imported from its module on first use.
__getattr__, __dir__, __all__ = lazy_loader.attach(__name__, submod_attrs={
    "coefficients": ["Coefficients", "Theory", "large_bending", "classical", "THEORIES",
        "register_theory", "get_theory", "evaluate", "SERIES_SWITCH"],
    "energy": ["Strains", "strains", "kinematics", "density", "pointwise", "intrinsic_function",
        "local_function", "LOCAL_OUTPUTS", "parameter_symbols", "boundary_layer_width",
        "unpack_intrinsic", "CACHE_SIZE"],
    "geometry": ["Geometry", "SPHERE", "DISC", "GEOMETRIES", "get_geometry"],
    "layouts": ["VectorLayout", "BASE_PARAMETERS", "parameter_layout", "INTRINSIC", "CELL_DATA",
        "BVP_STATE"],
    "problem": ["Problem", "Structure", "BASE_KEYS", "MIN_SHELL_LENGTH", "MIN_THICKNESS",
        "MIN_CUT"],
    "profiles": ["Profiles", "ProfileFamily", "FAMILIES", "register_family", "get_family",
        "available_families", "ENTRY_POINT_GROUP", "curvature_limit", "check_curvature"],
})
