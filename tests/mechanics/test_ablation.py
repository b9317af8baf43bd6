"""ablate's arguments and recoil_jacobian's result (mechanics/ablation.py)."""
import pytest

from morphoshell import Problem, ablate
from morphoshell.solvers import routes

CUT = Problem("uniform", {"k": 0.0}, h=0.3, cut=0.3)


@pytest.mark.parametrize("args, kwargs, match", [
    # a user audit: AttributeError: 'int' object has no attribute 'problem'
    ((CUT,), {"pre": 5}, r"^pre = 5 must be an Equilibrium"),
    (("uniform",), {}, r"^problem = 'uniform' must be a morphoshell Problem"),
])
def test_arguments_of_the_wrong_kind_are_named_before_any_work(args, kwargs, match):
    builds = routes.cache_info()["builds"]
    with pytest.raises(TypeError, match=match):
        ablate(*args, nodes=50, **kwargs)
    assert routes.cache_info()["builds"] == builds
