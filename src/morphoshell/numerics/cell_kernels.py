"""One cell's share of the NLP and of the Newton system, as SX kernels, compiled to C once.

Each cell's energy terms and constraints depend on its 3S + 2 local unknowns
z_c = (r at its S + 1 points, ψ at them, f_s at its S Gauss points) and on
parameter-only *data* at its Gauss points, laid out as
:data:`~morphoshell.model.layouts.CELL_DATA` (:mod:`morphoshell.numerics.parameter_data`).
The family and the theory enter only through those data, so the kernels of
:func:`cell_functions` depend on the number of stages alone and every structure
shares them: the paper's energy (:func:`morphoshell.model.energy.pointwise`) at the
Gauss points, its gradient, the collocated compatibility r' = f_s cos ψ and its
Jacobian, the Lagrangian's Hessian, the pointwise fields of a result, the cell's
KKT residual and its derivative in the data, and the cell's block of the certified
Newton system (:func:`cell_functions`, ``"newton"``, ``"newton_rhs"``).

The transcription maps these kernels over the cells and gathers their values into
place (:mod:`morphoshell.numerics.gathers`, :mod:`morphoshell.numerics.newton_assembly`).
Ipopt's callbacks, Newton's steps and the results evaluate them many times, so
:func:`compiled_cell_functions` compiles them to C, once per machine, and a later
process finds the library by a hash of the package's source without building a
single expression (:func:`_kernel_index`).
"""
from __future__ import annotations

import logging
import os
import platform
import shutil
import sys
from functools import lru_cache
from hashlib import blake2b
from pathlib import Path

import casadi as ca
import numpy as np

from .._runtime import IMPORTED_NS
from .._runtime.compiled import CFLAGS, block_function, compiled_library, kernel_cache_dir, renamed
from ..model.energy import LOCAL_OUTPUTS, optimal_controls, pointwise
from ..model.layouts import CELL_DATA, INTRINSIC
from .scheme import collocation

__all__ = ["COMPILED_KERNELS", "BLOCKED_KERNELS", "NEWTON_EPSILON", "PACKAGE", "NODE_OUTPUTS",
           "cell_functions",
           "compiled_cell_functions", "kernel_cache_dir"]

_log = logging.getLogger("morphoshell")

#: Cell kernels that are compiled to C (the evaluations of Ipopt's callbacks
#: and of results); the rest of :func:`cell_functions` stays in CasADi (the
#: total energy of results comes from the fields).
COMPILED_KERNELS = ("f", "g", "grad", "jac", "hess", "fields", "ends", "node", "newton",
                    "newton_rhs", "kkt_data")

#: Compiled kernels also compiled in blocks of cells, as ``<name>_block``
#: (:func:`morphoshell._runtime.compiled.block_map`), used on meshes of at least
#: :data:`~morphoshell._runtime.compiled.BLOCKED_POINTS` cells: the chord step's
#: right-hand side, a small kernel whose per-call overhead the blocks save (tuned by
#: scripts/bench_equilibrium.py: warm re-solves).  The others stay cell by cell: their
#: own work dominates, and padding their inputs would add to every build.
BLOCKED_KERNELS = ("newton_rhs",)

#: Relative size ε of the (λ, λ) block −ε W⁻¹ of the Newton system
#: (:meth:`morphoshell.numerics.discretisation.Discretisation.newton_system`).
NEWTON_EPSILON = 1e-8

#: Outputs of the ``"node"`` kernel of :func:`cell_functions`, in order: the controls
#: f_s and ψ', then the shape-dependent :data:`~morphoshell.model.energy.LOCAL_OUTPUTS`.
NODE_OUTPUTS = ("f_s", "dpsi", *LOCAL_OUTPUTS[:len(LOCAL_OUTPUTS) - len(INTRINSIC)])

#: The package whose source the kernel index hashes (:func:`_kernel_index`): all of it,
#: every subpackage, since the kernels are built from modules across the layers.
PACKAGE = Path(__file__).resolve().parents[1]


@lru_cache(maxsize=8)
def cell_functions(stages: int) -> dict[str, ca.Function]:
    """Values, gradients and the Lagrangian's triu Hessian of one cell (SX).

    The family and the theory enter only through the cell data D (profiles,
    η and coefficients are evaluated by the structure's ``pre`` function), so
    these depend on the number of stages alone and every structure shares them.

    Returns
    -------
    dict of str to casadi.Function
        With z (3S + 2,) the cell's unknowns, D (n_D S,) its data, σ a scalar
        and λ (S,) its multipliers: ``"f"`` (z, D) -> the scaled energy ℓ;
        ``"energy"`` the energy itself; ``"g"`` the S collocated constraints;
        ``"grad"`` (ℓ, ∇ℓ); ``"jac"`` (g, vec ∂g/∂z); ``"hess"`` (z, D, σ, λ) ->
        the upper triangle of ∇²(σ ℓ + λᵀg), row by row; ``"fields"`` the
        pointwise fields at the S Gauss points, one column each; ``"kkt"`` (z, D, λ)
        -> (∇ℓ + Jᵀλ, g) (4S + 2,) and ``"kkt_data"`` its ∂/∂D, dense;
        ``"newton"`` and ``"newton_rhs"`` (:func:`_newton_cells`); ``"ends"`` and
        ``"node"``, the nodal fields (:func:`_node_functions`).
    """
    S = stages
    _, _, values, derivs, _, _ = collocation(S)
    n_D = len(CELL_DATA)
    off = CELL_DATA.after(INTRINSIC)
    z, D = ca.SX.sym("z", 3 * S + 2), ca.SX.sym("D", n_D * S)
    sigma, lam = ca.SX.sym("sigma"), ca.SX.sym("lam", S)
    zr, zp, zf = z[:S + 1], z[S + 1:2 * S + 2], z[2 * S + 2:]
    V, Dv = ca.DM(values), ca.DM(derivs)
    energy, g, fields = 0, [], []
    for k in range(S):
        Dk = D[k * n_D:(k + 1) * n_D]
        d = CELL_DATA.unpack(Dk)
        I = Dk[off:]
        r_k, psi_k = ca.dot(V[k, :].T, zr), ca.dot(V[k, :].T, zp)
        dr_k, dpsi_k = ca.dot(Dv[k, :].T, zr) / d["ds"], ca.dot(Dv[k, :].T, zp) / d["ds"]
        point = pointwise(r_k, psi_k, zf[k], dpsi_k, I, d["h"])
        energy += d["weight"] * d["ds"] * point["L"]
        g.append(dr_k - zf[k] * ca.cos(psi_k))
        n_shape = len(LOCAL_OUTPUTS) - len(INTRINSIC)
        fields.append(ca.vertcat(d["s"], d["ds"], d["weight"], r_k, psi_k, zf[k], dpsi_k,
                                 *[point[name] for name in LOCAL_OUTPUTS[:n_shape]], I))
    ell = energy * CELL_DATA.unpack(D[:n_D])["scale"]
    g = ca.vertcat(*g)
    H = ca.hessian(sigma * ell + ca.dot(lam, g), z)[0]
    kkt = ca.vertcat(ca.gradient(ell, z) + ca.mtimes(ca.jacobian(g, z).T, lam), g)
    ku, lu = np.triu_indices(3 * S + 2)
    scale = CELL_DATA.unpack(D[:n_D])["scale"]
    return {
        **_newton_cells(z, D, lam, kkt[:3 * S + 2], g, ca.substitute(H, sigma, 1.0)),
        **_node_functions(z, D, lam, kkt, scale),
        "f": ca.Function("cell_f", [z, D], [ell]),
        "energy": ca.Function("cell_energy", [z, D], [energy]),
        "g": ca.Function("cell_g", [z, D], [g]),
        "grad": ca.Function("cell_grad", [z, D], [ell, ca.gradient(ell, z)]),
        "jac": ca.Function("cell_jac", [z, D], [g, ca.vec(ca.jacobian(g, z))]),
        "hess": ca.Function("cell_hess", [z, D, sigma, lam],
                            [ca.vertcat(*[H[int(i), int(j)] for i, j in zip(ku, lu)])]),
        "fields": ca.Function("cell_fields", [z, D], [ca.horzcat(*fields)]),
        # the cell's KKT residual (∇ℓ + Jᵀλ, g) and its ∂/∂D, dense (parametric derivatives)
        "kkt": ca.Function("cell_kkt", [z, D, lam], [kkt]),
        "kkt_data": ca.Function("cell_kkt_data", [z, D, lam], [ca.densify(ca.jacobian(kkt, D))]),
    }


def _node_functions(z, D, lam, kkt, scale) -> dict[str, ca.Function]:
    """The kernels of the fields at the mesh nodes, to the scheme's order.

    At the Gauss points f_s and ψ' converge at order 2S − 1 (3 at S = 2) and the
    nodal r, ψ at order 2S; so do the costates at the nodes.  Those are the
    multipliers of the continuity of r and ψ across a node, which the layout builds
    in by sharing the node's unknowns: a cell's own share of the Lagrangian's
    gradient in its end node's r and ψ, the same from either side at a solution
    (their sum is the KKT residual).  ``"ends"`` ``(z, D, λ) -> (λ_r, λ_ψ at the
    cell's first node, λ_r, λ_ψ at its last)`` gives them, in the energy's units
    (the objective's scale divided out), signed as the costates of the
    boundary-value reference (λ_r 2π times the radial force per radian, λ_ψ 2π times
    minus the bending moment).  ``"node"`` ``((r, ψ, λ_r, λ_ψ), I, h) -> NODE_OUTPUTS``
    solves Pontryagin's ∂H/∂(f_s, ψ') = 0 for the controls there
    (:func:`~morphoshell.model.energy.optimal_controls`, as the boundary-value
    reference does) and evaluates the pointwise fields of
    :func:`~morphoshell.model.energy.pointwise` with them: fields of order 2S at the
    nodes (documentation: "Solution routes", accuracy of the fields).  I is the node's
    :data:`~morphoshell.model.layouts.INTRINSIC` data; off the axis only (ρ > 0).
    """
    S = lam.shape[0]
    ends = ca.vertcat(kkt[0], kkt[S + 1], -kkt[S], -kkt[2 * S + 1]) / scale
    y, I, h = ca.SX.sym("y", 4), ca.SX.sym("I", len(INTRINSIC)), ca.SX.sym("h")
    f, u = ca.SX.sym("f_s"), ca.SX.sym("dpsi")
    _, w = optimal_controls(pointwise(y[0], y[1], f, u, I, h)["L"], f, u, y[1], y[2], y[3])
    point = pointwise(y[0], y[1], w[0], w[1], I, h)
    return {"ends": ca.Function("cell_ends", [z, D, lam], [ends]),
            "node": ca.Function("cell_node", [y, I, h], [ca.vertcat(
                w, *[point[name] for name in NODE_OUTPUTS[2:]])])}


def _newton_cells(z, D, lam, dual, g, H) -> dict[str, ca.Function]:
    """One cell's share of the certified Newton system
    (:meth:`morphoshell.numerics.discretisation.Discretisation.newton_system`).

    Both kernels take the cell's unknowns and multipliers as one input
    (z, λ) of L = 4S + 2 local slots, as gathered from the cell order u
    (:mod:`morphoshell.numerics.cell_order`).  ``"newton"``: weights
    W_k = ρ Σ_l |H_ll| / ‖∇g_k‖² (the cell's Hessian scale per unit of the
    constraint's gradient; any W > 0 is valid), the penalised Hessian
    M = H + Jᵀ W J, and the local block [[M, Jᵀ], [J, −ε W⁻¹]] as its upper
    triangle; the stationarity residual ∇ℓ + Jᵀλ (zeros in λ's slots), the
    right-hand side −(∇ℓ + Jᵀ(λ + W g), g), g and W.  ``"newton_rhs"``: the
    same residual and right-hand side for given weights W, without the
    Hessian (:meth:`morphoshell.numerics.discretisation.Discretisation.newton_rhs`).
    The triangle, residual and right-hand side end with a zero, dense: the value that
    the assembly takes where a slot has no second cell
    (:func:`morphoshell.numerics.cell_order.assembly`).
    """
    S, n_z = g.shape[0], z.shape[0]
    rho, w_in = ca.SX.sym("rho"), ca.SX.sym("w", S)
    zl = ca.SX.sym("zl", n_z + S)
    Jc = ca.jacobian(g, z)
    w = rho * ca.sum1(ca.fabs(ca.diag(H))) / ca.fmax(ca.sum2(Jc * Jc), 1e-300)
    M = H + ca.mtimes(Jc.T, ca.mtimes(ca.diag(w), Jc))
    K = ca.blockcat([[M, Jc.T], [Jc, ca.diag(-NEWTON_EPSILON / w)]])
    ku, lu = np.triu_indices(K.shape[0])
    zero = ca.SX.zeros(1)

    def residual(weights):     # ∇ℓ + Jᵀλ and the right-hand side −(∇ℓ + Jᵀ(λ + W g), g)
        return [ca.densify(ca.vertcat(dual, ca.SX.zeros(S), zero)),
                ca.densify(ca.vertcat(-(dual + ca.mtimes(Jc.T, weights * g)), -g, zero))]

    def local(name, inputs, outputs):      # (z, λ) as one input
        f = ca.Function("local", [z, D, lam, inputs[-1]], outputs)
        return ca.Function(name, [zl, D, inputs[-1]], f(zl[:n_z], D, zl[n_z:], inputs[-1]))

    tri = ca.densify(ca.vertcat(*[K[int(i), int(j)] for i, j in zip(ku, lu)], zero))
    return {"newton": local("cell_newton", [rho], [tri, *residual(w), g, w]),
            "newton_rhs": local("cell_newton_rhs", [w_in], [*residual(w_in), g])}


# -- the compiled library and its index ---------------------------------------------

@lru_cache(maxsize=8)
def compiled_cell_functions(stages: int) -> dict[str, ca.Function] | None:
    """The cell kernels of ``stages`` as compiled C (``casadi.external``), or None.

    The kernels depend on the number of stages alone, so each is compiled
    once per machine (C code generated by CasADi, compiled by ``$CC`` or
    ``cc``, a few seconds) and cached in :func:`kernel_cache_dir` under a hash
    of the serialised expressions, the compiler and CasADi's version; later
    processes load it directly, finding it by a hash of the package's source
    (:func:`_kernel_index`) without building the expressions.  Compiled, they
    evaluate several times faster than CasADi's SX virtual machine.  None, and
    the pure-CasADi kernels are used, if ``MORPHOSHELL_COMPILE=0``, no compiler
    is found, or anything fails (logged at debug level): nothing depends on a
    compiler.

    Returns
    -------
    dict of str to casadi.Function or None
        The kernels of :data:`COMPILED_KERNELS`, and ``<name>_block`` for
        :data:`BLOCKED_KERNELS`, with the signatures of :func:`cell_functions`.
    """
    if os.environ.get("MORPHOSHELL_COMPILE", "1") == "0":
        return None
    compiler = shutil.which(os.environ.get("CC", "cc"))
    if compiler is None:
        return None
    names = {k: f"morphoshell_cell{stages}_{k}" for k in COMPILED_KERNELS}
    names.update({f"{k}_block": f"morphoshell_cell{stages}_{k}_block" for k in BLOCKED_KERNELS})
    # Fast path: the library recorded for this exact source, without building the
    # expressions (most of a fresh process's first solve, otherwise)
    index = _kernel_index(stages, compiler)
    kernels = _indexed_kernels(index, stages, names)
    if kernels is not None:
        return kernels
    try:
        return _compile_cell_functions(stages, names, compiler, index)
    except Exception as exc:     # no working compiler, read-only cache, ...: stay in CasADi
        _log.debug("cell kernels not compiled (%s: %s); using CasADi's virtual machine",
                   type(exc).__name__, exc)
        return None


def _indexed_kernels(index: Path | None, stages: int, names: dict) -> dict | None:
    """The kernels of the library that ``index`` names, or None (no index, or no library)."""
    try:
        if index is not None and index.exists():
            library = index.parent / index.read_text().strip()
            if library.name.startswith(f"cells{stages}_") and library.exists():
                return {k: ca.external(name, str(library)) for k, name in names.items()}
    except Exception as exc:     # unreadable index or library: the full path decides
        _log.debug("kernel index %s not used (%s: %s)", index, type(exc).__name__, exc)
    return None


def _compile_cell_functions(stages: int, names: dict, compiler: str,
                            index: Path | None) -> dict[str, ca.Function]:
    """The full path of :func:`compiled_cell_functions`: build the expressions, compile (or
    find) their library, load it, and record it in ``index``.  Raises on any failure."""
    cell = cell_functions(stages)
    # Symbols named per scheme, so that libraries of different stages never clash.
    named = {k: renamed(cell[k], names[k]) for k in COMPILED_KERNELS}
    named.update({f"{k}_block": block_function(named[k], names[f"{k}_block"])
                  for k in BLOCKED_KERNELS})
    # nlpsol builds the reverse derivative of f and g (unused with the
    # exact derivatives supplied, but it must exist): CasADi finds it in
    # the library as adj1_<name>.
    adjoints = [renamed(named[k].reverse(1), f"adj1_{named[k].name()}") for k in ("f", "g")]
    functions = [*named.values(), *adjoints]
    path = compiled_library(f"cells{stages}", functions, compiler)
    kernels = {k: ca.external(f.name(), str(path)) for k, f in named.items()}
    if index is not None:
        try:    # atomic, as the library; a read-only cache only loses the fast path
            part = index.with_suffix(f".{os.getpid()}.part")
            part.write_text(path.name)
            os.replace(part, index)
        except OSError as exc:
            _log.debug("kernel index %s not written (%s)", index, exc)
    return kernels


def _kernel_index(stages: int, compiler: str) -> Path | None:
    """The file naming the compiled kernels of ``stages`` for this exact source, or None.

    Its name hashes every module of the package (:data:`PACKAGE`, all
    subpackages: the kernels are built from them), the versions of CasADi,
    NumPy and Python, the machine, the compiler and its flags: with any of
    them changed the expressions are built and hashed again
    (:func:`compiled_cell_functions`), and the index rewritten.  None when
    the package's source cannot be read or changed since the package was
    imported.
    """
    try:
        package = PACKAGE
        sources = sorted(package.rglob("*.py"))
        # A module edited after this process imported the package may differ
        # from the code in memory, which built (or would be given) the kernels;
        # 1 s of margin for coarse file times.
        if not sources or any(f.stat().st_mtime_ns > IMPORTED_NS - 10**9 for f in sources):
            return None
        # (BLAKE2: about half SHA-256's time on the package's source)
        key = blake2b("\0".join([str(stages), compiler, *CFLAGS, ca.__version__,
                                 np.__version__, sys.version, platform.machine()])
                      .encode(), digest_size=10)
        for source in sources:
            key.update(b"\0" + source.relative_to(package).as_posix().encode() + b"\0"
                       + source.read_bytes())
        return kernel_cache_dir() / f"cells{stages}_{key.hexdigest()}.source"
    except OSError:
        return None
