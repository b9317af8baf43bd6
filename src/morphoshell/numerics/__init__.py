"""Numerics: meshes, the collocation transcription of the energy, and its back ends.

:mod:`.mesh` grades the nodes; :mod:`.discretisation` transcribes the energy of
:mod:`morphoshell.model.energy` into a parametric NLP by Gauss collocation and
builds its per-cell kernels (compiled to C) and the KKT (Newton) system in cell
order (:mod:`.cell_order`); :mod:`.ipopt` and :mod:`.newton` solve it.
"""
