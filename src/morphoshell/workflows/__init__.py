"""Many solves at once: parameter sweeps and fit campaigns, in parallel.

:func:`~morphoshell.workflows.sweeps.sweep` solves on grids of parameters,
:func:`~morphoshell.workflows.campaigns.campaign` fits every timepoint of an
inversion sequence; both send small specifications to worker processes
(:mod:`.executor`: Dask or a local process pool).
"""

import lazy_loader

# Every public name of the subpackage, imported from its module on first use.
__getattr__, __dir__, __all__ = lazy_loader.attach(__name__, submod_attrs={
    "campaigns": ["Timepoint", "CampaignResult", "NumericalAblation", "campaign", "read_timepoints",
        "load_campaign", "fitted_problem", "fitted_state", "numerical_ablation", "ablation_errors",
        "HELD", "CAMPAIGN_NODES", "CUT", "RESULT_SUFFIX", "SUMMARY"],
    "sweeps": ["sweep", "SweepResult", "ERRORS", "MAX_SPLITS", "SOLVE_COLUMNS", "ABLATE_COLUMNS",
        "ESTIMATED_ABLATION", "UNITS", "chunk_plan"],
    "executor": ["open_executor", "run", "SerialExecutor", "backend_name"],
})
