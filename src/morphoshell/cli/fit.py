"""``morphoshell fit``: the Volvox model fitted to a traced midline."""
from __future__ import annotations

from pathlib import Path

from ._args import add_outputs, integer, real
from ._outputs import Outputs
from ._profiles import (add_profile_options, plot_profiles, profile_json, profile_names,
                        profile_plot_path, profile_table, run_profiles)

__all__ = ["register"]


def register(sub) -> None:
    """Add ``morphoshell fit`` to the subcommands ``sub``."""
    from ..fitting import FIT_NODES, METHODS, VARIANTS
    from ..io import FORMATS, SECTIONS

    p = sub.add_parser(
        "fit", help="fit the 13-parameter Volvox model to a traced midline",
        description="Fit the morphoelastic Volvox model (volvox_model; Haas & Hohn, Cut it out, "
                    "Supplementary, 'Fitting of the morphoelastic theory') to the midline in "
                    "MIDLINE by minimising E_fit = (sum_i |model_i - data_i|^2)^(1/2) over "
                    "100 points equally spaced in arclength (units of R), the model being an "
                    "equilibrium. Image traces are aligned on their axis of symmetry and scaled "
                    "by --pixel-size and --radius-um. Standard errors are Gauss-Newton lower "
                    "bounds (the residuals of a traced midline are correlated).")
    p.add_argument("midline", metavar="MIDLINE", help="traced midline: CSV of r,z (units of "
                   "R), CSV of image x,y, Fiji XY coordinates, or an ImageJ .roi")
    p.add_argument("--format", choices=FORMATS, default=None,
                   help="file format (default: from the content)")
    p.add_argument("--pixel-size", dest="pixel_size", type=real(0, 1e6, open_lo=True, unit=" um"),
                   default=None, metavar="UM", help="image pixel size in micrometres")
    p.add_argument("--radius-um", dest="radius_um", type=real(0, 1e6, open_lo=True, unit=" um"),
                   default=None, metavar="R", help="embryo radius R in micrometres")
    p.add_argument("--section", choices=SECTIONS, default="auto",
                   help="an image trace is a whole mid-sagittal section (rim to rim through the "
                        "posterior pole) or a half (pole to rim); default: whole for images")
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
                   help="start from the parameters of a previous fit (or any result JSON); "
                        "default: the family's illustrative values, h = 0.15, P = 0.3")
    p.add_argument("--nodes", type=integer(*FIT_NODES), default=200, metavar="N",
                   help="mesh nodes of the inner solves (default 200)")
    add_outputs(p, json="write the fit (parameters by name, standard errors, E_fit, both "
                        "midlines) as JSON; usable as a problem file",
                csv="write the fitted parameters with their standard errors as CSV",
                plot="write the fitted shell over the data")
    add_profile_options(p)
    p.set_defaults(run=_fit)


def _start_problem(args):
    """The start problem and the held values, from --start and --set (checked)."""
    from ..fitting import volvox_spec
    from ..io.problem_files import ProblemFileError, load_problem, parse_overrides
    from ..model.problem import Problem

    base = Problem("volvox", h=0.15, opening=0.3)
    if args.start is not None:
        start, _ = load_problem(args.start)
        if start.family != "volvox":
            raise ProblemFileError(f"--start {args.start}: a {start.family!r} problem, not volvox")
        base = start
    overrides = parse_overrides(args.overrides)
    base_keys = {k: overrides.pop(k) for k in ("h", "opening", "sigma") if k in overrides}
    unknown = sorted(set(overrides) - set(base.family_obj.parameters))
    if unknown:
        raise ProblemFileError(f"--set: unknown Volvox parameter(s) {unknown}; valid: "
                               f"{list(base.family_obj.parameters)}, h, opening")
    try:
        base = base.with_updates(**base_keys)
        return volvox_spec(args.variant, base, hold=overrides)
    except ValueError as exc:
        raise ProblemFileError(f"--set/--start: {exc}") from None


def _fit(args) -> int:
    from ..fitting import N_FIT, check_midline, fit
    from ..io.problem_files import write_csv, write_json
    from ..io import load_midline
    from ..solvers.results import SolverError

    spec = _start_problem(args)
    names = profile_names(args.profile, spec)        # (a bad name: exit 2, before any work)
    midline = load_midline(args.midline, args.format, n=N_FIT, section=args.section,
                           pixel_size_um=args.pixel_size, radius_um=args.radius_um)
    check_midline(spec, midline, f"{args.midline}: the midline")
    try:
        result = fit(spec, midline, args.method, nodes=args.nodes)
    except SolverError as exc:
        # the usual cause: a mid-inversion stage fitted from the family's defaults
        where = "--start FIT.json (a fit of a neighbouring stage)" if args.start is None \
            else "a --start nearer the data"
        raise type(exc)(f"{exc}. A fit from far away can cross folds of the branch: try {where}, "
                        f"or another --method", exc.status, exc.last_iterate) from None
    print(result.summary())
    print(f"  E_fit = {result.E_fit:.6g} R over {N_FIT} points; {result.inner_solves} inner "
          f"solves, {result.seconds:.2f} s")
    profiles = run_profiles(args, spec, midline, result, names) if names else {}
    if profiles:
        print(profile_table(result, profiles))
    out = Outputs()
    out.add(args.json, lambda path: write_json(path, {**result.to_dict(),
                                                      "midline_file": str(args.midline),
                                                      **(profile_json(profiles) if profiles
                                                         else {})}))
    out.add(args.csv, lambda path: write_csv(path, {
        "parameter": list(result.fitted),
        "value": [result.parameters[n] for n in result.fitted],
        "standard_error": [result.standard_errors[n] for n in result.fitted]}))
    if args.plot:
        from ..plotting import fit_axes, plot_fit, save
        shell, residual = fit_axes(pyplot=False)
        ax = plot_fit(result, shell, residual_ax=residual, name=Path(args.midline).name)
        out.add(args.plot, lambda path: save(ax, path))
    if profiles and profile_plot_path(args) is not None:
        from ..plotting import save
        figure = plot_profiles(profiles)
        out.add(profile_plot_path(args), lambda path: save(figure, path))
    for path in out.commit():
        print(f"  wrote {path}")
    return 0 if result.converged else 3
