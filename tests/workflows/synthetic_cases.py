"""The generator of the SYNTHETIC inversion sequences the campaign tests fit
(scripts/make_synthetic_inversion.py), loaded from its script."""
import importlib.util
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def generator():
    spec = importlib.util.spec_from_file_location(
        "make_synthetic_inversion", ROOT / "scripts" / "make_synthetic_inversion.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module
