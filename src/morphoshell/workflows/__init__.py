"""Many solves at once: parameter sweeps and fit campaigns, in parallel.

:func:`~morphoshell.workflows.sweeps.sweep` solves on grids of parameters,
:func:`~morphoshell.workflows.campaigns.campaign` fits every timepoint of an
inversion sequence; both send small specifications to worker processes
(:mod:`.executor`: Dask or a local process pool).
"""
