"""Fits of the 13-parameter Volvox model to traced midlines: a bilevel problem.

The outer least-squares fit of a midline over the model's parameters, the inner
problem an equilibrium; nested (Nelder-Mead, exact gradient) or as one
KKT-constrained NLP (paper, Supplementary, "Fitting of the morphoelastic theory").
:mod:`.spec` says what is fitted, :mod:`.inner` solves the inner problem,
:mod:`.nested` and :mod:`.kkt` (with :mod:`.kkt_problem`) are the methods,
:mod:`.bilevel` is the front door :func:`~morphoshell.fitting.bilevel.fit`,
:mod:`.results` what it returns, :mod:`.multistart` a fit from several starts (the
lowest of its local minima), :mod:`.midline_checks` what it refuses and
:mod:`.profiles` what the data determine (profile-likelihood intervals, their noise
from :mod:`.profile_noise`, read back from a fit's JSON by :mod:`.profile_records`), and
:mod:`.hypotheses` which hypotheses on κ₁ the data tell apart (each against the free fit).
"""

import lazy_loader

# Every public name of the subpackage, imported from its module on first use.
__getattr__, __dir__, __all__ = lazy_loader.attach(__name__, submod_attrs={
    "spec": ["FitSpec", "SpecError", "volvox_spec", "breakpoint_bounds", "VARIANTS", "LABELS",
             "BOUNDS"],
    "inner": ["model_midline", "synthetic_midline", "N_FIT"],
    "results": ["FitResult", "FitError", "load_fit"],
    "midline_checks": ["intrinsic_lengths", "check_midline", "LENGTH_SLACK", "MAX_TURN",
                       "TURN_LENGTH", "POLE_SLACK", "MAX_MEAN_STRETCH", "POLE_ANGLE", "POLE_ARC",
                       "SCALE_HINT", "input_check", "IMPLAUSIBLE_E_FIT"],
    "bilevel": ["fit", "METHODS", "FIT_NODES", "EVALUATION_LIMITS"],
    "multistart": ["multi_start_fit", "MultiStartFit", "MULTI_STARTS"],
    "profiles": ["Profile", "profile", "profile_intervals", "profiled_fit"],
    "profile_records": ["load_profiles", "profile_from_dict"],
    "profile_noise": ["noise_variance", "traces_missing", "noise_dof", "threshold_quantile"],
    "hypotheses": ["compare_hypotheses", "HypothesisTest", "Hypothesis"],
})
