"""Intrinsic stretches and curvatures f_s⁰, f_φ⁰, κ_s⁰, κ_φ⁰ of s.

A *profile family* turns named parameters into the four intrinsic profiles as
CasADi expressions of the undeformed arclength s (and, where the family needs
it, of the shell's ends: the cut Σ at the start and the end s_end = L − P).
Families are looked up by name in :data:`FAMILIES`; :func:`register_family`
adds another.  A name that is not registered is looked up among the
installed packages' entry points of the group ``morphoshell.families``
(:data:`ENTRY_POINT_GROUP`): a plugin package makes its family usable from
problem files and the command line without any import (documentation:
"Write your own profile family").

Families of the paper (Haas & Höhn, *Cut it out*: Materials and Methods,
"Numerical solution of the toy problems"; Supplementary, "Fitting of the
morphoelastic theory to the average cell sheet midlines", and this project's
smoothed parameterisation, documentation page "Problems and families"):

``uniform``            f⁰ = 1, κ_s⁰ = κ_φ⁰ = k (toy problems 1 and 2)
``anisotropic``        f_s⁰ = 1 + f0 = 1/f_φ⁰, κ⁰ = 1 (toy problem 3)
``local_relaxation``   f⁰ = 1 + F0 (Σ + s0 − s)/s0 on [Σ, Σ + s0], else 1;
                       κ⁰ = 1 (fast active relaxation near the cut)
``volvox``             the 13-parameter inversion model, smoothing width σ

and a disc that buckles at branch points (documentation: "Branches, folds and
snap-throughs", "Branch switching: the blister"):

``central_growth``     f_s⁰ = f_φ⁰ = 1 + G exp(−(s/w)²), κ⁰ = 0
"""
from __future__ import annotations

import logging
from dataclasses import dataclass, field
from typing import Callable, Mapping, NamedTuple

import casadi as ca
import numpy as np

from .._runtime.compiled import PointEvaluator
from .._runtime.validate import lookup

__all__ = ["Profiles", "ProfileFamily", "FAMILIES", "register_family", "get_family",
           "available_families", "ENTRY_POINT_GROUP", "family_entry_points", "curvature_limit",
           "check_curvature"]

log = logging.getLogger(__name__)

#: Entry-point group of plugin families: each entry point is named like its
#: family and refers to a :class:`ProfileFamily` or to a callable returning one.
ENTRY_POINT_GROUP = "morphoshell.families"


class Profiles(NamedTuple):
    """Intrinsic stretches and curvatures f_s⁰, f_φ⁰, κ_s⁰, κ_φ⁰ (Materials and Methods).

    At a point or at many: floats, arrays of one shape, or CasADi expressions.
    """

    f_s0: object
    f_phi0: object
    kappa_s0: object
    kappa_phi0: object

    def eta(self, h):
        """Large-bending parameter η = κ_s⁰ h / (2 f_s⁰ f_φ⁰) (paper, Materials and
        Methods; the intrinsic thickness is h⁰ = h/(f_s⁰ f_φ⁰), so η = κ_s⁰ h⁰/2)."""
        return self.kappa_s0 * h / (2 * self.f_s0 * self.f_phi0)


def curvature_limit(h: float) -> float:
    """The largest |k| a shell of relative thickness h can have: 2/h.

    A sheet of thickness h curved with radius 1/|k| below h/2 would have its
    inner face at or past its centre of curvature: |η| = |k| h/2 ≥ 1 for an
    unstretched sheet (:meth:`Profiles.eta`, which a :class:`~morphoshell.model.problem.
    Problem` keeps below 1; the bulk's intrinsic configuration degenerates there too,
    :func:`morphoshell.mechanics.bulk.undeformed_geometry`).  It also bounds the work
    of an inversion: the grid of a k-range has at most 2·(2/h)/
    :data:`~morphoshell.inverse.inversion.GRID_STEP` nodes.
    """
    return 2.0 / h


def check_curvature(k_range: tuple[float, ...], h: float, label: str, shell: str,
                    remedy: str = "search a range") -> None:
    """ValueError, naming ``label`` and ``shell``, when the k-range reaches |k| ≥ 2/h.

    Here, in the lowest layer, so that the asymptotics (:mod:`morphoshell.mechanics`)
    refuse such k as the inversions and the command line do (audit 26 F2:
    ``predictions(0.1, 1000, 0.3)`` returned a rotation of −387 rad).

    Parameters
    ----------
    k_range : tuple of float
        A checked k-range (:func:`~morphoshell.inverse.inversion.check_k_range`), or one
        k, ``(k,)`` (``morphoshell asymptotics --k``: its predictions there are no shell's).
    h : float
        Relative thickness H/R of the shell.
    label : str
        How the message names the range (``"--k-range -100 100"``, ``"k_range = ..."``).
    shell : str
        Which shell h is, for the message (e.g. "embryo 'S05'").
    remedy : str
        What to do, completed by "within (-2/h, 2/h)" (e.g. "give --k").
    """
    limit = curvature_limit(h)
    worst = max(k_range, key=abs)
    if abs(worst) >= limit:
        raise ValueError(
            f"{label}: k = {worst:g} is beyond the curvature of {shell} (h = H/R = {h:.4g}): "
            f"|k| must stay below 2/h = {limit:.4g}, since a sheet of thickness h cannot curve "
            f"with a radius 1/|k| below h/2 (its inner face would pass its centre of "
            f"curvature); {remedy} within (-{limit:.4g}, {limit:.4g})")


@dataclass(frozen=True, eq=False)
class ProfileFamily:
    """A named family of intrinsic profiles.

    Families are compared and hashed by identity: every compiled function of
    a family (here and in the solvers' caches) belongs to that object, so a
    family registered again under the same name (a re-run notebook cell) is
    a new family and nothing built for the old one is reused.

    Attributes
    ----------
    name : str
    parameters : tuple of str
        Parameter names, in the order of the NLP parameter vector.
    defaults : mapping
        Default value of every parameter.
    build : callable
        ``build(s, p, cut, end) -> Profiles`` with ``p`` a dict of CasADi
        symbols keyed by parameter name.
    validate : callable
        ``validate(values, cut, end)`` raises ``ValueError`` naming the
        offending value; called before any work starts.
    neutral : mapping
        Parameter values for which the undeformed sphere is stress free
        (f⁰ = 1, κ⁰ = 1); continuation starts there.
    pre_ablation : mapping
        Parameter values of the intact shell when they differ from the cut
        one (a response triggered by the cut, such as ``local_relaxation``).
    breakpoints : callable, optional
        ``breakpoints(p, cut, end) -> [(position, width), ...]``: material
        points where the profiles kink or change fast, as expressions of the
        named parameters ``p`` (floats or CasADi symbols), with the width of
        the change (None for a kink).  The direct solver's mesh puts a node
        at each (and refines on the width's scale), following them as the
        parameters change, so the scheme keeps its order.
    units : mapping
        The unit of each parameter, as :data:`morphoshell.solvers.results.FIELD_UNITS`
        writes them: ``"R"`` (lengths in units of R), ``"1/R"`` (curvatures), ``"1"``
        (dimensionless); what a fit prints beside a value.  A parameter without one
        is printed without.
    """

    name: str
    parameters: tuple[str, ...]
    defaults: Mapping[str, float]
    build: Callable[..., Profiles]
    validate: Callable[[Mapping[str, float], float, float], None] = lambda v, cut, end: None
    description: str = ""
    neutral: Mapping[str, float] = field(default_factory=dict)
    pre_ablation: Mapping[str, float] = field(default_factory=dict)
    breakpoints: Callable | None = None
    units: Mapping[str, str] = field(default_factory=dict)
    _function: dict = field(default_factory=dict, repr=False, compare=False)

    def function(self, points: int | None = None) -> ca.Function:
        """CasADi Function ``(s, p, cut, end) -> (f_s0, f_phi0, kappa_s0, kappa_phi0)``.

        With ``points``, the same mapped over that many values of s (a row).
        """
        if "f" not in self._function:
            s, cut, end = ca.SX.sym("s"), ca.SX.sym("cut"), ca.SX.sym("end")
            p = ca.SX.sym("p", len(self.parameters))
            named = {n: p[i] for i, n in enumerate(self.parameters)}
            prof = self.build(s, named, cut, end)
            self._function["f"] = ca.Function(
                f"profiles_{self.name}", [s, p, cut, end], list(prof),
                ["s", "p", "cut", "end"], list(Profiles._fields))
        if points is None:
            return self._function["f"]
        # An explicit map: calling with a row of points would build one each time.
        return self._mapped("maps", points, lambda: self._function["f"].map(points))

    def evaluate(self, s: np.ndarray, values, cut: float, end: float) -> Profiles:
        """Numerical profiles at the points ``s`` (1-d) for parameter ``values`` in order.

        Parameters
        ----------
        s : ndarray, shape (N,)
        values : sequence of float
            The family's parameters, in the order of :attr:`parameters`.
        cut, end : float
            Σ and L − P.

        Returns
        -------
        Profiles
            Each an ndarray of shape (N,).
        """
        # compiled code where available (evaluation only: faster than CasADi's
        # virtual machine); the parameters, cut and end given once for all points
        if "numeric" not in self._function:
            self._function["numeric"] = PointEvaluator(self.function())
        return Profiles(*(v[0] for v in self._function["numeric"](s, values, cut, end)))

    def _mapped(self, kind: str, points: int, make: Callable):
        maps = self._function.setdefault(kind, {})
        if points not in maps:
            if len(maps) >= 8:                    # a few sizes recur; keep the cache small
                maps.pop(next(iter(maps)))
            maps[points] = make()
        return maps[points]


def _positive(values, *names):
    for n in names:
        if not values[n] > 0:
            raise ValueError(f"parameter {n} = {values[n]!r} must be positive")


def _within(values, lo, hi, *names, why="", open_lo=False):
    """ValueError naming the first parameter outside [lo, hi], or (lo, hi] with ``open_lo``
    (``why`` says what the range means)."""
    for n in names:
        if not (lo < values[n] if open_lo else lo <= values[n]) or not values[n] <= hi:
            raise ValueError(f"parameter {n} = {values[n]!r} must lie in "
                             f"{'(' if open_lo else '['}{lo:g}, {hi:g}]{why}")


#: Plausible ranges, so that absurd values are named before any solve starts:
#: intrinsic stretches between 1/10 and 10, intrinsic curvatures at most 1000/R.
STRETCH_RANGE = (0.1, 10.0)
MAX_CURVATURE = 1e3


def _uniform(s, p, cut, end):
    one = 1 + 0 * s
    return Profiles(one, one, p["k"] * one, p["k"] * one)


def _anisotropic(s, p, cut, end):
    one = 1 + 0 * s
    return Profiles((1 + p["f0"]) * one, one / (1 + p["f0"]), one, one)


def _validate_uniform(v, cut, end):
    _within(v, -MAX_CURVATURE, MAX_CURVATURE, "k", why=" (intrinsic curvature in units of 1/R)")


def _validate_anisotropic(v, cut, end):
    # (one check, one bound: a separate "must exceed -1" named the wrong one for f0 = -1)
    lo, hi = STRETCH_RANGE
    _within(v, lo - 1, hi - 1, "f0", why=" (intrinsic stretch 1 + f0 between 1/10 and 10)")


def _central_growth(s, p, cut, end):
    f = 1 + p["G"] * ca.exp(-(s / p["w"]) ** 2)
    zero = 0 * s
    return Profiles(f, f, zero, zero)


def _validate_central_growth(v, cut, end):
    lo, hi = STRETCH_RANGE
    _within(v, lo - 1, hi - 1, "G", why=" (intrinsic stretch 1 + G at the centre between 1/10 "
                                         "and 10)")
    _within(v, 0, 2 * np.pi, "w", open_lo=True,
            why=" (width of the grown region, in units of R)")


def _local_relaxation(s, p, cut, end):
    # Piecewise linear as printed in the paper; the kink at Σ + s0 is in the
    # data, not in the unknowns, so Ipopt's derivatives stay exact.
    f = 1 + p["F0"] * ca.fmax(0, 1 - (s - cut) / p["s0"])
    one = 1 + 0 * s
    return Profiles(f, f, one, one)


def _validate_local_relaxation(v, cut, end):
    lo, hi = STRETCH_RANGE
    _within(v, lo - 1, hi - 1, "F0", why=" (intrinsic stretch 1 + F0 between 1/10 and 10)")
    _within(v, 0, 2 * np.pi, "s0", open_lo=True,
            why=" (width of the relaxed region, in units of R)")


def _local_relaxation_breakpoints(p, cut, end):
    return [(cut + p["s0"], None)]       # the kink of the ramp


def _volvox_breakpoints(p, cut, end):
    return [(p[f"s{i}"], p["sigma"]) for i in range(1, 5)]    # steps of width sigma


def _softplus(x):
    return ca.fmax(x, 0) + ca.log1p(ca.exp(-ca.fabs(x)))


def _volvox(s, p, cut, end):
    sig = p["sigma"]

    def step(si):  # the smoothed step H(s − s_i) (documentation: "Problems and families")
        return (1 + ca.tanh((s - si) / sig)) / 2

    ramp = sig * (_softplus((s - p["s3"]) / sig) - _softplus((s - p["s4"]) / sig)) / (
        p["s4"] - p["s3"])
    k1, k2, k3, k4 = (p[f"kappa{i}"] for i in range(1, 5))
    f1, f2, f3, f4, f5 = (p[f"f{i}"] for i in range(1, 6))
    return Profiles(
        f_s0=f1 + (f2 - f1) * step(p["s2"]) + (f3 - f2) * ramp,
        f_phi0=f1 + (f4 - f1) * step(p["s2"]) + (f5 - f4) * ramp,
        kappa_s0=k1 + (k2 - k1) * step(p["s1"]) + (k3 - k2) * step(p["s2"]),
        kappa_phi0=k1 + (k4 - k1) * step(p["s2"]),
    )


def _validate_volvox(v, cut, end):
    _positive(v, "f1", "f2", "f3", "f4", "f5", "sigma")
    _within(v, *STRETCH_RANGE, "f1", "f2", "f3", "f4", "f5", why=" (intrinsic stretches)")
    _within(v, -MAX_CURVATURE, MAX_CURVATURE, "kappa1", "kappa2", "kappa3", "kappa4",
            why=" (intrinsic curvatures in units of 1/R)")
    _within(v, 1e-3, 0.5, "sigma", why=" (smoothing width of the steps, in units of R)")
    bps = [("s1", v["s1"]), ("s2", v["s2"]), ("s3", v["s3"]), ("s4", v["s4"])]
    if not bps[0][1] > 0:
        raise ValueError(f"breakpoint s1 = {v['s1']!r} must be positive")
    for (na, a), (nb, b) in zip(bps, bps[1:]):
        if not a < b:
            raise ValueError(f"breakpoints must satisfy 0 < s1 < s2 < s3 < s4 < pi - P; "
                             f"got {na} = {a!r} >= {nb} = {b!r}")
    if not v["s4"] < end:
        raise ValueError(f"breakpoint s4 = {v['s4']!r} must lie before the shell's end "
                         f"s = {end:.6g} (pi - P)")


FAMILIES: dict[str, ProfileFamily] = {}


def register_family(family: ProfileFamily) -> ProfileFamily:
    """Add ``family`` to :data:`FAMILIES` (replacing one of the same name).

    Problems created afterwards use the new family; problems created before
    keep the family they were created with.
    """
    if not isinstance(family, ProfileFamily):
        raise ValueError(f"register_family needs a ProfileFamily, got {family!r}")
    missing = set(family.parameters) - set(family.defaults)
    if missing:
        raise ValueError(f"family {family.name!r} lacks defaults for {sorted(missing)}")
    stray = set(family.units) - set(family.parameters)
    if stray:
        raise ValueError(f"family {family.name!r} gives units of {sorted(stray)}, which are "
                         f"not among its parameters {list(family.parameters)}")
    FAMILIES[family.name] = family
    return family


def get_family(name: "str | ProfileFamily") -> ProfileFamily:
    """The family called ``name`` (a ProfileFamily is returned as is).

    Registered families come first; an unknown name is then looked up among
    the entry points of :data:`ENTRY_POINT_GROUP` of the installed packages,
    loaded and registered (once: later look-ups find it in :data:`FAMILIES`).

    Raises
    ------
    ValueError
        No family of that name (the message lists the available ones), or a
        plugin that fails to load or does not give a :class:`ProfileFamily`.
    """
    if isinstance(name, ProfileFamily):
        return name
    if isinstance(name, str) and name not in FAMILIES:
        _load_plugin(name)
    if isinstance(name, str) and name in FAMILIES:
        return FAMILIES[name]
    # not registered and no plugin of that name: ValueError listing the available names
    return lookup(available_families(), name, "profile family")


def family_entry_points() -> dict:
    """Entry points of :data:`ENTRY_POINT_GROUP`, by name (the first of a duplicated name)."""
    from importlib.metadata import entry_points

    out: dict = {}
    for ep in entry_points(group=ENTRY_POINT_GROUP):
        out.setdefault(ep.name, ep)
    return out


def available_families() -> dict[str, "ProfileFamily | str"]:
    """Registered families and, not yet loaded, the installed plugins' ones.

    Returns
    -------
    dict
        name → the :class:`ProfileFamily`, or for a plugin not loaded yet
        the entry point's value (``"module:attribute"``).
    """
    return {**{n: ep.value for n, ep in family_entry_points().items()}, **FAMILIES}


def _load_plugin(name: str) -> None:
    """Load and register the plugin family ``name``, if an entry point provides it."""
    ep = family_entry_points().get(name)
    if ep is None:
        return
    where = f"plugin family {name!r} (entry point {ep.value!r} of {ENTRY_POINT_GROUP!r})"
    try:
        obj = ep.load()
        if callable(obj) and not isinstance(obj, ProfileFamily):
            obj = obj()
    except Exception as exc:  # a broken plugin: name it, whatever it raised
        raise ValueError(f"{where} failed to load: {type(exc).__name__}: {exc}") from exc
    if not isinstance(obj, ProfileFamily):
        raise ValueError(f"{where} gives {obj!r}, not a ProfileFamily")
    if obj.name != name:
        raise ValueError(f"{where} gives a family called {obj.name!r}: the entry point's name "
                         f"must be the family's name")
    if FAMILIES.get(name) is not obj:   # a plugin module may register it itself on import
        register_family(obj)
    log.debug("loaded %s", where)


register_family(ProfileFamily(
    "uniform", ("k",), {"k": 0.0}, _uniform, _validate_uniform,
    description="f0 = 1, kappa_s0 = kappa_phi0 = k (toy problems 1 and 2)", neutral={"k": 1.0},
    units={"k": "1/R"}))
register_family(ProfileFamily(
    "anisotropic", ("f0",), {"f0": 0.1}, _anisotropic, _validate_anisotropic,
    description="f_s0 = 1 + f0 = 1/f_phi0, kappa0 = 1 (toy problem 3)", neutral={"f0": 0.0},
    units={"f0": "1"}))
register_family(ProfileFamily(
    "local_relaxation", ("F0", "s0"), {"F0": 0.35, "s0": 0.2}, _local_relaxation,
    _validate_local_relaxation,
    description="f0 = 1 + F0 (cut + s0 - s)/s0 near the cut, kappa0 = 1 (fast relaxation)",
    # The relaxation is an active response to the cut: the intact shell has none.
    neutral={"F0": 0.0}, pre_ablation={"F0": 0.0}, breakpoints=_local_relaxation_breakpoints,
    units={"F0": "1", "s0": "R"}))
register_family(ProfileFamily(
    "central_growth", ("G", "w"), {"G": 0.2, "w": 0.3}, _central_growth,
    _validate_central_growth,
    description="f_s0 = f_phi0 = 1 + G exp(-(s/w)^2), kappa0 = 0: a flat disc grown in its "
                "centre, which buckles (the blister)",
    # stress-free as a flat disc (geometry = "disc"), which it stays, by mirror symmetry,
    # on an unstable branch past its first branch point
    neutral={"G": 0.0}, units={"G": "1", "w": "R"}))
register_family(ProfileFamily(
    "volvox",
    ("f1", "f2", "f3", "f4", "f5", "kappa1", "kappa2", "kappa3", "kappa4",
     "s1", "s2", "s3", "s4", "sigma"),
    # Illustrative early-invagination values (not a fit): contracted posterior,
    # strongly curved wedge cells in the bend region (eta about -0.8 at h = 0.15).
    {"f1": 0.9, "f2": 1.0, "f3": 1.1, "f4": 1.0, "f5": 1.15,
     "kappa1": 1 / 0.9, "kappa2": -9.0, "kappa3": 1.0, "kappa4": 1.0,
     "s1": 1.3, "s2": 1.6, "s3": 1.9, "s4": 2.3, "sigma": 0.05},
    _volvox, _validate_volvox,
    description="13-parameter Volvox inversion model, smoothing width sigma",
    neutral={**{f"f{i}": 1.0 for i in range(1, 6)}, **{f"kappa{i}": 1.0 for i in range(1, 5)}},
    breakpoints=_volvox_breakpoints,
    # stretches f, curvatures kappa (units of 1/R), breakpoints s and smoothing width (of R)
    units={**{f"f{i}": "1" for i in range(1, 6)}, **{f"kappa{i}": "1/R" for i in range(1, 5)},
           **{f"s{i}": "R" for i in range(1, 5)}, "sigma": "R"}))

