"""Cross-section plots of equilibria (Matplotlib, no screen needed).

Shells are drawn as in the paper's figures: the meridian (r, z) and its
mirror image (−r, z), with the cell sheet as a band of the deformed thickness
h/(f_s f_φ) (incompressible cells: volume is conserved) around the midline.
Lengths are in units of the undeformed radius R.
"""
from __future__ import annotations

from pathlib import Path
from typing import Sequence

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from .equilibrium import Equilibrium  # noqa: E402

__all__ = ["sheet_outline", "plot_cross_section", "save"]


def sheet_outline(eq: Equilibrium) -> tuple[np.ndarray, np.ndarray]:
    """Closed polygon (r, z) of the cell sheet: midline ± half the deformed thickness."""
    half = eq.problem.h / (eq.f_s * eq.f_phi) / 2
    # At a pole f_φ → f_s: the nodal values are finite by construction.
    nr, nz = -np.sin(eq.psi), np.cos(eq.psi)   # normal to the meridian (tangent (cos ψ, sin ψ))
    outer = (eq.r + half * nr, eq.z + half * nz)
    inner = (eq.r - half * nr, eq.z - half * nz)
    return (np.concatenate([outer[0], inner[0][::-1]]),
            np.concatenate([outer[1], inner[1][::-1]]))


def plot_cross_section(eqs: Sequence[Equilibrium], labels: Sequence[str] | None = None,
                       ax=None, colors: Sequence[str] | None = None, title: str | None = None,
                       alphas: Sequence[float] | None = None):
    """Draw one or more equilibria as mid-sagittal cross-sections.

    Returns the Matplotlib axes.
    """
    if ax is None:
        _, ax = plt.subplots(figsize=(4.8, 4.8))
    colors = colors or [f"C{i}" for i in range(len(eqs))]
    alphas = alphas or [0.35] * len(eqs)
    labels = labels or [eq.problem.name or eq.problem.family for eq in eqs]
    for eq, label, color, alpha in zip(eqs, labels, colors, alphas):
        pr, pz = sheet_outline(eq)
        for sign in (1, -1):
            ax.fill(sign * pr, pz, color=color, alpha=alpha, lw=0)
            ax.plot(sign * eq.r, eq.z, color=color, lw=1.0, label=label if sign == 1 else None)
    ax.set_aspect("equal")
    ax.set_xlabel(r"$r/R$")
    ax.set_ylabel(r"$z/R$")
    ax.legend(loc="best", fontsize="small", frameon=False)
    if title:
        ax.set_title(title, fontsize="medium")
    return ax


def save(fig_or_ax, path: str | Path, formats: Sequence[str] | None = None) -> list[Path]:
    """Save a figure (PNG and, if asked, further formats); returns the paths written."""
    fig = fig_or_ax.figure if hasattr(fig_or_ax, "figure") and not hasattr(fig_or_ax, "savefig") \
        else fig_or_ax
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    out = []
    for fmt in formats or [path.suffix.lstrip(".") or "png"]:
        target = path.with_suffix("." + fmt)
        fig.savefig(target, dpi=150, bbox_inches="tight")
        out.append(target)
    plt.close(fig)
    return out
