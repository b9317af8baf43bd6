"""Named layouts of packed vectors: round trips and errors."""
import casadi as ca
import numpy as np
import pytest

from morphoshell import Problem
from morphoshell.numerics.scheme import Layout
from morphoshell.model.layouts import CELL_DATA, INTRINSIC, VectorLayout, parameter_layout
from morphoshell.model.profiles import get_family


def test_vector_layout_round_trip_numeric_and_symbolic():
    lay = parameter_layout(get_family("volvox"))
    assert lay.names[:3] == ("h", "cut", "opening") and lay.names[3:] == get_family("volvox").parameters
    values = {n: float(i) + 0.5 for i, n in enumerate(lay.names)}
    vec = lay.pack(values)
    assert lay.unpack(vec) == values
    sym = ca.SX.sym("p", len(lay))
    assert str(lay.unpack(sym)["s2"]) == str(sym[lay.index("s2")])
    with pytest.raises(ValueError, match="missing entries"):
        lay.pack({"h": 1.0})
    with pytest.raises(ValueError, match="has no entry 'k'"):
        lay.index("k")
    with pytest.raises(ValueError, match="repeats a name"):
        VectorLayout("bad", ("a", "a"))


def test_problem_parameter_vector_follows_the_layout():
    p = Problem("local_relaxation", {"F0": 0.2, "s0": 0.3}, h=0.05, cut=0.4)
    named = p.parameter_layout.unpack(p.parameter_vector())
    assert named == {"h": 0.05, "cut": 0.4, "opening": 0.0, "F0": 0.2, "s0": 0.3}


def test_cell_data_ends_with_the_intrinsic_data():
    off = CELL_DATA.after(INTRINSIC)
    assert CELL_DATA.names[off:] == INTRINSIC.names
    with pytest.raises(ValueError, match="does not end with"):
        INTRINSIC.after(CELL_DATA)


@pytest.mark.parametrize("start_pole, end_pole", [(True, True), (False, True), (False, False)])
@pytest.mark.parametrize("stages", [1, 2, 3])
def test_unknowns_pack_split_round_trip(start_pole, end_pole, stages):
    lay = Layout(7, stages, start_pole, end_pole)
    rng = np.random.default_rng(1)
    r, psi, f = rng.random(lay.points), rng.random(lay.points), rng.random(lay.cells * stages)
    if start_pole:
        r[0], psi[0] = 0.0, 0.0
    if end_pole:
        r[-1], psi[-1] = 0.0, np.pi
    x = lay.pack(r, psi, f)
    assert len(x) == lay.size == 2 * lay.free_points + lay.cells * stages
    r2, psi2, f2 = lay.split(x)
    assert np.array_equal(r2, r) and np.array_equal(psi2, psi) and np.array_equal(f2, f)
    # derivatives: the fixed pole values do not move
    dr, dpsi, _ = lay.split(x, derivative=True)
    if end_pole:
        assert dpsi[-1] == 0.0
