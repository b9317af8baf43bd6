"""What a fit varies (fitting.spec): variants, ties, holds, breakpoint boxes and the
constraints a fit ends on."""
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from morphoshell import Problem
from morphoshell.fitting import breakpoint_bounds, volvox_spec

from fitting_cases import START


def test_variants_tie_hold_and_refuse():
    unstressed = volvox_spec("unstressed", START)
    assert "kappa1" not in unstressed.fitted and "f1" in unstressed.fitted
    params = unstressed.params(unstressed.theta0)
    assert params["kappa1"] == pytest.approx(1 / params["f1"])
    # d kappa1 / d f1 = -1/f1² through the tie
    chain = unstressed.chain(unstressed.theta0, ["kappa1"])
    assert chain[0, unstressed.fitted.index("f1")] == pytest.approx(-1 / params["f1"] ** 2)
    assert volvox_spec("undeformed", START).base.params["kappa1"] == 1.0
    assert "kappa1" in volvox_spec("free", START).fitted
    with pytest.raises(ValueError, match="cannot be held"):
        volvox_spec("unstressed", START, hold={"kappa1": 0.5})
    # flat and undeformed fix kappa1: holding it elsewhere would mislabel the hypothesis
    assert volvox_spec("flat", START, hold={"kappa1": 0.0}).base.params["kappa1"] == 0.0
    for variant, value in (("flat", 0.5), ("undeformed", 0.0)):
        with pytest.raises(ValueError, match=f"{variant} variant holds kappa1"):
            volvox_spec(variant, START, hold={"kappa1": value})
    with pytest.raises(ValueError, match="variant = 'rigid'"):
        volvox_spec("rigid")


@given(st.lists(st.floats(0.001, 3.0), min_size=5, max_size=5), st.floats(0.001, 0.5))
@settings(max_examples=200, deadline=None)
def test_breakpoint_boxes_hold_their_start_and_keep_breakpoints_sigma_apart(gaps, sigma):
    """Any point of the boxes keeps the breakpoints σ apart and inside the shell (a
    pair that starts closer keeps its gap), and each box holds its breakpoint."""
    s = np.cumsum(gaps)
    end, s = s[-1], s[:-1]
    boxes = np.array(breakpoint_bounds(s.tolist(), sigma, end))
    assert np.all(boxes[:, 0] <= s) and np.all(s <= boxes[:, 1])
    # the nearest two points of neighbouring boxes, and the pole and the end
    least = np.minimum(sigma, np.diff([0.0, *s, end]))
    reach = np.diff([0.0, *boxes.ravel(), end])[::2]
    assert np.all(reach >= least * (1 - 1e-12)), (reach, least)


def test_on_constraints_names_the_ordering_and_the_bounds():
    spec = volvox_spec("free", start=Problem("volvox", h=0.15, opening=0.3))
    theta = spec.theta0.copy()
    i = {n: spec.fitted.index(n) for n in spec.fitted}
    assert spec.on_constraints(theta) == []
    theta[i["s1"]] = 0.05                      # sigma from the pole
    theta[i["f1"]] = spec.bounds["f1"][0]      # on its bound
    theta[i["s4"]] = theta[i["s3"]] + 0.05 + 1e-5
    got = dict(spec.on_constraints(theta))
    assert got == {"s1 = sigma (from the pole)": ("s1",), "s4 - s3 = sigma": ("s3", "s4"),
                   f"f1 = {spec.bounds['f1'][0]:g} (its bound)": ("f1",)}


@pytest.mark.parametrize("variant", ["free", "flat"])
def test_a_start_outside_a_bound_by_ipopts_relaxation_is_projected_onto_it(variant):
    """An earlier fit's f2 = 0.499999990065968 (Ipopt's bound relaxation of 0.5) starts the
    next fit on the bound; a start truly outside is refused with the same message as ever."""
    from morphoshell.fitting.spec import BOUND_SLACK

    lo, hi = volvox_spec(variant, START).bounds["f2"]
    for value, edge in ((0.499999990065968, lo), (hi * (1 + 0.5 * BOUND_SLACK), hi)):
        spec = volvox_spec(variant, START.with_updates(f2=value))
        assert spec.base.params["f2"] == edge and spec.theta0[spec.fitted.index("f2")] == edge
    with pytest.raises(ValueError, match=r"the start f2 = 0\.4999 lies outside its bounds "
                                         r"\(0\.5, 2\)"):
        volvox_spec(variant, START.with_updates(f2=0.4999))
    inside = volvox_spec(variant, START.with_updates(f2=0.5 + 1e-9))
    assert inside.base.params["f2"] == 0.5 + 1e-9          # inside: untouched


DEFAULTS = Problem("volvox", h=0.15, opening=0.3)       # s1..s4 = 1.3, 1.6, 1.9, 2.3


def test_a_held_value_outside_the_bounds_is_refused_naming_them():
    """--set f1=5 (bounds 0.5-2) ran 4 s to E_fit 16.5 R (audit 3, #10); a value an earlier
    fit left on its bound, outside by Ipopt's relaxation, is still held."""
    from morphoshell.fitting import SpecError
    from morphoshell.fitting.spec import BOUND_SLACK

    for name, value, said in (("f1", 5.0, r"f1 = 5 lies outside the fit's bounds \[0\.5, 2\]"),
                              ("kappa2", -16.0, r"kappa2 = -16 lies outside the fit's bounds "
                                                r"\[-15, 15\]")):
        with pytest.raises(SpecError, match=said) as exc:
            volvox_spec("free", DEFAULTS, hold={name: value})
        assert exc.value.names == (name,)
    held = volvox_spec("flat", DEFAULTS, hold={"f1": 2 * (1 + 0.5 * BOUND_SLACK)})
    assert held.base.params["f1"] == 2 * (1 + 0.5 * BOUND_SLACK) and "f1" not in held.fitted


def test_a_sigma_that_leaves_a_breakpoint_no_box_is_refused_naming_the_largest():
    """sigma = 0.3 (in its range [0.001, 0.5]) gave SciPy's "Each lower bound must be strictly
    less than each upper bound" after the set-up (audit 3, #8): s2 is 0.3 from both
    neighbours.  The message names the breakpoint and the largest sigma they allow."""
    from morphoshell.fitting import SpecError

    with pytest.raises(SpecError, match=r"sigma = 0\.3 leaves no room for s2 \(0\.3 from s1, "
                                        r"0\.3 from s3\).* sigma must be below 0\.3") as exc:
        volvox_spec("free", DEFAULTS.with_updates(sigma=0.3))
    assert exc.value.names == ("sigma", "s1", "s2", "s3")
    spec = volvox_spec("free", DEFAULTS.with_updates(sigma=0.299))
    assert all(lo < hi for lo, hi in spec.bounds.values())
    # held, s2 needs no box; held neighbours closer than sigma break the ordering
    assert volvox_spec("free", DEFAULTS.with_updates(sigma=0.3), hold={"s2": 1.6}).bounds
    with pytest.raises(SpecError, match=r"s2 and s3, held, 0\.3 apart.* below 0\.3"):
        volvox_spec("free", DEFAULTS.with_updates(sigma=0.35), hold={"s2": 1.6, "s3": 1.9})


@given(st.lists(st.floats(0.01, 1.0), min_size=5, max_size=5), st.floats(0.001, 0.5),
       st.lists(st.booleans(), min_size=4, max_size=4))
@settings(max_examples=200, deadline=None)
def test_sigma_is_refused_exactly_when_a_fitted_box_would_have_no_width(gaps, sigma, held):
    """Either every fitted breakpoint's box has room (what SciPy needs) and held ones are
    sigma apart, or the spec is refused with a limit that sigma reaches and just below
    which it is accepted."""
    from morphoshell.fitting import SpecError

    s = np.cumsum(gaps)
    opening = np.pi - s[-1]
    if not 0 <= opening < np.pi - 0.2:
        return
    names = ("s1", "s2", "s3", "s4")
    base = DEFAULTS.with_updates(opening=float(opening), **dict(zip(names, s[:-1].tolist())))
    hold = {n: base.params[n] for n, h in zip(names, held) if h}
    try:
        spec = volvox_spec("free", base.with_updates(sigma=sigma), hold=hold)
    except SpecError as exc:
        limit = float(str(exc).split("sigma must be below ")[1].split(",")[0])
        assert sigma >= limit * (1 - 1e-3)
        below = 0.999 * limit
        if below >= 0.001:
            volvox_spec("free", base.with_updates(sigma=below), hold=hold)
        return
    assert all(hi - lo > 0 for n, (lo, hi) in spec.bounds.items() if n in names)
    fixed, points = [True, *held, True], [0.0, *s]     # the pole, s1..s4, the shell's end
    for j in range(5):                                   # each pair of neighbours
        if fixed[j] and fixed[j + 1]:
            assert points[j + 1] - points[j] >= sigma * (1 - 1e-9)


def test_a_start_that_is_not_a_problem_is_named():
    # audit 12: volvox_spec("free", {"f1": 0.8}) raised AttributeError 'dict' ... 'family'
    with pytest.raises(TypeError, match=r"start = \{'f1': 0.8\} must be a Problem"):
        volvox_spec("free", {"f1": 0.8})
