"""The measurement table, as the inverse estimates offer it.

The table of laser ablations (one row per embryo, in µm, degrees and µm/s)
is read and checked in :mod:`morphoshell.io.measurements`, below this
subpackage in the layers; its names are re-exported here so that
``from morphoshell.inverse import read_measurements, Measurement`` offers the
input of :func:`morphoshell.inverse.pipeline.estimate` beside it (the lazy
exports of ``morphoshell.inverse`` reach only its own modules).
"""
from ..io.measurements import (MEASURES, OPTIONAL_COLUMNS, REQUIRED_COLUMNS, UNITS, Measurement,
                               MeasurementError, read_measurements, to_dimensionless, to_physical)

__all__ = ["MEASURES", "REQUIRED_COLUMNS", "OPTIONAL_COLUMNS", "UNITS", "MeasurementError",
           "Measurement", "read_measurements", "to_dimensionless", "to_physical"]
