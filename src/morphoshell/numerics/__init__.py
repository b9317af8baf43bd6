"""Numerics: meshes, the collocation transcription of the energy, and its back ends.

:mod:`.mesh` grades the nodes; :mod:`.discretisation` transcribes the energy of
:mod:`morphoshell.model.energy` into a parametric NLP by Gauss collocation
(:mod:`.scheme`), from per-cell kernels compiled to C (:mod:`.cell_kernels`) and
the parameter data at the Gauss points (:mod:`.parameter_data`), assembled by
index gathers (:mod:`.gathers`); it builds the KKT (Newton) system in cell order
(:mod:`.cell_order`, :mod:`.newton_assembly`), the KKT residual's derivatives
(:mod:`.kkt_derivatives`) and the shape as expressions (:mod:`.shape`);
:mod:`.ipopt` and :mod:`.newton` solve it (:mod:`.ipopt_options` checks Ipopt's
options before a build), and :mod:`.status` is the table of
how a solve can end, with the error every route raises.
"""

import lazy_loader

# The transcription's public names, imported from their module on first use.
__getattr__, __dir__, __all__ = lazy_loader.attach(__name__, submod_attrs={
    "discretisation": ["Discretisation"],
    "scheme": ["Layout", "collocation", "within_cells", "PointData"],
    "cell_kernels": ["compiled_cell_functions", "kernel_cache_dir"],
    "shape": ["SymbolicShape", "arclength_point", "increments"],
})
