"""Toy problem 1 in bulk nonlinear elasticity: a thick incompressible sphere.

Paper, Supplementary "Toy Problem 1", sections "Geometry of the deformed
shell" and "Elasticity of the deformed shell".  A spherical shell of
thickness ``h`` whose inner and outer radii average to 1 has uniform intrinsic
curvature ``k`` and stays spherical with deformed mean radius ``f``.  The
asymptotic answer is the Supplementary's f ("Next-order calculation",
:func:`morphoshell.mechanics.asymptotics.f_bulk_asymptotic`); this module computes ``f``
without expanding in ``h``.

Reduction of the printed equations
----------------------------------
The two maps of the Supplementary's "Geometry of the deformed shell" (here
called *cond1*, deformed, and *cond2*, undeformed) are statements of volume
conservation: multiplying them by 3a² gives

* *cond2*: (a + ζ)³ − a³ = a²[(1 + kZ)³ − 1]/k = a² Z (3 + 3kZ + k²Z²),
* *cond1*: (ã + ζ̃)³ − ã³ = (a + ζ)³ − a³.

Since a = 1 − (h⁺ − h⁻)/2 and h⁺ + h⁻ = h, the undeformed faces are at
r± = a ± h^± = 1 ± h/2 whatever h^± are.  Subtracting and adding the two
equations for the faces (*heqs*, "Geometry of the deformed shell"; second
line, Z = ±h⁰/2) then gives two equations for a and h⁰ alone (:func:`undeformed_geometry`)::

    3h + h³/4           = a² (3h⁰ + k² h⁰³/4),
    2 + 3h²/2 − 2a³     = (3/2) a² k h⁰².

The first line of *heqs* says that the deformed faces r̃± = ã ± h̃^±
enclose the same volume, (r̃₊³ − r̃₋³) = (r₊³ − r₋³), with f = (r̃₊ + r̃₋)/2;
ã follows from r̃₊³ − ã³ = r₊³ − a³ (:func:`deformed_geometry`).  The
definition ã = f − (h̃⁺ − h̃⁻)/2 is then an identity.

Energy and stationarity
-----------------------
With ρ = a(1 + kZ) and r̃ = ã + ζ̃ the elastic stretch is Λ = r̃/ρ and the
energy is 𝓔 = 4π a² ∫ e(Λ) (1 + kZ)² dZ over Z ∈ [−h⁰/2, h⁰/2] (the
Supplementary's 4πh∫…dz with Z = hz).  Because r̃³ − ã³ does not depend on f,
∂r̃/∂ã = ã²/r̃², and ::

    d𝓔/df = 4π a r̃₊² (dr̃₊/df) ∫ e'(Λ) (1 + kZ)/r̃² dZ,

with dr̃₊/df = (2f − t)²/(4f² + t²) > 0 for the deformed thickness t.  The
minimiser solves ∫ e'(Λ)(1 + kZ)/r̃² dZ = 0 (:func:`stationarity`), which is
what :func:`f_bulk` root-finds; locating the minimum from energy values would
give f only to about √eps, useless since f − 1 = O(h²).

Precision
---------
The integrand is dominated by an O(h) part odd in Z that integrates to zero,
leaving O(h³).  This loses nothing in *absolute* terms: Λ − 1 is formed from
small quantities (f − 1, t − h, ã − a, ζ̃ − Z) without subtracting numbers
near 1, and the invariants use I₁ − 3 = (Λ² − 1)²(2Λ² + 1)/Λ⁴ and
I₂ − 3 = (Λ² − 1)²(Λ² + 2)/Λ², so the residual has absolute error
≈ eps·h and f is obtained to a few 1e-16.  The integrand is analytic on an
interval of half-width ≈ h/2 ≪ its distance to the nearest singularity
(1 + kZ = 0 or r̃ = 0), so Gauss–Legendre quadrature converges geometrically;
24 nodes are at machine precision for h ≤ 0.2 and moderate k (checked against
48 nodes in the tests).

Parity
------
Replacing h by −h maps (h⁰, t) → (−h⁰, −t) and swaps the two faces but leaves
a, ã and the set of Z unchanged, so 𝓔 changes sign and its stationary points
do not move: f is an even function of h.  Hence the O(h³) remainder of
f (Supplementary, "Next-order calculation") actually vanishes and f − f_asymptotic = O(h⁴).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache
from typing import Any, Mapping

import numpy as np

from .._runtime.validate import real
from ..numerics.status import NO_STATIONARY_RADIUS, SolverError, explain

__all__ = [
    "UndeformedGeometry", "DeformedGeometry", "undeformed_geometry",
    "deformed_geometry", "zeta_of_Z", "zeta_tilde_of_zeta", "stretch",
    "energy_density", "energy_density_derivative", "energy", "energy_derivative",
    "stationarity", "f_bulk", "DEFAULT_NODES",
]

#: Gauss–Legendre nodes across the thickness (see "Precision" above).
DEFAULT_NODES = 24


def _thickness(h: Any) -> float:
    h = real("h", h)
    # The inner face sits at 1 − h/2, so h ≥ 2 is not a shell at all.
    if not 0 < h < 2:
        raise ValueError(f"h = {h!r} must satisfy 0 < h < 2")
    return h


def _material(c10, c01, c20=0.0, c11=0.0, c02=0.0) -> dict[tuple[int, int], float]:
    """Nonzero coefficients C_mn of the energy density, keyed by (m, n)."""
    values = {(1, 0): real("c10", c10), (0, 1): real("c01", c01),
              (2, 0): real("c20", c20), (1, 1): real("c11", c11),
              (0, 2): real("c02", c02)}
    if values[(1, 0)] + values[(0, 1)] <= 0:
        # Supplementary, "Elasticity of the deformed shell": positive bulk
        # modulus; otherwise the sphere f = 1 + O(h²) is not a minimum.
        raise ValueError(
            f"c10 + c01 = {values[(1, 0)] + values[(0, 1)]!r} must be positive")
    return {key: c for key, c in values.items() if c != 0}


@dataclass(frozen=True)
class UndeformedGeometry:
    """Solution of the second line of *heqs* with h⁺ + h⁻ = h.

    Attributes
    ----------
    h, k : float
        Thickness and intrinsic curvature.
    a : float
        Undeformed midsurface radius, a = 1 − (h⁺ − h⁻)/2.
    h0 : float
        Intrinsic thickness h⁰; the intrinsic coordinate is Z ∈ [−h⁰/2, h⁰/2].
    h_plus, h_minus : float
        h^±, the distances from the midsurface to the outer and inner faces.
    """

    h: float
    k: float
    a: float
    h0: float
    h_plus: float
    h_minus: float


@dataclass(frozen=True)
class DeformedGeometry:
    """Solution of the first line of *heqs* for a deformed radius f.

    Attributes
    ----------
    f : float
        Deformed mean radius, (r̃₊ + r̃₋)/2.
    f_minus_1 : float
        f − 1, carried separately because it is O(h²).
    t : float
        Deformed thickness r̃₊ − r̃₋ = h̃⁺ + h̃⁻.
    a_tilde : float
        Deformed midsurface radius ã (image of ζ = 0).
    a_tilde_minus_a : float
        ã − a, computed without cancellation.
    h_tilde_plus, h_tilde_minus : float
        h̃^±; ã = f − (h̃⁺ − h̃⁻)/2 holds identically.
    """

    f: float
    f_minus_1: float
    t: float
    a_tilde: float
    a_tilde_minus_a: float
    h_tilde_plus: float
    h_tilde_minus: float


def undeformed_geometry(h: float, k: float) -> UndeformedGeometry:
    """Midsurface radius a, intrinsic thickness h⁰ and h^± (*heqs*).

    Solves 3h + h³/4 = a²(3h⁰ + k²h⁰³/4) and 2 + 3h²/2 − 2a³ = (3/2)a²kh⁰²
    (the difference and sum of the two signs of the second line of
    *heqs*, see the module docstring) by eliminating a² with the first
    and root-finding h⁰ in the second.

    Raises
    ------
    ValueError
        If h ∉ (0, 2), k is not finite, or the intrinsic configuration
        degenerates (1 ± kh⁰/2 ≤ 0).
    """
    h = _thickness(h)
    k = real("k", k)
    volume = 3 * h + h**3 / 4

    def a_of(u):
        return math.sqrt(volume / (3 * u + k * k * u**3 / 4))

    def residual(u):
        a = a_of(u)
        return 2 + 1.5 * h * h - 2 * a**3 - 1.5 * a * a * k * u * u

    # The residual falls like −3/h⁰ and vanishes at h⁰ = h(1 + O(h²)).
    lo, hi = 0.5 * h, 1.5 * h
    if residual(lo) * residual(hi) > 0:
        raise ValueError(
            f"no intrinsic thickness near h for h = {h!r}, k = {k!r}; "
            "the shell is too thick for this intrinsic curvature")
    from scipy.optimize import brentq  # (on use: 0.3 s to import)

    h0 = brentq(residual, lo, hi, xtol=1e-300, rtol=4 * np.finfo(float).eps, maxiter=200)
    if abs(k) * h0 / 2 >= 1:
        raise ValueError(
            f"k = {k!r}: the intrinsic configuration degenerates for h = {h!r}: |k| h0/2 = "
            f"{abs(k) * h0 / 2:.6g} >= 1, where h0 = {h0:.6g} is the intrinsic thickness that "
            f"keeps the shell's volume (the intrinsic radius 1/|k| within half of it); "
            f"|k| must stay below {2 / h0:.6g}")
    a = a_of(h0)
    # r± = 1 ± h/2 (module docstring), so h⁺ = 1 + h/2 − a, h⁻ = a − 1 + h/2.
    return UndeformedGeometry(h=h, k=k, a=a, h0=h0,
                              h_plus=(1 - a) + h / 2, h_minus=h / 2 - (1 - a))


def deformed_geometry(geom: UndeformedGeometry, f_minus_1: float) -> DeformedGeometry:
    """Deformed thickness t, ã and h̃^± for f = 1 + ``f_minus_1`` (*heqs*).

    The faces r̃± = f ± t/2 enclose the undeformed volume,
    3f²t + t³/4 = 3h + h³/4, solved for t − h by fixed-point iteration on
    t − h = −3h(f² − 1)/(3f² + (t² + th + h²)/4) (a contraction with factor
    O(h²)).  Then ã³ − a³ = r̃₊³ − r₊³ (*cond1* at the outer face).
    """
    F = real("f - 1", f_minus_1)
    if F <= -1:
        raise ValueError(f"f - 1 = {F!r} must exceed -1")
    h, a = geom.h, geom.a
    f = 1 + F
    f2m1 = F * (2 + F)
    dt = 0.0
    for _ in range(100):
        t = h + dt
        new = -3 * h * f2m1 / (3 * f * f + (t * t + t * h + h * h) / 4)
        if new == dt:
            break
        dt = new
    t = h + dt
    r_plus, rt_plus = 1 + h / 2, f + t / 2
    # ã³ − a³ = (r̃₊ − r₊)(r̃₊² + r̃₊r₊ + r₊²) with r̃₊ − r₊ = F + (t − h)/2.
    cube_diff = (F + dt / 2) * (rt_plus**2 + rt_plus * r_plus + r_plus**2)
    a_tilde = a * math.exp(math.log1p(cube_diff / a**3) / 3)
    a_tilde_minus_a = cube_diff / (a_tilde**2 + a_tilde * a + a * a)
    return DeformedGeometry(f=f, f_minus_1=F, t=t, a_tilde=a_tilde,
                            a_tilde_minus_a=a_tilde_minus_a,
                            h_tilde_plus=rt_plus - a_tilde,
                            h_tilde_minus=a_tilde - (f - t / 2))


def _cbrt_step(base, increment):
    """(base³ + increment)^(1/3) − base, accurate when increment ≪ base³."""
    return base * np.expm1(np.log1p(increment / base**3) / 3)


def zeta_of_Z(geom: UndeformedGeometry, Z):
    """Undeformed transverse coordinate ζ(Z), the solution of *cond2*.

    Returns
    -------
    ndarray
        ζ, of the shape of ``Z``.
    """
    a, k = geom.a, geom.k
    Z = np.asarray(Z, dtype=float)
    return _cbrt_step(a, a * a * Z * (3 + 3 * k * Z + k * k * Z * Z))


def zeta_tilde_of_zeta(geom: UndeformedGeometry, deformed: DeformedGeometry, zeta):
    """Deformed transverse coordinate ζ̃(ζ), the solution of *cond1*.

    Returns
    -------
    ndarray
        ζ̃, of the shape of ``zeta``.
    """
    a = geom.a
    zeta = np.asarray(zeta, dtype=float)
    return _cbrt_step(deformed.a_tilde, zeta * (3 * a * a + 3 * a * zeta + zeta * zeta))


def stretch(geom: UndeformedGeometry, deformed: DeformedGeometry, Z):
    """Elastic stretch Λ − 1 and deformed radius r̃ at intrinsic coordinate Z.

    Λ = (ã/a)(1 + ζ̃/ã)/(1 + kZ) = r̃/ρ (Supplementary, "Elasticity of the
    deformed shell"), evaluated as Λ − 1 = [(ã − a) + (ζ̃ − Z) + (1 − ak)Z]/ρ
    so that no two numbers near 1 are subtracted.

    Returns
    -------
    lam_minus_1, r_tilde : ndarray
        Λ − 1 and r̃ = ã + ζ̃, of the shape of ``Z``.
    """
    a, k = geom.a, geom.k
    Z = np.asarray(Z, dtype=float)
    # ζ̃(Z) directly: (ã + ζ̃)³ − ã³ = a² Z (3 + 3kZ + k²Z²) by eqs. cond1-2.
    zt = _cbrt_step(deformed.a_tilde, a * a * Z * (3 + 3 * k * Z + k * k * Z * Z))
    rho = a * (1 + k * Z)
    lam_minus_1 = (deformed.a_tilde_minus_a + (zt - Z) + (1 - a * k) * Z) / rho
    return lam_minus_1, deformed.a_tilde + zt


def _invariants(lam_minus_1):
    """Λ, I₁ − 3, I₂ − 3 and dI₁/dΛ, dI₂/dΛ in cancellation-free form."""
    lam = 1 + lam_minus_1
    x = lam * lam
    xm1 = lam_minus_1 * (2 + lam_minus_1)        # Λ² − 1
    p = xm1**2 * (2 * x + 1) / (x * x)           # I₁ − 3 = 2Λ² + Λ⁻⁴ − 3
    q = xm1**2 * (x + 2) / x                     # I₂ − 3 = Λ⁴ + 2Λ⁻² − 3
    six = xm1 * (x * x + x + 1)                  # Λ⁶ − 1
    dp = 4 * six / lam**5                        # 4Λ − 4Λ⁻⁵
    dq = 4 * six / lam**3                        # 4Λ³ − 4Λ⁻³
    return p, q, dp, dq


def energy_density(lam_minus_1, material: Mapping[tuple[int, int], float]):
    """e = ½ Σ C_mn (I₁ − 3)^m (I₂ − 3)^n with I₁ = 2Λ² + Λ⁻⁴, I₂ = Λ⁴ + 2Λ⁻².

    ``material`` maps (m, n) to C_mn (see :func:`_material`); Supplementary,
    "Elasticity of the deformed shell".

    Returns
    -------
    ndarray
        e, of the shape of ``lam_minus_1``.
    """
    p, q, _, _ = _invariants(np.asarray(lam_minus_1, dtype=float))
    return 0.5 * sum(c * p**m * q**n for (m, n), c in material.items())


def energy_density_derivative(lam_minus_1, material: Mapping[tuple[int, int], float]):
    """de/dΛ for :func:`energy_density`."""
    p, q, dp, dq = _invariants(np.asarray(lam_minus_1, dtype=float))
    total = 0.0
    for (m, n), c in material.items():
        if m:
            total = total + c * m * p ** (m - 1) * q**n * dp
        if n:
            total = total + c * n * p**m * q ** (n - 1) * dq
    return 0.5 * total


@lru_cache(maxsize=None)
def _gauss(nodes: int):
    return np.polynomial.legendre.leggauss(nodes)


def _nodes(geom: UndeformedGeometry, nodes: int):
    if isinstance(nodes, bool) or not isinstance(nodes, (int, np.integer)) or nodes < 2:
        raise ValueError(f"nodes = {nodes!r} must be an integer >= 2")
    x, w = _gauss(int(nodes))
    half = geom.h0 / 2
    return half * x, half * w


def _setup(h, k, c10, c01, c20, c11, c02):
    return undeformed_geometry(h, k), _material(c10, c01, c20, c11, c02)


def energy(f: float, h: float, k: float, c10: float, c01: float, c20: float = 0.0,
           c11: float = 0.0, c02: float = 0.0, *, nodes: int = DEFAULT_NODES) -> float:
    """Elastic energy 𝓔(f) = 4πh ∫ e a² (1 + khz)² dz of the deformed sphere.

    Supplementary, "Elasticity of the deformed shell"; the integral over
    z ∈ [−h⁰/2h, h⁰/2h] is done by Gauss–Legendre quadrature in Z = hz.
    Since e = O(h²), 𝓔 = 2π(C₁₀ + C₀₁)[12f₁² + (k − 1)²]h³ + O(h⁴) for
    f = 1 + hf₁; the Supplementary prints h² there (a factor h dropped,
    immaterial for the minimiser).

    Parameters
    ----------
    f : float
        Deformed mean radius.
    h, k : float
        Thickness (0 < h < 2) and intrinsic curvature.
    c10, c01, c20, c11, c02 : float
        Coefficients C_mn of the energy density; c10 + c01 > 0.
    nodes : int
        Number of Gauss–Legendre nodes.

    Returns
    -------
    float
        𝓔 (units of the C_mn times the radius cubed).
    """
    geom, material = _setup(h, k, c10, c01, c20, c11, c02)
    deformed = deformed_geometry(geom, real("f", f) - 1)
    Z, w = _nodes(geom, nodes)
    lam_minus_1, _ = stretch(geom, deformed, Z)
    integrand = energy_density(lam_minus_1, material) * (1 + k * Z) ** 2
    return float(4 * math.pi * geom.a**2 * np.dot(w, integrand))


def _stationarity(geom, material, Z, w, F):
    deformed = deformed_geometry(geom, F)
    lam_minus_1, rt = stretch(geom, deformed, Z)
    integrand = energy_density_derivative(lam_minus_1, material) * (1 + geom.k * Z) / rt**2
    return float(np.dot(w, integrand)), deformed


def stationarity(f_minus_1: float, h: float, k: float, c10: float, c01: float,
                 c20: float = 0.0, c11: float = 0.0, c02: float = 0.0, *,
                 nodes: int = DEFAULT_NODES) -> float:
    """S(f) = ∫ e'(Λ)(1 + kZ)/r̃² dZ, a positive multiple of d𝓔/df.

    Takes f − 1 rather than f because f − 1 = O(h²) is the quantity solved
    for.  See :func:`energy_derivative` for the factor.
    """
    geom, material = _setup(h, k, c10, c01, c20, c11, c02)
    Z, w = _nodes(geom, nodes)
    return _stationarity(geom, material, Z, w, real("f - 1", f_minus_1))[0]


def energy_derivative(f: float, h: float, k: float, c10: float, c01: float,
                      c20: float = 0.0, c11: float = 0.0, c02: float = 0.0, *,
                      nodes: int = DEFAULT_NODES) -> float:
    """d𝓔/df = 4π a r̃₊² (dr̃₊/df) S(f), differentiated through *heqs*.

    dr̃₊/df = 1 + t'(f)/2 with t' = −8ft/(4f² + t²) from the volume
    constraint, i.e. (2f − t)²/(4f² + t²).
    """
    geom, material = _setup(h, k, c10, c01, c20, c11, c02)
    Z, w = _nodes(geom, nodes)
    S, deformed = _stationarity(geom, material, Z, w, real("f", f) - 1)
    f_, t = deformed.f, deformed.t
    drt = (2 * f_ - t) ** 2 / (4 * f_ * f_ + t * t)
    return 4 * math.pi * geom.a * (f_ + t / 2) ** 2 * drt * S


def _closed(geom: UndeformedGeometry) -> float:
    """f − 1 at which the deformed inner face reaches the centre, r̃₋ = f − t/2 = 0.

    The faces keep the volume, r̃₊³ − r̃₋³ = 3h + h³/4, so there f = (3h + h³/4)^(1/3)/2.
    Below it the deformed radii of the inner Gauss nodes turn negative and the energy is
    not defined (NaN from the cube roots); for h ≳ 0.33 it lies above f = 1/2, where the
    bracket of :func:`f_bulk` once stopped and found no sign change (audit 26, F1).
    """
    h = geom.h
    return (3 * h + h**3 / 4) ** (1 / 3) / 2 - 1


def _bracket(S, centre: float, width: float, floor: float):
    """(lo, hi, S(lo), S(hi)) with S(lo) ≤ 0 ≤ S(hi): a rising sign change of ``S``, the
    minimum of the energy, found by doubling ``width`` about ``centre`` down to ``floor``;
    None where 60 doublings find none.

    The whole interval is taken first, as it always was.  Where S falls again above its
    root (C01 < 0: the energy falls without bound as the sphere grows), or is finite only
    above ``floor``, the interval's ends alone miss it; then the pair of adjacent points
    evaluated so far whose S rises through 0 nearest ``centre`` is taken.
    """
    seen = {centre: S(centre)}
    for _ in range(60):
        lo, hi = max(centre - width, floor), centre + width
        seen.update({lo: S(lo), hi: S(hi)})
        if seen[lo] <= 0 <= seen[hi]:
            return lo, hi, seen[lo], seen[hi]
        found = _rising(seen, centre)
        if found is not None:
            return found
        width *= 2
    return None


def _rising(seen: dict, centre: float):
    """Of the points ``seen`` (F -> S(F)), the adjacent pair whose S rises through 0
    nearest ``centre``, as (lo, hi, S(lo), S(hi)); None if there is none."""
    xs = sorted(seen)
    rising = [(a, b) for a, b in zip(xs, xs[1:]) if seen[a] <= 0 <= seen[b]]
    if not rising:
        return None
    a, b = min(rising, key=lambda ab: min(abs(ab[0] - centre), abs(ab[1] - centre)))
    return a, b, seen[a], seen[b]


#: The scan of :func:`_scan`: radii f from where the energy is defined up to this, points
#: equally spaced in log f.
SCAN_F_MAX, SCAN_POINTS = 1e3, 400


def _scan(S, centre: float, floor: float):
    """A rising sign change of ``S`` (as :func:`_bracket`'s) that the doublings missed: S on
    :data:`SCAN_POINTS` radii equally spaced in log f from ``floor`` to f =
    :data:`SCAN_F_MAX`, and at every local maximum of S on them, that maximum found between
    its neighbours (a rise through 0 narrower than the grid's steps, under 2 % in f); None
    if neither finds one.

    With C01 < 0 a local minimum of the energy can lie in a window of S > 0 a few per cent
    of f wide, between a rise and a fall of S, both missed by the doublings' coarse points:
    f - 1 = 0.50 to 0.58 at h = 0.9, k = -0.5, C10 : C01 = 1 : -0.5 (audit 26, F1).
    """
    from scipy.optimize import minimize_scalar  # (on use: 0.3 s to import)

    F = np.geomspace(1 + floor, SCAN_F_MAX, SCAN_POINTS) - 1
    seen = {float(x): S(float(x)) for x in F}
    found = _rising(seen, centre)
    if found is not None:
        return found
    values = np.array(list(seen.values()))
    for i in np.flatnonzero((values[1:-1] >= values[:-2]) & (values[1:-1] >= values[2:])) + 1:
        top = minimize_scalar(lambda x: -S(x), bounds=(F[i - 1], F[i + 1]), method="bounded",
                              options={"xatol": 1e-12 * (1 + abs(F[i]))})
        seen[float(top.x)] = -float(top.fun)
    return _rising(seen, centre)


def f_bulk(h: float, k: float, c10: float, c01: float, c20: float = 0.0,
           c11: float = 0.0, c02: float = 0.0, *, nodes: int = DEFAULT_NODES,
           return_deviation: bool = False) -> float:
    """Deformed radius f minimising 𝓔 (Supplementary, toy problem 1).

    Root-finds the stationarity condition S(f) = 0 (:func:`stationarity`) in
    f − 1 with Brent's method to relative precision 4·eps, bracketing around
    the asymptotic prediction for f (Supplementary, "Next-order
    calculation"), or where that finds no rising sign change of S, from a scan
    of the radii where the energy is defined (:func:`_scan`).  S increases with f near the root
    (𝓔'' ≈ 24π(C₁₀ + C₀₁)h > 0), so the root is the minimum.

    Parameters
    ----------
    h : float
        Thickness, 0 < h < 2 (meant for h ≲ 0.2).
    k : float
        Intrinsic curvature.
    c10, c01 : float
        Mooney–Rivlin coefficients, c10 + c01 > 0.
    c20, c11, c02 : float
        Optional higher-order coefficients of the energy density.
    nodes : int
        Gauss–Legendre nodes across the thickness.
    return_deviation : bool
        Return f − 1 (full relative precision) instead of f.

    Returns
    -------
    float
        f, or f − 1 if ``return_deviation``.

    Raises
    ------
    ValueError
        A bad argument, or a k whose intrinsic configuration degenerates
        (:func:`undeformed_geometry`), before any work.
    SolverError
        ``"No_Stationary_Radius"``: dE/df rises through 0 nowhere the bracket
        and the scan looked (:func:`_scan`), from where the inner face reaches
        the centre to f = 1000: no local minimum of the energy there.
    """
    geom, material = _setup(h, k, c10, c01, c20, c11, c02)
    Z, w = _nodes(geom, nodes)
    c10, c01 = material.get((1, 0), 0.0), material.get((0, 1), 0.0)
    # the asymptotic f, used only to centre the bracket.
    F0 = -(geom.h**2 / 12) * (k - 1) * ((11 * c10 + 7 * c01) - (5 * c10 + c01) * k) \
        / (2 * (c10 + c01))

    def S(F):
        return _stationarity(geom, material, Z, w, F)[0]

    width = abs(F0) + geom.h**2 * (1 + abs(k - 1)) / 4
    floor = max(-0.5, _closed(geom) + 1e-6)
    found = _bracket(S, F0, width, floor) or _scan(S, F0, floor)
    if found is None:
        raise SolverError(
            f"no stationary radius found for h = {h!r}, k = {k!r}: dE/df has no rising sign "
            f"change from f - 1 = {floor:.3g} (where the inner face nears the centre, or "
            f"-0.5) to f = {SCAN_F_MAX:g}, nor in 60 doublings of a bracket about the "
            f"asymptotic f - 1 = {F0:.3g}: {explain(NO_STATIONARY_RADIUS)}",
            NO_STATIONARY_RADIUS)
    lo, hi, s_lo, s_hi = found
    if s_lo == 0:
        F = lo
    elif s_hi == 0:
        F = hi
    else:
        from scipy.optimize import brentq  # (on use: 0.3 s to import)

        F = brentq(S, lo, hi, xtol=1e-24, rtol=4 * np.finfo(float).eps, maxiter=500)
    return F if return_deviation else 1 + F
