"""morphoshell: equilibria of axisymmetric morphoelastic shells.

Direct energy minimisation (CasADi + Ipopt) of the large-bending shell energy
of Haas & Höhn, "Cut it out" (Materials and Methods), verified against a
boundary-value reference derived from the same energy.

Quick start::

    from morphoshell import Problem, solve
    eq = solve(Problem("uniform", {"k": 0.0}, h=0.3, cut=0.3))
    eq.r[0], eq.psi[0], eq.energy
"""
__version__ = "0.1.0"

from .problem import Problem, Structure  # noqa: E402
from .results import Equilibrium, NotAMinimumError, SolverError  # noqa: E402
from .direct import DirectSolver  # noqa: E402
from .equilibrium import solve  # noqa: E402
from .parametric import Parametric  # noqa: E402
from .ablation import Ablation, ablate  # noqa: E402

__all__ = ["Problem", "Structure", "DirectSolver", "Equilibrium", "SolverError",
           "NotAMinimumError", "solve", "Parametric", "Ablation", "ablate", "__version__"]
