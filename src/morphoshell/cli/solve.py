"""``morphoshell solve`` and ``morphoshell ablate``: equilibria of problem files."""
from __future__ import annotations

import argparse

from ..io.problem_files import METHODS
from ._args import (add_outputs, family_keys, integer, linear_solver, note,
                    problem_and_settings, real)
from ._commands import help_of
from ._outputs import Outputs

__all__ = ["register"]



def _common(p: argparse.ArgumentParser) -> None:
    from ..solvers.direct import MAX_NODES
    from ..solvers.routes import MIN_RTOL

    p.add_argument("problem", metavar="PROBLEM.toml",
                   help="problem file (`morphoshell example NAME` prints one to start from)")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                   help=f"override a problem or solver entry, once each: h, theory, family, "
                        f"cut (Sigma), opening (P), nodes, stages, method, or a parameter of "
                        f"the problem's family ({family_keys()})")
    p.add_argument("--method", choices=METHODS, default=None,
                   help="direct energy minimisation (default), or a reference route: bvp "
                        "(collocation of the Euler-Lagrange equations) or shooting (multiple "
                        "shooting of the same equations; refuses thin shells)")
    p.add_argument("--nodes", type=integer(5, MAX_NODES), default=None, metavar="N",
                   help=f"mesh nodes, 5..{MAX_NODES} (default: the file's [solver] nodes, "
                        f"or those a result's JSON records, else 200); the direct solver's "
                        f"points are the nodes and S - 1 interior points per cell")
    p.add_argument("--stages", type=int, choices=(1, 2, 3), default=None, metavar="S",
                   help="Gauss points per cell of the direct solver: order 2S (default: the "
                        "file's [solver] stages, or those a result's JSON records, else 2)")
    p.add_argument("--linear-solver", default="mumps", type=linear_solver, metavar="NAME",
                   help="Ipopt's linear solver for the direct method: mumps (default, bundled) "
                        "or an HSL solver such as ma27/ma57 if libhsl.so is installed")
    p.add_argument("--rtol", type=real(MIN_RTOL, 1, open_hi=True), default=None,
                   metavar="TOLERANCE",
                   help=f"direct method: refine the mesh (doubling the cells) until the error "
                        f"estimate meets TOLERANCE in [{MIN_RTOL:g}, 1) (energy relative to "
                        f"itself, edge values in units of R and radians), or fail with exit "
                        f"status 3; a continuation that fails for want of a finer mesh is "
                        f"retried on finer ones; without it the estimate is only reported")
    p.add_argument("--max-nodes", type=integer(5, MAX_NODES), default=None, metavar="N",
                   help=f"direct method with --rtol: the finest mesh it may refine to (default "
                        f"{MAX_NODES}; each doubling about doubles the time)")
    p.add_argument("--no-continuation", dest="continuation", action="store_false",
                   help="direct method: one cold solve from the undeformed shell instead of "
                        "continuation from the family's stress-free parameters (faster, but "
                        "may land on a spurious local minimum)")


def register(sub) -> None:
    """Add ``morphoshell solve`` and ``morphoshell ablate`` to the subcommands ``sub``."""
    p = sub.add_parser("solve", help=help_of("solve"),
                       description="Solve for the equilibrium shape of PROBLEM.toml and print a "
                                   "summary (energy, edge values, solver statistics). z is in "
                                   "the solver's gauge: z(first point) = its undeformed height.")
    _common(p)
    add_outputs(p, json="write the equilibrium and the solver settings that made it (settings: "
                         "nodes, stages, method, rtol, max_nodes, linear_solver, continuation) "
                         "as JSON; solve OUT.json solves it again on the nodes and stages it "
                         "records",
                csv="write the nodal arrays (s, r, z, psi, strains, ...) as CSV",
                plot="write a cross-section plot")
    p.set_defaults(run=_solve)

    p = sub.add_parser("ablate", help=help_of("ablate"),
                       description="Solve PROBLEM.toml before (cut = 0) and after the cut "
                                   "Sigma = cut > 0 and report the recoil observables opening, "
                                   "rotation, displacement and energy_released (Supplementary, "
                                   "toy problem 2): post- minus pre-ablation state at the "
                                   "material point s = Sigma, z in the far-end gauge (the far "
                                   "end keeps its undeformed height). energy_released = "
                                   "energy_post - (energy_pre - energy_removed) is the change "
                                   "of the remaining shell's energy: negative when the cut "
                                   "releases energy (the paper's Delta E); both states' "
                                   "energies are printed beside it. Each observable comes "
                                   "with its estimated error (+-, and relative: the lengths "
                                   "to the displacement d, the others to themselves, none "
                                   "to less than round-off or, for an energy, the shell's "
                                   "energy scale), made "
                                   "from the half and quarter meshes of solve's own "
                                   "estimate; one above 0.1 relative is a warning, and "
                                   "--rtol refines until the observables meet it too. "
                                   "Of a fit's JSON (morphoshell fit --json), the recoil "
                                   "observables also get the fit's uncertainty, +- (fit): its "
                                   "standard errors and correlations carried linearly through "
                                   "the ablation (lower bounds, as they are), or a note says "
                                   "why not.")
    _common(p)
    add_outputs(p, json="write both equilibria (pre, post), the observables, their estimated "
                         "errors (errors, relative_errors) and the solver settings (settings, "
                         "as solve's) as JSON; of a fit's JSON also the fit's "
                         "errors (se_<name>) and what they are (fit_error_note)",
                csv="write the observables and their errors (<name>_error; of a fit's JSON "
                    "also the fit's, se_<name>) as a one-row CSV",
                plot="write the pre/post cross-section plot")
    p.set_defaults(run=_ablate)


def _load(args):
    """Problem, method and solver options from the file, --set and the options; all checked.
    A result's JSON is solved with the settings it records (a note says which)."""
    problem, settings = problem_and_settings(args.problem, args.overrides)
    nodes = settings.nodes if args.nodes is None else args.nodes
    stages = settings.stages if args.stages is None else args.stages
    method = args.method or settings.method
    _note_recorded(args, nodes, stages)
    if method == "direct":
        options = {"stages": stages, "linear_solver": args.linear_solver, "rtol": args.rtol,
                   "continuation": args.continuation}
        if args.max_nodes is not None:
            if args.rtol is None:
                raise ValueError("--max-nodes bounds the refinement of --rtol: give --rtol too")
            if args.max_nodes < nodes:
                raise ValueError(f"--max-nodes {args.max_nodes} is below the first mesh's "
                                 f"{nodes} nodes")
            options["max_nodes"] = args.max_nodes
    else:
        if args.rtol is not None or not args.continuation or args.max_nodes is not None:
            raise ValueError("--rtol, --max-nodes and --no-continuation are options of the "
                             "direct method")
        options = {}
    return problem, method, nodes, options


def _note_recorded(args, nodes: int, stages: int) -> None:
    """Say on which mesh a result's JSON is solved: as it records, by the options, or (a
    file that records none, or other results) by the defaults, which may not reproduce it."""
    from ..io.problem_files import recorded_solver

    record = _record_of(args.problem)
    if not record:
        return
    recorded = recorded_solver(record)

    def said(name, given):
        return (f"--{name}" if given is not None else "as recorded" if name in recorded
                else "the default")
    text = (f"{args.problem}: solved on {nodes} nodes ({said('nodes', args.nodes)}), stages "
            f"{stages} ({said('stages', args.stages)})")
    if not recorded:
        text += ("; the file records no solver settings (a result written before they were "
                 "recorded, or not by solve, ablate or fit): it may have been solved otherwise")
    note(text)


def solve_settings(method: str, nodes: int, options: dict) -> dict:
    """What ``solve``/``ablate --json`` record of the options that change the numbers:
    ``nodes`` (of the first mesh), ``method`` and, direct, ``stages``, ``rtol``,
    ``max_nodes``, ``linear_solver`` and ``continuation``. ``morphoshell solve`` of the JSON
    reuses nodes, stages and method (:func:`~morphoshell.io.problem_files.recorded_solver`)."""
    return {"nodes": nodes, "method": method, "stages": None, "rtol": None, "max_nodes": None,
            **options}


def _label(problem) -> str:
    return problem.name or problem.family


def _report_quality(eq) -> None:
    """How the solution was reached and its estimated error (direct method)."""
    if "path" in eq.solver.details:
        print(f"  reached by      {eq.solver.details['path']}")
    if eq.error is not None:
        if eq.error.note:
            print(f"  error estimate  unavailable: {eq.error.note}")
        else:
            print(f"  error estimate  {eq.error.summary('C R^2')}")


def _solve(args) -> int:
    from ..solvers.routes import solve
    from ..io.problem_files import write_csv, write_json
    from ..solvers.results import FIELDS

    problem, method, nodes, options = _load(args)
    settings = solve_settings(method, nodes, options)
    eq = solve(problem, nodes=nodes, method=method, **options)
    if method == "direct":
        _check_fitted(eq, _record_of(args.problem), args.problem)
    edge = "start" if problem.structure.start == "free" else "end"
    e = eq.edge(edge)
    it = eq.solver.iterations
    points = {"direct": f"{eq.solver.nodes} nodes, {len(eq.s)} points",
              "bvp": f"{len(eq.s)} collocation points"}.get(method, f"{len(eq.s)} points")
    print(f"{_label(problem)}: {method} solution, {points}, {it} iteration{'s' * (it != 1)}, "
          f"{eq.solver.seconds * 1e3:.1f} ms ({eq.solver.status})")
    print(f"  energy          = {eq.energy:.12g} C R^2")
    print(f"  {edge} edge s = {e['s']:.6g} R: r = {e['r']:.10g} R, z = {e['z']:.10g} R, "
          f"psi = {e['psi']:.10g} rad")
    print(f"  max |eta|       = {abs(eq.eta).max():.4g} (dimensionless)")
    _report_quality(eq)
    out = Outputs()
    out.add(args.json, lambda path: write_json(path, {**eq.to_dict(), "settings": settings},
                                                [args.problem]))
    out.add(args.csv, lambda path: write_csv(path, {k: getattr(eq, k) for k in FIELDS}))
    if args.plot:
        from ..plotting import new_axes, plot_cross_section, save
        # a figure outside pyplot: no backend or display needed, none left open; the
        # title names the problem, the caption its parameters and the method
        ax = plot_cross_section(eq, new_axes(pyplot=False))
        out.add(args.plot, lambda path: save(ax, path))
    for path in out.commit():
        print(f"  wrote {path}")
    return 0


def _ablation_lines(ab, fit=None) -> list[str]:
    """The observables of ``ab``, one a line, the energies with both states' and the sign
    convention of energy_released spelled out (a negative "released" energy beside a positive
    removed one, with neither state's energy, read as a bug); with ``fit``, a
    :class:`~morphoshell.workflows.fitted_shapes.FitUncertainty` with errors, each recoil
    observable's error from the fit beside its numerical one, and what they are."""
    from ..mechanics.ablation import UNITS

    errors, rel = ab.errors or {}, ab.relative_errors()
    carried = fit.errors if fit is not None else {}
    traces = fit.traces.errors if fit is not None and fit.traces is not None else {}

    def line(key, value, unit, note=""):
        # (the estimate beside the value where there is one: a state's energy has its own)
        err = (f" +- {errors[key]:.2g} {unit} (numerical, {rel[key]:.2g} relative)"
               if key in errors and not ab.error_note else "")
        # (audit 25: the numerical +- alone, 1.8e-6 rad, read as the fitted recoil's
        # uncertainty, 0.019 rad from the fit's parameters)
        err += f" +- {carried[key]:.2g} {unit} (fit)" if key in carried else ""
        # (audit 28: the residual's sigma^2 made (fit) 2-3.7 times too small on averages)
        err += f" +- {traces[key]:.2g} {unit} (traces)" if key in traces else ""
        return f"  {key:20s} = {value:.10g} {unit}{err}" + (f"   ({note})" if note else "")

    recoil = {k: v for k, v in ab.observables().items() if not k.startswith("energy")}
    delta = ab.energy_released
    sign = (f"negative: the cut released {-delta:.4g} C R^2" if delta < 0 else
            "positive: the remaining shell gained energy, not a release (an active response?)"
            if delta > 0 else "zero")
    if errors and not ab.error_note:
        pre, post = ab.pre.error.reference_nodes, ab.post.error.reference_nodes
        levels = (f"both states on {pre} nodes and on half that" if pre == post else
                  f"the states on {pre} (before the cut) and {post} nodes (after) and on "
                  f"half that")
        head = (f"  observables +- their estimated errors (from {levels}; relative: lengths "
                f"to d, the opening to 2d, the others to themselves or, near 0, to their "
                f"scale):")
    else:
        # (a reference route's states carry no estimate, hence no levels: audit 26 F4)
        head = f"  observables (error estimates unavailable: {ab.error_note or 'none made'}):"
    return [head, *_fit_lines(fit), *(line(k, v, UNITS[k]) for k, v in recoil.items()),
            line("energy_pre", ab.pre.energy, "C R^2", "the intact shell, before the cut"),
            line("energy_removed", ab.energy_removed, "C R^2",
                 "of energy_pre, the cap s < Sigma that the cut removes"),
            line("energy_post", ab.post.energy, "C R^2", "the shell after the cut"),
            line("energy_released", delta, "C R^2",
                 f"energy_post - (energy_pre - energy_removed), {sign}")]


def _fit_lines(fit) -> list[str]:
    """What the errors ``(fit)`` are, and the profiled parameters whose intervals they miss."""
    traces = [f"  {fit.traces.text()}"] if fit is not None and fit.traces is not None else []
    return [f"  +- (fit): {text}" for text in _fit_texts(fit)] + traces


def _fit_texts(fit) -> list[str]:
    """:attr:`~morphoshell.workflows.fitted_shapes.FitUncertainty.note`, and where the fit's
    profile intervals are far wider than its standard errors' ± (the free fits of averages in
    audit 25 and of the shipped t02: kappa1's 13 and 4.9 times, the profiles' sigma^2 from the
    traces' spread), that they are."""
    if fit is None or not fit.errors:
        return []
    texts = [fit.note]
    if fit.wider:
        ratios = sorted(fit.wider.values())
        times = f"{ratios[0]:.2g}" if len(ratios) == 1 else f"{ratios[0]:.2g} to {ratios[-1]:.2g}"
        texts.append(f"these miss the profile intervals of {', '.join(fit.wider)}, {times} "
                     f"times as wide as the +- of the standard errors carried, at the "
                     f"profiles' confidence: the recoil is less determined than they say")
    return texts


def _fit_of(path) -> tuple[dict | None, dict]:
    """The source of a fit's JSON (:func:`morphoshell.io.problem_files.fit_source`: a warning
    if it did not converge) and the record, or None and {} for a problem file or another
    result."""
    from ..io.problem_files import fit_source

    record = _record_of(path)
    return (fit_source(record, str(path)) if record else None), record


def _record_of(path) -> dict:
    """The JSON result read as a problem (load_problem has read and checked it), or {}."""
    from pathlib import Path

    from ..io.problem_files import read_json

    return read_json(Path(path)) if Path(path).suffix.lower() == ".json" else {}


def _check_fitted(eq, record: dict, path) -> None:
    """Warn where ``eq``, a direct solution of a fit's shell, is not the fitted shell
    (:func:`morphoshell.workflows.fitted_shapes.off_the_fit`); nothing where it is another
    problem (``--set`` changed a parameter, or a cut)."""
    from ..io.problem_files import problem_of_record

    if "fitted_midline" not in record:
        return
    fitted, p = problem_of_record(record, str(path)), eq.problem
    if p.cut == 0 and (p.params, p.h, p.opening) == (fitted.params, fitted.h, fitted.opening):
        from ..workflows.fitted_shapes import off_the_fit
        off_the_fit(eq, record, str(path))


def _ablation_json(ab, source, fit) -> dict:
    """``ablate --json``: the ablation, and of a fit's shell its ``source`` (a reader of the
    JSON alone could not tell a fit that stopped short), its errors from the fit beside the
    numerical ones (``se_<observable>``, their units in ``units``) and ``fit_error_note``,
    what they are or why there are none."""
    from ..mechanics.ablation import UNITS

    data = ab.to_dict()
    if source is None:
        return data
    columns = fit.columns()
    data["units"].update({k: UNITS[k.removeprefix("se_").removeprefix("traces_")]
                          for k in columns if k.startswith("se_")})
    note = "; ".join(_fit_texts(fit)) or fit.note
    traces = {} if fit.traces is None else {"fit_error_traces": fit.traces.to_dict()}
    return {**data, "source": source, **columns, "fit_error_note": note, **traces}


def _ablate(args) -> int:
    from ..mechanics.ablation import ablate
    from ..io.problem_files import write_csv, write_json

    problem, method, nodes, options = _load(args)
    if not problem.cut > 0:
        raise ValueError(f"{args.problem}: cut (Sigma) = {problem.cut!r}: an ablation needs a "
                         f"cut > 0 (set it in the file's [problem] table or with --set cut=0.15)")
    source, record = _fit_of(args.problem)
    ab = ablate(problem, nodes=nodes, method=method, **options)
    if method == "direct":
        _check_fitted(ab.pre, record, args.problem)
    mesh = (f"{ab.post.solver.nodes} nodes, " if method == "direct" else "")
    print(f"{_label(problem)}: ablation of cut Sigma = {problem.cut:g} R (arclength) "
          f"({method}, {mesh}{len(ab.post.s)} points)")
    if source is not None:
        print(f"  shape of the fit in {source['file']}: E_fit = {source['E_fit']:.6g} R, "
              f"{'converged' if source['converged'] else 'NOT converged'}")
    # (a reference route reports neither a path nor an estimate: no empty headings)
    states = (("pre-ablation", ab.pre), ("post-ablation", ab.post)) if method == "direct" else ()
    for label, eq in states:
        print(f"  {label}:")
        _report_quality(eq)
    fit = None
    if source is not None:          # (a fit's shell: its errors carried, or why not)
        from ..io.problem_files import record_midline
        from ..workflows.fitted_shapes import fit_uncertainty
        # (σ² from the traces' spread of the average it was fitted to, where it is here)
        fit = fit_uncertainty(record, ab, record_midline(record))
    print("\n".join(_ablation_lines(ab, fit)))
    if fit is not None and not fit.errors:
        note(f"{args.problem}: {fit.note}")
    columns = fit.columns() if fit is not None else {}
    out = Outputs()
    settings = solve_settings(method, nodes, options)
    out.add(args.json, lambda path: write_json(path, {**_ablation_json(ab, source, fit),
                                                      "settings": settings}, [args.problem]))
    out.add(args.csv, lambda path: write_csv(path, {**problem.describe()["params"],
                                                    "h": problem.h, "cut": problem.cut,
                                                    # "opening" is the observable o below
                                                    "opening_P": problem.opening,
                                                    **ab.observables(),
                                                    **ab.error_columns(), **columns}))
    if args.plot:
        from ..plotting import new_axes, plot_ablation, save
        ax = plot_ablation(ab, new_axes(legend=True, pyplot=False))
        out.add(args.plot, lambda path: save(ax, path))
    for path in out.commit():
        print(f"  wrote {path}")
    return 0
