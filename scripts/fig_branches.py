#!/usr/bin/env python3
"""The bifurcation diagram of docs/branches.md: the issue's Volvox shell along its path
from the stress-free parameters (tests/data/volvox_fold.toml, 400 nodes).

Follows the branch through its folds (``follow_branch``, pseudo-arclength) and, for the
quasi-static path with its snap-through, ``follow="stable"``; draws both diagrams with
the shapes at the events (``plot_branch``) and prints the events.  Writes
branches_volvox.png and branches_volvox_stable.png to --out (default docs/figures).

Usage: python scripts/fig_branches.py [--out DIR] [--nodes N]
"""
from __future__ import annotations

import argparse
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--out", type=Path, default=ROOT / "docs" / "figures")
    p.add_argument("--nodes", type=int, default=400)
    args = p.parse_args(argv)
    import matplotlib
    matplotlib.use("Agg")

    from morphoshell import follow_branch
    from morphoshell.io.problem_files import load_problem
    from morphoshell.plotting import paper_style, plot_branch, save

    problem, _ = load_problem(ROOT / "tests" / "data" / "volvox_fold.toml")
    args.out.mkdir(parents=True, exist_ok=True)
    for follow, name in (("branch", "branches_volvox"), ("stable", "branches_volvox_stable")):
        branch = follow_branch(problem, nodes=args.nodes, follow=follow)
        print(f"{follow}: {len(branch.points)} points in {branch.seconds:.2f} s; events "
              + ", ".join(f"{pt.event} at {pt.tau:.7f}" for pt in branch.events))
        with paper_style():
            save(plot_branch(branch), args.out / f"{name}.png")
    print(f"wrote {args.out}/branches_volvox.png and branches_volvox_stable.png")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
