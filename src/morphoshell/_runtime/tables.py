"""Results as tables: what DataFrames, xarray Datasets and Jupyter views of results share.

Every result class (an equilibrium, an ablation, a sweep, the inverse estimates)
describes its problem the same way: as flat attributes (:func:`problem_attrs`,
valid netCDF attributes) and as rows of a small HTML table (:func:`problem_rows`,
:func:`html_table`).  xarray is an optional extra (:func:`xarray_module`).  The
problems are taken by their ``describe()``, ``name``, ``family``, ... attributes:
no import of the model is needed here.
"""
from __future__ import annotations

from typing import Any

__all__ = ["XARRAY_MISSING", "xarray_module", "problem_attrs", "problem_rows", "html_table"]

XARRAY_MISSING = ("to_xarray() needs xarray, an optional extra of morphoshell: "
                  "pip install 'morphoshell[xarray]'")


def xarray_module():
    """The xarray module, or ImportError naming the extra that provides it."""
    try:
        import xarray
    except ImportError:
        raise ImportError(XARRAY_MISSING) from None
    return xarray


def problem_attrs(problem) -> dict[str, Any]:
    """A problem as flat attributes (strings and numbers: valid netCDF attributes too).

    ``family``, ``theory``, ``geometry``, ``name``, ``h``, ``cut``, ``opening``
    (units of R), ``param_<name>`` for each family parameter, and ``problem``,
    the whole description as JSON (:meth:`Problem.describe`).
    """
    import json

    d = problem.describe()
    out: dict[str, Any] = {k: d[k] for k in ("name", "family", "theory", "geometry", "h", "cut",
                                             "opening")}
    out.update({f"param_{k}": float(v) for k, v in d["params"].items()})
    out["problem"] = json.dumps(d)
    return out


def problem_rows(problem) -> list[tuple[str, str]]:
    """A problem as (name, value) rows for :func:`html_table` (lengths in units of R)."""
    what = f"{problem.family} family, {problem.theory.replace('_', '-')} theory, {problem.geometry}"
    rows = [("problem", f"{problem.name}: {what}" if problem.name else what),
            ("thickness h", f"{problem.h:g} R"), ("cut Σ", f"{problem.cut:g} R"),
            ("far-end opening P", f"{problem.opening:g} R")]
    if problem.params:
        rows.append(("parameters", ", ".join(f"{k} = {v:g}" for k, v in problem.params.items())))
    return rows


def html_table(rows: list[tuple[str, str]], caption: str) -> str:
    """A small HTML table of (name, value) rows: the Jupyter view of results."""
    from html import escape

    body = "".join(f"<tr><th style='text-align:left'>{escape(k)}</th>"
                   f"<td style='text-align:left'>{escape(v)}</td></tr>" for k, v in rows)
    head = f"<caption style='text-align:left'><b>{escape(caption)}</b></caption>"
    return f"<table>{head}{body}</table>"
