"""Plots (Matplotlib): cross-sections of equilibria, ablations and fits, the paper's
figures and their styling (:mod:`.shells`), and bifurcation diagrams of branches
(:mod:`.branches`).

Importing the package leaves the Matplotlib backend alone, so plots show inline
in Jupyter; the command line draws into figures outside pyplot
(``new_axes(pyplot=False)``).  Lengths are in units of the undeformed radius R.
"""

import lazy_loader

# Every public name of the subpackage, imported from its module on first use.
__getattr__, __dir__, __all__ = lazy_loader.attach(__name__, submod_attrs={
    "shells": ["plot_fit", "plot_k_estimates", "plot_recoil_velocity", "figure_JK",
        "MEASURE_COLOURS", "sheet_outline", "far_end_shift", "problem_label", "new_axes",
        "plot_cross_section", "plot_ablation", "plot_ablation_overlay", "save",
        "paper_style", "label_panel", "SINGLE_COLUMN", "DOUBLE_COLUMN", "MIN_FONT_SIZE",
        "PAPER_RC", "ABLATION_STYLE"],
    "branches": ["plot_branch", "BRANCH_STYLE"],
})
