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


def test_recoil_jacobian_names_its_rows_and_still_unpacks():
    """Rows in RECOIL's order (a user audit: a bare tuple of 5 unnamed rows); the pair
    unpacks as before.  Exact equality: the same arrays, picked by name."""
    from morphoshell.mechanics.ablation import recoil_jacobian
    from morphoshell.solvers.observables import RECOIL
    ab = ablate(CUT, nodes=50)
    result = recoil_jacobian(ab, ["k", "h"])
    values, jacobian = result
    assert result.rows == RECOIL and jacobian.shape == (5, 2)
    value, gradient = result.row("rotation")
    assert value == ab.rotation == values[1] and list(gradient) == list(jacobian[1])
    with pytest.raises(ValueError, match="row = 'energy_released': choose one of"):
        result.row("energy_released")
