"""The commands of ``morphoshell``: the module registering each and its one-line help.

Here, apart from the modules, so that ``morphoshell --help`` (and a mistyped
command) lists them without importing any command module or what those pull in
(NumPy, CasADi, the solvers: most of a short command's time).
"""
from __future__ import annotations

__all__ = ["COMMANDS", "help_of"]

#: Command → (the module of :mod:`morphoshell.cli` that registers it, its one-line help),
#: in the order ``morphoshell --help`` lists them.
COMMANDS: dict[str, tuple[str, str]] = {
    "solve": ("solve", "equilibrium of a problem file"),
    "ablate": ("solve", "laser ablation: pre- and post-ablation equilibria"),
    "continue": ("branches", "follow a branch of equilibria: stability, folds, snap-throughs"),
    "asymptotics": ("analytic", "the paper's asymptotic predictions for toy problem 2"),
    "sphere": ("analytic", "toy problem 1: radius of a sphere with intrinsic curvature"),
    "estimate": ("estimate", "intrinsic curvature k and E/mu from ablation recoils"),
    "fit": ("fit", "fit the 13-parameter Volvox model to a traced midline"),
    "compare": ("compare", "test the hypotheses on kappa1 of fits of one midline against "
                           "the free fit"),
    "average": ("average", "average the traces of one stage into the midline a campaign fits"),
    "sweep": ("sweep", "equilibria or ablations on a grid of parameters (parallel)"),
    "campaign": ("campaign", "fit every timepoint of an inversion sequence for each variant "
                             "(parallel, resumable)"),
    "example": ("example", "print an example problem file (start your own from it)"),
}


def help_of(command: str) -> str:
    """The one-line help of ``command`` (its module's ``add_parser(..., help=...)``)."""
    return COMMANDS[command][1]
