#!/usr/bin/env python3
"""The bifurcation diagrams of docs/branches.md.

* The issue's Volvox shell along its path from the stress-free parameters
  (tests/data/volvox_fold.toml, --nodes, 400): the branch through its folds
  (``follow_branch``, pseudo-arclength) and the quasi-static path with its
  snap-through (``follow="stable"``): branches_volvox.png, branches_volvox_stable.png.
* The blister (the packaged example ``blister``: a disc grown in its centre, family
  ``central_growth``, f = 1 + G exp(−(s/0.3)²), h = 0.02, G from 0 to 0.2;
  --blister-nodes, 100): its flat branch, which loses
  stability at branch points, and the branches through the first two
  (``switch_branch``, both halves): branches_blister.png.

Draws the diagrams with the shapes at the events (``plot_branch``, in its journal style: the
figures ``morphoshell continue --plot`` writes), prints the events, writes to --out (default
docs/figures).

Usage: python scripts/fig_branches.py [--out DIR] [--nodes N] [--blister-nodes N]
"""
from __future__ import annotations

import argparse
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--out", type=Path, default=ROOT / "docs" / "figures")
    p.add_argument("--nodes", type=int, default=400)
    p.add_argument("--blister-nodes", type=int, default=100)
    args = p.parse_args(argv)
    import matplotlib
    matplotlib.use("Agg")

    from morphoshell import follow_branch
    from morphoshell.io.problem_files import load_problem
    from morphoshell.plotting import plot_branch, save

    problem, _ = load_problem(ROOT / "tests" / "data" / "volvox_fold.toml")
    args.out.mkdir(parents=True, exist_ok=True)
    for follow, name in (("branch", "branches_volvox"), ("stable", "branches_volvox_stable")):
        branch = follow_branch(problem, nodes=args.nodes, follow=follow)
        print(f"{follow}: {len(branch.points)} points in {branch.seconds:.2f} s; events "
              + ", ".join(f"{pt.event} at {pt.tau:.7f}" for pt in branch.events))
        save(plot_branch(branch), args.out / f"{name}.png")
    blister(args.out, args.blister_nodes)
    print(f"wrote {args.out}/branches_volvox.png, branches_volvox_stable.png and "
          f"branches_blister.png")
    return 0


def blister(out: Path, nodes: int) -> None:
    """The blister's flat branch and the branches through its first two branch points."""
    from morphoshell import follow_branch, switch_branch
    from morphoshell.io.problem_files import example_path, load_problem
    from morphoshell.plotting import plot_branch, save

    flat = follow_branch(load_problem(example_path("blister"))[0], nodes=nodes)
    switched = [switch_branch(flat, k, d) for k in (0, 1) for d in (1, -1)]
    for b in [flat, *switched]:
        print(f"blister {b.origin or 0:.7f} {b.direction:+g}: {len(b.points)} points in "
              f"{b.seconds:.2f} s, end {'stable' if b.end.stable else 'unstable'} "
              f"({b.end.negative_eigenvalues}), psi_end {b.end.psi_end:.6f}, energy "
              f"{b.end.energy:.6g}; events " + ", ".join(f"{pt.event} at {pt.tau:.7f}"
                                                         for pt in b.events))
    save(plot_branch(flat, switched=switched), out / "branches_blister.png")


if __name__ == "__main__":
    raise SystemExit(main())
