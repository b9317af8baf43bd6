"""Asymptotic predictions of the paper's toy problems 1 and 2.

Every function cites the part of the paper (Haas & Höhn, *Cut it out*: main
text or Supplementary, by section title) it implements, validates its input (ValueError naming
the offending value) and accepts NumPy arrays wherever the formula is
elementwise; scalar input gives a Python float.

Conventions
-----------
* Lengths are scaled by the undeformed radius R, h = H/R.
* Toy problem 2: ε = h/√12 and δ = √ε (Supplementary, "Asymptotic
  solution"); Σ ∈ (0, π) is the half-angle of the ablation and σ = Σ/δ its
  size on the scale of the inner region; ς = 3^{1/4}σ/√2.
* Signs follow the paper: the opening o and rotation ϱ are positive when the
  rim curls outwards (k < 1); the displacement d is a magnitude.
* Kelvin functions follow Abramowitz & Stegun / DLMF §10.61, which is the
  convention of the paper's derivation ("Approximate solution for small
  ablations"): ker_ν(x) + i kei_ν(x) = e^{−iνπ/2} K_ν(x e^{iπ/4}).
"""
from __future__ import annotations

import functools
import math
import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy import special

from ..model.energy import boundary_layer_width
from ..model.profiles import check_curvature

__all__ = [
    "f_shell_exact", "f_shell_asymptotic", "f_bulk_asymptotic", "k_star",
    "delta", "opening", "rotation", "displacement", "b_inner", "kelvin_k",
    "rotation_small_cut", "displacement_small_cut", "VARSIGMA_LIMITS", "energy_released",
    "recoil_velocity", "predictions", "ENERGY_UNITS",
    "InnerSolution", "inner_solution", "inner_problem", "inner_recoil", "INNER_LENGTH",
]

#: Accepted ``units`` of :func:`energy_released`.
ENERGY_UNITS = ("morphoshell", "paper")

_SQRT2 = math.sqrt(2.0)


# --------------------------------------------------------------------------
# input validation
# --------------------------------------------------------------------------

def _array(name: str, value: Any) -> np.ndarray:
    if isinstance(value, (bool, np.bool_)) or (
            isinstance(value, np.ndarray) and value.dtype == bool):
        raise ValueError(f"{name} = {value!r} must be a real number")
    if np.iscomplexobj(value):
        raise ValueError(f"{name} = {value!r} must be a real number")
    try:
        return np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{name} = {value!r} must be a real number") from None


def _first_bad(arr: np.ndarray, bad: np.ndarray) -> float:
    return float(arr[bad].flat[0]) if arr.ndim else float(arr)


def _finite(name: str, value: Any) -> np.ndarray:
    arr = _array(name, value)
    bad = ~np.isfinite(arr)
    if np.any(bad):
        raise ValueError(f"{name} = {_first_bad(arr, bad)!r} must be finite")
    return arr


def _positive(name: str, value: Any) -> np.ndarray:
    arr = _finite(name, value)
    bad = arr <= 0
    if np.any(bad):
        raise ValueError(f"{name} = {_first_bad(arr, bad)!r} must be positive")
    return arr


def _angle(name: str, value: Any) -> np.ndarray:
    arr = _finite(name, value)
    bad = (arr <= 0) | (arr >= math.pi)
    if np.any(bad):
        raise ValueError(f"{name} = {_first_bad(arr, bad)!r} must lie in (0, pi)")
    return arr


def _out(value):
    """Python float for 0-d results, ndarray otherwise."""
    value = np.asarray(value)
    return float(value) if value.ndim == 0 else value


def _cut_alias(func):
    """Accept the deprecated keyword ``Sigma=`` for ``cut=`` (the one name of the cut)."""
    @functools.wraps(func)
    def wrapper(*args, **kwargs):
        if "Sigma" in kwargs:
            if "cut" in kwargs:
                raise TypeError(f"{func.__name__}() got both cut and its deprecated alias Sigma")
            warnings.warn(f"{func.__name__}(Sigma=...) is deprecated: the cut is called cut",
                          DeprecationWarning, stacklevel=2)
            kwargs["cut"] = kwargs.pop("Sigma")
        return func(*args, **kwargs)
    return wrapper


def _material(c10: Any, c01: Any) -> tuple[float, float]:
    c10 = float(_finite("c10", c10))
    c01 = float(_finite("c01", c01))
    if c10 + c01 <= 0:
        # Supplementary, toy problem 1: a positive bulk modulus needs
        # C₁₀ + C₀₁ > 0, and the result for f (Supplementary, toy problem 1) divides by it.
        raise ValueError(f"c10 + c01 = {c10 + c01!r} must be positive")
    return c10, c01


# --------------------------------------------------------------------------
# toy problem 1
# --------------------------------------------------------------------------

def _f_shell_exact_scalar(h: float, k: float) -> float:
    c = h * h / 12
    # Stationarity of (f − 1)² + c(1/f − k)², multiplied by f³/2 and written
    # for F = f − 1 so that F = O(h²) keeps full relative precision.
    def g(F):
        return F * (1 + F) ** 3 - c * (1 - k - k * F)

    F0 = -c * (k - 1)
    width = abs(F0) + c
    for _ in range(200):
        lo, hi = max(F0 - width, -1 + 1e-12), F0 + width
        if g(lo) <= 0 <= g(hi):
            break
        width *= 2
    else:  # pragma: no cover - g(−1) < 0 < g(∞) always brackets
        raise ValueError(f"no stationary radius for h = {h!r}, k = {k!r}")
    from scipy.optimize import brentq  # (on use: 0.3 s to import)

    F = brentq(g, lo, hi, xtol=1e-20 * c, rtol=4 * np.finfo(float).eps, maxiter=500) \
        if g(lo) != 0 and g(hi) != 0 else (lo if g(lo) == 0 else hi)
    f = 1 + F
    curvature = 2 + (h * h / 6) * (1 / f**4 + 2 * (1 / f - k) / f**3)
    if curvature <= 0:
        raise ValueError(
            f"the stationary radius f = {f!r} for h = {h!r}, k = {k!r} is not a minimum")
    return f


def f_shell_exact(h, k):
    """Exact minimiser of the shell energy of toy problem 1 (main text, toy problem 1:
    E² + (h²/12)K²).

    Minimises (f − 1)² + (h²/12)(1/f − k)² over the deformed radius f.  The
    stationarity condition f³(f − 1) = (h²/12)(1 − kf) is solved for f − 1
    with Brent's method to relative precision 4·eps, on the branch that
    continues f = 1 from h = 0 (the only one for h ≪ 1).

    Parameters
    ----------
    h : float or array_like
        Relative thickness, positive.
    k : float or array_like
        Intrinsic curvature (broadcast against h).

    Returns
    -------
    float or ndarray
        The deformed radius f.

    Raises
    ------
    ValueError
        If h ≤ 0 or any value is not finite, or if the stationary point is
        not a minimum (only possible for h = O(1)).
    """
    h = _positive("h", h)
    k = _finite("k", k)
    hb, kb = np.broadcast_arrays(h, k)
    out = np.array([_f_shell_exact_scalar(float(a), float(b))
                    for a, b in zip(hb.ravel(), kb.ravel())]).reshape(hb.shape)
    return _out(out)


def f_shell_asymptotic(h, k):
    """Shell-theory prediction f ~ 1 − h²(k − 1)/12 (main text, toy problem 1)."""
    h = _positive("h", h)
    k = _finite("k", k)
    return _out(1 - h * h * (k - 1) / 12)


def f_bulk_asymptotic(h, k, c10, c01):
    """Bulk-elasticity prediction for the deformed radius (Supplementary, toy problem 1,
    "Next-order calculation").

    f = 1 − (h²/12)(k − 1)[(11C₁₀ + 7C₀₁) − (5C₁₀ + C₀₁)k] / (2(C₁₀ + C₀₁)).
    The remainder is printed as O(h³); it is in fact O(h⁴) because f is
    even in h (see :mod:`morphoshell.mechanics.bulk`).

    Parameters
    ----------
    h : float or array_like
        Relative thickness, positive.
    k : float or array_like
        Intrinsic curvature.
    c10, c01 : float
        Mooney–Rivlin coefficients C₁₀, C₀₁ with C₁₀ + C₀₁ > 0.

    Returns
    -------
    float or ndarray
        f, of the broadcast shape of h and k.
    """
    h = _positive("h", h)
    k = _finite("k", k)
    c10, c01 = _material(c10, c01)
    bracket = (11 * c10 + 7 * c01) - (5 * c10 + c01) * k
    return _out(1 - (h * h / 12) * (k - 1) * bracket / (2 * (c10 + c01)))


def k_star(c10, c01) -> float:
    """Second zero k* = (11C₁₀ + 7C₀₁)/(5C₁₀ + C₀₁) of the O(h²) correction to f (Supplementary,
    toy problem 1, "Surprising mechanical behaviour").

    Supplementary, "Surprising mechanical behaviour":
    k* = 1 + 6(C₁₀ + C₀₁)/(5C₁₀ + C₀₁), so k* > 1 iff 5C₁₀ + C₀₁ > 0.

    Raises
    ------
    ValueError
        If C₁₀ + C₀₁ ≤ 0, or if 5C₁₀ + C₀₁ = 0 (the correction then vanishes
        only at k = 1 and k* does not exist).
    """
    c10, c01 = _material(c10, c01)
    denominator = 5 * c10 + c01
    if denominator == 0:
        raise ValueError(
            f"5*c10 + c01 = 0 (c10 = {c10!r}, c01 = {c01!r}): the O(h^2) correction to f is then "
            "linear in k and has no second zero k*")
    return (11 * c10 + 7 * c01) / denominator


# --------------------------------------------------------------------------
# toy problem 2, Σ = O(1)
# --------------------------------------------------------------------------

def delta(h):
    """Width δ = √ε = (h/√12)^{1/2} of the inner region (Supplementary,
    "Asymptotic solution", toy problem 2)."""
    h = _positive("h", h)
    return _out(boundary_layer_width(h))


@_cut_alias
def opening(h, k, cut):
    """Cut opening o ~ h(1 − k) sin Σ (Supplementary, toy problem 2, "Cut opening"; main text).

    Twice the radial displacement of the rim across the inner region;
    positive when the rim curls outwards (k < 1).
    """
    h = _positive("h", h)
    k = _finite("k", k)
    cut = _angle("cut Sigma", cut)
    return _out(h * (1 - k) * np.sin(cut))


def rotation(h, k):
    """Leading-order cut rotation ϱ ~ δ b(0) = √(3h/2)(1 − k), radians (Supplementary,
    toy problem 2, "Cut rotation and cut displacement").

    Independent of Σ; valid for δ ≪ Σ (see :func:`rotation_small_cut`).
    """
    h = _positive("h", h)
    k = _finite("k", k)
    return _out(np.sqrt(1.5 * h) * (1 - k))


def displacement(h, k):
    """Leading-order cut displacement d ~ (h/2)|1 − k|, units of R (Supplementary, toy
    problem 2, "Cut rotation and cut displacement").

    Independent of Σ; valid for δ ≪ Σ (see :func:`displacement_small_cut`).
    """
    h = _positive("h", h)
    k = _finite("k", k)
    return _out(0.5 * h * np.abs(1 - k))


def b_inner(xi, k):
    """Leading-order inner solution b(ξ) (Supplementary, toy problem 2, "Asymptotic solution").

    b(ξ) = −3^{3/4}(k − 1) e^{−3^{1/4}ξ/2} cos(3^{1/4}ξ/2), the solution of
    4b'''' + 3b = 0 with 2b'(0) = 3(k − 1), b''(0) = 0, b → 0 as ξ → ∞; the
    tangent angle is ψ = s + δ b + O(δ²) with s = Σ + δξ.  The shell occupies
    ξ ≥ 0, but the expression is evaluated for any finite ξ.
    """
    xi = _finite("xi", xi)
    k = _finite("k", k)
    q = 3**0.25 * xi / 2
    return _out(-(3**0.75) * (k - 1) * np.exp(-q) * np.cos(q))


# --------------------------------------------------------------------------
# toy problem 2, Σ = O(δ): Kelvin-function approximation
# --------------------------------------------------------------------------

def _kelvin_scaled(x: np.ndarray):
    """(ker₀ + i kei₀, ker₁ + i kei₁) at x > 0, both times e^{x e^{iπ/4}}.

    The common complex factor cancels in every ratio used below (they are
    built from |K₁|² and K₁ conj(K₀)) and avoids underflow for large x,
    where ker, kei ~ e^{−x/√2}.
    """
    z = x * np.exp(0.25j * math.pi)
    return special.kve(0, z), -1j * special.kve(1, z)


def kelvin_k(order: int, x):
    """Kelvin functions (ker_ν x, kei_ν x) of order ν = 0 or 1, x > 0.

    ker_ν(x) + i kei_ν(x) = e^{−iνπ/2} K_ν(x e^{iπ/4}) (DLMF 10.61.2),
    evaluated with :func:`scipy.special.kv` at complex argument; scipy has
    ker/kei only for ν = 0.  For ν = 0 this agrees with
    :func:`scipy.special.ker`, :func:`scipy.special.kei`; for ν = 1 it
    satisfies ker₁ = (ker₀' − kei₀')/√2 and kei₁ = (ker₀' + kei₀')/√2
    (DLMF 10.63.1 for K-type functions).
    """
    if order not in (0, 1):
        raise ValueError(f"order = {order!r} must be 0 or 1")
    x = _positive("x", x)
    value = np.exp(-0.5j * order * math.pi) * special.kv(order, x * np.exp(0.25j * math.pi))
    return _out(value.real), _out(value.imag)


#: ς below and above which the small-cut forms take their limits ς → 0 and ς → ∞: the
#: Kelvin functions overflow below ς ≈ 1e-154 and give NaN above 1e9 (at Σ = 0.5: h < 3e-19),
#: and the limits equal the forms to round-off here (relative corrections 1.6 ς² and
#: 3.8/ς²: 2e-16 and 4e-16).
VARSIGMA_LIMITS = (1e-8, 1e8)


def _small_cut_parts(varsigma: np.ndarray):
    """ς|K₁|², the denominator D and the displacement numerator ςN.

    With K_ν = ker_ν ς + i kei_ν ς (Supplementary, "Approximate solution for
    small ablations")::

        D  = ker₁² + kei₁² + √2 ς [ker₁(ker₀ + kei₀) + kei₁(kei₀ − ker₀)],
        N  = ker₁(kei₀ − ker₀) − kei₁(kei₀ + ker₀).

    All three are quadratic in the Kelvin functions, so the common factor of
    :func:`_kelvin_scaled` cancels in the ratios.  Outside :data:`VARSIGMA_LIMITS`
    they are replaced by their limits, as (ςP, 1, ςN): ςP/D → 1/√2 and ςN/D → 1/√2 as
    ς → ∞ (the leading-order rotation and displacement); ςP/D → ς and
    ςN/D → √2 ς² (ln(2/ς) − γ) as ς → 0, from ker₀ ≈ −ln(ς/2) − γ, kei₀ ≈ −π/4
    and ker₁ ≈ kei₁ ≈ −1/(√2 ς).
    """
    varsigma = np.asarray(varsigma, dtype=float)
    lo, hi = VARSIGMA_LIMITS
    small, large = varsigma < lo, varsigma > hi
    clipped = np.clip(varsigma, lo, hi)
    K0, K1 = _kelvin_scaled(clipped)
    ker0, kei0, ker1, kei1 = K0.real, K0.imag, K1.real, K1.imag
    P = ker1**2 + kei1**2
    D = P + _SQRT2 * clipped * (ker1 * (ker0 + kei0) + kei1 * (kei0 - ker0))
    N = ker1 * (kei0 - ker0) - kei1 * (kei0 + ker0)
    sP, sN = clipped * P, clipped * N
    if not (np.any(small) or np.any(large)):
        return sP, D, sN
    v = np.clip(varsigma, np.finfo(float).tiny, lo)      # (ς = 0 underflowed: its limit 0)
    with np.errstate(under="ignore"):
        lead = _SQRT2 * v**2 * (np.log(2 / v) - np.euler_gamma)
    sP = np.where(small, varsigma, np.where(large, 1 / _SQRT2, sP))
    sN = np.where(small, lead, np.where(large, 1 / _SQRT2, sN))
    return sP, np.where(small | large, 1.0, D), sN


def _varsigma(h: np.ndarray, Sigma: np.ndarray) -> np.ndarray:
    with np.errstate(divide="ignore"):      # δ underflowed to 0 (h < 2e-323): σ = ∞, its limit
        sigma = Sigma / boundary_layer_width(h)
    return 3**0.25 * sigma / _SQRT2


@_cut_alias
def rotation_small_cut(h, k, cut):
    """Cut rotation for small ablations Σ = O(δ) (Supplementary, "Approximate
    solution for small ablations")::

        ϱ ~ δ b(σ) = √3 ς (ker₁²ς + kei₁²ς) / D(ς) · √h (1 − k),

    with σ = Σ/δ, ς = 3^{1/4}σ/√2 and D as in :func:`_small_cut_parts`.  It
    tends to 0 as σ → 0 and to :func:`rotation` as σ → ∞; outside
    :data:`VARSIGMA_LIMITS` (at Σ = 0.5: h < 7.5e-17; or Σ ≲ 1e-8 δ), where the Kelvin
    functions over- or underflow, it is that limit's leading-order value (√3 ς √h (1 − k)
    as ς → 0), equal to the formula to round-off there.
    """
    h = _positive("h", h)
    k = _finite("k", k)
    cut = _angle("cut Sigma", cut)
    sP, D, _ = _small_cut_parts(_varsigma(h, cut))
    return _out(math.sqrt(3) * sP / D * np.sqrt(h) * (1 - k))


@_cut_alias
def displacement_small_cut(h, k, cut):
    """Cut displacement for small ablations Σ = O(δ) (Supplementary,
    "Approximate solution for small ablations")::

        d = ς [ker₁(kei₀ − ker₀) − kei₁(kei₀ + ker₀)] / (√2 D(ς)) · h |1 − k|,

    all Kelvin functions at ς = 3^{1/4}σ/√2.  It tends to 0 as σ → 0 and to
    :func:`displacement` as σ → ∞; outside :data:`VARSIGMA_LIMITS` it is that
    limit's leading-order value (ς² (ln(2/ς) − γ) h |1 − k| as ς → 0), as
    :func:`rotation_small_cut`.
    """
    h = _positive("h", h)
    k = _finite("k", k)
    cut = _angle("cut Sigma", cut)
    _, D, sN = _small_cut_parts(_varsigma(h, cut))
    return _out(sN / (_SQRT2 * D) * h * np.abs(1 - k))


# --------------------------------------------------------------------------
# toy problem 2, Σ = O(δ): the nonlinear inner problem
# --------------------------------------------------------------------------

#: The inner problem's half-line ξ ≥ 0 is truncated at ξ = INNER_LENGTH: b and n
#: decay like exp(−3^{1/4}ξ/2) (the Kelvin functions of the linearised
#: problem), e^{−26} ≈ 5e-12 at 40.
INNER_LENGTH = 40.0

#: ``solve_bvp`` tolerance of the inner problem: the scaled recoils agree with
#: those at tol = 1e-8 to a few parts in 10⁹ (tuned for σ = 0.3, 1, 3).
INNER_TOL = 1e-6

#: Recoil per unit of the inner solution (Supplementary, toy problem 2, "Approximate
#: solution for small ablations": the equations for u and v; δ = 12^{−1/4}√h):
#: ϱ/√h = 12^{−1/4} b(σ), d/h = 12^{−1/2} |∫b dξ|, o/h^{3/2} = 2·12^{−3/4} ∫[b²/2 + xb − f] dξ.
_INNER_SCALE = {"opening": 2 * 12**-0.75, "rotation": 12**-0.25, "signed_displacement": 12**-0.5}

#: (state, point) of each integral/value in the solution: w(∞), b(σ), v(∞).
_INNER_ENTRY = {"opening": (5, -1), "rotation": (0, 0), "signed_displacement": (4, -1)}

#: Powers of h that turn the scaled recoils into units of R and radians.
_INNER_POWER = {"opening": 1.5, "rotation": 0.5, "signed_displacement": 1.0}


def _inner_rhs(x, y):
    """The nonlinear inner problem as a first-order system in x = σ + ξ, with the
    integrals of u, v.

    y = (b, b', n, n', v, w): v' = b is the axial displacement (units of δ²),
    w' = b²/2 + xb − f, f = (n − xn')/3, minus the radial one (units of δ³).
    """
    b, db, n, dn = y[0], y[1], y[2], y[3]
    x2 = x * x
    return np.vstack([db, (-2 * x * db + 2 * b + x**3 * n + x2 * b * n) / (2 * x2),
                      dn, (-12 * x * dn - 6 * x * b - 3 * b**2) / (4 * x2),
                      b, b * b / 2 + x * b - (n - x * dn) / 3])


def _inner_jacobian(x, y):
    """∂(:func:`_inner_rhs`)/∂y, shape (6, 6, m): also the matrix of the tangent system."""
    b, n = y[0], y[2]
    x2 = x * x
    J = np.zeros((6, 6, np.size(x)))
    J[0, 1] = J[2, 3] = J[4, 0] = 1.0
    J[1, 0], J[1, 1], J[1, 2] = (2 + x2 * n) / (2 * x2), -1 / x, (x + b) / 2
    J[3, 0], J[3, 3] = -3 * (x + b) / (2 * x2), -3 / x
    J[5, 0], J[5, 2], J[5, 3] = b + x, -1 / 3, x / 3
    return J


def _inner_bc(sigma: float, forcing: float):
    """Its boundary conditions: n(σ) = 0, 2b'(σ) + b(σ)/σ = ``forcing``, b, n → 0;
    v(σ) = w(σ) = 0.

    ``forcing`` is 3(k − 1) for the problem and 3 for its derivative in k.
    Returns the residual and its (constant) Jacobians.
    """
    A, B = np.zeros((6, 6)), np.zeros((6, 6))
    A[0, 2] = A[2, 4] = A[3, 5] = B[4, 0] = B[5, 2] = 1.0
    A[1, 0], A[1, 1] = 1 / sigma, 2.0

    def bc(ya, yb):
        return np.array([ya[2], 2 * ya[1] + ya[0] / sigma - forcing, ya[4], ya[5], yb[0], yb[2]])
    return bc, lambda ya, yb: (A, B)


@dataclass(frozen=True, eq=False)
class InnerSolution:
    """The nonlinear inner problem solved at one (σ, k).

    Attributes
    ----------
    sigma, k : float
        Cut size σ = Σ/δ and intrinsic curvature.
    opening, rotation, signed_displacement : float
        o/h^{3/2}, ϱ/√h and d/h, the displacement with the sign of ∫b dξ
        (positive for k < 1, like ϱ); independent of h at this order.
    derivative : dict or None
        Their derivatives with respect to k (from the tangent problem: the
        same equations linearised about the solution, forcing 3), if computed.
    bvp : object
        ``solve_bvp``'s result: a warm start for nearby (σ, k).
    """

    sigma: float
    k: float
    opening: float
    rotation: float
    signed_displacement: float
    derivative: dict | None
    bvp: Any

    def __repr__(self) -> str:
        return (f"InnerSolution(sigma={self.sigma:g}, k={self.k:g}, opening={self.opening:.6g}, "
                f"rotation={self.rotation:.6g}, displacement={self.displacement:.6g})")

    @property
    def displacement(self) -> float:
        """d/h ≥ 0."""
        return abs(self.signed_displacement)

    def recoil(self, h: float) -> dict[str, float]:
        """o, ϱ, signed d in units of R and radians (and d/dk of each, keys ``d_...``)."""
        h = float(_positive("h", h))
        out = {key: getattr(self, key) * h**p for key, p in _INNER_POWER.items()}
        if self.derivative is not None:
            out |= {f"d_{key}": self.derivative[key] * h**p for key, p in _INNER_POWER.items()}
        return out


def inner_solution(sigma, k, guess: InnerSolution | None = None, derivatives: bool = True,
                   length: float = INNER_LENGTH, tol: float = INNER_TOL) -> InnerSolution:
    """Numerical solution of the nonlinear small-cut inner problem (Supplementary, toy problem 2,
    "Asymptotic governing equations for small ablations").

    4x²n'' = −12xn' − 6xb − 3b², 2x²b'' = −2xb' + 2b + x³n + x²bn on
    x = σ + ξ ≥ σ, with n(σ) = 0, 2b'(σ) + b(σ)/σ = 3(k − 1), b, n → 0
    (truncated at ξ = ``length``: b decays like exp(−3^{1/4}ξ/2)).
    The Kelvin-function formulas linearise it for large x.  With ψ = s + δb
    and the equations for u and v of "Approximate solution for small ablations"
    (du/dξ = −δ³[b²/2 + xb − f], f = (n − xn')/3, dv/dξ = δ²b):

        ϱ/√h = 12^{−1/4} b(σ),   d/h = 12^{−1/2} |∫ b dξ|,
        o/h^{3/2} = 2·12^{−3/4} ∫ [b²/2 + xb − f] dξ,

    since v ≫ u there (the rim moves axially; the paper's d), while the
    opening o = 2[u(0) − u(∞)] is the next order, with no closed form.  The
    solution is not proportional to k − 1: the problem is nonlinear.

    Parameters
    ----------
    sigma : float
        σ = Σ/δ > 0.
    k : float
        Intrinsic curvature.
    guess : InnerSolution, optional
        A solution at nearby (σ, k) to start from (its mesh is shifted to σ).
    derivatives : bool
        Also solve the tangent problem for d/dk (linear: one extra solve).
    length, tol : float
        Truncation of the half-line and ``solve_bvp``'s tolerance.

    Returns
    -------
    InnerSolution

    Raises
    ------
    ValueError
        σ ≤ 0 or a value not finite.
    RuntimeError
        ``solve_bvp`` did not converge (its message attached).
    """
    # on use: scipy.integrate (with scipy.optimize and linalg) is a third of a second that the
    # closed forms (`morphoshell asymptotics`, `sphere`) need not wait for
    from scipy.integrate import solve_bvp

    sigma = float(_positive("sigma", sigma))
    k = float(_finite("k", k))
    if guess is None:
        x = sigma + length * np.linspace(0.0, 1.0, 200) ** 2   # graded toward the rim
        y = np.zeros((6, x.size))
    else:
        x, y = guess.bvp.x - guess.bvp.x[0] + sigma, guess.bvp.y
    bc, bc_jac = _inner_bc(sigma, 3 * (k - 1))
    sol = solve_bvp(_inner_rhs, bc, x, y, fun_jac=_inner_jacobian, bc_jac=bc_jac, tol=tol,
                    max_nodes=100000)
    if sol.status != 0:
        raise RuntimeError(f"inner problem: solve_bvp failed at sigma = {sigma:g}, k = {k:g}: "
                           f"{sol.message}")
    derivative = None
    if derivatives:
        def tangent(x, z):
            return np.einsum("ijm,jm->im", _inner_jacobian(x, sol.sol(x)), z)

        bc_t, _ = _inner_bc(sigma, 3.0)
        tan = solve_bvp(tangent, bc_t, sol.x, np.zeros_like(sol.y),
                        fun_jac=lambda x, z: _inner_jacobian(x, sol.sol(x)), bc_jac=bc_jac,
                        tol=tol, max_nodes=100000)
        if tan.status != 0:
            raise RuntimeError(f"inner problem: the tangent problem failed at sigma = {sigma:g}, "
                               f"k = {k:g}: {tan.message}")
        derivative = {key: float(_INNER_SCALE[key] * tan.y[i, j])
                      for key, (i, j) in _INNER_ENTRY.items()}
    return InnerSolution(sigma, k, **{key: float(_INNER_SCALE[key] * sol.y[i, j])
                                      for key, (i, j) in _INNER_ENTRY.items()},
                         derivative=derivative, bvp=sol)


def inner_problem(sigmas, k: float = 0.0, length: float = INNER_LENGTH) -> dict[str, np.ndarray]:
    """:func:`inner_solution` for many σ (Fig. 2 E, F), by continuation from the largest σ down.

    Returns
    -------
    dict
        ``sigma`` (increasing), ``rotation`` ϱ/√h, ``displacement`` d/h and
        ``opening`` o/h^{3/2}: ndarrays of shape (n,) for the n values of
        ``sigmas``.
    """
    sigmas = np.sort(np.asarray(_positive("sigmas", sigmas), dtype=float).ravel())[::-1]
    out: dict[str, list[float]] = {"rotation": [], "displacement": [], "opening": []}
    prev = None
    for sigma in sigmas:
        prev = inner_solution(sigma, k, guess=prev, derivatives=False, length=length)
        for key in out:
            out[key].append(getattr(prev, key))
    return {"sigma": sigmas[::-1], **{key: np.array(v[::-1]) for key, v in out.items()}}


@_cut_alias
def inner_recoil(h, k, cut, guess: InnerSolution | None = None) -> InnerSolution:
    """:func:`inner_solution` at σ = Σ/δ(h) (the recoil in units of R: ``.recoil(h)``)."""
    h = float(_positive("h", h))
    cut = float(_angle("cut Sigma", cut))
    return inner_solution(cut / boundary_layer_width(h), k, guess=guess)


@_cut_alias
def energy_released(h, k, cut, units: str = "morphoshell"):
    """Energy change on ablation ΔE (Supplementary, "Recoil velocity: scaling
    argument"), deformed minus undeformed, so ≤ 0.

    The paper's ΔE = −3^{7/4} π δ⁵ (k − 1)² sin Σ is for the energy density
    E_s² + E_sE_φ + E_φ² + ε²(K_s² + K_sK_φ + K_φ²).  morphoshell's classical
    density is (h/2) times that (C = 1, see
    :func:`morphoshell.model.coefficients.classical`).

    Parameters
    ----------
    h, k, cut : float or array_like
        Thickness h = H/R (> 0), intrinsic curvature k (units of 1/R), the cut
        Σ ∈ (0, π) (its half-angle, radians).
    units : {"morphoshell", "paper"}
        ``"morphoshell"`` returns (h/2)·ΔE_paper, ``"paper"`` ΔE_paper.

    Returns
    -------
    float or ndarray
        ΔE ≤ 0, of the broadcast shape of h, k and cut.
    """
    if units not in ENERGY_UNITS:
        raise ValueError(f"units = {units!r} must be one of {ENERGY_UNITS}")
    h = _positive("h", h)
    k = _finite("k", k)
    cut = _angle("cut Sigma", cut)
    d = boundary_layer_width(h)
    # (0 − x, not −x: no negative zero at k = 1 or when δ⁵ underflows, printed "-0")
    paper = 0.0 - 3**1.75 * math.pi * d**5 * (k - 1) ** 2 * np.sin(cut)
    return _out(paper if units == "paper" else 0.5 * h * paper)


def recoil_velocity(E_over_mu, H, R, k):
    """Scaling of the initial recoil velocity V ~ (E/μ) H^{5/2} R^{−3/2} |1 − k|.

    Main text and Supplementary, "Recoil velocity: scaling argument".  This
    is dimensional and a scaling (prefactor 1): with E/μ in s⁻¹ and H, R in
    the same length unit L, V is in L/s.

    Parameters
    ----------
    E_over_mu : float or array_like
        Elastic modulus over effective viscosity, positive (s⁻¹).
    H, R : float or array_like
        Dimensional sheet thickness and radius, positive, same unit.
    k : float or array_like
        Intrinsic curvature (dimensionless, in units of 1/R).

    Returns
    -------
    float or ndarray
        V in L/s, of the broadcast shape of the inputs.
    """
    E_over_mu = _positive("E_over_mu", E_over_mu)
    H = _positive("H", H)
    R = _positive("R", R)
    k = _finite("k", k)
    return _out(E_over_mu * H**2.5 / R**1.5 * np.abs(1 - k))


@_cut_alias
def predictions(h, k, cut) -> dict:
    """All toy-problem-2 predictions for one ablation.

    Returns
    -------
    dict
        ``opening``, ``rotation``, ``displacement`` (leading order, Σ = O(1)),
        ``rotation_small_cut``, ``displacement_small_cut`` (Kelvin forms),
        ``energy_released`` (morphoshell units), ``delta`` = δ and
        ``sigma`` = Σ/δ.

    Raises
    ------
    ValueError
        h ≤ 0, k not finite, the cut outside (0, π), or |k| ≥ 2/h: a curvature the
        shell cannot have (:func:`morphoshell.model.profiles.check_curvature`), where
        the formulas gave a rotation of −387 rad (h = 0.1, k = 1000).
    """
    h_arr = _positive("h", h)
    hb, kb = np.broadcast_arrays(h_arr, _finite("k", k))
    worst = int(np.argmax(np.abs(kb) * hb))      # (of arrays, the k nearest its bound 2/h)
    check_curvature((float(kb.flat[worst]),), float(hb.flat[worst]), "predictions()",
                    "the shell", "give a k")
    cut_arr = _angle("cut Sigma", cut)
    d = delta(h)
    return {
        "opening": opening(h, k, cut),
        "rotation": rotation(h, k),
        "displacement": displacement(h, k),
        "rotation_small_cut": rotation_small_cut(h, k, cut),
        "displacement_small_cut": displacement_small_cut(h, k, cut),
        "energy_released": energy_released(h, k, cut, units="morphoshell"),
        "delta": d,
        "sigma": _out(cut_arr / boundary_layer_width(h_arr)),
    }
