"""Coefficients α, β, γ of the shell energy as functions of η.

The paper (Materials and Methods, Eq. 7) uses the large-bending shell theory of
Haas & Goldstein (PRE 103, 022411, 2021), whose printed coefficient formulas
(their Eqs. 58 and 64) are not available to this project.  The closed forms
below were **re-derived** from three-dimensional incompressible
morphoelasticity (documentation: "Theory", large-bending coefficients; the
through-thickness check is :func:`morphoshell.mechanics.thickness.exact_density`).  They
are the project's definition.

A *theory* is a function ``eta -> Coefficients`` that works on CasADi
expressions; :data:`THEORIES` maps theory names to :class:`Theory` objects and
:func:`register_theory` adds another set without touching the rest of the code.

Conventions
-----------
η = κ_s⁰ h / (2 f_s⁰ f_φ⁰), abs(η) < 1.  α and γ are even in η, β is odd.
β_ab multiplies E_a K_b, and enters the energy with a factor 2 (see
:func:`morphoshell.model.energy.density`).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, NamedTuple

import casadi as ca
import numpy as np

from .._runtime.compiled import PointEvaluator
from .._runtime.validate import lookup

__all__ = [
    "Coefficients", "Theory", "large_bending", "classical", "THEORIES", "register_theory",
    "get_theory", "evaluate", "SERIES_SWITCH",
]


class Coefficients(NamedTuple):
    """The ten independent coefficients (α_sφ = α_φs and γ_sφ = γ_φs)."""

    alpha_ss: object
    alpha_sphi: object
    alpha_phiphi: object
    beta_ss: object
    beta_sphi: object
    beta_phis: object
    beta_phiphi: object
    gamma_ss: object
    gamma_sphi: object
    gamma_phiphi: object


#: abs(η) below which the series branch is used.  With the series to η¹² the
#: truncation error there is ~η¹⁴ ≈ 1e-14, while the closed forms lose about
#: two digits to cancellation (terms ~1/(8η²) ≈ 12 against results ~0.08).
SERIES_SWITCH = 0.1


def _F(p: int, q: int) -> float:
    """The rational p/q, correctly rounded (= float(Fraction(p, q)), without
    importing fractions at every start-up)."""
    return p / q


# Taylor coefficients of the closed forms in powers of η (exact rationals,
# expanded with sympy): α, γ even up to η¹², β odd up to η¹³.
_SERIES = {
    "alpha_ss": [1, 2, 3, 4, 5, 6, 7],
    "alpha_sphi": [_F(1, 2), 1, _F(3, 2), 2, _F(5, 2), 3, _F(7, 2)],
    "alpha_phiphi": [1, _F(1, 2), _F(3, 4), 1, _F(5, 4), _F(3, 2), _F(7, 4)],
    "beta_ss": [_F(-5, 12), _F(-7, 10), _F(-27, 28), _F(-11, 9), _F(-65, 44), _F(-45, 26),
                _F(-119, 60)],
    "beta_sphi": [_F(-1, 6), _F(-1, 4), _F(-1, 3), _F(-5, 12), _F(-1, 2), _F(-7, 12), _F(-2, 3)],
    "beta_phis": [_F(-5, 24), _F(-7, 20), _F(-27, 56), _F(-11, 18), _F(-65, 88), _F(-45, 52),
                  _F(-119, 120)],
    "beta_phiphi": [_F(1, 24), _F(-1, 8), _F(-1, 6), _F(-5, 24), _F(-1, 4), _F(-7, 24), _F(-1, 3)],
    "gamma_ss": [_F(1, 12), _F(13, 80), _F(13, 56), _F(43, 144), _F(4, 11), _F(89, 208),
                 _F(59, 120)],
    "gamma_sphi": [_F(1, 24), _F(7, 120), _F(9, 112), _F(11, 108), _F(65, 528), _F(15, 104),
                   _F(119, 720)],
    "gamma_phiphi": [_F(1, 12), _F(1, 48), _F(1, 36), _F(5, 144), _F(1, 24), _F(7, 144), _F(1, 18)],
}
_ODD = {"beta_ss", "beta_sphi", "beta_phis", "beta_phiphi"}


def _series(name: str, eta):
    """Horner evaluation of the series in η² (times η for the odd β)."""
    x = eta * eta
    acc = 0
    for c in reversed(_SERIES[name]):
        acc = acc * x + float(c)
    return acc * eta if name in _ODD else acc


def _closed(eta) -> Coefficients:
    """Closed forms of the coefficients (documentation: "Theory"; η ≠ 0)."""
    D = (1 - eta**2) ** 2
    L = ca.log((1 + eta) / (1 - eta))
    return Coefficients(
        alpha_ss=1 / D,
        alpha_sphi=1 / (2 * D),
        alpha_phiphi=0.75 + 1 / (4 * D),
        beta_ss=L / (8 * eta**2) - 1 / (4 * eta * D),
        beta_sphi=-eta * (2 - eta**2) / (12 * D),
        beta_phis=L / (16 * eta**2) - 1 / (8 * eta * D),
        beta_phiphi=eta * (1 - 5 * eta**2 + 3 * eta**4) / (24 * D),
        gamma_ss=(1 + 1 / D) / (16 * eta**2) - L / (16 * eta**3),
        gamma_sphi=1 / 144 + 1 / (48 * eta**2 * D) - L / (96 * eta**3),
        gamma_phiphi=(12 - 21 * eta**2 + 10 * eta**4) / (144 * D),
    )


def large_bending(eta) -> Coefficients:
    """Large-bending coefficients α, β, γ(η) for a CasADi expression ``eta``.

    Closed form for abs(η) ≥ :data:`SERIES_SWITCH`, Taylor series below it;
    both branches are CasADi expressions joined by ``if_else`` so that Ipopt
    gets exact first and second derivatives.  The closed-form branch is
    evaluated at a guarded η so that its discarded value is finite at η = 0.
    The coefficients of the energy density of Materials and Methods, Eq. 7.

    Returns
    -------
    Coefficients
        CasADi expressions of ``eta``.
    """
    small = ca.fabs(eta) < SERIES_SWITCH
    guarded = ca.if_else(small, SERIES_SWITCH, eta)
    closed = _closed(guarded)
    return Coefficients(*[
        ca.if_else(small, _series(name, eta), value)
        for name, value in zip(Coefficients._fields, closed)
    ])


def classical(eta) -> Coefficients:
    """η → 0 limit: the classical incompressible shell (Poisson ratio 1/2).

    The energy density is then E_s² + E_sE_φ + E_φ² + (h²/12)(K_s² + K_sK_φ
    + K_φ²) up to the factor C h/2 (paper, Supplementary, toy problem 2).
    """
    zero = 0 * eta
    return Coefficients(
        *[zero + float(_SERIES[name][0]) if name not in _ODD else zero
          for name in Coefficients._fields]
    )


@dataclass(frozen=True, eq=False)
class Theory:
    """A named coefficient set ``eta -> Coefficients``.

    Compared and hashed by identity: compiled functions are cached on the
    object, so registering another theory under an existing name (re-running
    a notebook cell) can never reuse the old one's functions.
    """

    name: str
    coefficients: Callable = field(repr=False)
    description: str = ""
    _cache: dict = field(default_factory=dict, repr=False)

    def __call__(self, eta) -> Coefficients:
        return self.coefficients(eta)

    def evaluate(self, eta) -> Coefficients:
        """Numerical values at ``eta`` (scalar or array, abs(eta) < 1).

        Returns
        -------
        Coefficients
            Each an ndarray of the shape of ``eta``.
        """
        eta = np.asarray(eta, dtype=float)
        if np.any(np.abs(eta) >= 1) or not np.all(np.isfinite(eta)):
            raise ValueError(f"eta must be finite with abs(eta) < 1, got {eta}")
        # compiled where available, one evaluator for every number of points: a call
        # on a row built CasADi a map each time, which cost more than the rest of a
        # result's fields (docs/benchmarks.md, "Nodal fields at the scheme's order")
        if "f" not in self._cache:
            sym = ca.SX.sym("eta")
            self._cache["f"] = PointEvaluator(ca.Function(f"coefficients_{self.name}", [sym],
                                                          list(self(sym))))
        out = self._cache["f"](eta.ravel())
        return Coefficients(*[v.reshape(eta.shape) for v in out])


#: The registered theories by name (:func:`register_theory` adds one).
THEORIES: dict[str, Theory] = {
    "large_bending": Theory("large_bending", large_bending,
                            "re-derived large-bending coefficients alpha, beta, gamma(eta)"),
    "classical": Theory("classical", classical, "eta -> 0: classical incompressible shell"),
}


def register_theory(name: str, coefficients: Callable, description: str = "") -> Theory:
    """Add (or replace) the coefficient set ``eta -> Coefficients`` under ``name``.

    Problems created afterwards use the new set; problems created before keep
    the one they were created with (:class:`Theory` objects are compared by
    identity, so no cached function of the old set is reused).
    """
    if not name or not isinstance(name, str):
        raise ValueError(f"theory name must be a non-empty string, got {name!r}")
    if not callable(coefficients):
        raise ValueError(f"theory {name!r}: coefficients must be callable eta -> Coefficients")
    THEORIES[name] = theory = Theory(name, coefficients, description)
    return theory


def get_theory(name: "str | Theory") -> Theory:
    """The registered :class:`Theory` called ``name`` (a Theory is returned as is)."""
    if isinstance(name, Theory):
        return name
    return lookup(THEORIES, name, "theory")


def evaluate(eta, theory: "str | Theory" = "large_bending") -> Coefficients:
    """Numerical values of the coefficients at ``eta`` (scalar or array).

    Returns
    -------
    Coefficients
        Each an ndarray of the shape of ``eta`` (:meth:`Theory.evaluate`).
    """
    return get_theory(theory).evaluate(eta)
