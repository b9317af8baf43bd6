"""Notebooks in a real Jupyter kernel (nbclient + ipykernel): inline plots, tables, the tutorial.

The kernel runs the Python of this test process (the project's venv) with
this checkout's ``src`` first on its path, so it imports the package under
test, not an installed copy.
"""
import json
import os
import sys
from pathlib import Path

import pytest

nbformat = pytest.importorskip("nbformat")
nbclient = pytest.importorskip("nbclient")
pytest.importorskip("ipykernel")

import morphoshell  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
TUTORIAL = ROOT / "docs" / "notebooks" / "tutorial.ipynb"
SRC = Path(morphoshell.__file__).resolve().parents[1]
#: Seconds a cell may take (the tutorial's slowest, a sweep of 18 ablations, takes ~3 s).
CELL_TIMEOUT = 120


def _is_this_python(argv0: str) -> bool:
    # jupyter_client runs a spec whose argv[0] is "python"/"python3" with sys.executable
    return argv0 in ("python", f"python{sys.version_info[0]}",
                     "python%d.%d" % sys.version_info[:2]) or \
        Path(argv0).resolve() == Path(sys.executable).resolve()


@pytest.fixture(scope="module")
def kernel_name(tmp_path_factory):
    """"python3" if it runs this Python; else a kernelspec in a temporary JUPYTER_PATH."""
    from jupyter_client.kernelspec import KernelSpecManager

    specs = KernelSpecManager().get_all_specs()
    mp = pytest.MonkeyPatch()
    mp.setenv("PYTHONPATH", os.pathsep.join(filter(None, [str(SRC),
                                                          os.environ.get("PYTHONPATH")])))
    # as under Jupyter: the kernel chooses its (inline) backend, not an inherited MPLBACKEND=Agg
    mp.delenv("MPLBACKEND", raising=False)
    if "python3" in specs and _is_this_python(specs["python3"]["spec"]["argv"][0]):
        name = "python3"
    else:
        name = "morphoshell-test"
        folder = tmp_path_factory.mktemp("jupyter") / "kernels" / name
        folder.mkdir(parents=True)
        (folder / "kernel.json").write_text(json.dumps({
            "argv": [sys.executable, "-m", "ipykernel_launcher", "-f", "{connection_file}"],
            "display_name": "morphoshell test", "language": "python"}))
        mp.setenv("JUPYTER_PATH", str(folder.parents[1]))
    yield name
    mp.undo()


def _run(nb, kernel_name, cwd):
    client = nbclient.NotebookClient(nb, kernel_name=kernel_name, timeout=CELL_TIMEOUT,
                                     resources={"metadata": {"path": str(cwd)}})
    client.execute()
    return nb


def _outputs(nb):
    return [out for cell in nb.cells if cell.cell_type == "code" for out in cell.outputs]


def test_plots_render_inline_after_importing_morphoshell_plotting(kernel_name, tmp_path):
    nb = nbformat.v4.new_notebook()
    nb.cells = [nbformat.v4.new_code_cell(
        "import matplotlib\nimport morphoshell.plotting as mp\nprint(matplotlib.get_backend())"),
        nbformat.v4.new_code_cell(
        "from morphoshell import Problem, solve\n"
        "mp.plot_cross_section(solve(Problem('uniform', {'k': 0.0}, h=0.3, cut=0.3), nodes=30));")]
    _run(nb, kernel_name, tmp_path)
    first, second = nb.cells[0].outputs, nb.cells[1].outputs
    assert "inline" in "".join(o.get("text", "") for o in first), first
    assert any("image/png" in o.get("data", {}) for o in second), second


def test_the_tutorial_runs_end_to_end_with_plots_and_tables(kernel_name):
    # in its folder, as Jupyter and the docs build run it (it reads ../../data)
    nb = _run(nbformat.read(TUTORIAL, as_version=4), kernel_name, TUTORIAL.parent)
    outputs = _outputs(nb)
    assert not [o for o in outputs if o.output_type == "error"]
    data = [o.get("data", {}) for o in outputs]
    pngs = sum("image/png" in d for d in data)
    # shell, ablation, sweep lines, rings; the fit, its residuals, the fitted shell's ablation
    assert pngs >= 7, f"{pngs} inline images"
    html = [d["text/html"] for d in data if "text/html" in d]
    # DataFrames (pandas' table repr), an xarray Dataset, and the results' own tables
    assert sum("dataframe" in h and "<table" in h for h in html) >= 3
    assert any("xarray.Dataset" in h for h in html)
    assert any(d.get("text/plain", "").startswith("<xarray.Dataset>") for d in data)
    assert any("SweepResult(18 ablations: 3 k x 6 cut; 0 failed" in d.get("text/plain", "")
               for d in data)
    # the fitting section: a converged free fit of the shipped trace, the fitted shell ablated
    text = "".join(o.get("text", "") for o in outputs) + "".join(d.get("text/plain", "") for d in data)
    assert "FitResult(gradient, free," in text and "converged=True" in text, text
    assert "Ablation(cut=0.15 R" in text and "cold solve differs by" in text, text
    # the stored notebook carries no outputs (it is run here, not trusted; the docs build runs
    # it again to show its outputs)
    stored = nbformat.read(TUTORIAL, as_version=4)
    assert all(not c.get("outputs") for c in stored.cells if c.cell_type == "code")
