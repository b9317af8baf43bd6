"""Inverse estimates from laser-ablation recoils: intrinsic curvature k and E/μ.

Paper, main text, Fig. 2 J-K: each embryo's k from its recoil by several
methods, and E/μ from the initial recoil velocities.
"""

import lazy_loader

# Every public name of the subpackage, imported from its module on first use.
__getattr__, __dir__, __all__ = lazy_loader.attach(__name__, submod_attrs={
    "core": ["MEASURES", "METHODS", "ASYMPTOTIC", "DEFAULT_K_RANGE", "GRID_STEP", "K_TOL", "NODES",
        "MU_MIN", "REQUIRED_COLUMNS", "OPTIONAL_COLUMNS", "UNITS", "MeasurementError",
        "Measurement", "read_measurements", "to_dimensionless", "to_physical", "RecoilModel",
        "RecoilPoint", "Estimate", "EmbryoEstimate", "Spread", "VelocityFit", "InverseResult",
        "estimate", "estimate_embryo", "summarise", "fit_velocity", "velocity_scale",
        "elastic_bounds"],
})
