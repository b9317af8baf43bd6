"""Inverse estimates from laser-ablation recoils: intrinsic curvature k and E/μ.

Paper, main text, Fig. 2 J-K: each embryo's k from its recoil by several
methods, and E/μ from the initial recoil velocities.
"""
