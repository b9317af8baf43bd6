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

import importlib
import sys
import time
import types

# When this process imported the package: compiled kernels are found by a hash
# of the source only if no module changed since (discretisation._kernel_index).
_IMPORTED_NS = time.time_ns()

# Submodules are imported on first use of a name (PEP 562): the command line
# and ``import morphoshell`` then load only what they need; scipy's
# interpolate, optimize and sparse.linalg alone took most of a fresh
# process's first solve.
_LAZY = {"Problem": "problem", "Structure": "problem", "ProfileFamily": "profiles",
         "Profiles": "profiles", "register_family": "profiles", "Equilibrium": "results",
         "NotAMinimumError": "results", "SolverError": "results", "DirectSolver": "direct",
         "solve": "equilibrium", "Parametric": "parametric", "Ablation": "ablation",
         "ablate": "ablation", "estimate": "inverse", "example_path": "io",
         "examples": "io", "load_problem": "io", "sweep": "sweep",
         "keep_large_blocks": "_allocator"}


def __getattr__(name: str):
    """Import the submodule that defines ``name`` on first access."""
    if name not in _LAZY:
        raise AttributeError(f"module 'morphoshell' has no attribute {name!r}")
    value = getattr(importlib.import_module(f".{_LAZY[name]}", __name__), name)
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(_LAZY))


class _Package(types.ModuleType):
    """The package module: ``morphoshell.sweep`` stays the function.

    Importing the submodule ``morphoshell.sweep`` would bind it as the
    package attribute ``sweep``; the function is meant (the module stays in
    ``sys.modules``).
    """

    def __setattr__(self, name, value):
        if name == "sweep" and isinstance(value, types.ModuleType):
            value = value.sweep
        super().__setattr__(name, value)


sys.modules[__name__].__class__ = _Package

__all__ = ["Problem", "Structure", "ProfileFamily", "Profiles", "register_family",
           "DirectSolver", "Equilibrium", "SolverError", "NotAMinimumError", "solve",
           "Parametric", "Ablation", "ablate", "estimate", "load_problem", "examples",
           "example_path", "sweep", "keep_large_blocks", "__version__"]
