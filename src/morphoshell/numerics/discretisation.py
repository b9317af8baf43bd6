"""Discretisation of the shell energy as a parametric NLP (Gauss collocation).

:class:`Discretisation` is the transcription's one entry point: for a problem
structure, a mesh and a number of stages S it gives the NLP (objective,
constraints and their exact derivatives, for Ipopt), the certified Newton system
(for :mod:`morphoshell.numerics.newton`), the fields of a solution, and the shape
and KKT derivatives as CasADi expressions (for observables, parametric derivatives
and fits).  The pieces live in modules of one job each:

* :mod:`.scheme`: S-stage Gauss collocation (order 2S), the layout of the
  unknowns x = [r_free, ψ_free, f_s], the points of a mesh, integration to them;
* :mod:`.cell_kernels`: one cell's energy, constraints, derivatives and Newton
  block as SX kernels, compiled to C once per machine;
* :mod:`.parameter_data`: the NLP's parameter vector D, the parameter-only data
  at every Gauss point, and its derivatives in the physical parameters;
* :mod:`.gathers`: the sparse assembly of per-cell values by index gathers;
* :mod:`.newton_assembly` (with :mod:`.cell_order`): the Newton system in cell order;
* :mod:`.kkt_derivatives`: the KKT residual's curvature and θ-derivatives;
* :mod:`.shape`: the discrete shape as expressions of (x, p).

Parametric mesh
---------------
The nodes are material points s_i = Σ + (L − P − Σ) t_i of a fixed graded mesh
t_i (:mod:`morphoshell.numerics.mesh`), so Σ and P are NLP parameters like h and the
profile parameters.

Assembly
--------
Each cell's energy terms and constraints depend on its 3S + 2 local unknowns and
on its data; the cell kernels are mapped over the cells and their values gathered
into the global gradient, Jacobian and Hessian by constant index patterns computed
numerically, so no symbolic work grows with the mesh (the build still grows about
linearly with N, in CasADi's constructions of patterns, maps and index lists).
What depends on the layout and the kernels alone (the symbols x and D, the NLP,
its patterns, the Newton system) is shared by every live discretisation of that
layout (:class:`_Shared`): a second mesh of the same size builds only its
parameter data.

Symbolic fields
---------------
Besides the NLP, a :class:`Discretisation` gives the shape as CasADi
expressions of the unknowns x and the physical parameters p: r and ψ at the
points, z and the deformed arclength by exact integration of z' = f_s sin ψ
and S' = f_s, and (r, z, ψ) anywhere inside a cell by its polynomials
(:class:`~morphoshell.numerics.shape.SymbolicShape`).  The observables of
:mod:`morphoshell.solvers.observables` are built from these, so that forward
evaluation, parametric derivatives and fits share one definition.
"""
from __future__ import annotations

import weakref
from functools import cached_property

import casadi as ca
import numpy as np

from .._runtime.compiled import ChunkedMap
from ..model.energy import LOCAL_OUTPUTS
from ..model.layouts import CELL_DATA
from ..model.problem import Structure
from .cell_kernels import cell_functions, compiled_cell_functions
from .cell_order import Assembly, CellOrder, assembly
from .gathers import assembled, gather, triu
from .kkt_derivatives import KKTDerivatives
from .mesh import Knot, check_monotone
from .newton_assembly import newton_rhs, newton_system
from .parameter_data import ParameterData
from .cell_kernels import NODE_OUTPUTS
from .scheme import (POLE_VALUES, Layout, PointData, collocation, integrate_numeric,
                     integrate_symbolic, integration_operators, mesh_point_data, reconstruction)
from .shape import SymbolicShape, cell_state

__all__ = ["Discretisation"]

#: Cells per call of the results' fields (:func:`_fields_map`).
FIELDS_CHUNK = 64
_FIELDS_MAPS: dict = {}


def _fields_map(kernel: ca.Function) -> ChunkedMap:
    """``(cells, *inputs) -> [outputs]``: the cell kernel ``kernel`` (the results' "fields":
    pointwise fields at the Gauss points from a cell's unknowns and data, one stacked output
    so that a solve copies to NumPy once; "ends", "node": those at the nodes) over any number
    of cells or nodes, one evaluator per kernel and process
    (:class:`~morphoshell._runtime.compiled.ChunkedMap`), where a map per mesh would cost
    every build its construction."""
    key = id(kernel)
    if key not in _FIELDS_MAPS:        # (the kernel is held: its id is not reused)
        _FIELDS_MAPS[key] = kernel, ChunkedMap(kernel.map(FIELDS_CHUNK), FIELDS_CHUNK)
    return _FIELDS_MAPS[key][1]


class _Shared:
    """What every discretisation of one layout and set of cell kernels builds alike.

    The unknowns x and data D (symbols), each cell's share of them, and all
    that is assembled from the cell kernels alone in ``built``: the fields,
    Ipopt's NLP and its scatter patterns, the Newton system.  The structure,
    the mesh and the parameters enter through the values of D only, so two
    solvers with the same number of cells and order (say, meshes graded for
    different h) share these, and the second build costs the mesh and its
    parameter data alone.  Entries are held weakly (:data:`_SHARED`): nothing
    outlives the last discretisation using it, and a fresh build of a size
    that no live solver has is a full build.
    """

    def __init__(self, layout: Layout, cell: dict):
        self.cell = cell      # (held: the key's id(cell) cannot be reused while this lives)
        self.x = ca.MX.sym("x", layout.size)
        self.D = ca.MX.sym("D", len(CELL_DATA) * layout.cells * layout.stages)
        self.built: dict = {}


#: (layout, id of the cell kernels) -> _Shared, weakly held.
_SHARED: "weakref.WeakValueDictionary" = weakref.WeakValueDictionary()


def _shared(layout: Layout, cell: dict) -> _Shared:
    """The :class:`_Shared` objects of ``layout`` with the cell kernels ``cell``."""
    key = (layout, id(cell))
    found = _SHARED.get(key)
    if found is None or found.cell is not cell:
        found = _SHARED[key] = _Shared(layout, cell)
    return found


class Discretisation:
    """The discrete energy and constraints for one (structure, mesh, stages).

    Each cell's energy terms and constraints depend on its 3S + 2 local
    unknowns z_c = (r at its S + 1 points, ψ at them, f_s at its S Gauss
    points) and on parameter-only *data* at its Gauss points, laid out as
    :data:`~morphoshell.model.layouts.CELL_DATA`.  Small SX functions give a cell's
    values, gradients and Hessian (:mod:`morphoshell.numerics.cell_kernels`); they
    are mapped over the cells and assembled into the global gradient, Jacobian and
    Hessian by constant index gathers computed numerically
    (:mod:`morphoshell.numerics.gathers`).  The Newton system is assembled in cell
    order (:mod:`morphoshell.numerics.cell_order`,
    :mod:`morphoshell.numerics.newton_assembly`).  The parameter data D are
    evaluated by one compiled kernel per cell fed the mesh's numbers at its nodes
    (:mod:`morphoshell.numerics.parameter_data`).  Ipopt's callbacks run the kernels
    compiled to C when a compiler is available
    (:func:`~morphoshell.numerics.cell_kernels.compiled_cell_functions`, ``numeric``).
    The data are computed once per solve (:meth:`cell_data`) and are the NLP's
    parameter vector, so Ipopt's callbacks never re-evaluate profiles or
    coefficients.

    Parameters
    ----------
    structure : Structure
    t : ndarray
        Nodes in [0, 1] (see :func:`morphoshell.numerics.mesh.graded_mesh`).
    stages : int
        Gauss points per cell S (order 2S).
    knots : tuple of Knot (or float)
        Nodes of ``t`` that sit at given material points: the anchors q
        passed with every solve, or the family's breakpoints, which move with
        the parameters (see :class:`morphoshell.numerics.mesh.Knot`; a float is an
        anchor).

    Attributes
    ----------
    x : casadi.MX
        Unknowns [r_free, ψ_free, f_s] (:class:`~morphoshell.numerics.scheme.Layout`).
    D : casadi.MX
        NLP parameters: the Gauss-point data, column-major (n_D × cells S).
    p : casadi.MX
        Physical parameters (``structure.parameters``); ``pre(p, q)`` gives ``D``.
    q : casadi.MX
        Positions of the anchors (one per anchor knot; empty without).
    pre_numeric : casadi.Function
        ``(p, q) -> D``, for evaluation
        (:attr:`morphoshell.numerics.parameter_data.ParameterData.numeric`).
    energy, objective : casadi.MX
        Total energy 𝓔(x, D) and the scaled objective handed to Ipopt.
    g : casadi.MX
        Compatibility constraints (cells S,), all equalities g = 0.
    grad_f, jac_g, hess_lag : casadi.Function
        Exact derivatives in the signatures of ``nlpsol``'s options.
    cell_index : ndarray of int, shape (n_loc, cells)
        Where each cell's unknowns z_c sit in ``[x, POLE_VALUES]`` (pole values
        after the unknowns): the gather that every per-cell assembly starts from.
    """

    def __init__(self, structure: Structure, t: np.ndarray, stages: int = 2,
                 knots: tuple = ()):
        if stages not in (1, 2, 3):
            raise ValueError(f"stages = {stages!r} must be 1, 2 or 3")
        self.structure = structure
        self.geometry = structure.geometry
        self.t = np.asarray(t, dtype=float)
        self.knot_list = tuple(k if isinstance(k, Knot) else Knot(float(k), "anchor", i)
                               for i, k in enumerate(knots))
        self.knots = tuple(k.t for k in self.knot_list)
        self.anchors = sum(k.source == "anchor" for k in self.knot_list)
        missing = [k for k in self.knots if not np.any(self.t == k)]
        if missing:
            raise ValueError(f"mesh knots {missing} are not nodes of the mesh")
        self.stages = S = stages
        cells = len(self.t) - 1
        self.layout = lay = Layout(cells, S, structure.start == "pole", structure.end == "pole")
        self.tau, self.weights = collocation(S)[:2]

        self.p = ca.MX.sym("p", len(structure.parameters))
        self.q = ca.MX.sym("q", self.anchors)
        self._data = ParameterData(structure, self.t, S, self.knot_list, self.p, self.q)
        self.pre_numeric = self._data.numeric
        # Ipopt and results evaluate compiled cell kernels when a C compiler is
        # available; the differentiable SX-based functions (parametric derivatives,
        # observables, fits) are assembled on first use, and so is Ipopt's NLP
        # (``numeric``): a solve that Newton certifies needs neither.
        compiled = compiled_cell_functions(S)
        self.kernels = "compiled" if compiled is not None else "casadi"
        self._cell = compiled or cell_functions(S)
        # x, D and what is assembled from the cell kernels alone are shared
        # with the other live discretisations of this layout (_Shared)
        self._shared = _shared(lay, self._cell)
        self.x, self.D = self._shared.x, self._shared.D
        self.cell_index = lay.cell_indices()
        self._idx_flat = self.cell_index.ravel(order="F")
        self._field_names = ("s", "ds", "weight", "r", "psi", "f_s", "dpsi", *LOCAL_OUTPUTS)
        self._points = (None, None)
        self._fields = _fields_map(self._cell["fields"])
        self._ends = _fields_map(self._cell["ends"])
        self._node = _fields_map(self._cell["node"])

    # -- the NLP ---------------------------------------------------------------
    def _built(self, name: str, build):
        """The object ``name``, shared by every live discretisation of this layout and
        kernels (:class:`_Shared`); ``build()`` on first use."""
        built = self._shared.built
        if name not in built:
            built[name] = build()
        return built[name]

    def _pattern(self, name: str) -> tuple:
        """Where stacked cell values go in the NLP's derivatives (:func:`gather`): ``name``
        is ``"grad"``, ``"jac"`` or ``"hess"``; computed numerically on first use."""
        return self._built(f"pattern {name}", getattr(self, f"_{name}_pattern"))

    def _grad_pattern(self) -> tuple:
        idx, n, cells = self.cell_index, self.layout.size, self.layout.cells
        n_loc = idx.shape[0]
        free = idx < n  # which local slots are unknowns
        cols = np.arange(n_loc * cells).reshape(cells, n_loc).T  # position of (slot, cell)
        return gather((n, 1), idx[free], np.zeros(int(free.sum())), cols[free], n_loc * cells)

    def _jac_pattern(self) -> tuple:
        idx, n, S, cells = self.cell_index, self.layout.size, self.stages, self.layout.cells
        m, n_loc = cells * S, idx.shape[0]
        # dg is (S n_loc × cells), row-major in (k, slot) within a cell.
        k_, l_ = np.meshgrid(np.arange(S), np.arange(n_loc), indexing="ij")
        rows = (np.arange(cells)[None, None, :] * S + k_[..., None])
        colv = np.broadcast_to(idx[l_.ravel()].reshape(S, n_loc, cells), rows.shape[:2] + (cells,))
        rows = np.broadcast_to(rows, colv.shape)
        src = (np.arange(cells)[None, None, :] * (S * n_loc)
               + (l_ * S + k_)[..., None])   # column-major jacobian (S × n_loc) per cell
        keep = colv < n
        return gather((m, n), rows[keep], colv[keep], src[keep], S * n_loc * cells)

    def _hess_pattern(self) -> tuple:
        idx, n, cells = self.cell_index, self.layout.size, self.layout.cells
        n_loc = idx.shape[0]
        ku, lu = triu(n_loc)
        I, Jc = idx[ku], idx[lu]
        ok = (I < n) & (Jc < n)
        n_tri = len(ku)
        srch = (np.arange(n_tri)[:, None] + n_tri * np.arange(cells)[None, :])[ok]
        return gather((n, n), np.minimum(I, Jc)[ok], np.maximum(I, Jc)[ok], srch, n_tri * cells)

    def _nlp(self, cell: dict, energy: bool = True) -> dict:
        """Objective, constraints, their derivatives and the fields, from cell kernels ``cell``.

        ``energy``: include the total energy's expression (only the
        differentiable NLP needs it; solves take it from the fields).
        """
        S, cells = self.stages, self.layout.cells
        m = cells * S
        Z, Dc = self._local
        sigma, lam = ca.MX.sym("lam_f"), ca.MX.sym("lam_g", m)
        ell, dell = cell["grad"].map(cells)(Z, Dc)
        g2, dg = cell["jac"].map(cells)(Z, Dc)
        hess = cell["hess"].map(cells)(Z, Dc, sigma, ca.reshape(lam, S, cells))
        grad = assembled(*self._pattern("grad"), dell)
        J = assembled(*self._pattern("jac"), dg)
        H = assembled(*self._pattern("hess"), hess)
        x, D = self.x, self.D
        nlp = {
            "objective": ca.sum2(cell["f"].map(cells)(Z, Dc)),
            "g": ca.vec(cell["g"].map(cells)(Z, Dc)),
            "grad_f": ca.Function("grad_f", [x, D], [ca.sum2(ell), grad],
                                  ["x", "p"], ["f", "grad_f_x"]),
            "jac_g": ca.Function("jac_g", [x, D], [ca.vec(g2), J], ["x", "p"], ["g", "jac_g_x"]),
            "hess_lag": ca.Function("hess_lag", [x, D, sigma, lam], [H],
                                    ["x", "p", "lam_f", "lam_g"], ["triu_hess_gamma_x_x"]),
        }
        if energy:
            nlp["energy"] = ca.sum2(cell["energy"].map(cells)(Z, Dc))
        return nlp

    @property
    def numeric(self) -> dict:
        """The NLP on the cheapest kernels (compiled when available), for Ipopt's callbacks:
        ``objective``, ``g``, ``grad_f``, ``jac_g``, ``hess_lag``; built on first use."""
        return self._built("numeric",
                           lambda: self._nlp(self._cell, energy=self.kernels == "casadi"))

    @property
    def _local(self) -> tuple:
        """(Z, D_c): each cell's unknowns (:meth:`cell_unknowns` of x) and data, a column per
        cell, as expressions of the symbols x, D."""
        return self._built("local", lambda: (self.cell_unknowns(self.x),
                                             ca.reshape(self.D, -1, self.layout.cells)))

    def _symbolic_nlp(self) -> dict:
        if self.kernels == "casadi":
            return self.numeric
        return self._built("symbolic", lambda: self._nlp(cell_functions(self.stages)))

    @property
    def objective(self) -> ca.MX:
        """The scaled objective handed to Ipopt (differentiable expression of x, D)."""
        return self._symbolic_nlp()["objective"]

    @property
    def energy(self) -> ca.MX:
        """The total energy 𝓔(x, D) (differentiable expression)."""
        return self._symbolic_nlp()["energy"]

    @property
    def g(self) -> ca.MX:
        """The compatibility constraints g(x, D) = 0 (differentiable expression)."""
        return self._symbolic_nlp()["g"]

    @property
    def grad_f(self) -> ca.Function:
        """``(x, D) -> (f, ∇f)`` (differentiable)."""
        return self._symbolic_nlp()["grad_f"]

    @property
    def jac_g(self) -> ca.Function:
        """``(x, D) -> (g, ∂g/∂x)`` (differentiable)."""
        return self._symbolic_nlp()["jac_g"]

    @property
    def hess_lag(self) -> ca.Function:
        """``(x, D, σ, λ) -> triu ∇²(σ f + λᵀg)`` (differentiable)."""
        return self._symbolic_nlp()["hess_lag"]

    @property
    def constraints(self) -> int:
        """Number of constraints (cells × S)."""
        return self.layout.cells * self.stages

    # -- the mesh and the parameter data ---------------------------------------
    def nodes(self, p, q, ends: tuple | None = None):
        """Material points s of the mesh nodes (the parametric map of
        :mod:`morphoshell.numerics.mesh`).

        Each cell is affine in s between its nodes: Gauss and interpolation
        points sit at fixed fractions of it.  ``ends``: :meth:`shell_ends` of p,
        if at hand.
        """
        return self._data.nodes(p, q, ends)

    def knot_positions(self, p, q) -> list:
        """Material points of the knots: anchors from q, breakpoints from the parameters."""
        return self._data.knot_positions(p, q)

    def shell_ends(self, p):
        """(Σ, L − P) from the parameter vector (CasADi or NumPy)."""
        return self._data.shell_ends(p)

    @property
    def pre(self) -> ca.Function:
        """``(p, q) -> D``, differentiable (MX); built on first use
        (:attr:`morphoshell.numerics.parameter_data.ParameterData.function`).

        Solves evaluate :attr:`pre_numeric`; only fits, observables and
        parametric derivatives differentiate D.
        """
        return self._data.function

    @property
    def pre_jacobian(self) -> ca.Function:
        """``(p, q) -> dD/dp`` (dense, n_D·cells·S × n_p), for evaluation; built on first use
        (:attr:`morphoshell.numerics.parameter_data.ParameterData.jacobian`)."""
        return self._data.jacobian

    @property
    def pre_hessian(self) -> ca.Function:
        """``(p, q, c) -> ∂²(c·D)/∂p²`` (n_p × n_p), for evaluation; built on first use.

        c weighs the cell data D (as D); the chain rule one Gauss point at a time
        (:attr:`morphoshell.numerics.parameter_data.ParameterData.hessian`).
        """
        return self._data.hessian

    def cell_data(self, p: np.ndarray, q=()) -> np.ndarray:
        """The NLP parameter vector D for physical parameters ``p`` and anchors ``q``."""
        return self._data(p, q)

    # -- numerical interface -------------------------------------------------
    def points(self, p: np.ndarray, q=()) -> np.ndarray:
        """Arclength s of the points (nodes and interior points) for parameters ``p``."""
        return self.point_data(p, q).s.copy()

    def point_data(self, p: np.ndarray, q=()) -> PointData:
        """The points for parameters ``p`` and anchors ``q``, with what depends on them alone
        (:class:`~morphoshell.numerics.scheme.PointData`, read-only)."""
        nodes = self.nodes(np.asarray(p, dtype=float), q)
        # the nodes stay put unless the shell's ends or the knots move: kept, and a warm
        # re-solve skips recomputing them
        key = nodes.tobytes()
        if self._points[0] != key:
            self._points = (key, mesh_point_data(nodes, self.tau, self.geometry, self.layout))
        return self._points[1]

    def initial_guess(self, p: np.ndarray, q=()) -> np.ndarray:
        """The undeformed shell: r = ρ, ψ = ψ₀, f_s = 1."""
        pts = self.point_data(p, q)
        return self.layout.pack(pts.rho, pts.psi0, np.ones(self.layout.cells * self.stages))

    def check_anchors(self, p: np.ndarray, q) -> np.ndarray:
        """``q`` as an array, or ValueError unless it holds increasing points inside the shell."""
        q = np.asarray(q, dtype=float).ravel()
        if len(q) != self.anchors:
            raise ValueError(f"this mesh has {self.anchors} anchor(s), got {len(q)}")
        p = np.asarray(p, dtype=float)
        a, b = self.shell_ends(p)
        where = [float(v) for v in self.knot_positions(p, q)]
        if where and not np.all(np.diff(np.concatenate([[a], where, [b]])) > 0):
            names = [f"{k.source} {k.index}" for k in self.knot_list]
            raise ValueError(
                f"this mesh puts nodes at {dict(zip(names, where))}, which must be increasing and "
                f"lie inside the shell ({a:.6g}, {b:.6g}): a breakpoint of the family moved past "
                f"another or out of the shell; solve with solve() (which picks a suitable mesh) "
                f"or build a DirectSolver with mesh_spec for this problem")
        if where:
            check_monotone(self.nodes(p, q))
        return q

    def gauss_fields(self, x: np.ndarray, D: np.ndarray) -> dict[str, np.ndarray]:
        """Every pointwise quantity at the Gauss points, given the data ``D``."""
        out = self._fields(self.layout.cells, self.local_values(x), D)[0].reshape(
            -1, len(self._field_names)).T
        return dict(zip(self._field_names, out))

    def node_fields(self, x: np.ndarray, lam: np.ndarray, D: np.ndarray, r: np.ndarray,
                    psi: np.ndarray, I: np.ndarray, h: float) -> dict[str, np.ndarray]:
        """The pointwise fields at the mesh nodes, from their state and costates.

        The costates at a node are the mean of its two cells' (one at an end; the two
        differ by the KKT residual), the controls f_s and ψ' there solve Pontryagin's
        stationarity, and the fields follow pointwise
        (:func:`~morphoshell.numerics.cell_kernels.cell_functions`, ``"ends"`` and
        ``"node"``): order 2S, where Gauss-point values are of order 2S − 1 at best.

        Parameters
        ----------
        x, lam : ndarray
            The NLP's unknowns and multipliers.
        D : ndarray
            The cell data.
        r, psi : ndarray, shape (N + 1,)
            The state at the nodes.
        I : ndarray, shape (len(INTRINSIC), N + 1)
            The intrinsic data at the nodes
            (:func:`~morphoshell.model.energy.intrinsic_values`).
        h : float
            The thickness.

        Returns
        -------
        dict
            :data:`~morphoshell.numerics.cell_kernels.NODE_OUTPUTS` by name, each (N + 1,);
            not finite on the axis (ρ = 0), where the caller extrapolates.
        """
        cells, S = self.layout.cells, self.stages
        ends = self._ends(cells, self.local_values(x), D, lam)[0].reshape(cells, 4).T
        lam_nodes = np.empty((2, cells + 1))
        lam_nodes[:, 0], lam_nodes[:, -1] = ends[:2, 0], ends[2:, -1]
        lam_nodes[:, 1:-1] = 0.5 * (ends[2:, :-1] + ends[:2, 1:])
        n = cells + 1
        out = self._node(n, np.vstack([r, psi, lam_nodes]), I, np.full(n, float(h)))[0]
        return dict(zip(NODE_OUTPUTS, out.reshape(n, len(NODE_OUTPUTS)).T))

    def to_points(self, gauss: np.ndarray, nodes: np.ndarray) -> np.ndarray:
        """Fields at the points from their values at the Gauss points and at the nodes.

        The nodes keep their values, the interior points of a cell take the
        polynomial through the cell's two node values and its Gauss values, and a pole
        (no value of its own) the polynomial through the cell's others
        (:func:`~morphoshell.numerics.scheme.reconstruction`): within cells, never
        across a node, where a profile may kink.

        Parameters
        ----------
        gauss : ndarray, shape (F, cells S)
        nodes : ndarray, shape (F, N + 1)

        Returns
        -------
        ndarray, shape (F, points)
        """
        S, cells, lay = self.stages, self.layout.cells, self.layout
        inner, start, end = reconstruction(S)
        F = gauss.shape[0]
        G = gauss.reshape(F, cells, S)
        nodes = nodes.copy()
        if lay.start_pole:      # (first, as the cell's interior points need it)
            nodes[:, 0] = G[:, 0] @ start[1:-1] + nodes[:, 1] * start[-1]
        if lay.end_pole:
            nodes[:, -1] = nodes[:, -2] * end[0] + G[:, -1] @ end[1:-1]
        data = np.concatenate([nodes[:, :-1, None], G, nodes[:, 1:, None]], axis=2)
        out = np.empty((F, lay.points))
        out[:, ::S] = nodes
        for l in range(1, S):
            out[:, l:-1:S] = data @ inner[l - 1]
        return out

    def integrate_to_points(self, values: np.ndarray, p: np.ndarray | None = None, q=(), *,
                            ds: np.ndarray | None = None) -> np.ndarray:
        """∫ ds from the first node to every point, of a function known at the Gauss points.

        Exact for the degree S − 1 interpolant of ``values`` through the Gauss
        points of each cell.  The cell widths come from the parameters ``p``
        and anchors ``q``, or are given as ``ds`` (one per Gauss point, as
        :meth:`gauss_fields` returns them).  Numbers or CasADi expressions; the
        result has one entry per point.
        """
        if ds is None:
            ds = np.repeat(np.diff(self.nodes(np.asarray(p, dtype=float), q)), self.stages)
        if isinstance(values, (ca.MX, ca.SX)) or isinstance(ds, (ca.MX, ca.SX)):
            return integrate_symbolic(values, ds, self._integration)
        return integrate_numeric(values, ds, self.stages)

    @cached_property
    def _integration(self) -> tuple:
        """:func:`~morphoshell.numerics.scheme.integration_operators`, built on first use
        (only expressions need them)."""
        return integration_operators(self.layout)

    def state_at(self, x: np.ndarray, p: np.ndarray, q, z_points: np.ndarray,
                 s_star: float) -> dict:
        """(r, ψ, z) at the material point ``s_star`` of a solution, numerically.

        The same cell polynomials as :meth:`SymbolicShape.at`; ``z_points`` are
        the solution's z at the points (any gauge: the result is in the same).
        At a node (an anchor) the values are the nodal ones.
        """
        cell = self.cell_of(p, q, s_star)
        s0, s1 = (float(v) for v in self.nodes(np.asarray(p, dtype=float), q)[[cell, cell + 1]])
        Zc = np.append(x, POLE_VALUES)[self.cell_index[:, cell]]
        out = cell_state(self.stages)(Zc, s1 - s0, z_points[cell * self.stages], 0.0,
                                      (s_star - s0) / (s1 - s0))
        return {k: float(v) for k, v in zip(("r", "psi", "z"), out)}

    def cell_of(self, p: np.ndarray, q, s_star: float) -> int:
        """Index of the cell that contains the material point ``s_star``."""
        nodes = self.nodes(np.asarray(p, dtype=float), q)
        return int(np.clip(np.searchsorted(nodes, s_star, side="right") - 1, 0,
                           self.layout.cells - 1))

    # -- symbolic interface (for observables) --------------------------------
    def local_values(self, x: np.ndarray) -> np.ndarray:
        """:meth:`cell_unknowns` in numbers: each cell's unknowns, column-major (flat)."""
        return np.append(np.asarray(x, dtype=float), POLE_VALUES)[self._idx_flat]

    def cell_unknowns(self, x) -> ca.MX:
        """(3S + 2, cells): each cell's r, ψ at its points and f_s at its Gauss points."""
        n_loc, cells = self.cell_index.shape
        xfull = ca.vertcat(x, ca.DM(POLE_VALUES))
        return ca.reshape(xfull[self._idx_flat.tolist()], n_loc, cells)

    def gauss_values(self, Z) -> tuple:
        """f_s and ψ at the Gauss points (vectors, cell by cell) from ``cell_unknowns``."""
        S = self.stages
        psi_g = ca.mtimes(ca.DM(collocation(S)[2]), Z[S + 1:2 * S + 2, :])
        return ca.vec(Z[2 * S + 2:, :]), ca.vec(psi_g)

    def shape(self, x, p, q) -> SymbolicShape:
        """The discrete shape as CasADi expressions of the unknowns x, parameters p, anchors q."""
        return SymbolicShape(self, x, p, q)

    def symbolic_points(self, x, p, q) -> dict:
        """s, r, ψ, z and the deformed arclength S at the points (see :class:`SymbolicShape`)."""
        return self.shape(x, p, q).points

    # -- the Newton system -----------------------------------------------------
    @cached_property
    def cell_order(self) -> CellOrder:
        """The cell order u of (x, λ) in which the Newton system is assembled and solved
        (:mod:`morphoshell.numerics.cell_order`)."""
        lay = self.layout
        return CellOrder(lay.cells, lay.stages, lay.start_pole, lay.end_pole)

    @property
    def cell_assembly(self) -> Assembly:
        """Where the Newton system's entries come from
        (:func:`morphoshell.numerics.cell_order.assembly`)."""
        return self._built("cell assembly", lambda: assembly(self.cell_order))

    def kkt_pack(self, x: np.ndarray, lam: np.ndarray) -> np.ndarray:
        """(x, λ) in cell order u (:attr:`cell_order`), the poles' fixed values filled in."""
        return self.cell_order.pack(x, lam, POLE_VALUES)

    def newton_system(self) -> ca.Function:
        """``(u, D, ρ) -> (K, rhs, ‖∇f + Jᵀλ‖∞, ‖g‖∞, ‖λ‖₁, W)``: the certified Newton system.

        u holds x and λ in cell order (:attr:`cell_order`; :meth:`kkt_pack`
        and ``cell_order.unpack`` convert), the system's unknowns are u[lo:hi].
        K = [[M, Jᵀ], [J, −Δ]] with M = ∇²ℒ + Jᵀ W J, W > 0 per constraint
        scaled by ρ, Δ = ε W⁻¹ (ε = :data:`~morphoshell.numerics.cell_kernels.NEWTON_EPSILON`);
        rhs = −(∇f + Jᵀ(λ + W g), g), both symmetrically permuted to cell
        order.  Its solution is Newton's step on the KKT conditions (to a
        relative ε), and its inertia certifies a minimum (see
        :mod:`morphoshell.numerics.newton`).  Assembled from one kernel per cell
        (:func:`morphoshell.numerics.newton_assembly.newton_system`), built on first
        use.  K is (n + m) × (n + m), sparse and symmetric; rhs (n + m,); W (m,).
        """
        return self._built("newton", lambda: newton_system(
            self._cell["newton"], self.cell_order, self.cell_assembly, self.D))

    def newton_rhs(self) -> ca.Function:
        """``(u, D, W) -> (rhs, ‖∇f + Jᵀλ‖∞, ‖g‖∞, ‖λ‖₁)``: :meth:`newton_system`'s
        right-hand side and errors for given weights W (m,), without the Hessian.

        With W those of a factorised K, a step with that factorisation is a
        chord (simplified Newton) step (:mod:`morphoshell.numerics.newton`).
        """
        return self._built("newton_rhs", lambda: newton_rhs(
            self._cell["newton_rhs"], self._cell.get("newton_rhs_block"), self.cell_order,
            self.cell_assembly, self.D))

    # -- the KKT residual's derivatives (fits) ---------------------------------
    @cached_property
    def _kkt(self) -> KKTDerivatives:
        """The KKT residual's curvature and θ-derivatives, set up on first use."""
        return KKTDerivatives(self.layout, self.cell_index, self._cell["kkt_data"],
                              self.cell_unknowns, lambda: self._local, self.x, self.D)

    def kkt_curvature(self, x, lam, D, mu_F, mu_dz, mu_dS, ds) -> ca.MX:
        """Upper triangle of ∂²/∂(x, λ)² [μ_F·F(x, λ) − Σ_c (μ_dz,c Δz_c + μ_dS,c ΔS_c)].

        F = (∇f + Jᵀλ, g) is the KKT residual of the NLP
        (:attr:`morphoshell.solvers.parametric.Parametric.kkt_residual`) and Δz_c, ΔS_c
        the cell increments of z and of the deformed arclength
        (:meth:`SymbolicShape.increments`, cell widths ``ds``): the curvature
        of the equilibrium as constraints of a larger NLP (a fit in one NLP).
        Assembled from one SX kernel per cell, as :attr:`hess_lag` is
        (:meth:`morphoshell.numerics.kkt_derivatives.KKTDerivatives.curvature`).

        Shapes: x (n,), λ and the constraints (m,), μ_F (n + m,), μ_dz, μ_dS
        and ds (cells,); the result is (n + m) × (n + m), sparse.
        """
        return self._kkt.curvature(x, lam, D, mu_F, mu_dz, mu_dS, ds)

    def kkt_curvature_theta(self, x, lam, D, T, mu_F, mu_dz, mu_dS) -> tuple:
        """The curvature of :meth:`kkt_curvature`'s function across the cell data D.

        With D moving along D + T t (T = ∂D/∂θ, rows as D, k columns) and the
        cell widths read from D: the mixed block ∂²/∂(x, λ)∂t ((n + m) × k,
        sparse rows), the block ∂²/∂t² (k × k) and the gradient ∂/∂D (as D)
        (:meth:`morphoshell.numerics.kkt_derivatives.KKTDerivatives.curvature_theta`).
        The second derivatives of D itself are the caller's (they need the parameters).
        """
        return self._kkt.curvature_theta(x, lam, D, T, mu_F, mu_dz, mu_dS)

    def kkt_residual_theta(self, x, lam, D, T) -> ca.MX:
        """∂F/∂θ = (∂F/∂D) T of the KKT residual F = (∇f + Jᵀλ, g), cell by cell.

        T = ∂D/∂θ (rows as D, k columns).  (n + m) × k, sparse rows.
        """
        return self._kkt.residual_theta(x, lam, D, T)

    def kkt_residual_theta_numeric(self, x: np.ndarray, lam: np.ndarray, D: np.ndarray,
                                   T: np.ndarray) -> np.ndarray:
        """:meth:`kkt_residual_theta`'s (∂F/∂D) T in numbers, (n + m) × k, dense
        (:meth:`morphoshell.numerics.kkt_derivatives.KKTDerivatives.residual_theta_numeric`)."""
        return self._kkt.residual_theta_numeric(x, lam, D, T)
