"""``morphoshell fit --profile``: profile-likelihood intervals of the fitted parameters.

The options (checked before any work: an unknown name, one the variant does
not fit, a --profile-* option without --profile, or noise from traces the
midline file does not hold exits with status 2 and one line), the table
printed beside the Gauss–Newton errors and the JSON entries of the profiles
(:mod:`morphoshell.fitting.profiles`); :mod:`morphoshell.plotting.profiles`
draws them.
"""
from __future__ import annotations

import math
from pathlib import Path

from ..fitting.profile_noise import RETRACED
from ._args import integer
from ._outputs import output_path

__all__ = ["add_profile_options", "profile_names", "profile_plot_path", "profile_data",
           "run_profiles", "profile_table", "profile_json", "refit_lines"]

#: The defaults of --profile-points and --profile-noise (their options default to None, so
#: that one given without --profile is seen and refused rather than ignored).
_DEFAULTS = {"profile_points": 20, "profile_noise": "auto"}


def add_profile_options(p) -> None:
    """``--profile``, ``--profile-points``, ``--profile-noise`` and ``--profile-plot``."""
    p.add_argument("--profile", default=None, metavar="NAMES",
                   help="profile-likelihood intervals (95 %%) of these fitted parameters, "
                        "comma-separated (e.g. kappa1,f1), or 'all': each stepped over a grid "
                        "around its fitted value, the others refitted at every step (by the "
                        "gradient method, whatever --method); a side "
                        "that does not close is null (not determined by the data, or open "
                        "where a refit failed). A refit "
                        "lower than the fit means the fit was not at its minimum: the lower "
                        "refit becomes the fit, as the terminal and the JSON (replaced_fit) say. "
                        "Ctrl-C (SIGTERM) during the profiles writes the fit and the profiles "
                        "finished, the JSON marked partial; exit status 130 (143)")
    p.add_argument("--profile-points", dest="profile_points", type=integer(2, 1000), default=None,
                   metavar="N", help="refits per profile, 2 to 1000 (default 20); with --profile")
    p.add_argument("--profile-noise", dest="profile_noise", default=None,
                   choices=("auto", "residual", "traces"),
                   help="the noise variance of the threshold: from the fit's residual, or from "
                        "the spread of the traces an averaged midline CSV records (n_traces > 1, "
                        "as morphoshell average writes it); auto (default): traces when the file "
                        "has them; with --profile")
    p.add_argument("--profile-plot", dest="profile_plot", type=output_path("plot"), default=None,
                   metavar="OUT.png", help="draw the profiles (default with --plot: beside it, "
                                           "named *_profiles); with --profile")


def profile_names(text: str | None, spec, args=None) -> list[str]:
    """The names of ``--profile`` (ValueError: unknown, or not fitted by ``spec``; without
    --profile, a --profile-* option given in ``args``, which would do nothing)."""
    if text is None:
        given = [f"--{k.replace('_', '-')} {getattr(args, k)}" for k in ("profile_plot", *_DEFAULTS)
                 if getattr(args, k, None) is not None]
        if given:
            raise ValueError(f"{', '.join(given)} without --profile NAMES: there are no "
                             f"profiles (name the parameters to profile, or 'all')")
        return []
    if text.strip() == "all":
        return list(spec.fitted)
    names = [n.strip() for n in text.split(",") if n.strip()]
    if not names:           # ("unknown parameter(s) []" named nothing)
        raise ValueError(f"--profile {text!r}: no parameter named; give one or more of "
                         f"{list(spec.fitted)}, comma-separated, or 'all'")
    family = spec.base.family_obj.parameters
    unknown = [n for n in names if n not in family]
    if unknown:
        raise ValueError(f"--profile {text!r}: unknown parameter(s) {unknown}; valid: "
                         f"{list(spec.fitted)} or 'all'")
    held = [n for n in names if n not in spec.fitted]
    if held:
        raise ValueError(f"--profile {text!r}: {held} not fitted in the {spec.variant} variant "
                         f"(fitted: {list(spec.fitted)})")
    return list(dict.fromkeys(names))


def profile_plot_path(args) -> Path | None:
    """Where the profiles are drawn: --profile-plot, or beside --plot."""
    if not args.profile or (args.profile_plot is None and args.plot is None):
        return None
    if args.profile_plot is not None:
        return args.profile_plot
    return args.plot.with_name(f"{args.plot.stem}_profiles{args.plot.suffix}")


def profile_data(args, spec, midline):
    """The data the profiles refit: the midline as the loader read it, an average with the
    spread of its traces (:func:`morphoshell.io.load_midline` keeps them, resampled onto the
    fitted points whatever the file's rows).

    Checked before the fit, so that ``--profile-noise traces`` on a file that is not an
    average is refused before any work (it had been refused after the fit, whose result was
    lost, in the library's words).
    """
    from ..fitting import traces_missing

    missing = traces_missing(midline)
    if _option(args, "profile_noise") == "traces" and missing:
        raise ValueError(f"--profile-noise traces: {args.midline}: the midline holds {missing}, "
                         f"so there is no spread of traces to take the noise from: average the "
                         f"stage's traces with morphoshell average TRACE... --csv AVERAGE.csv "
                         f"and fit that, or take the noise from the fit's residual "
                         f"(--profile-noise residual)")
    if _option(args, "profile_noise") == "auto" and missing:
        print(f"note: --profile-noise auto: the midline holds {missing}: sigma^2 from the fit's "
              f"residual, whose intervals are lower bounds on traced data (an average of "
              f"traces, morphoshell average TRACE... --csv AVERAGE.csv, gives calibrated ones)")
    return midline


def run_profiles(args, spec, data, result, names: list[str], inflation=None) -> tuple:
    """The fit the profiles of ``names`` are about, and the profiles, refitted by the gradient
    method (:func:`morphoshell.fitting.profiled_fit`): ``result``, or the lower fit a refit
    found (then ``result`` was not the minimum; the profiles' intervals are about the lower).

    Whatever the fit's method: with the Volvox model's at most 13 parameters a KKT refit is
    the gradient refit's Gauss-Newton steps and an NLP after them, and a KKT fit's profiles
    took 2.8 times as long for the same intervals (docs/benchmarks.md, "Profile intervals").
    """
    from ..fitting import profiled_fit, traces_missing

    noise = _option(args, "profile_noise")
    if noise == "auto":     # (resolved here: profile_data has said so in the CLI's words)
        noise = "residual" if traces_missing(data) else "traces"
    return profiled_fit(spec, data, names, result=result,
                        points=_option(args, "profile_points"), method="gradient",
                        nodes=args.nodes, noise=noise, inflation=inflation)


def _option(args, key: str):
    """A --profile-* option's value, or its default (:data:`_DEFAULTS`) when not given."""
    value = getattr(args, key)
    return _DEFAULTS[key] if value is None else value


def refit_lines(before, after) -> str:
    """What the terminal says when the profiles' refit replaced the fit ``before`` by the lower
    ``after``: why, and the new fit (:meth:`FitResult.summary`)."""
    return (f"  the profiles' refit went on from the fit's end to a lower E_fit, "
            f"{after.E_fit:.6g} R (the fit: {before.E_fit:.6g} R), so the fit had not reached "
            f"its minimum; the fit is that refit, the intervals are about it:\n"
            f"{after.summary()}\n  E_fit = {after.E_fit:.6g} R over {len(after.data)} points")


def _dof(p) -> str:
    """How the threshold counts σ²'s degrees of freedom, for the table's header."""
    return f", {p.dof:g} degrees of freedom: F(1, {p.dof:g})" if math.isfinite(p.dof) else ""


def profile_table(result, profiles: dict) -> str:
    """The intervals beside the Gauss–Newton ±1.96 SE ones, one line a parameter."""
    first = next(iter(profiles.values()))
    retraced = first.sigma2_source == RETRACED
    sigma2 = (f"sigma^2 from the fit's {first.sigma2_source}, per parameter (JSON); +-1.96 SE "
              f"of the re-tracings beside" if retraced else
              f"sigma^2 = {first.sigma2:.3g} R^2 from the {first.sigma2_source}{_dof(first)}; "
              f"Gauss-Newton +-1.96 SE beside")
    lines = [f"  profile intervals ({100 * first.confidence:g} %, {first.method} refits, "
             f"{sigma2}):"]
    for name, p in profiles.items():
        lo, hi = p.interval
        se = result.standard_errors.get(name, math.nan)
        gn = f"+-{1.96 * se:.3g}" if math.isfinite(se) else "(on a constraint)"
        unit = f" {result.unit(name)}".rstrip()
        lines.append(f"  {name:8s} {p.fitted_value: .6g}  [{lo: .6g}, {hi: .6g}]{unit}  "
                     f"{'SE' if retraced else 'GN'} {gn}"
                     + (f"  {p.verdict()}" if p.verdict() else "")
                     + (f"  ({p.note})" if p.note else ""))
    return "\n".join(lines)


def profile_json(profiles: dict, before=None, after=None) -> dict:
    """The fit JSON's entries: ``profile_intervals`` ({name: [low, high]}, null where open),
    ``profiles`` (each profile's grid, objective and threshold) and, where the profiles'
    refit replaced the fit ``before`` by ``after``, ``replaced_fit``: what ``before`` was."""
    out = {n: p.to_dict() for n, p in profiles.items()}
    entries = {"profile_intervals": {n: d["interval"] for n, d in out.items()},
               "profiles": out}
    if before is not None and after is not before:
        entries["replaced_fit"] = {
            "note": "the profiles' refit went on from this fit's end to a lower E_fit: it had "
                    "not reached its minimum, and the parameters, E_fit and standard errors "
                    "above are the refit's",
            "method": before.method, "E_fit": before.E_fit, "converged": before.converged,
            "outer_iterations": before.outer_iterations,
            "parameters": {n: before.parameters[n] for n in before.fitted}}
    return entries
