"""Fixtures of the campaign tests: a tiny SYNTHETIC inversion sequence
(scripts/make_synthetic_inversion.py: 3 timepoints of early invagination, where the flat
hypothesis generated the data, 2 noisy embryo traces each)."""
import pytest

from synthetic_cases import generator

TIMES = (0.0, 0.05, 0.1)          # kappa1 = 0 throughout: the flat variant generated them


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    folder = tmp_path_factory.mktemp("synthetic")
    truth = generator().make(folder, pseudotimes=TIMES, embryos=2, nodes=120, quiet=True)
    return folder, truth


