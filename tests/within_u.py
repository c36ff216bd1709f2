"""One realisation against its stated uncertainty, tested honestly (issue 31 point 8).

An expanded uncertainty U = k u with k for 95.45 % covers the truth at about 95 % of lines, so
one run of N lines has some line outside U with probability 1 - 0.95^N (51 % for 14 lines,
72 % for 25): "every line within U" is a statement about many runs, tested over many seeds by
bench/coverage.py and bench/lpm_coverage.py (docs/benchmarks.md), not about one.

A test of one realisation asserts instead a bound that a correct analysis meets at every one
of its M comparisons together with probability at least 1 - RISK (RISK = 0.001):

    |error| <= t(1 - RISK / (2 M), nu) u = [t(1 - RISK / (2 M), nu) / k] U

(Bonferroni over the M comparisons, valid whatever their correlation, e.g. the systematic
deviations a run shares between its lines; Student's t with each comparison's own degrees of
freedom nu, recovered from its coverage factor k = t(0.97725, nu), which is conservative for
rectangular type B components). For M = 50 and large nu that is 4.26 u = 2.13 U; for one
comparison 3.29 u = 1.65 U. An analysis whose U is too small by a factor of two or more
still fails it at some line of a typical run.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from scipy import optimize, stats

RISK = 1e-3  # a correct analysis fails a test of one realisation once in 1000 seeds at most
COVERAGE = 0.9545  # the coverage probability every U of the product is stated at


def dof_of_coverage_factor(k: float, coverage: float = COVERAGE) -> float:
    """The degrees of freedom nu with Student's t((1 + coverage) / 2, nu) = k (inf: normal)."""
    q = (1 + coverage) / 2
    if not k > stats.norm.ppf(q) * (1 + 1e-9):
        return math.inf
    return float(math.exp(optimize.brentq(lambda x: stats.t.ppf(q, math.exp(x)) - k, 0.0, 60.0)))


def bound_in_u(coverage_factors: Sequence[float] | np.ndarray, comparisons: int) -> np.ndarray:
    """Per comparison: the multiple of U within which a correct analysis keeps |error| at all
    `comparisons` together with probability >= 1 - RISK (module docstring)."""
    p = 1 - RISK / (2 * comparisons)
    out = []
    for k in np.asarray(coverage_factors, dtype=float).ravel():
        nu = dof_of_coverage_factor(float(k))
        z = stats.norm.ppf(p) if math.isinf(nu) else stats.t.ppf(p, nu)
        out.append(z / k)
    return np.array(out)


def assert_consistent_with_u(
    *checks: tuple[str, np.ndarray, np.ndarray, np.ndarray | float],
) -> None:
    """Each check (name, |error| or error, U, coverage factor k per line or one for all) within
    the bound of `bound_in_u` over all the checks' comparisons together; the message lists
    |error| / U per line."""
    total = sum(np.size(error) for _, error, _, _ in checks)
    for name, error, expanded, k in checks:
        e = np.abs(np.asarray(error, dtype=float))
        u = np.asarray(expanded, dtype=float)
        assert e.shape == u.shape and np.all(u > 0), (name, e.shape, u.shape)
        ks = np.broadcast_to(np.asarray(k, dtype=float), e.shape)
        limit = bound_in_u(ks, total).reshape(e.shape)
        ratio = e / u
        assert np.all(ratio <= limit), (
            f"{name}: |error| / U = {np.round(ratio, 2).tolist()}, beyond the bound "
            f"{np.round(limit, 2).tolist()} a correct analysis meets with probability "
            f"{1 - RISK} over {total} comparisons"
        )
