"""The right minimum or an error: branch-safe cold solves, error estimates, valid meshes.

Each reproducer of the issue "The right minimum or an error" is a test here.
"""
import numpy as np
import pytest

from morphoshell import Problem, SolverError, solve
from morphoshell.solvers import routes
from morphoshell.solvers.continuation import neutral_problem
from morphoshell.model.problem import MIN_CUT, MIN_SHELL_LENGTH
from morphoshell.numerics.mesh import MIN_POLE_CELL, graded_mesh

SPURIOUS = [
    # (problem, energy of the physical branch: continuation, or 400 and 800 nodes cold)
    (Problem("anisotropic", {"f0": -0.19}, h=0.009, cut=0.164, theory="classical"), 3.3233e-4),
    (Problem("anisotropic", {"f0": -0.18947}, h=0.0089405, cut=0.16393, theory="classical"),
     3.2710e-4),
]


@pytest.mark.parametrize("problem, energy", SPURIOUS, ids=["f0=-0.19", "f0=-0.18947"])
def test_cold_solves_follow_the_physical_branch(problem, energy):
    eq = solve(problem)
    assert eq.energy == pytest.approx(energy, rel=2e-4)
    assert eq.solver.details["path"].startswith("continuation")
    # the single cold solve lands on a spurious minimum with 2.7x the energy
    # (measured 9.03e-4 and 8.89e-4) that Ipopt certifies as a minimum: the
    # test above can fail
    cold = solve(problem, continuation=False)
    assert cold.energy > 2 * energy and cold.solver.details["path"] == "cold"
    # and the error estimate exposes it: the half mesh from the cold solution
    # does not agree with it as a fourth-order scheme would
    assert eq.error.relative()["energy"] < 1e-6 < cold.error.relative()["energy"] or \
        cold.error.note


def test_continuation_does_not_snap_into_a_loop():
    """Fuzzing (2026-11-24): a thin closed sphere whose first continuation step of a quarter
    snapped into a loop (ψ − s up to 7 rad, later 14) and ended 17 % above the physical
    energy, its error estimate (2.4e-5) covering neither; eight fixed steps stay on the
    physical branch."""
    from morphoshell.solvers.direct import DirectSolver
    from morphoshell.numerics.mesh import mesh_spec

    problem = Problem("anisotropic", {"f0": -0.28515625}, h=0.001, cut=0.0)
    eq = solve(problem, nodes=200)
    solver, ref = DirectSolver(problem.structure, mesh=mesh_spec(problem, 200, 2)), None
    for tau in np.linspace(0, 1, 9):
        ref = solver.solve(problem.with_updates(f0=tau * problem.params["f0"]), warm_start=ref)
    assert np.max(np.abs(ref.psi - ref.s)) < np.pi / 2           # the physical branch
    # the same mesh by another path: measured 5e-11 apart (the KKT tolerance's scale)
    assert eq.energy == pytest.approx(ref.energy, rel=1e-8)
    assert np.max(np.abs(eq.psi - eq.s)) < np.pi / 2
    assert abs(eq.energy - ref.energy) <= eq.error.errors["energy"] + 1e-12


AXIS = Problem("anisotropic", {"f0": 0.1924125775330447}, h=0.0018789515602294436)


def test_a_meridian_crossing_the_axis_is_refused():
    eq = solve(AXIS, nodes=400)
    assert eq.energy == pytest.approx(1.4419e-8, rel=1e-3)
    assert eq.r.min() >= 0 and eq.quadrature_points()[1].min() > 0
    with pytest.raises(SolverError) as exc:
        solve(AXIS, nodes=400, continuation=False)
    assert exc.value.status == "Meridian_Crosses_Axis"
    assert exc.value.last_iterate.r.min() < 0 or exc.value.last_iterate.quadrature_points()[1].min() < 0


def test_a_hole_that_closes_is_named():
    """A thick shell (h = 0.3) with a small hole (cut 0.01) closes it under a stretch f0 = 0.3:
    its edge reaches the axis at 0.91 of the way, past which the meridian crosses it. The
    refusal says that the hole closes (the audit's message named only a fold or the mesh);
    a wider cut (0.03) stays open and solves."""
    with pytest.raises(SolverError) as exc:
        solve(Problem("anisotropic", {"f0": 0.3}, h=0.3, cut=0.01), nodes=200)
    assert "the cut edge (s = 0.01) reaches the axis: the hole closes" in str(exc.value)
    eq = solve(Problem("anisotropic", {"f0": 0.3}, h=0.3, cut=0.03), nodes=200)
    assert eq.r[0] > 0


@pytest.mark.parametrize("kwargs", [{"cut": 3.138}, {"cut": 1.57, "opening": 1.568},
                                    {"cut": 1.0, "opening": 2.1316}])
@pytest.mark.parametrize("nodes", [200, 800])
def test_short_shells_solve(kwargs, nodes):
    """Shells of 0.0036 and 0.01 R failed at 400–800 nodes (Restoration_Failed, issue 40):
    their meshes now hold cells of MIN_CELL at least, and the result matches a coarser mesh's."""
    from morphoshell.numerics.mesh import MIN_CELL

    problem = Problem("anisotropic", h=0.002, **kwargs)
    eq = solve(problem, nodes=nodes)
    assert np.isfinite(eq.energy) and eq.converged
    length = problem.end - problem.cut
    assert eq.solver.nodes <= max(20, int(length / MIN_CELL) + 1)
    coarse = solve(problem, nodes=60)
    assert abs(eq.psi[-1] - coarse.psi[-1]) < 1e-6 and abs(eq.r[-1] - coarse.r[-1]) < 1e-8


def test_a_shell_shorter_than_its_thickness_is_refused():
    """Issue 40: shells of 0.028 R at h = 0.24 and 0.0015 R at h = 0.014 were solved onto a
    wrong branch or failed in Ipopt; thin-shell theory does not hold there."""
    with pytest.raises(ValueError, match="shorter than its thickness h = 0.2420126494091666"):
        Problem("local_relaxation", {"F0": -0.14006119263684613, "s0": 0.13128156296513638},
                h=0.2420126494091666, cut=1.6588042976183948, opening=1.4544579606152306)
    with pytest.raises(ValueError, match="shorter than its thickness"):
        Problem("uniform", {"k": 2.595822261784333}, h=0.013779525617002138,
                cut=2.0428758278056804, opening=1.0972331390638899, theory="classical")


def test_shells_below_the_minimum_length_are_named():
    with pytest.raises(ValueError, match="is shorter than 0.001"):
        Problem("anisotropic", h=0.1, cut=1.57, opening=np.pi - 1.5705)


def test_a_shell_of_exactly_the_minimum_length_is_accepted():
    """L − P − Σ is computed: 1e-3 to round-off (1.1e-13 relative short here), and was
    refused as shorter than 0.001."""
    p = Problem("uniform", {"k": 0.0}, h=1e-4, cut=0.5, opening=np.pi - 0.5 - MIN_SHELL_LENGTH)
    assert p.end - p.cut == pytest.approx(MIN_SHELL_LENGTH, rel=1e-12)


@pytest.mark.parametrize("kwargs, match", [
    ({"cut": 1e-300}, r"cut \(Sigma\) = 1e-300 must be 0 \(a pole\) or at least 0.0001"),
    ({"cut": MIN_CUT / 2}, r"cut \(Sigma\) = 5e-05 must be 0"),
    ({"cut": -MIN_CUT}, r"cut \(Sigma\) = -0.0001 must be non-negative"),
    ({"cut": 0.3, "opening": 1e-20}, r"opening \(P\) = 1e-20 must be 0 \(a pole\) or at least"),
])
def test_cuts_and_openings_below_the_smallest_are_named(kwargs, match):
    """Cuts of 1e-20 ... 1e-300 failed with unrelated statuses (Continuation_Failed,
    Meridian_Crosses_Axis, Restoration_Failed) and raw CasADi warnings (user audit)."""
    with pytest.raises(ValueError, match=match):
        Problem("uniform", {"k": 0.0}, h=0.3, **kwargs)


def test_an_opening_of_a_disc_is_no_edge_near_the_axis():
    assert Problem("central_growth", h=0.02, geometry="disc", opening=MIN_CUT / 10).opening > 0


@pytest.mark.parametrize("problem", [
    Problem("uniform", {"k": 0.0}, h=0.3, cut=MIN_CUT),
    Problem("uniform", {"k": 0.0}, h=0.3, cut=0.3, opening=MIN_CUT),
    Problem("anisotropic", {"f0": -0.1}, h=0.05, cut=MIN_CUT),
    Problem("volvox", h=0.15, cut=MIN_CUT, opening=0.3),
    # the first to fail below it (at 1e-7, 200 nodes; docs/benchmarks.md)
    Problem("central_growth", {"G": 0.1, "w": 0.3}, h=0.05, geometry="disc", cut=MIN_CUT),
], ids=lambda p: f"{p.family} cut={p.cut:g} opening={p.opening:g}")
def test_the_smallest_cut_solves(problem):
    eq = solve(problem)
    assert eq.converged and eq.r.min() >= 0 and eq.s[0] == problem.cut


@pytest.mark.parametrize("nodes", [51200])
def test_fine_pole_graded_meshes_have_no_empty_cells(nodes):
    t = graded_mesh(nodes - 1, 1.0, "pole", "pole", 0.1, q=4.0)
    cells = np.diff(t)
    # every cell, including the last at s = pi, is representable
    assert cells.min() >= MIN_POLE_CELL * 0.999 and np.all(np.diff(np.pi * t) > 0)


def test_error_estimate_bounds_the_actual_error():
    # the estimate from the half mesh against the error measured on a mesh
    # four times finer (fourth order: 256 times more accurate)
    for problem in (Problem("anisotropic", {"f0": 0.1}, h=0.3, cut=0.3),
                    Problem("volvox", h=0.15, opening=0.3),
                    Problem("local_relaxation", {"F0": 0.35, "s0": 0.2}, h=0.05, cut=0.3)):
        eq = solve(problem, nodes=100)
        fine = solve(problem, nodes=397).estimated_values()
        for key, err in eq.error.errors.items():
            actual = abs(eq.estimated_values()[key] - fine[key])
            assert actual <= err + 1e-13, (problem.family, key, actual, err)
            # and it is not wildly pessimistic: SAFETY (2) x (2^4 - 1) = 30 times
            # on resolved fourth-order meshes; up to 138 times (measured: Volvox
            # z_end) where the quarter mesh (25 nodes) is far from resolved
            assert err < 200 * actual + 1e-11, (problem.family, key, actual, err)


def test_rtol_refines_until_met_or_raises():
    problem = Problem("volvox", h=0.15, opening=0.3)
    eq = solve(problem, nodes=50, rtol=1e-7)
    assert eq.error.meets(1e-7) and eq.solver.nodes > 50
    assert "refined from 50" in eq.solver.details["path"]
    with pytest.raises(SolverError) as exc:
        solve(problem, nodes=50, rtol=1e-10, max_nodes=400)
    assert exc.value.status == "Tolerance_Not_Met" and "does not meet rtol = 1e-10" in str(exc.value)
    assert exc.value.last_iterate.solver.nodes == 393     # 50 -> 99 -> 197 -> 393 nodes
    with pytest.raises(ValueError, match=r"rtol = 1e-11 must be a number in \[1e-10, 1\)"):
        solve(problem, nodes=50, rtol=1e-11)          # below the solvers' tolerance: refused


def test_a_thin_shells_error_is_relative_to_its_own_energy(caplog):
    """At h = 1e-6 a shell's energy (~h^3) lies far below the fixed floor of 1e-12 that the
    relative error was divided by: 100 nodes gave an energy 80 % off with a "relative"
    estimate of 4e-5, and rtol = 1e-3 accepted it (user audit).  With the floor scaled by
    h^3 the estimate says 13, a warning names the coarse mesh, and rtol refines to the
    energy of the unrelaxed sphere (k = 0: its bending energy, less the cut's tiny
    release) to 1e-4."""
    import logging

    from morphoshell.mechanics import asymptotics

    h, cut = 1e-6, 0.3
    problem = Problem("uniform", {"k": 0.0}, h=h, cut=cut, theory="classical")
    reference = h**3 / 8 * 2 * np.pi * (1 + np.cos(cut)) + asymptotics.energy_released(h, 0.0, cut)
    with caplog.at_level(logging.WARNING, logger="morphoshell"):
        coarse = solve(problem, nodes=100)
    assert abs(coarse.energy / reference - 1) > 0.5 and coarse.error.relative()["energy"] > 1
    assert "the mesh is too coarse" in caplog.text
    fine = solve(problem, nodes=100, rtol=1e-3)
    assert abs(fine.energy / reference - 1) < 1e-4 and fine.error.meets(1e-3)
    # a stress-free state's energy is round-off (the fast relaxation's intact shell: 1e-14
    # C R^2, estimate 6e-12): no warning for it
    from morphoshell import ablate
    from morphoshell.io.problem_files import example_path, load_problem

    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="morphoshell"):
        pre = ablate(load_problem(example_path("fast_relaxation"))[0]).pre
    assert abs(pre.energy) < pre.error.energy_floor and "too coarse" not in caplog.text


THIN_RIM = Problem("anisotropic", {"f0": -0.278375609690089}, h=4.3723617825288633e-4,
                   cut=0.02)


def test_rtol_retries_a_failed_continuation_on_finer_meshes():
    """make fuzz's thin sphere, whose rim curls over: on 200 nodes the rim folds a second
    time, where no landing is found (``Snap_Through_Failed``; 300, 400 and 800 nodes snap
    once, tests/solvers/test_arclength.py). With rtol the solve retries on 399 nodes, says
    so, and ends where 800 nodes end (7.977922e-5 C R²); without it, or with no finer mesh
    allowed, the named error."""
    for options in ({}, {"rtol": 1e-3, "max_nodes": 300}):
        with pytest.raises(SolverError) as exc:
            solve(THIN_RIM, nodes=200, **options)
        assert exc.value.status == "Snap_Through_Failed" and "before" not in str(exc.value)
    eq = solve(THIN_RIM, nodes=200, rtol=1e-3)
    assert "on 399 nodes after Snap_Through_Failed on 200 nodes (retried for rtol)" in \
        eq.solver.details["path"]
    assert eq.error.meets(1e-3) and abs(eq.energy - 7.977922e-5) < 1e-5 * eq.energy


def test_rtol_retries_a_few_times_then_names_each_failure(monkeypatch):
    """At most MESH_RETRIES finer meshes (8 times the nodes), and the error lists them."""
    tried = []

    def failing(solver, problem, anchors, switch):
        tried.append(solver.nodes)
        raise SolverError("no landing", "Snap_Through_Failed")
    monkeypatch.setattr(routes, "continue_to", failing)
    with pytest.raises(SolverError) as exc:
        solve(Problem("uniform", {"k": 0.5}, h=0.1, cut=0.3), nodes=20, rtol=1e-6)
    assert tried == [20, 39, 77, 153] and exc.value.status == "Snap_Through_Failed"
    assert str(exc.value) == ("no landing (on 153 nodes; before: Snap_Through_Failed on 20 "
                              "nodes, Snap_Through_Failed on 39 nodes, Snap_Through_Failed "
                              "on 77 nodes)")


def test_bvp_runs_within_its_time_budget():
    problem = Problem("uniform", {"k": 0.0}, h=0.3, cut=0.3)
    with pytest.raises(SolverError) as exc:
        solve(problem, method="bvp", max_seconds=1e-3)
    assert exc.value.status == "Time_Limit_Exceeded"


def test_bvp_time_out_keeps_its_last_iterate(monkeypatch):
    # A clock that ticks once per reading makes the time-out land after a
    # fixed number of solve_bvp callbacks, whatever the machine's speed.
    from morphoshell.solvers import bvp
    problem = Problem("uniform", {"k": 0.0}, h=0.3, cut=0.3)
    converged = solve(problem, method="bvp")
    ticks = iter(range(10**9))
    monkeypatch.setattr(bvp, "time", type("Clock", (), {"perf_counter": lambda: next(ticks)}))
    with pytest.raises(SolverError) as exc:
        solve(problem, method="bvp", max_seconds=12)
    last = exc.value.last_iterate
    assert exc.value.status == "Time_Limit_Exceeded" and "last iterate is attached" in str(exc.value)
    assert last is not None and not last.converged and last.solver.status == "Time_Limit_Exceeded"
    # an iterate on a whole mesh from the cut to the pole's offset, near the
    # converged energy (0.0398 C R^2 here; the iterates differ from it at 1e-8)
    assert last.s[0] == pytest.approx(0.3) and last.s[-1] == pytest.approx(np.pi - 1e-4)
    assert last.energy == pytest.approx(converged.energy, rel=1e-3)


def test_neutral_problem():
    p = Problem("volvox", h=0.15, opening=0.3)
    n = neutral_problem(p)
    assert n.params["f2"] == 1.0 and n.params["s2"] == p.params["s2"]
    assert neutral_problem(Problem("uniform", {"k": 1.0}, h=0.1)) is None


def test_error_estimate_holds_before_the_asymptotic_range():
    # found by make fuzz: the error of psi(Sigma) shrank only 1.7x from 100 to
    # 200 nodes (1.2e-8 -> 7.0e-9), and the plain difference 5.0e-9
    # under-stated it; the limit from 1600 nodes (error ~2e-11 there)
    problem = Problem("volvox", {"f1": 0.90625, "f2": 1.09375, "f3": 1.0, "f4": 1.0, "f5": 1.0,
                                 "kappa1": 0.5, "kappa2": -2.0, "kappa3": 1.0, "kappa4": 1.0,
                                 "sigma": 0.05,
                                 "s1": 1.1867676689142115, "s2": 1.460637130971337,
                                 "s3": 1.7345065930284627, "s4": 2.0996658757712967},
                      h=0.23713737056616552, cut=1.158203125, opening=0.3)
    eq = solve(problem, nodes=200)
    limit = solve(problem, nodes=1600).estimated_values()
    for key, err in eq.error.errors.items():
        actual = abs(eq.estimated_values()[key] - limit[key])
        assert actual <= err + 1e-12, (key, actual, err)


@pytest.mark.xfail(strict=True, reason="a known limit of estimates from coarser meshes "
                   "(docs/solution.md, 'An error estimate'): if this passes, update the docs")
def test_error_estimate_of_a_shell_whose_steps_are_not_yet_resolved():
    # found by make fuzz (2026-11-24): z_end is off by 9.8e-7 at 100 nodes and 7.9e-7 at
    # 200 (a shrink of 1.2x, after 4.6x from 50 to 100), estimate 4.7e-7; from about 400
    # nodes (18 across each step of width sigma) it shrinks 14-17x per refinement
    problem = Problem("volvox", {"f1": 0.818359375, "f2": 1.03125, "f3": 1.0, "f4": 1.0,
                                 "f5": 1.09375, "kappa1": 0.0, "kappa2": -2.0, "kappa3": 1.0,
                                 "kappa4": 1.0, "sigma": 0.05,
                                 "s1": 1.184207084522778, "s2": 1.4574856424895728,
                                 "s3": 1.7307642004563677, "s4": 2.095135611078761},
                      h=0.0012863969449369746, cut=0.241036234688102, opening=0.3,
                      theory="classical")
    eq = solve(problem, nodes=200)
    limit = solve(problem, nodes=1600).estimated_values()
    actual = abs(eq.estimated_values()["z_end"] - limit["z_end"])
    assert actual <= eq.error.errors["z_end"], (actual, eq.error.errors["z_end"])


def test_a_refinement_that_cannot_carry_the_solution_over_continues_on_the_finer_mesh(
        monkeypatch):
    """Where the solution interpolated onto the finer mesh leaves Ipopt short of a solution
    (make fuzz: a thin sphere's curled rim, 1593 -> 3185 nodes, Maximum_Iterations_Exceeded),
    rtol's refinement reaches the finer mesh by continuation, as solve() does there, and
    says so; forced here on the toy sphere, which then ends where solve() on 99 nodes does."""
    from morphoshell.solvers import refinement
    problem = Problem("uniform", {"k": 0.5}, h=0.1, cut=0.3)
    carried = refinement.solve_from

    def failing(solver, problem, eq, anchors=()):
        if solver.nodes > eq.solver.nodes:
            raise SolverError("no", "Maximum_Iterations_Exceeded")
        return carried(solver, problem, eq, anchors)
    monkeypatch.setattr(refinement, "solve_from", failing)
    eq = solve(problem, nodes=50, rtol=1e-5, max_nodes=99)
    assert eq.solver.nodes == 99 and "(99 nodes by continuation: carried over, " \
        "Maximum_Iterations_Exceeded)" in eq.solver.details["path"]
    assert np.max(np.abs(eq.x - solve(problem, nodes=99).x)) < 1e-12
