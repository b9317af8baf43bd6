"""Former single module of the inverse estimates, kept so that old imports still work.

``from morphoshell.inverse.core import estimate, Measurement`` (the README's
example, user scripts) keeps working; new code imports from
``morphoshell.inverse``.  Each name is defined in the module of its job (see
the subpackage's docstring) or, for the measurement table, in
:mod:`morphoshell.io.measurements`.
"""
from ..io.measurements import (ERROR_COLUMN, MEASURE_COLUMN, MEASURES, OPTIONAL_COLUMNS,
                               REQUIRED_COLUMNS, UNITS, Measurement, MeasurementError,
                               read_measurements, to_dimensionless, to_physical)
from .embryo import EmbryoEstimate, estimate_embryo
from .inversion import (ASYMPTOTIC, DEFAULT_K_RANGE, GRID_STEP, K_TOL, MAX_STEPS, METHODS, SYMBOL,
                        Estimate)
from .pipeline import estimate
from .recoil_model import NODES, RecoilModel, RecoilPoint
from .recoil_velocity import MU_MIN, VelocityFit, elastic_bounds, fit_velocity, velocity_scale
from .result import InverseResult
from .summaries import BOOTSTRAP, SEED, Spread, summarise

__all__ = [
    "MEASURES", "METHODS", "ASYMPTOTIC", "DEFAULT_K_RANGE", "GRID_STEP", "K_TOL", "NODES",
    "MU_MIN", "REQUIRED_COLUMNS", "OPTIONAL_COLUMNS", "UNITS",
    "MeasurementError", "Measurement", "read_measurements", "to_dimensionless", "to_physical",
    "RecoilModel", "RecoilPoint", "Estimate", "EmbryoEstimate", "Spread", "VelocityFit",
    "InverseResult", "estimate", "estimate_embryo", "summarise", "fit_velocity",
    "velocity_scale", "elastic_bounds",
    "MEASURE_COLUMN", "ERROR_COLUMN", "SYMBOL", "MAX_STEPS", "BOOTSTRAP", "SEED",
]
