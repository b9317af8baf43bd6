"""The certified Newton system, assembled in cell order from one kernel per cell.

The Newton back end (:mod:`morphoshell.numerics.newton`) solves

    K = [[M, Jᵀ], [J, −Δ]],   M = ∇²ℒ + Jᵀ W J,   Δ = ε W⁻¹,
    rhs = −(∇f + Jᵀ(λ + W g), g),

with weights W > 0 per constraint.  Each cell's share (its triangle of K, its part
of the residual and right-hand side, W) is one kernel of
:func:`morphoshell.numerics.cell_kernels.cell_functions` (``"newton"``,
``"newton_rhs"``), mapped over the cells; the unknowns are gathered from the cell
order u of (x, λ) and the shares summed into place by the periodic index tables of
:func:`morphoshell.numerics.cell_order.assembly` (:func:`~morphoshell.numerics.gathers.summed`).
The chord step's right-hand side, evaluated once per warm start, runs the kernel in
compiled blocks of cells on large meshes
(:data:`~morphoshell.numerics.cell_kernels.BLOCKED_KERNELS`).
"""
from __future__ import annotations

import casadi as ca

from .._runtime.compiled import block_map
from .cell_order import Assembly, CellOrder
from .gathers import summed

__all__ = ["newton_system", "newton_rhs"]


def newton_system(kernel: ca.Function, order: CellOrder, a: Assembly, D: ca.MX) -> ca.Function:
    """``(u, D, ρ) -> (K, rhs, ‖∇f + Jᵀλ‖∞, ‖g‖∞, ‖λ‖₁, W)`` from the cell kernel ``"newton"``.

    Parameters
    ----------
    kernel : casadi.Function
        The cell kernel ``"newton"`` (compiled or not).
    order : CellOrder
        The cell order u of (x, λ); the system's unknowns are u[lo:hi].
    a : Assembly
        Where the system's entries come from (:func:`morphoshell.numerics.cell_order.assembly`).
    D : casadi.MX
        The symbol of the cell data.

    Returns
    -------
    casadi.Function
        K (n + m) × (n + m), sparse and symmetric, rhs (n + m,), the three
        norms, and W (m,).
    """
    cells = order.cells
    u, rho = ca.MX.sym("u", order.size), ca.MX.sym("rho")
    tri, dual, rhs, g, w = kernel.map(cells)(*_cell_locals(u, a, D, cells), rho)
    K = ca.MX(a.K, summed(tri, a.first, a.pairs))
    return ca.Function("newton_system", [u, D, rho],
                       [K, *_residual(u, dual, rhs, g, order, a), ca.vec(w)])


def newton_rhs(kernel: ca.Function, block: ca.Function | None, order: CellOrder, a: Assembly,
               D: ca.MX) -> ca.Function:
    """``(u, D, W) -> (rhs, ‖∇f + Jᵀλ‖∞, ‖g‖∞, ‖λ‖₁)``: :func:`newton_system`'s right-hand
    side and errors for given weights W (m,), without the Hessian.

    ``kernel`` is the cell kernel ``"newton_rhs"``, ``block`` the same over a block
    of cells (compiled; None to map the kernel cell by cell).  With W those of a
    factorised K, a step with that factorisation is a chord (simplified Newton)
    step (:mod:`morphoshell.numerics.newton`).
    """
    S, cells = order.stages, order.cells
    u, w = ca.MX.sym("u", order.size), ca.MX.sym("w", cells * S)
    dual, rhs, g = block_map(block, kernel, cells,
                             [*_cell_locals(u, a, D, cells), ca.reshape(w, S, cells)])
    return ca.Function("newton_rhs", [u, D, w], _residual(u, dual, rhs, g, order, a))


def _cell_locals(u, a: Assembly, D, cells: int) -> list:
    """(each cell's (z, λ), its data D), a column per cell, from u and the symbol D."""
    return [ca.reshape(u.get_nz(False, a.local), -1, cells), ca.reshape(D, -1, cells)]


def _residual(u, dual, rhs, g, order: CellOrder, a: Assembly) -> list:
    """rhs, ‖∇f + Jᵀλ‖∞, ‖g‖∞ and ‖λ‖₁ from the cells' shares (a column per cell)."""
    lam = ca.MX.binary(ca.OP_MUL, u[order.lo:order.hi], 1 - a.x_mask)
    return [summed(rhs, a.rhs_first, a.rhs_pairs),
            ca.norm_inf(summed(dual, a.rhs_first, a.rhs_pairs)), ca.norm_inf(g),
            ca.norm_1(lam)]
