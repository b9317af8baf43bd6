"""Bad arguments of the routes fail before any work, naming the argument and its value
(a user audit found raw CasADi RuntimeErrors with Ipopt's option table on stdout,
AttributeErrors, tolerances silently ignored and 30-s runs blamed on a boundary layer)."""
import math

import pytest

from morphoshell import DirectSolver, Problem, solve
from morphoshell.numerics.ipopt_options import check_ipopt_options
from morphoshell.solvers import routes
from morphoshell.solvers.options import MAX_DIRECT_TOL, POLE_OFFSET, REFERENCE_TOL

TOY2 = Problem("uniform", {"k": 0.0}, h=0.1, cut=0.3)
POLE = Problem("uniform", {"k": 0.0}, h=0.1)

NAN = float("nan")


def _refused(capfd, error, match, *args, **kwargs):
    """``solve(*args, **kwargs)`` raises ``error`` matching ``match`` without building a
    solver and without printing anything (Ipopt printed its option table on stdout)."""
    builds = routes.cache_info()["builds"]
    capfd.readouterr()
    with pytest.raises(error, match=match):
        solve(*args, **kwargs)
    assert routes.cache_info()["builds"] == builds
    assert capfd.readouterr().out == ""


@pytest.mark.parametrize("kwargs, error, match", [
    ({"linear_solver": "ma27x"}, ValueError, r"linear_solver = 'ma27x': choose one of \['mumps'"),
    # the wheel has no libhsl.so: Ipopt would fail with Invalid_Option at its first solve
    ({"linear_solver": "ma27"}, ValueError, r"linear_solver = 'ma27': Ipopt cannot load it.*"
                                            r"libhsl\.so"),
    # ma97 without libhsl.so crashed Ipopt's probe (a segmentation fault): refused first
    ({"linear_solver": "ma97"}, ValueError, r"linear_solver = 'ma97': Ipopt cannot load it "
                                            r"\(libhsl\.so: cannot open"),
    ({"linear_solver": "pardiso"}, ValueError, r"'pardiso': Ipopt cannot load it \(libpardiso"),
    ({"ipopt_options": {"tol": -1}}, ValueError,
     r"ipopt_options: tol = -1 is refused by Ipopt: .*valid: 0 < \(1e-08\) <= \+inf"),
    ({"ipopt_options": {"tolx": 1}}, ValueError, r"tolx = 1 is refused by Ipopt: No such IPOPT "
                                                 r"option: tolx"),
    ({"ipopt_options": {"max_iter": "a"}}, ValueError, r"max_iter = 'a' .*must be an integer"),
    ({"ipopt_options": {"mu_strategy": "x"}}, ValueError, r"valid: monotone, adaptive"),
    ({"ipopt_options": [("tol", 1e-8)]}, TypeError, r"ipopt_options = \[.*must be a mapping"),
    ({"warm_start": 42}, TypeError, r"warm_start = 42 must be an Equilibrium"),
    # a user audit: "'float' object is not iterable", and a string taken as True
    ({"anchors": 1.0}, TypeError, r"anchors = 1.0 must be a sequence of material points s"),
    ({"anchors": ["0.5"]}, TypeError, r"anchors = \['0.5'\] must be a sequence of material"),
    ({"continuation": "no"}, TypeError, r"continuation = 'no' must be True or False"),
])
def test_bad_direct_arguments_are_named_before_any_work(capfd, kwargs, error, match):
    _refused(capfd, error, match, TOY2, nodes=50, **kwargs)


def test_a_problem_that_is_no_problem_is_named(capfd):
    _refused(capfd, TypeError, r"problem = \{'family': 'uniform'\} must be a morphoshell Problem",
             {"family": "uniform"})


@pytest.mark.parametrize("tol", [NAN, -1.0, 0.0, 1e6, 2 * MAX_DIRECT_TOL, True])
def test_a_direct_tolerance_out_of_range_is_named(capfd, tol):
    # nan, -1 and 0 were ignored; 1e6 returned the undeformed shell as Newton_Converged
    _refused(capfd, ValueError, f"tol = {tol!r} must", TOY2, nodes=50, tol=tol)


def test_tolerances_at_their_bounds_are_accepted():
    assert math.isfinite(solve(TOY2, nodes=50, tol=MAX_DIRECT_TOL).energy)
    assert math.isfinite(solve(TOY2, method="bvp", tol=REFERENCE_TOL[1]).energy)


@pytest.mark.parametrize("method, kwargs, match", [
    # tol = -1 ran 30 s and then blamed a boundary layer; nan and pole_offset = -1 failed
    # with messages about bc_tol and a singular Jacobian
    ("bvp", {"tol": -1.0}, r"tol = -1.0 must lie in \[1e-11, 0.001\]"),
    ("bvp", {"tol": NAN}, r"tol = nan must be finite"),
    ("bvp", {"bc_tol": 1.0}, r"bc_tol = 1.0 must lie in"),
    ("bvp", {"pole_offset": -1.0}, r"pole_offset = -1.0 must lie in \[1e-06, 0.1\]"),
    ("bvp", {"homotopy_steps": 0}, r"homotopy_steps = 0 must be an integer >= 1"),
    ("bvp", {"max_seconds": 0}, r"max_seconds = 0 must be positive"),
    ("shooting", {"tol": 1e-14}, r"tol = 1e-14 must lie in"),
    ("shooting", {"atol": 0}, r"atol = 0 must lie in \[1e-16, 1e-06\]"),
    ("shooting", {"pole_offset": 2 * POLE_OFFSET[1]}, r"pole_offset = 0.2 must lie in"),
    ("shooting", {"integrator": "RK45"}, r"integrator = 'RK45' must be one of"),
    ("shooting", {"segments": NAN}, r"segments = nan must be finite"),
    ("shooting", {"points": 1}, r"points = 1 must be an integer >= 2"),
    ("shooting", {"warm_start": "x"}, r"warm_start = 'x' must be an Equilibrium"),
])
def test_bad_reference_options_are_named_before_any_work(capfd, method, kwargs, match):
    _refused(capfd, (ValueError, TypeError), match, POLE, method=method, **kwargs)


def test_a_pole_offset_must_leave_the_shell_near_the_pole():
    short = Problem("uniform", {"k": 0.0}, h=1e-3, opening=math.pi - 0.05)    # 0.05 long
    with pytest.raises(ValueError, match="pole_offset = 0.01 must be at most a tenth of the "
                                         "shell's length 0.05"):
        solve(short, method="bvp", pole_offset=0.01)


def test_ipopt_options_it_accepts_pass_and_bundled_solvers_load():
    check_ipopt_options("mumps", {"mu_strategy": "adaptive", "max_iter": 100})
    check_ipopt_options("spral")
    with pytest.raises(TypeError, match="the key 1 must be the name of an Ipopt option"):
        check_ipopt_options("mumps", {1: 2})


def test_a_direct_solver_of_a_problem_instead_of_its_structure_is_named():
    # a user audit: AttributeError: 'str' object has no attribute 'length'
    builds = routes.cache_info()["builds"]
    with pytest.raises(TypeError, match=r"structure must be a Structure, a Problem's "
                                        r"\.structure \(pass problem\.structure\), not a Problem"):
        DirectSolver(TOY2, nodes=50)
    assert routes.cache_info()["builds"] == builds


THIN = Problem("uniform", {"k": 0.0}, h=1e-5, cut=0.5)


@pytest.mark.parametrize("problem", [THIN, Problem("uniform", {"k": 0.0}, h=1e-5)],
                         ids=["cut", "closed"])
def test_a_direct_failure_on_a_shell_too_thin_for_it_names_h_and_bvp(problem, caplog):
    """h = 1e-5 is a valid Problem (MIN_THICKNESS = 1e-6; the BVP route solves it) but the
    direct route failed on it with Restoration_Failed, Continuation_Failed or
    Error_In_Step_Computation on every mesh and option, naming only the mesh (user
    audit).  The failure keeps its status and now names h, the thinnest shell the route
    solves from its default start and the route that solves it: first, once, before the
    continuation's advice that does not apply (audit 21: it came last, after 800
    characters), and solve() warns of it before it starts.  (Not refused up front: 100
    nodes refined by rtol solve a classical h = 1e-6 shell, test_right_minimum.)"""
    import logging

    from morphoshell import SolverError
    with caplog.at_level(logging.WARNING, logger="morphoshell.solvers.routes"), \
            pytest.raises(SolverError) as exc:
        solve(problem)
    assert exc.value.status in ("Restoration_Failed", "Continuation_Failed")
    message = str(exc.value)
    assert message.startswith("the shell is thinner (h = 1e-05) than 2e-05")
    assert message.count('method="bvp"') == 1
    [warned] = [r.getMessage() for r in caplog.records]
    assert warned.startswith("solve of uniform: the shell is thinner (h = 1e-05) than 2e-05")


def test_the_thin_shell_note_leads_a_message_once_and_leaves_others_alone():
    """A direct solve's failure, already led by the note, quoted inside a continuation's:
    the note is moved to the front, not repeated; a thick shell's message is unchanged."""
    from morphoshell.solvers.options import thin_shell_first, thin_shell_note

    inner = thin_shell_first(THIN, "Ipopt stopped")
    outer = thin_shell_first(THIN, f"continuation stopped ({inner}); try a finer mesh")
    assert outer.startswith(thin_shell_note(THIN)) and outer.count(thin_shell_note(THIN)) == 1
    assert outer.endswith("continuation stopped (Ipopt stopped); try a finer mesh")
    assert thin_shell_first(THIN.with_updates(h=2e-5), "Ipopt stopped") == "Ipopt stopped"


def test_the_direct_solver_itself_names_it():
    """ablate, sweep, continue and fits call DirectSolver.solve, not solve() (on the mesh
    solve() grades for h = 1e-5; a mesh graded for h = 0.1 happened to solve it cold)."""
    from morphoshell import SolverError
    from morphoshell.numerics.mesh import mesh_spec
    solver = DirectSolver(THIN.structure, mesh=mesh_spec(THIN, 200, 2))
    with pytest.raises(SolverError, match=r'^the shell is thinner \(h = 1e-05\) than 2e-05.*'
                                          r'method="bvp"'):
        solver.solve(THIN)


@pytest.mark.parametrize("cut, nodes", [(0.5, 200), (0.0, 200), (0.5, 800), (0.0, 800)])
def test_the_thinnest_shell_the_direct_route_takes_solves(cut, nodes):
    """At h = MIN_DIRECT_THICKNESS = 2e-5 the audit's shells solve on 200 and 800 nodes (1.5e-5
    failed closed on 800: Restoration_Failed).  Energies measured 1.178896e-14 (cut 0.5)
    and 1.256637e-14 (closed) on 800 and 1600 nodes, 200 nodes within 2e-5 relative of
    them (its discretisation error): 1e-4 allowed."""
    eq = solve(Problem("uniform", {"k": 0.0}, h=2e-5, cut=cut), nodes=nodes)
    assert eq.energy == pytest.approx(1.178896e-14 if cut else 1.256637e-14, rel=1e-4)


def test_the_bvp_route_solves_the_thinnest_accepted_shell():
    """The route the refusal names solves h = 1e-6 (MIN_THICKNESS), cut 0.5 (6 s): the
    documented range of Problem is what works.  Energy measured 1.474419e-18, the
    bending energy's h³ times that of h = 1e-5 (1.473921e-15, the audit's BVP value) to
    3.4e-4 (the boundary layer's share shrinks like √h): 1e-3 allowed."""
    eq = solve(Problem("uniform", {"k": 0.0}, h=1e-6, cut=0.5), method="bvp")
    assert eq.energy == pytest.approx(1.473921e-15 * 1e-3, rel=1e-3)
