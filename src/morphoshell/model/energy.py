"""Strains and energy density of the morphoelastic shell: the one source of truth.

Paper, Materials and Methods, Eqs. (5)–(7), with the coefficients of
:mod:`morphoshell.model.coefficients` and this project's normalisation (documentation:
"Theory", energy):

    𝓔 = 2π ∫ e ρ ds,
    e = (C/2) { h [α_ss E_s² + 2α_sφ E_s E_φ + α_φφ E_φ²]
              + 2h² [β_ss E_s K_s + β_sφ E_s K_φ + β_φs E_φ K_s + β_φφ E_φ K_φ]
              + h³ [γ_ss K_s² + 2γ_sφ K_s K_φ + γ_φφ K_φ²] }.

Both the direct solver (:mod:`morphoshell.numerics.discretisation`) and the
boundary-value reference (:mod:`morphoshell.solvers.bvp`) evaluate the energy
through :func:`local_function`, so they minimise the same functional.  The
shape-independent data at a point are packed as
:data:`morphoshell.model.layouts.INTRINSIC`.
"""
from __future__ import annotations

from functools import lru_cache
from typing import NamedTuple

import casadi as ca
import numpy as np

from .coefficients import Coefficients
from .layouts import INTRINSIC
from .problem import Structure
from .profiles import Profiles

__all__ = ["Strains", "strains", "kinematics", "density", "pointwise", "intrinsic_function",
           "local_function", "LOCAL_OUTPUTS", "parameter_symbols", "boundary_layer_width",
           "unpack_intrinsic", "optimal_controls", "intrinsic_values", "CACHE_SIZE"]

#: Compiled functions kept per structure (least recently used are dropped).
CACHE_SIZE = 32


def _sin(x):
    return ca.sin(x) if isinstance(x, (ca.SX, ca.MX, ca.DM)) else np.sin(x)


def boundary_layer_width(h):
    """δ = √ε, ε = h/√12: width of the bending boundary layer at a free edge.

    Supplementary, toy problem 2, "Asymptotic solution": the ratio of bending
    to stretching stiffness sets ε; a free edge relaxes over s − Σ = O(δ).
    Works on floats, arrays and CasADi expressions.
    """
    return (h / np.sqrt(12)) ** 0.5


class Strains(NamedTuple):
    """The shell strains E_s, E_φ and curvature strains K_s, K_φ (Materials and Methods, Eq. 6).

    Floats, arrays of one shape, or CasADi expressions.
    """

    E_s: object
    E_phi: object
    K_s: object
    K_phi: object


def kinematics(rho, r, psi, f_s, dpsi) -> dict:
    """Stretches and curvatures of the deformed meridian (Materials and Methods, Eq. 5).

    f_φ = r/ρ, κ_s = ψ'/f_s, κ_φ = sin ψ / r.

    Parameters
    ----------
    rho, r, psi, f_s, dpsi
        ρ(s), r(s), ψ(s), f_s = dS/ds and ψ' = dψ/ds: floats, arrays of one
        shape, or CasADi expressions.

    Returns
    -------
    dict
        ``f_phi``, ``kappa_s``, ``kappa_phi``, of the inputs' shape.
    """
    return {"f_phi": r / rho, "kappa_s": dpsi / f_s, "kappa_phi": _sin(psi) / r}


def strains(rho, r, psi, f_s, dpsi, prof: Profiles) -> Strains:
    """Stretching and bending strains (Materials and Methods, Eq. 6).

    Uses f_s κ_s = ψ' and f_φ κ_φ = sin ψ / ρ, so nothing is divided by r.

    Parameters
    ----------
    rho, r, psi, f_s, dpsi
        As for :func:`kinematics`.
    prof : Profiles
        The intrinsic stretches and curvatures there.

    Returns
    -------
    Strains
        Of the inputs' shape.
    """
    f_phi = kinematics(rho, r, psi, f_s, dpsi)["f_phi"]
    return Strains(
        E_s=(f_s - prof.f_s0) / prof.f_s0,
        E_phi=(f_phi - prof.f_phi0) / prof.f_phi0,
        K_s=(dpsi - prof.f_s0 * prof.kappa_s0) / (prof.f_s0**2 * prof.f_phi0),
        K_phi=(_sin(psi) / rho - prof.f_phi0 * prof.kappa_phi0) / (prof.f_s0 * prof.f_phi0**2),
    )


def density(E: Strains, h, c: Coefficients, C=1.0):
    """Energy per undeformed area e (Materials and Methods, Eq. 7, project normalisation).

    Parameters
    ----------
    E : Strains
    h : float or CasADi expression
        Relative thickness.
    c : Coefficients
        α, β, γ at η (:mod:`morphoshell.model.coefficients`).
    C : float
        The material parameter (energies in units of C).

    Returns
    -------
    float, ndarray or CasADi expression
        e, of the strains' shape.
    """
    Es, Ep, Ks, Kp = E
    stretching = c.alpha_ss * Es**2 + 2 * c.alpha_sphi * Es * Ep + c.alpha_phiphi * Ep**2
    coupling = (c.beta_ss * Es * Ks + c.beta_sphi * Es * Kp
                + c.beta_phis * Ep * Ks + c.beta_phiphi * Ep * Kp)
    bending = c.gamma_ss * Ks**2 + 2 * c.gamma_sphi * Ks * Kp + c.gamma_phiphi * Kp**2
    return C / 2 * (h * stretching + 2 * h**2 * coupling + h**3 * bending)


#: Outputs of :func:`local_function`, in order.
LOCAL_OUTPUTS = ("L", "e", "E_s", "E_phi", "K_s", "K_phi", "N_s", "N_phi", "M_s", "M_phi",
                 "f_phi", "kappa_s", "kappa_phi", *INTRINSIC.names)


def unpack_intrinsic(I) -> tuple:
    """(ρ, Profiles, η, Coefficients) from an ``INTRINSIC`` vector."""
    v = INTRINSIC.unpack(I)
    return (v["rho"], Profiles(*[v[n] for n in Profiles._fields]), v["eta"],
            Coefficients(*[v[n] for n in Coefficients._fields]))


def parameter_symbols(structure: Structure) -> tuple[ca.SX, dict]:
    """Symbolic parameter vector p (``structure.parameters``) and its named entries."""
    layout = structure.parameters
    p = ca.SX.sym("p", len(layout))
    return p, layout.unpack(p)


@lru_cache(maxsize=CACHE_SIZE)
def intrinsic_function(structure: Structure) -> ca.Function:
    """``(s, p) -> I``: everything at s that does not depend on the shape (``INTRINSIC``).

    ρ(s), the intrinsic profiles, η and the coefficients α, β, γ(η) depend
    only on s and the parameters; the direct solver evaluates them once per
    solve rather than in every Ipopt callback.
    """
    geo, fam = structure.geometry, structure.family
    s = ca.SX.sym("s")
    p, named = parameter_symbols(structure)
    prof = fam.build(s, {n: named[n] for n in fam.parameters}, named["cut"],
                     geo.length - named["opening"])
    eta = prof.eta(named["h"])
    return ca.Function("intrinsic", [s, p], [ca.vertcat(geo.rho(s), *prof, eta,
                                                        *structure.theory(eta))],
                       ["s", "p"], ["I"])


def pointwise(r, psi, f_s, dpsi, I, h) -> dict:
    """Energy integrand L = 2πρe, e, strains, resultants and kinematics from ``I``.

    Materials and Methods, Eqs. 5-7, at one point: ``I`` the point's
    :data:`~morphoshell.model.layouts.INTRINSIC` vector, h the thickness.

    Returns
    -------
    dict
        CasADi expressions by the names of :data:`LOCAL_OUTPUTS` (but the
        intrinsic ones).
    """
    rho, prof, _, coeffs = unpack_intrinsic(I)
    E = strains(rho, r, psi, f_s, dpsi, prof)
    # Resultants from the same density, differentiated with respect to the strains.
    Esym = Strains(*(ca.SX.sym(n) for n in Strains._fields))
    grads = ca.gradient(density(Esym, h, coeffs), ca.vertcat(*Esym))
    grads = ca.substitute(grads, ca.vertcat(*Esym), ca.vertcat(*E))
    e = density(E, h, coeffs)
    return {"L": 2 * ca.pi * rho * e, "e": e, **E._asdict(),
            **dict(zip(("N_s", "N_phi", "M_s", "M_phi"), ca.vertsplit(grads))),
            **kinematics(rho, r, psi, f_s, dpsi)}


def optimal_controls(L, f, u, psi, lam_r, lam_psi):
    """The controls (f_s, ψ') that make the Hamiltonian stationary, given the costates.

    Pontryagin's principle for the optimal-control form of the energy, with states
    (r, ψ), controls (f_s, u = ψ') and costates (λ_r, λ_ψ) (documentation: "Theory",
    governing equations):

        H = L + λ_r f_s cos ψ + λ_ψ u,    ∂H/∂(f_s, u) = 0.

    H is quadratic in the controls, so they follow from a 2×2 linear solve.  The
    boundary-value reference (:func:`morphoshell.solvers.bvp.pontryagin_functions`)
    and the direct route's nodal fields (:mod:`morphoshell.numerics.cell_kernels`,
    ``"node"``) both use this one formula.

    Parameters
    ----------
    L : casadi.SX
        The integrand L = 2πρe as an expression of the symbols ``f`` and ``u``.
    f, u : casadi.SX
        The symbols of f_s and ψ' in ``L``.
    psi, lam_r, lam_psi : casadi.SX
        ψ and the costates.

    Returns
    -------
    H : casadi.SX
        The Hamiltonian.
    controls : casadi.SX, shape (2,)
        (f_s, ψ'), free of ``f`` and ``u``.
    """
    H = L + lam_r * f * ca.cos(psi) + lam_psi * u
    w = ca.vertcat(f, u)
    Hw = ca.gradient(H, w)
    A = ca.jacobian(Hw, w)  # independent of (f, u): H is quadratic in them
    b = ca.substitute(Hw, w, ca.DM.zeros(2))
    det = A[0, 0] * A[1, 1] - A[0, 1] * A[1, 0]
    return H, -ca.vertcat(A[1, 1] * b[0] - A[0, 1] * b[1],
                          A[0, 0] * b[1] - A[1, 0] * b[0]) / det


def intrinsic_values(theory, rho, profiles: dict) -> np.ndarray:
    """:func:`intrinsic_function`'s data in numbers, from ρ and the profiles at some points.

    ``profiles`` as :meth:`~morphoshell.model.problem.Problem.profiles` returns them (the
    four profiles and η), the coefficients from ``theory``
    (:meth:`~morphoshell.model.coefficients.Theory.evaluate`): the same quantities from
    the problem's numerical evaluators, so that nothing is built per structure.

    Returns
    -------
    ndarray, shape (len(INTRINSIC), N)
        Rows in the order of :data:`~morphoshell.model.layouts.INTRINSIC`.
    """
    values = {"rho": rho, **profiles, **theory.evaluate(profiles["eta"])._asdict()}
    return np.array([values[n] for n in INTRINSIC.names], dtype=float)


@lru_cache(maxsize=CACHE_SIZE)
def local_function(structure: Structure) -> ca.Function:
    """Pointwise energy ``(s, r, psi, f_s, dpsi, p) -> LOCAL_OUTPUTS``.

    ``L = 2π ρ e`` is the integrand of the total energy; N_a = ∂e/∂E_a and
    M_a = ∂e/∂K_a are the stress and moment resultants (units of C, with the
    paper's bending strains K).  Calling it with row vectors evaluates it at
    many points at once.
    """
    s, r, psi, f_s, dpsi = (ca.SX.sym(n) for n in ("s", "r", "psi", "f_s", "dpsi"))
    p, named = parameter_symbols(structure)
    I = intrinsic_function(structure)(s, p)
    out = pointwise(r, psi, f_s, dpsi, I, named["h"])
    n_shape = len(LOCAL_OUTPUTS) - len(INTRINSIC)
    outs = [out[k] for k in LOCAL_OUTPUTS[:n_shape]] + ca.vertsplit(I)
    return ca.Function(f"local_{structure.family.name}_{structure.theory.name}",
                       [s, r, psi, f_s, dpsi, p], outs,
                       ["s", "r", "psi", "f_s", "dpsi", "p"], list(LOCAL_OUTPUTS))
