"""A shell problem: geometry, intrinsic profiles, thickness, ends, theory.

Units and conventions (paper, Materials and Methods)
----------------------------------------------------
* Lengths are scaled by the undeformed radius R; ``h`` is the relative
  thickness H/R.  Energies are in units of C R², C the material constant of
  the energy density (C = 4μ for an incompressible neo-Hookean sheet of shear
  modulus μ, lengths scaled by R).
* The shell occupies s ∈ [Σ, L − P] of the undeformed meridian, Σ = ``cut``
  (an ablation of angle 2Σ around the pole s = 0) and P = ``opening`` (the
  phialopore around s = L).  An end is a regular *pole* when Σ = 0 (or P = 0
  on a closed meridian) and a *free edge* (no force, no torque) otherwise.

Every value is checked when the problem is created, so that bad input fails
with a message naming it before any work starts.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Mapping

import numpy as np

from ._validate import real
from .coefficients import get_theory
from .geometry import get_geometry, Geometry
from .profiles import get_family, ProfileFamily, Profiles

__all__ = ["Problem", "Structure", "BASE_KEYS"]

#: Keys of a problem other than the family's parameters (``--set`` names).
BASE_KEYS = ("h", "theory", "cut", "opening")


@dataclass(frozen=True)
class Structure:
    """What an NLP is built for: everything except the parameter values."""

    geometry: str
    family: str
    theory: str
    start: str  # "pole" or "free"
    end: str    # "pole" or "free"


@dataclass(frozen=True)
class Problem:
    """An axisymmetric morphoelastic shell problem.

    Parameters
    ----------
    family : str
        Profile family (see :mod:`morphoshell.profiles`).
    params : mapping
        Values of the family's parameters; missing ones take the defaults.
    h : float
        Relative thickness, 0 < h < 1.
    cut : float
        Σ ≥ 0, arclength of the ablation around the pole s = 0.
    opening : float
        P ≥ 0, arclength of the opening at the far end.
    theory : str
        ``"large_bending"`` (default) or ``"classical"`` (η → 0 coefficients).
    geometry : str
        Undeformed meridian, ``"sphere"`` by default.
    name : str
        Label used in outputs.
    """

    family: str = "uniform"
    params: Mapping[str, float] = field(default_factory=dict)
    h: float = 0.1
    cut: float = 0.0
    opening: float = 0.0
    theory: str = "large_bending"
    geometry: str = "sphere"
    name: str = ""

    def __post_init__(self):
        fam = get_family(self.family)
        geo = get_geometry(self.geometry)
        get_theory(self.theory)
        h = real("thickness h", self.h)
        if not 0 < h < 1:
            raise ValueError(f"thickness h = {h!r} must lie in (0, 1) (relative to the radius)")
        cut = real("cut (Sigma)", self.cut)
        opening = real("opening (P)", self.opening)
        if cut < 0:
            raise ValueError(f"cut (Sigma) = {cut!r} must be non-negative")
        if opening < 0:
            raise ValueError(f"opening (P) = {opening!r} must be non-negative")
        end = geo.length - opening
        if not cut < end:
            raise ValueError(
                f"cut (Sigma) = {cut!r} is larger than the shell: with opening P = {opening!r} "
                f"the {geo.name} ends at s = {end:.6g}")
        if not isinstance(self.params, Mapping):
            raise ValueError(f"params must be a mapping of names to numbers, got {self.params!r}")
        unknown = sorted(set(self.params) - set(fam.parameters))
        if unknown:
            raise ValueError(f"unknown parameter(s) {unknown} for family {fam.name!r}; "
                             f"valid: {list(fam.parameters)}")
        values = {n: real(f"parameter {n}", self.params.get(n, fam.defaults[n]))
                  for n in fam.parameters}
        fam.validate(values, cut, end)
        for k, v in (("h", h), ("cut", cut), ("opening", opening), ("params", values)):
            object.__setattr__(self, k, v)
        self._check_intrinsic(fam, geo)

    # -- derived -----------------------------------------------------------
    @property
    def end(self) -> float:
        """s at the far end of the shell, L − P."""
        return self.geometry_obj.length - self.opening

    @property
    def geometry_obj(self) -> Geometry:
        return get_geometry(self.geometry)

    @property
    def family_obj(self) -> ProfileFamily:
        return get_family(self.family)

    @property
    def structure(self) -> Structure:
        geo = self.geometry_obj
        return Structure(
            self.geometry, self.family, self.theory,
            "pole" if self.cut == 0 else "free",
            "pole" if (self.opening == 0 and geo.closed) else "free")

    def parameter_vector(self) -> np.ndarray:
        """NLP parameters [h, Σ, P, family parameters in declaration order]."""
        fam = self.family_obj
        return np.array([self.h, self.cut, self.opening] + [self.params[n] for n in fam.parameters])

    def with_updates(self, **changes) -> "Problem":
        """A copy with ``h``, ``theory``, ``cut``, ``opening`` or family parameters changed."""
        base = {k: changes.pop(k) for k in list(changes)
                if k in BASE_KEYS or k in ("family", "geometry", "name")}
        params = dict(self.params)
        if "family" in base and base["family"] != self.family:
            params = {}
        params.update(changes)
        return replace(self, params=params, **base)

    def profiles(self, s) -> dict[str, np.ndarray]:
        """Intrinsic profiles and η at the points ``s`` (NumPy arrays)."""
        s = np.asarray(s, dtype=float)
        fam = self.family_obj
        p = [self.params[n] for n in fam.parameters]
        out = fam.function(s.size)(s.reshape(1, -1), p, self.cut, self.end)
        prof = {k: np.asarray(v).reshape(s.shape) for k, v in zip(Profiles._fields, out)}
        prof["eta"] = prof["kappa_s0"] * self.h / (2 * prof["f_s0"] * prof["f_phi0"])
        return prof

    def _check_intrinsic(self, fam: ProfileFamily, geo: Geometry) -> None:
        s = np.linspace(self.cut, self.end, 2001)
        prof = self.profiles(s)
        for key in ("f_s0", "f_phi0"):
            bad = ~(prof[key] > 0)
            if bad.any():
                i = int(np.argmax(bad))
                raise ValueError(f"intrinsic stretch {key} = {prof[key][i]:.6g} at s = {s[i]:.6g} "
                                 f"must be positive (family {fam.name!r}, params {self.params})")
        eta = prof["eta"]
        i = int(np.argmax(np.abs(eta)))
        if not abs(eta[i]) < 1:
            raise ValueError(
                f"abs(eta) = {abs(eta[i]):.6g} >= 1 at s = {s[i]:.6g} "
                f"(eta = kappa_s0 h / (2 f_s0 f_phi0), h = {self.h}): the intrinsic wedge closes "
                f"within the thickness; reduce h or kappa_s0")

    def max_abs_eta(self) -> float:
        return float(np.max(np.abs(self.profiles(np.linspace(self.cut, self.end, 2001))["eta"])))

    def describe(self) -> dict:
        """JSON-ready description."""
        return {"name": self.name, "family": self.family, "params": dict(self.params),
                "h": self.h, "cut": self.cut, "opening": self.opening,
                "theory": self.theory, "geometry": self.geometry}
