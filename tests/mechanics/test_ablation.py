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


def test_an_ablation_pickles_and_its_derivatives_survive():
    """A user audit: ablate's result did not pickle (its equilibria's problems and solvers).
    Unpickled, its observables and recoil_jacobian (which needs both states' solvers,
    rebuilt from their meshes) are the original's, to the bit."""
    import pickle

    import numpy as np

    from morphoshell.mechanics.ablation import recoil_jacobian

    ab = ablate(Problem("uniform", {"k": 0.5}, h=0.2, cut=0.3), nodes=50)
    back = pickle.loads(pickle.dumps(ab))
    assert back.problem == ab.problem and back.observables() == ab.observables()
    for a, b in zip(recoil_jacobian(back, ["k", "h"]), recoil_jacobian(ab, ["k", "h"])):
        assert np.array_equal(a, b)
