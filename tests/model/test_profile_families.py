"""The packaged profile families' formulas and their parameters' checks."""
import numpy as np
import pytest

from morphoshell import Problem
from morphoshell.cli import main
from morphoshell.io.problem_files import example_path
from morphoshell.model.profiles import (Profiles, check_curvature, curvature_limit,
                                       get_family)


def test_central_growth_is_a_gaussian_growth_of_a_flat_disc():
    """f_s0 = f_phi0 = 1 + G exp(-(s/w)^2), no intrinsic curvature; stress-free at G = 0."""
    p = Problem("central_growth", {"G": 0.3, "w": 0.4}, h=0.02, geometry="disc")
    s = np.array([0.0, 0.4, 0.8])
    prof = p.profiles(s)
    expected = 1 + 0.3 * np.exp(-(s / 0.4) ** 2)
    np.testing.assert_allclose(prof["f_s0"], expected, rtol=1e-15)
    np.testing.assert_allclose(prof["f_phi0"], expected, rtol=1e-15)
    assert np.all(prof["kappa_s0"] == 0) and np.all(prof["kappa_phi0"] == 0)
    assert get_family("central_growth").neutral == {"G": 0.0}


@pytest.mark.parametrize("params, match", [
    ({"G": -0.95}, r"parameter G = -0.95 must lie in \[-0.9, 9\] \(intrinsic stretch 1 \+ G"),
    ({"w": 0.0}, r"parameter w = 0.0 must lie in \(0, 6.28319\] \(width of the grown region"),
    ({"w": 7.0}, r"parameter w = 7.0 must lie in \(0, 6.28319\] \(width of the grown region"),
])
def test_central_growth_names_a_bad_parameter(params, match):
    with pytest.raises(ValueError, match=match):
        Problem("central_growth", params, h=0.02, geometry="disc")


def test_the_blister_example_refuses_a_bad_growth_before_any_work(capsys):
    assert main(["solve", str(example_path("blister")), "--set", "G=-2"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "G = -2" in err[0]


def test_every_packaged_family_gives_each_parameter_a_unit():
    """A fit prints each value with its unit (FitResult.unit): the families say which, and a
    unit of a name that is no parameter is refused when the family is registered."""
    from morphoshell.model.profiles import FAMILIES, ProfileFamily, register_family

    for name in ("uniform", "anisotropic", "local_relaxation", "central_growth", "volvox"):
        family = FAMILIES[name]
        assert set(family.units) == set(family.parameters), name
        assert set(family.units.values()) <= {"R", "1/R", "1"}, name
    uniform = FAMILIES["uniform"]
    with pytest.raises(ValueError, match=r"gives units of \['kk'\], which are not among"):
        register_family(ProfileFamily("stray_units", ("k",), {"k": 0.0}, uniform.build,
                                      units={"kk": "1/R"}))
    assert "stray_units" not in FAMILIES


def test_the_curvature_limit_is_where_an_unstretched_sheets_wedge_closes():
    """|k| < 2/h, checked here, in the lowest layer, for the inversions, the asymptotics and the
    command line alike (audit 26 F2: mechanics could not import it from inverse): the k at
    which eta of a uniform, unstretched sheet reaches 1, which a Problem refuses."""
    h = 0.1
    assert Profiles(1.0, 1.0, curvature_limit(h), curvature_limit(h)).eta(h) == 1.0
    check_curvature((-19.999, 19.999), h, "k_range", "the shell")
    for k in (20.0, -20.0):
        with pytest.raises(ValueError, match=rf"k_range: k = {k:g} is beyond the curvature of "
                                             rf"the shell \(h = H/R = 0.1\): \|k\| must stay "
                                             rf"below 2/h = 20.*search a range within \(-20, 20\)"):
            check_curvature((0.0, k), h, "k_range", "the shell")
    with pytest.raises(ValueError, match="abs.eta. = 1 >= 1.*wedge closes"):   # the same bound
        Problem("uniform", {"k": 20.0}, h=h)
    Problem("uniform", {"k": 19.999}, h=h)
