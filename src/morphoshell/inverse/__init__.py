"""Inverse estimates from laser-ablation recoils: intrinsic curvature k and E/μ.

Paper, main text "Quantitative estimates of the curvature mismatch during
*Volvox* invagination…" and "Recoil velocity measurements yield a bound on the
elastic modulus…", Fig. 2 J–K: each embryo's k from its recoil by several
methods, and E/μ from the initial recoil velocities.

:func:`~morphoshell.inverse.pipeline.estimate` is the front door: a
measurement table (:mod:`morphoshell.io.measurements`, re-exported by
:mod:`.measurements`) in, an :class:`~morphoshell.inverse.result.InverseResult`
out.  Behind it: the numerical forward model, toy problem 2 with its exact
k-derivative (:mod:`.recoil_model`); the inversion of one measure by each
method (:mod:`.inversion`); one embryo's estimates and their combination
(:mod:`.embryo`); summaries over embryos (:mod:`.summaries`); E/μ and the
bounds on E (:mod:`.recoil_velocity`); the result (:mod:`.result`) and the
front door with its worker pool (:mod:`.pipeline`).
"""

import lazy_loader

# Every public name of the subpackage, imported from its module on first use.
__getattr__, __dir__, __all__ = lazy_loader.attach(__name__, submod_attrs={
    "measurements": ["MEASURES", "REQUIRED_COLUMNS", "OPTIONAL_COLUMNS", "UNITS",
                     "MeasurementError", "Measurement", "read_measurements", "to_dimensionless",
                     "to_physical"],
    "inversion": ["METHODS", "ASYMPTOTIC", "DEFAULT_K_RANGE", "GRID_STEP", "K_TOL", "Estimate"],
    "recoil_model": ["NODES", "RecoilModel", "RecoilPoint"],
    "embryo": ["EmbryoEstimate", "estimate_embryo"],
    "summaries": ["Spread", "summarise"],
    "recoil_velocity": ["MU_MIN", "VelocityFit", "fit_velocity", "velocity_scale",
                        "elastic_bounds"],
    "result": ["InverseResult"],
    "pipeline": ["estimate", "check_shells"],
})
