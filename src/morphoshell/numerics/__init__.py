"""Numerics: meshes, the collocation transcription of the energy, and its back ends.

:mod:`.mesh` grades the nodes; :mod:`.discretisation` transcribes the energy of
:mod:`morphoshell.model.energy` into a parametric NLP by Gauss collocation and
builds its per-cell kernels (compiled to C) and the KKT (Newton) system in cell
order (:mod:`.cell_order`); :mod:`.ipopt` and :mod:`.newton` solve it.
"""

import lazy_loader

# The transcription's public names, imported from their module on first use.
__getattr__, __dir__, __all__ = lazy_loader.attach(__name__, submod_attrs={
    "discretisation": ["Discretisation", "Layout", "SymbolicShape", "collocation", "within_cells",
                       "PointData", "compiled_cell_functions", "kernel_cache_dir",
                       "arclength_point", "increments"],
})
