"""The package's layers import downward only (README, Architecture)."""
import ast
from pathlib import Path

import morphoshell

#: Layers, bottom first; a module may import from its own layer or below.
LAYERS = [
    {"_validate", "_buffered", "_compiled", "_console", "_allocator", "executor"},
    {"geometry", "coefficients", "profiles", "layouts", "problem"},
    {"energy"},
    {"mesh", "results", "midlines"},
    {"cell_order", "discretisation"},
    {"ipopt", "newton"},
    {"direct", "reference", "shooting"},
    {"observables", "parametric"},
    {"continuation", "refinement"},
    {"equilibrium"},
    {"ablation", "asymptotics", "bulk", "thickness", "fitting", "inverse", "sweep", "campaign"},
    {"io", "plotting", "cli"},
]


def _layer(name):
    for i, layer in enumerate(LAYERS):
        if name in layer:
            return i
    raise AssertionError(f"module {name!r} is in no layer: add it to the README and here")


def test_imports_point_down():
    root = Path(morphoshell.__file__).parent
    # modules of the package, and the command line's subpackage (in the cli layer)
    files = [(p, p.stem, 1) for p in root.glob("*.py") if p.stem != "__init__"]
    files += [(p, "cli", 2) for p in (root / "cli").glob("*.py")]
    for path, name, depth in files:
        mine = _layer(name)
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and node.level == depth and node.module:
                target = node.module.split(".")[0]
                assert _layer(target) <= mine, f"{path.name} imports {target} from a higher layer"


def test_every_ipopt_solver_is_created_after_load_ipopt():
    """The first ``nlpsol(..., "ipopt", ...)`` of a process loads Ipopt's plugin; it must do so
    through ``ipopt.load_ipopt`` (OpenBLAS single-threaded: spin-waiting BLAS threads made
    warm solves 2.7x slower on a busy machine). Solvers set Ipopt up only when needed, so no
    other call may be relied on to have loaded it: each function creating one calls it."""
    root = Path(morphoshell.__file__).parent
    for path in [*root.glob("*.py"), *(root / "cli").glob("*.py")]:
        for fn in ast.walk(ast.parse(path.read_text())):
            if not isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef)):
                continue
            calls = [n.func for n in ast.walk(fn) if isinstance(n, ast.Call)]
            names = {getattr(f, "attr", getattr(f, "id", None)) for f in calls}
            if "nlpsol" in names:
                assert "load_ipopt" in names, f"{path.name}:{fn.name} creates an nlpsol " \
                                              f"without calling load_ipopt() first"
