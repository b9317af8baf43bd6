"""Fits of the 13-parameter Volvox model to traced midlines: a bilevel problem.

The outer least-squares fit of a midline over the model's parameters, the inner
problem an equilibrium; nested (Nelder-Mead, exact gradient) or as one
KKT-constrained NLP (paper, Supplementary, "Fitting of the morphoelastic theory").
"""

import lazy_loader

# Every public name of the subpackage, imported from its module on first use.
__getattr__, __dir__, __all__ = lazy_loader.attach(__name__, submod_attrs={
    "core": ["FitSpec", "FitResult", "FitError", "fit", "volvox_spec", "breakpoint_bounds",
        "model_midline", "synthetic_midline", "intrinsic_lengths", "check_midline", "METHODS",
        "VARIANTS", "N_FIT", "FIT_NODES", "BOUNDS", "LENGTH_SLACK", "MAX_TURN", "TURN_LENGTH",
        "POLE_SLACK"],
})
