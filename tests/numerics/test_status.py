"""The table of statuses (morphoshell.numerics.status): every status a route sets is in it."""
import pickle
import re
from pathlib import Path

import pytest

from morphoshell.numerics.status import (BVP_STATUSES, STATUSES, NotAMinimumError, SolverError,
                                         explain)

SRC = Path(__file__).resolve().parents[2] / "src" / "morphoshell"
#: A status literal: Capitalised_Words_Joined ("Not_A_Minimum" too), in either quotes.
LITERAL = re.compile(r"""["']([A-Z][a-zA-Z]*[a-z](?:_[A-Z][a-zA-Z]*)+)["']""")


def test_every_status_literal_in_the_package_is_in_the_table():
    found = {(m.group(1), path.relative_to(SRC).as_posix())
             for path in SRC.rglob("*.py") for m in LITERAL.finditer(path.read_text())}
    assert len(found) > 20                          # the pattern finds them
    missing = sorted(f"{status} ({where})" for status, where in found if status not in STATUSES)
    assert not missing, missing


def test_every_status_says_what_it_means_in_one_line():
    for status, meaning in STATUSES.items():
        assert meaning and "\n" not in meaning and not meaning.endswith("."), status
    assert set(BVP_STATUSES.values()) <= set(STATUSES)


def test_solve_bvp_statuses_are_named_as_the_others():
    """scipy's messages were the statuses ("The maximum number of mesh nodes is exceeded.",
    beside the others' Continuation_Failed): a name for each of its four outcomes (audit 26)."""
    from scipy.integrate._bvp import TERMINATION_MESSAGES

    assert set(BVP_STATUSES) == set(TERMINATION_MESSAGES)
    assert all(LITERAL.fullmatch(repr(name)) for name in BVP_STATUSES.values()), BVP_STATUSES
    assert BVP_STATUSES[1] == "Bvp_Max_Nodes_Exceeded"


def test_solver_error_takes_only_statuses_of_the_table():
    with pytest.raises(ValueError, match="Made_Up_Status"):
        SolverError("failed", "Made_Up_Status")
    exc = NotAMinimumError("a saddle", "Not_A_Minimum")
    assert exc.status == "Not_A_Minimum" and "saddle" in explain(exc.status)
    again = pickle.loads(pickle.dumps(exc))       # worker processes send them back
    assert type(again) is NotAMinimumError and again.status == exc.status
    assert str(again) == "a saddle"
