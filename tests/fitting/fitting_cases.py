"""The Volvox problems the fitting tests fit: the truth, a start near it, and a fit of three
of its parameters."""
from morphoshell import Problem
from morphoshell.fitting import volvox_spec

NODES = 60
TRUE = Problem("volvox", {"kappa1": 0.0, "kappa2": -8.0, "f1": 0.88, "s2": 1.62, "f3": 1.12},
               h=0.15, opening=0.3)
START = TRUE.with_updates(kappa2=-7.2, f1=0.91, s2=1.58)
THREE = ("kappa2", "f1", "s2")


def three_parameter_spec(start=START):
    """The flat variant fitting κ₂, f₁, s₂ only (the rest held at the truth)."""
    hold = {n: TRUE.params[n] for n in TRUE.family_obj.parameters
            if n not in THREE and n not in ("kappa1", "sigma")}
    return volvox_spec("flat", start, hold=hold)
