"""Many solves at once: parameter sweeps and fit campaigns, in parallel.

:func:`~morphoshell.workflows.sweeps.sweep` solves on grids of parameters
(:mod:`.sweep_results`: its table),
:func:`~morphoshell.workflows.campaigns.campaign` fits every timepoint of an
inversion sequence (:mod:`.timepoint_fits`: one variant's timepoints in order;
:mod:`.campaign_results`: the records and the summary table), and
:mod:`.fitted_shapes` ablates the fitted shapes numerically; sweeps and
campaigns send small specifications to worker processes (:mod:`.executor`:
Dask or a local process pool).
"""

import lazy_loader

# Every public name of the subpackage, imported from its module on first use.  Timepoint and
# read_timepoints are defined in morphoshell.io.timepoints (the data set's table, a layer below):
# campaigns imports them to check a data set, and they are exported from there as before.
__getattr__, __dir__, __all__ = lazy_loader.attach(__name__, submod_attrs={
    "campaigns": ["campaign", "CampaignInterrupted", "CAMPAIGN_NODES", "Timepoint",
                  "read_timepoints"],
    "campaign_results": ["CampaignResult", "load_campaign", "RESULT_SUFFIX", "SUMMARY"],
    "fitted_shapes": ["NumericalAblation", "numerical_ablation", "ablation_errors",
                      "FitUncertainty", "TracesNoise", "fit_uncertainty", "PROFILE_WIDER",
                      "fitted_problem", "fitted_state", "CUT"],
    "timepoint_fits": ["HELD"],
    "start_candidates": ["MULTI_STARTS", "RANK_NODES"],
    "sweeps": ["sweep", "ERRORS", "MAX_SPLITS", "SOLVE_COLUMNS", "ABLATE_COLUMNS",
        "ESTIMATED_ABLATION", "UNITS", "chunk_plan"],
    "sweep_results": ["SweepResult"],
    "executor": ["open_executor", "run", "SerialExecutor", "backend_name", "check_workers"],
})
