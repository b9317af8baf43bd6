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

The package's layers, bottom first (documentation: "Architecture"): ``model``
(the physics), ``numerics`` (meshes, the transcription, the back ends),
``solvers`` (the routes to an equilibrium), ``io`` (files), ``mechanics``
(ablation and the paper's analysis), ``inverse`` and ``fitting`` (estimates and
fits from data), ``workflows`` (sweeps and campaigns), ``plotting`` and ``cli``.
"""
__version__ = "0.1.0"   # the one version source (pyproject.toml reads it)

import lazy_loader

from . import _runtime  # noqa: F401 - first: it stamps the import time (compiled kernels)

# The entry points import their subpackages on first use (PEP 562): the command
# line and ``import morphoshell`` then load only what they need.
__getattr__, __dir__, __all__ = lazy_loader.attach(__name__, submod_attrs={
    "model.problem": ["Problem", "Structure"],
    "model.profiles": ["ProfileFamily", "Profiles", "register_family"],
    "numerics.status": ["SolverError", "NotAMinimumError"],
    "solvers.results": ["Equilibrium"],
    "solvers.direct": ["DirectSolver"],
    "solvers.routes": ["solve"],
    "solvers.parametric": ["Parametric"],
    "solvers.branches": ["follow_branch", "switch_branch", "continuation_path"],
    "mechanics.ablation": ["Ablation", "ablate"],
    "inverse": ["estimate"],
    "io.problem_files": ["load_problem"],
    "io.example_problems": ["examples", "example_path"],
    "workflows.sweeps": ["sweep"],
    "_runtime.allocator": ["keep_large_blocks"],
})
__all__ += ["__version__"]
