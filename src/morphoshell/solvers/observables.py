"""Observables of direct solutions, as CasADi functions of the NLP's (x, p).

An observable is defined once, symbolically, on a
:class:`~morphoshell.numerics.discretisation.Discretisation`: the unknowns x and the
physical parameters p go in, the observed quantities come out.  The same
definition serves forward evaluation, exact parametric derivatives
(:mod:`morphoshell.solvers.parametric`), nested gradient fits and fits posed as one
NLP with the equilibrium conditions as constraints.

Observables
-----------
``shape_points``  s, r, z, ψ at every point of the mesh (z in the solver's gauge
                  z(s_0) = z₀(s_0));
``energy``        the total elastic energy 𝓔 (units of C R²);
``state_at``      (r, z, ψ) at a material point s* by the cell polynomials, z in a
                  chosen gauge;
``midline``       (r_i, z_i) at N points equally spaced in the *deformed*
                  arclength, posterior end first, z from the first point
                  (the gauge of traced midlines; documentation: "Observables and gauges");
``recoil``        the ablation observables from the states of the rim before and
                  after a cut (:func:`recoil`, used by :mod:`morphoshell.mechanics.ablation`).

Gauges of z
-----------
The energy does not fix rigid translations along the axis.  ``"solver"``:
z(s_0) = z₀(s_0), the undeformed height of the first point; ``"far_end"``:
the last point keeps its undeformed height (the gauge of the Supplementary's
cut displacement); ``"start"``: z = 0 at the first point.

Lengths in units of R.
"""
from __future__ import annotations

import weakref
from dataclasses import dataclass
from typing import Callable

import casadi as ca
import numpy as np

from .._runtime.buffered import Buffered
from ..numerics import Discretisation, SymbolicShape

__all__ = ["Observable", "GAUGES", "shape_points", "energy", "state_at", "midline",
           "midline_cells", "recoil", "RECOIL"]

#: Accepted gauges of z (see the module docstring).
GAUGES = ("solver", "far_end", "start")

#: Names of the outputs of :func:`recoil`, in order.
RECOIL = ("opening", "rotation", "displacement", "radial_displacement", "axial_displacement")


@dataclass(frozen=True, eq=False)
class Observable:
    """A named vector-valued function y(x, p) of a direct solution.

    Attributes
    ----------
    name : str
    labels : tuple of str
        Name of every output entry.
    function : casadi.Function
        ``(x, p, q, *extra) -> y`` with y a column of ``len(labels)`` entries
        (q: the positions of the mesh's anchors, empty for meshes without).
    extra : callable, optional
        ``extra(x, p, q) -> list of arrays``: numerical inputs that select
        *where* the observable is evaluated (which cell holds each point of a
        midline) but are not differentiated; computed from the solution at
        every evaluation, so the function and its derivatives are built once.
    jacobian : callable, optional
        ``jacobian(x, p, q, *extra) -> (y, ∂y/∂x, ∂y/∂p (dense))``
        when the observable knows a cheaper chain rule than differentiating
        ``function`` (:mod:`morphoshell.solvers.parametric` uses it if given); ∂y/∂x
        is anything that multiplies a dense matrix by ``@`` (a sparse matrix,
        or an operator that never forms a dense ∂y/∂x).
    """

    name: str
    labels: tuple[str, ...]
    function: ca.Function
    extra: Callable | None = None
    jacobian: Callable | None = None

    def inputs(self, x: np.ndarray, p: np.ndarray, q=()) -> list:
        """All inputs of ``function`` at (x, p, q), the extra ones computed."""
        q = np.asarray(q, dtype=float)
        return [x, p, q, *(self.extra(x, p, q) if self.extra else [])]

    def __call__(self, x: np.ndarray, p: np.ndarray, q=()) -> np.ndarray:
        if not hasattr(self, "_buffered"):
            object.__setattr__(self, "_buffered", Buffered(self.function))
        return self._buffered(*self.inputs(x, p, q))[0]

    def at(self, eq) -> np.ndarray:
        """The value at a direct solution ``eq`` (of the discretisation it was built on).

        Returns
        -------
        ndarray, shape (len(labels),)
        """
        return self(eq.x, eq.problem.parameter_vector(), eq.anchors)

    def __len__(self) -> int:
        return len(self.labels)


def _gauge(z, shape: SymbolicShape, gauge: str):
    if gauge == "solver":
        return z
    pts = shape.points["z"]
    if gauge == "far_end":
        return z - pts[pts.shape[0] - 1] + shape.disc.geometry.z0(shape.b)
    if gauge == "start":
        return z - pts[0]
    raise ValueError(f"gauge = {gauge!r} must be one of {GAUGES}")


def _observable(disc: Discretisation, name: str, labels, build) -> Observable:
    y = build(disc.shape(disc.x, disc.p, disc.q))
    return Observable(name, tuple(labels), ca.Function(name, [disc.x, disc.p, disc.q], [y],
                                                       ["x", "p", "q"], ["y"]))


def shape_points(disc: Discretisation) -> Observable:
    """s, r, z, ψ at all points, stacked in that order (z in the solver's gauge).

    Returns
    -------
    Observable
        y of shape (4N,) for the N points of the mesh: s, then r, z, ψ.
    """
    n = disc.layout.points
    labels = [f"{k}[{i}]" for k in ("s", "r", "z", "psi") for i in range(n)]
    return _observable(disc, "shape_points", labels,
                       lambda sh: ca.vertcat(*[sh.points[k] for k in ("s", "r", "z", "psi")]))


def energy(disc: Discretisation) -> Observable:
    """The total elastic energy 𝓔(x, D(p)) (units of C R²; Materials and Methods, Eqs. 5-7).

    Returns
    -------
    Observable
        y of shape (1,).
    """
    f = ca.Function("energy", [disc.x, disc.D], [disc.energy])
    return Observable("energy", ("energy",),
                      ca.Function("energy", [disc.x, disc.p, disc.q],
                                  [f(disc.x, disc.pre(disc.p, disc.q))], ["x", "p", "q"], ["y"]))


def state_at(disc: Discretisation, s_star, cell: int, gauge: str = "solver") -> Observable:
    """(r, z, ψ) at the material point ``s_star`` inside ``cell``.

    Parameters
    ----------
    disc : Discretisation
    s_star : float or callable
        The material point, or a function of the named parameters (a dict of
        CasADi symbols, e.g. ``lambda q: q["cut"]``) so that it moves with them.
    cell : int
        The cell that contains it (:meth:`Discretisation.cell_of`).
    gauge : {"solver", "far_end", "start"}

    Returns
    -------
    Observable
        y = (r, z, ψ), shape (3,), by the cell's polynomials.
    """
    def build(sh: SymbolicShape):
        point = s_star(disc.structure.parameters.unpack(disc.p)) if callable(s_star) else s_star
        st = sh.at(cell, point)
        return ca.vertcat(st["r"], _gauge(st["z"], sh, gauge), st["psi"])
    return _observable(disc, "state_at", ("r", "z", "psi"), build)


#: The deformed arclength at the points, per transcription (built once: fits call it often).
_ARCLENGTH: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def _arclength_function(disc: Discretisation) -> Buffered:
    """S(x, p, q) at the points of ``disc``, cached for as long as ``disc`` lives."""
    if disc not in _ARCLENGTH:
        _ARCLENGTH[disc] = Buffered(ca.Function(
            "S", [disc.x, disc.p, disc.q], [disc.symbolic_points(disc.x, disc.p, disc.q)["S"]]))
    return _ARCLENGTH[disc]


def midline_cells(disc: Discretisation, x: np.ndarray, p: np.ndarray, n: int,
                  q=()) -> tuple[int, ...]:
    """Cells that contain the n points equally spaced in deformed arclength.

    Returns
    -------
    tuple of int
        n cell indices, one per point (the first end's point first).
    """
    S = _arclength_function(disc)(x, p, np.asarray(q, dtype=float))[0]
    nodes = S[::disc.stages]
    targets = np.linspace(0.0, 1.0, n) * nodes[-1]
    cells = np.searchsorted(nodes, targets, side="right") - 1
    return tuple(int(c) for c in np.clip(cells, 0, disc.layout.cells - 1))


def midline(disc: Discretisation, n: int, gauge: str = "start") -> Observable:
    """(r_1 … r_N, z_1 … z_N) at N = n points equally spaced in deformed arclength.

    Point i sits at the deformed arclength S_i = (i − 1)/(N − 1) S_total from
    the first end of the shell, found by Newton's method on the cell
    polynomials (:meth:`SymbolicShape.at_arclength`).  Which cell holds each
    point is a numerical input (a one-hot matrix, recomputed from every
    solution by :func:`midline_cells`), so the observable and its
    derivatives are built once.  z is in ``gauge`` (default: 0 at the first
    point).

    Returns
    -------
    Observable
        y of shape (2n,): r_1 … r_n, then z_1 … z_n; with an analytic
        ``jacobian`` in the gauge ``"start"``.
    """
    cells = disc.layout.cells
    select = ca.MX.sym("cells", cells, n)

    def build(sh: SymbolicShape):
        S_total = sh.points["S"][sh.points["S"].shape[0] - 1]
        at = sh.at_arclength_selected(select, S_total * ca.DM(np.linspace(0, 1, n)).T)
        return ca.vertcat(at["r"].T, _gauge(at["z"], sh, gauge).T)

    shape = disc.shape(disc.x, disc.p, disc.q)
    y = build(shape)
    function = ca.Function("midline", [disc.x, disc.p, disc.q, select], [y],
                           ["x", "p", "q", "cells"], ["y"])

    def one_hot(x, p, q):
        out = np.zeros((cells, n))
        out[list(midline_cells(disc, x, p, n, q)), np.arange(n)] = 1.0
        return [out]
    labels = [f"r[{i}]" for i in range(n)] + [f"z[{i}]" for i in range(n)]
    jacobian = _MidlineJacobian(disc, n) if gauge == "start" else None
    return Observable("midline", tuple(labels), function, one_hot, jacobian)


class _MidlineJacobian:
    """Value and Jacobian of the midline by the chain rule through its structure.

    Point i depends on its cell's unknowns, on z and S at that cell's first
    node (cumulative sums of per-cell increments Δz_c = ∫ f_s sin ψ ds and
    ΔS_c = ∫ f_s ds) and on the target S_i = (i − 1)/(N − 1) S_total; the
    local derivatives come from small SX functions, the sums are cumulative
    sums of sparse rows, far cheaper than differentiating the assembled
    graph.  Gauge "start" only (z from the first point).
    """

    def __init__(self, disc: Discretisation, n: int):
        from ..numerics import arclength_point, increments

        S, cells = disc.stages, disc.layout.cells
        self.disc, self.n = disc, n
        point = arclength_point(S)
        u = [point.sx_in(i) for i in range(point.n_in())]
        _, r, _, z = point(*u)
        ru = ca.vertcat(*u)
        # (dense outputs: Buffered hands over nonzeros, and the layout must be fixed)
        self._point = Buffered(ca.Function(
            "point_jac", u, [r, z, ca.densify(ca.jacobian(ca.vertcat(r, z), ru))]).map(n))
        inc = increments(S)
        v = [inc.sx_in(i) for i in range(inc.n_in())]
        out = ca.vertcat(*inc(*v))
        self._incr = Buffered(ca.Function(
            "incr_jac", v, [out, ca.densify(ca.jacobian(out, ca.vertcat(*v)))]).map(cells))
        self._nodes = Buffered(ca.Function("nodes_jac", [disc.p, disc.q],
                                           [disc.nodes(disc.p, disc.q), ca.densify(
                                               ca.jacobian(disc.nodes(disc.p, disc.q), disc.p))]))
        self.fractions = np.linspace(0.0, 1.0, n)

    def __call__(self, x, p, q, select):
        d, n, S = self.disc, self.n, self.disc.stages
        cells, nloc = d.layout.cells, 3 * S + 2
        idx = d.cell_index
        Z = np.append(x, [0.0, 0.0, np.pi])[idx]                       # (nloc, cells)
        nodes, dnodes = self._nodes(p, q)
        dnodes = dnodes.reshape(len(p), cells + 1).T                   # (cells + 1, np)
        ds = np.diff(nodes)
        inc, dinc = self._incr(Z, ds)
        inc = inc.reshape(cells, 2)                                    # Δz, ΔS per cell
        dinc = dinc.reshape(cells, nloc + 1, 2).transpose(2, 0, 1)     # (2, cells, nloc + 1)
        z0 = np.concatenate([[0.0], np.cumsum(inc[:, 0])])
        S0 = np.concatenate([[0.0], np.cumsum(inc[:, 1])])
        c = np.argmax(select, axis=0)
        target = self.fractions * S0[-1]
        r, zz, J = self._point(Z[:, c], nodes[c], ds[c], z0[c], S0[c], target)
        J = J.reshape(n, nloc + 5, 2).transpose(0, 2, 1)               # (n, 2, inputs)
        # ∂/∂p through the node positions (s0, Δs of each cell, and each Δs in the sums)
        dds = np.diff(dnodes, axis=0)                                   # (cells, np)
        yp = (J[:, :, nloc, None] * dnodes[c][:, None] + J[:, :, nloc + 1, None] * dds[c][:, None]
              + self._sums(J, c, dinc[:, :, nloc, None] * dds))
        return np.concatenate([r, zz]), _MidlineDx(self, J, c, dinc), _stack(yp)

    def _sums(self, J, c, per_cell):
        """The terms through z and S at each point's cell and S_total, (n, 2, k), from
        the derivatives of every cell's increments (Δz, ΔS) ``per_cell`` (2, cells, k)."""
        nloc = J.shape[2] - 5
        cum = np.zeros((2, per_cell.shape[1] + 1, per_cell.shape[2]))
        np.cumsum(per_cell, axis=1, out=cum[:, 1:])                    # at each cell's first node
        return (J[:, :, nloc + 2, None] * cum[0, c][:, None] + J[:, :, nloc + 3, None]
                * cum[1, c][:, None] + (J[:, :, nloc + 4] * self.fractions[:, None])[:, :, None]
                * cum[1, -1])


def _stack(a):
    """(n, 2, k) per point and output (r, z) as rows r_1 … r_n, z_1 … z_n."""
    return a.transpose(1, 0, 2).reshape(-1, a.shape[2])


class _MidlineDx:
    """∂y/∂x of the midline as an operator: ``dx @ M`` without forming dx.

    dx itself is dense (each point depends on every cell before its own through
    the cumulative sums) and costly to build, but dx @ M is the chain rule
    applied to M's rows: each cell's and each point's local Jacobian times M's
    rows of its unknowns, cumulative sums of (cells × k).
    """

    def __init__(self, owner: _MidlineJacobian, J, c, dinc):
        self._owner, self._J, self._c, self._dinc = owner, J, c, dinc
        self.shape = (2 * owner.n, owner.disc.layout.size)

    def __matmul__(self, M):
        J, c, nloc = self._J, self._c, self._J.shape[2] - 5
        M = np.asarray(M, dtype=float)
        # M's rows of each cell's unknowns, (cells, nloc, k); the constants' rows are zero
        rows = np.concatenate([M, np.zeros((3, M.shape[1]))])[self._owner.disc.cell_index.T]
        local = np.matmul(J[:, :, :nloc], rows[c])
        per_cell = np.matmul(self._dinc[:, :, :nloc].transpose(1, 0, 2), rows)
        return _stack(local + self._owner._sums(J, c, per_cell.transpose(1, 0, 2)))

    def toarray(self) -> np.ndarray:
        """dx as a dense array (for checks)."""
        return self @ np.eye(self.shape[1])


def recoil(pre: dict, post: dict) -> dict:
    """Ablation observables from the rim's (r, z, ψ) before and after the cut.

    Supplementary, toy problem 2 ("Cut opening", "Cut rotation and cut
    displacement"), with both states at the material point s = Σ and z in
    the far-end gauge:

    * opening o = 2 [r_post − r_pre] (change of the hole's diameter);
    * rotation ϱ = ψ_post − ψ_pre (positive when the rim curls outward);
    * displacement d = |(Δr, Δz)|, and its radial and axial parts.

    Works on floats and CasADi expressions.

    Parameters
    ----------
    pre, post : mapping
        ``r``, ``z``, ``psi`` of the rim before and after the cut.

    Returns
    -------
    dict
        The keys of :data:`RECOIL`, floats (or CasADi expressions).
    """
    dr, dz = post["r"] - pre["r"], post["z"] - pre["z"]
    hypot = ca.sqrt(dr**2 + dz**2) if isinstance(dr, (ca.SX, ca.MX)) else float(np.hypot(dr, dz))
    return {"opening": 2 * dr, "rotation": post["psi"] - pre["psi"], "displacement": hypot,
            "radial_displacement": dr, "axial_displacement": dz}
