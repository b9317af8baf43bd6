"""``morphoshell fit``: the Volvox model fitted to a traced midline."""
from __future__ import annotations

from pathlib import Path

from ._args import (FORMAT_HELP, OUTLIER_POINTS_HELP, SECTION_HELP, TRACE_OPTIONS, add_outputs,
                    integer, micrometre_list, micrometres, note, reader_notes, reworded,
                    scale_hint)
from ._commands import help_of
from ._outputs import Outputs, kept_in
from ._profiles import (add_profile_options, profile_data, profile_json, profile_names,
                        profile_plot_path, profile_table, refit_lines, run_profiles)

__all__ = ["register"]


def register(sub) -> None:
    """Add ``morphoshell fit`` to the subcommands ``sub``."""
    from ..fitting import EVALUATION_LIMITS, FIT_NODES, METHODS, VARIANTS
    from ..io import FORMATS, SECTIONS

    p = sub.add_parser(
        "fit", help=help_of("fit"),
        description="Fit the morphoelastic Volvox model (volvox_model; Haas & Hohn, Cut it out, "
                    "Supplementary, 'Fitting of the morphoelastic theory') to the midline in "
                    "MIDLINE by minimising E_fit = (sum_i |model_i - data_i|^2)^(1/2) over "
                    "100 points equally spaced in arclength (units of R), the model being an "
                    "equilibrium. Image traces (pixel coordinates: Fiji XY, .roi, RoiSet.zip, "
                    "x,y CSV) need --pixel-size and --radius-um: they are aligned on their axis "
                    "of symmetry and scaled to units of R. A trace too long or short for the "
                    "model (a wrong scale) or leaving its pole along the axis (r and z "
                    "swapped) is refused before any work. Standard errors are Gauss-Newton "
                    "lower bounds (the residuals of a traced midline are correlated), or for "
                    "one image trace those of 100 simulated re-tracings of its pixel noise; "
                    "the JSON's and CSV's standard_errors_source says which.")
    p.add_argument("midline", metavar="MIDLINE", help="traced midline: CSV of r,z (units of "
                   "R, pole first), or an image trace: CSV of x,y, Fiji XY coordinates, an "
                   "ImageJ .roi or a ROI Manager set RoiSet.zip (with --roi)")
    p.add_argument("--format", choices=FORMATS, default=None,
                   help=f"file format (default: from the content). {FORMAT_HELP}")
    p.add_argument("--pixel-size", dest="pixel_size", type=micrometres,
                   default=None, metavar="UM", help="image traces: micrometres per pixel "
                   "(Fiji: Image > Properties > Pixel width; 1 if the trace was exported in "
                   "calibrated um); required with --radius-um")
    p.add_argument("--radius-um", dest="radius_um", type=_radius, default=None,
                   metavar="R[,R...]", help="image traces: the embryo's radius R in "
                   "micrometres, the unit of lengths; required with --pixel-size. A ROI "
                   "set's --roi all takes one for every line ROI or one per line ROI in the "
                   "set's order, comma-separated (as morphoshell average)")
    p.add_argument("--roi", default=None, metavar="NAME|INDEX|all",
                   help="a ROI Manager set (RoiSet.zip, from ROI Manager > More > Save): the "
                        "line ROI to fit, by its name in the ROI Manager's list or its position "
                        "there (from 1), or all: the average of every line ROI (the traces of "
                        "one stage); default: the set's only line ROI. Other ROIs are skipped")
    p.add_argument("--section", choices=SECTIONS, default="auto",
                   help=f"what an image trace covers. {SECTION_HELP}")
    p.add_argument("--drop-outlier-points", dest="drop_outlier_points", action="store_true",
                   help=OUTLIER_POINTS_HELP)
    p.add_argument("--variant", choices=VARIANTS, required=True,
                   help="posterior intrinsic curvature kappa1: flat (0), undeformed (1), "
                        "unstressed (1/f1), free (fitted)")
    p.add_argument("--method", choices=METHODS, default="gradient",
                   help="nelder-mead (the paper's baseline), gradient (exact Jacobian, "
                        "default), kkt (one NLP with the equilibrium as constraints)")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="NAME=VALUE",
                   help="hold a Volvox parameter (f1..f5, kappa1..kappa4, s1..s4) at a value, "
                        "or set h, opening or sigma (never fitted)")
    p.add_argument("--start", type=Path, default=None, metavar="PARAMS.json",
                   help="start from the Volvox parameters, h and opening of a previous fit's "
                        "JSON (or of any result JSON or problem file of an intact Volvox shell; "
                        "one with a cut, as morphoshell ablate writes, or another theory or "
                        "geometry is refused); default: the family's illustrative values, "
                        "h = 0.15, P = 0.3")
    p.add_argument("--multi-start", dest="multi_start", action="store_true",
                   help="fit from several starts and keep the lowest E_fit: --start (if "
                        "given), the family's defaults and a few fixed changes of them "
                        "(kappa2 = -3, -6, and a late stage's breakpoints), all with the "
                        "variant's ties and the --set values; each start that stops short "
                        "is continued once from its end. Prints (and the JSON records under "
                        "'starts') every start's E_fit, converged and constraints. A "
                        "variant's fit ends in a local minimum that depends on its start: "
                        "compare variants after --multi-start, with morphoshell compare "
                        "(their E_fit ranking alone does not decide)")
    p.add_argument("--nodes", type=integer(*FIT_NODES), default=200, metavar="N",
                   help=f"mesh nodes of the inner solves, {FIT_NODES[0]} to {FIT_NODES[1]} "
                        f"(default 200)")
    limits = "; ".join(f"{m}: {unit} (default {n})" for m, (unit, n) in EVALUATION_LIMITS.items())
    p.add_argument("--max-evaluations", dest="max_evaluations", type=integer(1, 10**9),
                   default=None, metavar="N",
                   help=f"stop the fit after N steps of its method ({limits}); a fit that "
                        f"goes on from moved breakpoint boxes gets N anew for each run")
    add_outputs(p, json="write the fit (parameters by name, standard errors, E_fit, both "
                        "midlines, the options that made it under 'settings') as JSON; usable "
                        "as a problem file, solved at the fit's --nodes",
                csv="write the parameters as CSV, the fitted ones first, with their standard "
                    "errors, units, fitted and on_constraint (True/False), every row with the "
                    "fit's E_fit (R), converged (True/False), stop (how it ended) and "
                    "walls_cross (True/False: the fitted shape's walls pass through each "
                    "other); units: docs, 'Results as tables'",
                plot="write the fitted shell over the data")
    add_profile_options(p)
    p.set_defaults(run=_fit)


#: Why a start whose problem has another value of these is not a start of a fit: every fit
#: models an intact shell (a traced embryo, not one cut at its pole) in the theory and on the
#: geometry it is solved in; neither --set nor the fit can change them.
_FIXED = {"cut": "a fit's shell is intact (cut = 0), this one is cut at the pole (as "
                 "morphoshell ablate writes): start from the JSON of the fit it ablated",
          "theory": "a fit solves the 'large_bending' theory",
          "geometry": "a fit's shell is a sphere ('sphere')"}


def _fit_problem():
    """The problem every fit starts from unless --start gives parameters: the family's
    illustrative values, h = 0.15, P = 0.3 (the paper's)."""
    from ..model.problem import Problem
    return Problem("volvox", h=0.15, opening=0.3)


def _start_of(path: Path):
    """The fit's problem with the Volvox parameters, h and opening of the problem or result
    file ``path``; ProblemFileError naming the file and the entry where its problem is not
    a fit's (:data:`_FIXED`), so that nothing else of it reaches the fit unseen."""
    from ..io.problem_files import ProblemFileError, load_problem

    start, _ = load_problem(path)
    if start.family != "volvox":
        raise ProblemFileError(f"--start {path}: a {start.family!r} problem, not volvox")
    base = _fit_problem()
    for key, why in _FIXED.items():
        value = getattr(start, key)
        if value != getattr(base, key):
            entry = f"problem.{key}" if path.suffix.lower() == ".json" else f"[problem] {key}"
            raise ProblemFileError(f"--start {path}: {entry} = {value!r}: {why}")
    return base.with_updates(h=start.h, opening=start.opening, **start.params)


def _start_problem(args):
    """The start problem and the held values, from --start and --set (checked).

    A refusal names the options that gave the values it is about: ``--set NAME=VALUE``
    as typed, or ``--start FILE`` (:attr:`morphoshell.fitting.SpecError.names`).
    """
    from ..fitting import SpecError, volvox_spec
    from ..io.problem_files import ProblemFileError, parse_overrides

    base = _fit_problem() if args.start is None else _start_of(args.start)
    given = parse_overrides(args.overrides)
    overrides = dict(given)
    base_keys = {k: overrides.pop(k) for k in ("h", "opening", "sigma") if k in overrides}
    unknown = sorted(set(overrides) - set(base.family_obj.parameters))
    if unknown:
        raise ProblemFileError(f"--set: unknown Volvox parameter(s) {unknown}; valid: "
                               f"{list(base.family_obj.parameters)}, h, opening")
    try:
        base = base.with_updates(**base_keys)
    except ValueError as exc:       # (h, opening and sigma come from --set alone)
        raise ProblemFileError(f"{_options(base_keys, given, None)}: {exc}") from None
    try:
        return volvox_spec(args.variant, base, hold=overrides)
    except SpecError as exc:
        raise ProblemFileError(f"{_options(exc.names, given, args.start)}: {exc}") from None
    except ValueError as exc:
        raise ProblemFileError(f"--set/--start: {exc}") from None


def _options(names, given: dict, start: Path | None) -> str:
    """The options that gave the values of ``names``: ``--set NAME=VALUE`` for those set, and
    ``--start FILE`` for the others when a start file gave them."""
    named = [f"--set {n}={given[n]:g}" for n in names if n in given]
    if start is not None and any(n not in given for n in names):
        named.append(f"--start {start}")
    return ", ".join(named) or "--set/--start"


def _radius(text: str) -> float | list[float]:
    """``--radius-um``: one radius in µm, or one per line ROI of a set's ``--roi all``
    (average's parsing; the reader refuses several for one trace, naming the option)."""
    values = micrometre_list(text)
    return values[0] if len(values) == 1 else values


_radius.__name__ = "number"


def load_checked(args, spec, n: int):
    """The midline of ``args.midline`` (n points), refused unless ``spec``'s shell can fit it.

    The messages name the command line's options; a wrong length says which
    ones set the scale (ValueError, exit status 2, before any work).  What the
    reader did to the trace (bins, a spline through sparse points, a half
    section's axis) is printed as notes once the midline is accepted.
    """
    from ..fitting import check_midline
    from ..io import MidlineError, load_midline

    try:
        with reader_notes() as notes:
            midline = load_midline(args.midline, args.format, n=n, section=args.section,
                                   pixel_size_um=args.pixel_size, radius_um=args.radius_um,
                                   roi=args.roi, drop_outlier_points=args.drop_outlier_points)
    except MidlineError as exc:
        raise MidlineError(reworded(str(exc), TRACE_OPTIONS)) from None
    if args.pixel_size is not None:          # (an image trace: the loader required both)
        hint = scale_hint(args.midline, args.format, args.pixel_size, args.radius_um,
                          "each embryo's" if isinstance(args.radius_um, list) else "the embryo's")
    else:
        hint = ("are its r and z in units of R, the embryo's radius (µm divided by the radius "
                "in µm; a trace in pixels needs --format xy with --pixel-size and --radius-um)?")
    check_midline(spec, midline, f"{args.midline}: the midline", scale_hint=hint)
    for text in notes:
        note(text)
    return midline


#: The stages (Gauss points per cell) of a fit's inner solves (fitting.inner builds its
#: meshes with mesh_spec(problem, nodes, 2)): the [solver] table of its JSON says so.
_INNER_STAGES = 2


def fit_record(args, limit: int) -> dict:
    """What the fit JSON records of how the fit was made, beside the result.

    ``solver``: the [solver] table of the JSON as a problem file (``morphoshell solve
    FIT.json`` re-solves at the fit's nodes, not the default 200); ``settings``: the
    options that made it (the midline and how it was read, the start, the held values,
    the method, nodes and evaluation limit; ``multi_start: true`` with --multi-start), so
    that a result says how it was made.
    """
    from ..io.problem_files import parse_overrides

    return {"midline_file": str(args.midline),
            "solver": {"nodes": args.nodes, "stages": _INNER_STAGES, "method": "direct"},
            "settings": {"midline_file": str(args.midline), "format": args.format,
                         "roi": args.roi, "section": args.section,
                         "pixel_size_um": args.pixel_size, "radius_um": args.radius_um,
                         "variant": args.variant, "method": args.method, "nodes": args.nodes,
                         "max_evaluations": args.max_evaluations, "evaluation_limit": limit,
                         "start": None if args.start is None else str(args.start),
                         "set": parse_overrides(args.overrides),
                         # (only when given: a single fit's JSON stays as it was)
                         **({"multi_start": True} if args.multi_start else {}),
                         **({"drop_outlier_points": True} if args.drop_outlier_points else {})}}


def _inputs(args) -> list:
    """The files the fit read, for the JSON's ``provenance.inputs``: the midline, and the
    start's file with --start."""
    return [args.midline, *([args.start] if args.start is not None else [])]


def _fit(args) -> int:
    from ..fitting import EVALUATION_LIMITS, N_FIT
    from ..fitting.midline_checks import input_check
    from ..io.problem_files import write_csv, write_json
    from ..solvers.contact import warn_of_contact
    from ._fit_stops import stop_line

    spec = _start_problem(args)
    names = profile_names(args.profile, spec, args)  # (a bad name: exit 2, before any work)
    midline = load_checked(args, spec, N_FIT)
    data = profile_data(args, spec, midline) if names else None
    unit, default = EVALUATION_LIMITS[args.method]
    limit = args.max_evaluations or default
    result, starts = _run_fit(args, spec, midline, limit, unit)
    retraced = _retracings(result, args)
    result = _trace_errors(result, retraced)
    print(result.summary())
    print(f"  E_fit = {result.E_fit:.6g} R over {N_FIT} points; {result.inner_solves} inner "
          f"solves, {result.seconds:.2f} s")
    if starts is not None:
        print(f"  starts (--multi-start, {len(starts.starts)} fits in {starts.seconds:.1f} s; "
              f"* the lowest E_fit, the fit above):\n{starts.table()}")
    before, profiles, not_done = result, {}, None
    if names:
        from ..fitting.trace_errors import fit_inflation

        result, profiles, not_done = _profiled(args, spec, data, result, names,
                                               fit_inflation(result))
        if result is not before:        # (the fit was not its minimum: the refit is the fit)
            result = _trace_errors(result, retraced)    # (the same data: the same re-tracings)
            print(refit_lines(before, result))
            limit = EVALUATION_LIMITS["gradient"][1]      # (the refit's: profile_intervals)
        if not_done is None:
            print(profile_table(result, profiles))
    out = Outputs()
    out.add(args.json, lambda path: write_json(path, {
        **result.to_dict(), **fit_record(args, limit),
        "input_check": input_check(result.E_fit),
        **(starts.to_dict() if starts is not None else {}),
        **(profile_json(profiles, before, result) if names else {}),
        **({"complete": False, "not_done": not_done} if not_done else {})},
        _inputs(args)))
    out.add(args.csv, lambda path: write_csv(path, result.table()))
    if not_done:
        return _cut_short(out, not_done, list(profiles), args)
    if args.plot:
        from ..plotting import fit_axes, plot_fit, save

        shell, residual = fit_axes(pyplot=False)
        ax = plot_fit(result, shell, residual_ax=residual, name=Path(args.midline).name)
        out.add(args.plot, lambda path: save(ax, path))
    if profiles and profile_plot_path(args) is not None:
        from ..plotting import plot_profiles, save

        figure = plot_profiles(profiles, pyplot=False)
        out.add(profile_plot_path(args), lambda path: save(figure, path))
    for path in out.commit():
        print(f"  wrote {path}")
    if starts is None:
        _local_minimum_note(result)
    if result.contact is not None:      # (the fitted shell, as solve() warns of a solved one)
        warn_of_contact(result.contact, f"{Path(args.midline).name}, fitted {result.variant} shell")
    print(stop_line(result, limit, before if result is not before else None))
    return 0 if result.converged else 3


def _profiled(args, spec, data, result, names: list[str], inflation) -> tuple:
    """(the fit, its profiles, what was not done: None when all were): :func:`run_profiles`,
    or where Ctrl-C or SIGTERM cuts it short, the fit and the profiles finished, and the
    names not profiled (audit 23: an interrupted ``fit --profile`` lost the fit, done in
    the first second, and every profile finished)."""
    from .._runtime import interrupts
    from ..fitting.profile_runs import ProfilesInterrupted

    try:
        return (*run_profiles(args, spec, data, result, names, inflation), None)
    except BaseException as exc:
        if not interrupts.interrupted(exc):
            raise
        interrupts.swallowed()      # (claimed: the outputs' commit would raise it again)
        if isinstance(exc, ProfilesInterrupted):    # (else cut before the first profile)
            result, profiles = exc.fit, exc.profiles
        else:
            profiles = {}
    return result, profiles, f"{', '.join(n for n in names if n not in profiles)} not profiled"


def _cut_short(out, not_done: str, done: list[str], args) -> int:
    """Write the fit and its finished profiles (``out``: the JSON, marked partial, and the
    CSV; no plot) and say so on one line, as ``continue`` and ``sweep`` do; the
    interruption's exit status (130, 143 after SIGTERM)."""
    import sys

    from .._runtime import interrupts

    paths = out.commit()
    what = f"the fit and the profiles of {', '.join(done)}" if done else "the fit"
    where = kept_in(paths, what, ", the JSON marked partial" if args.json else "",
                    "; not kept: no --json or --csv")
    unplotted = "; no plot drawn" if args.plot or profile_plot_path(args) else ""
    print(f"morphoshell: {interrupts.reason()} during the profiles ({not_done}){where}"
          f"{unplotted}", file=sys.stderr)
    return interrupts.exit_status()


def _run_fit(args, spec, midline, limit: int, unit: str):
    """(the fit, the :class:`~morphoshell.fitting.multistart.MultiStartFit` or None): one
    fit, or with --multi-start the lowest of several; a failure's message says what to try."""
    from ..fitting import fit, multi_start_fit
    from ..solvers.results import SolverError
    from ._fit_stops import failure_hint

    try:
        if args.multi_start:
            starts = multi_start_fit(spec, midline, args.method, nodes=args.nodes,
                                     max_iterations=args.max_evaluations)
            return starts.result, starts
        return fit(spec, midline, args.method, nodes=args.nodes,
                   max_iterations=args.max_evaluations), None
    except SolverError as exc:
        hint = failure_hint(exc.status, limit, unit, args.start is not None)
        raise type(exc)(f"{str(exc).rstrip('.')}. {hint}", exc.status, exc.last_iterate) from None


def _retracings(result, args):
    """The data's errors from re-tracings of its one image trace
    (:func:`morphoshell.fitting.trace_errors.trace_retracings`), said in a note, or None
    without a single trace (a csv midline, an average of several traces: their errors are
    the Gauss–Newton ones or the traces' spread) or a Jacobian.  With too many re-tracings
    refused by the reader the Gauss–Newton errors stand (:func:`_trace_errors`); the note
    says why."""
    if args.pixel_size is None or result.jacobian is None:
        return None
    from ..fitting.trace_errors import single_trace, trace_retracings

    trace = single_trace(args.midline, args.format, pixel_size_um=args.pixel_size,
                         radius_um=args.radius_um, roi=args.roi)
    if trace is None:
        return None
    retraced = trace_retracings(result, trace, args.section)
    made, refused = len(retraced.errors) + len(retraced.refused), len(retraced.refused)
    first = (f"{'the first' if refused > 1 else 'it'}: "
             f"{reworded(retraced.refused[0], TRACE_OPTIONS).partition(': ')[0]}"
             if refused else "")
    if not retraced.usable:
        note(f"the ± are the Gauss–Newton errors, which take the midline's points as independent "
             f"(for one trace 1.3-1.8x too small): {refused} of the {made} simulated "
             f"re-tracings of the trace's pixel noise (about {retraced.sigma_px:.2g} px) that "
             f"would give them were refused by the reader ({first})")
    else:
        note(f"the ± are the errors of the trace's pixel noise (about {retraced.sigma_px:.2g} "
             f"px) carried through its alignment and resampling, from "
             f"{len(retraced.errors)} simulated re-tracings (not the Gauss–Newton errors, which "
             f"take the midline's points as independent)"
             + (f"; {refused} of {made} refused by the reader and left out, which narrows "
                f"the ± a little ({first})" if refused else ""))
    return retraced


def _trace_errors(result, retraced):
    """``result`` with the sandwich errors of its trace's re-tracings (the Gauss–Newton ones
    assume independent residuals and were 1.3–1.8x too small) and their record
    (:func:`morphoshell.fitting.trace_errors.with_trace_errors`), or as it is without them
    or when it carries them already (a profile's re-centring that kept a copy of the fit)."""
    if retraced is None or result.re_tracings is not None:
        return result
    from ..fitting.trace_errors import with_trace_errors
    return with_trace_errors(result, retraced)


def _local_minimum_note(result) -> None:
    """A note when a fixed variant's fit ends with a parameter on a bound and breakpoints on
    constraints: the sign of a poor local minimum that another start avoids (audit: the
    unstressed fit of a traced sine-perturbed sphere at 0.041 R from the defaults, kappa4 on
    its bound; 0.018 R from a multi-start)."""
    from ..fitting.multistart import local_minimum_signs

    bounds, breakpoints = local_minimum_signs(result)
    if bounds:
        note(f"{', '.join(bounds)} on a bound and {', '.join(breakpoints)} on constraints: this "
             f"may be a local minimum of the {result.variant} variant; before comparing "
             f"variants' E_fit, fit with --multi-start")
