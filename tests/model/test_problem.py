"""Problem: immutable once checked, hashable, its name a string (model/problem.py)."""
import pickle

import pytest

from morphoshell import Problem
from morphoshell.model.problem import Params


def _problem(**params):
    return Problem("uniform", {"k": 0.0, **params}, h=0.3, cut=0.3)


@pytest.mark.parametrize("mutate", [
    lambda p: p.params.__setitem__("k", 50.0),
    lambda p: p.params.update(k=50.0),
    lambda p: p.params.pop("k"),
    lambda p: p.params.__delitem__("k"),
    lambda p: p.params.setdefault("x", 1.0),
    lambda p: p.params.clear(),
])
def test_a_checked_problems_params_cannot_change(mutate):
    """A user audit set p.params["k"] = 50 (η = 7.5) on a checked Problem; its solve then
    failed inside the continuation, naming an intermediate η.  The change is refused and
    the values stay; with_updates makes a changed copy, checked anew."""
    p = _problem()
    with pytest.raises(TypeError, match=r"params are read-only .*with_updates"):
        mutate(p)
    assert p.params == {"k": 0.0}
    assert p.with_updates(k=0.5).params == {"k": 0.5}
    with pytest.raises(ValueError, match="abs"):
        p.with_updates(k=50.0)


def test_problems_hash_equal_when_equal_and_params_stay_a_dict():
    """Hashable (frozen): equal problems hash equal; the params still compare, print,
    pickle (to worker processes) and serialise as a plain dict."""
    p, q = _problem(), _problem()
    assert p == q and hash(p) == hash(q) and len({p, q, _problem(k=0.5)}) == 2
    assert isinstance(p.params, dict) and repr(p.params) == "{'k': 0.0}"
    back = pickle.loads(pickle.dumps(p.params))
    assert type(back) is Params and back == p.params
    assert "params={'k': 0.0}" in repr(p)


@pytest.mark.parametrize("name", [5, None, b"x"])
def test_a_name_that_is_not_a_string_is_refused(name):
    with pytest.raises(TypeError, match=rf"^name = {name!r} must be a string"):
        Problem("uniform", {"k": 0.0}, h=0.3, name=name)


@pytest.mark.parametrize("problem", [
    Problem("uniform", {"k": 0.0}, h=0.3, cut=0.3),
    Problem("volvox", h=0.15, opening=0.3, theory="classical", name="v"),
    Problem("central_growth", {"G": 0.2}, h=0.02, geometry="disc"),
])
def test_a_problem_pickles_as_its_declaration(problem):
    """A user audit: pickle.dumps(Problem(...)) failed (its family object holds CasADi
    functions, the sphere a lambda), so no process pool could take a problem.  It pickles
    by name and comes back equal, bound to this process's registered objects."""
    back = pickle.loads(pickle.dumps(problem))
    assert back == problem and hash(back) == hash(problem) and repr(back) == repr(problem)
    assert back.family_obj is problem.family_obj and back.geometry_obj is problem.geometry_obj
    assert back.theory_obj is problem.theory_obj and type(back.params) is Params


def test_a_problem_of_an_unregistered_family_is_refused_by_pickle_naming_it():
    """By name another process would rebuild another problem (or none): said on pickling."""
    from dataclasses import replace

    from morphoshell.model.profiles import get_family

    fam = replace(get_family("uniform"), _function={})     # (a copy, not the registered one)
    with pytest.raises(pickle.PicklingError, match="its family 'uniform' is not the one "
                                                   "registered under that name"):
        pickle.dumps(Problem(fam, {"k": 0.0}, h=0.3))
