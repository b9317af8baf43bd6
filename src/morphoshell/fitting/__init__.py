"""Fits of the 13-parameter Volvox model to traced midlines: a bilevel problem.

The outer least-squares fit of a midline over the model's parameters, the inner
problem an equilibrium; nested (Nelder-Mead, exact gradient) or as one
KKT-constrained NLP (paper, Supplementary, "Fitting of the morphoelastic theory").
"""
