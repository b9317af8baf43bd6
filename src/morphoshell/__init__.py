"""morphoshell: equilibria of axisymmetric morphoelastic shells.

Direct energy minimisation (CasADi + Ipopt) of the large-bending shell energy
of Haas & Höhn, "Cut it out" (Materials and Methods), verified against a
boundary-value reference derived from the same energy.  Lengths are in units
of the undeformed radius R, energies in units of C R² (documentation:
"Theory").

Quick start::

    from morphoshell import Problem, solve, ablate
    eq = solve(Problem("uniform", {"k": 0.0}, h=0.3, cut=0.3))
    eq.r[0], eq.psi[0], eq.energy          # R, rad, C R²
    eq.to_dataframe()                      # one row per point, units in df.attrs

The common entry points are importable from here: :class:`Problem`,
:func:`solve`, :func:`ablate`, :func:`sweep`, :func:`load_problem`, :func:`estimate`,
:class:`ProfileFamily` and :func:`register_family` (your own families),
:func:`example_path` (the packaged example problems).
"""
__version__ = "0.1.0"   # the one version source (pyproject.toml reads it)

from .problem import Problem, Structure  # noqa: E402
from .profiles import ProfileFamily, Profiles, register_family  # noqa: E402
from .results import Equilibrium, NotAMinimumError, SolverError  # noqa: E402
from .direct import DirectSolver  # noqa: E402
from .equilibrium import solve  # noqa: E402
from .parametric import Parametric  # noqa: E402
from .ablation import Ablation, ablate  # noqa: E402
from .inverse import estimate  # noqa: E402
from .io import example_path, examples, load_problem  # noqa: E402
from .sweep import sweep  # noqa: E402  (the function; the module is morphoshell.sweep)

__all__ = ["Problem", "Structure", "ProfileFamily", "Profiles", "register_family",
           "DirectSolver", "Equilibrium", "SolverError", "NotAMinimumError", "solve",
           "Parametric", "Ablation", "ablate", "estimate", "load_problem", "examples",
           "example_path", "sweep", "__version__"]
