"""What a fit returns: the fitted equilibrium, its parameters and their uncertainty.

The Gauss–Newton covariance of the fitted parameters comes from the exact
Jacobian J of the residuals: σ² (JᵀJ)⁻¹ with σ² = E_fit²/(2N − n).  The
residuals of a traced midline are correlated along it (one tracing, one smooth
curve), so these standard errors are *lower bounds*.  Small singular values of
the Jacobian scaled by the parameters' magnitudes flag poorly identified
directions.  A fitted state near a **fold** of the inner equilibrium branch
shows as one singular value that dwarfs all others (the inner Hessian is
nearly singular, so ∂x/∂p ~ 1/λ_min blows up along one direction): a
least-squares fit can creep onto a fold, where a tiny E_fit gain buys a large
change of shape and the standard errors collapse.  Such a fit is reported as
not converged (:data:`FOLD_RATIO`).

A fit's record (:meth:`FitResult.to_dict`, the JSON of ``morphoshell fit --json``) reads
back as a FitResult with :func:`load_fit` (:meth:`FitResult.from_dict`), without the
fitted equilibrium, which the record does not hold.

Lengths and E_fit in units of R.
"""
from __future__ import annotations

import math

from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any, Mapping, Sequence

import numpy as np

from .._runtime.tables import problem_attrs, xarray_module
from .._runtime.validate import choice, flag, integer, real, short, text, within
from ..io.problem_files import problem_of_record, read_json
from ..io.provenance import note_unknown
from ..numerics.status import (FIT_CONVERGED, FIT_CONVERGED_STOPS, FIT_NEAR_FOLD,
                               IPOPT_UNKNOWN, STATUSES)
from ..solvers.contact import WallContact, wall_contact
from ..solvers.results import Equilibrium, SolverError
from .spec import LABELS
from .trace_errors import MAX_REFUSED, Retracings

if TYPE_CHECKING:
    from ..model.problem import Problem
    from .inner import InnerProblem
    from .spec import FitSpec

__all__ = ["FitResult", "FitError", "fit_result", "load_fit", "FOLD_RATIO", "KNOWN"]

#: Entries of a fit's record (:meth:`FitResult.to_dict`) that :meth:`FitResult.from_dict` needs.
_RECORD_KEYS = ("problem", "parameters", "fitted", "standard_errors", "correlation",
                "poorly_identified", "E_fit", "method", "variant", "converged",
                "data_midline", "fitted_midline")

#: Every entry of a fit's record, in one place: others are not read, and :func:`load_fit`
#: warns of them (:func:`~morphoshell.io.provenance.note_unknown`, as ``load_equilibrium``).
KNOWN = (*_RECORD_KEYS,
         # the rest of FitResult.to_dict (units and note are rewritten from the fields)
         "units", "standard_errors_source", "re_tracings", "E_fit_units", "stop", "message",
         "seconds", "constrained", "outer_iterations", "inner_solves", "walls_cross", "note",
         # morphoshell fit --json (cli/fit.py: fit_record, multi-start, profiles, input_check)
         "midline_file", "solver", "settings", "input_check", "started_from", "starts",
         "profile_intervals", "profiles", "replaced_fit", "complete", "not_done", "provenance",
         # a campaign's record (workflows/timepoint_fits.py)
         "status", "label", "timepoint", "pseudotime", "data", "first_start", "previous",
         "held_from", "traces", "held", "start_candidates", "other_starts", "continued", "state",
         "fitted_by", "embryo_standard_errors", "embryo_t95", "embryo_errors_message",
         "embryo_fits", "nodes")

#: A fit whose scaled Jacobian has its second singular value below this fraction of the
#: first sits near a fold of the inner branch (module docstring) and is not converged
#: (tuned between the synthetic inversion fits on their branch and one on a fold).
FOLD_RATIO = 1e-4
#: What a fit's record and tables say of Gauss–Newton standard errors (and of a record
#: written before records said which errors they hold: :attr:`FitResult.standard_errors_source`).
_NOTE = ("standard errors are Gauss-Newton lower bounds: the residuals of a traced midline "
         "are correlated")
#: The values of :attr:`FitResult.standard_errors_source`, in records and tables.
GAUSS_NEWTON, RE_TRACINGS = "gauss-newton", "re-tracings"


class FitError(SolverError):
    """A fit that did not deliver (status names why; the last state is attached).

    A :class:`morphoshell.solvers.results.SolverError`: ``status`` (e.g.
    ``"Fit_Saddle"``, ``"Fit_Not_Reproduced"``, ``"Gauss_Newton_Stopped"``
    or Ipopt's status) and ``last_iterate``; the KKT fit also sets
    ``iterations``, the outer iterations spent before it.
    """


@dataclass(frozen=True, eq=False)
class FitResult:
    """A fitted equilibrium and how it was found.

    Attributes
    ----------
    method : str
        The fit method (:data:`morphoshell.fitting.bilevel.METHODS`).
    variant : str
        The fit's label (:attr:`FitSpec.variant`).
    fitted : tuple of str
        The fitted parameters, in the order of θ.
    parameters : dict
        Every family parameter by name, plus ``h``, ``cut``, ``opening``.
    standard_errors : dict
        Standard errors of the fitted parameters: Gauss–Newton's (lower bounds: the
        residuals of a traced midline are correlated), or for a fit of one image trace
        those of its re-tracings (:func:`~morphoshell.fitting.trace_errors.with_trace_errors`);
        :attr:`standard_errors_source` says which.
    correlation : ndarray, shape (k, k)
        Their correlation matrix, in the order of ``fitted``.
    poorly_identified : list of dict
        Directions of θ (scaled by the parameters' magnitudes) with singular
        values below 1e-3 of the largest: ``{"singular_value", "direction"}``.
    constrained : tuple of str
        The hard constraints the fit ends on (:meth:`FitSpec.on_constraints`,
        e.g. ``"s3 - s2 = sigma"``); the standard errors of the parameters in
        them are NaN (a constrained optimum has none of a free one's).
    E_fit : float
        The fit energy (units of R).
    residuals : ndarray, shape (2N,)
        r − R then z − Z at the N points.
    equilibrium : Equilibrium or None
        The fitted shape; None for a fit read back from its record (:func:`load_fit`).
    data, model : ndarray, shape (N, 2)
        The data midline and the fitted midline (r, z).
    outer_iterations : int
        Outer iterations in all (the method's own count: function
        evaluations, least-squares evaluations or Ipopt iterations).
    inner_solves : int
        Inner equilibrium solves.
    seconds : float
        Wall time of the fit (NaN for a record read back without it: a campaign's).
    converged : bool
        Whether the method converged to a fit that is not near a fold.
    message : str
        The method's message, and what the fit ends on.
    stop : str
        How the fit ended, a key of :data:`morphoshell.numerics.status.STATUSES`
        (what it means and what to try: :func:`morphoshell.numerics.status.explain`):
        ``"Fit_Converged"`` or, of the KKT fit, Ipopt's status;
        ``"Maximum_Evaluations_Exceeded"``, ``"Fit_Stalled"``,
        ``"Fit_Not_Stationary"``, ``"Fit_Near_Fold"``, ``"Fit_On_Box_Edges"``
        or ``"Fit_Moved_Boxes_Failed"``.  In :meth:`to_dict` (a record written
        before it reads back with ``"Fit_Converged"``, or ``"Unknown"`` if it did
        not converge).
    problem : Problem
        The fitted shell (the equilibrium's problem, if not given).
    jacobian : ndarray, shape (2N, k), or None
        The residuals' exact Jacobian at the fit (None for a record read back): the
        sandwich errors of a fit to one image trace need it
        (:mod:`morphoshell.fitting.trace_errors`).  Not in :meth:`to_dict`.
    contact : WallContact or None
        Where the fitted shape's walls pass through each other
        (:func:`~morphoshell.solvers.contact.wall_contact`), or None.  The model has no
        self-contact: such a fit is a minimum of the model but not a physical shape.  The
        record's ``walls_cross`` (null where they do not cross).
    re_tracings : Retracings or None
        The re-tracings of the fit's image trace, where they were made
        (:func:`~morphoshell.fitting.trace_errors.with_trace_errors`: their count, how many
        the reader refused, the noise σ, the seed and the Gauss–Newton errors they replaced);
        None for a fit without them.  The record's ``re_tracings``.
    source_recorded : bool
        False for a record written before records said which standard errors they hold (no
        ``standard_errors_source`` entry): :attr:`standard_errors_source` is None (not
        known) and :meth:`to_dict` leaves the entry out again.
    contact_checked : bool
        Whether the fitted shape was checked for it: False for a record written before
        the check (no ``walls_cross`` entry), whose :attr:`walls_cross` is None (unknown,
        as the campaign summary's empty cell) and whose :meth:`to_dict` leaves the entry
        out again.
    """

    method: str
    variant: str
    fitted: tuple[str, ...]
    parameters: dict
    standard_errors: dict
    correlation: np.ndarray
    poorly_identified: list
    E_fit: float
    residuals: np.ndarray
    equilibrium: Equilibrium
    data: np.ndarray
    model: np.ndarray
    outer_iterations: int
    inner_solves: int
    seconds: float
    converged: bool
    message: str = ""
    constrained: tuple[str, ...] = ()
    stop: str = FIT_CONVERGED
    problem: Problem | None = None
    jacobian: np.ndarray | None = None
    contact: WallContact | None = None
    contact_checked: bool = True
    re_tracings: Retracings | None = None
    source_recorded: bool = True

    def __post_init__(self):
        if self.problem is None:    # (None too where a test's stand-in has no problem)
            object.__setattr__(self, "problem", getattr(self.equilibrium, "problem", None))

    @classmethod
    def from_dict(cls, record: Mapping[str, Any], where: str = "the record") -> "FitResult":
        """The fit of its record (:meth:`to_dict`, ``morphoshell fit --json``, a campaign's).

        Everything :meth:`to_dict` writes comes back (standard errors and correlations
        that JSON writes as null, on constraints, as NaN), so that ``to_dict()`` gives
        the record again.  What it does not write: the ``equilibrium`` (None: solve
        ``problem`` for one), the ``residuals`` (the fitted minus the data midline, to
        round-off).  A record without ``stop`` (written before records kept it) reads
        back with ``"Fit_Converged"``, or ``"Unknown"`` for a fit that did not converge
        (its ``message`` says how it ended); one without ``standard_errors_source`` with
        that not known (:attr:`source_recorded`).

        Parameters
        ----------
        record : mapping
            A fit's record.
        where : str
            The file or record, for messages.

        Returns
        -------
        FitResult

        Raises
        ------
        ValueError
            A failed fit's record, a missing entry, a problem its parameters disagree
            with (:func:`~morphoshell.io.problem_files.problem_of_record`), or an entry
            that is not what :meth:`to_dict` writes (of another type, not finite, of
            another length, an unknown method, variant or stop): one line naming
            ``where``, the entry and what it must be.
        """
        if record.get("status", "ok") != "ok":
            raise ValueError(f"{where}: the fit failed ({record.get('message', 'no message')}): "
                             f"it has no result")
        missing = [k for k in _RECORD_KEYS if k not in record]
        if missing:
            raise ValueError(f"{where}: no {', '.join(missing)}: not a fit's record (the JSON "
                             f"of morphoshell fit --json or FitResult.to_dict())")
        fields = _record_fields(record, where)
        problem = problem_of_record(record, where)
        fields["contact_checked"] = "walls_cross" in record
        if record.get("walls_cross") is not None:     # (its s within the problem's shell)
            fields["contact"] = _entry(record, "walls_cross", where, _contact,
                                       (problem.cut, problem.end))
        data, model = (_entry(record, key, where, _midline)
                       for key in ("data_midline", "fitted_midline"))
        if len(data) != len(model):
            raise ValueError(f"{where}: fitted_midline has {len(model)} points, data_midline "
                             f"{len(data)}: expected one fitted point for each data point")
        result = cls(**fields, residuals=np.concatenate([model[:, 0] - data[:, 0],
                                                         model[:, 1] - data[:, 1]]),
                     equilibrium=None, data=data, model=model, problem=problem)
        _check_source(record, result, where)
        return result

    def __repr__(self) -> str:
        return (f"FitResult({self.method}, {self.variant}, E_fit={self.E_fit:.6g} R, "
                f"{len(self.fitted)} parameters, {self.outer_iterations} iterations, "
                f"{self.inner_solves} inner solves, "
                f"{f'{self.seconds:.2f} s' if math.isfinite(self.seconds) else 'time not recorded'}"
                f", "
                f"converged={self.converged})")

    def summary(self) -> str:
        """A few lines: the result, which standard errors (:attr:`standard_errors_source`),
        every fitted parameter with its standard error and unit,
        the constraints it ends on and the poorly identified directions (as sums of the
        parameters, e.g. ``0.718 kappa1 + 0.585 f2 + 0.195 f4``)."""
        lines = [repr(self), self._errors_line()]
        for n in self.fitted:
            e, unit = self.standard_errors[n], self.unit(n)
            value = f"{self.parameters[n]: .6g}"
            lines.append(f"  {n:8s} = " + (f"{value} ± {e:.2g} {unit}".rstrip() if np.isfinite(e)
                                          else f"{value} {unit} (on a constraint)"))
        for c in self.constrained:
            lines.append(f"  on the constraint {c}")
        for d in self.poorly_identified:
            lines.append(f"  poorly identified: {_combination(d['direction'], len(self.fitted))} "
                         f"(parameters relative to their size; singular value "
                         f"{d['singular_value']:.2g} of the largest)")
        return "\n".join(lines)

    @property
    def walls_cross(self) -> bool | None:
        """Whether the fitted shape's walls pass through each other (:attr:`contact`); None
        for a record written before the check (:attr:`contact_checked`): not known."""
        return self.contact is not None if self.contact_checked else None

    @property
    def standard_errors_source(self) -> str | None:
        """Which standard errors the fit holds: ``"gauss-newton"`` (σ²(JᵀJ)⁻¹, lower bounds),
        ``"re-tracings"`` (the sandwich of its image trace's re-tracings: :attr:`re_tracings`),
        or None for a record that does not say (:attr:`source_recorded`: written before
        records said; its note says Gauss–Newton, but ``morphoshell fit`` of one image trace
        wrote the re-tracings' errors under it)."""
        if not self.source_recorded:
            return None
        return RE_TRACINGS if self.re_tracings is not None and self.re_tracings.used \
            else GAUSS_NEWTON

    @property
    def note(self) -> str:
        """What the record and the tables say of the standard errors (their ``note``)."""
        if self.standard_errors_source != RE_TRACINGS:
            refused = self.re_tracings
            return _NOTE + ("" if refused is None else
                            f" (the reader refused {refused.refused} of the "
                            f"{refused.replicates} re-tracings of the image trace that would "
                            f"have given its errors: re_tracings)")
        return (f"standard errors are the sandwich of {self.re_tracings.describe()} of the "
                f"image trace carried through the reader, not the Gauss-Newton ones "
                f"(re_tracings.gauss_newton_errors), which take the midline's points as "
                f"independent")

    def _errors_line(self) -> str:
        """The summary's line on the standard errors."""
        source = self.standard_errors_source
        if source is None:
            return ("  ± not known to be Gauss–Newton's or the re-tracings' (a record written "
                    "before records said: standard_errors_source)")
        if source == GAUSS_NEWTON:
            return "  ± Gauss–Newton (lower bounds: the midline's residuals are correlated)" + (
                "" if self.re_tracings is None else
                f"; the re-tracings of its trace: {self.re_tracings.refused} of "
                f"{self.re_tracings.replicates} refused by the reader")
        return f"  ± from {self.re_tracings.describe()} of the image trace, not Gauss–Newton"

    def unit(self, name: str) -> str:
        """How the unit of parameter ``name`` is printed: ``"1/R"``, ``"R"``,
        ``"(dimensionless)"`` (the family's :attr:`~morphoshell.model.profiles.ProfileFamily.units`;
        h and the opening are lengths), or ``""`` where the family gives none."""
        unit = self._unit(name)
        return "(dimensionless)" if unit == "1" else unit

    def _unit(self, name: str) -> str:
        """The unit of parameter ``name`` as tables write it: ``"1"``, ``"1/R"``, ``"R"``
        (:meth:`unit`), or ``""``."""
        return {"h": "R", "opening": "R", "cut": "R",
                **self.problem.family_obj.units}.get(name, "")

    def table(self) -> dict[str, list]:
        """The fit as columns, one row per parameter: what ``morphoshell fit --csv`` writes
        and :meth:`to_dataframe` holds.

        Returns
        -------
        dict of str to list
            The fitted parameters first (in the order of θ), then the others of
            :attr:`parameters` (held, tied to others, or the shell's h, cut and opening):
            ``parameter``, ``value``, ``standard_error`` (NaN for a parameter not fitted or
            on a constraint), ``unit`` (the value's:
            ``"1"``, ``"1/R"``, ``"R"``), ``fitted``, ``on_constraint``
            (:attr:`pinned`); and on every row how the fit ended, so that an unconverged
            fit's table does not pass for a converged one's: ``E_fit`` (R),
            ``converged``, ``stop``, ``walls_cross``, and which standard errors these are,
            ``standard_errors_source`` (:attr:`standard_errors_source`: empty where not known).
        """
        names = [*self.fitted, *(n for n in self.parameters if n not in self.fitted)]
        rows = len(names)
        return {"parameter": names, "value": [float(self.parameters[n]) for n in names],
                "standard_error": [float(self.standard_errors.get(n, math.nan))
                                   for n in names],
                "unit": [self._unit(n) for n in names],
                "fitted": [n in self.fitted for n in names],
                "on_constraint": [n in self.pinned for n in names],
                "E_fit": [self.E_fit] * rows, "converged": [self.converged] * rows,
                "stop": [self.stop] * rows, "walls_cross": [self.walls_cross] * rows,
                "standard_errors_source": [self.standard_errors_source] * rows}

    def to_dataframe(self):
        """The fit as a table, one row per parameter (:meth:`table`).

        Returns
        -------
        pandas.DataFrame
            The columns of :meth:`table`.  ``df.attrs`` holds ``units`` (column → unit:
            ``value`` and ``standard_error`` in each row's ``unit``, ``E_fit`` in R),
            ``problem`` (:meth:`Problem.describe`), ``method``, ``variant``, ``message``,
            ``constrained`` and ``note`` (:attr:`note`: which standard errors these are).
            The midlines: :meth:`to_xarray`, or :attr:`data` and :attr:`model`.
        """
        import pandas as pd

        df = pd.DataFrame(self.table())
        df.attrs.update(units={"value": "the row's unit", "standard_error": "the row's unit",
                               "E_fit": "R"},
                        problem=self.problem.describe(), method=self.method,
                        variant=self.variant, message=self.message,
                        constrained=list(self.constrained), note=self.note)
        return df

    def to_xarray(self):
        """The fit as an xarray Dataset: its parameters, their correlations and the midlines.

        Needs the optional extra ``xarray`` (``pip install 'morphoshell[xarray]'``).

        Returns
        -------
        xarray.Dataset
            Along ``parameter`` (with the coordinate ``unit``, each value's), the
            variables ``value``, ``standard_error``, ``fitted`` and ``on_constraint`` of
            :meth:`table`; ``correlation`` along (``fitted_i``, ``fitted_j``), the fitted
            parameters; ``r_data``, ``z_data``, ``r_fit``, ``z_fit`` along ``point`` (units
            of R).  Attributes: the problem (flat, as :meth:`Equilibrium.to_xarray`),
            ``E_fit`` (R), ``method``, ``variant``, ``converged``, ``stop``,
            ``walls_cross`` (0 or 1; absent where not checked), ``standard_errors_source``
            (absent where not known), ``note``, ``message``, ``constrained``
            (``; ``-separated), ``outer_iterations``, ``inner_solves``, ``seconds``: strings
            and numbers only, so that the Dataset can be written to netCDF.
        """
        xr = xarray_module()
        table = self.table()
        names, fitted = table["parameter"], list(self.fitted)
        data = {k: ("parameter", np.asarray(table[k])) for k in
                ("value", "standard_error", "fitted", "on_constraint")}
        data["correlation"] = (("fitted_i", "fitted_j"), np.asarray(self.correlation, float),
                               {"units": "1"})
        for label, points in (("data", self.data), ("fit", self.model)):
            data.update({f"{c}_{label}": ("point", np.asarray(points[:, j], float),
                                          {"units": "R"}) for j, c in enumerate("rz")})
        coords = {"parameter": names, "unit": ("parameter", table["unit"]),
                  "fitted_i": fitted, "fitted_j": fitted}
        attrs = {**problem_attrs(self.problem), "E_fit": float(self.E_fit), "E_fit_units": "R",
                 "method": self.method, "variant": self.variant,
                 "converged": int(self.converged), "stop": self.stop,
                 **({} if self.walls_cross is None else {"walls_cross": int(self.walls_cross)}),
                 "message": self.message,
                 "constrained": "; ".join(self.constrained),
                 "outer_iterations": int(self.outer_iterations),
                 "inner_solves": int(self.inner_solves), "seconds": float(self.seconds),
                 **({} if self.standard_errors_source is None else
                    {"standard_errors_source": self.standard_errors_source}),
                 "note": self.note}
        return xr.Dataset(data, coords=coords, attrs=attrs)

    @property
    def pinned(self) -> tuple[str, ...]:
        """The fitted parameters in the constraints the fit ends on (no standard error)."""
        return tuple(n for n in self.fitted if not np.isfinite(self.standard_errors[n]))

    @property
    def near_fold(self) -> bool:
        """Whether the fitted state is near a fold of the inner branch (:data:`FOLD_RATIO`).

        All singular values of the scaled Jacobian but the largest are below
        FOLD_RATIO of it; such a fit is reported as not converged.
        """
        # poorly_identified keeps every singular value below 1e-3 of the largest, so with
        # FOLD_RATIO < 1e-3 it holds all k - 1 of them exactly when the fit is near a fold
        k = len(self.fitted)
        return k > 1 and len(self.poorly_identified) == k - 1 and all(
            d["singular_value"] < FOLD_RATIO for d in self.poorly_identified)

    def to_dict(self) -> dict:
        """JSON-ready: the problem, the fitted parameters with their ``units`` (each
        parameter's, as :meth:`table`'s ``unit``; its standard error's too), standard errors
        (``standard_errors_source`` says which, ``re_tracings`` how they were made, ``note``
        in words) and correlations, the fit energy E_fit (units of R) and the solver's
        report.  Numbers JSON has not (NaN) are written null."""
        return {"problem": self.problem.describe(), "parameters": dict(self.parameters),
                "units": {n: self._unit(n) for n in self.parameters},
                "fitted": list(self.fitted),
                # (none on a constraint: JSON has no NaN)
                "standard_errors": {n: (float(e) if np.isfinite(e) else None)
                                    for n, e in self.standard_errors.items()},
                **({} if self.standard_errors_source is None else
                   {"standard_errors_source": self.standard_errors_source}),
                **({} if self.re_tracings is None else
                   {"re_tracings": self.re_tracings.to_dict()}),
                "correlation": self.correlation.tolist(),
                "poorly_identified": self.poorly_identified, "E_fit": self.E_fit,
                "E_fit_units": "R", "method": self.method, "variant": self.variant,
                "converged": self.converged, "stop": self.stop, "message": self.message,
                # (a campaign's record has no time: null, not NaN, which JSON has not)
                "seconds": self.seconds if math.isfinite(self.seconds) else None,
                "constrained": list(self.constrained),
                "outer_iterations": self.outer_iterations, "inner_solves": self.inner_solves,
                "data_midline": {"r": self.data[:, 0].tolist(), "z": self.data[:, 1].tolist()},
                "fitted_midline": {"r": self.model[:, 0].tolist(), "z": self.model[:, 1].tolist()},
                **({"walls_cross": None if self.contact is None else self.contact.to_dict()}
                   if self.contact_checked else {}),
                "note": self.note}


def load_fit(path: str | Path) -> FitResult:
    """The fit saved by ``morphoshell fit --json`` (or :meth:`FitResult.to_dict`) at ``path``.

    Returns
    -------
    FitResult
        Without its equilibrium (:meth:`FitResult.from_dict`).  Entries not in
        :data:`KNOWN` are not read: a warning names them, once per entry and process.

    Raises
    ------
    ValueError
        An unreadable file, not JSON, or a record :meth:`FitResult.from_dict` refuses
        (the file named).
    """
    record = read_json(path)
    if not isinstance(record, dict):
        raise ValueError(f"{path}: expected the JSON object written by morphoshell fit --json")
    result = FitResult.from_dict(record, str(path))
    note_unknown(record, KNOWN, str(path), "load_fit")     # (after the refusals: a fit)
    return result


def _record_fields(record: Mapping[str, Any], where: str) -> dict[str, Any]:
    """The :class:`FitResult` fields a fit's record holds (but its problem and midlines),
    each checked (:func:`_entry`): optional ones at their defaults when absent."""
    from .bilevel import METHODS      # (bilevel imports this module)

    def get(key, check, *args, default=None):
        return _entry(record, key, where, check, *args) if key in record else default

    parameters = get("parameters", _numbers)
    fitted = get("fitted", _names, parameters)
    converged = get("converged", flag)
    return {"method": get("fitted_by" if "fitted_by" in record else "method", choice, METHODS),
            "variant": get("variant", choice, LABELS), "fitted": fitted,
            "parameters": parameters, "standard_errors": get("standard_errors", _errors, fitted),
            "correlation": get("correlation", _matrix, len(fitted)),
            "poorly_identified": get("poorly_identified", _directions, fitted),
            "E_fit": get("E_fit", within, 0.0, math.inf), "converged": converged,
            "outer_iterations": get("outer_iterations", integer, 0, default=0),
            "inner_solves": get("inner_solves", integer, 0, default=0),
            "seconds": get("seconds", _optional, default=math.nan),
            "message": get("message", text, default=""),
            "constrained": get("constrained", _names, None, default=()),
            "stop": get("stop", _status, converged,
                        default=FIT_CONVERGED if converged else IPOPT_UNKNOWN),
            "contact": None,    # (FitResult.from_dict: its check needs the problem)
            "re_tracings": get("re_tracings", Retracings.from_dict, fitted),
            "source_recorded": "standard_errors_source" in record}


def _check_source(record: Mapping[str, Any], result: FitResult, where: str) -> None:
    """ValueError naming ``where`` unless the record's ``standard_errors_source`` (if it has
    one) is the one its ``re_tracings`` give ("re-tracings" exactly where they were used)."""
    if "standard_errors_source" not in record:
        return
    source = _entry(record, "standard_errors_source", where, choice,
                    (GAUSS_NEWTON, RE_TRACINGS))
    if source != result.standard_errors_source:
        why = ("no re_tracings entry" if result.re_tracings is None else
               f"re_tracings has {result.re_tracings.refused} of "
               f"{result.re_tracings.replicates} refused")
        raise ValueError(f"{where}: standard_errors_source = {source!r} disagrees with "
                         f"{why}: {RE_TRACINGS!r} is written exactly where at most "
                         f"{MAX_REFUSED:.0%} of the re-tracings were refused")


def _entry(record: Mapping[str, Any], key: str, where: str, check, *args) -> Any:
    """``check(key, record[key], *args)``, its ValueError or TypeError (the checks of
    :mod:`morphoshell._runtime.validate` and those below: one line naming the entry and
    what it must be) as a ValueError naming ``where`` too."""
    try:
        return check(key, record[key], *args)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{where}: {exc}") from None


def _numbers(key: str, value: Any, names: Sequence[str] | None = None) -> dict[str, float]:
    """``value`` as {name: finite number}, its names among ``names`` if given."""
    if not isinstance(value, Mapping) or names is not None and not set(value) <= set(names):
        raise ValueError(f"{key} = {short(value)} must map "
                         f"{'names' if names is None else f'some of {list(names)}'} to numbers")
    return {n: real(f"{key}.{n}", v) for n, v in value.items()}


def _names(key: str, value: Any, known: Mapping | None) -> tuple[str, ...]:
    """``value`` as a tuple of distinct strings, each a key of ``known`` (if given) and at
    least one of them."""
    if not (isinstance(value, (list, tuple)) and all(isinstance(n, str) for n in value)
            and len(set(value)) == len(value)
            and (known is None or value and set(value) <= set(known))):
        of = "strings" if known is None else "names of 'parameters', at least one"
        raise ValueError(f"{key} = {short(value)} must be a list of distinct {of}")
    return tuple(value)


def _status(key: str, value: Any, converged: bool | None = None) -> str:
    """``value``, a status of :data:`~morphoshell.numerics.status.STATUSES` (too many to
    list in a message), one of :data:`~morphoshell.numerics.status.FIT_CONVERGED_STOPS`
    exactly where ``converged`` (if known): a fit never ends with a pair that disagrees, and
    its tables would print both (an audit: converged true beside
    Maximum_Evaluations_Exceeded)."""
    if not (isinstance(value, str) and value in STATUSES):
        raise ValueError(f"{key} = {short(value)} is not a status of morphoshell.numerics."
                         f"status.STATUSES (e.g. {FIT_CONVERGED!r})")
    if converged is not None and (value in FIT_CONVERGED_STOPS) != converged:
        stops = ", ".join(FIT_CONVERGED_STOPS)
        raise ValueError(f"{key} = {value!r} disagrees with converged = "
                         f"{str(converged).lower()}: a converged fit's stop is one of {stops}, "
                         f"an unconverged fit's another")
    return value



def _null(value: Any) -> bool:
    """Whether ``value`` is null or NaN: a number the fit has not (JSON writes NaN as null:
    a constraint's standard errors and correlations, a campaign's time)."""
    return value is None or isinstance(value, float) and math.isnan(value)


def _optional(key: str, value: Any) -> float:
    """``value``, a number >= 0, or NaN for null or NaN (:func:`_null`)."""
    return math.nan if _null(value) else within(key, value, 0.0, math.inf)


def _errors(key: str, value: Any, fitted: tuple[str, ...]) -> dict[str, float]:
    """``value`` as {fitted parameter: standard error}: a number >= 0, NaN for null."""
    if not isinstance(value, Mapping) or set(value) != set(fitted):
        raise ValueError(f"{key} must map each fitted parameter ({', '.join(fitted)}) to a "
                         f"number, or null on a constraint")
    return {n: _optional(f"{key}.{n}", e) for n, e in value.items()}


def _matrix(key: str, value: Any, k: int) -> np.ndarray:
    """``value`` as a k x k array of correlations in [-1, 1] (NaN for null or NaN: on a
    constraint)."""
    if not (isinstance(value, list) and len(value) == k
            and all(isinstance(row, list) and len(row) == k for row in value)):
        raise ValueError(f"{key} must be a {k} x {k} matrix (a list of {k} rows of {k} "
                         f"correlations or null, one per fitted parameter)")
    # (|correlation| <= 1 up to the round-off of cov / outer(se, se): 1e-6 leaves room for an
    # ill-conditioned covariance and still refuses an edit)
    slack = 1 + 1e-6
    return np.array([[math.nan if _null(c) else within(f"{key}[{i}][{j}]", c, -slack, slack)
                      for j, c in enumerate(row)] for i, row in enumerate(value)],
                     dtype=float).reshape(k, k)


def _directions(key: str, value: Any, fitted: tuple[str, ...]) -> list[dict]:
    """``value`` as a list of {"singular_value": number in [0, 1], "direction": {fitted
    parameter: number}} (:attr:`FitResult.poorly_identified`)."""
    if not (isinstance(value, list) and all(isinstance(d, Mapping) and {
            "singular_value", "direction"} <= set(d) for d in value)):
        raise ValueError(f"{key} must be a list of {{'singular_value': number, 'direction': "
                         f"{{fitted parameter: number}}}}")
    return [{"singular_value": within(f"{key}[{i}].singular_value", d["singular_value"], 0, 1),
             "direction": _numbers(f"{key}[{i}].direction", d["direction"], fitted)}
            for i, d in enumerate(value)]


def _midline(key: str, value: Any) -> np.ndarray:
    """The midline ``value`` ({"r": [...], "z": [...]}) as an array of shape (N, 2)."""
    if not (isinstance(value, Mapping) and all(isinstance(value.get(c), list) for c in "rz")
            and 0 < len(value["r"]) == len(value["z"])):
        raise ValueError(f"{key} must hold lists of numbers r and z of one length")
    return np.column_stack([[real(f"{key}.{c}[{i}]", v) for i, v in enumerate(value[c])]
                            for c in "rz"])


def _contact(key: str, value: Any, shell: tuple[float, float]) -> WallContact | None:
    """``value`` as the :class:`~morphoshell.solvers.contact.WallContact` it was written
    from (its s within ``shell``, the problem's [cut, L - opening]), or None for null."""
    return None if value is None else WallContact.from_dict(value, key, shell)


def _combination(direction: dict, k: int) -> str:
    """A direction {name: component} written as a sum, ``0.864 kappa3 - 0.471 kappa4 ...``
    (``+ ...`` where it lists fewer than all ``k`` fitted parameters)."""
    written = " ".join(f"{'-' if v < 0 else '+'} {abs(v):g} {n}" for n, v in direction.items())
    # (no sign before the first)
    written = written[2:] if written.startswith("+ ") else "-" + written[2:]
    return written + (" + ..." if len(direction) < k else "")


def fit_result(method: str, spec: FitSpec, inner: InnerProblem, theta: np.ndarray,
               iterations: int, seconds: float, converged: bool, message: str,
               stop: str = FIT_CONVERGED) -> FitResult:
    """The :class:`FitResult` of a fit that ended at θ, with its Gauss–Newton statistics.

    The inner state at θ, its residuals r and exact Jacobian J give the
    covariance σ² (JᵀJ)⁺ with σ² = |r|²/(2N − k), the standard errors and
    correlations, and the singular values of J scaled by |θ| (at least
    10⁻²): directions below 10⁻³ of the largest are poorly identified.  A
    fit ending on a hard constraint (:meth:`FitSpec.on_constraints`) gets
    NaN errors for the parameters in it, and one near a fold of the inner
    branch (:attr:`FitResult.near_fold`) is reported as not converged; the
    message says so.

    Parameters
    ----------
    method : str
        The fit method.
    spec : FitSpec
        What was fitted.
    inner : InnerProblem
        The fit's inner problem.
    theta : ndarray, shape (k,)
        The fitted parameters, in ``spec.fitted`` order.
    iterations : int
        Outer iterations.
    seconds : float
        Wall time of the fit (NaN for a record read back without it: a campaign's).
    converged : bool
        Whether the method converged.
    message : str
        The method's message.
    stop : str
        How the method ended (:attr:`FitResult.stop`).

    Returns
    -------
    FitResult
    """
    eq = inner.solve(theta)
    res = inner.residuals(eq)
    J = inner.jacobian(eq, theta)
    n, k = len(res), len(theta)
    sigma2 = float(res @ res) / max(n - k, 1)
    JTJ = J.T @ J
    cov = sigma2 * np.linalg.pinv(JTJ)
    se = np.sqrt(np.maximum(np.diag(cov), 0))
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = cov / np.outer(se, se)
    scale = np.maximum(np.abs(theta), 1e-2)
    _, sv, vt = np.linalg.svd(J * scale, full_matrices=False)
    poor = [{"singular_value": float(s / sv[0]),
             "direction": {spec.fitted[j]: round(float(v[j]), 3)
                           for j in np.argsort(-np.abs(v))[:3]}}
            for s, v in zip(sv, vt) if s < 1e-3 * sv[0]]
    params = {**eq.problem.params, "h": eq.problem.h, "cut": eq.problem.cut,
              "opening": eq.problem.opening}
    errors = dict(zip(spec.fitted, se.tolist()))
    active = spec.on_constraints(theta)
    if active:
        pinned = sorted({n for _, names in active for n in names}, key=spec.fitted.index)
        errors.update({n: float("nan") for n in pinned})
        message = (f"{message}; it ends on the constraint {', '.join(d for d, _ in active)}: a "
                   f"constrained optimum, so {', '.join(pinned)} have no standard errors (NaN)"
                   ).lstrip("; ")
    result = FitResult(method, spec.variant, spec.fitted, params, errors, corr, poor,
                       float(np.sqrt(res @ res)), res, eq, inner.data,
                       inner.data + np.column_stack([res[:inner.n], res[inner.n:]]),
                       iterations, inner.solves, seconds, converged, message,
                       tuple(d for d, _ in active), stop, jacobian=J,
                       contact=wall_contact(eq))   # (the CLI and campaigns warn of it)
    if not result.near_fold:
        return result
    return replace(result, converged=False, stop=FIT_NEAR_FOLD, message=(
        f"{message}; but the fitted state is near a fold of the equilibrium branch: the "
        f"midline's sensitivity to the parameters is {sv[0] / sv[1]:.2g}x larger along one "
        f"direction than along any other (FOLD_RATIO), so the shape is nearly unstable and the "
        f"standard errors are meaningless").lstrip("; "))
