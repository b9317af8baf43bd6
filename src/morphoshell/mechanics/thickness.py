"""Exact through-thickness energy of the three-dimensional model behind the shell.

Documentation "Theory", the three-dimensional model: straight-sided wedge cells
of an incompressible neo-Hookean material, normals stay normal, the material
midsurface ζ = 0 maps to the deformed midsurface z = 0.  This module evaluates
that model *without* expanding in the strains, so that the quadratic shell
energy of :func:`morphoshell.model.energy.density` (with the coefficients of
:mod:`morphoshell.model.coefficients`) can be checked against it (section 4).  It is
a verification tool: nothing in the solvers depends on it.

Model (κ_φ⁰ = 0)
----------------
Intrinsic thickness h⁰ = h / (f_s⁰ f_φ⁰), normal coordinate ζ ∈ [−h⁰/2, h⁰/2],
deformed normal coordinate z(ζ).  The elastic stretches are

    λ_s = f_s (1 + κ_s z) / (f_s⁰ (1 + κ_s⁰ ζ)),   λ_φ = f_φ (1 + κ_φ z) / f_φ⁰,
    λ_n = dz/dζ,

and incompressibility λ_s λ_φ λ_n = 1 reads
f_s f_φ (1 + κ_s z)(1 + κ_φ z) dz = f_s⁰ f_φ⁰ (1 + κ_s⁰ ζ) dζ; integrated from
z(0) = 0 it is the cubic

    f_s f_φ (z + (κ_s + κ_φ) z²/2 + κ_s κ_φ z³/3) = f_s⁰ f_φ⁰ (ζ + κ_s⁰ ζ²/2).

The energy per undeformed midsurface area is f_s⁰ f_φ⁰ ∫ W (1 + κ_s⁰ ζ) dζ with
W = (μ/2)(λ_s² + λ_φ² + λ_n² − 3).

Relation between μ and C
------------------------
At κ⁰ = 0 and small strain, λ_s = 1 + E_s, λ_φ = 1 + E_φ and
λ_n = 1/(λ_s λ_φ) = 1 − E_s − E_φ + E_s² + E_s E_φ + E_φ² + …, so

    W = 2μ (E_s² + E_s E_φ + E_φ²) + O(E³).

Integrating over the intrinsic thickness h⁰ and multiplying by f_s⁰ f_φ⁰
gives 2μh (E_s² + E_s E_φ + E_φ²), while the shell energy at η = 0 is
(C/2) h (E_s² + E_s E_φ + E_φ²).  Hence **C = 4μ**, not 4μh as written in
section 3 of the theory document: the thickness h already appears explicitly
in the shell energy, so it must not be absorbed into C as well.  (In units,
with lengths scaled by the radius R, C = 4μR; with R = 1, C = 4μ.)  The
bending part agrees: W = 2μ ζ² (κ_s² + κ_s κ_φ + κ_φ²) integrates to
2μ (h³/12)(…), the η = 0 value (C/2) h³ γ with γ = 1/12, 1/24, 1/12.
:data:`C_PER_MU` holds this constant and is checked numerically in the tests.

Strain directions
-----------------
Deformations are given as a direction (E_s, E_φ, h⁰K̂_s, h⁰K̂_φ) times an
amplitude, with K̂_s = (ψ' − f_s⁰κ_s⁰)/f_s⁰, K̂_φ = (sin ψ/ρ − f_φ⁰κ_φ⁰)/f_φ⁰ and
h K = h⁰ K̂ (theory document section 1).  Inverting these definitions,

    f_s = f_s⁰ (1 + E_s),   f_φ = f_φ⁰ (1 + E_φ),
    f_s κ_s = ψ' = f_s⁰ (κ_s⁰ + K̂_s),   f_φ κ_φ = sin ψ / ρ = f_φ⁰ (κ_φ⁰ + K̂_φ).
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..model import coefficients as _coefficients
from ..model import energy as _energy
from ..model.profiles import Profiles

__all__ = [
    "C_PER_MU", "Deformed", "deformed_state", "normal_coordinate", "exact_density",
    "shell_density", "energies",
]

#: C = C_PER_MU · μ (lengths scaled by the undeformed radius; see module docstring).
C_PER_MU = 4.0

#: Default number of Gauss–Legendre nodes through the thickness.  The integrand
#: is analytic on [−h⁰/2, h⁰/2] with its nearest singularity at
#: 1 + κ_s⁰ζ = 0, i.e. at ζ/(h⁰/2) = −1/η; for abs(η) = 0.99 the Bernstein
#: ellipse parameter is ≈ 1.15, so 200 nodes give an error ~ 1.15⁻⁴⁰⁰ ≈ 1e−24.
DEFAULT_NODES = 200


class Deformed(NamedTuple):
    """Deformed midsurface stretches and curvatures."""

    f_s: float
    f_phi: float
    kappa_s: float
    kappa_phi: float


def deformed_state(f_s0: float, f_phi0: float, kappa_s0: float, h: float,
                   direction, amplitude: float = 1.0) -> Deformed:
    """Deformed (f_s, f_φ, κ_s, κ_φ) for a strain ``amplitude · direction``.

    Parameters
    ----------
    f_s0, f_phi0, kappa_s0, h : float
        Intrinsic stretches, meridional curvature (κ_φ⁰ = 0) and thickness.
    direction : sequence of 4 floats
        (E_s, E_φ, h⁰K̂_s, h⁰K̂_φ), with h⁰ = h/(f_s⁰ f_φ⁰).
    amplitude : float
        Multiplies ``direction``.

    Notes
    -----
    Inverts the definitions of theory document section 1 (see module docstring).
    :func:`shell_density` recomputes the strains from the result with
    :func:`morphoshell.model.energy.strains`; ``tests/test_coefficients.py`` checks
    that this round trip returns ``amplitude · direction``.
    """
    E_s, E_phi, k_s, k_phi = (amplitude * float(d) for d in direction)
    h0 = h / (f_s0 * f_phi0)
    f_s = f_s0 * (1 + E_s)
    f_phi = f_phi0 * (1 + E_phi)
    return Deformed(f_s=f_s, f_phi=f_phi,
                    kappa_s=f_s0 * (kappa_s0 + k_s / h0) / f_s,
                    kappa_phi=f_phi0 * (k_phi / h0) / f_phi)


def normal_coordinate(zeta, f_s0: float, f_phi0: float, kappa_s0: float, d: Deformed,
                      tol: float = 1e-15, maxiter: int = 60) -> np.ndarray:
    """Deformed normal coordinate z(ζ) from the incompressibility cubic.

    Solves g(z) = f_s f_φ (z + (κ_s + κ_φ) z²/2 + κ_s κ_φ z³/3) − f_s⁰ f_φ⁰ (ζ + κ_s⁰ζ²/2) = 0
    (module docstring).  g' = f_s f_φ (1 + κ_s z)(1 + κ_φ z) is positive on the
    admissible interval where both factors are positive (no deformed cell turned
    inside out), so the root there, continued from z(0) = 0, is unique.

    Returns
    -------
    ndarray
        z, of the shape of ``zeta``.

    Raises
    ------
    ValueError
        If there is no admissible root: the deformation closes the thin end of
        the wedge (for abs(η) → 1 this happens at strains ~ (1 − abs(η))²).
    """
    zeta = np.asarray(zeta, dtype=float)
    F = d.f_s * d.f_phi
    R = f_s0 * f_phi0 * (zeta + kappa_s0 * zeta**2 / 2) / F
    ks, kp = d.kappa_s, d.kappa_phi
    # Start from the root of the quadratic without the small κ_s κ_φ z³ term,
    # written as 2R/(1 + √(1 + 2cR)) so that it does not cancel for small c R.
    # Where that quadratic has no root, start from z = 0 and let the damped
    # iteration (and the final check) decide whether the cubic has one.
    disc = 1 + 2 * (ks + kp) * R
    z = np.where(disc >= 0, 2 * R / (1 + np.sqrt(np.fmax(disc, 0))), 0.0)

    def admissible(z):
        return (1 + ks * z > 0) & (1 + kp * z > 0)

    for _ in range(maxiter):
        g = z + (ks + kp) * z**2 / 2 + ks * kp * z**3 / 3 - R
        step = g / ((1 + ks * z) * (1 + kp * z))
        # Damped Newton: halve the step wherever it would leave the admissible
        # interval (g is monotone there, so the iteration still converges).
        for _ in range(60):
            bad = ~admissible(z - step)
            if not bad.any():
                break
            step = np.where(bad, step / 2, step)
        z = z - step
        if np.all(np.abs(step) <= tol * np.abs(z)):
            break
    g = z + (ks + kp) * z**2 / 2 + ks * kp * z**3 / 3 - R
    if not (np.all(admissible(z)) and
            np.all(np.abs(g) <= 1e3 * tol * (np.abs(R) + 1e-300) + 1e-300)):
        raise ValueError("no admissible z(zeta): the deformation closes the thin end of the wedge")
    return z


def exact_density(f_s0: float, f_phi0: float, kappa_s0: float, h: float, d: Deformed,
                  mu: float = 1.0, nodes: int = DEFAULT_NODES) -> float:
    """Exact neo-Hookean energy per undeformed area, f_s⁰ f_φ⁰ ∫ W (1 + κ_s⁰ζ) dζ.

    Theory document section 3, κ_φ⁰ = 0, Gauss–Legendre quadrature with
    ``nodes`` points on ζ ∈ [−h⁰/2, h⁰/2].
    """
    h0 = h / (f_s0 * f_phi0)
    if not abs(kappa_s0 * h0 / 2) < 1:
        raise ValueError(f"need abs(eta) < 1, got eta = {kappa_s0 * h0 / 2}")
    x, w = np.polynomial.legendre.leggauss(nodes)
    zeta, w = x * h0 / 2, w * h0 / 2
    z = normal_coordinate(zeta, f_s0, f_phi0, kappa_s0, d)
    # Stretches minus one, as differences of like terms (no 1 + O(A) − 1).
    base_s = f_s0 * (1 + kappa_s0 * zeta)
    a = ((d.f_s - f_s0) + (d.f_s * d.kappa_s * z - f_s0 * kappa_s0 * zeta)) / base_s  # λ_s − 1
    b = ((d.f_phi - f_phi0) + d.f_phi * d.kappa_phi * z) / f_phi0                      # λ_φ − 1
    # λ_n = dz/dζ = 1/(λ_s λ_φ) by incompressibility: using it in this form keeps
    # λ_s λ_φ λ_n = 1 exact at the nodes (no differentiation of z needed).
    # With c = λ_n − 1 = −(a + b + ab)/((1 + a)(1 + b)), the first-order terms of
    # λ_s² + λ_φ² + λ_n² − 3 = a² + b² + c² + 2(a + b + c) cancel exactly:
    # a + b + c = (a² + ab + b² + ab(a + b))/((1 + a)(1 + b)).  Writing it so keeps
    # the relative rounding error of W at ~1e−16/A instead of ~1e−16/A², which
    # matters at strain amplitudes A ≲ 1e−5.
    p = (1 + a) * (1 + b)
    c = -(a + b + a * b) / p
    excess = a**2 + b**2 + c**2 + 2 * (a**2 + a * b + b**2 + a * b * (a + b)) / p
    W = mu / 2 * excess
    return float(f_s0 * f_phi0 * np.sum(w * W * (1 + kappa_s0 * zeta)))


def shell_density(f_s0: float, f_phi0: float, kappa_s0: float, h: float, d: Deformed,
                  mu: float = 1.0, theory: str = "large_bending", rho: float = 1.0,
                  return_strains: bool = False):
    """Quadratic shell energy e of the deformed state ``d`` (theory document section 2).

    The strains come from :func:`morphoshell.model.energy.strains` and the energy
    from :func:`morphoshell.model.energy.density` with the coefficients
    :func:`morphoshell.model.coefficients.evaluate` at η = κ_s⁰h/(2f_s⁰f_φ⁰), i.e.
    the project's own pipeline, with C = :data:`C_PER_MU` · μ.  The deformed
    state is placed at distance ``rho`` from the axis: r = f_φ ρ,
    ψ = arcsin(ρ f_φ κ_φ) (so sin ψ/r = κ_φ) and ψ' = f_s κ_s.  The energy
    density of Materials and Methods, Eq. 7.

    Returns
    -------
    float or (float, Strains)
        e, and with ``return_strains`` the strains it came from.
    """
    prof = Profiles(f_s0, f_phi0, kappa_s0, 0.0)
    s = rho * d.f_phi * d.kappa_phi
    if not abs(s) <= 1:
        raise ValueError("rho * f_phi * kappa_phi must lie in [-1, 1]; choose a smaller rho")
    E = _energy.strains(rho, d.f_phi * rho, float(np.arcsin(s)), d.f_s, d.f_s * d.kappa_s, prof)
    E = _energy.Strains(*(float(v) for v in E))
    eta = float(prof.eta(h))
    coeffs = _coefficients.evaluate(eta, theory)
    e = float(_energy.density(E, h, coeffs, C=C_PER_MU * mu))
    return (e, E) if return_strains else e


def energies(f_s0: float, f_phi0: float, kappa_s0: float, h: float, direction,
             amplitude: float, mu: float = 1.0, theory: str = "large_bending",
             nodes: int = DEFAULT_NODES) -> tuple[float, float]:
    """Exact and quadratic energy per undeformed area along a strain direction.

    Parameters
    ----------
    f_s0, f_phi0, kappa_s0, h : float
        Intrinsic state (κ_φ⁰ = 0); η = κ_s⁰h/(2f_s⁰f_φ⁰) must satisfy abs(η) < 1.
    direction : sequence of 4 floats
        (E_s, E_φ, h⁰K̂_s, h⁰K̂_φ) (theory document section 4).
    amplitude : float
        Strain amplitude A; the strains are A · direction.

    Returns
    -------
    exact, quadratic : float
        :func:`exact_density` and :func:`shell_density` of the same deformed
        state.  Their relative difference is O(A) if the coefficients are the
        second-order expansion of the three-dimensional model.
    """
    d = deformed_state(f_s0, f_phi0, kappa_s0, h, direction, amplitude)
    return (exact_density(f_s0, f_phi0, kappa_s0, h, d, mu=mu, nodes=nodes),
            shell_density(f_s0, f_phi0, kappa_s0, h, d, mu=mu, theory=theory))
