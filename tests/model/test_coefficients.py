"""Tests of the coefficients α, β, γ(η) of the shell energy.

``shared/docs/large_bending_theory.md``: reference table (section 2), parity,
limits and positive definiteness (section 4, items 2–3), and the
three-dimensional check (section 4, item 1) against the exact through-thickness
energy of :mod:`morphoshell.mechanics.thickness`.  The quadratic shell energy is always
taken from :func:`morphoshell.model.energy.density` with
:func:`morphoshell.model.coefficients.evaluate`, never retyped here.
"""
from __future__ import annotations

import math

import casadi as ca
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from morphoshell.model import coefficients as co
from morphoshell.mechanics import thickness as th
from morphoshell.model.energy import Strains, density

NAMES = co.Coefficients._fields
ODD = np.array([n.startswith("beta") for n in NAMES])
PARITY = np.where(ODD, -1.0, 1.0)  # c(−η) = PARITY · c(η)
EPS = np.finfo(float).eps


def values(eta, theory="large_bending") -> np.ndarray:
    """The ten coefficients at a scalar η, as an array in Coefficients order."""
    return np.array([float(v) for v in co.evaluate(eta, theory)])


def shell_matrix(eta) -> np.ndarray:
    """Symmetric S with e = (C h/2) xᵀ S x, x = (E_s, E_φ, hK_s, hK_φ).

    Built by polarisation of :func:`morphoshell.model.energy.density` (h = 1, C = 2),
    so it tests the energy as the solvers use it, including the factor 2 on β.
    """
    c = co.evaluate(eta)
    unit = np.eye(4)

    def e(x):
        return float(density(Strains(*x), 1.0, c, C=2.0))

    return np.array([[(e(unit[i] + unit[j]) - e(unit[i]) - e(unit[j])) / 2 if i != j else e(unit[i])
                      for j in range(4)] for i in range(4)])


# Entry (i, j) of shell_matrix and the coefficient it holds.
MATRIX_ENTRIES = {
    (0, 0): "alpha_ss", (0, 1): "alpha_sphi", (1, 1): "alpha_phiphi",
    (0, 2): "beta_ss", (0, 3): "beta_sphi", (1, 2): "beta_phis", (1, 3): "beta_phiphi",
    (2, 2): "gamma_ss", (2, 3): "gamma_sphi", (3, 3): "gamma_phiphi",
}


def intrinsic(eta, f_s0=1.3, f_phi0=0.8, h=0.05):
    """(f_s⁰, f_φ⁰, κ_s⁰, h) with κ_s⁰h/(2f_s⁰f_φ⁰) = η."""
    return f_s0, f_phi0, 2 * eta * f_s0 * f_phi0 / h, h


# --------------------------------------------------------------------------
# Reference values (theory document section 2)
# --------------------------------------------------------------------------

REFERENCE = {
    0.1: (1.020304, 0.510152, 1.005076, -0.042376, -0.016920, -0.021188, 0.004040,
          0.084982, 0.042258, 0.083544),
    0.5: (1.777778, 0.888889, 1.194444, -0.339583, -0.129630, -0.169791, -0.002315,
          0.145138, 0.063542, 0.091049),
    -0.5: (1.777778, 0.888889, 1.194444, 0.339583, 0.129630, 0.169791, 0.002315,
           0.145138, 0.063542, 0.091049),
    0.9: (27.700831, 13.850416, 7.675208, -7.240287, -2.472299, -3.620143, -1.123650,
          1.962132, 0.677341, 0.298361),
}


@pytest.mark.parametrize("sign", [1, -1])
@pytest.mark.parametrize("eta", sorted(REFERENCE))
def test_reference_table(eta, sign):
    # The table is rounded to 6 decimals: |error| ≤ 5e-7.  The float64
    # evaluation error of the closed forms is ≤ ~1e-13 for these η (worst: the
    # 1/(8η²) cancellation at η = 0.1), hence the extra 1e-12.  The mirrored
    # row uses the parity of section 4 (α, γ even, β odd).
    expected = (PARITY if sign < 0 else 1.0) * np.array(REFERENCE[eta])
    got = values(sign * eta)
    bad = {n: (g, e) for n, g, e in zip(NAMES, got, expected) if not abs(g - e) <= 5e-7 + 1e-12}
    assert not bad, f"eta = {sign * eta}: coefficient (computed, table) {bad}"


# --------------------------------------------------------------------------
# Closed form and series at the switch
# --------------------------------------------------------------------------

def _switch_tolerance(name: str, order: int) -> float:
    """Allowed jump of the ``order``-th η-derivative of ``name`` at η_s = SERIES_SWITCH.

    Truncation: the series stops at η¹² (α, γ) or η¹³ (β); the first omitted
    term c·ηᵐ (m = 14 or 15) is estimated by linear extrapolation of the last two
    Taylor coefficients, |c| ≈ |c₆| + |c₆ − c₅| (exact for α_ss: 1/D = Σ(n+1)η²ⁿ
    gives 8), and its k-th derivative is c·m!/(m−k)!·ηᵐ⁻ᵏ; factor 3 margin for
    the further terms.  Cancellation: the closed forms subtract terms of size
    1/(8η²) (module docstring), allowed 10 ulp of the k-th derivative of that
    term, (k+1)!/(8η²⁺ᵏ) (2.8e-14, 5.5e-13, 1.7e-11 at η_s = 0.1; measured
    closed-minus-series differences of the non-α coefficients ≤ 2e-15).
    Measured jumps are ≤ 0.34 of this bound for every coefficient and order;
    zeroing the η¹² coefficient of γ_ss (a 5e-13 change) or changing the η¹⁰
    coefficient of α_sφ by 1/2 (5e-11) fails it.
    """
    x = co.SERIES_SWITCH
    c = [float(v) for v in co._SERIES[name]]
    m = 2 * len(c) + (1 if name.startswith("beta") else 0)
    nxt = abs(c[-1]) + abs(c[-1] - c[-2])
    trunc = nxt * math.factorial(m) / math.factorial(m - order) * x ** (m - order)
    cancel = 10 * EPS * math.factorial(order + 1) / (8 * x ** (2 + order))
    return 3 * trunc + cancel


def _check_jumps(jumps, order):
    bad = {n: (j, _switch_tolerance(n, order)) for n, j in zip(NAMES, jumps)
           if not j <= _switch_tolerance(n, order)}
    assert not bad, f"derivative order {order}: coefficient (jump, allowed) {bad}"


@pytest.mark.parametrize("sign", [1, -1])
def test_closed_form_and_series_agree_at_switch(sign):
    eta = sign * co.SERIES_SWITCH
    closed = np.array([float(v) for v in co._closed(eta)])
    series = np.array([co._series(n, eta) for n in NAMES])
    _check_jumps(np.abs(closed - series), 0)


@pytest.mark.parametrize("sign", [1, -1])
def test_large_bending_continuous_with_derivatives_at_switch(sign):
    # Value, first and second η-derivatives (Ipopt uses both) of the
    # if_else-joined expression, just outside (closed form) and just inside
    # (series, one ulp closer to 0) the switch.
    x = ca.SX.sym("eta")
    c = ca.vertcat(*co.large_bending(x))
    d1 = ca.jacobian(c, x)
    d2 = ca.jacobian(d1, x)
    f = ca.Function("f", [x], [c, d1, d2])
    outside = sign * co.SERIES_SWITCH
    inside = np.nextafter(outside, 0.0)
    assert abs(inside) < co.SERIES_SWITCH <= abs(outside)
    for order, (a, b) in enumerate(zip(f(outside), f(inside))):
        _check_jumps(np.abs(np.array(a) - np.array(b)).ravel(), order)


def test_derivatives_finite_at_zero():
    # The discarded closed-form branch is evaluated at a guarded η, so no
    # 0·inf = NaN leaks into the derivatives at η = 0.  There they are the
    # Taylor coefficients: c'(0) = first β coefficient, c''(0) = 2 × η² one.
    x = ca.SX.sym("eta")
    c = ca.vertcat(*co.large_bending(x))
    d1 = ca.jacobian(c, x)
    f = ca.Function("f", [x], [c, d1, ca.jacobian(d1, x)])
    v, g, H = (np.array(a).ravel() for a in f(0.0))
    assert np.all(np.isfinite(np.concatenate([v, g, H])))
    first = np.array([float(co._SERIES[n][0]) if o else 0.0 for n, o in zip(NAMES, ODD)])
    second = np.array([0.0 if o else 2 * float(co._SERIES[n][1]) for n, o in zip(NAMES, ODD)])
    np.testing.assert_allclose(g, first, rtol=0, atol=1e-15)
    np.testing.assert_allclose(H, second, rtol=0, atol=1e-15)


# --------------------------------------------------------------------------
# Limits and parity (theory document section 4, item 3)
# --------------------------------------------------------------------------

def test_eta_zero_is_classical():
    classical = values(0.0, "classical")
    np.testing.assert_array_equal(classical, [1, 0.5, 1, 0, 0, 0, 0, 1 / 12, 1 / 24, 1 / 12])
    # Series constant terms are exactly the classical values at η = 0 ...
    np.testing.assert_array_equal(values(0.0), classical)
    # ... and the approach is O(η) (β) or O(η²) (α, γ): every coefficient's
    # η or η² Taylor factor is ≤ 2 in magnitude, so 2η (plus rounding) bounds it.
    for eta in (1e-3, -1e-5):
        np.testing.assert_allclose(values(eta), classical, rtol=0, atol=2 * abs(eta))


def test_classical_energy_is_incompressible_shell():
    # η = 0: e = (C h/2)[E_s² + E_sE_φ + E_φ² + (h²/12)(K_s² + K_sK_φ + K_φ²)]
    # (theory document section 2); only rounding separates the two forms.
    rng = np.random.default_rng(0)
    c = co.evaluate(0.0)
    for _ in range(5):
        Es, Ep, Ks, Kp = rng.normal(size=4)
        h, C = rng.uniform(0.01, 0.3), rng.uniform(0.5, 3)
        expected = C * h / 2 * (Es**2 + Es * Ep + Ep**2 + h**2 / 12 * (Ks**2 + Ks * Kp + Kp**2))
        assert float(density(Strains(Es, Ep, Ks, Kp), h, c, C)) == pytest.approx(expected, rel=1e-13)


def test_parity():
    # α, γ even and β odd, on both branches.  The closed forms evaluate
    # ln((1+η)/(1−η)) and ln((1−η)/(1+η)) separately, which agree to a few ulp;
    # after cancellation (≤ ~100× at the smallest closed-form η = 0.1, see the
    # module docstring) the relative difference is ≤ ~1e-13 (measured 6e-14).
    eta = np.concatenate([np.linspace(1e-4, co.SERIES_SWITCH, 50), np.linspace(0.1, 0.999, 300)])
    plus = np.array(co.evaluate(eta))
    minus = np.array(co.evaluate(-eta))
    rel = np.abs(minus - PARITY[:, None] * plus) / np.abs(plus)
    assert rel.max() <= 1e-12, (NAMES[int(np.argmax(rel.max(axis=1)))], rel.max())


# D·c(η) → these limits as η → 1, so every coefficient diverges like 1/D
# (D = (1 − η²)²: the thin end of the wedge closes).  From the closed forms:
# the L = 2 artanh η terms are O(ln(1 − η)) and drop out after multiplying by D.
DIVERGENCE = dict(zip(NAMES, (1, 1 / 2, 1 / 4, -1 / 4, -1 / 12, -1 / 8, -1 / 24,
                              1 / 16, 1 / 48, 1 / 144)))


@pytest.mark.parametrize("sign", [1, -1])
def test_coefficients_diverge_at_unit_eta(sign):
    limit = np.array([DIVERGENCE[n] for n in NAMES]) * np.where(ODD, sign, 1.0)
    previous = np.abs(values(sign * 0.9))
    for gap in (1e-2, 1e-4, 1e-6):
        eta = sign * (1 - gap)
        c = values(eta)
        D = (1 - eta**2) ** 2
        # Corrections to D·c are O(1 − η) (≤ ~0.5 gap from the expansions
        # above), so 2·gap bounds the deviation.
        np.testing.assert_allclose(D * c, limit, rtol=0, atol=2 * gap, err_msg=f"eta = {eta}")
        assert np.all(np.abs(c) > previous)  # monotone growth towards |η| = 1
        previous = np.abs(c)
    assert np.abs(c).min() > 1e9  # 1/D ≈ 2.5e11 at 1 − η = 1e-6


# --------------------------------------------------------------------------
# Positive definiteness (theory document section 4, item 2)
# --------------------------------------------------------------------------

def test_quadratic_form_positive_definite():
    # The 4×4 form in (E_s, E_φ, hK_s, hK_φ) built from energy.density.
    # Measured: smallest eigenvalue ≥ 0.03 on this grid while the largest grows
    # like 1/D (≈ 3e5 at 0.999); eigvalsh errors are ~eps·λ_max ≈ 1e-10, so
    # requiring λ_min > 1e3·eps·λ_max is a genuine, rounding-proof margin.
    eta = np.unique(np.concatenate([
        np.linspace(-0.999, 0.999, 401),
        [0.0, co.SERIES_SWITCH, -co.SERIES_SWITCH, 0.9999, -0.9999]]))
    for e in eta:
        S = shell_matrix(e)
        assert np.allclose(S, S.T, rtol=0, atol=1e-14 * np.abs(S).max())
        lam = np.linalg.eigvalsh(S)
        assert lam[0] > 1e3 * EPS * lam[-1], f"eta = {e}: eigenvalues {lam}"
        np.linalg.cholesky(S)


# --------------------------------------------------------------------------
# The three-dimensional model (theory document sections 3 and 4, item 1)
# --------------------------------------------------------------------------

def test_incompressibility_cubic_matches_ode():
    # z(ζ) from the cubic (thickness.normal_coordinate) against a direct
    # integration of λ_s λ_φ dz/dζ = 1 from z(0) = 0.  solve_ivp at rtol 1e-12
    # is accurate to ~1e-12·h⁰, so 1e-10·h⁰ is a safe bound; a wrong cubic
    # (e.g. without the κ_sκ_φz³/3 term) is off by up to 4e-3·h⁰ here.
    f_s0, f_phi0, kappa_s0, h = intrinsic(-0.7)
    d = th.deformed_state(f_s0, f_phi0, kappa_s0, h, (0.03, -0.02, 0.05, 0.04))
    h0 = h / (f_s0 * f_phi0)

    def rhs(zeta, z):
        return [f_s0 * f_phi0 * (1 + kappa_s0 * zeta)
                / (d.f_s * d.f_phi * (1 + d.kappa_s * z[0]) * (1 + d.kappa_phi * z[0]))]

    for end in (h0 / 2, -h0 / 2):
        zeta = np.linspace(0, end, 21)[1:]
        sol = solve_ivp(rhs, (0, end), [0.0], t_eval=zeta, rtol=1e-12, atol=1e-14 * h0, method="DOP853")
        z = th.normal_coordinate(zeta, f_s0, f_phi0, kappa_s0, d)
        np.testing.assert_allclose(z, sol.y[0], rtol=0, atol=1e-10 * h0)


def test_intrinsic_state_is_stress_free_and_strains_round_trip():
    f_s0, f_phi0, kappa_s0, h = intrinsic(0.4)
    rest = th.deformed_state(f_s0, f_phi0, kappa_s0, h, (0, 0, 0, 0))
    # z = ζ solves the cubic at rest up to rounding, so W = O(eps²).
    assert abs(th.exact_density(f_s0, f_phi0, kappa_s0, h, rest)) < 1e-25
    # Deformed state → energy.strains gives back the direction: E exactly as
    # put in, and hK = h⁰K̂ (theory document section 1).  Only rounding.
    direction = np.array([0.02, -0.03, 0.015, 0.01])
    d = th.deformed_state(f_s0, f_phi0, kappa_s0, h, direction)
    _, E = th.shell_density(f_s0, f_phi0, kappa_s0, h, d, return_strains=True)
    got = np.array([E.E_s, E.E_phi, h * E.K_s, h * E.K_phi])
    np.testing.assert_allclose(got, direction, rtol=1e-12, atol=1e-15)


@pytest.mark.parametrize("h, f_s0, f_phi0", [(0.02, 1.0, 1.0), (0.2, 1.2, 0.7)])
def test_shear_modulus_to_C(h, f_s0, f_phi0):
    # Small-strain limit at κ⁰ = 0 (η = 0): exact energy with modulus μ over the
    # shell energy with C = 1 tends to C/μ.  Derivation (thickness module
    # docstring): W → 2μ(E_s² + E_sE_φ + E_φ²) + 2μζ²(κ_s² + κ_sκ_φ + κ_φ²),
    # integrated over h⁰ and times f_s⁰f_φ⁰ → 2μh(...) = (C/2)h(...), so C = 4μ.
    # The ratio is the same for both h: C carries no factor h (the document's
    # "C = 4μh" counts h twice).  Relative error O(A) = O(1e-6) ⇒ rtol 1e-5.
    mu, A = 2.5, 1e-6
    direction = (0.6, -0.3, 0.5, 0.55)
    d = th.deformed_state(f_s0, f_phi0, 0.0, h, direction, A)
    exact = th.exact_density(f_s0, f_phi0, 0.0, h, d, mu=mu)
    E = Strains(A * direction[0], A * direction[1], A * direction[2] / h, A * direction[3] / h)
    unit_C = float(density(E, h, co.evaluate(0.0), C=1.0))
    assert exact / unit_C == pytest.approx(4 * mu, rel=1e-5)
    assert th.C_PER_MU == 4.0


def test_quadrature_converged():
    # DEFAULT_NODES is converged even close to the closing end (η = −0.95):
    # doubling the nodes changes the energy by rounding only.
    f_s0, f_phi0, kappa_s0, h = intrinsic(-0.95)
    d = th.deformed_state(f_s0, f_phi0, kappa_s0, h, (0.3, -0.5, 0.6, 0.4), 1e-5)
    a = th.exact_density(f_s0, f_phi0, kappa_s0, h, d)
    b = th.exact_density(f_s0, f_phi0, kappa_s0, h, d, nodes=2 * th.DEFAULT_NODES)
    assert a == pytest.approx(b, rel=1e-11)


def exact_matrix(eta, t) -> np.ndarray:
    """S of the exact 3D energy: its second-order part, in shell_matrix units.

    q(x) = [E(t x) + E(−t x)]/2 removes the odd (cubic, quintic) terms; dividing
    by t²·(C h/2) with C = C_PER_MU·μ and polarising gives S + O(t²).
    Richardson (4 S(t) − S(2t))/3 removes the O(t²) term.
    """
    p = intrinsic(eta)
    h = p[3]

    def q(x, t):
        plus, _ = th.energies(*p, x, t)
        minus, _ = th.energies(*p, x, -t)
        return (plus + minus) / 2 / (t * t * th.C_PER_MU * h / 2)

    def S(t):
        unit = np.eye(4)
        diag = [q(unit[i], t) for i in range(4)]
        return np.array([[(q(unit[i] + unit[j], t) - diag[i] - diag[j]) / 2 if i != j else diag[i]
                          for j in range(4)] for i in range(4)])

    return (4 * S(t) - S(2 * t)) / 3


@pytest.mark.parametrize("eta, t", [(-0.52, 1e-4), (0.29, 1e-4), (0.025, 1e-4), (0.5, 1e-4),
                                    (-0.9, 1e-5)])
def test_coefficients_are_second_order_expansion_of_3d_model(eta, t):
    # Coefficient by coefficient: the Hessian of the exact through-thickness
    # energy equals the shell's.  Measured agreement ≤ 6e-11 of max|S| (t
    # chosen ≪ (1 − |η|)² so the remainder O(t⁴) is negligible; rounding of the
    # polarisation is ~1e-16/t² relative to q).  A coefficient wrong in its
    # 4th digit would be 1e-4 off; the tolerance 1e-8·max|S| pinpoints it.
    exact = exact_matrix(eta, t)
    shell = shell_matrix(eta)
    scale = np.abs(shell).max()
    bad = {name: (exact[ij], shell[ij]) for ij, name in MATRIX_ENTRIES.items()
           if not abs(exact[ij] - shell[ij]) <= 1e-8 * scale}
    assert not bad, f"eta = {eta}: coefficient (3D model, shell) {bad}"


# Amplitudes 1e-2, 5e-3, ..., 7.8e-5: eight halvings covering 1e-2 ... 1e-4.
AMPLITUDES = 1e-2 / 2.0 ** np.arange(8)


def relative_errors(eta, direction, amplitudes) -> np.ndarray:
    p = intrinsic(eta, *_SHAPES[eta]) if eta in _SHAPES else intrinsic(eta)
    out = []
    for A in amplitudes:
        exact, quadratic = th.energies(*p, direction, A)
        out.append((exact - quadratic) / exact)
    return np.array(out)


# Different (f_s⁰, f_φ⁰, h) per η: the comparison must depend on them only
# through η (and the project's h⁰ = h/(f_s⁰f_φ⁰), hK = h⁰K̂ bookkeeping).
_SHAPES = {-0.52: (1.3, 0.8, 0.05), 0.29: (0.9, 1.15, 0.12), 0.025: (1.0, 1.0, 0.02),
           -0.9: (1.1, 0.95, 0.08)}


def random_directions(seed, n=3):
    rng = np.random.default_rng(seed)
    d = rng.normal(size=(n, 4))
    return d / np.linalg.norm(d, axis=1, keepdims=True)


@pytest.mark.parametrize("eta", [-0.52, 0.29, 0.025])
def test_3d_relative_error_falls_linearly(eta):
    # The quadratic form is the exact second-order term, so the relative error
    # is c₁A + c₂A² + …, and err(A)/err(A/2) = 2 + (c₂/c₁)A + O(A²).  Measured
    # |c₂/c₁|A ≤ 0.08 at A = 1e-2 (ratios 1.98–2.08 for these directions), so
    # [1.7, 2.3] holds with margin, while a wrong coefficient (relative error →
    # constant, ratio → 1) or an error falling like A² (ratio → 4) would fail.
    for direction in random_directions(seed=int(1000 * abs(eta)) + 7):
        err = relative_errors(eta, direction, AMPLITUDES)
        ratios = err[:-1] / err[1:]
        assert np.all((ratios >= 1.7) & (ratios <= 2.3)), (direction, ratios)
        # "about 1e-3 at amplitude 1e-3" (measured 9e-5 ... 4e-3): order of magnitude.
        (at_1e3,) = relative_errors(eta, direction, [1e-3])
        assert abs(at_1e3) < 1e-2, (direction, at_1e3)


def test_3d_relative_error_near_closing_wedge():
    # η = −0.9: the thin end has 1 − |η| = 0.1, so nonlinearity sets in at strains
    # ~ (1 − |η|)² = 1e-2 (at A = 1e-2 some directions even close the wedge:
    # no admissible z(ζ)).  Well below it, A = 1e-3 ... 1.2e-4, the error halves
    # again (measured ratios 1.98–2.02; same [1.7, 2.3] reasoning as above).
    eta = -0.9
    for direction in random_directions(seed=11):
        err = relative_errors(eta, direction, 1e-3 / 2.0 ** np.arange(4))
        ratios = err[:-1] / err[1:]
        assert np.all((ratios >= 1.7) & (ratios <= 2.3)), (direction, ratios)


def test_3d_model_rejects_closing_wedge():
    f_s0, f_phi0, kappa_s0, h = intrinsic(-0.9)
    d = th.deformed_state(f_s0, f_phi0, kappa_s0, h, (-0.8, 0.0, 0.6, 0.0), 2e-2)
    with pytest.raises(ValueError, match="closes"):
        th.exact_density(f_s0, f_phi0, kappa_s0, h, d)


# --------------------------------------------------------------------------
# Input validation
# --------------------------------------------------------------------------

@pytest.mark.parametrize("bad", [1.0, -1.0, 1.5, -3.0, np.inf, -np.inf, np.nan,
                                 [0.2, 1.0], [0.1, np.nan]])
def test_evaluate_rejects_invalid_eta(bad):
    with pytest.raises(ValueError, match="eta"):
        co.evaluate(bad)


def test_evaluate_accepts_eta_just_inside():
    c = co.evaluate(np.array([-(1 - 1e-9), 0.0, 1 - 1e-9]))
    assert all(np.all(np.isfinite(v)) and np.shape(v) == (3,) for v in c)
