"""One embryo: k from each of its measures by every method, and its combined k.

Paper, main text "Quantitative estimates of the curvature mismatch during
*Volvox* invagination…", Fig. 2 J: each embryo's recoil (opening o, rotation
ϱ, displacement d) gives one estimate of k per measure and method
(:func:`morphoshell.inverse.inversion.invert`); the embryo's k is the
numerical ϱ and d estimates combined (their inverse-variance weighted mean).
The forward map of a method is sampled once per embryo and shared by its
three measures.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Callable, Mapping, Sequence

import numpy as np

from .._runtime.validate import name_list, short
from ..io.measurements import ERROR_COLUMN, MEASURES, UNITS, Measurement, to_physical
from ..mechanics import asymptotics
from ..model.profiles import check_curvature
from .inversion import (ASYMPTOTIC, DEFAULT_K_RANGE, METHODS, SYMBOL, Curve, Estimate,
                        check_k_range, forward_map, invert)
from .recoil_model import RecoilModel

__all__ = ["EmbryoEstimate", "estimate_embryo", "check_methods", "format_k", "NOT_REQUESTED"]

#: The note of the estimates of a method left out of ``methods`` (and of the combined k
#: without ``numerical``): no entry in the JSON or the table, and no note.
NOT_REQUESTED = "method not requested"


def format_k(k: float | None) -> str:
    """k printed with its sign and three decimals; ``null`` when there is none."""
    return "null" if k is None else f"{k:+.3f}"


@dataclass(frozen=True, eq=False)
class EmbryoEstimate:
    """Every estimate of one embryo, and the combined estimate from ϱ and d.

    ``estimates[(measure, method)]`` for every measure and method (``asymptotic``
    included, see :data:`morphoshell.inverse.inversion.ASYMPTOTIC`); ``combined``
    is the numerical ϱ and d estimates' inverse-variance weighted mean when both
    errors are given, else their mean (the paper's per-embryo k).  ``seconds``:
    the time spent by each requested method.
    """

    measurement: Measurement
    estimates: Mapping[tuple[str, str], Estimate]
    combined: Estimate
    seconds: Mapping[str, float] = field(default_factory=dict)

    def __repr__(self) -> str:
        ks = ", ".join(f"k_{SYMBOL[m]}={format_k(self.k(m))}" for m in MEASURES)
        return (f"EmbryoEstimate({self.measurement.embryo!r}, numerical {ks}, "
                f"combined={format_k(self.combined.k)})")

    def k(self, measure: str, method: str = "numerical") -> float | None:
        """The estimate of k (units of 1/R) from ``measure`` by ``method``; None if there is
        none."""
        return self.estimates[(measure, method)].k

    @property
    def notes(self) -> list[str]:
        """Why estimates are missing (``measure, method: reason``)."""
        out = [f"{m}, {meth}: {e.note}" for (m, meth), e in self.estimates.items()
               if e.note and meth != "asymptotic" and e.note != NOT_REQUESTED]
        c = self.combined.note
        return out + ([f"combined: {c}"] if c and c != NOT_REQUESTED else [])

    def to_dict(self) -> dict:
        """The JSON object of the embryo (keys ``k_<measure>_<method>`` …, ``notes``)."""
        m = self.measurement
        out: dict = {"embryo": m.embryo, "row": m.row, "h": m.h, "cut_rad": m.cut,
                     "sigma_inner": m.cut / asymptotics.delta(m.h)}
        # (a method not run has no entry: a column of nulls read as its failure)
        for (measure, method), e in self.estimates.items():
            if e.note != NOT_REQUESTED:
                out[f"k_{measure}_{method}"] = e.k
                out[f"k_{measure}_{method}_error"] = e.error   # (null without sigma: same keys)
        if self.combined.note != NOT_REQUESTED:
            out["k_combined"] = self.combined.k
            out["k_combined_error"] = self.combined.error
        out["notes"] = self.notes
        if m.extra:
            out["extra"] = dict(m.extra)
        return out


def _combine(estimates: Sequence[Estimate]) -> Estimate:
    """Inverse-variance weighted mean of the estimates with a k (their mean without errors)."""
    ok = [e for e in estimates if e.k is not None]
    if not ok:
        return Estimate("combined", "numerical", None, status="missing",
                        note="no numerical estimate from the rotation or the displacement")
    if all(e.error for e in ok):
        w = np.array([1 / e.error**2 for e in ok])
        k = float(np.dot(w, [e.k for e in ok]) / w.sum())
        return Estimate("combined", "numerical", k, float(1 / math.sqrt(w.sum())))
    # (a weighted mean of the estimates with errors alone would drop the others' k: the plain
    # mean keeps both, and the note says so, since the column mixes the two otherwise unseen)
    missing = [ERROR_COLUMN[e.measure] for e in ok if not e.error]
    return Estimate("combined", "numerical", float(np.mean([e.k for e in ok])),
                    note=f"plain mean of {', '.join(e.measure for e in ok)}, not weighted: "
                         f"no {' or '.join(missing)} (empty cell), so no error")


def _formatter(measure: str, R_um: float) -> Callable[[float], str]:
    """Values in units of R or radians, printed in the table's unit (µm to 1 nm, 0.01°)."""
    def fmt(v: float) -> str:
        return f"{to_physical(measure, float(v), R_um):.{2 if measure == 'rotation' else 3}f} " \
               f"{UNITS[measure]}"
    return fmt


def _without_inversion(m: Measurement, measure: str, method: str) -> Estimate | None:
    """The estimate when there is nothing to invert: no value, or no formula; else None."""
    if m.value(measure) is None:
        return Estimate(measure, method, None, status="missing", note=f"no {measure} measured")
    if method == "kelvin" and measure == "opening":
        return Estimate(
            measure, method, None, status="no_formula",
            note="no small-cut closed form for the opening (the equation for u is not integrable "
                 "in closed form; the inner method solves it)")
    return None


def _by_method(m: Measurement, method: str, curve: Curve,
               k_range: tuple[float, float]) -> dict[tuple[str, str], Estimate]:
    """Every measure's estimate by one method; after a solver fails, the rest fail with it."""
    out: dict[tuple[str, str], Estimate] = {}
    failure = None
    for measure in MEASURES:
        none = _without_inversion(m, measure, method)
        if none is not None:
            out[(measure, method)] = none
            continue
        if failure is None:
            try:
                if not curve.points:
                    curve.sample(k_range)
                out[(measure, method)] = invert(curve, measure, method, m.value(measure),
                                                m.error(measure), k_range,
                                                _formatter(measure, m.R_um))
                continue
            except (RuntimeError, ValueError) as exc:   # SolverError, solve_bvp, a shell
                failure = exc                             # the k-range makes invalid
        out[(measure, method)] = Estimate(measure, method, None, status="failed",
                                          note=f"solver failed: {failure}")
    return out


def check_methods(methods) -> tuple[str, ...]:
    """The methods asked for (names, or one comma-separated string: "kelvin" is one method, not
    six letters), each once in the order asked (a method asked twice was listed, and run,
    twice); ValueError naming the unknown ones, or none at all (``''`` or ``[]`` returned a
    result without a single estimate); TypeError for what is not names (``3``)."""
    asked = name_list(methods, "methods")
    unknown = [m for m in asked if m not in METHODS]
    if unknown:
        raise ValueError(f"methods = {short(methods)}: unknown method(s) {short(unknown)}; "
                         f"valid: {list(METHODS)}")
    if not asked:
        raise ValueError(f"methods = {short(methods)} names no method; choose from "
                         f"{list(METHODS)}")
    return tuple(dict.fromkeys(asked))


def estimate_embryo(m: Measurement, model: RecoilModel | None = None,
                    k_range: tuple[float, float] = DEFAULT_K_RANGE,
                    methods: Sequence[str] = METHODS) -> EmbryoEstimate:
    """Estimates of k for one embryo by every method and measure.

    Parameters
    ----------
    m : Measurement
        The embryo's shell, cut and recoil.
    model : RecoilModel, optional
        The numerical model (default: a new one, if ``"numerical"`` is requested).
    k_range : (float, float)
        Range of k searched.
    methods : sequence of str, or str
        Subset of :data:`morphoshell.inverse.inversion.METHODS` (or one comma-separated
        string of them, :func:`check_methods`); the others
        get the status ``missing`` (note :data:`NOT_REQUESTED`), and so does the
        combined k without ``"numerical"``.

    Returns
    -------
    EmbryoEstimate
        With an :class:`~morphoshell.inverse.inversion.Estimate` for each of
        the 3 measures × 5 methods (``asymptotic`` included) and the combined k.

    Raises
    ------
    ValueError
        An unknown method; a bad k-range, or one reaching |k| ≥ 2/h, a curvature the shell
        cannot have (:func:`morphoshell.model.profiles.check_curvature`).

    See Also
    --------
    morphoshell.inverse.pipeline.estimate : a whole table.
    """
    methods = check_methods(methods)
    if model is None and "numerical" in methods:
        model = RecoilModel()
    k_range = check_k_range(k_range)
    check_curvature(k_range, m.h, f"k_range = {k_range!r}", f"embryo {m.embryo!r}")
    out: dict[tuple[str, str], Estimate] = {}
    seconds: dict[str, float] = {}
    for method in METHODS:
        t0 = time.perf_counter()
        if method not in methods:
            for measure in MEASURES:
                out[(measure, method)] = Estimate(measure, method, None, status="missing",
                                                  note=NOT_REQUESTED)
            continue
        curve = Curve(forward_map(method, m.h, m.cut, model))
        out |= _by_method(m, method, curve, k_range)
        seconds[method] = time.perf_counter() - t0
    for measure in MEASURES:
        out[(measure, "asymptotic")] = out[(measure, ASYMPTOTIC[measure])]
    combined = (_combine([out[("rotation", "numerical")], out[("displacement", "numerical")]])
                if "numerical" in methods else
                Estimate("combined", "numerical", None, status="missing", note=NOT_REQUESTED))
    return EmbryoEstimate(m, out, combined, seconds)
