"""``morphoshell asymptotics`` and ``morphoshell sphere``: the paper's closed forms."""
from __future__ import annotations

import logging
import math

from ._args import add_outputs, real
from ._commands import help_of
from ._outputs import Outputs

__all__ = ["register"]

log = logging.getLogger(__name__)

_H = real(0, 1, open_lo=True, open_hi=True, unit=" (thickness relative to the radius)")
_K = real(-1e3, 1e3, unit=" (intrinsic curvature in units of 1/R)")


def register(sub) -> None:
    """Add ``morphoshell asymptotics`` and ``morphoshell sphere`` to the subcommands ``sub``."""
    p = sub.add_parser("asymptotics", help=help_of("asymptotics"),
                       description="Leading-order and small-cut (Kelvin function) predictions "
                                   "of the Supplementary for the cut SIGMA (half-angle of the "
                                   "ablation) in a sphere of relative thickness h = H/R and "
                                   "intrinsic curvature k. Lengths in units of R, angles in "
                                   "radians, energies in C R^2.")
    _thickness_and_curvature(p)
    cut = p.add_mutually_exclusive_group(required=True)
    angle = real(0, math.pi, open_lo=True, open_hi=True, unit=" rad")
    cut.add_argument("--cut", type=angle, metavar="SIGMA",
                     help="the cut Sigma: half-angle of the ablation, radians (= its arclength "
                          "in units of R), 0 < Sigma < pi; `cut` in problem files and the API")
    cut.add_argument("--cut-angle", type=angle, metavar="SIGMA", dest="cut_angle",
                     help="deprecated alias of --cut")
    add_outputs(p, json="write the predictions as JSON",
                csv="write the predictions as a one-row CSV")
    p.set_defaults(run=_asymptotics)

    p = sub.add_parser("sphere", help=help_of("sphere"),
                       description="Toy problem 1: deformed radius f (units of R) of a complete "
                                   "sphere with intrinsic curvature k: the minimiser of the main "
                                   "text's shell energy, the exact bulk-elasticity minimiser "
                                   "(Mooney-Rivlin C10, C01) and the Supplementary's asymptotic "
                                   "formula.")
    _thickness_and_curvature(p)
    # only the ratio C01/C10 matters; bounded so that energies cannot overflow
    modulus = real(-1e6, 1e6, unit=" (Mooney-Rivlin coefficient; only ratios matter)")
    p.add_argument("--c10", type=modulus, default=1.0, metavar="MODULUS",
                   help="Mooney-Rivlin coefficient C10 (default 1; only C01/C10 matters)")
    p.add_argument("--c01", type=modulus, default=0.0, metavar="MODULUS",
                   help="Mooney-Rivlin coefficient C01 (default 0)")
    add_outputs(p, json="write the results as JSON", csv="write the results as a one-row CSV")
    p.set_defaults(run=_sphere)


def _thickness_and_curvature(p) -> None:
    """--h and --k, named by what they are (the paper's H is the thickness in µm, h = H/R)."""
    p.add_argument("--h", type=_H, required=True, metavar="THICKNESS",
                   help="relative thickness h = H/R, 0 < h < 1")
    p.add_argument("--k", type=_K, required=True, metavar="CURVATURE",
                   help="intrinsic curvature k, in units of 1/R")


def _write(args, data: dict, units: dict) -> None:
    """The JSON (with a ``units`` table, as ``solve --json`` has) and the one-row CSV."""
    def json_file(path):
        # (the writers' module imports NumPy, CasADi and the solvers: only for a file)
        from ..io.problem_files import write_json
        write_json(path, {**data, "units": units})

    def csv_file(path):
        from ..io.problem_files import write_csv
        write_csv(path, {k: (math.nan if v is None else v) for k, v in data.items()})

    out = Outputs()
    out.add(args.json, json_file)
    out.add(args.csv, csv_file)
    for path in out.commit():
        print(f"  wrote {path}")


_UNITS = {"opening": "R", "rotation": "rad", "displacement": "R", "rotation_small_cut": "rad",
          "displacement_small_cut": "R", "energy_released": "C R^2", "delta": "R",
          "sigma": "(dimensionless: Sigma/delta)"}
#: The inputs' units in the JSON ("1": dimensionless, as in ``solve --json``; the moduli:
#: only their ratio matters).  The cut in rad, the cap's half-angle the sphere's formulas
#: take, where solve and ablate write R, the model's arclength: one number on the unit
#: sphere (docs/tables.md says why the labels differ).
_INPUT_UNITS = {"h": "R", "k": "1/R", "cut": "rad", "c10": "1", "c01": "1"}


def _check_curvature(args) -> None:
    """ValueError naming --k and the bound 2/h (the API's own check names its arguments)."""
    from ..model.profiles import check_curvature

    check_curvature((args.k,), args.h, "--k", f"the shell of --h {args.h:g}", "give a --k")


def _asymptotics(args) -> int:
    from ..mechanics.asymptotics import predictions

    # (the wedge closes: the predictions were printed, rotation -387 rad, audit 26 F2)
    _check_curvature(args)
    cut = args.cut
    if cut is None:
        log.warning("--cut-angle is deprecated, use --cut (the same cut Sigma, radians)")
        cut = args.cut_angle
    out = predictions(args.h, args.k, cut)
    print(f"toy problem 2 asymptotics, thickness h = {args.h:g} R, k = {args.k:g} / R, "
          f"cut Sigma = {cut:g} rad")
    for key, value in out.items():
        print(f"  {key:22s} = {value:.10g} {_UNITS[key]}")
    _write(args, {"h": args.h, "k": args.k, "cut": cut, **out},
           {**{k: _INPUT_UNITS[k] for k in ("h", "k", "cut")},
            **{k: "1" if k == "sigma" else _UNITS[k] for k in out}})
    return 0


def _sphere(args) -> int:
    from ..mechanics.asymptotics import f_bulk_asymptotic, f_shell_asymptotic, f_shell_exact, k_star
    from ..mechanics.bulk import f_bulk

    _check_curvature(args)
    if not args.c10 + args.c01 > 0:
        raise ValueError(f"--c10 + --c01 = {args.c10 + args.c01:g} must be positive "
                         f"(a positive bulk modulus)")
    out = {"f_shell": f_shell_exact(args.h, args.k),
           "f_shell_asymptotic": f_shell_asymptotic(args.h, args.k),
           "f_bulk": f_bulk(args.h, args.k, args.c10, args.c01),
           "f_asymptotic": f_bulk_asymptotic(args.h, args.k, args.c10, args.c01)}
    try:
        out["k_star"] = k_star(args.c10, args.c01)
    except ValueError as exc:   # 5 C10 + C01 = 0: no second sign change
        out["k_star"] = None
        print(f"  (k_star: {exc})")
    print(f"toy problem 1, thickness h = {args.h:g} R, k = {args.k:g} / R, Mooney-Rivlin "
          f"C10 : C01 = {args.c10:g} : {args.c01:g} (moduli; only their ratio matters)")
    units = {key: "1/R" if key == "k_star" else "R" for key in out}
    for key, value in out.items():
        unit = " / R" if key == "k_star" else " R"
        print(f"  {key:18s} = {'none' if value is None else format(value, '.15g') + unit}")
    if out["k_star"] is not None:        # (what it is: the printout had not said)
        print("  (k_star: the second k at which f's O(h^2) correction vanishes, the first "
              "being k = 1)")
    _write(args, {"h": args.h, "k": args.k, "c10": args.c10, "c01": args.c01, **out},
           {**{k: _INPUT_UNITS[k] for k in ("h", "k", "c10", "c01")}, **units})
    return 0
