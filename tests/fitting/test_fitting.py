"""Bilevel fits of the Volvox model to midlines (fitting.bilevel.fit, end to end): three
methods, one optimum; boxes that move; the fit command.

Noiseless data come from the forward model on the truth's own mesh, the one a fit
that ends there uses (a test of the fit, not of the discretisation, which
tests/test_direct_vs_bvp.py checks), so the generating parameters are the exact
optimum.  Meshes are coarse (60
nodes) to keep the suite fast; scripts/bench_fit.py runs 200 nodes.  The tests
of each module of the subpackage are in test_<module>.py beside this one.
"""
import json

import casadi as ca
import numpy as np
import pytest

from morphoshell import solve
from morphoshell.cli import main
from morphoshell.fitting import FitError, fit, model_midline, synthetic_midline, volvox_spec
from morphoshell.io import Midline
from morphoshell.numerics.mesh import mesh_spec
from morphoshell.solvers.continuation import continue_to
from morphoshell.solvers.direct import DirectSolver

from fitting_cases import NODES, START, THREE, TRUE, three_parameter_spec


@pytest.fixture(scope="module")
def noiseless():
    spec = three_parameter_spec()
    # (Nelder-Mead stays on its start's mesh: fit() does not go on from its end's own)
    return spec, {"own": synthetic_midline(TRUE, nodes=NODES),
                  "start": synthetic_midline(TRUE, spec.base, nodes=NODES)}


@pytest.mark.parametrize("method", ["nelder-mead", "gradient", "kkt"])
def test_noiseless_midline_gives_back_the_generating_parameters(noiseless, method):
    spec, data = noiseless
    result = fit(spec, data["start" if method == "nelder-mead" else "own"], method, nodes=NODES)
    assert result.converged and result.E_fit <= 1e-6
    assert result.stop in (("Fit_Converged",) if method != "kkt" else
                           ("Solve_Succeeded", "Solved_To_Acceptable_Level")), result.stop
    for name in THREE:
        assert abs(result.parameters[name] / TRUE.params[name] - 1) <= 1e-3, name
    # held parameters stay where they were held
    assert result.parameters["f2"] == TRUE.params["f2"] and result.parameters["kappa1"] == 0.0


@pytest.fixture(scope="module")
def full_flat():
    spec = volvox_spec("flat", START)
    data = synthetic_midline(TRUE, nodes=NODES)
    return spec, data, {m: fit(spec, data, m, nodes=NODES) for m in ("gradient", "kkt")}


def test_all_twelve_parameters_of_the_flat_variant(full_flat):
    spec, data, results = full_flat
    assert len(spec.fitted) == 12 and "kappa1" not in spec.fitted
    for method, result in results.items():
        assert result.E_fit <= 1e-6, method
        for name in ("kappa2", "f1", "s1", "s2", "s3", "s4"):
            assert abs(result.parameters[name] / TRUE.params[name] - 1) <= 1e-3, (method, name)
    # κ₃, κ₄ shape only the anterior pole's neighbourhood: flagged as poorly
    # identified (singular values of the scaled Jacobian below 1e-3)
    flagged = set().union(*(d["direction"] for d in results["gradient"].poorly_identified))
    assert flagged & {"kappa3", "kappa4"}


# (a test of fitting.kkt_problem, kept in this file while numerics' internals it imports move)
@pytest.mark.parametrize("variant, compiled", [("flat", "1"), ("unstressed", "1"), ("flat", "0")])
def test_kkt_derivatives_are_those_of_the_whole_graph(variant, compiled, monkeypatch, request):
    """The kernel-assembled Hessian of the KKT fit's Lagrangian and Jacobian of its
    constraints equal CasADi's of the whole graph, from compiled kernels or not."""
    from morphoshell.numerics import kkt_derivatives
    from morphoshell.fitting import kkt_problem as fitting
    from morphoshell.fitting.inner import InnerProblem
    from morphoshell.solvers.observables import midline_cells

    monkeypatch.setenv("MORPHOSHELL_COMPILE", compiled)
    for cached in (fitting._compiled_misfit, kkt_derivatives._compiled_kkt_data_curvature):
        cached.cache_clear()
        request.addfinalizer(cached.cache_clear)     # later tests compile again

    spec = volvox_spec(variant, START)
    inner = InnerProblem(spec, synthetic_midline(TRUE, spec.base, nodes=30, noise=1e-3), 30)
    theta, x, lam = spec.theta0, inner.eq.x, inner.eq.lam_g
    nlp = fitting.KKTProblem(spec, inner, 1e-8, 10)
    nlp._build(midline_cells(inner.solver.disc, x, spec.problem(theta).parameter_vector(),
                             inner.n))
    w, target, sigma, mult, f, g, hess, jac_g = nlp.lagrangian
    direct = ca.Function("direct", [w, target, sigma, mult],
                         [ca.triu(ca.hessian(sigma * f + ca.dot(mult, g), w)[0])])
    rng = np.random.default_rng(0)
    w0 = np.concatenate([theta, x, lam, nlp._lifted_start(theta, x)])
    w0 = w0 + 1e-3 * rng.normal(size=w0.shape)     # off the equilibrium: every term counts
    mu = 1e-2 * rng.normal(size=g.shape[0])
    one = np.array(ca.densify(direct(w0, inner.data.ravel(), 0.7, mu)))
    two = np.array(ca.densify(hess(w0, inner.data.ravel(), 0.7, mu)))
    k = len(theta)
    assert np.abs(one[:k, k:]).max() > 1e-3 and np.abs(one[:k, :k]).max() > 1e-3
    assert np.abs(one - two).max() < 1e-12 * np.abs(one).max()
    one = np.array(ca.densify(ca.Function("direct_jac", [w], [ca.jacobian(g, w)])(w0)))
    two = np.array(ca.densify(jac_g(w0, inner.data.ravel())[1]))
    assert np.abs(one[:, :k]).max() > 1e-3
    assert np.abs(one - two).max() < 1e-12 * np.abs(one).max()


def test_the_kkt_state_is_a_true_equilibrium(full_flat):
    spec, _, results = full_flat
    kkt = results["kkt"]
    problem = kkt.equilibrium.problem
    # the physical branch at the fitted parameters, solved afresh on the fit's
    # mesh: the fitted problem's own (a fit ends on its end's own mesh)
    again = continue_to(DirectSolver(problem.structure, mesh=mesh_spec(problem, NODES, 2)),
                        problem)
    assert np.max(np.abs(model_midline(again) - kkt.model)) < 1e-6
    # and the boundary-value reference agrees with it (seeded with it: the
    # Volvox shell has several equilibria)
    bvp = solve(problem, method="bvp", warm_start=kkt.equilibrium)
    fine = solve(problem, nodes=400)
    assert abs(bvp.r[-1] - fine.r[-1]) < 1e-6 and abs(bvp.psi[-1] - fine.psi[-1]) < 1e-6


def test_noisy_fits_reach_the_noise_floor_and_agree():
    spec = three_parameter_spec()
    sigma = 1e-3
    data = synthetic_midline(TRUE, spec.base, nodes=NODES, noise=sigma, seed=3)
    results = {m: fit(spec, data, m, nodes=NODES) for m in ("nelder-mead", "gradient", "kkt")}
    # E_fit² ≈ σ² (2N − k) at the optimum (noise on 2N − 2 coordinates; the
    # pole is exact): within 15 % for 198 values
    floor = sigma * np.sqrt(2 * len(data) - 2 - len(THREE))
    ref = results["gradient"]
    for method, result in results.items():
        assert abs(result.E_fit / floor - 1) < 0.15, (method, result.E_fit, floor)
        assert abs(result.E_fit / ref.E_fit - 1) < 0.01, method
        for name in THREE:
            assert abs(result.parameters[name] - ref.parameters[name]) < ref.standard_errors[name]
            # and the truth lies within a few standard errors
            assert abs(result.parameters[name] - TRUE.params[name]) < 4 * ref.standard_errors[name]


def test_a_breakpoint_resting_on_its_box_moves_it_to_the_fits_optimum():
    """The boxes that order the breakpoints for least squares are not the fit's
    constraints: with kappa3 = kappa4 = 0 held, s3 and s4 slide far below the start's
    boxes (the fit used to stop on their edge, converged) to σ apart; there E_fit
    falls along no feasible move of any breakpoint (first-order optimality, checked
    by inner solves at ±1e-3)."""
    from morphoshell.fitting.inner import InnerProblem

    spec = volvox_spec("flat", START, hold={"kappa3": 0.0, "kappa4": 0.0})
    data = synthetic_midline(TRUE, spec.base, nodes=NODES, noise=1e-3, seed=3)
    lo, _ = spec.box()
    result = fit(spec, data, "gradient", nodes=NODES)
    assert result.converged and "moving the breakpoints' boxes" in result.message
    s = [result.parameters[f"s{i}"] for i in range(1, 5)]
    assert s[3] < lo[spec.fitted.index("s4")] - 0.3
    sigma = spec.base.params["sigma"]
    assert np.all(np.diff([0.0, *s, spec.base.end]) >= sigma * (1 - 1e-9))
    theta = np.array([result.parameters[n] for n in spec.fitted])
    inner = InnerProblem(spec.recentred(theta), data, NODES, start=result.equilibrium)
    for i in range(4):
        for step in (-1e-3, 1e-3):
            moved = theta.copy()
            moved[spec.fitted.index(f"s{i + 1}")] += step
            gaps = np.diff([0.0, *s[:i], s[i] + step, *s[i + 1:], spec.base.end])
            if np.all(gaps >= sigma):
                res = inner.residuals(inner.solve(moved))
                assert np.sqrt(res @ res) >= result.E_fit * (1 - 1e-9), (i, step)


def test_a_fit_that_fails_from_moved_boxes_keeps_the_last_one_unconverged(monkeypatch):
    """When the fit from moved boxes fails (FitError), the fit within the last boxes is
    returned, not converged, saying why; a failure before any move still raises."""
    from morphoshell.fitting import bilevel      # where fit() finds the method

    spec = volvox_spec("flat", START, hold={"kappa3": 0.0, "kappa4": 0.0})
    data = synthetic_midline(TRUE, spec.base, nodes=NODES, noise=1e-3, seed=3)
    calls, gradient = [], bilevel.gradient_fit

    def failing_second(spec, inner, *args):
        calls.append(spec.theta0)
        if len(calls) == 2:
            raise FitError("the NLP failed", "Maximum_Iterations_Exceeded")
        return gradient(spec, inner, *args)

    monkeypatch.setattr(bilevel, "gradient_fit", failing_second)
    result = fit(spec, data, "gradient", nodes=NODES)
    assert len(calls) == 2 and not result.converged and result.stop == "Fit_Moved_Boxes_Failed"
    assert "the fit from moved boxes failed: the NLP failed" in result.message
    # the first fit's end: the start of the second, on the edge of the start's boxes
    theta = np.array([result.parameters[n] for n in spec.fitted])
    assert np.allclose(theta, calls[1]) and spec.on_box_edges(theta)
    calls.clear()
    calls.append(None)           # now the first call fails
    with pytest.raises(FitError):
        fit(spec, data, "gradient", nodes=NODES)


@pytest.mark.parametrize("options, message", [
    ({"nodes": 5}, "nodes = 5 must be an integer from 20 to 3200"),      # was "4 cells cannot..."
    ({"nodes": 200.0}, "nodes = 200.0 must be an integer"),
    ({"tol": -1.0}, "tol = -1.0 must lie in [1e-15, 1)"),                # was a scipy warning
    ({"tol": float("nan")}, "tol = nan must be finite"),
    ({"max_iterations": 0}, "max_iterations = 0 must be a positive integer"),   # was accepted
    ({"method": "bfgs"}, "method = 'bfgs' must be one of"),
])
def test_fit_refuses_bad_options_before_any_work(options, message):
    spec = three_parameter_spec()
    data = np.column_stack([np.linspace(0, 1, 20), np.linspace(0, 1, 20) ** 2])
    with pytest.raises(ValueError) as exc:
        fit(spec, data, **{"method": "gradient", "nodes": NODES, **options})
    assert message in str(exc.value)


# --------------------------------------------------------------------------
# command line
# --------------------------------------------------------------------------

@pytest.fixture(scope="module")
def midline_csv(tmp_path_factory):
    spec = three_parameter_spec()
    points = synthetic_midline(TRUE, spec.base, nodes=NODES, noise=5e-4, seed=2)
    path = tmp_path_factory.mktemp("fit") / "synthetic_midline.csv"
    Midline(points[:, 0], points[:, 1], None, 1, ("synthetic",)).to_csv(path)
    return path


def test_fit_command_writes_a_usable_result(midline_csv, tmp_path, capsys):
    out, png = tmp_path / "fit.json", tmp_path / "fit.png"
    held = [f"--set={n}={TRUE.params[n]}" for n in TRUE.family_obj.parameters
            if n not in THREE and n not in ("kappa1", "sigma")]
    assert main(["fit", str(midline_csv), "--variant", "flat", "--method", "gradient",
                 "--nodes", str(NODES), *held, "--json", str(out), "--plot", str(png)]) == 0
    data = json.loads(out.read_text())
    assert set(data) >= {"parameters", "standard_errors", "E_fit", "method", "variant",
                         "converged", "seconds", "inner_solves", "data_midline",
                         "fitted_midline"}
    assert set(data["parameters"]) >= set(TRUE.family_obj.parameters) | {"h", "opening"}
    assert set(data["standard_errors"]) == set(THREE)
    assert abs(data["parameters"]["kappa2"] - TRUE.params["kappa2"]) < 0.1
    assert png.stat().st_size > 10_000
    # the fit JSON is a problem file: solve and ablate the fitted shape
    assert main(["solve", str(out), "--nodes", "100"]) == 0
    assert main(["ablate", str(out), "--set", "cut=0.3", "--nodes", "100"]) == 0
    assert "rotation" in capsys.readouterr().out


@pytest.mark.parametrize("args, named", [
    (["--variant", "unstressed", "--set", "kappa1=1"], "cannot be held"),
    (["--variant", "flat", "--set", "kappa1=0.5"], "holds kappa1 = 0, not 0.5"),
    (["--variant", "flat", "--set", "kappa9=1"], "unknown Volvox parameter(s) ['kappa9']"),
    (["--variant", "flat", "--format", "xy"], "pixel"),
    (["--variant", "sideways"], "argument --variant: invalid choice"),
])
def test_fit_command_refuses_bad_input(midline_csv, args, named, capsys):
    assert main(["fit", str(midline_csv), *args]) == 2
    err = capsys.readouterr().err
    assert named in err and "Traceback" not in err


def test_fit_start_takes_the_parameters_and_refuses_a_cut_shell(midline_csv, tmp_path, capsys):
    """--start takes the Volvox parameters, h and opening of a problem or result file; one
    whose problem no fit has (a cut, as the JSON of morphoshell ablate: a shell with a hole at
    the pole was fitted to an intact trace, E_fit 48 times normal, 'converged'; another
    theory) is refused in one line naming the file and the entry, before any work."""
    held = [f"--set={n}={TRUE.params[n]}" for n in TRUE.family_obj.parameters
            if n not in THREE and n not in ("kappa1", "sigma")]
    first, out = tmp_path / "first.json", tmp_path / "fit.json"
    fit_argv = ["fit", str(midline_csv), "--variant", "flat", "--nodes", str(NODES), *held]
    assert main([*fit_argv, "--set", "h=0.14", "--json", str(first)]) == 0
    ablation = tmp_path / "ablation.json"
    assert main(["ablate", str(first), "--set", "cut=0.15", "--nodes", "40",
                 "--json", str(ablation)]) == 0
    capsys.readouterr()
    assert main([*fit_argv, "--start", str(ablation), "--json", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"--start {ablation}: problem.cut = 0.15: " in err
    assert "intact (cut = 0)" in err and not out.exists()
    toml = tmp_path / "start.toml"
    toml.write_text('[problem]\nfamily = "volvox"\ntheory = "classical"\nh = 0.15\n'
                    'opening = 0.3\n')
    assert main([*fit_argv, "--start", str(toml), "--json", str(out)]) == 2
    err = capsys.readouterr().err
    assert f"--start {toml}: [problem] theory = 'classical': " in err and not out.exists()
    # a fit's JSON or a problem file: its parameters and h go on, the rest is a fit's own
    assert main([*fit_argv, "--start", str(first), "--json", str(out)]) == 0
    problem = json.loads(out.read_text())["problem"]
    assert (problem["cut"], problem["h"], problem["theory"]) == (0.0, 0.14, "large_bending")
    toml.write_text('[problem]\nfamily = "volvox"\nname = "stage5"\nh = 0.13\n'
                    'opening = 0.3\n[parameters]\nf1 = 0.85\n')
    assert main([*fit_argv, "--start", str(toml), "--json", str(out)]) == 0
    problem = json.loads(out.read_text())["problem"]
    assert (problem["name"], problem["h"]) == ("", 0.13)


def test_fit_help_gives_the_range_of_nodes(capsys):
    """--nodes accepts 20 to 3200 (bilevel.FIT_NODES): --help says so.  A campaign's fits
    accept the same (it stopped at 2000, its --help silent on it: audit 3, #14)."""
    assert main(["fit", "--help"]) == 0
    assert "mesh nodes of the inner solves, 20 to 3200 (default 200)" in \
        " ".join(capsys.readouterr().out.split())
    assert main(["campaign", "--help"]) == 0
    assert "mesh nodes of the inner solves, 20 to 3200 as for morphoshell fit (default 200)" \
        in " ".join(capsys.readouterr().out.split())
    assert main(["campaign", "no_such_folder", "--nodes", "3201"]) == 2
    assert "argument --nodes: 3201 must lie in [20, 3200]" in capsys.readouterr().err


def test_fit_command_names_a_midline_of_the_wrong_scale(midline_csv, tmp_path, capsys):
    small = tmp_path / "small.csv"
    m = Midline.from_csv(midline_csv)
    Midline(m.r / 5, m.z / 5, None, 1, ("scaled",)).to_csv(small)
    out = tmp_path / "fit.json"
    assert main(["fit", str(small), "--variant", "flat", "--json", str(out)]) == 2
    err = capsys.readouterr().err
    assert f"{small}: the midline is " in err and "5.3× shorter" in err and "units of R" in err
    assert err.count("\n") == 1
    assert not out.exists()


def test_a_failed_fit_exits_3_saying_what_to_try(midline_csv, tmp_path, capsys, monkeypatch):
    """A fit that fails (as the KKT fit of a mid-inversion stage from the family's defaults)
    exits with status 3 in one line that keeps the solver's reason and says what to try;
    nothing is written."""
    import morphoshell.fitting as fitting       # where the command line finds fit()

    def failing(*args, **kwargs):
        raise FitError("the KKT fit's NLP failed", "Maximum_Iterations_Exceeded")

    monkeypatch.setattr(fitting, "fit", failing)
    out = tmp_path / "fit.json"
    assert main(["fit", str(midline_csv), "--variant", "flat", "--json", str(out)]) == 3
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "the KKT fit's NLP failed" in err
    assert "Maximum_Iterations_Exceeded" in err and "--start FIT.json" in err
    assert not out.exists()


