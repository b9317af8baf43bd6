"""Make the SYNTHETIC Volvox inversion sequence of ``data/synthetic_inversion/``.

No traced midlines of Volvox inversion are public, so the fit campaign
(``morphoshell campaign``, paper Fig. 3 D–O) is demonstrated and tested on
data that the project's own forward model makes, clearly labelled synthetic:

* a parameter **trajectory** through pseudotime t ∈ [0, 1] (:data:`KEYFRAMES`,
  piecewise linear between early invagination, late invagination,
  mid-inversion and just before phialopore opening; h = 0.15, P = 0.3, σ =
  0.05; f₁ = 0.8, κ₃ = κ₄ = 1 constant).  The posterior intrinsic curvature
  rises from flat to the curvature that leaves the contracted posterior
  unstressed, κ₁(t) = S((t − 0.2)/0.4)/f₁ with the smoothstep S(x) = 3x² − 2x³
  clipped to [0, 1] (:func:`kappa1`): the ``flat`` hypothesis generated the
  timepoints with t ≤ 0.2, ``unstressed`` those with t ≥ 0.6, and the
  ``free`` one all of them;
* at each timepoint the equilibrium (400 nodes) and several "embryos": whole
  mid-sagittal sections, rim to rim through the posterior pole, written as
  image traces (``x,y`` in pixels, y down) with a random radius R, rotation
  and offset and Gaussian pixel noise, as a microscope and Fiji give them;
* their average midline (:func:`morphoshell.io.load_midline` of each
  trace, then :func:`morphoshell.io.average`), in units of R, which the
  campaign fits; ``timepoints.csv`` lists them with their pseudotimes.

The ground truth (the script, its seed and options, the trajectory, the
parameters, the noiseless midline of every timepoint, each embryo's radius,
pixel size, rotation and offset, the rms distance of each average from
the truth, and ``walls_cross``: null, or where the generating shape's walls pass
through each other, :func:`morphoshell.solvers.contact.wall_contact`) is in
``synthetic_inversion.json``.  The shipped sequence's shapes at t08 and t09 cross
themselves (walls 0.077 and 0.124 R apart against 0.17 R thick): not physical
shapes, kept because every variant's fits there cross as well and say so.  Running the script again with
the same options writes identical files (no time stamps, seeded noise).

    python scripts/make_synthetic_inversion.py                # the data set of the repository
    python scripts/make_synthetic_inversion.py --out DIR --timepoints 4 --embryos 3
"""
from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_OUT = ROOT / "data" / "synthetic_inversion"
SEED = 2025
#: Label written at the top of every file.
LABEL = "SYNTHETIC data (not measurements): made by scripts/make_synthetic_inversion.py"

#: Fixed parameters of the whole sequence (h, P, σ and the ones the fits hold).
FIXED = {"h": 0.15, "opening": 0.3, "sigma": 0.05, "f1": 0.8, "kappa3": 1.0, "kappa4": 1.0}
#: Keyframes of the trajectory (pseudotime: parameters), linear in between.
#: The bend region of wedge-shaped cells (κ₂ on [s₁, s₂]) widens towards the
#: posterior pole while the anterior expands (f₃, f₅: thinning disc cells).
KEYFRAMES = {
    0.00: {"f2": 1.00, "f3": 1.10, "f4": 1.00, "f5": 1.15, "kappa2": -7.0,     # early invagination
           "s1": 1.30, "s2": 1.65, "s3": 1.95, "s4": 2.35},
    0.35: {"f2": 1.00, "f3": 1.15, "f4": 1.00, "f5": 1.25, "kappa2": -7.0,     # late invagination
           "s1": 1.00, "s2": 1.50, "s3": 1.90, "s4": 2.35},
    0.70: {"f2": 1.00, "f3": 1.22, "f4": 1.00, "f5": 1.32, "kappa2": -7.0,     # mid-inversion
           "s1": 0.75, "s2": 1.38, "s3": 1.78, "s4": 2.35},
    1.00: {"f2": 1.00, "f3": 1.28, "f4": 1.00, "f5": 1.38, "kappa2": -7.0,     # before opening
           "s1": 0.55, "s2": 1.28, "s3": 1.68, "s4": 2.35},
}
#: κ₁ rises from 0 to 1/f₁ between these pseudotimes.
RISE = (0.2, 0.6)
STAGES = {0.0: "early invagination", 0.35: "late invagination", 0.7: "mid-inversion",
          1.0: "before phialopore opening"}

#: Microscope: pixel size (µm), embryo radii (µm, uniform), image size (pixels),
#: trace point spacing (pixels) and pixel noise (standard deviation, pixels).
PIXEL_UM = 0.3
RADIUS_UM = (36.0, 44.0)
IMAGE_PX = 1024
SPACING_PX = 1.5
NOISE_PX = 0.5
N_FIT = 100


def shipped_pseudotimes() -> dict[str, float]:
    """Pseudotime by timepoint name of the shipped data set (data/synthetic_inversion)."""
    truth = json.loads((ROOT / "data" / "synthetic_inversion" / "synthetic_inversion.json")
                       .read_text(encoding="utf-8"))
    return {t["timepoint"]: t["pseudotime"] for t in truth["timepoints"]}


def smoothstep(x: float) -> float:
    """3x² − 2x³ on [0, 1], 0 below and 1 above."""
    x = min(max(x, 0.0), 1.0)
    return x * x * (3 - 2 * x)


def kappa1(t: float) -> float:
    """The generating posterior intrinsic curvature κ₁(t) (units of 1/R)."""
    return smoothstep((t - RISE[0]) / (RISE[1] - RISE[0])) / FIXED["f1"]


def generating_variant(t: float) -> str | None:
    """The fixed-κ₁ hypothesis that generated timepoint t: flat, unstressed, or None between."""
    k = kappa1(t)
    return "flat" if k == 0 else "unstressed" if k == 1 / FIXED["f1"] else None


def parameters(t: float) -> dict:
    """All parameters of the trajectory at pseudotime t (h and opening included)."""
    times = sorted(KEYFRAMES)
    out = {k: v for k, v in FIXED.items()}
    for name in KEYFRAMES[0.0]:
        out[name] = float(np.interp(t, times, [KEYFRAMES[s][name] for s in times]))
    out["kappa1"] = kappa1(t)
    return out


def problem(t: float):
    """The generating :class:`~morphoshell.model.problem.Problem` at pseudotime t."""
    from morphoshell import Problem

    p = parameters(t)
    return Problem("volvox", {k: v for k, v in p.items() if k not in ("h", "opening")},
                   h=p["h"], opening=p["opening"], name=f"synthetic_t{t:.3f}")


def _truth_midline(t: float, nodes: int, n: int):
    """The noiseless half midline (n, 2) of timepoint t, units of R, and its equilibrium."""
    from morphoshell import solve
    from morphoshell.fitting import model_midline

    eq = solve(problem(t), nodes=nodes)
    return model_midline(eq, n), eq


def _write_midline(path: Path, midline, what: str) -> None:
    """A midline CSV (units of R) with the synthetic label and what it is in its header."""
    midline.to_csv(path)
    text = path.read_text(encoding="utf-8")
    path.write_text(f"# {LABEL}\n# {what}\n" + text, encoding="utf-8")


def _write_trace(path: Path, pixels: np.ndarray, header: list[str]) -> None:
    lines = [f"# {h}" for h in header] + ["x,y"] + [f"{x:.2f},{y:.2f}" for x, y in pixels]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")


def embryo_trace(fine: np.ndarray, rng: np.random.Generator) -> tuple:
    """One noisy "embryo": a whole section of the half midline ``fine`` as an image trace.

    Parameters
    ----------
    fine : ndarray (m, 2)
        The noiseless half midline (r, z), units of R, densely sampled.
    rng : numpy.random.Generator
        Draws, in this order, the radius R (µm), the rotation (degrees), the
        offset (pixels) and the pixel noise.

    Returns
    -------
    pixels : ndarray (n, 2)
        Rim to rim through the pole, image pixels (x right, y down), every
        :data:`SPACING_PX` pixels with Gaussian noise :data:`NOISE_PX`.
    radius_um, angle_deg : float
    offset_px : ndarray (2,)
    """
    from morphoshell.io import to_image

    length = float(np.sum(np.hypot(*np.diff(fine, axis=0).T)))
    radius_um = float(rng.uniform(*RADIUS_UM))
    radius_px = radius_um / PIXEL_UM
    angle = float(rng.uniform(0.0, 360.0))
    offset = rng.uniform(0.35 * IMAGE_PX, 0.65 * IMAGE_PX, 2)
    n = int(math.ceil(length * radius_px / SPACING_PX)) + 1
    idx = np.linspace(0, len(fine) - 1, n)
    half = np.column_stack([np.interp(idx, np.arange(len(fine)), fine[:, j]) for j in range(2)])
    pixels = to_image(half, radius_px=radius_px, angle_deg=angle, offset_px=tuple(offset),
                      section="whole")
    return pixels + rng.normal(0.0, NOISE_PX, pixels.shape), radius_um, angle, offset


def make(out: Path, *, timepoints: int = 12, embryos: int = 5, seed: int = SEED,
         nodes: int = 400, quiet: bool = False, pseudotimes=None) -> dict:
    """Write the data set into ``out``; returns the ground truth (also written as JSON).

    ``pseudotimes`` (increasing, in [0, 1]) replaces the ``timepoints`` equally
    spaced ones (small test sets: a short stretch of the trajectory).
    """
    times = (np.linspace(0.0, 1.0, timepoints) if pseudotimes is None
             else np.asarray(pseudotimes, dtype=float))
    timepoints = len(times)
    from morphoshell.io import average, load_midline
    from morphoshell.solvers.contact import wall_contact

    out.mkdir(parents=True, exist_ok=True)
    streams = np.random.SeedSequence(seed).spawn(timepoints)
    command = (f"python scripts/make_synthetic_inversion.py --seed {seed} --timepoints "
               f"{timepoints} --embryos {embryos} --nodes {nodes}"
               + ("" if pseudotimes is None else
                  " --pseudotimes " + ",".join(f"{t:g}" for t in times)))
    truth = {"label": LABEL, "command": command, "seed": seed, "nodes": nodes,
             "family": "volvox", "fixed": FIXED, "keyframes": {f"{t:g}": v for t, v in
                                                                KEYFRAMES.items()},
             "stages": {f"{t:g}": s for t, s in STAGES.items()},
             "kappa1": f"S((t - {RISE[0]})/{RISE[1] - RISE[0]:g})/f1, S(x) = 3x^2 - 2x^3 on [0, 1]",
             "microscope": {"pixel_um": PIXEL_UM, "radius_um": list(RADIUS_UM),
                            "image_px": IMAGE_PX, "spacing_px": SPACING_PX,
                            "noise_px": NOISE_PX},
             "units": {"lengths": "R (each embryo's own radius)", "kappa": "1/R",
                       "pixels": "x right, y down"},
             "timepoints": []}
    rows = []
    for k, t in enumerate(times):
        t = float(round(t, 6))
        name = f"t{k + 1:02d}"
        folder = out / name
        folder.mkdir(exist_ok=True)
        fine, eq = _truth_midline(t, nodes, 4001)
        rng = np.random.default_rng(streams[k])
        singles, placements = [], []
        for e in range(1, embryos + 1):
            pixels, radius_um, angle, offset = embryo_trace(fine, rng)
            path = folder / f"synthetic_embryo{e}.csv"
            _write_trace(path, pixels, [LABEL, f"timepoint {name}, pseudotime t = {t:g}, "
                                       f"embryo {e}: whole mid-sagittal section, rim to rim",
                                       f"pixel size {PIXEL_UM} um, embryo radius R = "
                                       f"{radius_um:.4f} um"])
            singles.append(load_midline(path, "xy", n=N_FIT, section="whole",
                                        pixel_size_um=PIXEL_UM, radius_um=round(radius_um, 4)))
            placements.append({"embryo": e, "file": f"{name}/{path.name}",
                               "radius_um": round(radius_um, 4), "angle_deg": angle,
                               "offset_px": offset.tolist(), "points": len(pixels)})
        mean = average(singles)
        mean = type(mean)(mean.r, mean.z, mean.spread, mean.n_traces,
                          tuple(Path(s).relative_to(out).as_posix() for s in mean.source))
        avg = folder / "synthetic_average.csv"
        _write_midline(avg, mean, f"timepoint {name}, pseudotime t = {t:g}: average of "
                                  f"{embryos} traces, units of R")
        # each trace's midline too: a campaign with embryo_errors fits them one by one
        traces = []
        for e, single in enumerate(singles, start=1):
            path = folder / f"synthetic_embryo{e}_midline.csv"
            _write_midline(path, type(single)(single.r, single.z, single.spread, 1,
                                              (f"{name}/synthetic_embryo{e}.csv",)),
                           f"timepoint {name}, pseudotime t = {t:g}: midline of embryo {e}, "
                           f"units of R")
            traces.append(f"{name}/{path.name}")
        exact = fine[np.round(np.linspace(0, len(fine) - 1, N_FIT)).astype(int)]
        # The model has no self-contact: a generating shape whose walls pass through each
        # other is not a physical shape, and its fits are fits of such shapes (t08, t09 of
        # the shipped set: docs/campaigns.md, "Walls that cross")
        contact = wall_contact(eq)
        rms = float(np.sqrt(np.mean(np.sum((mean.points - exact) ** 2, axis=1))))
        truth["timepoints"].append({
            "timepoint": name, "pseudotime": t, "parameters": parameters(t),
            "generating_variant": generating_variant(t),
            "energy": eq.energy, "midline": {"r": exact[:, 0].tolist(), "z": exact[:, 1].tolist()},
            "average": f"{name}/{avg.name}", "average_rms_error": rms,
            "E_noise": float(np.sqrt(np.sum((mean.points - exact) ** 2))),
            "walls_cross": None if contact is None else contact.to_dict(),
            "embryos": placements})
        rows.append(f"{name},{t:g},{name}/{avg.name},{';'.join(traces)}")
        if not quiet:
            print(f"{name}: t = {t:.3f}, kappa1 = {kappa1(t):.4f} 1/R, average off the truth by "
                  f"{rms:.2e} R rms" + ("" if contact is None else
                                        f"; WALLS CROSS: {contact.describe()}"),
                  file=sys.stderr)
    (out / "timepoints.csv").write_text(
        f"# {LABEL}\n# ground truth: synthetic_inversion.json\n"
        f"timepoint,pseudotime,midline,traces\n"
        + "\n".join(rows) + "\n", encoding="utf-8")
    (out / "synthetic_inversion.json").write_text(json.dumps(truth, indent=1) + "\n",
                                                  encoding="utf-8")
    return truth


def main(argv=None) -> int:
    """Command line of the script (see the module docstring)."""
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--out", type=Path, default=DEFAULT_OUT, help="output folder")
    p.add_argument("--seed", type=int, default=SEED, help=f"random seed (default {SEED})")
    p.add_argument("--timepoints", type=int, default=12, help="timepoints (default 12)")
    p.add_argument("--embryos", type=int, default=5, help="embryos per timepoint (default 5)")
    p.add_argument("--nodes", type=int, default=400, help="mesh nodes of the forward model")
    p.add_argument("--pseudotimes", default=None,
                   help="comma-separated pseudotimes in [0, 1] instead of --timepoints equally "
                        "spaced ones")
    p.add_argument("-q", "--quiet", action="store_true")
    args = p.parse_args(argv)
    make(args.out, timepoints=args.timepoints, embryos=args.embryos, seed=args.seed,
         nodes=args.nodes, quiet=args.quiet,
         pseudotimes=None if args.pseudotimes is None else
         [float(v) for v in args.pseudotimes.split(",")])
    return 0


if __name__ == "__main__":
    sys.exit(main())
