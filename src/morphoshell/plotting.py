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
from matplotlib.colors import to_rgb  # noqa: E402
import numpy as np  # noqa: E402

from .results import Equilibrium  # noqa: E402

__all__ = ["sheet_outline", "plot_cross_section", "plot_ablation", "save"]

#: Colours of :func:`plot_ablation`, as in the paper (Fig. 2G–I, Fig. 3):
#: pre-ablation light red, post-ablation dark cyan.  ``fill`` is the opacity
#: of the band, blended with white (opaque, so that the mirrored halves, which
#: meet at the poles, show no seam); the pre-ablation midline is drawn on top.
ABLATION_STYLE = {"pre": {"color": "tab:red", "fill": 0.3, "line": "--"},
                  "post": {"color": "darkcyan", "fill": 0.85, "line": "-"}}


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
    return _finish(ax, title)


def _finish(ax, title: str | None):
    """Cross-section axes: equal aspect, lengths in units of R, legend, title."""
    ax.set_aspect("equal")
    ax.set_xlabel(r"$r/R$")
    ax.set_ylabel(r"$z/R$")
    ax.legend(loc="best", fontsize="small", frameon=False)
    if title:
        ax.set_title(title, fontsize="medium")
    return ax


def _far_end_shift(eq: Equilibrium) -> float:
    """z shift that puts ``eq`` in the gauge of the ablation observables.

    :func:`morphoshell.ablation.edge_state` keeps the far end of the shell
    at its undeformed height; its z at the first point minus the solver's
    z there is that shift (exact: the first point is not interpolated).
    """
    from .ablation import edge_state

    return edge_state(eq, float(eq.s[0]))["z"] - float(eq.z[0])


def plot_ablation(ablation, ax=None, title: str | None = None, mark_rim: bool = True):
    """Draw the pre- (light) and post-ablation (dark) cross-sections of an ablation.

    Both shells are drawn in the gauge of the observables (far end at its
    undeformed position, see :func:`morphoshell.ablation.edge_state`), so
    the recoil seen is the one measured by ``ablation.displacement``.  The
    whole intact shell is drawn, cap included; with ``mark_rim`` the material
    point s = Σ (the rim of the cut) is marked in both states.

    Parameters
    ----------
    ablation : morphoshell.observables.Ablation
    ax : matplotlib axes, optional
        Drawn into a new figure if not given.
    title : str, optional
    mark_rim : bool
        Mark the rim s = Σ before and after the cut.

    Returns the Matplotlib axes.
    """
    from .ablation import edge_state

    if ax is None:
        _, ax = plt.subplots(figsize=(4.8, 4.8))
    sigma = float(ablation.problem.cut)
    states = (("pre", ablation.pre, "pre-ablation"), ("post", ablation.post, "post-ablation"))
    for z_order, (key, eq, label) in enumerate(states):
        style = ABLATION_STYLE[key]
        rgb = np.array(to_rgb(style["color"]))
        face = 1 - style["fill"] * (1 - rgb)          # the colour at that opacity on white
        shift = _far_end_shift(eq)
        pr, pz = sheet_outline(eq)
        for sign in (1, -1):
            # an edge of the face colour hides the anti-aliasing seam at r = 0
            ax.fill(sign * pr, pz + shift, facecolor=face, edgecolor=face, lw=0.5,
                    zorder=1 + z_order, label=label if sign == 1 else None)
    # midlines above both bands, so that the pre-ablation shape stays visible
    for key, eq, _ in states:
        style = ABLATION_STYLE[key]
        shift = _far_end_shift(eq)
        for sign in (1, -1):
            ax.plot(sign * eq.r, eq.z + shift, color=style["color"], ls=style["line"], lw=0.8,
                    zorder=3)
        if mark_rim:
            rim = edge_state(eq, sigma)
            ax.plot([rim["r"], -rim["r"]], [rim["z"]] * 2, ls="none", marker="o", ms=3.5,
                    color=style["color"], zorder=4)
    return _finish(ax, title)


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
