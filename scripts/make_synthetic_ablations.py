#!/usr/bin/env python3
"""Make the SYNTHETIC laser-ablation table data/synthetic_ablations.csv (+ .json sidecar).

No measurement table of the paper is public.  This script stands in for one
with the forward model the estimator inverts, toy problem 2 (paper, Fig. 2 J–K,
Materials and Methods "2-photon microscopy and laser ablation experiments"):

* N = 14 embryos at early invagination; posterior radius R ~ U(35, 45) µm,
  sheet thickness H ~ U(9, 13) µm, cut radius R sin Σ ~ U(3, 6) µm ("removed
  cells within a radius of 3–6 µm"), so the hole's diameter is 2R sin Σ;
* intrinsic curvature k ~ N(0.05, 0.05²) per embryo (the paper's ⟨k⟩ ≈ 0.05);
* opening, rotation and displacement of the cut edge from
  :class:`morphoshell.inverse.RecoilModel` (large-bending theory, 400 mesh
  nodes: finer than the estimator's default 100, so estimates do not reuse its
  discretisation), plus Gaussian noise of standard deviation
  σ_o = 0.3 µm, σ_ϱ = 2°, σ_d = 0.2 µm.  The opening (0.1–1.5 µm here) is the
  hardest to measure (main text: "measuring o requires quantifying smaller
  deformations"); its error is about half its size, those of ϱ and d about a
  seventh.  A noisy displacement below 0 is reflected (it is a distance);
* initial recoil velocities V = (E/μ) H^{5/2} R^{−3/2} |1 − k| with
  E/μ = 0.6 s⁻¹ (the paper's ⟨E/μ⟩), times 1 + 0.15 N(0, 1).

The errors are written in the sigma_* columns.  The sidecar JSON holds the
script, seed, settings and the ground truth (true k, noiseless recoils and
velocities).  The CSV starts with comment lines saying it is synthetic.

Usage: python scripts/make_synthetic_ablations.py [--seed 2025] [--out data]
"""
from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np

from morphoshell import __version__
from morphoshell.inverse import RecoilModel, to_physical, velocity_scale
from morphoshell.io.problem_files import write_json

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = f"scripts/{Path(__file__).name}"
STEM = "synthetic_ablations"

N_EMBRYOS = 14
R_UM, H_UM, CUT_RADIUS_UM = (35.0, 45.0), (9.0, 13.0), (3.0, 6.0)
K_MEAN, K_STD = 0.05, 0.05
E_OVER_MU = 0.6              # 1/s
NOISE = {"opening": 0.3, "rotation": 2.0, "displacement": 0.2}   # µm, deg, µm
V_RELATIVE_NOISE = 0.15
THEORY, NODES = "large_bending", 400
DECIMALS = {"opening": 4, "rotation": 3, "displacement": 4}      # far below the noise


def generate(seed: int) -> tuple[list[dict], list[dict]]:
    """(rows of the table, ground truth per embryo)."""
    rng = np.random.default_rng(seed)
    model = RecoilModel(THEORY, NODES)
    rows, truth, start = [], [], None
    for i in range(N_EMBRYOS):
        R = round(float(rng.uniform(*R_UM)), 2)
        H = round(float(rng.uniform(*H_UM)), 2)
        hole = round(2 * float(rng.uniform(*CUT_RADIUS_UM)), 2)
        k = float(rng.normal(K_MEAN, K_STD))
        Sigma = math.asin(hole / (2 * R))
        point = model.evaluate(H / R, Sigma, k, start)
        start = point
        clean = {m: to_physical(m, getattr(point, m), R) for m in NOISE}
        noisy = {m: clean[m] + NOISE[m] * float(rng.standard_normal()) for m in NOISE}
        noisy["displacement"] = abs(noisy["displacement"])
        V_clean = E_OVER_MU * float(velocity_scale(H, R, k))
        V = V_clean * (1 + V_RELATIVE_NOISE * float(rng.standard_normal()))
        name = f"S{i + 1:02d}"
        rows.append({"embryo": name, "R_um": R, "H_um": H, "hole_diameter_um": hole,
                     **{f"{m}_{u}": round(noisy[m], DECIMALS[m]) for m, u in
                        (("opening", "um"), ("rotation", "deg"), ("displacement", "um"))},
                     "V_um_per_s": round(V, 4),
                     "sigma_opening_um": NOISE["opening"],
                     "sigma_rotation_deg": NOISE["rotation"],
                     "sigma_displacement_um": NOISE["displacement"]})
        truth.append({"embryo": name, "k": k, "h": H / R, "Sigma": Sigma,
                      "opening_um": clean["opening"], "rotation_deg": clean["rotation"],
                      "displacement_um": clean["displacement"], "V_um_per_s": V_clean})
    return rows, truth


def write(rows: list[dict], truth: list[dict], seed: int, out: Path) -> list[Path]:
    out.mkdir(parents=True, exist_ok=True)
    csv_path, json_path = out / f"{STEM}.csv", out / f"{STEM}.json"
    header = list(rows[0])
    lines = [f"# SYNTHETIC data, not measurements: made by {SCRIPT} --seed {seed} "
             f"(morphoshell {__version__}).",
             f"# Ground truth (k per embryo, E/mu = {E_OVER_MU} 1/s, noise) in {json_path.name}.",
             ",".join(header)]
    lines += [",".join(str(r[c]) for c in header) for r in rows]
    csv_path.write_text("\n".join(lines) + "\n")
    ks = np.array([t["k"] for t in truth])
    write_json(json_path, {
        "description": "SYNTHETIC laser-ablation recoils (not measurements) for paper Fig. 2 J-K",
        "script": SCRIPT, "seed": seed, "command": f"python {SCRIPT} --seed {seed}",
        "table": csv_path.name,
        "model": {"toy_problem": 2, "family": "uniform", "theory": THEORY, "nodes": NODES,
                  "observables": "post- minus pre-ablation (intact) state at s = Sigma, "
                                 "far-end gauge (morphoshell.mechanics.ablation.ablate)"},
        "sampling": {"embryos": N_EMBRYOS, "R_um": R_UM, "H_um": H_UM,
                     "cut_radius_um": CUT_RADIUS_UM, "k_mean": K_MEAN, "k_std": K_STD},
        "noise": {"sigma_opening_um": NOISE["opening"],
                  "sigma_rotation_deg": NOISE["rotation"],
                  "sigma_displacement_um": NOISE["displacement"],
                  "V_relative": V_RELATIVE_NOISE},
        "ground_truth": {"E_over_mu_per_s": E_OVER_MU, "k_sample_mean": float(ks.mean()),
                         "k_sample_std": float(ks.std(ddof=1)), "embryos": truth},
    })
    return [csv_path, json_path]


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=2025, help="random seed (default 2025)")
    parser.add_argument("--out", default=str(ROOT / "data"), help="output folder (default data/)")
    args = parser.parse_args(argv)
    rows, truth = generate(args.seed)
    for path in write(rows, truth, args.seed, Path(args.out)):
        print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
