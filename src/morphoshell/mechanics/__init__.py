"""The mechanics of the paper's analysis on top of the solvers.

Laser ablation and its recoil observables (:mod:`.ablation`), the paper's
asymptotic predictions (:mod:`.asymptotics`), toy problem 1 in bulk elasticity
(:mod:`.bulk`) and the exact through-thickness energy (:mod:`.thickness`).
"""
