"""The bound tests of one realisation use (tests/within_u.py) is the one its docstring states:
met by a correct analysis with probability >= 0.999, missed by one whose U is half the truth."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from tests.within_u import RISK, assert_consistent_with_u, bound_in_u, dof_of_coverage_factor


@pytest.mark.parametrize("nu", [3.0, 8.0, 40.0])
def test_the_degrees_of_freedom_come_back_from_the_coverage_factor(nu):
    k = stats.t.ppf(0.97725, nu)
    assert dof_of_coverage_factor(k) == pytest.approx(nu, rel=1e-6)
    assert dof_of_coverage_factor(2.0) == np.inf  # at or below the normal's k: no t needed


def test_the_bound_for_one_and_for_fifty_comparisons_at_large_dof():
    assert bound_in_u([2.0], 1)[0] == pytest.approx(stats.norm.ppf(1 - RISK / 2) / 2, rel=1e-9)
    assert bound_in_u([2.0], 1)[0] == pytest.approx(1.645, abs=1e-3)
    assert bound_in_u([2.0], 50)[0] == pytest.approx(2.13, abs=0.01)
    few = bound_in_u([stats.t.ppf(0.97725, 4.0)], 50)[0]
    assert few > 3.0  # Student's tails with 4 dof: far beyond the normal's


def test_a_correct_analysis_passes_at_the_stated_rate_and_a_too_small_u_fails():
    rng = np.random.default_rng(31)
    m, trials = 28, 20000
    errors = rng.standard_normal((trials, m))  # u = 1, U = 2 per line
    limit = bound_in_u(np.full(m, 2.0), m)
    failed = np.any(np.abs(errors) / 2.0 > limit, axis=1).mean()
    assert failed <= RISK * 1.5  # <= 0.001 by construction, sampling noise allowed
    halved = np.any(np.abs(errors) / 1.0 > limit, axis=1).mean()  # U stated at u, not 2 u
    assert halved > 0.5
    assert_consistent_with_u(("magnitude", errors[0], np.full(m, 2.0), 2.0))
    with pytest.raises(AssertionError, match="magnitude: \\|error\\| / U"):
        assert_consistent_with_u(("magnitude", np.full(m, 2.0) * 2.2, np.full(m, 2.0), 2.0))
