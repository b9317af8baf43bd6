"""Tests of the asymptotic predictions (paper, toy problems 1 and 2).

Each printed formula is checked against something computed independently of
it: the ODE and boundary conditions it solves, the integral it was derived
from, a numerical BVP solution, or scipy's own Kelvin functions.
"""
import math
import warnings

import numpy as np
import pytest
from scipy import special
from scipy.integrate import quad, solve_bvp

from morphoshell.mechanics import asymptotics as A

# --------------------------------------------------------------------------
# toy problem 1 (shell theory)
# --------------------------------------------------------------------------


@pytest.mark.parametrize("k", [0.0, 0.5, 2.0, -1.0])
def test_f_shell_exact_is_stationary_minimum(k):
    h = 0.1
    f = A.f_shell_exact(h, k)

    def energy(x):
        return (x - 1) ** 2 + h * h / 12 * (1 / x - k) ** 2

    # Relative residual of the stationarity condition at machine precision
    # (terms ~h²/12 ≈ 1e-3, so 1e-15 absolute is a few eps relative).
    assert abs((f - 1) * f**3 - h * h / 12 * (1 - k * f)) < 1e-15
    for step in (1e-4, -1e-4):
        assert energy(f + step) > energy(f)


@pytest.mark.parametrize("k", [0.0, 0.5, 2.0])
def test_f_shell_exact_matches_asymptotic_to_fourth_order(k):
    hs = np.array([0.04, 0.02, 0.01, 0.005])
    err = A.f_shell_exact(hs, k) - A.f_shell_asymptotic(hs, k)
    orders = np.log(err[:-1] / err[1:]) / np.log(hs[:-1] / hs[1:])
    # The O(h⁴) remainder has an O(h⁶) correction, so the local order
    # differs from 4 by O(h²) ≈ 1e-3 here; ±0.05 is generous yet excludes 3.
    assert np.all(np.abs(orders - 4) < 0.05), orders


def test_f_shell_exact_k_equal_one_is_undeformed():
    # k = 1: the undeformed sphere is stress-free, f = 1 exactly; and the
    # radius turns there with slope df/dk = -c/(1 + c), c = h²/12 (from
    # differentiating f³(f − 1) = c(1 − kf) at f = k = 1), which a wrong
    # root or branch would miss.
    h = 0.2
    c = h * h / 12
    assert A.f_shell_exact(h, 1.0) == 1.0
    eps = 1e-4
    slope = (A.f_shell_exact(h, 1 + eps) - A.f_shell_exact(h, 1 - eps)) / (2 * eps)
    assert slope == pytest.approx(-c / (1 + c), rel=1e-7)


def test_f_shell_vectorised():
    hs = np.array([0.01, 0.02, 0.03])
    out = A.f_shell_exact(hs, 0.0)
    assert out.shape == (3,)
    assert np.array_equal(out, [A.f_shell_exact(h, 0.0) for h in hs])


# --------------------------------------------------------------------------
# toy problem 1 (bulk) formulas
# --------------------------------------------------------------------------


@pytest.mark.parametrize("c10, c01", [(1.0, 0.0), (0.0, 1.0), (0.5, 0.5), (-1.0, 3.0)])
def test_k_star_is_zero_of_correction(c10, c01):
    ks = A.k_star(c10, c01)
    # Second printed form of k* (Supplementary, "Surprising mechanical
    # behaviour"); same quantity, so agreement to rounding.
    assert ks == pytest.approx(1 + 6 * (c10 + c01) / (5 * c10 + c01), rel=1e-14)
    h = 0.01
    assert A.f_bulk_asymptotic(h, ks, c10, c01) - 1 == pytest.approx(0, abs=1e-18)
    assert A.f_bulk_asymptotic(h, 1.0, c10, c01) == 1.0
    # k* > 1 iff 5C10 + C01 > 0.
    assert (ks > 1) == (5 * c10 + c01 > 0)


def test_bulk_asymptotic_neo_hookean_value():
    # C01 = 0: f − 1 = −(h²/12)(k − 1)(11 − 5k)/2; at k = 0 that is 11h²/24.
    assert A.f_bulk_asymptotic(0.1, 0.0, 1.0, 0.0) - 1 == pytest.approx(11e-2 / 24, rel=1e-12)


# --------------------------------------------------------------------------
# toy problem 2: leading order
# --------------------------------------------------------------------------

K = 0.3
_C = 3**0.25 / 2


def _b_derivative(xi, k, n):
    """n-th derivative of eq:bsol written as Re[−3^{3/4}(k−1) e^{−(1−i)cξ}]."""
    lam = -(1 - 1j) * _C
    return (-(3**0.75) * (k - 1) * lam**n * np.exp(lam * xi)).real


def test_b_inner_matches_independent_form():
    xi = np.linspace(0, 12, 50)
    assert np.allclose(A.b_inner(xi, K), _b_derivative(xi, K, 0), rtol=0, atol=1e-15)


def test_b_inner_solves_leading_order_problem():
    # Central differences of b_inner itself (not of the analytic form).
    s = 1e-2
    xi = np.linspace(0.0, 10.0, 41)

    def b(x):
        return A.b_inner(x, K)

    d4 = (b(xi - 2 * s) - 4 * b(xi - s) + 6 * b(xi) - 4 * b(xi + s) + b(xi + 2 * s)) / s**4
    scale = np.max(np.abs(b(xi)))
    # Stencil error s²b⁽⁶⁾/6 ≈ 2e-5·|b| (|λ|⁶ ≈ 0.65) plus rounding
    # eps·|b|/s⁴ ≈ 1e-8·|b|: 1e-4 relative is safe and still tiny vs 3|b|.
    assert np.max(np.abs(4 * d4 + 3 * b(xi))) < 1e-4 * scale
    # Boundary conditions at ξ = 0 (rim): 2b'(0) = 3(k − 1), b''(0) = 0.
    # Fourth-order stencils, error ~s⁴ ≈ 1e-8.
    h1 = 1e-2
    d1 = (-b(2 * h1) + 8 * b(h1) - 8 * b(-h1) + b(-2 * h1)) / (12 * h1)
    d2 = (-b(2 * h1) + 16 * b(h1) - 30 * b(0.0) + 16 * b(-h1) - b(-2 * h1)) / (12 * h1**2)
    assert 2 * d1 == pytest.approx(3 * (K - 1), abs=1e-7)
    assert abs(d2) < 1e-6
    # Decay.
    assert abs(b(40.0)) < 1e-10


@pytest.mark.parametrize("h, k, Sigma", [(1e-3, 0.3, 0.7), (0.02, 1.5, 2.0), (1e-5, -0.5, 0.1)])
def test_opening_rotation_from_inner_solution(h, k, Sigma):
    d = A.delta(h)
    assert d == pytest.approx(math.sqrt(h / math.sqrt(12)), rel=1e-15)
    # eq:Usol: o = 2δ² sinΣ ∫₀^∞ b dξ; quad to ~1e-13 relative.
    integral = quad(lambda x: A.b_inner(x, k), 0, np.inf, epsabs=0, epsrel=1e-13)[0]
    o = 2 * d**2 * math.sin(Sigma) * integral
    assert A.opening(h, k, Sigma) == pytest.approx(o, rel=1e-11)
    # eq:cutr: ϱ = δ b(0), exact algebra up to rounding.
    assert A.rotation(h, k) == pytest.approx(d * A.b_inner(0.0, k), rel=1e-14)
    # eq:cutd: the rim moves along the undeformed normal by δ² ∫₀^∞ b dξ
    # (dv/dξ = δ²b, eq:uv), whatever Σ: d = δ² |∫ b dξ| by quadrature.
    assert A.displacement(h, k) == pytest.approx(d**2 * abs(integral), rel=1e-11)


@pytest.mark.parametrize("h, k, Sigma", [(1e-3, 0.3, 0.7), (0.01, 2.0, 2.5), (1e-4, 0.0, 0.05)])
def test_energy_released_constant_from_its_integral(h, k, Sigma):
    """The printed −3^{7/4}π is checked against the Supplementary's integral
    2π∫δ⁴[(4/3)b'''² + b'² + 3b'(1−k)] sinΣ δ dξ with b from eq:bsol."""
    d = A.delta(h)

    def integrand(x):
        b1, b3 = _b_derivative(x, k, 1), _b_derivative(x, k, 3)
        return d**4 * (4 / 3 * b3**2 + b1**2 + 3 * b1 * (1 - k))

    integral = quad(integrand, 0, np.inf, epsabs=0, epsrel=1e-13)[0]
    expected = 2 * math.pi * integral * math.sin(Sigma) * d
    # quad converges to ~1e-13 on this smooth, exponentially decaying
    # integrand; 1e-10 leaves room while a wrong constant fails by O(1).
    assert A.energy_released(h, k, Sigma, units="paper") == pytest.approx(expected, rel=1e-10)
    assert A.energy_released(h, k, Sigma) == pytest.approx(0.5 * h * expected, rel=1e-10)
    assert A.energy_released(h, k, Sigma) <= 0


def test_recoil_velocity_scaling():
    v = A.recoil_velocity(0.6, 11.0, 50.0, 0.05)
    assert v == pytest.approx(0.6 * 11.0**2.5 / 50.0**1.5 * 0.95, rel=1e-14)
    # V ∝ H^{5/2} R^{−3/2}.
    assert A.recoil_velocity(0.6, 22.0, 50.0, 0.05) / v == pytest.approx(2**2.5, rel=1e-14)
    assert A.recoil_velocity(0.6, 11.0, 200.0, 0.05) / v == pytest.approx(4**-1.5, rel=1e-14)


# --------------------------------------------------------------------------
# Kelvin functions
# --------------------------------------------------------------------------

X = np.array([0.05, 0.3, 1.0, 2.5, 7.0, 20.0])


def _close(a, b, envelope):
    """|a − b| ≤ 1e-10 · envelope, envelope the modulus of ker_ν + i kei_ν.

    scipy's cephes ker/kei/kerp/keip sum power series up to x = 8 whose terms
    grow like e^{x/√2} while the result decays like e^{−x/√2}: at x = 7
    about four digits are lost (5e-12 relative error measured near a zero of
    ker₀), so a relative test of the real and imaginary parts separately
    would be too strict; 1e-10 of the modulus is still far below any
    convention error (which is O(1)).
    """
    return np.all(np.abs(a - b) <= 1e-10 * envelope)


def test_kelvin_order_zero_matches_scipy():
    ker0, kei0 = A.kelvin_k(0, X)
    # scipy's ker/kei (cephes) are an independent implementation from the
    # complex K₀ (AMOS).
    env = np.hypot(ker0, kei0)
    assert _close(ker0, special.ker(X), env)
    assert _close(kei0, special.kei(X), env)


def test_kelvin_order_one_derivative_identity():
    """ker₀' = (ker₁ + kei₁)/√2 and kei₀' = (kei₁ − ker₁)/√2 (DLMF 10.63.1),
    with scipy's kerp/keip for the derivatives."""
    ker1, kei1 = A.kelvin_k(1, X)
    env = np.hypot(ker1, kei1)
    assert _close((ker1 + kei1) / math.sqrt(2), special.kerp(X), env)
    assert _close((kei1 - ker1) / math.sqrt(2), special.keip(X), env)
    # A swapped sign convention (kei₁ → −kei₁) must fail this test.
    assert not _close((ker1 - kei1) / math.sqrt(2), special.kerp(X), env)


def test_kelvin_order_one_ode():
    """w = ker₁ + i kei₁ solves x²w'' + xw' − (1 + i x²)w = 0."""
    x = np.array([0.5, 1.0, 3.0])
    s = 1e-3

    def w(y):
        r, i = A.kelvin_k(1, y)
        return r + 1j * i

    d1 = (w(x + s) - w(x - s)) / (2 * s)
    d2 = (w(x + s) - 2 * w(x) + w(x - s)) / s**2
    residual = x**2 * d2 + x * d1 - (1 + 1j * x**2) * w(x)
    # Stencil error ~s²·|w'''|x² ≈ 1e-6·|w|; rounding eps/s² ≈ 1e-10.
    assert np.all(np.abs(residual) < 1e-5 * np.abs(w(x)) * (1 + x**2))


def test_scaled_kelvin_parts_match_unscaled():
    varsigma = np.array([0.1, 1.0, 5.0, 30.0])
    sP, D, sN = A._small_cut_parts(varsigma)
    ker0, kei0 = A.kelvin_k(0, varsigma)
    ker1, kei1 = A.kelvin_k(1, varsigma)
    P = ker1**2 + kei1**2
    D0 = P + math.sqrt(2) * varsigma * (ker1 * (ker0 + kei0) + kei1 * (kei0 - ker0))
    N0 = ker1 * (kei0 - ker0) - kei1 * (kei0 + ker0)
    assert np.allclose(sP / D, varsigma * P / D0, rtol=1e-12)
    assert np.allclose(sN / D, varsigma * N0 / D0, rtol=1e-12)


# --------------------------------------------------------------------------
# small-ablation (Kelvin) forms
# --------------------------------------------------------------------------


def test_small_cut_forms_tend_to_leading_order_for_large_sigma():
    h, k = 1e-6, 0.2
    d = A.delta(h)
    Sigma = d * np.array([20.0, 200.0, 2000.0])
    rot = A.rotation_small_cut(h, k, Sigma) / A.rotation(h, k) - 1
    disp = A.displacement_small_cut(h, k, Sigma) / A.displacement(h, k) - 1
    # Measured: relative differences ≈ −0.43/σ² and −0.87/σ², i.e. ~1e-3 at
    # σ = 20; require < 1e-3 at σ ≥ 200 and a decrease by ≥ 50 per decade
    # (σ⁻² gives 100, σ⁻¹ would give 10 and fail).
    assert np.all(np.abs(rot[1:]) < 1e-3) and np.all(np.abs(disp[1:]) < 1e-3)
    assert np.all(np.abs(rot[1:]) < np.abs(rot[:-1]) / 50)
    assert np.all(np.abs(disp[1:]) < np.abs(disp[:-1]) / 50)


def test_small_cut_forms_vanish_for_small_sigma():
    h, k = 1e-4, -0.5
    d = A.delta(h)
    Sigma = d * np.array([1e-2, 1e-3, 1e-4])
    rot = A.rotation_small_cut(h, k, Sigma) / A.rotation(h, k)
    disp = A.displacement_small_cut(h, k, Sigma) / A.displacement(h, k)
    # ϱ ∝ σ and d ∝ σ² log σ as σ → 0 (measured); both must decrease
    # monotonically towards 0 and be small at σ = 1e-4.
    assert np.all(np.diff(rot) < 0) and np.all(np.diff(disp) < 0)
    assert np.all(rot > 0) and np.all(disp > 0)
    assert rot[-1] < 1e-3 and disp[-1] < 1e-5


def test_small_cut_forms_huge_sigma_are_finite():
    # ς ≈ 4e5: ker, kei underflow, the scaled evaluation must not.
    p = A.predictions(1e-12, 0.0, 3.0)
    assert p["rotation_small_cut"] == pytest.approx(p["rotation"], rel=1e-9)
    assert p["displacement_small_cut"] == pytest.approx(p["displacement"], rel=1e-9)


@pytest.mark.parametrize("h, cut", [(1e-19, 0.5), (1e-300, 0.5), (0.01, 1e-300), (0.01, 1e-200),
                                    (5e-324, 3.0)])
def test_small_cut_forms_are_their_limits_where_kelvin_functions_fail(h, cut):
    """ς beyond 1e9 gave NaN (h < 3e-19 at Σ = 0.5), below 1e-154 NaN with a RuntimeWarning
    (the CLI printed nan and exited 0): their limits there, finite, without warnings."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        rot = A.rotation_small_cut(h, 0.5, cut)
        disp = A.displacement_small_cut(h, 0.5, cut)
    assert math.isfinite(rot) and math.isfinite(disp)
    varsigma = A._varsigma(h, cut)
    if varsigma > 1:     # rotation() and displacement(), h's subnormal rounding aside
        assert rot == pytest.approx(math.sqrt(1.5) * math.sqrt(h) * 0.5, rel=1e-15, abs=0)
        assert disp == pytest.approx(0.5 * h * 0.5, rel=1e-15, abs=5e-324)
    else:     # ϱ ≈ √3 ς √h (1 − k); d ≈ ς² (ln(2/ς) − γ) h |1 − k| underflows to 0
        assert rot == pytest.approx(math.sqrt(3) * varsigma * math.sqrt(h) * 0.5, rel=1e-15, abs=0)
        assert disp == 0.0


def test_small_cut_forms_are_continuous_at_their_limits():
    """Each side of VARSIGMA_LIMITS, by the Kelvin forms and by the limits: equal to round-off."""
    lo, hi = A.VARSIGMA_LIMITS
    for v in (lo, hi):
        sides = np.array([v * (1 - 1e-12), v * (1 + 1e-12)])
        sP, D, sN = A._small_cut_parts(sides)
        assert sP[0] / D[0] == pytest.approx(sP[1] / D[1], rel=1e-11, abs=0)
        assert sN[0] / D[0] == pytest.approx(sN[1] / D[1], rel=1e-11, abs=0)


def _linear_small_cut_bvp(sigma, k, length=40.0):
    """Numerical solution of eq:prob2 with the boundary conditions eq:probbc.

    Independent of Kelvin functions; decay at ξ → ∞ is imposed at
    ξ = ``length``, where the solution is ~e^{−0.66·40} ≈ 1e-12 of its size.
    """
    def rhs(x, y):
        b, bp, n, np_ = y
        return np.vstack([bp, (-2 * x * bp + 2 * b + x**3 * n) / (2 * x * x),
                          np_, (-6 * x * np_ - 3 * x * b) / (2 * x * x)])

    def bc(ya, yb):
        return np.array([ya[2], 2 * ya[1] + ya[0] / sigma - 3 * (k - 1), yb[0], yb[2]])

    x = np.linspace(sigma, sigma + length, 300)
    sol = solve_bvp(rhs, bc, x, np.zeros((4, x.size)), tol=1e-9, max_nodes=50000)
    assert sol.status == 0
    return sol


@pytest.mark.parametrize("sigma", [0.1, 1.0, 3.0, 15.0])
def test_small_cut_forms_against_bvp(sigma):
    """The printed Kelvin-function ϱ and d against a BVP solution of eq:prob2:
    ϱ = δ b(σ) and d = δ²|∫ b dξ| (from eq:uv, v' = δ² b)."""
    h, k = 1e-4, 0.2
    d = A.delta(h)
    sol = _linear_small_cut_bvp(sigma, k)
    rot = d * sol.sol(sigma)[0]
    integral = quad(lambda x: sol.sol(x)[0], sigma, sigma + 40, limit=200,
                    epsabs=0, epsrel=1e-11)[0]
    disp = d**2 * abs(integral)
    # solve_bvp at tol 1e-9 reproduces these to ~1e-11 (measured); 1e-7
    # leaves margin while any error in the printed constants is O(1).
    assert A.rotation_small_cut(h, k, sigma * d) == pytest.approx(rot, rel=1e-7)
    assert A.displacement_small_cut(h, k, sigma * d) == pytest.approx(disp, rel=1e-7)


def test_predictions_keys_and_values():
    h, k, Sigma = 1e-3, 0.05, 0.4
    p = A.predictions(h, k, Sigma)
    assert set(p) == {"opening", "rotation", "displacement", "rotation_small_cut",
                      "displacement_small_cut", "energy_released", "delta", "sigma"}
    assert p["sigma"] == pytest.approx(Sigma / A.delta(h), rel=1e-15)
    assert p["energy_released"] == A.energy_released(h, k, Sigma, units="morphoshell")
    assert p["opening"] == A.opening(h, k, Sigma)
    arr = A.predictions(h, k, np.array([0.1, 0.2]))
    assert arr["rotation_small_cut"].shape == (2,)


@pytest.mark.parametrize("h, k, worst", [(0.1, 1000, "1000"), (0.1, -20, "-20"),
                                         (np.array([0.1, 0.2]), np.array([15, -10]), "-10")])
def test_predictions_refuse_a_curvature_beyond_the_thickness(h, k, worst):
    """Audit 26 F2: |k| >= 2/h (the intrinsic wedge closes) returned a rotation of -387 rad
    (h = 0.1, k = 1000); only the command line refused it.  Of arrays, the k nearest its
    bound is named (-10 at h = 0.2, where 15 at h = 0.1 is within its 20)."""
    with pytest.raises(ValueError, match=rf"predictions\(\): k = {worst} is beyond the curvature "
                                         rf"of the shell .*2/h = "):
        A.predictions(h, k, 0.3)
    assert np.isfinite(A.predictions(0.1, 19.9, 0.3)["rotation"])     # (just within)


# --------------------------------------------------------------------------
# bad input
# --------------------------------------------------------------------------


@pytest.mark.parametrize("h, text", [(0.0, "h = 0.0"), (-1.0, "h = -1.0"),
                                     (float("nan"), "h = nan"), (float("inf"), "h = inf"),
                                     (np.array([0.1, np.nan]), "h = nan")])
def test_bad_h(h, text):
    for call in (lambda: A.delta(h), lambda: A.rotation(h, 0.0),
                 lambda: A.opening(h, 0.0, 1.0), lambda: A.f_shell_exact(h, 0.0),
                 lambda: A.f_bulk_asymptotic(h, 0.0, 1.0, 0.0),
                 lambda: A.predictions(h, 0.0, 1.0)):
        with pytest.raises(ValueError, match=text):
            call()


@pytest.mark.parametrize("Sigma, text", [(0.0, "Sigma = 0.0"), (math.pi, "Sigma = 3.14"),
                                         (4.0, "Sigma = 4.0"), (float("nan"), "Sigma = nan"),
                                         ([0.5, -0.1], "Sigma = -0.1")])
def test_bad_sigma(Sigma, text):
    for fn in (A.opening, A.rotation_small_cut, A.displacement_small_cut,
               A.energy_released, A.predictions):
        with pytest.raises(ValueError, match=text):
            fn(1e-3, 0.0, Sigma)


def test_other_bad_input():
    with pytest.raises(ValueError, match="k = nan"):
        A.rotation(1e-3, float("nan"))
    with pytest.raises(ValueError, match="xi = inf"):
        A.b_inner(float("inf"), 0.0)
    with pytest.raises(ValueError, match="units = 'joules'"):
        A.energy_released(1e-3, 0.0, 1.0, units="joules")
    with pytest.raises(ValueError, match=r"5\*c10 \+ c01 = 0"):
        A.k_star(-1.0, 5.0)
    with pytest.raises(ValueError, match="c10 \\+ c01 = 0.0"):
        A.k_star(1.0, -1.0)
    with pytest.raises(ValueError, match="c10 \\+ c01 = -1.0"):
        A.f_bulk_asymptotic(0.1, 0.0, -1.0, 0.0)
    with pytest.raises(ValueError, match="c01 = nan"):
        A.k_star(1.0, float("nan"))
    with pytest.raises(ValueError, match="H = 0.0"):
        A.recoil_velocity(0.6, 0.0, 50.0, 0.0)
    with pytest.raises(ValueError, match="E_over_mu = -1.0"):
        A.recoil_velocity(-1.0, 11.0, 50.0, 0.0)
    with pytest.raises(ValueError, match="order = 2"):
        A.kelvin_k(2, 1.0)
    with pytest.raises(ValueError, match="x = 0.0"):
        A.kelvin_k(1, 0.0)
    with pytest.raises(ValueError, match="h = 'a'"):
        A.delta("a")
    with pytest.raises(ValueError, match="h = True"):
        A.delta(True)
