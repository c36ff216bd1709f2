"""dsp.quantiles against scipy.special (which the tests may import): the distribution
functions that replaced it on a run's path give the same numbers (issue 34)."""

from __future__ import annotations

import math

import pytest
from scipy import special

from dsp import quantiles
from dsp.uncertainty import coverage_factor

PROBABILITIES = (0.6, 0.6827, 0.8, 0.9, 0.95, 0.9545, 0.975, 0.97725, 0.99, 0.995, 0.9973, 0.999)
DOFS = (0.3, 0.5, 1, 1.5, 2, 2.5, 3, 4.7, 9, 10, 19.99, 20, 20.01, 30, 50, 99.5, 1e3, 5e3)
LARGE_DOFS = (9999.0, 1e4, 2e4, 1e5, 1e6, 1e8, 1e12, 1e20)


@pytest.mark.parametrize("nu", DOFS + LARGE_DOFS)
def test_t_quantile_is_scipys(nu: float) -> None:
    for q in PROBABILITIES:
        assert quantiles.t_quantile(nu, q) == pytest.approx(
            float(special.stdtrit(nu, q)), rel=1e-13
        )
        assert quantiles.t_quantile(nu, 1 - q) == pytest.approx(
            float(special.stdtrit(nu, 1 - q)), rel=1e-13
        )


def test_t_quantile_near_the_median_is_exact_where_known() -> None:
    """Near q = 1/2 scipy's stdtrit loses digits (3e-13 relative); the closed forms for 1 and
    2 degrees of freedom are the reference there."""
    for q in (0.5001, 0.501, 0.55):
        assert quantiles.t_quantile(1, q) == pytest.approx(math.tan(math.pi * (q - 0.5)), rel=1e-14)
        two = (2 * q - 1) * math.sqrt(2 / (4 * q * (1 - q)))
        assert quantiles.t_quantile(2, q) == pytest.approx(two, rel=1e-14)
    assert quantiles.t_quantile(7.5, 0.5) == 0.0


def test_t_tail_is_scipys() -> None:
    for nu in (1, 2.5, 10, 30, 300):
        for t in (0.01, 0.5, 1, 2, 5, 20):
            assert quantiles.t_tail(nu, t) == pytest.approx(float(special.stdtr(nu, -t)), rel=1e-12)


def test_coverage_factor_is_what_it_was_with_scipy() -> None:
    for nu in (2, 7.3, 50, math.inf):
        expected = float(special.ndtri(0.97725) if math.isinf(nu) else special.stdtrit(nu, 0.97725))
        assert coverage_factor(nu) == pytest.approx(expected, rel=1e-13)


def test_normal_f2_and_chi2_are_scipys() -> None:
    for q in (1e-10, 1e-3, 0.1, 0.5, 0.9, 0.97725, 1 - 1e-10):
        assert quantiles.normal_quantile(q) == pytest.approx(float(special.ndtri(q)), rel=1e-14)
    for d2 in (2, 4, 6, 18, 98, 1000, 1e5):
        for p in (0.0, 0.5, 0.95, 0.999, 1 - 1e-9):
            expected = float(special.fdtri(2, d2, p))
            assert quantiles.f2_quantile(d2, p) == pytest.approx(expected, rel=1e-13, abs=1e-300)
    for k in (2, 4, 6):
        for x in (0.0, 0.01, 1, 3, 30, 700):
            assert quantiles.chi2_sf_even(k, x) == pytest.approx(
                float(special.chdtrc(k, x)), rel=1e-13
            )


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (lambda: quantiles.t_quantile(0, 0.9), "nu must be > 0"),
        (lambda: quantiles.t_quantile(3, 1.0), "q must be in"),
        (lambda: quantiles.normal_quantile(0.0), "q must be in"),
        (lambda: quantiles.f2_quantile(-1, 0.5), "d2 must be > 0"),
        (lambda: quantiles.chi2_sf_even(3, 1.0), "k must be even"),
    ],
)
def test_bad_arguments_are_refused_by_name(call, message) -> None:  # type: ignore[no-untyped-def]
    with pytest.raises(ValueError, match=message):
        call()


def test_the_lpm_nonlinearity_threshold_is_scipys_per_line() -> None:
    """dsp.lpm's F threshold: closed form for two periods (d2 per line), scipy beyond."""
    import numpy as np

    from dsp.quantiles import f_quantiles

    d2 = np.array([2.0, 4.0, 10.0, 37.5, 100.0, 1000.0])
    for d1 in (2, 4, 8):
        np.testing.assert_allclose(
            f_quantiles(d1, d2, 0.99), special.fdtri(d1, d2, 0.99), rtol=1e-13
        )


def test_median_is_numpys_to_the_bit() -> None:
    import numpy as np

    rng = np.random.default_rng(34)
    for size in (1, 2, 3, 10, 11, 1000, 1001):
        values = rng.standard_normal(size) * 10.0 ** rng.integers(-5, 5)
        assert quantiles.median(values) == float(np.median(values))
    assert math.isnan(quantiles.median(np.array([1.0, np.nan, 3.0])))
    assert math.isnan(float(np.median(np.array([1.0, np.nan, 3.0]))))
    with pytest.raises(ValueError, match="no values"):
        quantiles.median(np.array([]))
