"""The front door: a measurement table → every estimate, their summaries, and E/μ.

Paper, main text "Quantitative estimates of the curvature mismatch during
*Volvox* invagination…" and "Recoil velocity measurements yield a bound on the
elastic modulus…", Fig. 2 J–K.  :func:`estimate` checks its arguments, builds
one numerical model for the whole table (meshed for its median shell), shares
the embryos between forked worker processes
(:func:`morphoshell.inverse.embryo.estimate_embryo` for each), summarises
every estimate over the embryos and fits E/μ to the recoil velocities.

Every random draw (the bootstrap intervals) comes from its own generator,
seeded with (``seed``, index of the summary), so that the numbers depend
neither on the workers nor on which estimates were requested.
"""
from __future__ import annotations

import logging
import math
import multiprocessing
import os
import time
from pathlib import Path
from typing import Iterable, Sequence

import numpy as np

from .._runtime.workers import worker_start
from .._runtime.console import progress as _progress_bar
from ..io.measurements import MEASURES, Measurement, read_measurements
from ..model.profiles import check_curvature
from .embryo import EmbryoEstimate, check_methods, estimate_embryo
from .inversion import ASYMPTOTIC, DEFAULT_K_RANGE, GRID_STEP, K_TOL, METHODS, check_k_range
from .recoil_model import NODES, RecoilModel
from .recoil_velocity import MU_MIN, VelocityFit, fit_velocity, velocity_scale
from .result import InverseResult
from .summaries import BOOTSTRAP, SEED, Spread, check_bootstrap, summarise

log = logging.getLogger(__name__)

__all__ = ["estimate", "check_shells"]


# --------------------------------------------------------------------------
# arguments
# --------------------------------------------------------------------------

def _load(measurements) -> tuple[Measurement, ...]:
    """The measurements of a table's path, or the given ones, checked."""
    data = read_measurements(measurements) if isinstance(measurements, (str, Path)) \
        else tuple(measurements)
    if not data:
        raise ValueError("no measurements")
    if not all(isinstance(m, Measurement) for m in data):
        raise ValueError("measurements must be Measurement objects or a table's path")
    return data


def _check_settings(k_range, mu_min, bootstrap) -> tuple[float, float]:
    """ValueError for a bad k-range, μ_min or bootstrap; the k-range."""
    k_range = check_k_range(k_range)
    if not (isinstance(mu_min, (int, float)) and math.isfinite(mu_min) and mu_min > 0):
        raise ValueError(f"mu_min = {mu_min!r} must be a positive number (Pa s)")
    check_bootstrap(bootstrap)
    return k_range


def check_shells(data: Sequence[Measurement], k_range: tuple[float, float],
                 label: str | None = None) -> None:
    """ValueError when a shell of ``data`` cannot have every k of ``k_range`` (before any work).

    The thickest shell bounds the range: |k| < 2/h
    (:func:`~morphoshell.model.profiles.curvature_limit`).

    Parameters
    ----------
    data : sequence of Measurement
        The embryos (not empty).
    k_range : (float, float)
        A checked k-range.
    label : str, optional
        How the message names the range (default ``k_range = (lo, hi)``).
    """
    thickest = max(data, key=lambda m: m.h)
    check_curvature(k_range, thickest.h, label or f"k_range = {tuple(k_range)!r}",
                    f"the thickest shell, embryo {thickest.embryo!r}")


def _check_workers(workers, n: int) -> int:
    """Worker processes: default one per core (at most one per embryo); fork only (POSIX)."""
    if workers is None:
        workers = os.cpu_count() or 1
    if isinstance(workers, bool) or not isinstance(workers, (int, np.integer)) or workers < 1:
        raise ValueError(f"workers = {workers!r} must be a positive integer")
    if "fork" not in multiprocessing.get_all_start_methods():
        return 1
    return int(min(workers, n))


# --------------------------------------------------------------------------
# the embryos, in this process or in forked workers
# --------------------------------------------------------------------------

#: What forked workers of :func:`estimate` inherit.
_WORKER: dict = {}


def _estimate_in_worker(m: Measurement) -> EmbryoEstimate:
    return estimate_embryo(m, _WORKER["model"], _WORKER["k_range"], _WORKER["methods"])


def _estimate_embryos(data: tuple[Measurement, ...], model: RecoilModel | None, k_range,
                      methods: Sequence[str], workers: int,
                      progress: bool | None) -> tuple[EmbryoEstimate, ...]:
    """Every embryo's estimates, in the order of ``data``, with a progress bar."""
    bar = dict(total=len(data), desc="embryos", unit="embryo", enabled=progress)
    if workers == 1:
        return tuple(estimate_embryo(m, model, k_range, methods)
                     for m in _progress_bar(data, **bar))
    # Embryos are independent (each starts from k = 1), so the result does not
    # depend on how they are shared.  Forked workers inherit the built solvers (and
    # the command line's signal handlers, which worker_start puts back).
    _WORKER.update(model=model, k_range=k_range, methods=tuple(methods))
    try:
        with multiprocessing.get_context("fork").Pool(
                workers, initializer=worker_start) as pool:
            return tuple(_progress_bar(pool.imap(_estimate_in_worker, data, chunksize=1),
                                       **bar))
    finally:
        _WORKER.clear()


# --------------------------------------------------------------------------
# over the embryos
# --------------------------------------------------------------------------

def _keys() -> list[str]:
    """The summaries' keys: ``<measure>_<method>`` (``asymptotic`` first), then ``combined``."""
    return [f"{m}_{meth}" for m in MEASURES for meth in ("asymptotic", *METHODS)] + ["combined"]


def _summaries(embryos: tuple[EmbryoEstimate, ...], keys: list[str], bootstrap: int,
               seed: int) -> dict[str, Spread]:
    """A :class:`~morphoshell.inverse.summaries.Spread` per key, every key's bootstrap from
    the same resamples of the embryos (seeded (seed, 0)): equal estimates get equal
    intervals, and two methods' intervals differ by their estimates, not by the draws
    (each key had its own stream: rotation's asymptotic and Kelvin estimates, equal,
    got [-0.118, 0.027] and [-0.118, 0.023])."""
    summary: dict[str, Spread] = {}
    for key in keys:
        if key == "combined":
            ests = [e.combined for e in embryos]
        else:
            measure, method = key.split("_", 1)
            ests = [e.estimates[(measure, method)] for e in embryos]
        ok = [e for e in ests if e.k is not None]
        summary[key] = summarise([e.k for e in ok], [e.error for e in ok], bootstrap,
                                 np.random.default_rng([seed, 0]))
    return summary


def _velocity_fit(embryos: tuple[EmbryoEstimate, ...], data: tuple[Measurement, ...],
                  mu_min: float, bootstrap: int, rng: np.random.Generator) -> VelocityFit | None:
    """E/μ from the embryos with a velocity and a combined k (None if there is none)."""
    with_v = [e for e in embryos if e.measurement.V_um_per_s is not None]
    fitted = [e for e in with_v if e.combined.k is not None]
    if not fitted:
        return None
    return fit_velocity(
        [e.measurement.V_um_per_s for e in fitted],
        [velocity_scale(e.measurement.H_um, e.measurement.R_um, e.combined.k) for e in fitted],
        mu_min=mu_min, H_mean_um=float(np.mean([m.H_um for m in data])),
        embryos=[e.measurement.embryo for e in fitted], bootstrap=bootstrap, rng=rng,
        excluded=[e.measurement.embryo for e in with_v if e.combined.k is None])


def estimate(measurements: str | Path | Iterable[Measurement], *,
             theory: str = "large_bending", k_range: tuple[float, float] = DEFAULT_K_RANGE,
             mu_min: float = MU_MIN, bootstrap: int = BOOTSTRAP, seed: int = SEED,
             nodes: int = NODES, methods: Sequence[str] | str = METHODS,
             workers: int | None = None, progress: bool | None = None) -> InverseResult:
    """Estimate k for every embryo and measure, summarise, and fit E/μ.

    Parameters
    ----------
    measurements : path or iterable of Measurement
        A table (:func:`morphoshell.io.measurements.read_measurements`) or measurements.
    theory : {"large_bending", "classical"}
        Shell theory of the numerical model.
    k_range : (float, float)
        Range of k searched (default
        :data:`~morphoshell.inverse.inversion.DEFAULT_K_RANGE`).
    mu_min : float
        Lower bound of the effective viscosity (Pa s).
    bootstrap : int
        Resamples of the bootstrap intervals (0: none).
    seed : int
        Seed of the bootstrap.
    nodes : int
        Mesh nodes of the numerical model.
    methods : sequence of str, or str
        Subset of :data:`~morphoshell.inverse.inversion.METHODS` to compute
        (the others are null): names, or one string of comma-separated names
        (``"kelvin"``, ``"kelvin,inner"``); at least one, each once (repeats are dropped).
    workers : int, optional
        Processes sharing the embryos (default: one per core; 1: this one).
        The estimates do not depend on it.
    progress : bool, optional
        A progress bar over the embryos on standard error (default: when it
        is a terminal and the ``morphoshell`` logger shows warnings).

    Returns
    -------
    InverseResult
        ``embryos`` (one :class:`~morphoshell.inverse.embryo.EmbryoEstimate`
        per row), ``summary`` (a Spread per estimate), ``velocity`` (the E/μ
        fit, None without velocities), ``settings`` and ``timing``.

    Raises
    ------
    MeasurementError
        For a bad table (:func:`morphoshell.io.measurements.read_measurements`).
    ValueError
        For no measurements, an unknown method or none at all, or a bad k-range (one that a
        shell cannot have included: |k| ≥ 2/h, :func:`check_shells`), ``mu_min``,
        ``bootstrap`` or ``workers``.
    TypeError
        ``methods`` neither a string nor a sequence
        (:func:`~morphoshell.inverse.embryo.check_methods`).
    """
    t0 = time.perf_counter()
    data = _load(measurements)
    methods = check_methods(methods)
    k_range = _check_settings(k_range, mu_min, bootstrap)
    check_shells(data, k_range)
    model = None
    if "numerical" in methods:
        model = RecoilModel(theory, nodes, mesh_for=(float(np.median([m.h for m in data])),
                                                      float(np.median([m.cut for m in data]))))
    workers = _check_workers(workers, len(data))
    log.info("estimating k of %d embryos (methods %s, %d worker%s)", len(data),
             ", ".join(methods), workers, "s" * (workers != 1))
    embryos = _estimate_embryos(data, model, k_range, methods, workers, progress)
    t1 = time.perf_counter()
    keys = _keys()
    summary = _summaries(embryos, keys, bootstrap, seed)
    velocity = _velocity_fit(embryos, data, mu_min, bootstrap,
                             np.random.default_rng([seed, len(keys)]))
    per_method = {f"{meth}_seconds": sum(e.seconds.get(meth, 0.0) for e in embryos)
                  for meth in METHODS}
    timing = {"total": time.perf_counter() - t0, "estimates": t1 - t0, **per_method,
              "numerical_solver_builds": 0 if model is None else model.builds,
              "workers": workers}
    settings = {"theory": theory, "k_range": list(k_range), "mu_min_Pa_s": mu_min,
                "bootstrap": bootstrap, "seed": seed, "nodes": nodes, "methods": list(methods),
                "workers": workers,
                "grid_step": GRID_STEP, "k_tol": K_TOL,
                "asymptotic": dict(ASYMPTOTIC)}
    if isinstance(measurements, (str, Path)):
        settings["input"] = str(measurements)
    return InverseResult(embryos, summary, velocity, settings, timing)
