"""The results of a fit campaign: one JSON file per fit, and the summary table.

A campaign (:func:`morphoshell.workflows.campaigns.campaign`) writes, in its
output folder, ``<timepoint>_<variant>.json`` per fit (the record of
:func:`morphoshell.workflows.timepoint_fits.fit_variant`) and :data:`SUMMARY`,
E_fit and the parameters against pseudotime (paper Fig. 3 N, O).
:class:`CampaignResult` holds the records; :func:`load_campaign` reads them
back without fitting, for figures and reports.
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterable

import numpy as np

from .._runtime.tables import xarray_module
from ..fitting import VARIANTS
from ..fitting.midline_checks import input_check
from ..io.problem_files import problem_of_record
from ..io.provenance import check_format
from ..io.timepoints import Timepoint, read_timepoints
from ..model.profiles import get_family
from ..solvers.contact import WallContact

__all__ = ["CampaignResult", "load_campaign", "RESULT_SUFFIX", "SUMMARY", "SETTINGS",
           "result_path", "read_record", "read_records", "column_unit", "record_input_check",
           "record_contact"]

#: Result files are ``<timepoint>_<variant>.json``.
RESULT_SUFFIX = ".json"
#: The summary table in the output folder.
SUMMARY = "campaign_summary.csv"
#: The file in the output folder that records the campaign's settings
#: (:func:`morphoshell.workflows.campaigns.campaign`'s ``force``).
SETTINGS = "campaign_settings.json"
#: Parameters of a record that are the problem's geometry, not the Volvox family's.
_GEOMETRY = ("h", "cut", "opening")


@dataclass(frozen=True)
class CampaignResult:
    """The results of a campaign, one record per (timepoint, variant).

    Attributes
    ----------
    out : Path
        The folder of the result files and of the summary (:data:`SUMMARY`).
    timepoints : tuple of Timepoint
    variants : tuple of str
    records : dict
        ``{(timepoint, variant): record}``, each record the content of its JSON
        file (see :func:`morphoshell.workflows.campaigns.campaign`), as
        :func:`read_records` read and checked it.
    timing : dict
        ``seconds`` (wall clock), ``workers``, ``backend``, ``computed`` (fits
        done in this run), ``fit_seconds`` (their summed time).
    data_dir : Path or None
        The data set, whose averaged midlines give the noise of :meth:`hypothesis_tests`
        (None: the fits' residuals).
    """

    out: Path
    timepoints: tuple[Timepoint, ...]
    variants: tuple[str, ...]
    records: dict
    timing: dict = field(default_factory=dict)
    data_dir: Path | None = None

    def __repr__(self) -> str:
        """One line: the folder, the grid, how many fits, failed and not converged (the
        default repr held every record: 135 000 characters for 3 fits)."""
        ends = [why for *_, why in self.unfinished()]

        def count(n: int, what: str) -> str:
            return f"{n} {what}{'' if n == 1 else 's'}"
        return (f"CampaignResult({self.out}, {count(len(self.timepoints), 'timepoint')} x "
                f"{count(len(self.variants), 'variant')}, {count(len(self.records), 'fit')}, "
                f"{ends.count('failed')} failed, {ends.count('not converged')} not converged)")

    def record(self, timepoint: str, variant: str) -> dict:
        """The record of one fit (KeyError if it is missing)."""
        return self.records[(timepoint, variant)]

    def to_dataframe(self):
        """E_fit (units of R) and the parameters against pseudotime, one row per fit.

        Returns
        -------
        pandas.DataFrame
            Columns ``timepoint``, ``pseudotime``, ``variant``, ``status``,
            ``E_fit``, ``converged``, ``input_check`` (:func:`record_input_check`;
            empty below it), ``walls_cross`` (True where the fitted shape's walls pass
            through each other, :func:`record_contact`; empty where no shape was checked:
            a failed fit, or a record written before the check), ``nodes`` and ``method`` (the fit's
            settings: a folder that mixes them shows it), ``held_from`` (the
            variant whose first fit gave the held values; empty where a
            variant fitted its own), ``active_constraints`` (the constraints
            and bounds the fit ends on, ``; ``-separated), the 14 Volvox parameters (lengths in R,
            curvatures in 1/R), then ``se_<name>`` (Gauss–Newton standard
            errors; NaN for parameters not fitted at that timepoint), and
            with ``embryo_errors`` ``se_embryo_<name>`` (the jackknife over
            the traces) and ``embryo_t95`` (their 95 % interval is ± this many); last,
            the test of the fit's hypothesis against the timepoint's free fit
            (:meth:`hypothesis_tests`): ``delta_S_over_sigma2``, ``hypothesis_threshold``,
            ``hypothesis_test`` (``consistent``, ``rejected``, ``reference`` for free;
            ``not established`` where a fit that did not converge leaves it open; empty
            without a test) and ``hypothesis_noise`` (where σ² came from: ``traces`` or
            ``residual``; a campaign's fits carry no re-tracings, so never ``morphoshell
            compare``'s scaled residual of one image trace).
            ``df.attrs`` holds ``units`` (column → unit, :func:`column_unit`;
            the summary CSV has none, so that ``pandas.read_csv`` reads it as
            it is) and ``settings`` (the folder's :data:`SETTINGS`; empty
            without one).
        """
        import pandas as pd

        tests = self.hypothesis_tests()
        rows = [{**_summary_row(tp, v, self.records[(tp.name, v)]),
                 **_test_cells(tests[tp.name][0], v)}
                for tp in self.timepoints for v in self.variants
                if (tp.name, v) in self.records]
        df = pd.DataFrame(rows)
        df.attrs.update(units={str(c): column_unit(str(c)) for c in df.columns},
                        settings=read_record(self.out / SETTINGS) or {})
        return df

    def to_xarray(self):
        """E_fit and the parameters as an xarray Dataset along (``timepoint``, ``variant``).

        Needs the optional extra ``xarray`` (``pip install 'morphoshell[xarray]'``).

        Returns
        -------
        xarray.Dataset
            Coordinates ``timepoint`` (the campaign's, in order, with ``pseudotime``
            along it) and ``variant``; a variable for every other column of
            :meth:`to_dataframe`, with its ``units`` (:func:`column_unit`) where it has
            one: numbers as floats, flags (``converged``, ``walls_cross``) as bools, or as
            1.0/0.0 where some fit has none, the rest as strings; NaN, or ``""``, where a
            fit has no value (no record, a failed fit, a record written before the entry).
            Attributes: ``out`` and ``settings`` (JSON), so that the Dataset can be
            written to netCDF.  E.g. ``ds.E_fit.sel(variant="free")`` against
            ``ds.pseudotime``.
        """
        import pandas as pd

        xr = xarray_module()
        names, variants = [tp.name for tp in self.timepoints], list(self.variants)
        grid = pd.MultiIndex.from_product([names, variants], names=["timepoint", "variant"])
        table = self.to_dataframe()
        wide = table.set_index(["timepoint", "variant"]).drop(columns="pseudotime")
        wide = wide.reindex(grid)
        shape = (len(names), len(variants))
        data = {str(c): (("timepoint", "variant"), _grid(wide[c].tolist()).reshape(shape),
                         {"units": column_unit(str(c))} if column_unit(str(c)) else {})
                for c in wide.columns}
        coords = {"timepoint": names, "variant": variants,
                  "pseudotime": ("timepoint", [float(tp.pseudotime) for tp in self.timepoints],
                                 {"units": column_unit("pseudotime")})}
        return xr.Dataset(data, coords=coords, attrs={
            "out": str(self.out), "settings": json.dumps(table.attrs["settings"])})

    def hypothesis_tests(self) -> dict[str, tuple]:
        """Each timepoint's hypotheses tested against its free fit
        (:func:`morphoshell.fitting.hypotheses.compare_hypotheses` of its finished fits; σ²
        from the spread of the traces of its averaged midline when :attr:`data_dir` has
        them, else from the free fit's residual).

        Returns
        -------
        dict
            ``{timepoint: (HypothesisTest or None, why none)}``: None with fewer than two
            finished fits, or fits the test refuses (of other meshes: its one line).
        """
        from ..fitting.hypotheses import compare_hypotheses

        out = {}
        for tp in self.timepoints:
            fits = {f"{tp.name}_{v}": rec for v in self.variants
                    if (rec := self.records.get((tp.name, v), {})).get("status") == "ok"}
            if len(fits) < 2:
                out[tp.name] = (None, f"{len(fits)} finished fit(s)")
                continue
            try:
                out[tp.name] = (compare_hypotheses(fits, self.midline(tp)), "")
            except ValueError as exc:
                out[tp.name] = (None, str(exc))
        return out

    def midline(self, tp: Timepoint | str):
        """The averaged midline of a timepoint as its fits read it: the ``data`` of
        :func:`~morphoshell.fitting.hypotheses.compare_hypotheses` (:meth:`hypothesis_tests`)
        and of :func:`~morphoshell.workflows.fitted_shapes.fit_uncertainty` (its fits' errors
        carried into an ablation also at the traces' σ²).

        Parameters
        ----------
        tp : Timepoint or str
            The timepoint or its name.

        Returns
        -------
        Midline or None
            None: no data folder, or the file is gone or unreadable (then σ² comes from
            the residual).

        Raises
        ------
        ValueError
            A name none of the campaign's timepoints has.
        """
        from ..io import Midline

        if isinstance(tp, str):
            names = {t.name: t for t in self.timepoints}
            if tp not in names:
                raise ValueError(f"timepoint {tp}: not one of the campaign's "
                                 f"({', '.join(names)})")
            tp = names[tp]
        if self.data_dir is None:
            return None
        try:
            return Midline.from_csv(Path(self.data_dir) / tp.midline)
        except (OSError, ValueError):
            return None

    def unfinished(self) -> list[tuple[str, str, str]]:
        """The fits that failed or did not converge: (timepoint, variant, "failed" or
        "not converged"), in the campaign's order."""
        out = []
        for tp in self.timepoints:
            for v in self.variants:
                rec = self.records.get((tp.name, v))
                if rec is None:
                    continue
                if rec["status"] != "ok":
                    out.append((tp.name, v, "failed"))
                elif not rec.get("converged", False):
                    out.append((tp.name, v, "not converged"))
        return out

    def far_above(self) -> list[tuple[str, str]]:
        """The fits with an ``input_check`` verdict (:func:`record_input_check`): (timepoint,
        variant), in the campaign's order.  A wrong hypothesis may legitimately end there."""
        return [(tp.name, v) for tp in self.timepoints for v in self.variants
                if record_input_check(self.records.get((tp.name, v), {}))]

    def walls_cross(self) -> list[tuple[str, str]]:
        """The fits whose fitted shape's walls pass through each other (:func:`record_contact`):
        (timepoint, variant), in the campaign's order.  Minima of the model, not physical
        shapes (it has no self-contact)."""
        return [(tp.name, v) for tp in self.timepoints for v in self.variants
                if self.records.get((tp.name, v), {}).get("walls_cross") is not None]

    def walls_unchecked(self) -> list[tuple[str, str]]:
        """The finished fits whose records were written before the walls check (no
        ``walls_cross`` entry): (timepoint, variant), in the campaign's order.  Whether their
        walls cross is not known; ``resume=False`` refits and checks them."""
        return [(tp.name, v) for tp in self.timepoints for v in self.variants
                if (rec := self.records.get((tp.name, v), {})).get("status") == "ok"
                and "walls_cross" not in rec]

    def best_far_above(self) -> list[tuple[str, str]]:
        """The timepoints whose best fit (lowest E_fit of the variants' fits that finished)
        has an ``input_check`` verdict, with that fit's variant: no variant run describes
        their data, so the input (or every hypothesis) is wrong."""
        out = []
        for tp in self.timepoints:
            done = [(rec["E_fit"], v) for v in self.variants
                    if (rec := self.records.get((tp.name, v), {})).get("status") == "ok"]
            best = min(done, default=None)
            if best is not None and record_input_check(self.records[(tp.name, best[1])]):
                out.append((tp.name, best[1]))
        return out


def _summary_row(tp: Timepoint, variant: str, rec: dict) -> dict:
    """One row of :meth:`CampaignResult.to_dataframe`: a fit's status, settings, E_fit and
    parameters."""
    row = {"timepoint": tp.name, "pseudotime": tp.pseudotime, "variant": variant,
           "status": rec["status"], "E_fit": rec.get("E_fit", float("nan")),
           "converged": rec.get("converged", False),
           "input_check": record_input_check(rec) or "",
           # (None, an empty cell, where no fitted shape was checked; a crossing that is
           # there is one: read_records checked it)
           "walls_cross": rec["walls_cross"] is not None if "walls_cross" in rec else None,
           "nodes": rec.get("nodes"),
           "method": rec.get("method", ""),
           "held_from": (rec.get("held_from") or {}).get("variant", ""),
           "active_constraints": "; ".join(rec.get("constrained", []))}
    params = rec.get("parameters", {})
    names = [n for n in params if n not in _GEOMETRY]
    row.update({n: params[n] for n in names})
    se = rec.get("standard_errors", {})
    # (None: on a constraint, FitResult.constrained)
    row.update({f"se_{n}": _number(se.get(n)) for n in names})
    embryo = rec.get("embryo_standard_errors")
    if embryo is not None:
        row.update({f"se_embryo_{n}": _number(embryo.get(n)) for n in names})
        row["embryo_t95"] = rec.get("embryo_t95", float("nan"))   # (none: no errors)
    return row


def _test_cells(test, variant: str) -> dict:
    """The summary's cells of the test of ``variant``'s hypothesis in ``test`` (None: no
    test at its timepoint: empty cells)."""
    row = next((h for h in test.hypotheses if h.variant == variant), None) if test else None
    if row is None or not row.verdict:
        return {"delta_S_over_sigma2": float("nan"), "hypothesis_threshold": float("nan"),
                "hypothesis_test": "", "hypothesis_noise": ""}
    return {"delta_S_over_sigma2": row.ratio, "hypothesis_threshold": row.threshold,
            "hypothesis_test": row.verdict, "hypothesis_noise": test.sigma2_source}


def _grid(values: list) -> np.ndarray:
    """A column of the summary on the (timepoint, variant) grid as one array: numbers as
    floats, flags as bools (1.0/0.0 where some have none), the rest as strings; NaN, or
    ``""``, where a fit has no value (None or NaN: :meth:`CampaignResult.to_xarray`)."""
    none = [v is None or isinstance(v, float) and math.isnan(v) for v in values]
    given = [v for v, n in zip(values, none) if not n]
    if given and all(isinstance(v, (bool, np.bool_)) for v in given):
        if not any(none):
            return np.array(values, dtype=bool)
        return np.array([math.nan if n else float(v) for v, n in zip(values, none)])
    if all(isinstance(v, (int, float, np.number)) for v in given):
        return np.array([math.nan if n else v for v, n in zip(values, none)], dtype=float)
    return np.array(["" if n else str(v) for v, n in zip(values, none)], dtype=str)


def record_input_check(rec: dict) -> str | None:
    """The ``input_check`` of a campaign record: ``morphoshell fit``'s verdict on its E_fit
    (:func:`morphoshell.fitting.midline_checks.input_check`), None for a failed fit (or
    any without an E_fit).  From the E_fit, not the stored entry: a record of a version before it
    has none."""
    E_fit = rec.get("E_fit")
    return input_check(E_fit) if rec.get("status") == "ok" and E_fit is not None else None


def column_unit(column: str) -> str:
    """The unit of a column of the campaign summary: ``R`` (E_fit, breakpoints s and the
    smoothing width), ``1/R`` (curvatures κ), ``1`` (stretches f, ``embryo_t95``, the
    hypothesis test's ``delta_S_over_sigma2`` and ``hypothesis_threshold``); a
    standard error's is its parameter's; ``""`` for labels, flags and settings.  The
    pseudotime is in the unit of ``timepoints.csv``: ``"as timepoints.csv"``."""
    params = get_family("volvox").units
    for prefix in ("se_embryo_", "se_"):
        if column.startswith(prefix) and column[len(prefix):] in params:
            return params[column[len(prefix):]]
    return {**params, "E_fit": "R", "embryo_t95": "1", "delta_S_over_sigma2": "1",
            "hypothesis_threshold": "1", "pseudotime": "as timepoints.csv"}.get(column, "")


def _number(value) -> float:
    """A record's number, NaN for None (no value: JSON has no NaN)."""
    return float("nan") if value is None else float(value)


def result_path(out: Path, timepoint: str, variant: str) -> Path:
    """The file of one fit's record: ``out/<timepoint>_<variant>.json``."""
    return out / f"{timepoint}_{variant}{RESULT_SUFFIX}"


def read_record(path: Path) -> dict | None:
    """The record stored at ``path``, or None if there is none (missing, or not JSON).
    ValueError naming it for a record of a newer format (:func:`~morphoshell.io.provenance.
    check_format`): refitting it would overwrite what a newer version wrote."""
    try:
        record = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    check_format(record, str(path))
    return record


def read_records(out: Path, keys: Iterable[tuple[str, str]]) -> dict:
    """``{(timepoint, variant): record}`` of the stored ones among ``keys``, in their order.

    Raises
    ------
    ValueError
        A record whose ``walls_cross`` is not a crossing (:func:`record_contact`), the file
        named: the summary, the campaign's last line and its resume read it (an audit: a
        resume stopped on one of 8 files without saying which).
    """
    records = {}
    for name, variant in keys:
        path = result_path(out, name, variant)
        rec = read_record(path)
        if rec is not None:
            record_contact(rec, str(path))
            records[(name, variant)] = rec
    return records


def load_campaign(out: str | Path, data_dir: str | Path | None = None) -> CampaignResult:
    """The stored results of a campaign (no fitting): for figures and reports.

    Parameters
    ----------
    out : str or Path
        The campaign's output folder.
    data_dir : str or Path, optional
        Its data set (:func:`morphoshell.io.timepoints.read_timepoints`); by default the
        one the folder records (``campaign_settings.json``'s ``data``).

    Raises
    ------
    ValueError
        No ``data_dir`` and a folder that records none, or records one that is not there
        (moved: give ``data_dir``).

    Returns
    -------
    CampaignResult
        The records found, the variants that have any (in the order of
        :data:`morphoshell.fitting.spec.VARIANTS`); no timing.
    """
    if data_dir is None:
        data_dir = recorded_data(Path(out))
    timepoints = read_timepoints(data_dir)
    out = Path(out)
    records = read_records(out, [(tp.name, v) for v in VARIANTS for tp in timepoints])
    variants = tuple(dict.fromkeys(v for _, v in records))
    return CampaignResult(out, timepoints, variants, records, data_dir=Path(data_dir))


def recorded_data(out: Path) -> Path:
    """The data folder a campaign's output folder ``out`` records (ValueError naming the
    settings file when it records none or one that is not a folder)."""
    path = out / SETTINGS
    data = (read_record(path) or {}).get("data")
    if not isinstance(data, str):
        raise ValueError(f"{path}: no data folder recorded (not a campaign's output folder?): "
                         f"give the data folder, load_campaign(out, data_dir)")
    if not Path(data).is_dir():
        raise ValueError(f"{path}: the recorded data folder {data} is not there (moved?): give "
                         f"it, load_campaign(out, data_dir)")
    return Path(data)


def record_contact(rec: dict, where: str = "the record") -> WallContact | None:
    """Where the fitted shape of a campaign record passes through itself (its ``walls_cross``,
    :attr:`morphoshell.fitting.results.FitResult.contact`), or None: walls apart, a failed fit,
    or a record written before the check (which has no ``walls_cross``).  ValueError naming
    ``where`` (the file) for one that is not a crossing of the record's shell
    (:meth:`~morphoshell.solvers.contact.WallContact.from_dict`)."""
    stored = rec.get("walls_cross")     # (a failed fit's record has none)
    if stored is None:
        return None
    # (a record a campaign wrote has its problem; one made by hand may not: s >= 0 then)
    problem = problem_of_record(rec, where) if "problem" in rec else None
    try:
        return WallContact.from_dict(stored, shell=problem and (problem.cut, problem.end))
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{where}: {exc}") from None
