"""Strains and energy density of the morphoelastic shell: the one source of truth.

Paper, Materials and Methods, Eqs. (5)–(7), with the coefficients of
:mod:`morphoshell.coefficients` and the normalisation of
``large_bending_theory.md`` section 2:

    𝓔 = 2π ∫ e ρ ds,
    e = (C/2) { h [α_ss E_s² + 2α_sφ E_s E_φ + α_φφ E_φ²]
              + 2h² [β_ss E_s K_s + β_sφ E_s K_φ + β_φs E_φ K_s + β_φφ E_φ K_φ]
              + h³ [γ_ss K_s² + 2γ_sφ K_s K_φ + γ_φφ K_φ²] }.

Both the direct solver (:mod:`morphoshell.discretisation`) and the
boundary-value reference (:mod:`morphoshell.reference`) evaluate the energy
through :func:`local_function`, so they minimise the same functional.
"""
from __future__ import annotations

from typing import NamedTuple

import casadi as ca

from .coefficients import Coefficients, get_theory
from .geometry import get_geometry
from .problem import Structure
from .profiles import Profiles, get_family

__all__ = ["Strains", "strains", "eta", "density", "pointwise", "intrinsic_function",
           "local_function", "LOCAL_OUTPUTS", "INTRINSIC", "parameter_symbols"]


class Strains(NamedTuple):
    E_s: object
    E_phi: object
    K_s: object
    K_phi: object


def strains(rho, r, psi, f_s, dpsi, prof: Profiles) -> Strains:
    """Stretching and bending strains (paper, Eq. 6).

    Uses f_s κ_s = ψ' and f_φ κ_φ = sin ψ / ρ, so nothing is divided by r.
    """
    f_phi = r / rho
    return Strains(
        E_s=(f_s - prof.f_s0) / prof.f_s0,
        E_phi=(f_phi - prof.f_phi0) / prof.f_phi0,
        K_s=(dpsi - prof.f_s0 * prof.kappa_s0) / (prof.f_s0**2 * prof.f_phi0),
        K_phi=(ca.sin(psi) / rho - prof.f_phi0 * prof.kappa_phi0) / (prof.f_s0 * prof.f_phi0**2),
    )


def eta(h, prof: Profiles):
    """Large-bending parameter η = κ_s⁰ h / (2 f_s⁰ f_φ⁰)."""
    return prof.kappa_s0 * h / (2 * prof.f_s0 * prof.f_phi0)


def density(E: Strains, h, c: Coefficients, C=1.0):
    """Energy per undeformed area e (paper Eq. 7, project normalisation)."""
    Es, Ep, Ks, Kp = E
    stretching = c.alpha_ss * Es**2 + 2 * c.alpha_sphi * Es * Ep + c.alpha_phiphi * Ep**2
    coupling = (c.beta_ss * Es * Ks + c.beta_sphi * Es * Kp
                + c.beta_phis * Ep * Ks + c.beta_phiphi * Ep * Kp)
    bending = c.gamma_ss * Ks**2 + 2 * c.gamma_sphi * Ks * Kp + c.gamma_phiphi * Kp**2
    return C / 2 * (h * stretching + 2 * h**2 * coupling + h**3 * bending)


#: Parameter-only quantities at a point, in order (see :func:`intrinsic_function`).
INTRINSIC = ("rho", "f_s0", "f_phi0", "kappa_s0", "kappa_phi0", "eta", *Coefficients._fields)

#: Outputs of :func:`local_function`, in order.
LOCAL_OUTPUTS = ("L", "e", "E_s", "E_phi", "K_s", "K_phi", "N_s", "N_phi", "M_s", "M_phi",
                 *INTRINSIC)


def parameter_symbols(structure: Structure) -> tuple[ca.SX, dict]:
    """Symbolic NLP parameter vector [h, Σ, P, family...] and its named entries."""
    fam = get_family(structure.family)
    p = ca.SX.sym("p", 3 + len(fam.parameters))
    named = {"h": p[0], "cut": p[1], "opening": p[2]}
    named.update({n: p[3 + i] for i, n in enumerate(fam.parameters)})
    return p, named


_CACHE: dict[tuple, ca.Function] = {}


def intrinsic_function(structure: Structure) -> ca.Function:
    """``(s, p) -> INTRINSIC``: everything at s that does not depend on the shape.

    ρ(s), the intrinsic profiles, η and the coefficients α, β, γ(η) depend
    only on s and the parameters; the direct solver evaluates them once per
    solve rather than in every Ipopt callback.
    """
    key = ("intrinsic", structure)
    if key not in _CACHE:
        geo = get_geometry(structure.geometry)
        fam = get_family(structure.family)
        s = ca.SX.sym("s")
        p, named = parameter_symbols(structure)
        prof = fam.build(s, {n: named[n] for n in fam.parameters}, named["cut"],
                         geo.length - named["opening"])
        eta_ = eta(named["h"], prof)
        coeffs = get_theory(structure.theory)(eta_)
        _CACHE[key] = ca.Function("intrinsic", [s, p], [ca.vertcat(geo.rho(s), *prof, eta_, *coeffs)],
                                  ["s", "p"], ["I"])
    return _CACHE[key]


def pointwise(r, psi, f_s, dpsi, I, h) -> dict:
    """Energy integrand L = 2πρe, e, strains and resultants from the intrinsic data I."""
    rho, prof, coeffs = I[0], Profiles(*[I[1 + i] for i in range(4)]), Coefficients(*[I[6 + i] for i in range(10)])
    E = strains(rho, r, psi, f_s, dpsi, prof)
    # Resultants from the same density, differentiated with respect to the strains.
    Esym = Strains(*(ca.SX.sym(n) for n in Strains._fields))
    grads = ca.gradient(density(Esym, h, coeffs), ca.vertcat(*Esym))
    grads = ca.substitute(grads, ca.vertcat(*Esym), ca.vertcat(*E))
    e = density(E, h, coeffs)
    return {"L": 2 * ca.pi * rho * e, "e": e, **E._asdict(),
            **dict(zip(("N_s", "N_phi", "M_s", "M_phi"), ca.vertsplit(grads)))}


def local_function(structure: Structure) -> ca.Function:
    """Pointwise energy ``(s, r, psi, f_s, dpsi, p) -> LOCAL_OUTPUTS``.

    ``L = 2π ρ e`` is the integrand of the total energy; N_a = ∂e/∂E_a and
    M_a = ∂e/∂K_a are the stress and moment resultants (units of C, with the
    paper's bending strains K).  Calling it with row vectors evaluates it at
    many points at once.
    """
    key = ("local", structure)
    if key not in _CACHE:
        s, r, psi, f_s, dpsi = (ca.SX.sym(n) for n in ("s", "r", "psi", "f_s", "dpsi"))
        p, _ = parameter_symbols(structure)
        I = intrinsic_function(structure)(s, p)
        out = pointwise(r, psi, f_s, dpsi, I, p[0])
        outs = [out[k] for k in LOCAL_OUTPUTS[:10]] + ca.vertsplit(I)
        _CACHE[key] = ca.Function(f"local_{structure.family}_{structure.theory}",
                                  [s, r, psi, f_s, dpsi, p], outs,
                                  ["s", "r", "psi", "f_s", "dpsi", "p"], list(LOCAL_OUTPUTS))
    return _CACHE[key]
