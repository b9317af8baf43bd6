"""Property-based fuzzing: random valid problems and random bad command lines.

Properties (issue "The right minimum or an error"):

* a returned equilibrium agrees with the solution on a mesh with twice the
  cells within its own error estimate;
* r ≥ 0 everywhere on a returned equilibrium;
* the default solve (continuation) equals a reference continuation with many
  small steps on the finer mesh: no wrong-branch result (a solve that switched
  branches where its path lost stability, as the discs grown in their centre
  do, against a cold minimisation from a tilted start on the finer mesh);
* a cold solve (Newton's steps first) is the cold Ipopt solve: the same
  outcome, the same minimum;
* a branch (follow_branch, 40 nodes) records every change of its stability as
  an event, turns in τ exactly at its folds, has points that meet the KKT
  tolerance and their recorded inertia when re-evaluated apart from the
  correctors, and, stable all the way, ends where solve() ends;
* bad command-line input (of solve, continue and sweep; and of estimate, fit,
  campaign and ablate, drawn by tests/fuzz_bad_inputs.py) exits 2 with one
  line naming the item, no traceback, no raw warning, no file left behind,
  within REFUSAL_SECONDS (no solver runs before a refusal).

A problem may also be refused with a SolverError naming its status ("the right
minimum or an error"); that is counted, not failed.  ``make test`` runs a small
derandomised budget (profile "ci"); ``make fuzz`` runs 1500 random problems, 187
branches and 3000 bad command lines (profile "fuzz") and prints the counts.
"""
import collections
import math
import os
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from morphoshell import Problem, SolverError, solve
from morphoshell.io.problem_files import example_path
from morphoshell.solvers.arclength import Arclength
from morphoshell.solvers.branches import follow_branch
from morphoshell.solvers.direct import DirectSolver, solver_of
from morphoshell.solvers.routes import RETRIED
from morphoshell.numerics.mesh import mesh_spec

from fuzz_bad_inputs import Hang, bad_inputs, make_bad_files, run_cli

settings.register_profile("ci", max_examples=8, deadline=None, derandomize=True,
                          suppress_health_check=[HealthCheck.too_slow], database=None)
settings.register_profile("fuzz", max_examples=1500, deadline=None,
                          suppress_health_check=[HealthCheck.too_slow])
settings.load_profile(os.environ.get("MORPHOSHELL_FUZZ", "ci"))

ROOT = Path(__file__).resolve().parents[1]
TOY2 = str(example_path("toy2_ablation"))
COUNTS: collections.Counter = collections.Counter()
#: The valid problems refused with a solver status, and those whose solve found a lower
#: minimum than the reference (with the path that got there), printed after the counts: the
#: next session's reproducers (a refusal is named, but a valid problem should be solved).
REFUSED: list = []
#: Seconds a refusal may take: checks only, no solver (imports are warmed first).
REFUSAL_SECONDS = 10.0
#: Bad inputs of estimate, fit, campaign, ablate: the profile's examples (make fuzz), at
#: least 24 (make test).
BAD_INPUT_EXAMPLES = max(24, settings.default.max_examples)


#: Counts printed even when zero: what a run must show none of.
MUST_BE_ZERO = ("wrong branch or estimate", "hangs", "tracebacks", "raw warnings")


@pytest.fixture(scope="module", autouse=True)
def report():
    yield
    for key in MUST_BE_ZERO:
        COUNTS.setdefault(key, 0)
    print("\nfuzz counts: " + ", ".join(f"{k} {v}" for k, v in sorted(COUNTS.items())))
    for line in dict.fromkeys(REFUSED):          # (hypothesis replays a failing example)
        print(f"  {line}" if line.startswith("lower") else f"  refused: {line}")


# --------------------------------------------------------------------------
# random valid problems
# --------------------------------------------------------------------------

def _params(family: str, draw) -> dict:
    if family == "uniform":
        return {"k": draw(st.floats(-2.0, 3.0))}
    if family == "anisotropic":
        return {"f0": draw(st.floats(-0.3, 0.3))}
    if family == "local_relaxation":
        return {"F0": draw(st.floats(-0.3, 0.5)), "s0": draw(st.floats(0.05, 0.5))}
    scale = draw(st.floats(0.85, 1.0))     # volvox: the illustrative profile, perturbed
    return {"f1": draw(st.floats(0.8, 1.0)), "f2": draw(st.floats(0.9, 1.1)),
            "f3": draw(st.floats(1.0, 1.2)), "f5": draw(st.floats(1.0, 1.2)),
            "kappa1": draw(st.floats(0.0, 1.2)), "kappa2": draw(st.floats(-9.0, -2.0)),
            "s1": 1.3 * scale, "s2": 1.6 * scale, "s3": 1.9 * scale, "s4": 2.3 * scale}


def _disc(draw, h: float, theory: str) -> Problem:
    """A disc (or an annulus) grown in its centre: flat by mirror symmetry up to a branch point,
    where it buckles (solve switches to the stable half of the other branch)."""
    params = {"G": draw(st.floats(-0.3, 0.5)), "w": draw(st.floats(0.1, 1.0))}
    cut = draw(st.one_of(st.just(0.0), st.floats(0.02, 0.5)))
    return Problem("central_growth", params, h=h, cut=cut, theory=theory, geometry="disc")


@st.composite
def problems(draw):
    family = draw(st.sampled_from(["uniform", "anisotropic", "local_relaxation", "volvox",
                                   "central_growth"]))
    theory = draw(st.sampled_from(["large_bending", "classical"]))
    h = 10 ** draw(st.floats(-4.0, math.log10(0.3)))          # thinner than before, to 1e-4
    if family == "central_growth":
        return _disc(draw, h, theory)
    cut = draw(st.one_of(st.just(0.0), st.floats(0.02, 1.2)))
    opening = 0.3 if family == "volvox" else draw(st.one_of(st.just(0.0), st.floats(0.05, 1.0)))
    if family == "local_relaxation" and cut == 0:
        cut = 0.3                                  # the relaxation is at a cut
    if family != "volvox" and draw(st.integers(0, 3)) == 0:
        # a short shell (issue 40): an annulus of 1e-3 to 0.03 R next to the far end
        cut = max(0.02, math.pi - opening - 10 ** draw(st.floats(-3.0, -1.5)))
    try:
        return Problem(family, _params(family, draw), h=h, cut=cut, opening=opening,
                       theory=theory)
    except ValueError:
        assume(False)


def _solve_or_count(problem, **kwargs):
    try:
        return solve(problem, **kwargs)
    except SolverError as exc:
        COUNTS[f"refused ({exc.status})"] += 1
        REFUSED.append(f"{problem!r} ({exc.status}{_with_rtol(problem, exc, **kwargs)})")
        return None


def _with_rtol(problem, exc, **kwargs) -> str:
    """Whether a refusal whose remedy is a finer mesh is solved when rtol may refine: a
    loose rtol, so that only the retries refine (counted; the answer is not checked)."""
    if exc.status not in RETRIED:
        return ""
    try:
        eq = solve(problem, rtol=0.1, max_nodes=3200, **kwargs)     # (at most ~20 s)
    except SolverError as again:
        COUNTS["refused: not solved with rtol either"] += 1
        return f"; with rtol too: {again.status}"
    COUNTS["refused: solved with rtol"] += 1
    return f"; with rtol solved on {eq.solver.nodes} nodes"


@given(problems())
def test_solutions_agree_with_the_refined_mesh_within_their_estimate(problem):
    eq = _solve_or_count(problem, nodes=200)
    if eq is None:
        return
    COUNTS["solved"] += 1
    if eq.solver.details.get("switches"):       # (where its path lost stability at a branch point)
        COUNTS["switched branches"] += 1
    assert eq.r.min() >= 0 and eq.quadrature_points()[1].min() >= 0, "r < 0"
    if eq.error.note:
        COUNTS["no estimate"] += 1
        return
    # the reference: continuation with fixed small steps on twice the cells
    # (a different path and mesh from the solution's), from the stress-free
    # parameters
    reference = _reference(problem, 399)
    tilted = reference is None and bool(eq.solver.details.get("switches"))
    if tilted:
        reference = _tilted(problem, eq, 399)
    if reference is None:
        return
    values, ref = eq.estimated_values(), reference.estimated_values()
    if tilted:
        ref = _as_seen_from(ref, values)
    for key, err in eq.error.errors.items():
        if key.startswith("psi"):        # (an angle: the same modulo 2 pi)
            ref[key] = values[key] + math.remainder(ref[key] - values[key], 2 * math.pi)
        # the finer mesh's own error, ~1/16 of this one's, and round-off on top (a cold
        # minimisation's tolerance on top: it stops at a KKT error of 1e-8, 4e-10 off in
        # psi_start on a thick annulus, where the continuations agree to 1e-12)
        allowed = 1.1 * err + (1e-8 if tilted else 1e-10) * max(1.0, abs(values[key]))
        if abs(values[key] - ref[key]) > allowed:
            if eq.energy < reference.energy - 1e-9 * abs(reference.energy):
                # another equilibrium of lower energy than the reference's path found (short
                # annuli of thin shells have several, 1e-4 of their width apart): the solve
                # is the better minimum, not a wrong branch
                COUNTS["lower minimum than the reference"] += 1
                REFUSED.append(f"lower than the reference: {problem!r} "
                               f"({eq.solver.details['path']})")
                return
            COUNTS["wrong branch or estimate"] += 1
            pytest.fail(f"{problem}: {key} = {values[key]!r} but the refined continuation gives "
                        f"{ref[key]!r} (estimated error {err:.3g})")


def _reference(problem, nodes: int, steps: int = 16):
    solver = DirectSolver(problem.structure, mesh=mesh_spec(problem, nodes, 2))
    fam = problem.family_obj
    names = [n for n in fam.neutral if n in problem.params]
    eq = None
    try:
        for tau in np.linspace(0, 1, steps + 1):
            sub = problem.with_updates(**{n: fam.neutral[n] + tau * (problem.params[n]
                                                                      - fam.neutral[n])
                                          for n in names})
            eq = solver.solve(sub, warm_start=eq)
    except (SolverError, ValueError):
        COUNTS["reference refused"] += 1
        return None
    return eq


def _tilted(problem, eq, nodes: int):
    """The reference of a solve that switched branches (the reference continuation stays on
    the branch that lost its stability, and is refused there): a cold minimisation on the
    finer mesh from the undeformed shell tilted toward the solution's side (no continuation,
    no branch switching), polished by a warm re-solve."""
    solver = DirectSolver(problem.structure, mesh=mesh_spec(problem, nodes, 2))
    p = problem.parameter_vector()
    layout = solver.disc.layout
    r, psi, f = layout.split(solver.disc.initial_guess(p))
    s = solver.disc.points(p)
    side = 1.0 if eq.psi[-1] >= 0 else -1.0
    try:
        cold = solver.solve(problem, x0=layout.pack(r, psi + side * 0.1 * (s - s[0]), f))
        # then warm from itself (Newton's steps): Ipopt's cold solve of a thin shell stops
        # within its tolerance, at h = 1e-4 0.4 % off in psi_end
        return solver.solve(problem, warm_start=cold)
    except SolverError:
        COUNTS["reference refused"] += 1
        return None


def _as_seen_from(ref: dict, values: dict) -> dict:
    """A disc's reference values, ψ wrapped to (−π, π] and mirrored (z → −z, ψ → −ψ: a mirror
    image is as good a solution) if it bends the other way than ``values``'."""
    out = dict(ref)
    for key in ("psi_start", "psi_end"):
        out[key] = math.remainder(ref[key], 2 * math.pi)
    if out["psi_end"] * values["psi_end"] < 0:
        for key in ("psi_start", "psi_end", "z_end"):
            out[key] = -out[key]
    return out


@given(problems(), st.sampled_from([30, 60]), st.sampled_from([2, 3]))
def test_a_cold_newton_solve_is_the_cold_ipopt_solve(problem, nodes, stages):
    """Cold solves try Newton's steps first (morphoshell.numerics.newton, "Cold starts"): solved or
    refused as Ipopt alone would, and where solved the same minimum (within the KKT tolerance:
    measured up to 1e-8 of x at thin shells' round-off floor, 1e-14 elsewhere), or one of no
    higher energy: where a shell has several minima near the start Ipopt's line search can
    take it to another (a thin annulus of local_relaxation: Newton's the continuation's,
    Ipopt's 5 % higher), and they are counted and listed."""
    spec = mesh_spec(problem, nodes, stages)
    out = []
    for newton in (True, False):
        try:
            out.append(DirectSolver(problem.structure, stages=stages, mesh=spec,
                                    newton=newton).solve(problem))
        except SolverError as exc:
            out.append(exc.status)
    a, b = out
    if isinstance(a, str) or isinstance(b, str):
        COUNTS["cold: refused by both" if a == b else "cold: outcomes differ"] += 1
        assert a == b, f"{problem}: Newton first {a!r}, Ipopt alone {b!r}"
        return
    COUNTS[f"cold: solved by {a.solver.details.get('route', 'ipopt')}"] += 1
    if np.max(np.abs(a.x - b.x)) < 1e-7 * max(1.0, np.max(np.abs(b.x))):
        return
    COUNTS["cold: another minimum than Ipopt's"] += 1
    REFUSED.append(f"cold: Newton first {a.energy:.6g}, Ipopt alone {b.energy:.6g}: {problem!r} "
                   f"({nodes} nodes, {stages} stages)")
    assert a.energy <= b.energy * (1 + 1e-9), f"{problem}: Newton's steps to a higher minimum"


#: Branches followed per run of make fuzz (each a few tenths of a second on 40 nodes).
BRANCH_EXAMPLES = max(4, settings.default.max_examples // 8)


@settings(max_examples=BRANCH_EXAMPLES)
@given(problems())
def test_a_branch_records_every_change_of_its_stability(problem):
    """follow_branch on 40 nodes, on random problems: every change of the number of negative
    eigenvalues between neighbouring points is an event at one of them, τ turns exactly at
    the folds, and every ordinary point, re-evaluated by BorderedKKT.state (the Python
    path, apart from the correctors' fused calls), meets the KKT tolerance and has the
    recorded inertia; a branch stable all the way ends where solve() does."""
    try:
        branch = follow_branch(problem, nodes=40, max_points=600)
    except (SolverError, ValueError) as exc:
        COUNTS[f"branch: refused ({getattr(exc, 'status', type(exc).__name__)})"] += 1
        if isinstance(exc, SolverError):          # (ValueError: stress-free already)
            REFUSED.append(f"branch of {problem!r} ({exc.status})")
        return
    pts = branch.points
    COUNTS["branch: followed"] += 1
    COUNTS["branch: events"] += len(branch.events)
    for a, b in zip(pts, pts[1:]):
        if a.negative_eigenvalues != b.negative_eigenvalues:
            assert a.event or b.event, f"{problem}: stability changes at {b.tau} unrecorded"
    for i in range(1, len(pts) - 1):
        turns = (pts[i].tau - pts[i - 1].tau) * (pts[i + 1].tau - pts[i].tau) < 0
        assert turns == (pts[i].event == "fold"), f"{problem}: tau turns at {pts[i].tau}?"
    arc = Arclength(solver_of(pts[0].equilibrium), branch.line, pts[0].equilibrium.anchors)
    for pt in pts[1::max(1, len(pts) // 5)]:
        if pt.event:
            continue
        state = arc.kkt.state(arc.kkt.pack(pt.equilibrium.x, pt.equilibrium.lam_g),
                              arc._data(pt.tau))
        assert state.error <= arc.acceptable_tol, f"{problem}: KKT error {state.error:.2g}"
        assert arc.kkt.inertia(state).negative == pt.negative_eigenvalues, problem
    if all(pt.stable for pt in pts):
        eq = solve(problem, nodes=40)
        assert np.max(np.abs(eq.x - pts[-1].equilibrium.x)) < 1e-7, problem


# --------------------------------------------------------------------------
# random bad command lines
# --------------------------------------------------------------------------

_NOT_INT = st.sampled_from(["abc", "1.5", "1e3", "", " ", "nan", "-", "0x10", "5.0"])
_BAD_SET = st.one_of(
    st.tuples(st.sampled_from(["kappa", "hh", "cutt", "x", "K"]), st.just("1")),
    st.tuples(st.sampled_from(["k", "h", "cut", "opening"]),
              st.sampled_from(["abc", "nan", "inf", "-inf", "1e400", ""])),
    st.tuples(st.just("h"), st.sampled_from(["0", "-1", "1", "2", "1e308"])),
    st.tuples(st.just("k"), st.sampled_from(["1e4", "-1e308", "5000"])),
    st.tuples(st.just("cut"), st.sampled_from(["-0.1", "3.1413", "4", "1e9"])),
    st.tuples(st.sampled_from(["nodes", "stages"]), st.sampled_from(["0", "2.5", "x", "1e9"])),
    st.tuples(st.sampled_from(["method", "theory", "family"]), st.sampled_from(["x", "42", "shoot"])),
)


@st.composite
def bad_command_lines(draw, tmp):
    kind = draw(st.sampled_from(["nodes", "set", "stages", "method", "solver", "rtol", "output",
                                 "file", "command", "continue", "sweep"]))
    base = ["solve", TOY2]
    if kind == "nodes":
        return base + ["--nodes", draw(st.one_of(_NOT_INT, st.integers(-10**12, 4).map(str),
                                                 st.integers(102401, 10**15).map(str)))], "--nodes"
    if kind == "set":
        key, value = draw(_BAD_SET)
        return base + ["--set", f"{key}={value}"], key
    if kind == "stages":
        return base + ["--stages", draw(st.sampled_from(["0", "4", "2.0", "x"]))], "--stages"
    if kind == "method":
        return base + ["--method", draw(st.sampled_from(["x", "BVP", ""]))], "--method"
    if kind == "solver":
        return base + ["--linear-solver", draw(st.sampled_from(["x", "MUMPS", "ma2"]))], \
            "--linear-solver"
    if kind == "rtol":
        return base + ["--rtol", draw(st.sampled_from(["0", "1", "-1e-6", "nan", "x"]))], "--rtol"
    if kind == "output":
        option = draw(st.sampled_from(["--json", "--csv", "--plot"]))
        path = draw(st.sampled_from([f"{tmp}/no/such/dir/out", f"{tmp}/out.txt", str(tmp), "",
                                     f"{tmp}/file.txt/out"]))
        suffix = {"--json": ".json", "--csv": ".csv", "--plot": ".png"}[option]
        if path.endswith("/out"):
            path += suffix
        return base + [option, path], option
    if kind == "continue":       # the branches command (issue 38)
        args, named = draw(st.sampled_from([
            (["--param", "h"], "--param and --to"), (["--to", "0.2"], "--param and --to"),
            (["--param", "kk", "--to", "1"], "unknown parameter"),
            (["--param", "cut", "--to", "0"], "cannot take cut"),
            (["--param", "h", "--to", "1e308"], "thickness h"),
            (["--param", "h", "--to", "-1e-9"], "thickness h"),
            (["--max-step", "0"], "--max-step"), (["--max-points", "1"], "--max-points"),
            (["--follow", "x"], "--follow")]))
        return ["continue", TOY2, *args], named
    if kind == "sweep":          # grids out of proportion (issue 40)
        value = draw(st.sampled_from(["0:1:1000000000", "0:1:200001", "0:1:0", "0:1:x"]))
        return ["sweep", TOY2, "--set", f"k={value}"], "k="
    if kind == "file":
        name = draw(st.sampled_from(["missing.toml", "binary.toml", "garbage.toml"]))
        return ["solve", f"{tmp}/{name}"], name
    return [draw(st.sampled_from(["slove", "", "--bogus", "solve --x"]))], "morphoshell"


def test_bad_command_lines_exit_2_naming_the_item(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("bad_cli")
    (tmp / "file.txt").write_text("x")
    (tmp / "binary.toml").write_bytes(bytes(range(256)))
    (tmp / "garbage.toml").write_text("[[[problem")

    @given(bad_command_lines(tmp))
    def check(case):
        argv, named = case
        _check_refusal(tmp, argv, named, "bad command lines")
    check()


def _check_refusal(tmp: Path, argv: list[str], named: str, count: str) -> None:
    """``morphoshell ARGV`` exits 2 within REFUSAL_SECONDS with one line on standard error (C
    libraries' writes included) naming ``named``: no traceback, no raw warning, nothing
    written in ``tmp``."""
    before = set(tmp.rglob("*"))
    try:
        status, text, seconds, shown = run_cli(argv, REFUSAL_SECONDS)
    except Hang:
        COUNTS["hangs"] += 1
        pytest.fail(f"{argv}: still running after {REFUSAL_SECONDS:g} s")
    COUNTS[f"{count}: exit {status}"] += 1
    COUNTS["slowest refusal (ms)"] = max(COUNTS["slowest refusal (ms)"], int(1000 * seconds))
    if "Traceback" in text:
        COUNTS["tracebacks"] += 1
    if shown:
        COUNTS["raw warnings"] += 1
    assert status == 2, (argv, status, text)
    assert "Traceback" not in text and len(text.strip().splitlines()) == 1, (argv, text)
    assert not shown, (argv, shown)
    assert named in text, (argv, named, text)
    assert set(tmp.rglob("*")) == before, (argv, "left a file")


# --------------------------------------------------------------------------
# random bad inputs of estimate, fit, campaign and ablate (issue 40)
# --------------------------------------------------------------------------

def test_bad_inputs_of_the_fitting_commands_exit_2_at_once(tmp_path_factory):
    """estimate, fit, campaign, ablate: exit 2, one line naming the item, nothing written, no
    traceback or raw warning, within REFUSAL_SECONDS (no solver runs before a refusal)."""
    import importlib

    for module in ("fitting", "inverse", "mechanics.ablation", "workflows", "cli.fit",
                   "cli.campaign", "cli.estimate"):       # imports out of the time bound
        importlib.import_module(f"morphoshell.{module}")

    tmp = tmp_path_factory.mktemp("bad_inputs")
    make_bad_files(tmp)

    @settings(max_examples=BAD_INPUT_EXAMPLES)
    @given(bad_inputs(tmp))
    def check(case):
        argv, named = case
        _check_refusal(tmp, argv, named, f"bad input: {argv[0]}")
    check()
