"""Summaries over embryos (inverse.summaries): the 95 % interval of the mean holds its coverage
with few embryos, the bootstrap refuses too few resamples, and the weighted mean is over the
embryos that have an error."""
import numpy as np
import pytest

from morphoshell.inverse.summaries import MIN_BOOTSTRAP, summarise


def test_the_interval_of_the_mean_holds_its_coverage_with_few_embryos():
    """User audit: the percentile bootstrap's "95 %" interval held the mean in 50 % of tables
    of 2 embryos, 84 % of 5 (for n = 2 it is [min, max] of the two).  Student's t interval is
    exact for normal scatter: over 2000 seeded tables its coverage lies within 0.02 of 0.95,
    four Monte-Carlo standard errors (√(0.95 · 0.05/2000) = 0.005)."""
    for n in (2, 3, 5):
        rng = np.random.default_rng([5, n])
        hits = 0
        for _ in range(2000):
            lo, hi = summarise(rng.normal(0.05, 0.13, n), bootstrap=0).interval
            hits += lo <= 0.05 <= hi
        assert abs(hits / 2000 - 0.95) <= 0.02, (n, hits)


def test_two_embryos_get_an_interval_wider_than_their_range():
    s = summarise([0.0, 1.0], bootstrap=MIN_BOOTSTRAP)
    assert s.interval == pytest.approx((0.5 - 12.706 * 0.5, 0.5 + 12.706 * 0.5), rel=1e-4)
    assert s.bootstrap_interval == (0.0, 1.0)         # (the bootstrap's, for comparison)
    assert s.to_dict()["interval_method"] == "student_t"


@pytest.mark.parametrize("bootstrap", [1, MIN_BOOTSTRAP - 1])
def test_too_few_resamples_are_refused(bootstrap):
    """One resample gave a "95 %" interval of zero width; the 2.5 % and 97.5 % quantiles need
    at least 40 resamples (one on either side)."""
    with pytest.raises(ValueError, match="too few resamples"):
        summarise([0.1, 0.2, 0.3], bootstrap=bootstrap)
    assert summarise([0.1, 0.2, 0.3], bootstrap=0).bootstrap_interval is None


def test_the_weighted_mean_is_over_the_values_with_errors():
    """User audit: one missing error removed the weighted mean altogether (and its JSON keys).
    Now it is over the values with an error, says how many, and is null without any."""
    s = summarise([1.0, 3.0, 10.0], [1.0, 1.0, None], bootstrap=0)
    assert (s.weighted_mean, s.weighted_n) == (2.0, 2)
    assert s.weighted_error == pytest.approx(1 / np.sqrt(2))
    none = summarise([1.0, 3.0], [None, None], bootstrap=0).to_dict()
    assert none["weighted_mean"] is None and none["weighted_n"] == 0
    assert set(none) == set(s.to_dict())


def test_the_t_quantile_is_scipy_stats_one_to_the_bit_without_importing_it():
    """t_quantile takes scipy.special.stdtrit, not scipy.stats' t.ppf: the same number (t.ppf
    calls it; compared exactly, 2..500 embryos and the audit's 4.302652729749462 for 3), and
    a fresh process does not import scipy.stats (0.35-0.6 s of `estimate`, audit 18 F4)."""
    import subprocess
    import sys

    from scipy.stats import t

    from morphoshell.inverse.summaries import t_quantile
    assert t_quantile(3) == 4.302652729749462
    assert [t_quantile(n) for n in range(2, 501)] == [float(t.ppf(0.975, n - 1))
                                                       for n in range(2, 501)]
    code = ("import sys; from morphoshell.inverse.summaries import summarise; "
            "summarise([0.1, 0.2, 0.4], bootstrap=0); print('scipy.stats' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True)
    assert out.stdout.strip().splitlines()[-1] == "False"
