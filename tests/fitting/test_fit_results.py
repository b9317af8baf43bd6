"""What a fit returns (fitting.results): standard errors, constraints and folds."""
import math

import numpy as np
import pytest

from morphoshell import Problem
from morphoshell.fitting import fit, volvox_spec


@pytest.mark.parametrize("blowup, converged", [(1.0, True), (1e2, True), (1e6, False)])
def test_a_fit_near_a_fold_of_the_branch_is_not_converged(blowup, converged):
    """Near a fold dx/dp ~ 1/lambda_min blows up along one direction: the Jacobian is a
    rank-one term that dwarfs the rest (a free fit of the synthetic t07 crept onto one:
    second singular value 5e-7 of the first).  Random J + blowup * u v^T: the singular
    value ratio is ~0.5, ~0.1 and ~1e-6."""
    from types import SimpleNamespace

    from morphoshell.fitting import volvox_spec
    from morphoshell.fitting.results import FOLD_RATIO, fit_result

    spec = volvox_spec("free")
    k = len(spec.fitted)
    rng = np.random.default_rng(1)
    J = rng.normal(size=(200, k)) + blowup * np.outer(rng.normal(size=200), rng.normal(size=k))
    eq = SimpleNamespace(problem=spec.base)
    inner = SimpleNamespace(solve=lambda theta: eq, residuals=lambda eq: np.full(200, 1e-3),
                            jacobian=lambda eq, theta: J, data=np.zeros((100, 2)), n=100,
                            solves=1)
    r = fit_result("gradient", spec, inner, np.ones(k), 5, 0.1, True, "ftol reached")
    sv = np.linalg.svd(J, compute_uv=False)
    assert (sv[1] >= FOLD_RATIO * sv[0]) == converged
    assert r.converged is converged and r.near_fold is not converged
    assert ("near a fold" in r.message) is not converged and r.message.startswith("ftol")
    assert r.stop == ("Fit_Converged" if converged else "Fit_Near_Fold")


def test_the_summary_gives_every_parameter_its_unit_and_directions_as_sums():
    """Fitted values printed without units ('kappa1 = 1.37765 ± 0.12', though every printed
    quantity carries its unit) and poorly identified directions as a Python dict ("{'f2':
    0.695, ...}"): now the family's units (stretches dimensionless, curvatures 1/R,
    breakpoints R) and a sum of the parameters."""
    import re
    from types import SimpleNamespace

    from morphoshell.fitting.results import fit_result

    spec = volvox_spec("free")
    k = len(spec.fitted)
    rng = np.random.default_rng(2)
    u, sv, vt = np.linalg.svd(rng.normal(size=(200, k)), full_matrices=False)
    sv[-1] = 1e-5 * sv[0]                       # one direction the data hardly see
    theta = spec.theta0                         # (off every constraint)
    J = u @ np.diag(sv) @ vt / np.maximum(np.abs(theta), 1e-2)   # (fit_result scales by θ)
    eq = SimpleNamespace(problem=spec.base)
    inner = SimpleNamespace(solve=lambda theta: eq, residuals=lambda eq: np.full(200, 1e-3),
                            jacobian=lambda eq, theta: J, data=np.zeros((100, 2)), n=100,
                            solves=1)
    lines = fit_result("gradient", spec, inner, theta, 5, 0.1, True, "").summary().split("\n")
    units = {"f": "(dimensionless)", "kappa": "1/R", "s": "R"}
    for name in spec.fitted:
        [line] = [x for x in lines if x.startswith(f"  {name} ")]
        assert line.endswith(" " + units[name.rstrip("12345")]) and " ± " in line, line
    [poor] = [x for x in lines if "poorly identified" in x]
    assert "{" not in poor and "'" not in poor, poor
    assert re.search(r"poorly identified: -?\d\.\d+ \w+ [+-] \d\.\d+ \w+ [+-] \d\.\d+ \w+ "
                     r"\+ \.\.\. \(parameters relative to their size; singular value 1e-05 of "
                     r"the largest\)$", poor), poor


@pytest.fixture(scope="module")
def pinned_fit():
    """(spec, base, fit) of data whose s3 lies 0.6 sigma above s2: a fit that ends on the
    constraint s3 - s2 = sigma (NaN standard errors and correlations)."""
    from morphoshell.fitting import synthetic_midline

    base = Problem("volvox", h=0.15, opening=0.3)
    p = base.params
    hold = {k: v for k, v in p.items() if k not in ("s2", "s3")}
    spec = volvox_spec("free", start=base, hold=hold)
    return spec, base, fit(spec, synthetic_midline(
        base.with_updates(s3=p["s2"] + 0.6 * p["sigma"]), nodes=60), "gradient", nodes=60)


def test_a_fit_that_ends_on_a_constraint_says_so_and_gives_no_errors_there(pinned_fit):
    """Data whose s3 lies 0.6 sigma above s2: the fit (gaps of at least sigma) ends on
    s3 - s2 = sigma, a constrained optimum, and says so; s2 and s3 get no standard errors
    (Gauss-Newton errors of a free optimum; on replicate t02 data sets the jackknife
    errors of fits pinned there were 0.001-0.002 against misses of 0.018).  The
    same fit of data with the default gap (6 sigma) ends inside, with finite errors."""
    from morphoshell.fitting import synthetic_midline

    spec, base, pinned = pinned_fit
    p = base.params
    assert pinned.converged and pinned.constrained == ("s3 - s2 = sigma",)
    assert pinned.parameters["s3"] - pinned.parameters["s2"] == pytest.approx(p["sigma"],
                                                                              abs=1e-4)
    assert all(np.isnan(pinned.standard_errors[n]) for n in ("s2", "s3"))
    assert pinned.pinned == ("s2", "s3")
    assert "ends on the constraint s3 - s2 = sigma" in pinned.message
    d = pinned.to_dict()
    assert d["standard_errors"] == {"s2": None, "s3": None}
    assert d["constrained"] == ["s3 - s2 = sigma"]
    assert "(on a constraint)" in pinned.summary()
    inside = fit(spec, synthetic_midline(base, nodes=60), "gradient", nodes=60)
    assert inside.constrained == () and all(np.isfinite(list(inside.standard_errors.values())))
    assert inside.pinned == ()


def test_a_fit_pickles_with_its_equilibrium(pinned_fit):
    """A user audit: pickle.dumps(fit(...)) failed on the equilibrium's problem (t26.py)."""
    import pickle

    res = pinned_fit[2]
    back = pickle.loads(pickle.dumps(res))
    assert back.problem == res.problem and back.summary() == res.summary()
    assert back.equilibrium.energy == res.equilibrium.energy
    assert np.array_equal(back.equilibrium.r, res.equilibrium.r)
    assert np.array_equal(back.residuals, res.residuals) and back.stop == res.stop


def test_a_saved_fit_reads_back_as_the_fit(pinned_fit, tmp_path):
    """A user audit: a fit's JSON had no reader, so its standard errors, constraints and
    midlines were read from the raw dict.  Saved as fit --json saves it (null for the NaN
    of a constraint), it reads back to the same record and summary, without its
    equilibrium.  The residuals are the midlines' difference: to round-off (1e-15 R)."""
    from morphoshell.fitting import load_fit
    from morphoshell.io.problem_files import to_jsonable, write_json

    res = pinned_fit[2]
    back = load_fit(write_json(tmp_path / "fit.json", res.to_dict()))
    assert to_jsonable(back.to_dict()) == to_jsonable(res.to_dict())
    assert back.summary() == res.summary() and back.problem == res.problem
    assert back.pinned == ("s2", "s3") and back.constrained == res.constrained
    assert back.equilibrium is None and back.stop == res.stop == "Fit_Converged"
    assert np.array_equal(back.data, res.data) and np.array_equal(back.model, res.model)
    assert np.allclose(back.residuals, res.residuals, rtol=0, atol=1e-15)


def test_a_campaigns_record_and_an_unconverged_fits_read_back(pinned_fit):
    """A campaign's record names the fit's method fitted_by (its method is the campaign's
    setting) and drops seconds; a fit that did not converge has no stop to read back."""
    from morphoshell.fitting import FitResult

    record = {**pinned_fit[2].to_dict(), "method": "kkt", "fitted_by": "gradient",
              "converged": False, "status": "ok"}
    del record["seconds"]
    back = FitResult.from_dict(record)
    assert back.method == "gradient" and math.isnan(back.seconds)     # (not recorded)
    assert "time not recorded" in repr(back)
    assert not back.converged and back.stop == "Unknown"


@pytest.mark.parametrize("change, said", [
    (lambda r: r.update(status="failed", message="no start solved"),
     r"x.json: the fit failed \(no start solved\)"),
    (lambda r: r.pop("E_fit"), r"x.json: no E_fit: not a fit's record"),
    (lambda r: r.update(fitted_midline={"r": [1.0], "z": "abc"}),
     r"x.json: fitted_midline must hold lists of numbers"),
])
def test_a_broken_fit_record_is_refused_naming_the_entry(pinned_fit, change, said):
    from morphoshell.fitting import FitResult

    record = pinned_fit[2].to_dict()
    change(record)
    with pytest.raises(ValueError, match=said):
        FitResult.from_dict(record, "x.json")
