"""Results of every solution route, and the errors they raise.

An :class:`Equilibrium` is what the direct solver, the boundary-value
reference and the shooting route return; :class:`SolverError` (with the last
iterate attached) and its subclass :class:`NotAMinimumError` are what they
raise.  This module imports nothing else of the package but the problem, so
every route can depend on it.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any, Mapping

import numpy as np

from .problem import Problem

__all__ = ["Equilibrium", "SolverStats", "SolverError", "NotAMinimumError", "FIELDS", "unconverged"]


#: Nodal arrays of an :class:`Equilibrium`, in order.
FIELDS = ("s", "r", "z", "psi", "f_s", "f_phi", "kappa_s", "kappa_phi",
          "E_s", "E_phi", "K_s", "K_phi", "N_s", "N_phi", "M_s", "M_phi", "eta", "e")


@dataclass(frozen=True)
class SolverStats:
    """How an equilibrium was obtained."""

    method: str
    iterations: int
    seconds: float
    status: str
    nodes: int
    build_seconds: float = 0.0
    details: Mapping[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict:
        return {"method": self.method, "iterations": self.iterations, "seconds": self.seconds,
                "status": self.status, "nodes": self.nodes, "build_seconds": self.build_seconds,
                **{k: v for k, v in self.details.items() if np.isscalar(v)}}


@dataclass(frozen=True, eq=False)
class Equilibrium:
    """An equilibrium shape and its mechanics, all on the points ``s`` (increasing).

    For the direct solver the points are the mesh nodes and the interior
    interpolation points of each cell (``stages − 1`` per cell); for the
    boundary-value reference they are the collocation mesh.

    Attributes
    ----------
    problem : Problem
    s, r, z, psi : ndarray
        Undeformed arclength, deformed distance from the axis, height and
        tangent angle.  z is fixed by z(s[0]) = z₀(s[0]) (the undeformed height).
    f_s, f_phi, kappa_s, kappa_phi : ndarray
        Stretches and curvatures (paper, Eq. 5).
    E_s, E_phi, K_s, K_phi : ndarray
        Strains (paper, Eq. 6).
    N_s, N_phi, M_s, M_phi : ndarray
        Resultants ∂e/∂E_a and ∂e/∂K_a (units of C).
    eta : ndarray
        Large-bending parameter η(s).
    e : ndarray
        Energy per undeformed area (units of C); 𝓔 = 2π ∫ e ρ ds.
    energy : float
        Total elastic energy 𝓔 (units of C R²).
    solver : SolverStats
    converged : bool
        True for every returned result; False only on the ``last_iterate`` of
        a :class:`SolverError`.
    """

    problem: Problem
    s: np.ndarray
    r: np.ndarray
    z: np.ndarray
    psi: np.ndarray
    f_s: np.ndarray
    f_phi: np.ndarray
    kappa_s: np.ndarray
    kappa_phi: np.ndarray
    E_s: np.ndarray
    E_phi: np.ndarray
    K_s: np.ndarray
    K_phi: np.ndarray
    N_s: np.ndarray
    N_phi: np.ndarray
    M_s: np.ndarray
    M_phi: np.ndarray
    eta: np.ndarray
    e: np.ndarray
    energy: float
    solver: SolverStats
    converged: bool = True
    x: np.ndarray | None = field(default=None, repr=False)
    lam_g: np.ndarray | None = field(default=None, repr=False)
    quadrature: tuple | None = field(default=None, repr=False)
    #: Positions of the mesh's anchors (material points that are nodes), if any.
    anchors: tuple = ()
    #: The direct solver that produced it (a weak reference: results do not
    #: keep solvers alive); see :func:`morphoshell.direct.solver_of`.
    source: Any = field(default=None, repr=False)

    def __repr__(self) -> str:
        return (f"Equilibrium({self.problem.name or self.problem.family!r}, "
                f"energy={self.energy:.10g}, points={len(self.s)}, method={self.solver.method!r}, "
                f"converged={self.converged})")

    def edge(self, which: str = "start") -> dict[str, float]:
        """Values at the first (``"start"``) or last (``"end"``) node."""
        i = 0 if which == "start" else -1
        return {k: float(getattr(self, k)[i]) for k in FIELDS}

    def at(self, s: float) -> dict[str, float]:
        """Fields interpolated (cubic) at the undeformed arclength ``s``."""
        from scipy.interpolate import CubicSpline

        if not self.s[0] <= s <= self.s[-1]:
            raise ValueError(f"s = {s} lies outside the shell [{self.s[0]}, {self.s[-1]}]")
        return {k: float(CubicSpline(self.s, getattr(self, k))(s)) for k in FIELDS}

    def energy_between(self, a: float, b: float) -> float:
        """2π ∫_a^b e ρ ds: the energy of the part a ≤ s ≤ b of the shell.

        Direct solutions use their own Gauss rule (exact integration of the
        cell's interpolant of L = 2πρe where a or b cuts a cell), so that
        ``energy_between(s[0], s[-1]) == energy``; BVP solutions integrate the
        cubic spline of L through their collocation mesh.
        """
        from scipy.interpolate import CubicSpline

        if not self.s[0] <= a <= b <= self.s[-1]:
            raise ValueError(f"[{a}, {b}] is not a part of the shell [{self.s[0]}, {self.s[-1]}]")
        if self.quadrature is None:
            rho = self.problem.geometry_obj.numeric(self.s)[0]
            return float(CubicSpline(self.s, 2 * np.pi * rho * self.e).integrate(a, b))
        sk, wk, Lk, stages = self.quadrature
        nodes = self.s[::stages]
        total = 0.0
        for c in range(len(nodes) - 1):
            lo, hi = max(a, nodes[c]), min(b, nodes[c + 1])
            if hi <= lo:
                continue
            sl = slice(c * stages, (c + 1) * stages)
            if lo == nodes[c] and hi == nodes[c + 1]:
                total += float(np.dot(wk[sl], Lk[sl]))
            else:   # the degree S − 1 interpolant through the cell's Gauss values
                poly = np.polynomial.Polynomial.fit(sk[sl], Lk[sl], stages - 1).integ()
                total += float(poly(hi) - poly(lo))
        return total

    def to_dict(self, arrays: bool = True) -> dict:
        """JSON-ready: problem, energy, solver and (optionally) the nodal arrays."""
        out = {"problem": self.problem.describe(), "converged": self.converged,
               "energy": self.energy, "solver": self.solver.to_dict(),
               "edge_start": self.edge("start"), "edge_end": self.edge("end")}
        if arrays:
            out.update({k: getattr(self, k).tolist() for k in FIELDS})
        return out


class SolverError(RuntimeError):
    """The solver did not deliver a (stable) equilibrium.

    Attributes
    ----------
    status : str
        Ipopt's return status (or the BVP solver's message).
    last_iterate : Equilibrium or None
        The last iterate, with ``converged=False``, for inspection.
    """

    def __init__(self, message: str, status: str, last_iterate: Equilibrium | None = None):
        super().__init__(message)
        self.status = status
        self.last_iterate = last_iterate


class NotAMinimumError(SolverError):
    """Ipopt converged to a stationary point whose reduced Hessian is not positive definite."""


def unconverged(eq: Equilibrium) -> Equilibrium:
    """``eq`` marked as not converged (the last iterate of a failure)."""
    return replace(eq, converged=False)
