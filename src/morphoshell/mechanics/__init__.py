"""The mechanics of the paper's analysis on top of the solvers.

Laser ablation and its recoil observables (:mod:`.ablation`), the paper's
asymptotic predictions (:mod:`.asymptotics`), toy problem 1 in bulk elasticity
(:mod:`.bulk`) and the exact through-thickness energy (:mod:`.thickness`).
"""

import lazy_loader

# Every public name of the subpackage, imported from its module on first use.
__getattr__, __dir__, __all__ = lazy_loader.attach(__name__, submod_attrs={
    "ablation": ["Ablation", "ablate", "ablation_of", "edge_state", "intact_problem",
                 "recoil_jacobian", "RecoilJacobian", "UNITS"],
    "asymptotics": ["f_shell_exact", "f_shell_asymptotic", "f_bulk_asymptotic", "k_star", "delta",
        "opening", "rotation", "displacement", "b_inner", "kelvin_k", "rotation_small_cut",
        "displacement_small_cut", "energy_released", "recoil_velocity", "predictions",
        "ENERGY_UNITS", "InnerSolution", "inner_solution", "inner_problem", "inner_recoil",
        "INNER_LENGTH"],
    "bulk": ["UndeformedGeometry", "DeformedGeometry", "undeformed_geometry", "deformed_geometry",
        "zeta_of_Z", "zeta_tilde_of_zeta", "stretch", "energy_density", "energy_density_derivative",
        "energy", "energy_derivative", "stationarity", "f_bulk", "DEFAULT_NODES"],
    "thickness": ["C_PER_MU", "Deformed", "deformed_state", "normal_coordinate", "exact_density",
        "shell_density", "energies"],
})
