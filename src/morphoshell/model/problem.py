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

import pickle
from dataclasses import dataclass, field, replace
from typing import Mapping

import numpy as np

from .._runtime.validate import real
from .coefficients import THEORIES, Theory, get_theory
from .geometry import GEOMETRIES, Geometry, get_geometry
from .layouts import VectorLayout, parameter_layout
from .profiles import FAMILIES, ProfileFamily, Profiles, get_family

__all__ = ["Problem", "Params", "Structure", "BASE_KEYS", "MIN_SHELL_LENGTH", "MIN_THICKNESS",
           "MIN_CUT"]

#: Thinnest shell accepted, h = H/R: below it the bending energy (∝ h³) falls under the
#: solvers' round-off relative to the stretching energy, and Ipopt fails (h = 1e-12:
#: Restoration_Failed) or meets NaN (1e-40) instead of saying so.  The BVP route solves
#: down to here; the direct route from its default start down to
#: 2e-5 (:data:`morphoshell.solvers.options.MIN_DIRECT_THICKNESS`; below it solve() warns, and
#: a failure says so first).
MIN_THICKNESS = 1e-6

#: Shortest shell L − P − Σ accepted (units of R): shorter shells bring the
#: energy scale down to the solver's round-off floor, where Ipopt fails.
MIN_SHELL_LENGTH = 1e-3

#: Smallest positive cut Σ, and opening P of a closed meridian, accepted (units of R): a
#: free edge that close to the axis fails with statuses that name something else
#: (Continuation_Failed, Meridian_Crosses_Axis, Restoration_Failed; raw CasADi warnings
#: at 1e-300).  At 200 nodes every problem tried solved down to 3e-7 and the first
#: failed at 1e-7; finer meshes fail at larger cuts (5e-5 at 1600 nodes): docs/benchmarks.md,
#: "model/problem.py".  0 is a pole.
MIN_CUT = 1e-4

#: Relative tolerance of the comparisons with the bounds of lengths: a shell exactly
#: MIN_SHELL_LENGTH long, L − P − Σ computed, is that long to round-off.
_ROUND_OFF = 1e-9

#: Keys of a problem other than the family's parameters (``--set`` names).
BASE_KEYS = ("h", "theory", "cut", "opening")


@dataclass(frozen=True)
class Structure:
    """What an NLP is built for: everything except the parameter values.

    Holds the geometry, family and theory *objects* (compared by identity),
    so a solver or compiled function cached for one structure can never be
    reused for a family or theory registered later under the same name.

    Attributes
    ----------
    geometry : Geometry
    family : ProfileFamily
    theory : Theory
    start, end : {"pole", "free"}
        The kind of each end: a regular pole or a free edge.
    """

    geometry: Geometry
    family: ProfileFamily
    theory: Theory
    start: str  # "pole" or "free"
    end: str    # "pole" or "free"

    def __repr__(self) -> str:
        return (f"Structure(geometry={self.geometry.name!r}, family={self.family.name!r}, "
                f"theory={self.theory.name!r}, start={self.start!r}, end={self.end!r})")

    @property
    def parameters(self) -> VectorLayout:
        """Layout of the parameter vector p (see :mod:`morphoshell.model.layouts`)."""
        return parameter_layout(self.family)


class Params(dict):
    """A problem's parameter values, read-only.

    A Problem is checked once, when it is created: a user audit set
    ``p.params["k"] = 50`` on a checked problem (η = 7.5), and its solve failed
    only inside the continuation, naming an intermediate η.  A dict otherwise, so that
    it compares, prints, pickles (process pools) and serialises as one; hashable, so
    that an equal Problem hashes equal.
    """

    __slots__ = ()

    def _refuse(self, *args, **kwargs):
        """Refused: the values are read-only (TypeError)."""
        raise TypeError("a Problem's params are read-only (it was checked with them): make "
                        "a changed copy with problem.with_updates(parameter=value)")

    __setitem__ = __delitem__ = __ior__ = _refuse
    update = pop = popitem = clear = setdefault = _refuse

    def __hash__(self) -> int:
        return hash(tuple(sorted(self.items())))

    def __reduce__(self):
        return type(self), (dict(self),)


@dataclass(frozen=True)
class Problem:
    """An axisymmetric morphoelastic shell problem.

    Parameters
    ----------
    family : str or ProfileFamily
        Profile family (see :mod:`morphoshell.model.profiles`).  A name is looked
        up when the problem is created and the family object is kept
        (``family_obj``): re-registering the name later does not change this
        problem.
    params : mapping
        Values of the family's parameters; missing ones take the defaults.
    h : float
        Relative thickness, in [:data:`MIN_THICKNESS`, 1) = [1e-6, 1), which
        ``method="bvp"`` solves.  The direct route (the default) solves h ≥ 2e-5
        (:data:`~morphoshell.solvers.options.MIN_DIRECT_THICKNESS`) from its default
        start; on thinner shells ``solve()`` warns before it starts, and its failures
        begin with h and ``method="bvp"``.
    cut : float
        Σ, arclength of the ablation around the pole s = 0: 0 (a pole) or at
        least :data:`MIN_CUT` = 1e-4 (smaller cuts fail in the solvers).
    opening : float
        P, arclength of the opening at the far end: 0 or, on a closed meridian
        (a sphere), at least :data:`MIN_CUT`.  The shell L − P − Σ is at least
        :data:`MIN_SHELL_LENGTH` = 1e-3 long.
    theory : str or Theory
        ``"large_bending"`` (default) or ``"classical"`` (η → 0 coefficients);
        bound at creation like the family.
    geometry : str or Geometry
        Undeformed meridian, ``"sphere"`` by default.
    name : str
        Label used in outputs.

    Notes
    -----
    A Problem is immutable and hashable: ``params`` is read-only (:class:`Params`), and
    :meth:`with_updates` makes a changed copy, checked anew.  It pickles (process pools)
    as its declaration, which the receiving process checks anew and binds to its own
    registered family, theory and geometry of those names (:meth:`__reduce__`).
    """

    family: str = "uniform"
    params: Mapping[str, float] = field(default_factory=dict)
    h: float = 0.1
    cut: float = 0.0
    opening: float = 0.0
    theory: str = "large_bending"
    geometry: str = "sphere"
    name: str = ""
    family_obj: ProfileFamily = field(init=False, repr=False)
    theory_obj: Theory = field(init=False, repr=False)
    geometry_obj: Geometry = field(init=False, repr=False)

    def __post_init__(self):
        if not isinstance(self.name, str):
            raise TypeError(f"name = {self.name!r} must be a string (a label for outputs)")
        fam = get_family(self.family)
        geo = get_geometry(self.geometry)
        theory = get_theory(self.theory)
        for k, v in (("family", fam.name), ("theory", theory.name), ("geometry", geo.name),
                     ("family_obj", fam), ("theory_obj", theory), ("geometry_obj", geo)):
            object.__setattr__(self, k, v)
        h = real("thickness h", self.h)
        if not MIN_THICKNESS <= h < 1:
            raise ValueError(f"thickness h = {h!r} must lie in [{MIN_THICKNESS:g}, 1) (relative "
                             f"to the radius)")
        cut = real("cut (Sigma)", self.cut)
        opening = real("opening (P)", self.opening)
        end = _shell_end(cut, opening, h, geo)
        if not isinstance(self.params, Mapping):
            raise ValueError(f"params must be a mapping of names to numbers, got {self.params!r}")
        unknown = sorted(set(self.params) - set(fam.parameters))
        if unknown:
            raise ValueError(f"unknown parameter(s) {unknown} for family {fam.name!r}; "
                             f"valid: {list(fam.parameters)}")
        values = {n: real(f"parameter {n}", self.params.get(n, fam.defaults[n]))
                  for n in fam.parameters}
        fam.validate(values, cut, end)
        for k, v in (("h", h), ("cut", cut), ("opening", opening), ("params", Params(values))):
            object.__setattr__(self, k, v)
        self._check_intrinsic(fam, geo)

    def __reduce__(self):
        """Pickled as the constructor's arguments: the family, theory and geometry by name.

        Their objects hold CasADi functions and lambdas, which do not pickle; the
        unpickled problem is created anew and binds the registered objects of those
        names in its process (``family_obj`` etc. re-derived, values checked again).

        Raises
        ------
        pickle.PicklingError
            The family, theory or geometry is not the one registered under its name
            (passed as an object, or registered again since): by name, another process
            would rebuild a different problem.
        """
        for key, registry in (("family", FAMILIES), ("theory", THEORIES),
                              ("geometry", GEOMETRIES)):
            if registry.get(getattr(self, key)) is not getattr(self, f"{key}_obj"):
                raise pickle.PicklingError(
                    f"cannot pickle problem {self.name or self.family!r}: its {key} "
                    f"{getattr(self, key)!r} is not the one registered under that name, and a "
                    f"problem pickles its {key} by name: register it (in every process)")
        return type(self), (self.family, dict(self.params), self.h, self.cut, self.opening,
                            self.theory, self.geometry, self.name)

    # -- derived -----------------------------------------------------------
    @property
    def end(self) -> float:
        """s at the far end of the shell, L − P."""
        return self.geometry_obj.length - self.opening

    @property
    def structure(self) -> Structure:
        """What a solver is built for: geometry, family, theory and the kinds of both ends."""
        geo = self.geometry_obj
        return Structure(
            geo, self.family_obj, self.theory_obj,
            "pole" if self.cut == 0 else "free",
            "pole" if (self.opening == 0 and geo.closed) else "free")

    @property
    def parameter_layout(self) -> VectorLayout:
        """Layout of the NLP parameter vector p = [h, Σ, P, family parameters]."""
        return parameter_layout(self.family_obj)

    def parameter_vector(self) -> np.ndarray:
        """NLP parameters p = [h, Σ, P, family parameters].

        Returns
        -------
        ndarray, shape (3 + len(family.parameters),)
            In the order of :func:`~morphoshell.model.layouts.parameter_layout`.
        """
        return self.parameter_layout.pack({"h": self.h, "cut": self.cut, "opening": self.opening,
                                           **self.params})

    def with_updates(self, **changes) -> "Problem":
        """A copy with ``h``, ``theory``, ``cut``, ``opening`` or family parameters changed.

        The copy keeps this problem's family, theory and geometry objects
        unless their names are changed.
        """
        base = {k: changes.pop(k) for k in list(changes)
                if k in BASE_KEYS or k in ("family", "geometry", "name")}
        params = dict(self.params)
        for key in ("family", "theory", "geometry"):
            if key not in base or base[key] == getattr(self, key):
                base[key] = getattr(self, f"{key}_obj")
            elif key == "family":
                params = {}
        params.update(changes)
        return replace(self, params=params, **base)

    def profiles(self, s) -> dict[str, np.ndarray]:
        """Intrinsic profiles and η at the points ``s`` (NumPy arrays).

        Returns
        -------
        dict
            ``f_s0``, ``f_phi0``, ``kappa_s0``, ``kappa_phi0`` and ``eta``
            (η = κ_s⁰ h / (2 f_s⁰ f_φ⁰), Materials and Methods), each of the
            shape of ``s``.
        """
        s = np.asarray(s, dtype=float)
        prof = Profiles(*[v.reshape(s.shape) for v in self._profiles(s.ravel())])
        return {**prof._asdict(), "eta": prof.eta(self.h)}

    def eta(self, s: np.ndarray) -> np.ndarray:
        """η at the points ``s`` (:meth:`profiles` without the rest: a warm re-solve's
        results need η alone).

        Returns
        -------
        ndarray, shape (N,)
            For the N points ``s`` (1-d).
        """
        return self._profiles(np.asarray(s, dtype=float)).eta(self.h)

    def _profiles(self, s: np.ndarray) -> Profiles:
        fam = self.family_obj
        return fam.evaluate(s, [self.params[n] for n in fam.parameters], self.cut, self.end)

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
        """Largest |η| over the shell (dimensionless; 2001 points), which must stay below 1."""
        return float(np.max(np.abs(self.profiles(np.linspace(self.cut, self.end, 2001))["eta"])))

    def describe(self) -> dict:
        """JSON-ready description."""
        return {"name": self.name, "family": self.family, "params": dict(self.params),
                "h": self.h, "cut": self.cut, "opening": self.opening,
                "theory": self.theory, "geometry": self.geometry}


def _shell_end(cut: float, opening: float, h: float, geo: Geometry) -> float:
    """L − P, the far end, with the cut and the opening checked (ValueError naming them)."""
    for name, value in (("cut (Sigma)", cut), ("opening (P)", opening)):
        if value < 0:
            raise ValueError(f"{name} = {value!r} must be non-negative")
    if cut != 0 and not cut >= MIN_CUT:
        raise ValueError(f"cut (Sigma) = {cut!r} must be 0 (a pole) or at least {MIN_CUT:g} "
                         f"(units of R): the solvers fail on smaller cuts")
    if opening != 0 and geo.closed and not opening >= MIN_CUT:
        raise ValueError(f"opening (P) = {opening!r} must be 0 (a pole) or at least "
                         f"{MIN_CUT:g} (units of R): the solvers fail on smaller openings")
    end = geo.length - opening
    if not opening < geo.length:     # (else the cut was blamed: "cut = 0.0 is larger ...")
        raise ValueError(f"opening (P) = {opening!r} is larger than the shell: the "
                         f"{geo.name}'s meridian is {geo.length:.6g} long (units of R)")
    if not cut < end:
        raise ValueError(
            f"cut (Sigma) = {cut!r} is larger than the shell: with opening P = {opening!r} "
            f"the {geo.name} ends at s = {end:.6g}")
    if end - cut < MIN_SHELL_LENGTH * (1 - _ROUND_OFF):
        raise ValueError(
            f"the shell s in [cut, L - opening] = [{cut!r}, {end:.6g}] is shorter than "
            f"{MIN_SHELL_LENGTH:g} (units of R): that is a ring, not a shell")
    if end - cut < h:
        raise ValueError(
            f"the shell s in [cut, L - opening] = [{cut!r}, {end:.6g}] is {end - cut:.3g} "
            f"long, shorter than its thickness h = {h!r} (units of R): the thin-shell "
            f"theory of this model needs a shell longer than thick")
    return end
