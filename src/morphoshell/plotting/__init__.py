"""Plots (Matplotlib): cross-sections of equilibria (:mod:`.shells`), ablations
(:mod:`.ablation`) and fits with their residuals (:mod:`.fits`), the paper's
Fig. 2 J–K (:mod:`.estimates`), bifurcation diagrams of branches
(:mod:`.branches`), profile likelihoods of fitted parameters (:mod:`.profiles`), the traces of one
stage over their average (:mod:`.traces`), and the look they share — journal sizes, fonts, one-line
titles and captions, saving (:mod:`.style`).

Importing the package leaves the Matplotlib backend alone, so plots show inline
in Jupyter; the command line draws into figures outside pyplot
(``new_axes(pyplot=False)``).  Lengths are in units of the undeformed radius R.
"""

import lazy_loader

# Every public name of the subpackage, imported from its module on first use.
__getattr__, __dir__, __all__ = lazy_loader.attach(__name__, submod_attrs={
    "style": ["new_axes", "journal_figure", "save", "paper_style", "styled", "label_panel",
              "add_caption", "get_caption", "panel_title", "flag_panel", "is_flagged",
              "SINGLE_COLUMN", "DOUBLE_COLUMN", "MIN_FONT_SIZE", "SCRIPT_SCALE",
              "MIN_SCRIPT_SIZE", "OKABE_ITO", "PAPER_RC"],
    "shells": ["sheet_outline", "far_end_shift", "problem_label", "problem_title",
               "problem_caption", "plot_cross_section"],
    "ablation": ["plot_ablation", "plot_ablation_overlay", "ABLATION_STYLE", "recoil_caption"],
    "fits": ["plot_fit", "fit_axes", "fit_residuals", "plot_fit_series", "not_converged_handle",
             "NOT_CONVERGED", "DATA_STYLE", "FIT_ZORDER"],
    "estimates": ["plot_k_estimates", "plot_recoil_velocity", "figure_JK", "MEASURE_COLOURS",
                  "VELOCITY_COLOUR", "OFF_SCALE_LABEL"],
    "branches": ["plot_branch", "BRANCH_STYLE"],
    "profiles": ["plot_profiles", "plot_profile"],
    "traces": ["plot_traces", "trace_styles"],
})
