"""Solver behaviour: warm starts, parametric re-solves, failures, saddles."""
import numpy as np
import pytest

from morphoshell import DirectSolver, NotAMinimumError, Problem, SolverError, solve


@pytest.fixture(scope="module")
def toy3():
    problem = Problem("anisotropic", {"f0": 0.1}, h=0.3, cut=0.3)
    return problem, DirectSolver(problem.structure, 200)


def test_warm_start_reproduces_cold_solution_in_fewer_iterations(toy3):
    problem, solver = toy3
    base = solver.solve(problem)
    target = problem.with_updates(f0=0.102)
    cold = solver.solve(target)
    warm = solver.solve(target, warm_start=base)
    # same NLP solution: agreement to the Newton convergence level
    assert np.max(np.abs(warm.x - cold.x)) < 1e-9
    assert warm.solver.iterations < cold.solver.iterations


def test_cut_and_thickness_are_parameters_of_one_nlp(toy3):
    # Sigma and h change the mesh and the energy, not the NLP: re-solving on
    # the solver built for Sigma = 0.3 equals a solver built for Sigma = 0.5.
    problem, solver = toy3
    moved = problem.with_updates(cut=0.5, h=0.2)
    a = solver.solve(moved)
    b = DirectSolver(moved.structure, 200).solve(moved)
    assert abs(a.s[0] - 0.5) < 1e-15
    assert np.max(np.abs(a.x - b.x)) < 1e-9


def test_continuation_in_the_cut_stays_on_its_branch(toy3):
    problem, solver = toy3
    eq = solver.solve(problem)
    energies = []
    for cut in np.linspace(0.3, 0.8, 6)[1:]:
        eq = solver.solve(problem.with_updates(cut=cut), warm_start=eq)
        energies.append(eq.energy)
        assert eq.solver.iterations <= 6
    # cutting more of the stressed pole region releases energy monotonically
    assert np.all(np.diff(energies) < 0)


def test_ipopt_failure_raises_with_status_and_last_iterate():
    problem = Problem("uniform", {"k": 0.0}, h=0.3, cut=0.3)
    solver = DirectSolver(problem.structure, 200, max_iter=1, newton=False)
    with pytest.raises(SolverError) as exc:
        solver.solve(problem)
    assert exc.value.status == "Maximum_Iterations_Exceeded"
    assert "Maximum_Iterations_Exceeded" in str(exc.value)
    last = exc.value.last_iterate
    assert last is not None and last.converged is False and len(last.r) == 2 * 199 + 1


def test_bvp_failure_raises_with_message():
    problem = Problem("uniform", {"k": 0.0}, h=0.3, cut=0.3)
    with pytest.raises(SolverError) as exc:
        solve(problem, method="bvp", max_nodes=50)
    assert exc.value.status == "Bvp_Max_Nodes_Exceeded"
    assert "with status 'Bvp_Max_Nodes_Exceeded' (The maximum number of mesh nodes is exceeded)" \
        in str(exc.value)                               # the name, and scipy's own words
    assert exc.value.last_iterate.converged is False


@pytest.mark.parametrize("stability", ["auto", "exact"])
def test_saddle_reported_as_success_is_rejected(blister, stability):
    solver = DirectSolver(blister.structure, 200, stability=stability)
    with pytest.raises(NotAMinimumError) as exc:
        solver.solve(blister)   # the flat start keeps psi = 0: Ipopt converges to the saddle
    saddle = exc.value.last_iterate
    assert saddle.converged is False and np.max(np.abs(saddle.psi)) == 0.0
    assert saddle.solver.status == "Solve_Succeeded"       # Ipopt itself was satisfied
    assert saddle.solver.details["inertia_correction"] > 0

    x0 = solver.disc.initial_guess(blister.parameter_vector())
    n = solver.disc.layout.free_points
    x0[n:2 * n] = 0.1 * solver.disc.points(blister.parameter_vector())[1:]   # tilt it
    dome = solver.solve(blister, x0=x0)
    assert dome.solver.details["inertia_correction"] == 0
    assert dome.energy < saddle.energy / 10 and dome.z[-1] - dome.z[0] > 0.1


def test_equilibrium_fields_are_consistent():
    eq = solve(Problem("volvox", h=0.15, opening=0.3), nodes=400)
    # nodal f_phi = r / rho exactly; the strains are computed pointwise at the
    # nodes (equal to round-off; measured 0) and take a cell's cubic through node
    # and Gauss values between them (order 3: 6.7e-8 at 400 nodes, 1e-6 at 200),
    # away from the (weakly singular) pole.  A linear interpolation of Gauss values
    # was off by 2.6e-5 at the nodes and 4.9e-5 between them.
    prof = eq.problem.profiles(eq.s)
    assert np.max(np.abs(eq.f_phi[1:] - eq.r[1:] / np.sin(eq.s[1:]))) < 1e-14
    away, node = eq.s > 0.2, np.arange(len(eq.s)) % 2 == 0   # stages = 2: nodes at even points
    E_phi = (eq.f_phi - prof["f_phi0"]) / prof["f_phi0"]
    assert np.max(np.abs(eq.E_phi[away & node] - E_phi[away & node])) < 1e-13
    assert np.max(np.abs(eq.E_phi[away] - E_phi[away])) < 1e-6
    # the pole value is the limit f_phi = f_s (l'Hopital), to the mesh resolution
    assert abs(eq.f_phi[0] - eq.f_s[0]) < 1e-2
    # eta from the profiles
    assert np.max(np.abs(eq.eta - prof["eta"])) < 1e-12
    # the phialopore rim is free: no force, no torque -> N_s = M_s = 0 there, to
    # round-off at a node (measured <= 1.3e-14 of the largest at 200-800 nodes; the
    # interpolated Gauss values left 3e-6 and 2e-6)
    assert abs(eq.N_s[-1]) < 1e-10 * np.max(np.abs(eq.N_s))
    assert abs(eq.M_s[-1]) < 1e-10 * np.max(np.abs(eq.M_s))


def test_warm_solves_are_certified_without_an_ipopt_refactorisation(blister):
    problem = Problem("uniform", {"k": 0.0}, h=0.3, cut=0.3)
    solver = DirectSolver(problem.structure, 100)
    base = solver.solve(problem)
    eq = DirectSolver(problem.structure, 100, newton=False).solve(
        problem.with_updates(h=0.303), warm_start=base)
    assert eq.solver.details["stability"] in ("ipopt_last_step", "penalised_ldl")
    assert eq.solver.details["inertia_correction"] == 0
    # the penalised factorisation never certifies a saddle: the exact check decides
    saddle_solver = DirectSolver(blister.structure, 200)
    with pytest.raises(NotAMinimumError) as exc:
        saddle_solver.solve(blister)
    saddle = exc.value.last_iterate
    D = saddle_solver.disc.cell_data(blister.parameter_vector())
    assert not saddle_solver.backend.penalised_certificate(saddle.x, D, saddle.lam_g)


def test_compiled_kernels_match_casadi(monkeypatch, tmp_path):
    import os
    import shutil
    import time
    from morphoshell.numerics import cell_kernels as disc
    problem = Problem("uniform", {"k": 0.0}, h=0.3, cut=0.3)
    monkeypatch.setenv("MORPHOSHELL_CACHE_DIR", str(tmp_path))
    # as if imported well after the last edit of the source (the index needs that)
    monkeypatch.setattr(disc, "IMPORTED_NS", time.time_ns() + 2 * 10**9)
    disc.compiled_cell_functions.cache_clear()
    try:
        solver = DirectSolver(problem.structure, 30)
        if solver.disc.kernels != "compiled":
            pytest.skip("no working C compiler: the CasADi kernels are used")
        d, eq = solver.disc, solver.solve(problem)
        D = d.cell_data(problem.parameter_vector())
        slow_nlp = {**d._nlp(disc.cell_functions(2)),
                    "fields": disc.cell_functions(2)["fields"].map(d.layout.cells)}
        Z = d.local_values(eq.x).reshape(-1, d.layout.cells, order="F")
        for name, args in (("grad_f", (eq.x, D)), ("jac_g", (eq.x, D)),
                           ("hess_lag", (eq.x, D, 1.0, eq.lam_g)),
                           ("fields", (Z, D.reshape(-1, d.layout.cells, order="F")))):
            if name == "fields":     # (the compiled kernel, in chunks of cells)
                fast = d._fields(d.layout.cells, Z, D)
            else:
                fast = [np.array(v) for v in d.numeric[name].call(list(args))]
            slow = [np.array(v).ravel(order="F") if name == "fields" else np.array(v)
                    for v in slow_nlp[name].call(list(args))]
            for a, b in zip(fast, slow):
                assert np.allclose(a, b, rtol=1e-12, atol=1e-12 * np.max(np.abs(b))), name
        # later processes find the library by the source's hash, without building the
        # expressions; a stale index, or a module changed since the import, take the full path
        index = disc._kernel_index(2, shutil.which(os.environ.get("CC", "cc")))
        assert index is not None and (tmp_path / index.read_text()).exists()
        with monkeypatch.context() as m:
            m.setattr(disc, "cell_functions", None)      # not called on the fast path
            disc.compiled_cell_functions.cache_clear()
            fast = disc.compiled_cell_functions(2)
            assert fast["grad"].name() == "morphoshell_cell2_grad"
            assert np.array_equal(DirectSolver(problem.structure, 30).solve(problem).x, eq.x)
        index.write_text("cells2_missing.so")
        disc.compiled_cell_functions.cache_clear()
        assert disc.compiled_cell_functions(2) is not None
        assert (tmp_path / index.read_text()).exists()    # rewritten by the full path
        with monkeypatch.context() as m:
            m.setattr(disc, "IMPORTED_NS", 0)            # every module "changed" since
            assert disc._kernel_index(2, "cc") is None
            disc.compiled_cell_functions.cache_clear()
            assert disc.compiled_cell_functions(2) is not None
        # without a compiler (or with MORPHOSHELL_COMPILE=0) the same results from CasADi
        monkeypatch.setenv("MORPHOSHELL_COMPILE", "0")
        disc.compiled_cell_functions.cache_clear()
        plain = DirectSolver(problem.structure, 30)
        assert plain.disc.kernels == "casadi"
        assert np.allclose(plain.solve(problem).x, eq.x, rtol=1e-9, atol=1e-12)
    finally:
        disc.compiled_cell_functions.cache_clear()


def test_refinement_tolerance_grows_with_the_points_as_tol(monkeypatch):
    """Ipopt's residual_ratio_max: its default up to 800 points, then like tol, capped."""
    from morphoshell.solvers import direct

    problem = Problem("uniform", {"k": 0.0}, h=0.3, cut=0.3)
    small = DirectSolver(problem.structure, 200)
    assert small.backend.options["residual_ratio_max"] == 1e-10
    big = DirectSolver(problem.structure, 3201)                  # 6401 points: 64x
    growth = (big.disc.layout.points / 800) ** 2
    assert growth > 64
    assert big.backend.options["residual_ratio_max"] == pytest.approx(1e-10 * growth, rel=1e-12)
    assert big.tol / small.tol == pytest.approx(growth, rel=1e-12)
    mine = DirectSolver(problem.structure, 3201, ipopt_options={"residual_ratio_max": 1e-9})
    assert mine.backend.options["residual_ratio_max"] == 1e-9    # the user's option wins
    monkeypatch.setattr(direct, "RESIDUAL_RATIO_CAP", 2e-9)
    assert DirectSolver(problem.structure, 3201).backend.options["residual_ratio_max"] == 2e-9


def test_fine_meshes_do_not_refactorise_for_round_off(capfd):
    """At 12 800 nodes (Volvox) the KKT solves' backward error stalls at ~5e-10 (measured):
    with Ipopt's fixed 1e-10 refinement failed and Ipopt re-factorised the same matrix
    every iteration; the tolerance that grows with the points leaves one factorisation each."""
    problem = Problem("volvox", h=0.15, opening=0.3)
    failures = []
    for options in ({}, {"residual_ratio_max": 1e-10}):
        solver = DirectSolver(problem.structure, 12800, ipopt_options={"print_level": 6,
                                                                      **options})
        capfd.readouterr()
        solver.backend.solve(solver.disc.initial_guess(problem.parameter_vector(), ()),
                             solver.disc.cell_data(problem.parameter_vector()),
                             np.zeros(solver.disc.constraints))
        failures.append(capfd.readouterr().out.count("Iterative refinement failed"))
        del solver
    assert failures[0] == 0 and failures[1] >= 2


def test_a_warm_start_from_another_mesh_is_carried_onto_this_one():
    """A state of another mesh with as many unknowns (here: another boundary-layer grading)
    starts the solve from its fields interpolated in s (DirectSolver.carried), not from its
    raw unknowns, which would put each node's r and psi at another s; its multipliers are
    not used. Same iterates as the explicit carried start, to the bit."""
    p = Problem("uniform", {"k": 0.5}, h=0.2, cut=0.3)
    a = DirectSolver(p.structure, nodes=60)
    b = DirectSolver(p.structure, nodes=60, grading_width=0.3)
    eq = a.solve(p)
    assert a.made(eq) and not b.made(eq) and len(eq.x) == b.disc.layout.size
    x0 = b.carried(eq, p.parameter_vector())
    assert np.max(np.abs(x0 - eq.x)) > 1e-3         # the raw unknowns are another start
    warm, explicit = b.solve(p, warm_start=eq), b.solve(p, x0=x0)
    assert b.made(warm)
    assert np.array_equal(warm.x, explicit.x)
    assert warm.solver.iterations == explicit.solver.iterations
