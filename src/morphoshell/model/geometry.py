"""Undeformed meridians of shells of revolution.

Lengths are scaled by the undeformed radius R (paper, Materials and Methods).
The undeformed meridian is parametrised by arclength s; ρ(s) is its distance
from the axis, z₀(s) its height and ψ₀(s) its tangent angle, so that
ρ' = cos ψ₀ and z₀' = sin ψ₀.  A *pole* is a point where ρ = 0: the shell is
regular there (r = 0, ψ = 0 at the start, ψ = π at the end of a closed
meridian).

All callables accept CasADi expressions as well as floats.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import casadi as ca
import numpy as np

from .._runtime.compiled import PointEvaluator
from .._runtime.validate import lookup

__all__ = ["Geometry", "SPHERE", "DISC", "GEOMETRIES", "get_geometry"]


@dataclass(frozen=True, eq=False)
class Geometry:
    """Undeformed meridian s ↦ (ρ(s), z₀(s)), s ∈ [0, length].

    Attributes
    ----------
    name : str
    length : float
        Arclength of the whole meridian (π for the unit sphere).
    closed : bool
        Whether ρ(length) = 0, i.e. the meridian ends on the axis (a second
        pole) rather than at a rim.
    rho, z0, psi0 : callable
        Distance from the axis, height and tangent angle.
    """

    name: str
    length: float
    closed: bool
    rho: Callable = field(repr=False)
    z0: Callable = field(repr=False)
    psi0: Callable = field(repr=False)
    # compiled evaluator, owned by this object (compared by identity)
    _cache: dict = field(default_factory=dict, repr=False)

    def numeric(self, s) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(ρ, z₀, ψ₀) at the points ``s`` (scalar or array) as NumPy arrays.

        Returns
        -------
        rho, z0, psi0 : ndarray
            Each of the shape of ``s``.
        """
        s = np.asarray(s, dtype=float)
        if "numeric" not in self._cache:
            sym = ca.SX.sym("s")
            # buffered (no DM round trip per call) and compiled where available
            # (evaluation only: faster than CasADi's virtual machine)
            self._cache["numeric"] = PointEvaluator(ca.Function(
                "geometry", [sym], [ca.vertcat(self.rho(sym), self.z0(sym), self.psi0(sym))]))
        out = self._cache["numeric"](s)[0]
        return tuple(out[i].reshape(s.shape) for i in range(3))


#: The unit sphere of the paper, ρ(s) = sin s, with s the arclength from the pole at s = 0.
SPHERE = Geometry("sphere", float(np.pi), True,
                  rho=lambda s: ca.sin(s), z0=lambda s: 1 - ca.cos(s), psi0=lambda s: s)

#: A flat disc of unit radius (ρ = s), whose mirror symmetry makes every flat
#: state a stationary point: useful for checking stability detection.
DISC = Geometry("disc", 1.0, False,
                rho=lambda s: s, z0=lambda s: 0 * s, psi0=lambda s: 0 * s)

#: The geometries by name (``Problem(geometry=...)``).
GEOMETRIES: dict[str, Geometry] = {g.name: g for g in (SPHERE, DISC)}


def get_geometry(name: "str | Geometry") -> Geometry:
    """The geometry called ``name`` (a Geometry is returned as is)."""
    if isinstance(name, Geometry):
        return name
    return lookup(GEOMETRIES, name, "geometry")
