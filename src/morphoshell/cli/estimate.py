"""``morphoshell estimate``: intrinsic curvature k and E/μ from ablation recoils (Fig. 2 J–K).

Its ``--plot`` is :func:`morphoshell.plotting.figure_JK`, shared with
``scripts/fig2jk_estimates.py``.
"""
from __future__ import annotations

import argparse

from ._args import add_outputs, integer, real
from ._commands import help_of
from ._outputs import Outputs

__all__ = ["register"]

_DESCRIPTION = """\
Estimate the intrinsic curvature k of each embryo from the recoil of a laser
ablation, and E/mu from the initial recoil velocities (paper, Fig. 2 J-K).

MEASUREMENTS.csv has one row per embryo and the columns embryo, R_um
(posterior radius), H_um (sheet thickness), hole_diameter_um (diameter
2R sin(Sigma) of the ablated cap on the intact shell), opening_um (R o, the
signed change of the hole's diameter), rotation_deg (rho, positive when the
edge unfurls outwards, in (-180, 180)) and displacement_um (R d, a distance);
optionally V_um_per_s (initial recoil velocity) and the measurement errors
sigma_opening_um, sigma_rotation_deg, sigma_displacement_um (one standard
deviation). Other columns are kept and ignored; an empty cell (or NA, N/A,
#N/A, NaN, null, None) is a missing measure; lines starting with # are
comments. The shell is nondimensionalised
by R: h = H/R, Sigma = arcsin(hole_diameter / 2R).

The observables are those of `morphoshell ablate`: the post-ablation minus
the intact (Sigma = 0) equilibrium of the same shell at the material point
s = Sigma, z in the far-end gauge (the far pole keeps its height).

Each measure gives k by: the leading-order asymptotics (Sigma = O(1)), the
small-cut Kelvin forms (rotation, displacement), the nonlinear inner problem
(all three), and numerical inversion of toy problem 2 at the embryo's own h
and Sigma (safeguarded Newton with the exact derivative); "asymptotic" is the
paper's choice (leading order for o, Kelvin for rho and d). A measure that no
k in --k-range produces gives null and a reason ("outside the range", "not
monotonic"). Errors propagate to k to first order. The combined k of an
embryo is the inverse-variance weighted mean of its numerical rho and d
estimates (their plain mean, with a note naming the empty sigma column, when an
error is missing). E/mu (1/s) is the least-squares slope
through the origin of V against H^(5/2) R^(-3/2) |1 - k|; E >= (E/mu) mu_min
(Pa) and the bending modulus E H^3 (J, mean H).

95% intervals are Student's t (of the mean; of the slope with n - 1 degrees
of freedom): the percentile bootstrap's, in the JSON beside them, hold the
truth in only 50-84% of tables of 2-5 embryos.

JSON: embryos (k_<measure>_<method>_error, k_combined, notes; null where there
is none), summary (n, mean, std, interval_95, bootstrap_interval_95, the
inverse-variance weighted mean over the weighted_n embryos with errors, per
estimate and combined) and, with velocities, E_over_mu,
E_over_mu_standard_error, E_over_mu_interval_95, E_lower_bound_Pa,
bending_modulus_lower_bound_J. CSV: the per-embryo table."""


def _resamples(text: str) -> int:
    """--bootstrap: 0, or from MIN_BOOTSTRAP to 1 000 000 resamples."""
    from ..inverse.summaries import check_bootstrap
    value = integer(0, 1_000_000)(text)
    try:
        return check_bootstrap(value)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc).replace("bootstrap = ", "")) from None


def register(sub) -> None:
    """Add ``morphoshell estimate`` to the subcommands ``sub``."""
    p = sub.add_parser("estimate", help=help_of("estimate"),
                       description=_DESCRIPTION,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("measurements", metavar="MEASUREMENTS.csv", help="the measurement table")
    p.add_argument("--theory", choices=("large_bending", "classical"), default="large_bending",
                   help="shell theory of the numerical inversion (default large_bending)")
    p.add_argument("--mu-min", type=real(0, 1e6, open_lo=True, unit=" Pa s"), default=8e-4,
                   metavar="PA_S", help="lower bound of the effective viscosity in Pa s "
                                        "(default 8e-4, algal growth medium)")
    p.add_argument("--k-range", nargs=2, type=real(-100, 100), default=(-1.0, 1.0),
                   metavar=("LO", "HI"), help="range of k searched (default -1 1: from an "
                                              "intrinsic curvature reversed relative to the sphere "
                                              "to the stress-free k = 1); |k| < 2/h of the "
                                              "thickest shell (a sheet cannot curve with a "
                                              "radius below its half-thickness)")
    p.add_argument("--bootstrap", type=_resamples, default=2000, metavar="N",
                   help="resamples of the percentile bootstrap 95%% intervals written beside "
                        "the Student's t ones in the JSON (default 2000; 0: none; at least 40, "
                        "to estimate the 2.5%% and 97.5%% quantiles); the bootstrap covers "
                        "less than 95%% with few embryos (docs/inverse.md)")
    p.add_argument("--seed", type=integer(0, 2**32 - 1), default=0, metavar="S",
                   help="seed of the bootstrap (default 0)")
    p.add_argument("--nodes", type=integer(20, 3200), default=60, metavar="N",
                   help="mesh nodes of the numerical model (default 60: k to ~4e-5)")
    p.add_argument("--workers", type=integer(1, 256), default=None, metavar="N",
                   help="processes sharing the embryos (default: one per core); the "
                        "estimates do not depend on it")
    add_outputs(p, json="write every estimate, the summary and the E/mu fit as JSON",
                csv="write the per-embryo estimates as CSV (units: docs, 'Results as tables')",
                plot="write Fig. 2 J (and K with velocities)")
    p.set_defaults(run=_estimate)


def _estimate(args) -> int:
    from ..inverse import check_shells, estimate, read_measurements
    from ..io.problem_files import write_csv, write_json

    lo, hi = args.k_range
    if not lo < hi:
        raise ValueError(f"--k-range {lo:g} {hi:g}: LO must be smaller than HI")
    data = read_measurements(args.measurements)
    check_shells(data, (lo, hi), f"--k-range {lo:g} {hi:g}")    # (before any solve)
    result = estimate(data, theory=args.theory, k_range=(lo, hi), mu_min=args.mu_min,
                      bootstrap=args.bootstrap, seed=args.seed, nodes=args.nodes,
                      workers=args.workers)
    print(f"{args.measurements}: {result}")
    print(f"  ({result.timing['total']:.1f} s; numerical estimates "
          f"{result.timing['numerical_seconds']:.1f} s)")
    out = Outputs()
    out.add(args.json, lambda path: write_json(path, {"input": str(args.measurements),
                                                      **result.to_dict()},
                                                     [args.measurements]))
    out.add(args.csv, lambda path: write_csv(path, result.table()))
    if args.plot:
        from ..plotting import figure_JK, save
        fig = figure_JK(result, pyplot=False)    # (no pyplot figure left open)
        out.add(args.plot, lambda path: save(fig, path))
    for path in out.commit():
        print(f"  wrote {path}")
    return 0
