"""The discrete shape as CasADi expressions: points, cell polynomials, arclength.

A transcription's unknowns x (with the parameters p and anchors q) fix the whole
shape: r and ψ are the cells' Lagrange polynomials through their points, and z and
the deformed arclength S follow by exact integration of z' = f_s sin ψ and S' = f_s
over the Gauss interpolant of f_s in each cell (f_s = dS/ds and the tangent angle
ψ of the paper's Methods, Eq. 5).  :class:`SymbolicShape` gives them at the points
and anywhere inside a cell; the per-cell kernels here (:func:`cell_state`,
:func:`arclength_point`, :func:`increments`) are SX Functions of one cell's
unknowns, shared by every mesh of a scheme.  The observables of
:mod:`morphoshell.solvers.observables` are built from these, so that forward
evaluation, parametric derivatives and fits share one definition.
"""
from __future__ import annotations

from functools import lru_cache
from typing import TYPE_CHECKING

import casadi as ca
import numpy as np

from .scheme import collocation, horner, lagrange, within_cells

if TYPE_CHECKING:
    from .discretisation import Discretisation

__all__ = ["SymbolicShape", "cell_state", "arclength_point", "increments"]


class SymbolicShape:
    """The shape of a :class:`~morphoshell.numerics.discretisation.Discretisation` as
    expressions of (x, p).

    ``points`` holds s, r, ψ, z and the deformed arclength S at all points
    (nodes and interior interpolation points); z is fixed by z(s_0) = z₀(s_0)
    (the undeformed height) and S(s_0) = 0.  :meth:`at` evaluates the cell
    polynomials anywhere, :meth:`at_arclength_selected` finds the material
    points at given deformed arclengths.

    Parameters
    ----------
    disc : Discretisation
    x, p, q : casadi.MX
        Unknowns (n,), physical parameters and anchors.
    """

    def __init__(self, disc: "Discretisation", x, p, q):
        self.disc = d = disc
        S = d.stages
        self.Z = Z = d.cell_unknowns(x)
        self.p, self.q = p, q
        self.a, self.b = a, b = d.shell_ends(p)
        self.s_nodes = d.nodes(p, q)
        self.f_g, self.psi_g = d.gauss_values(Z)
        ds = (self.s_nodes[1:] - self.s_nodes[:-1])[np.repeat(np.arange(d.layout.cells),
                                                                S).tolist()]
        self.points = {
            "s": within_cells(self.s_nodes, np.arange(S) / S),
            "r": ca.vertcat(ca.vec(Z[:S, :]), Z[S, -1]),
            "psi": ca.vertcat(ca.vec(Z[S + 1:2 * S + 1, :]), Z[2 * S + 1, -1]),
            "z": d.geometry.z0(a) + d.integrate_to_points(self.f_g * ca.sin(self.psi_g), ds=ds),
            "S": d.integrate_to_points(self.f_g, ds=ds),
        }

    def increments(self) -> tuple:
        """(Δz, ΔS) over every cell: ∫ f_s sin ψ ds and ∫ f_s ds by the Gauss rule.

        Returns
        -------
        dz, dS : casadi.MX, shape (cells, 1)
        """
        S, cells = self.disc.stages, self.disc.layout.cells
        ds = self.s_nodes[1:] - self.s_nodes[:cells]
        f = self.Z[2 * S + 2:, :]
        psi_g = ca.mtimes(ca.DM(collocation(S)[2]), self.Z[S + 1:2 * S + 2, :])
        w = ca.DM(self.disc.weights).T
        return (ds * ca.mtimes(w, f * ca.sin(psi_g)).T, ds * ca.mtimes(w, f).T)

    def cell_bounds(self, cell: int):
        """(s at the cell's first node, its width in s)."""
        return self.s_nodes[cell], self.s_nodes[cell + 1] - self.s_nodes[cell]

    def _in_cell(self, cell: int, tau) -> dict:
        _, ds = self.cell_bounds(cell)
        first = cell * self.disc.stages
        out = cell_state(self.disc.stages)(self.Z[:, cell], ds, self.points["z"][first],
                                           self.points["S"][first], tau)
        return dict(zip(("r", "psi", "z", "S"), out))

    def at(self, cell: int, s_star) -> dict:
        """(r, ψ, z, S) at the material point ``s_star`` by the polynomials of ``cell``.

        ``s_star`` may be an expression of p.  The cell should contain it; a
        point just outside is extrapolated smoothly.
        """
        s0, ds = self.cell_bounds(cell)
        tau = (s_star - s0) / ds
        return {**self._in_cell(cell, tau), "s": s_star}

    def at_arclength_selected(self, select, targets) -> dict:
        """(s, r, ψ, z) at deformed arclengths ``targets`` (a row), each in the cell
        chosen by the corresponding column of the one-hot matrix ``select``
        (cells × points): :func:`arclength_point` mapped over the points."""
        S = self.disc.stages
        n = targets.shape[1]
        cells = self.disc.layout.cells
        first = (np.arange(cells) * S).tolist()
        lo, hi = self.s_nodes[:cells], self.s_nodes[1:]
        starts = ca.horzcat(lo, hi - lo, self.points["z"][first], self.points["S"][first])
        chosen = ca.mtimes(select.T, starts)                    # (points, 4)
        Zc = ca.mtimes(self.Z, select)                          # (3S + 2, points)
        out = arclength_point(S).map(n)(Zc, chosen[:, 0].T, chosen[:, 1].T, chosen[:, 2].T,
                                         chosen[:, 3].T, targets)
        return dict(zip(("s", "r", "psi", "z"), out))


@lru_cache(maxsize=8)
def cell_state(stages: int) -> ca.Function:
    """``(z_c, Δs, z_first, S_first, τ) -> (r, ψ, z, S)`` inside one cell.

    r and ψ by the cell's Lagrange polynomials, z and the deformed arclength
    S by exact integration of the Gauss interpolants of f_s sin ψ and f_s
    from the cell's first node (where they are ``z_first``, ``S_first``).
    z_c is the cell's 3S + 2 local unknowns (r, ψ at its points, f_s at its
    Gauss points); every output is a scalar.
    """
    S = stages
    tau_g, _, values, _, _, anti = collocation(S)
    nodes = np.linspace(0.0, 1.0, S + 1)
    zc, ds, z0, S0, tau = (ca.SX.sym("z_c", 3 * S + 2), ca.SX.sym("ds"), ca.SX.sym("z0"),
                           ca.SX.sym("S0"), ca.SX.sym("tau"))
    ell = [horner(lagrange(nodes, l).coef, tau) for l in range(S + 1)]
    Lam = [horner(c, tau) for c in anti]   # ∫₀^τ of the Gauss-point basis
    f = zc[2 * S + 2:]
    psi_g = ca.mtimes(ca.DM(values), zc[S + 1:2 * S + 2])
    r = sum(ell[l] * zc[l] for l in range(S + 1))
    psi = sum(ell[l] * zc[S + 1 + l] for l in range(S + 1))
    z = z0 + ds * sum(Lam[k] * f[k] * ca.sin(psi_g[k]) for k in range(S))
    arclength = S0 + ds * sum(Lam[k] * f[k] for k in range(S))
    return ca.Function("cell_state", [zc, ds, z0, S0, tau], [r, psi, z, arclength],
                       ["z_c", "ds", "z_first", "S_first", "tau"], ["r", "psi", "z", "S"])


@lru_cache(maxsize=8)
def arclength_point(stages: int, newton_steps: int = 6) -> ca.Function:
    """``(z_c, s_first, Δs, z_first, S_first, S*) -> (s, r, ψ, z)`` where S = S* in a cell.

    Newton's method on the cell's deformed arclength S(τ) (degree S, S' = f_s
    Δs > 0) from the linear interpolant, unrolled: a cell's stretch varies
    little, so a few steps reach machine precision, and differentiating the
    converged iteration gives the implicit-function derivative.  Every input
    and output is a scalar but z_c, the cell's 3S + 2 local unknowns.
    """
    S = stages
    tau_g = collocation(S)[0]
    zc, s0, ds, z0, S0, target = (ca.SX.sym("z_c", 3 * S + 2), ca.SX.sym("s0"), ca.SX.sym("ds"),
                                  ca.SX.sym("z0"), ca.SX.sym("S0"), ca.SX.sym("target"))
    state = cell_state(S)
    f = zc[2 * S + 2:]
    S1 = S0 + ds * ca.dot(ca.DM(collocation(S)[1]), f)
    tau = (target - S0) / (S1 - S0)
    basis = [lagrange(tau_g, k).coef for k in range(S)]
    for _ in range(newton_steps if S > 1 else 0):   # S is linear in τ for S = 1
        value = state(zc, ds, z0, S0, tau)[3] - target
        slope = ds * sum(horner(basis[k], tau) * f[k] for k in range(S))
        tau = tau - value / slope
    r, psi, z, _ = state(zc, ds, z0, S0, tau)
    return ca.Function("arclength_point", [zc, s0, ds, z0, S0, target],
                       [s0 + ds * tau, r, psi, z])


@lru_cache(maxsize=8)
def increments(stages: int) -> ca.Function:
    """``(z_c, Δs) -> (Δz, ΔS)``: ∫ f_s sin ψ ds and ∫ f_s ds over one cell (Gauss rule).

    z_c is the cell's 3S + 2 local unknowns, Δs its width; both outputs are scalars.
    """
    S = stages
    _, w, values, _, _, _ = collocation(S)
    zc, ds = ca.SX.sym("z_c", 3 * S + 2), ca.SX.sym("ds")
    f = zc[2 * S + 2:]
    psi_g = ca.mtimes(ca.DM(values), zc[S + 1:2 * S + 2])
    return ca.Function("increments", [zc, ds], [ds * ca.dot(ca.DM(w), f * ca.sin(psi_g)),
                                                ds * ca.dot(ca.DM(w), f)])
