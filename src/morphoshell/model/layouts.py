"""Named layouts of the packed vectors that cross module boundaries.

CasADi functions take and return flat vectors; which entry means what is
defined here, once, and every module reads entries by name through these
layouts instead of by position.

``parameter_layout(family)``  the physical parameter vector p = [h, Σ, P, family parameters]
                              (NLP parameters of the direct solver, ``Problem.parameter_vector``)
``INTRINSIC``                 parameter-only data at a point s: ρ, the intrinsic profiles,
                              η and the coefficients α, β, γ(η) (:mod:`morphoshell.model.energy`)
``CELL_DATA``                 the data of one Gauss point handed to Ipopt's callbacks:
                              s, Δs, weight, objective scale, h and ``INTRINSIC``
``BVP_STATE``                 the state of the boundary-value reference: r, ψ, the costates
                              λ_r, λ_ψ, z and the accumulated energy
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping, Sequence

import numpy as np

from .coefficients import Coefficients
from .profiles import ProfileFamily, Profiles

__all__ = ["VectorLayout", "BASE_PARAMETERS", "parameter_layout", "INTRINSIC", "CELL_DATA",
           "BVP_STATE"]


@dataclass(frozen=True)
class VectorLayout:
    """The entries of a packed vector, by name and in order.

    Works for NumPy arrays and CasADi vectors alike: :meth:`unpack` returns
    the entries (scalars or symbolic entries), :meth:`pack` builds a NumPy
    vector from a mapping.

    Examples
    --------
    >>> lay = VectorLayout("demo", ("a", "b"))
    >>> float(lay.unpack(lay.pack({"a": 1.0, "b": 2.0}))["b"])
    2.0
    """

    name: str
    names: tuple[str, ...]

    def __post_init__(self):
        if len(set(self.names)) != len(self.names):
            raise ValueError(f"layout {self.name!r} repeats a name: {self.names}")

    def __len__(self) -> int:
        return len(self.names)

    def index(self, name: str) -> int:
        """Position of ``name`` in the vector (ValueError naming the valid names)."""
        try:
            return self.names.index(name)
        except ValueError:
            raise ValueError(f"{self.name} has no entry {name!r}; entries: {list(self.names)}") \
                from None

    def indices(self, names: Sequence[str]) -> list[int]:
        """Positions of ``names`` in the vector, in their order."""
        return [self.index(n) for n in names]

    def unpack(self, vector) -> dict:
        """``{name: vector[i]}`` (entries of a NumPy array or a CasADi vector)."""
        if vector.shape[0] != len(self.names):
            raise ValueError(f"{self.name}: expected {len(self.names)} entries, "
                             f"got shape {vector.shape}")
        return {n: vector[i] for i, n in enumerate(self.names)}

    def pack(self, values: Mapping[str, float]) -> np.ndarray:
        """NumPy vector from a mapping that names every entry.

        Returns
        -------
        ndarray, shape (len(names),)
        """
        missing = [n for n in self.names if n not in values]
        if missing:
            raise ValueError(f"{self.name}: missing entries {missing}")
        return np.array([float(values[n]) for n in self.names])

    def after(self, prefix: "VectorLayout") -> int:
        """Offset of ``prefix``'s entries when this layout ends with them."""
        n = len(prefix)
        if self.names[-n:] != prefix.names:
            raise ValueError(f"{self.name} does not end with {prefix.name}")
        return len(self.names) - n


#: The parameters every problem has, before its family's.
BASE_PARAMETERS = ("h", "cut", "opening")


def parameter_layout(family: ProfileFamily) -> VectorLayout:
    """p = [h, Σ, P, the family's parameters in declaration order]."""
    return VectorLayout(f"parameters of {family.name!r}",
                        BASE_PARAMETERS + tuple(family.parameters))


#: Parameter-only quantities at a point (see :func:`morphoshell.model.energy.intrinsic_function`).
INTRINSIC = VectorLayout("intrinsic data", ("rho", *Profiles._fields, "eta", *Coefficients._fields))

#: One Gauss point's data D_k in the direct solver (see :mod:`morphoshell.numerics.discretisation`).
CELL_DATA = VectorLayout("cell data", ("s", "ds", "weight", "scale", "h", *INTRINSIC.names))

#: y of the boundary-value reference (see :mod:`morphoshell.solvers.bvp`).
BVP_STATE = VectorLayout("BVP state", ("r", "psi", "lam_r", "lam_psi", "z", "energy"))
