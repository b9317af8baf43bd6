"""The estimates of a whole measurement table, as text, JSON and tables.

Paper, main text "Quantitative estimates of the curvature mismatch during
*Volvox* invagination…" and "Recoil velocity measurements yield a bound on the
elastic modulus…", Fig. 2 J–K: :class:`InverseResult` holds every embryo's
estimates, their summaries over embryos and the E/μ fit, and writes them as
the printed summary, the JSON document, per-embryo columns (CSV), a pandas
DataFrame or an xarray Dataset.
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass
from typing import Mapping

from ..io.measurements import MEASURES
from .embryo import EmbryoEstimate, format_k
from .inversion import SYMBOL
from .recoil_velocity import VelocityFit
from .summaries import Spread

__all__ = ["InverseResult", "methods_ran"]


def _weighted(c) -> str:
    """The weighted summary's line: its value, over how many of the embryos, or why none."""
    if c.weighted_mean is None:
        return "none (no embryo's combined k has an error: an error column is empty)"
    over = "" if c.weighted_n == c.n else (f" (over the {c.weighted_n} of {c.n} embryos whose "
                                           f"combined k has an error)")
    return f"{c.weighted_mean:.4f} +- {c.weighted_error:.4f}{over}"


def methods_ran(settings: Mapping, kind: str) -> bool:
    """Whether a run's methods (``settings["methods"]``) include ``kind`` ("numerical",
    "inner" or "asymptotic": any of leading_order and kelvin); settings without them ran
    them all."""
    methods = settings.get("methods")
    if methods is None:
        return True
    return (kind in methods if kind != "asymptotic"
            else bool({"leading_order", "kelvin"} & set(methods)))


def _column_unit(column: str) -> str:
    """Unit of a column of :meth:`InverseResult.table`."""
    if column.startswith("k_"):
        return "1/R"
    return {"h": "H/R", "cut_rad": "rad", "sigma_inner": "1 (Sigma/delta)"}.get(column, "")


@dataclass(frozen=True, eq=False)
class InverseResult:
    """Estimates for a measurement table; ``print`` it for a summary.

    Returned by :func:`morphoshell.inverse.pipeline.estimate`.

    Attributes
    ----------
    embryos : tuple of EmbryoEstimate, length n_embryos
        Every embryo's estimates, in the order of the table.
    summary : mapping
        A :class:`~morphoshell.inverse.summaries.Spread` over embryos per
        estimate ``<measure>_<method>`` (``asymptotic`` included) and for
        ``combined``.
    velocity : VelocityFit or None
        The E/μ fit (None without velocities).
    settings, timing : mapping
        The arguments of the run, and its times (s), solver builds and workers.
    """

    embryos: tuple[EmbryoEstimate, ...]
    summary: Mapping[str, Spread]
    velocity: VelocityFit | None
    settings: Mapping[str, object]
    timing: Mapping[str, float]

    def __repr__(self) -> str:
        c = self.summary["combined"]
        v = "" if self.velocity is None else f", E_over_mu={self.velocity.E_over_mu:.4g}"
        k = (f"<k> = {format_k(c.mean)} (rotation + displacement, numerical)"
             if self._ran("numerical") else
             f"methods {', '.join(self.settings['methods'])}: no combined <k> (it needs "
             f"'numerical')")
        return f"InverseResult({len(self.embryos)} embryos, {k}{v})"

    def _ran(self, kind: str) -> bool:
        return methods_ran(self.settings, kind)

    def _cell(self, e: EmbryoEstimate, m: str) -> str:
        """An embryo's k from measure ``m``: numerical (asymptotic), or the one that ran."""
        num, asym = format_k(e.k(m)), format_k(e.k(m, "asymptotic"))
        if not self._ran("asymptotic"):
            return f"{num:>16s}"
        return f"{num:>6s} ({asym:>6s})" if self._ran("numerical") else f"{asym:>16s}"

    def __str__(self) -> str:
        return "\n".join([*self._embryo_lines(), *self._summary_lines(), *self._note_lines()])

    def _embryo_lines(self) -> list[str]:
        """The settings and a row per embryo: k from each measure, and combined."""
        s = self.settings
        asymptotic = "leading order for o, Kelvin for rho and d"
        shown = (f"numerical; asymptotic in parentheses: {asymptotic}"
                 if self._ran("numerical") and self._ran("asymptotic") else
                 "numerical" if self._ran("numerical") else f"asymptotic: {asymptotic}")
        lines = [f"{len(self.embryos)} embryos; toy problem 2, {s['theory']} theory, "
                 f"k in [{s['k_range'][0]:g}, {s['k_range'][1]:g}]",
                 f"k per embryo, in units of 1/R ({shown}):",
                 f"  {'embryo':10s} {'h':>6s} {'cut':>6s} "
                 + " ".join(f"{'k_' + SYMBOL[m]:>16s}" for m in MEASURES)
                 + (f" {'k_combined':>11s}" if self._ran("numerical") else "")]
        lines.append(f"  {'':10s} {'H/R':>6s} {'rad':>6s}")
        for e in self.embryos:
            cells = [self._cell(e, m) for m in MEASURES]
            lines.append(f"  {e.measurement.embryo:10s} {e.measurement.h:6.3f} "
                         f"{e.measurement.cut:6.3f} " + " ".join(cells)
                         + (f" {format_k(e.combined.k):>11s}" if self._ran("numerical") else ""))
        return lines

    def _summary_lines(self) -> list[str]:
        """The summaries over embryos, and the E/μ fit."""
        lines = ["summary over embryos (k in units of 1/R): mean +- std [Student's t 95% "
                 "interval of the mean]:"]
        for m in MEASURES:
            for meth in filter(self._ran, ("numerical", "asymptotic", "inner")):
                lines.append(f"  k from {m:12s} {meth:10s}  {self.summary[f'{m}_{meth}']}")
        c = self.summary["combined"]
        if self._ran("numerical"):
            lines.append(f"  <k> from rotation + displacement (numerical): {c}")
            lines.append(f"      inverse-variance weighted: {_weighted(c)}")
        else:
            lines.append("  <k> from rotation + displacement: none (it combines the numerical "
                         "estimates; add 'numerical' to methods)")
        if self.velocity is not None:
            lines.append(f"recoil velocities: {self.velocity}")
        return lines

    def _note_lines(self) -> list[str]:
        """Why estimates are missing (the measures no k in the range gives, and failures),
        and combined k's that are plain means (an error missing)."""
        notes = [f"  {e.measurement.embryo}: {m}, {meth}: {est.note}" for e in self.embryos
                 for (m, meth), est in e.estimates.items()
                 if meth != "asymptotic" and est.status in ("outside_range", "not_monotonic",
                                                            "failed")]
        lines = ["no estimate (measures that no k in the range produces, or failures):",
                 *notes] if notes else []
        plain = [f"  {e.measurement.embryo}: {e.combined.note}" for e in self.embryos
                 if e.combined.k is not None and e.combined.note]
        return lines + (["combined k without weights:", *plain] if plain else [])

    def to_dict(self) -> dict:
        """The JSON document (see ``morphoshell estimate --help``)."""
        out = {"description": "Inverse estimates of the intrinsic curvature k from laser-"
                              "ablation recoils (toy problem 2) and of E/mu from recoil "
                              "velocities: paper Fig. 2 J-K",
               "units": {"k": "1/R (each embryo's own R)", "h": "H/R", "cut_rad": "rad",
                         "sigma_inner": "Sigma/delta", "E_over_mu": "1/s",
                         "E_lower_bound_Pa": "Pa", "bending_modulus_lower_bound_J": "J"},
               "settings": dict(self.settings),
               "embryos": [e.to_dict() for e in self.embryos],
               "summary": {k: v.to_dict() for k, v in self.summary.items()}}
        if self.velocity is not None:
            out |= {k: v for k, v in self.velocity.to_dict().items()
                    if k in ("E_over_mu", "E_over_mu_standard_error", "E_over_mu_interval_95",
                             "E_lower_bound_Pa", "bending_modulus_lower_bound_J")}
            out["velocity_fit"] = self.velocity.to_dict()
        out["timing_seconds"] = dict(self.timing)
        return out

    def to_dataframe(self):
        """The per-embryo estimates as a table (the columns of :meth:`table`).

        Returns
        -------
        pandas.DataFrame
            One row per embryo: ``embryo``, ``row``, ``h`` (H/R), ``cut_rad``,
            ``sigma_inner`` (Σ/δ), ``k_<measure>_<method>`` [``_error``]
            (units of the embryo's 1/R; NaN where there is no estimate),
            ``k_combined`` [``_error``], ``notes``.  ``df.attrs`` holds
            ``units`` (column → unit), ``settings``, ``summary`` (per
            estimate: n, mean, std, interval) and, with velocities,
            ``E_over_mu`` (1/s).
        """
        import pandas as pd

        df = pd.DataFrame(self.table())
        doc = self.to_dict()
        df.attrs.update(units={c: _column_unit(c) for c in df.columns},
                        settings=doc["settings"], summary=doc["summary"])
        if self.velocity is not None:
            df.attrs["E_over_mu"] = self.velocity.E_over_mu
        return df

    def to_xarray(self):
        """The per-embryo estimates as an xarray Dataset along the coordinate ``embryo``.

        Needs the optional extra ``xarray`` (``pip install 'morphoshell[xarray]'``).
        Variables as the columns of :meth:`to_dataframe`, each with ``units``;
        attributes: the settings (strings and numbers).
        """
        from .._runtime.tables import xarray_module

        xr = xarray_module()
        df = self.to_dataframe()
        ds = xr.Dataset.from_dataframe(df.set_index("embryo"))
        for c in ds.data_vars:
            ds[c].attrs["units"] = _column_unit(str(c))
        ds.attrs.update({k: (v if isinstance(v, (str, int, float)) else json.dumps(v))
                         for k, v in self.settings.items() if v is not None})
        return ds

    def table(self) -> dict[str, list]:
        """Per-embryo columns for CSV (null → NaN, written as an empty cell).

        Returns
        -------
        dict of str to list, each of length n_embryos
            The keys of
            :meth:`~morphoshell.inverse.embryo.EmbryoEstimate.to_dict` in
            order of appearance (``extra`` left out), and ``notes`` joined by
            ``; ``.
        """
        rows = [e.to_dict() for e in self.embryos]
        keys = [k for k in rows[0] if k not in ("notes", "extra")]
        for r in rows[1:]:
            keys += [k for k in r if k not in keys and k not in ("notes", "extra")]
        cols = {k: [math.nan if r.get(k) is None else r.get(k) for r in rows] for k in keys}
        cols["notes"] = ["; ".join(r["notes"]) for r in rows]
        return cols
