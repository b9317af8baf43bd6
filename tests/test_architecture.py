"""The package's layers import downward only (documentation: "Architecture").

Each subpackage (or top-level module) sits in one layer; a module may import from
its own layer or below, never above.  Names imported across modules are public:
a private name (``_x``) is used only in the module that defines it.
"""
import ast
import re
from pathlib import Path

import morphoshell

ROOT = Path(morphoshell.__file__).parent

#: Layers, bottom first: subpackages and top-level modules of morphoshell.
LAYERS = [
    {"_runtime"},
    {"model"},
    {"numerics"},
    {"solvers"},
    {"io"},
    {"mechanics"},
    {"inverse", "fitting"},
    {"workflows"},
    {"plotting"},
    {"cli"},
]

#: What any module may take from the package's own ``__init__``.
FROM_ROOT = {"__version__"}


def _layer(unit: str) -> int:
    for i, layer in enumerate(LAYERS):
        if unit in layer:
            return i
    raise AssertionError(f"{unit!r} is in no layer: add it to docs/architecture.md and here")


def _modules():
    """(path, dotted name inside the package) of every module but the package's __init__."""
    for path in sorted(ROOT.rglob("*.py")):
        parts = list(path.relative_to(ROOT).with_suffix("").parts)
        if parts == ["__init__"]:
            continue
        if parts[-1] == "__init__":
            parts = parts[:-1]
        yield path, parts, path.name == "__init__.py"


def _imports(path: Path, parts: list[str], is_package: bool):
    """(target parts, imported names) of every import of the package's own modules."""
    base = parts if is_package else parts[:-1]
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.level:
            up = base[: len(base) - node.level + 1]
            target = up + (node.module.split(".") if node.module else [])
            yield target, [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and (node.module or "").startswith("morphoshell"):
            yield node.module.split(".")[1:], [a.name for a in node.names]
        elif isinstance(node, ast.Import):
            for a in node.names:
                if a.name.startswith("morphoshell."):
                    yield a.name.split(".")[1:], []


def test_every_unit_is_in_a_layer():
    units = {p.name if p.is_dir() else p.stem for p in ROOT.iterdir()
             if (p.is_dir() and (p / "__init__.py").exists()) or p.suffix == ".py"}
    units -= {"__init__"}
    for unit in units:
        _layer(unit)


def test_imports_point_down():
    for path, parts, is_package in _modules():
        mine = _layer(parts[0])
        for target, names in _imports(path, parts, is_package):
            if not target:     # the package's __init__
                assert set(names) <= FROM_ROOT, f"{path}: imports {names} from morphoshell"
                continue
            assert _layer(target[0]) <= mine, \
                f"{path.relative_to(ROOT)} imports {'.'.join(target)} from a higher layer"


def test_no_private_names_cross_modules():
    for path, parts, is_package in _modules():
        for target, names in _imports(path, parts, is_package):
            private = [n for n in names if n.startswith("_") and not n.startswith("__")]
            assert not private, f"{path.relative_to(ROOT)} imports {private} from " \
                                f"{'.'.join(target) or 'morphoshell'}: make them public there"


def test_subpackages_say_their_job():
    for init in ROOT.glob("*/__init__.py"):
        doc = ast.get_docstring(ast.parse(init.read_text()))
        assert doc and len(doc) > 40, f"{init.parent.name}/__init__.py has no docstring"


#: Longest module (lines) and most complex function (radon's cyclomatic complexity): a
#: module should have one job and a function fit in a head (docs/architecture.md).
MAX_LINES, MAX_COMPLEXITY = 800, 20


def test_modules_are_short_and_functions_simple():
    from radon.complexity import cc_visit

    long, complex_ = [], []
    for path in sorted(ROOT.rglob("*.py")):
        text = path.read_text()
        name = path.relative_to(ROOT)
        if text.count("\n") > MAX_LINES:
            long.append(f"{name}: {text.count(chr(10))} lines")
        for block in cc_visit(text):
            for b in [block, *getattr(block, "methods", [])]:
                if b.complexity > MAX_COMPLEXITY:
                    complex_.append(f"{name}: {b.fullname} {b.complexity}")
    assert not long, f"modules over {MAX_LINES} lines: {long}"
    assert not complex_, f"functions over complexity {MAX_COMPLEXITY}: {sorted(set(complex_))}"


def test_the_code_explains_its_design_and_keeps_no_measurement_log():
    """Timings, A/B ratios and dated runs belong in docs/benchmarks.md, not in comments."""
    dated = re.compile(r"\b20\d\d-\d\d-\d\d\b")
    hits = [(p.relative_to(ROOT), i, line.strip())
            for p in sorted(ROOT.rglob("*.py"))
            for i, line in enumerate(p.read_text().splitlines(), 1)
            if "measured" in line or dated.search(line)]
    assert len(hits) <= 10 and not [h for h in hits if dated.search(h[2])], hits


def test_every_ipopt_solver_is_created_after_load_ipopt():
    """The first ``nlpsol(..., "ipopt", ...)`` of a process loads Ipopt's plugin; it must do so
    through ``ipopt.load_ipopt`` (OpenBLAS single-threaded: spin-waiting BLAS threads made
    warm solves 2.7x slower on a busy machine). Solvers set Ipopt up only when needed, so no
    other call may be relied on to have loaded it: each function creating one calls it."""
    for path in ROOT.rglob("*.py"):
        for fn in ast.walk(ast.parse(path.read_text())):
            if not isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef)):
                continue
            calls = [n.func for n in ast.walk(fn) if isinstance(n, ast.Call)]
            names = {getattr(f, "attr", getattr(f, "id", None)) for f in calls}
            if "nlpsol" in names:
                assert "load_ipopt" in names, f"{path.name}:{fn.name} creates an nlpsol " \
                                              f"without calling load_ipopt() first"


def test_test_files_have_distinct_names():
    """The tests mirror the package without ``__init__.py`` files, so pytest imports each
    test file under its bare name: two of one name in different folders fail the whole
    run ("import file mismatch"; io/ and solvers/ each had a test_arclength.py)."""
    tests = Path(__file__).parent
    seen: dict[str, Path] = {}
    for path in sorted(tests.rglob("*.py")):
        if path.name in seen and path.name != "conftest.py":
            raise AssertionError(f"{path} and {seen[path.name]} share a name")
        seen[path.name] = path
