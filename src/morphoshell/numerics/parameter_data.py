"""The NLP's parameters: the data at every Gauss point, from the physical parameters.

The cell kernels (:mod:`morphoshell.numerics.cell_kernels`) see a problem only through
its parameter-only *data* D at the Gauss points, laid out as
:data:`~morphoshell.model.layouts.CELL_DATA`: the point s_k, its cell's width Δs,
the Gauss weight, the objective's scale and h, then the intrinsic data of
:func:`morphoshell.model.energy.intrinsic_function` (the undeformed shell, the
growth profiles, η and the coefficients of the paper's energy, Methods, Eq. 7).  D is
the NLP's parameter vector: it is computed once per solve, so Ipopt's callbacks
and Newton's steps never re-evaluate profiles or coefficients.

The nodes are material points s_i of the parametric map of
:mod:`morphoshell.numerics.mesh` (Σ, P and the knots move them), so D depends on
the parameters p and the anchors q through the mesh as well.
:class:`ParameterData` gives D three ways, all the same numbers:

* :attr:`ParameterData.numeric`, for evaluation: one compiled kernel per cell fed the
  mesh's numbers at its two nodes (:func:`_data_cell`), a handful of CasADi
  operations for any mesh;
* :attr:`ParameterData.function`, differentiable: the mesh's MX expressions mapped
  through the per-point data function (:func:`pre_function`);
* its derivatives :attr:`ParameterData.jacobian` and :attr:`ParameterData.hessian`
  by the chain rule one Gauss point at a time (:func:`_pre_chain`,
  :func:`_pre_curvature`), compiled where possible, instead of differentiating the
  mapped graph as a whole.
"""
from __future__ import annotations

from functools import cached_property, lru_cache

import casadi as ca
import numpy as np

from .._runtime.buffered import Buffered
from .._runtime.compiled import compiled_point_function, compiled_point_map
from ..model.energy import CACHE_SIZE, intrinsic_function
from ..model.layouts import CELL_DATA, INTRINSIC
from ..model.problem import Structure
from .mesh import Knot, knot_shapes, mapped_points, shell_points
from .scheme import between, collocation, within_cells

__all__ = ["ParameterData", "pre_function", "shell_ends", "knot_positions", "objective_scale"]


class ParameterData:
    """The cell data D(p, q) of one (structure, mesh, stages), evaluated and differentiable.

    Parameters
    ----------
    structure : Structure
    t : ndarray, shape (N + 1,)
        Mesh nodes in [0, 1].
    stages : int
        Gauss points per cell S.
    knots : tuple of Knot
        Nodes of ``t`` at given material points (anchors from q, or the
        family's breakpoints from p).
    p, q : casadi.MX
        Symbols of the physical parameters and of the anchors.

    Attributes
    ----------
    numeric : casadi.Function
        ``(p, q) -> D``, for evaluation, D of shape (n_D cells S,) (n_D = len(CELL_DATA)),
        column-major in (datum, Gauss point).
    """

    def __init__(self, structure: Structure, t: np.ndarray, stages: int,
                 knots: tuple[Knot, ...], p: ca.MX, q: ca.MX):
        self.structure, self.t, self.stages, self.p, self.q = structure, t, stages, p, q
        self.knots = tuple(k.t for k in knots)
        self.sources = tuple((k.source, k.index) for k in knots)
        self.cells = cells = len(t) - 1
        # D for evaluation (no derivatives), from one compiled kernel per cell fed the
        # mesh's numbers at its nodes (_data_cell); the differentiable expressions of the
        # same numbers (parts) are built on first use
        at_nodes = np.vstack([self.t, *knot_shapes(self.t, self.knots)])
        kernel, serialised = _data_cell(structure, self.sources, stages)
        self.numeric = ca.Function(
            "cell_data_numeric", [p, q],
            [ca.vec(compiled_point_map(
                kernel, cells, ca.DM(np.vstack([at_nodes[:, :-1], at_nodes[:, 1:]])),
                ca.vertcat(ca.DM(self.knots + (cells,)), p, q),
                serialised=serialised))],
            ["p", "q"], ["D"])
        self._buffered = None

    def __call__(self, p: np.ndarray, q) -> np.ndarray:
        """D (n_D cells S,) for physical parameters ``p`` and anchors ``q``, in numbers."""
        if self._buffered is None:
            self._buffered = Buffered(self.numeric)
        return self._buffered(p, np.asarray(q, dtype=float))[0]

    def shell_ends(self, p):
        """(Σ, L − P) from the parameter vector (CasADi or NumPy)."""
        return shell_ends(self.structure, p)

    def knot_positions(self, p, q) -> list:
        """Material points of the knots: anchors from q, breakpoints from the parameters."""
        return knot_positions(self.structure, self.sources, p, q)

    def nodes(self, p, q, ends: tuple | None = None):
        """Material points s of the mesh nodes (:func:`morphoshell.numerics.mesh.shell_points`),
        shape (N + 1,); ``ends``: :meth:`shell_ends` of p, if at hand."""
        a, b = self.shell_ends(p) if ends is None else ends
        return shell_points(self.t, a, b, self.knots, self.knot_positions(p, q))

    @cached_property
    def parts(self) -> tuple:
        """(pre, s_gauss, ds, weights, scale, m): the per-point data function and its mesh
        inputs as MX expressions of p, q (for :attr:`function` and its derivatives), m the
        number of Gauss points; built on first use."""
        cells, S = self.cells, self.stages
        tau, w = collocation(S)[:2]
        a, b = ends = self.shell_ends(self.p)
        s_nodes = self.nodes(self.p, self.q, ends)
        ds = (s_nodes[1:] - s_nodes[:-1])[np.repeat(np.arange(cells), S).tolist()]
        s_gauss = within_cells(s_nodes, tau, last=False)
        scale = objective_scale(cells, self.p[self.structure.parameters.index("h")], a, b)
        weights = ca.DM(np.tile(w, cells)).T
        return (pre_function(self.structure)[0], s_gauss, ds, weights, scale, cells * S)

    @cached_property
    def function(self) -> ca.Function:
        """``(p, q) -> D``, differentiable (MX); built on first use.

        Solves evaluate :attr:`numeric`; only fits, observables and parametric
        derivatives differentiate D, so a build makes none of these expressions.
        """
        pre, s_gauss, ds, weights, scale, m = self.parts
        return ca.Function(
            "cell_data", [self.p, self.q],
            [ca.vec(pre.map(m)(s_gauss.T, ds.T, weights, scale, self.p))], ["p", "q"], ["D"])

    @cached_property
    def jacobian(self) -> ca.Function:
        """``(p, q) -> dD/dp`` (dense, n_D cells S × n_p), for evaluation; built on first use.

        By the chain rule, one Gauss point at a time: D_k = pre(s_k, Δs_k, w_k,
        scale, p) with s_k, Δs_k and the scale functions of p (the parametric
        mesh).  A per-point SX kernel (:func:`_pre_chain`) takes the mesh's
        derivatives at its point (small MX Jacobians) and returns the point's
        whole block of dD/dp, in compiled C where available
        (:func:`~morphoshell._runtime.compiled.compiled_point_function`): far
        cheaper than per-point Jacobians in CasADi's virtual machine assembled by
        MX slices, or differentiating the mapped graph as a whole.  Compiled, the
        result has no derivatives.
        """
        pre, s_gauss, ds, weights, scale, m = self.parts
        blocks = _pre_chain(pre_function(self.structure)[1]).map(m)(
            s_gauss.T, ds.T, weights, scale, self.p, *(ca.jacobian(v, self.p).T
                                                      for v in (s_gauss, ds, scale)))
        return ca.Function("cell_data_jacobian", [self.p, self.q], [blocks.T],
                           ["p", "q"], ["dD_dp"])

    @cached_property
    def hessian(self) -> ca.Function:
        """``(p, q, c) -> ∂²(c·D)/∂p²`` (n_p × n_p), for evaluation; built on first use.

        c weighs the cell data D (as D).  Per Gauss point, D_k =
        pre(y_k) with y_k = (s_k, Δs_k, scale, p) and the mesh values s_k, Δs_k
        and the scale functions of p: ∂²(c·D)/∂p² = Σ_k M_kᵀ ∇²(c_k·pre) M_k
        + ∂²/∂p² Σ_k g_k·(s_k, Δs_k, scale)(p), M_k = ∂y_k/∂p and g_k =
        ∂(c_k·pre)/∂(s_k, Δs_k, scale) held fixed in the last term.  The first
        term is one per-point kernel (:func:`_pre_curvature`), compiled where
        possible (as :attr:`jacobian`), the second an MX Hessian of the mesh
        alone: far cheaper than the MX Hessian of the mapped cell data.
        """
        pre, s_gauss, ds, weights, scale, m = self.parts
        n_p = self.p.shape[0]
        # the mesh moves with the parameters it depends on only (a few of a family's),
        # so the per-point kernel's Hessian is taken in those columns alone
        J_mesh = [ca.jacobian(v, self.p) for v in (s_gauss, ds, scale)]
        cols = sorted(set().union(*(set(J.sparsity().get_col()) for J in J_mesh)))
        C = ca.MX.sym("c", len(CELL_DATA) * m)
        H_k, g = _pre_curvature(pre_function(self.structure)[1], tuple(cols)).map(m)(
            s_gauss.T, ds.T, weights, scale, self.p, *(J[:, cols].T for J in J_mesh),
            ca.reshape(C, -1, m))
        g_fixed = ca.MX.sym("g", 3, m)
        frozen = ca.Function("mesh_curvature", [self.p, self.q, g_fixed], [ca.hessian(
            ca.dot(g_fixed[0, :].T, s_gauss) + ca.dot(g_fixed[1, :].T, ds)
            + ca.sum2(g_fixed[2, :]) * scale, self.p)[0]])
        return ca.Function(
            "cell_data_hessian", [self.p, self.q, C],
            [ca.reshape(ca.sum2(H_k), n_p, n_p) + frozen(self.p, self.q, g)],
            ["p", "q", "c"], ["d2cD_dp2"])


def shell_ends(structure: Structure, p):
    """(Σ, L − P) from the parameter vector ``p`` (CasADi or NumPy)."""
    index = structure.parameters.index
    return p[index("cut")], structure.geometry.length - p[index("opening")]


def knot_positions(structure: Structure, knots: tuple[tuple[str, int], ...], p, q) -> list:
    """Material points of the knots, given as (source, index) of
    :class:`~morphoshell.numerics.mesh.Knot`: anchors from q, the family's breakpoints
    from the parameters p (one entry per knot; numbers or CasADi)."""
    if not knots:
        return []
    fam = structure.family
    named = structure.parameters.unpack(p)
    a, b = shell_ends(structure, p)
    bps = fam.breakpoints({n: named[n] for n in fam.parameters}, a, b) \
        if any(source == "breakpoint" for source, _ in knots) else []
    return [q[i] if source == "anchor" else bps[i][0] for source, i in knots]


def objective_scale(cells, h, cut, end):
    """The factor on the energy in the objective handed to the solvers: cells/(2π h³ (L − P − Σ)).

    Energies range over decades with h (bending ~ h³): dividing by h³ and by
    the mean cell size keeps Ipopt's gradients O(1).
    """
    return cells / (2 * ca.pi * h ** 3 * (end - cut))


@lru_cache(maxsize=CACHE_SIZE)
def pre_function(structure: Structure) -> tuple[ca.Function, str]:
    """``(s_k, Δs_c, w_k, scale, p) -> D_k``: parameter-only data at one Gauss point, and its
    serialisation (the key of its compiled code and derivative kernels).

    Cached per structure, as :func:`~morphoshell.model.energy.intrinsic_function`:
    building and serialising it would otherwise be a noticeable part of every build.

    Returns
    -------
    pre : casadi.Function
        D_k of shape (n_D,), laid out as :data:`~morphoshell.model.layouts.CELL_DATA`.
    serialised : str
    """
    n_p = len(structure.parameters)
    s_k, ds, wk, scale, p = (ca.SX.sym("s"), ca.SX.sym("ds"), ca.SX.sym("wk"),
                             ca.SX.sym("scale"), ca.SX.sym("p", n_p))
    I = intrinsic_function(structure)(s_k, p)
    data = {"s": s_k, "ds": ds, "weight": wk, "scale": scale,
            "h": structure.parameters.unpack(p)["h"]}
    off = CELL_DATA.after(INTRINSIC)
    pre = ca.Function("pre", [s_k, ds, wk, scale, p],
                      [ca.vertcat(*[data[n] for n in CELL_DATA.names[:off]], I)])
    return pre, pre.serialize()


@lru_cache(maxsize=CACHE_SIZE)
def _data_cell(structure: Structure, knots: tuple[tuple[str, int], ...],
               stages: int) -> tuple[ca.Function, str]:
    """``(c, (t_knots, cells, p, q)) -> D_c``: the parameter data at one cell's S Gauss points
    (point after point) from the mesh's numbers at its two nodes, and its serialisation.

    c = (t_c and the knots' shapes there, then the same at t_c+1) (:func:`knot_shapes`),
    t_knots the knots' places in t and ``knots`` their (source, index); the
    inputs shared by all cells are one vector (a map with several inputs, some
    of them empty, builds far slower).  The parametric map
    (:func:`~morphoshell.numerics.mesh.mapped_points`) at the cell's nodes, the points
    between them (:func:`~morphoshell.numerics.scheme.within_cells`), the cell's width
    and the objective's scale, then :func:`pre_function`'s data, in the same operations
    as the expressions of :attr:`ParameterData.parts`, so that both give the same bits.
    One kernel per structure, kind of knots and number of stages, mapped over the
    cells: a build makes a handful of CasADi operations for D where the mesh's
    expressions took some twenty, and hands it two numbers a cell (with no knots)
    where a kernel per point took 4S.  The kernel is compiled.
    """
    pre, _ = pre_function(structure)
    tau, w = collocation(stages)[:2]
    n_k, n_p = len(knots), len(structure.parameters)
    c = ca.SX.sym("c", 2 + 2 * n_k)
    shared = ca.SX.sym("shared", n_k + 1 + n_p + sum(source == "anchor" for source, _ in knots))
    t_k, cells, p, q = (shared[:n_k], shared[n_k], shared[n_k + 1:n_k + 1 + n_p],
                        shared[n_k + 1 + n_p:])
    a, b = shell_ends(structure, p)
    where = knot_positions(structure, knots, p, q)
    t_knots = [t_k[j] for j in range(n_k)]
    s0, s1 = (mapped_points(c[i * (1 + n_k)], [c[i * (1 + n_k) + 1 + j] for j in range(n_k)],
                            a, b, t_knots, where) for i in (0, 1))
    h = structure.parameters.unpack(p)["h"]
    scale = objective_scale(cells, h, a, b)
    D = ca.vertcat(*[pre(between(s0, s1, tau[k]), s1 - s0, w[k], scale, p)
                     for k in range(stages)])
    f = ca.Function("cell_data_cell", [c, shared], [D])
    return f, f.serialize()


@lru_cache(maxsize=16)
def _pre_chain(pre_serialised: str) -> ca.Function:
    """The per-point kernel of :attr:`ParameterData.jacobian` for the data function ``pre``.

    ``(s_k, Δs_k, w_k, scale, p, ∂s_k/∂p, ∂Δs_k/∂p, ∂scale/∂p) -> (dD_k/dp)ᵀ``,
    compiled where possible.  Cached on ``pre`` (serialised), so that the
    meshes of one problem structure (a fit's coarse and fine meshes, every
    fit of a campaign) build and serialise it once.
    """
    pre = ca.Function.deserialize(pre_serialised)
    args = [pre.sx_in(i) for i in range(pre.n_in())]
    s, dsk, _, sc, p = args
    n_p = p.shape[0]
    mesh = [ca.SX.sym(name, n_p) for name in ("ds_dp", "dDs_dp", "dscale_dp")]
    D = pre(*args)
    block = (ca.jacobian(D, p)
             + ca.mtimes(ca.jacobian(D, ca.vertcat(s, dsk, sc)), ca.horzcat(*mesh).T))
    # transposed: the map puts the points' blocks side by side, dD/dp stacks them
    return compiled_point_function(ca.Function("pre_chain", [*args, *mesh],
                                               [ca.densify(block.T)]))


@lru_cache(maxsize=16)
def _pre_curvature(pre_serialised: str, cols: tuple[int, ...]) -> ca.Function:
    """The per-point kernel of :attr:`ParameterData.hessian` (the mesh moving in ``cols``).

    ``(s_k, Δs_k, w_k, scale, p, mesh derivatives in cols, c_k) -> (vec M_kᵀ ∇²φ M_k,
    ∂φ/∂(s_k, Δs_k, scale))`` with φ = c_k·pre, M_kᵀ ∇²φ M_k as the Hessian
    of φ along y_k + M_k δ; compiled where possible, cached as
    :func:`_pre_chain` (building it, and serialising it for the compiled
    library's key, would otherwise cost every mesh).
    """
    pre = ca.Function.deserialize(pre_serialised)
    args = [pre.sx_in(i) for i in range(pre.n_in())]
    s, dsk, _, sc, p = args
    n_p = p.shape[0]
    c = ca.SX.sym("c", pre.size1_out(0))
    phi = ca.dot(c, pre(*args))
    mesh = [ca.SX.sym(name, len(cols)) for name in ("ds_dp", "dDs_dp", "dscale_dp")]
    delta = ca.SX.sym("delta", n_p)
    moved = [v + ca.dot(dv, delta[list(cols)]) for v, dv in zip((s, dsk, sc), mesh)]
    phi_d = ca.substitute(phi, ca.vertcat(s, dsk, sc, p), ca.vertcat(*moved, p + delta))
    H = ca.substitute(ca.hessian(phi_d, delta)[0], delta, ca.SX.zeros(n_p))
    return compiled_point_function(ca.Function(
        "pre_curvature", [*args, *mesh, c],
        [ca.densify(ca.vec(H)), ca.densify(ca.gradient(phi, ca.vertcat(s, dsk, sc)))]))
