"""The compiled cell kernels' cache (numerics.cell_kernels): keyed on every source file."""
import os
import shutil
import time

import pytest

from morphoshell.numerics import cell_kernels


@pytest.mark.parametrize("changed", ["model/energy.py", "workflows/__init__.py"],
                         ids=["kernels-source", "other-subpackage"])
def test_a_change_anywhere_in_the_package_changes_the_index_and_rebuilds_the_kernels(
        changed, monkeypatch, tmp_path):
    """The index hashes the whole package, subpackages included: on a copy of the package,
    editing one module (one the kernels are built from, or one they never import) gives
    another index, and the next process builds the expressions again and records them."""
    compiler = shutil.which(os.environ.get("CC", "cc"))
    if compiler is None:
        pytest.skip("no C compiler: the CasADi kernels are used")
    copy = tmp_path / "src" / "morphoshell"
    shutil.copytree(cell_kernels.PACKAGE, copy, ignore=shutil.ignore_patterns("__pycache__"))
    monkeypatch.setenv("MORPHOSHELL_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.setenv("MORPHOSHELL_COMPILE", "1")
    # as if imported well after the last edit of the source (the index needs that)
    monkeypatch.setattr(cell_kernels, "IMPORTED_NS", time.time_ns() + 2 * 10**9)
    original = cell_kernels._kernel_index(2, compiler)
    monkeypatch.setattr(cell_kernels, "PACKAGE", copy)
    before = cell_kernels._kernel_index(2, compiler)
    # the key is the source's content and relative paths, not where the package lies
    assert before is not None and before == original
    built = []
    real = cell_kernels.cell_functions
    monkeypatch.setattr(cell_kernels, "cell_functions",
                        lambda stages: built.append(stages) or real(stages))
    cell_kernels.compiled_cell_functions.cache_clear()
    try:
        if cell_kernels.compiled_cell_functions(2) is None:
            pytest.skip("no working C compiler: the CasADi kernels are used")
        assert built == [2] and before.exists()          # built, compiled and recorded
        cell_kernels.compiled_cell_functions.cache_clear()
        assert cell_kernels.compiled_cell_functions(2) is not None
        assert built == [2]                               # found by the index: not built

        source = copy / changed
        source.write_text(source.read_text() + "\n# an edit\n")
        assert cell_kernels._kernel_index(2, compiler) is None   # edited since the import
        # the next process, imported after the edit
        monkeypatch.setattr(cell_kernels, "IMPORTED_NS", time.time_ns() + 2 * 10**9)
        after = cell_kernels._kernel_index(2, compiler)
        assert after is not None and after != before and not after.exists()
        cell_kernels.compiled_cell_functions.cache_clear()
        kernels = cell_kernels.compiled_cell_functions(2)
        assert kernels is not None and kernels["grad"].name() == "morphoshell_cell2_grad"
        assert built == [2, 2]                            # the expressions built again
        assert after.exists() and (after.parent / after.read_text()).exists()
    finally:
        cell_kernels.compiled_cell_functions.cache_clear()
