"""The result of a sweep: one row per point, as a table, an xarray Dataset or JSON.

:func:`morphoshell.workflows.sweeps.sweep` returns a :class:`SweepResult`:
columns in the order of the Cartesian product of the axes (last axis
fastest), the axes first, then the values, their error estimates and the
bookkeeping (``status``, ``iterations``, ``path``, ``event``, ``walls_cross``,
``seconds``, ``message``), built from the workers' rows by :func:`result_columns`.
Lengths in units of R, angles in radians, energies in C R².
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from itertools import product
from typing import Any, Mapping

import numpy as np

from .._runtime.tables import problem_attrs, xarray_module
from ..model.problem import Problem
from ..numerics.status import NOT_COMPUTED

__all__ = ["SweepResult", "result_columns", "point_label", "axis_column", "NOT_COMPUTED"]

#: The bookkeeping columns, last and in this order.
_BOOK = ("status", "iterations", "path", "event", "walls_cross", "seconds", "message")
#: A summary names at most this many points (and how many more).
NAMED = 8

@dataclass(frozen=True, eq=False)
class SweepResult:
    """The rows of a sweep, in the order of the Cartesian product (last axis fastest).

    Attributes
    ----------
    problem : Problem
        The base problem; each point is ``problem.with_updates(**point)``.
    axes : mapping
        Axis name → its values, in the order given (the product's order).
    ablate : bool
        Ablation sweep (recoil observables) or equilibria.
    columns : mapping
        Column name → ndarray (one entry per point): the axes (``opening`` is
        ``opening_P`` in ablation sweeps), the values, their ``*_error``
        estimates (NaN where not estimated or failed), then ``status``,
        ``iterations``, ``path``, ``event``, ``walls_cross``, ``seconds`` and
        ``message``.
    units : mapping
        Column → unit (lengths in units of R, angles in rad, energies in C R²).
    timing : mapping
        ``seconds`` (wall time of the whole sweep, worker start-up included),
        ``workers``, ``backend`` ("serial", "processes" or "dask"), ``chunks``,
        ``chunk_axis``, ``nodes``, ``errors``.
    """

    problem: Problem
    axes: Mapping[str, tuple]
    ablate: bool
    columns: Mapping[str, np.ndarray]
    units: Mapping[str, str]
    timing: Mapping[str, Any] = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.columns["status"])

    def __repr__(self) -> str:
        shape = " x ".join(f"{len(v)} {k}" for k, v in self.axes.items())
        what = "ablations" if self.ablate else "equilibria"
        return (f"SweepResult({len(self)} {what}: {shape}; {self.failed} failed; "
                f"{self.timing.get('seconds', math.nan):.3g} s on "
                f"{self.timing.get('workers', '?')} worker(s))")

    @property
    def failed(self) -> int:
        """Number of points without a solution (their ``status`` says why)."""
        return int(np.sum(self.columns["message"] != ""))

    @property
    def shape(self) -> tuple[int, ...]:
        """Number of values of each axis."""
        return tuple(len(v) for v in self.axes.values())

    def dims(self) -> tuple[str, ...]:
        """The axes' names as columns and dimensions (``opening_P`` for ``opening`` in
        ablations)."""
        return tuple(axis_column(k, self.ablate) for k in self.axes)

    def points(self, rows) -> str:
        """The points of ``rows`` (indices or a boolean mask) in a line, e.g.
        ``"kappa2 = -8, -7.5, -7"`` or ``"(F0, h) = (9, 0.001), (3, 0.001)"``; the first
        :data:`NAMED` and how many more."""
        index = np.flatnonzero(rows) if np.asarray(rows).dtype == bool else np.asarray(rows)
        dims = self.dims()
        values = [", ".join(_short(self.columns[d][i]) for d in dims) for i in index[:NAMED]]
        if len(dims) > 1:
            values = [f"({v})" for v in values]
        more = f" and {len(index) - NAMED} more" if len(index) > NAMED else ""
        names = dims[0] if len(dims) == 1 else f"({', '.join(dims)})"
        return f"{names} = {', '.join(values)}{more}"

    def to_dataframe(self):
        """The sweep as a table: one row per point.

        Returns
        -------
        pandas.DataFrame
            The columns of :attr:`columns`.  ``df.attrs`` holds ``units``
            (column → unit), ``problem`` (the base problem,
            :meth:`Problem.describe`), ``axes``, ``ablate``, ``timing`` and,
            for ablations, ``gauge``.
        """
        import pandas as pd

        df = pd.DataFrame({k: v for k, v in self.columns.items()})
        df.attrs.update(units=dict(self.units), problem=self.problem.describe(),
                        axes=dict(zip(self.dims(), map(list, self.axes.values()))),
                        ablate=self.ablate,
                        timing=dict(self.timing))
        if self.ablate:
            df.attrs["gauge"] = _GAUGE
        return df

    def to_xarray(self):
        """The sweep as an xarray Dataset with the axes as dimensions.

        Needs the optional extra ``xarray`` (``pip install 'morphoshell[xarray]'``).

        Returns
        -------
        xarray.Dataset
            Coordinates: the axes (their values; ``units`` where known).
            Variables: every other column of :attr:`columns`, reshaped to
            :attr:`shape` (``units`` attached), e.g. ``ds["rotation"].sel(k=0.5)``.
            Attributes: the base problem (flat, as
            :meth:`Equilibrium.to_xarray`), ``ablate`` and the timing.
        """
        xr = xarray_module()
        dims = self.dims()
        coords = {d: (d, np.asarray(v), {"units": self.units[d]} if d in self.units else {})
                  for d, v in zip(dims, self.axes.values())}
        data = {k: (dims, np.asarray(v).reshape(self.shape),
                    {"units": self.units[k]} if k in self.units else {})
                for k, v in self.columns.items() if k not in dims}
        attrs = {**problem_attrs(self.problem), "ablate": int(self.ablate),
                 **{f"timing_{k}": v for k, v in self.timing.items()
                    if isinstance(v, (int, float, str))}}
        if self.ablate:
            attrs["gauge"] = _GAUGE
        return xr.Dataset(data, coords=coords, attrs=attrs)

    def to_dict(self) -> dict:
        """JSON-ready: the base problem, the axes (named as their columns: ``opening_P`` in
        ablations), the units, the timing and one dict per row."""
        names = list(self.columns)
        rows = [{k: _scalar(self.columns[k][i]) for k in names} for i in range(len(self))]
        return {"problem": self.problem.describe(), "ablate": self.ablate,
                "axes": {d: [_scalar(v) for v in vals]
                         for d, vals in zip(self.dims(), self.axes.values())},
                "units": dict(self.units), "timing": dict(self.timing), "rows": rows}


_GAUGE = ("post- minus pre-ablation state at the material point s = cut; z in the far-end "
          "gauge (the far end keeps its undeformed height)")


def _scalar(v):
    return v.item() if isinstance(v, np.generic) else v


def axis_column(axis: str, ablate: bool) -> str:
    """The table's column of a sweep's axis: in an ablation sweep the far-end opening P is
    ``opening_P`` (``opening`` is the observable o there), the others their names."""
    return "opening_P" if ablate and axis == "opening" else axis


def _short(value) -> str:
    """An axis value as a summary writes it (6 significant digits; a theory by name)."""
    return f"{value:.6g}" if isinstance(value, (float, int, np.number)) else str(value)


def point_label(point: Mapping[str, Any], ablate: bool) -> str:
    """A point of a sweep in words, its axes named as their columns: ``"k = 0.5, cut = 0.2"``."""
    return ", ".join(f"{axis_column(k, ablate)} = {_short(v)}" for k, v in point.items())




def result_columns(axes: Mapping[str, tuple], rows: list[dict], ablate: bool
                   ) -> dict[str, np.ndarray]:
    """The columns of a sweep from its rows: the axes, the values, then the bookkeeping.

    Parameters
    ----------
    axes : mapping
        Axis name → its values (the product's order, last axis fastest).
    rows : list of dict
        One row per point of the product, in its order (the workers' rows).
    ablate : bool
        Ablation sweep (``opening`` becomes ``opening_P``).

    Returns
    -------
    dict
        Column name → ndarray, shape (len(rows),): the axes (float; object for
        ``theory``), every key of the rows (``status``, ``path``, ``event`` and
        ``message`` str, ``iterations`` int, ``walls_cross`` bool, the rest
        float), then the bookkeeping in the order of ``_BOOK``.
    """
    grid = list(product(*axes.values()))
    out: dict[str, np.ndarray] = {}
    for j, name in enumerate(axes):
        out[axis_column(name, ablate)] = np.array([g[j] for g in grid],
                                                   dtype=object if name == "theory" else float)
    for key in rows[0]:
        values = [r[key] for r in rows]
        if key in ("status", "path", "event", "message"):
            out[key] = np.array(values, dtype=object).astype(str)
        elif key == "iterations":
            out[key] = np.array(values, dtype=int)
        elif key == "walls_cross":
            out[key] = np.array(values, dtype=bool)
        else:
            out[key] = np.array(values, dtype=float)
    # the bookkeeping last, in a fixed order
    for key in _BOOK:
        out[key] = out.pop(key)
    return out
