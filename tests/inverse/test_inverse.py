"""Inverse estimates from ablation recoils (paper Fig. 2 J-K): morphoshell.inverse.

Round trips forward model -> measurement -> estimate, honest "no estimate"
answers, recovery on the synthetic table within its noise, and the inner
problem that the asymptotic estimates use.  The E/mu fit is in
test_recoil_velocity.py, the measurement table in test_measurement_table.py.
"""
import json
import math
from pathlib import Path

import numpy as np
import pytest

from morphoshell import Problem
import morphoshell.inverse as I
from morphoshell.inverse.embryo import check_methods
from morphoshell.io.measurements import MEASURE_COLUMN
from morphoshell.mechanics import asymptotics as A
from morphoshell.mechanics.ablation import ablate, recoil_jacobian
from morphoshell.solvers.observables import RECOIL

ROOT = Path(__file__).resolve().parents[2]
TABLE = ROOT / "data" / "synthetic_ablations.csv"
#: A thick sheet and small cut, as in the experiments (h = 0.2-0.37, Sigma = 0.07-0.17).
H, SIGMA, R_UM = 0.3, 0.1, 40.0


@pytest.fixture(scope="module")
def model():
    return I.RecoilModel(mesh_for=(H, SIGMA))


def _measurement(values: dict, name="E", h=H, Sigma=SIGMA, R=R_UM, **kw) -> I.Measurement:
    """A Measurement from dimensionless o, rho, d (units of R, radians)."""
    return I.Measurement(name, R, h * R, 2 * R * math.sin(Sigma),
                         **{MEASURE_COLUMN[m]: (None if values.get(m) is None else
                                                  I.to_physical(m, values[m], R))
                            for m in I.MEASURES}, **kw)


# --------------------------------------------------------------------------
# the forward model
# --------------------------------------------------------------------------

def test_model_is_ablate_with_its_exact_derivative():
    # Without mesh_for the model uses the solvers of ablate(): the same
    # observables, from another starting point (continuation there, the
    # tangent path here), so equal to Ipopt's tolerance.
    k = 0.05
    point = I.RecoilModel().evaluate(H, SIGMA, k)
    ab = ablate(Problem("uniform", {"k": k}, h=H, cut=SIGMA), nodes=I.NODES)
    y, J = recoil_jacobian(ab, ["k"])
    for i, name in enumerate(RECOIL):
        assert getattr(point, name) == pytest.approx(getattr(ab, name), abs=1e-9), name
        assert point.derivative[name] == pytest.approx(J[i, 0], rel=1e-7, abs=1e-10), name
    # and the derivative is the slope of the map (central differences, step 1e-4:
    # truncation ~1e-9 relative)
    m = I.RecoilModel(mesh_for=(H, SIGMA))
    up, down = m.evaluate(H, SIGMA, k + 1e-4), m.evaluate(H, SIGMA, k - 1e-4)
    for name in ("opening", "rotation", "displacement"):
        fd = (getattr(up, name) - getattr(down, name)) / 2e-4
        assert m.evaluate(H, SIGMA, k).derivative[name] == pytest.approx(fd, rel=1e-6), name


def test_one_pair_of_solvers_serves_a_table(model):
    # h and Sigma are NLP parameters and the intact shell's anchor moves with Sigma
    before = model.builds
    for h, Sigma in ((0.2, 0.067), (0.37, 0.17), (0.28, 0.1)):
        model.evaluate(h, Sigma, 0.0)
    assert model.builds == before == 2


# --------------------------------------------------------------------------
# round trips
# --------------------------------------------------------------------------

@pytest.mark.parametrize("k", [-0.5, 0.0, 0.05, 0.5])
def test_noiseless_round_trip_numerical(model, k):
    p = model.evaluate(H, SIGMA, k)
    m = _measurement({"opening": p.opening, "rotation": p.rotation,
                      "displacement": p.displacement})
    e = I.estimate_embryo(m, model, methods=("numerical",))
    for measure in I.MEASURES:
        est = e.estimates[(measure, "numerical")]
        # the Newton iteration stops at an estimated error of 1e-9 (K_TOL); the
        # measures are written in um and degrees and read back (round-off 1e-15)
        assert est.status == "ok" and abs(est.k - k) < 1e-6, (measure, est)
        assert est.k == pytest.approx(k, abs=1e-8)


@pytest.mark.parametrize("k", [-0.5, 0.0, 0.05, 0.5])
def test_noiseless_round_trip_closed_forms_and_inner(k):
    lo = {"opening": A.opening(H, k, SIGMA), "rotation": A.rotation(H, k),
          "displacement": A.displacement(H, k)}
    kv = {"opening": None, "rotation": A.rotation_small_cut(H, k, SIGMA),
          "displacement": A.displacement_small_cut(H, k, SIGMA)}
    inner = A.inner_recoil(H, k, SIGMA).recoil(H)
    inner = {"opening": inner["opening"], "rotation": inner["rotation"],
             "displacement": abs(inner["signed_displacement"])}
    for method, values, tol in (("leading_order", lo, 1e-12), ("kelvin", kv, 1e-12),
                                # solve_bvp re-meshes at every k: the map is smooth
                                # only to its tolerance
                                ("inner", inner, 1e-7)):
        e = I.estimate_embryo(_measurement(values), methods=(method,))
        for measure in I.MEASURES:
            est = e.estimates[(measure, method)]
            if values[measure] is None:
                assert est.status == "missing"
            elif method == "kelvin" and measure == "opening":
                assert est.status == "no_formula" and est.k is None
            else:
                assert abs(est.k - k) < tol, (method, measure, est)


def test_methods_not_run_leave_no_entries_or_notes():
    # a column of nulls for a method that was not asked for read as its failure,
    # and every embryo's notes said the combined k was missing
    k = 0.3
    e = I.estimate_embryo(_measurement({"opening": A.opening(H, k, SIGMA),
                                        "rotation": A.rotation_small_cut(H, k, SIGMA),
                                        "displacement": A.displacement_small_cut(H, k, SIGMA)}),
                          methods=("kelvin",))
    d = e.to_dict()
    assert "k_rotation_kelvin" in d and "k_opening_kelvin" in d      # (no formula: null, noted)
    assert not any(key.startswith(("k_combined", "k_rotation_numerical", "k_opening_inner",
                                   "k_rotation_leading_order")) for key in d), sorted(d)
    assert e.notes and not any("combined" in n or "not requested" in n for n in e.notes)


def test_error_propagation_uses_the_exact_slope(model):
    p = model.evaluate(H, SIGMA, 0.05)
    m = _measurement({"opening": p.opening, "rotation": p.rotation,
                      "displacement": p.displacement},
                     sigma_opening_um=0.3, sigma_rotation_deg=2.0, sigma_displacement_um=0.2)
    e = I.estimate_embryo(m, model, methods=("numerical",))
    for measure in I.MEASURES:
        est = e.estimates[(measure, "numerical")]
        expected = m.error(measure) / abs(p.derivative[measure])
        # the slope is the last Newton iterate's (within ~1e-3 of k), moved to k
        # with the curvature of the sampled map
        assert est.error == pytest.approx(expected, rel=1e-5), measure
    w = np.array([1 / e.estimates[(m_, "numerical")].error ** 2 for m_ in ("rotation",
                                                                           "displacement")])
    assert e.combined.error == pytest.approx(1 / math.sqrt(w.sum()), rel=1e-12)
    assert e.combined.k == pytest.approx(0.05, abs=1e-8)


def test_estimates_do_not_depend_on_the_workers():
    # each embryo starts from k = 1 on its own: rows can be shared between
    # processes (forked, inheriting the solvers) without changing a digit
    rows = I.read_measurements(TABLE)[:2]
    one, two = (I.estimate(rows, methods=("numerical",), bootstrap=100, workers=w)
                for w in (1, 2))
    for a, b in zip(one.embryos, two.embryos):
        for measure in I.MEASURES:
            assert a.k(measure) == b.k(measure)
    assert one.summary["combined"] == two.summary["combined"]


# --------------------------------------------------------------------------
# honest "no estimate"
# --------------------------------------------------------------------------

def test_unattainable_measures_give_null_and_a_reason(model):
    m = _measurement({"opening": 0.9, "rotation": math.radians(170.0), "displacement": None})
    e = I.estimate_embryo(m, model)
    for method in ("leading_order", "kelvin", "inner", "numerical"):
        est = e.estimates[("rotation", method)]
        assert est.k is None and est.status == "outside_range" and est.side == "below", est
        assert "outside the range" in est.note and "rho = 170.00 deg" in est.note
        assert "k < -1" in est.note
        # an opening of 0.9 R is far beyond any recoil of the shell
        assert e.estimates[("opening", method if method != "kelvin" else "inner")].side == "below"
    assert e.estimates[("opening", "kelvin")].status == "no_formula"
    assert e.estimates[("displacement", "numerical")].note == "no displacement measured"
    assert any("outside the range" in n for n in e.notes)
    # inward curling (rho < 0) needs k > 1, outside the default range
    inward = I.estimate_embryo(_measurement({"rotation": -0.05}), model, methods=("numerical",))
    est = inward.estimates[("rotation", "numerical")]
    assert est.k is None and est.side == "above" and "k > 1" in est.note


def test_displacement_is_not_monotonic_across_k_equal_1(model):
    # d = |...| vanishes at k = 1: with a range on both sides, a small d has two k
    p = model.evaluate(H, SIGMA, 0.5)
    m = _measurement({"displacement": p.displacement})
    e = I.estimate_embryo(m, model, k_range=(-1.0, 2.0), methods=("numerical", "leading_order"))
    for method in ("numerical", "leading_order"):
        est = e.estimates[("displacement", method)]
        assert est.k is None and est.status == "not_monotonic", est
        assert "2 values of k" in est.note
    # ... one of them is k = 0.5; the leading-order one is exactly 1 +- 2d/h
    assert "k = 0.5," in e.estimates[("displacement", "numerical")].note
    # on one side of k = 1 it is unique again
    one_side = I.estimate_embryo(m, model, k_range=(1.0, 2.0), methods=("numerical",))
    assert one_side.k("displacement") > 1.4


def test_a_k_range_beyond_the_shells_curvature_is_refused_before_any_solve():
    """|k| < 2/h: a sheet cannot curve with a radius below its half-thickness (at h = 0.3,
    2/h = 6.67); refused by the embryo and by the table, naming the shell and the limit."""
    m = _measurement({"rotation": 0.1})
    with pytest.raises(ValueError, match=r"k = -7 is beyond the curvature of embryo 'E' "
                                         r"\(h = H/R = 0.3\): \|k\| must stay below 2/h = 6.667"):
        I.estimate_embryo(m, None, k_range=(-7.0, 1.0), methods=("inner",))
    with pytest.raises(ValueError, match=r"k_range = \(1.0, 6.7\): k = 6.7 .* thickest shell"):
        I.estimate([m, _measurement({"rotation": 0.1}, name="F", h=0.1)], k_range=(1.0, 6.7))
    assert I.estimate_embryo(m, None, k_range=(-6.6, 1.0), methods=("leading_order",)).k(
        "rotation", "leading_order") is not None


def test_a_model_that_does_not_resolve_the_shell_gives_no_estimate():
    """At h = 1e-5 the 60-node model's stress-free shell (k = 1) recoils as if k were off by
    ~2: its estimates were returned as if right; now failed, naming the error in k."""
    thin = I.RecoilModel(mesh_for=(1e-5, 0.2))
    e = I.estimate_embryo(_measurement({"rotation": 0.01}, h=1e-5, Sigma=0.2), thin,
                          methods=("numerical", "inner"))
    est = e.estimates[("rotation", "numerical")]
    assert est.k is None and est.status == "failed", est
    assert "does not resolve this shell: at the stress-free k = 1 it gives rho = " in est.note
    assert e.estimates[("rotation", "inner")].status in ("ok", "outside_range")


# --------------------------------------------------------------------------
# the synthetic table
# --------------------------------------------------------------------------

@pytest.fixture(scope="module")
def synthetic():
    truth = json.loads(TABLE.with_suffix(".json").read_text())
    return I.estimate(TABLE), truth


def test_synthetic_table_is_labelled(synthetic):
    _, truth = synthetic
    assert "synthetic" in TABLE.name
    assert TABLE.read_text().startswith("# SYNTHETIC data, not measurements")
    assert truth["script"] == "scripts/make_synthetic_ablations.py" and truth["seed"] == 2025
    assert len(truth["ground_truth"]["embryos"]) == 14


def test_synthetic_numerical_estimates_recover_k_within_the_noise(synthetic):
    result, truth = synthetic
    k_true = {e["embryo"]: e["k"] for e in truth["ground_truth"]["embryos"]}
    z = []
    for e in result.embryos:
        for measure in I.MEASURES:
            est = e.estimates[(measure, "numerical")]
            if est.k is not None:
                z.append((est.k - k_true[e.measurement.embryo]) / est.error)
    z = np.array(z)
    # 38 estimates (4 noisy openings are negative: null, "needs k > 1"); with
    # Gaussian noise propagated to first order z ~ N(0, 1): |z| < 3.5 for all
    # (P > 0.98) and mean z^2 ~ chi2_38/38 = 1 +- 0.23
    assert z.size == 38
    assert np.max(np.abs(z)) < 3.5 and 0.5 < np.mean(z**2) < 1.7
    # Against the truth, with this noise (sigma_o = 0.3 um, sigma_rho = 2 deg,
    # sigma_d = 0.2 um), numerical beats the paper's asymptotic estimates in RMS
    # error for o and d (in 98 % and 97 % of noise draws for these shells,
    # linearised Monte Carlo); for rho only in 84 % (Kelvin's rotation is within
    # 2-5 % here), so it is not asserted.  The spread over embryos is smaller for
    # d (99.9 % of draws); for o the leading-order formula, which overestimates
    # the recoil 2-4 times, shrinks the noise and spreads *less* in 85 % of draws
    # (the shipped table is one of the other 15 %): its error is a bias, see the
    # noiseless test below.
    for measure in ("opening", "displacement"):
        rms = {}
        for method in ("numerical", "asymptotic"):
            d = [e.k(measure, method) - k_true[e.measurement.embryo] for e in result.embryos
                 if e.k(measure, method) is not None]
            rms[method] = math.sqrt(np.mean(np.square(d)))
        assert rms["numerical"] < rms["asymptotic"], (measure, rms)
    s = result.summary
    assert s["displacement_numerical"].std < s["displacement_asymptotic"].std


def test_noiseless_synthetic_shells_show_the_asymptotic_bias():
    # The synthetic table's noiseless recoils (sidecar; 400 mesh nodes) of four
    # of its shells: numerical inversion (60 nodes) returns the true k to the
    # discretisation error, the paper's asymptotic formulas are
    # off by 0.37-0.72 (o, leading order), 0.023-0.050 (rho, Kelvin) and
    # 0.034-0.090 (d, Kelvin) for these thick sheets (h = 0.23-0.34).
    truth = json.loads(TABLE.with_suffix(".json").read_text())["ground_truth"]["embryos"]
    rows = {m.embryo: m for m in I.read_measurements(TABLE)}
    picked = [truth[i] for i in (0, 6, 9, 12)]   # h and Sigma at the ends of the sample
    clean = [I.Measurement(g["embryo"], rows[g["embryo"]].R_um, rows[g["embryo"]].H_um,
                           rows[g["embryo"]].hole_diameter_um, g["opening_um"],
                           g["rotation_deg"], g["displacement_um"]) for g in picked]
    result = I.estimate(clean, methods=("leading_order", "kelvin", "numerical"), bootstrap=0)
    for e, g in zip(result.embryos, picked):
        for measure, floor in (("opening", 0.3), ("rotation", 0.02), ("displacement", 0.03)):
            assert abs(e.k(measure) - g["k"]) < 1e-4
            assert abs(e.k(measure, "asymptotic") - g["k"]) > floor


def test_synthetic_combined_k_and_E_over_mu(synthetic):
    result, truth = synthetic
    gt = truth["ground_truth"]
    c = result.summary["combined"]
    assert c.n == 14
    # the bootstrap 95 % interval of the mean covers the embryos' true mean k
    assert c.interval[0] < gt["k_sample_mean"] < c.interval[1]
    assert abs(c.weighted_mean - gt["k_sample_mean"]) < 3 * c.weighted_error
    v = result.velocity
    assert len(v.embryos) == 14 and abs(v.E_over_mu - gt["E_over_mu_per_s"]) < 3 * v.standard_error
    assert v.interval[0] < v.E_over_mu < v.interval[1]
    # the 4 negative openings: honest nulls, by every method
    for e in result.embryos:
        if e.measurement.opening_um < 0:
            for method in ("leading_order", "inner", "numerical"):
                est = e.estimates[("opening", method)]
                assert est.k is None and "needs k > 1" in est.note
    # one pair of solvers for the whole table
    assert result.timing["numerical_solver_builds"] == 2


def test_result_serialises_and_prints(synthetic):
    result, _ = synthetic
    d = result.to_dict()
    first = d["embryos"][0]
    for measure in I.MEASURES:
        for method in ("asymptotic", "numerical"):
            assert f"k_{measure}_{method}" in first and f"k_{measure}_{method}_error" in first
    assert first["k_opening_numerical"] is None and first["notes"]
    assert {"E_over_mu", "E_over_mu_standard_error", "E_lower_bound_Pa",
            "bending_modulus_lower_bound_J"} <= set(d)
    assert set(d["summary"]["combined"]) >= {"n", "mean", "std", "interval_95"}
    text = str(result)
    assert "14 embryos" in text and "E/mu = " in text and "outside the range" in text
    assert repr(result).startswith("InverseResult(14 embryos")
    cols = result.table()
    assert len(cols["embryo"]) == 14 and math.isnan(cols["k_opening_numerical"][0])


# --------------------------------------------------------------------------
# the inner problem (asymptotic estimates)
# --------------------------------------------------------------------------

def test_inner_problem_linearises_to_the_kelvin_forms():
    # at k = 1 the solution is b = n = 0 and the tangent problem is the linear
    # problem that the Kelvin forms solve exactly
    s = A.inner_solution(1.0, 1.0)
    h = 1e-8
    Sigma = 1.0 * A.delta(h)
    assert s.rotation == 0 and s.displacement == 0
    assert -s.derivative["rotation"] * math.sqrt(h) == pytest.approx(
        A.rotation_small_cut(h, 0.0, Sigma), rel=1e-7)
    assert -s.derivative["signed_displacement"] * h == pytest.approx(
        A.displacement_small_cut(h, 0.0, Sigma), rel=1e-7)
    # away from k = 1 the derivatives are those of the map (central differences)
    s = A.inner_solution(0.5, 0.3)
    for key in ("opening", "rotation", "signed_displacement"):
        up, down = (getattr(A.inner_solution(0.5, 0.3 + d, s, derivatives=False), key)
                    for d in (1e-4, -1e-4))
        assert s.derivative[key] == pytest.approx((up - down) / 2e-4, rel=1e-6), key


def test_inner_opening_matches_thin_shell_numerics():
    # eq:uv gives the opening of small cuts, o = O(delta^3): the classical shell
    # at h = 1e-4, Sigma = delta/2 agrees to O(delta) = 5e-3
    h, sigma, k = 1e-4, 0.5, 0.0
    inner = A.inner_recoil(h, k, sigma * A.delta(h)).recoil(h)
    ab = ablate(Problem("uniform", {"k": k}, h=h, cut=sigma * A.delta(h), theory="classical"),
                nodes=800)
    assert ab.opening / inner["opening"] == pytest.approx(1.0, abs=A.delta(h))
    assert ab.rotation / inner["rotation"] == pytest.approx(1.0, abs=A.delta(h))


def test_a_run_without_numerical_estimates_shows_only_the_methods_run():
    # the README's call: only the asymptotic forms; the text and repr had put
    # "null (rotation + displacement, numerical)" first, a method not run
    result = I.estimate(str(TABLE), methods=("leading_order", "kelvin"))
    assert repr(result) == ("InverseResult(14 embryos, methods leading_order, kelvin: no "
                            "combined <k> (it needs 'numerical'))")
    text = str(result)
    assert " numerical  " not in text and "inner" not in text     # no summary rows of them
    assert "k from rotation     asymptotic  -0.042 +- 0.143" in text
    assert "none (it combines the numerical estimates; add 'numerical' to methods)" in text
    # an embryo's row: the asymptotic k alone, not "null (-0.119)"
    assert next(line for line in text.splitlines() if "S01" in line).split()[3:] == [
        "null", "-0.119", "+0.041"]                      # (no k_combined column of nulls)
    assert "k_combined" not in text


def test_methods_may_be_one_string_of_names():
    """A user audit: methods="kelvin" was split into letters ("unknown method(s) ['e', 'i',
    ..."); one name, or names separated by commas, as campaign's embryo_errors takes them."""
    rows = [_measurement({"opening": A.opening(H, 0.3, SIGMA)})]
    for methods, ran in (("kelvin", ["kelvin"]), ("kelvin, inner", ["kelvin", "inner"])):
        result = I.estimate(rows, methods=methods, bootstrap=0, workers=1)
        assert result.settings["methods"] == ran
        assert "k_opening_kelvin" in result.embryos[0].to_dict()
        assert ("k_opening_inner" in result.embryos[0].to_dict()) == ("inner" in ran)
    with pytest.raises(ValueError, match=r"^methods = 'kelvn': unknown method\(s\) \['kelvn'\]; "
                                         r"valid: \['leading_order', 'kelvin', 'inner', "
                                         r"'numerical'\]$"):
        I.estimate(rows, methods="kelvn")


def test_methods_name_at_least_one_method_each_once():
    """Audit 23 F10: methods='' or [] returned a result without a single estimate and no
    error, 'kelvin,kelvin' listed (and ran) kelvin twice, and methods=3 raised "'int'
    object is not iterable"."""
    rows = [_measurement({"opening": A.opening(H, 0.3, SIGMA)})]
    for methods in ("", " , ", []):
        with pytest.raises(ValueError, match=r"^methods = .* names no method; choose from "
                                             r"\['leading_order', 'kelvin', 'inner', "
                                             r"'numerical'\]$"):
            I.estimate(rows, methods=methods)
    with pytest.raises(TypeError, match=r"^methods = 3 must be a name, names separated by "
                                        r"commas or a sequence of names, not int$"):
        I.estimate(rows, methods=3)
    result = I.estimate(rows, methods="inner, kelvin,inner", bootstrap=0, workers=1)
    assert result.settings["methods"] == ["inner", "kelvin"]        # (the order asked)
    assert check_methods(("kelvin", "kelvin")) == ("kelvin",)


def test_one_embryos_methods_are_checked_as_a_tables():
    """estimate_embryo took methods by membership: "kelvn" (a typo) ran no method at all,
    every estimate 'missing' without a word, and "kelvin,inner" ran them by substring."""
    m = _measurement({"opening": A.opening(H, 0.3, SIGMA)})
    with pytest.raises(ValueError, match=r"^methods = 'kelvn': unknown method\(s\) \['kelvn'\]"):
        I.estimate_embryo(m, methods="kelvn")
    d = I.estimate_embryo(m, methods="kelvin, inner").to_dict()
    assert d["k_opening_inner"] is not None and "k_opening_kelvin" in d
    assert "k_opening_leading_order" not in d       # (not requested: no column)
