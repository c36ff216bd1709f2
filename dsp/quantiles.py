"""The few distribution functions the estimators and the budget need, without scipy.special.

Importing scipy.special costs about twice `import numpy` (scipy 1.17 builds its array-API
wrappers and parses docstrings at import), more than a warm run's whole start-up budget
(issue 34). These are what the code uses, to double precision:

    normal_quantile(q)          scipy.special.ndtri(q)       statistics.NormalDist (AS241)
    t_quantile(nu, q)           scipy.special.stdtrit(nu, q) Newton on Student's t tail
    f2_quantile(d2, p)          scipy.special.fdtri(2, d2, p) closed form of F(2, d2)
    chi2_sf_even(k, x)          scipy.special.chdtrc(k, x)   closed form, k even
    median(values)              np.median(values)            without importing numpy.ma

tests/dsp/test_quantiles.py compares each with scipy.special over the ranges used, to 1e-13.
Student's t tail is the regularised incomplete beta function I_x(nu/2, 1/2), x = nu/(nu+t^2),
by its continued fraction (modified Lentz); log B(nu/2, 1/2) by Stirling's series for large
nu, where math.lgamma's difference would cancel.
"""

from __future__ import annotations

import math
from statistics import NormalDist

import numpy as np

_EPS = 2.220446049250313e-16
_TINY = 1e-300
_MAX_TERMS = 100_000  # continued-fraction terms; about 3 sqrt(a) are needed for large a
_STANDARD_NORMAL = NormalDist()
# degrees of freedom from which the quantile's expansion in 1/nu is used: its next term is
# below 1e-16 relative there, while the continued fraction's rounding grows with nu
_ASYMPTOTIC_NU = 1e4


def normal_quantile(q: float) -> float:
    """The standard normal quantile at probability `q` in (0, 1)."""
    if not 0.0 < q < 1.0:
        raise ValueError(f"normal_quantile: q must be in (0, 1), got {q!r}")
    return _STANDARD_NORMAL.inv_cdf(q)


def _stirling_tail(z: float) -> float:
    """log Gamma(z) minus its leading Stirling terms: sum of B_2k / (2k (2k-1) z^(2k-1))."""
    r = 1.0 / (z * z)
    return (
        1.0 / 12.0 - r * (1.0 / 360.0 - r * (1.0 / 1260.0 - r * (1.0 / 1680.0 - r / 1188.0)))
    ) / z


def _log_beta_half(a: float) -> float:
    """log B(a, 1/2) = log Gamma(a) + log Gamma(1/2) - log Gamma(a + 1/2), accurate for large
    `a` too (the two lgamma's differ by 1/2 log a while each grows as a log a)."""
    if a < 20.0:
        return math.lgamma(a) + math.lgamma(0.5) - math.lgamma(a + 0.5)
    # log Gamma(a + 1/2) - log Gamma(a) from Stirling's series, the large terms combined
    difference = (
        a * math.log1p(0.5 / a) + 0.5 * math.log(a) - 0.5 + _stirling_tail(a + 0.5)
    ) - _stirling_tail(a)
    return 0.5 * math.log(math.pi) - difference


def _beta_fraction(a: float, b: float, x: float) -> float:
    """The continued fraction of I_x(a, b) (Numerical Recipes' betacf, modified Lentz)."""
    qab, qap, qam = a + b, a + 1.0, a - 1.0
    c, d = 1.0, 1.0 - qab * x / qap
    d = 1.0 / (d if abs(d) > _TINY else _TINY)
    h = d
    for m in range(1, _MAX_TERMS):
        m2 = 2 * m
        aa = m * (b - m) * x / ((qam + m2) * (a + m2))
        d = 1.0 + aa * d
        d = 1.0 / (d if abs(d) > _TINY else _TINY)
        c = 1.0 + aa / c
        c = c if abs(c) > _TINY else _TINY
        h *= d * c
        aa = -(a + m) * (qab + m) * x / ((a + m2) * (qap + m2))
        d = 1.0 + aa * d
        d = 1.0 / (d if abs(d) > _TINY else _TINY)
        c = 1.0 + aa / c
        c = c if abs(c) > _TINY else _TINY
        delta = d * c
        h *= delta
        if abs(delta - 1.0) < _EPS:
            return h
    raise ArithmeticError(f"incomplete beta: no convergence at a={a}, b={b}, x={x}")


def _t_excess(nu: float, t: float, q: float) -> float:
    """P(T > t) - (1 - q) for Student's t, t > 0, q in (1/2, 1), each side computed without
    cancellation: the tail itself when its continued fraction converges, else the central
    probability P(|T| < t) (small for small t) against 2q - 1 (exact in floating point)."""
    a = 0.5 * nu
    s = t * t / nu
    # x = nu / (nu + t^2) = 1 / (1 + s), 1 - x = s / (1 + s); logs without cancellation
    log_x, log_1mx = -math.log1p(s), math.log(s) - math.log1p(s)
    x, one_minus_x = 1.0 / (1.0 + s), s / (1.0 + s)
    front = math.exp(a * log_x + 0.5 * log_1mx - _log_beta_half(a))
    if x < (a + 1.0) / (a + 2.5):  # I_x(a, 1/2) by its fraction: the tail is I_x / 2
        return 0.5 * front / a * _beta_fraction(a, 0.5, x) - (1.0 - q)
    central = front / 0.5 * _beta_fraction(0.5, a, one_minus_x)  # I_{1-x}(1/2, a)
    return 0.5 * ((2.0 * q - 1.0) - central)


def t_tail(nu: float, t: float) -> float:
    """P(T > t) for Student's t with `nu` > 0 degrees of freedom, t >= 0."""
    return 0.5 if t == 0.0 else _t_excess(nu, t, 0.75) + 0.25


def _t_density(nu: float, t: float) -> float:
    """Student's t density at t."""
    return math.exp(
        -0.5 * (nu + 1.0) * math.log1p(t * t / nu) - _log_beta_half(0.5 * nu)
    ) / math.sqrt(nu)


def t_quantile(nu: float, q: float) -> float:
    """Student's t quantile at probability `q` in (0, 1) with `nu` > 0 degrees of freedom
    (infinite: the normal quantile)."""
    if not 0.0 < q < 1.0:
        raise ValueError(f"t_quantile: q must be in (0, 1), got {q!r}")
    if not nu > 0.0:
        raise ValueError(f"t_quantile: nu must be > 0, got {nu!r}")
    if math.isinf(nu):
        return normal_quantile(q)
    if q < 0.5:
        return -t_quantile(nu, 1.0 - q)
    if q == 0.5:
        return 0.0
    z = normal_quantile(q)
    if nu >= _ASYMPTOTIC_NU:  # Abramowitz & Stegun 26.7.5: exact to rounding this far out
        z2 = z * z
        g1 = (z2 + 1.0) * z / 4.0
        g2 = ((5.0 * z2 + 16.0) * z2 + 3.0) * z / 96.0
        g3 = (((3.0 * z2 + 19.0) * z2 + 17.0) * z2 - 15.0) * z / 384.0
        g4 = ((((79.0 * z2 + 776.0) * z2 + 1482.0) * z2 - 1920.0) * z2 - 945.0) * z / 92160.0
        return z + (g1 + (g2 + (g3 + g4 / nu) / nu) / nu) / nu
    # bracket [low, high] with tail(low) > 1 - q > tail(high), Newton inside it
    low, high = 0.0, max(1.0, z)
    while _t_excess(nu, high, q) > 0.0:
        low, high = high, 2.0 * high
        if high > 1e300:
            return math.inf
    t = 0.5 * (low + high)
    for _ in range(200):
        error = _t_excess(nu, t, q)
        if error > 0.0:
            low = t
        else:
            high = t
        step = error / _t_density(nu, t)
        candidate = t + step
        if not low < candidate < high:
            candidate = 0.5 * (low + high)
        if abs(candidate - t) <= 2.0 * _EPS * abs(candidate) or high - low <= _EPS * high:
            return candidate
        t = candidate
    return t


def f2_quantile(d2: float, p: float) -> float:
    """The F(2, d2) quantile at probability `p` in [0, 1): its CDF is 1 - (1 + 2x/d2)^(-d2/2),
    so x = d2/2 ((1 - p)^(-2/d2) - 1)."""
    if not 0.0 <= p < 1.0:
        raise ValueError(f"f2_quantile: p must be in [0, 1), got {p!r}")
    if not d2 > 0.0:
        raise ValueError(f"f2_quantile: d2 must be > 0, got {d2!r}")
    return 0.5 * d2 * math.expm1(-2.0 / d2 * math.log1p(-p))


def chi2_sf_even(k: int, x: float) -> float:
    """P(X > x) for chi-square with an even number `k` of degrees of freedom:
    exp(-x/2) sum_{i < k/2} (x/2)^i / i!."""
    if k <= 0 or k % 2:
        raise ValueError(f"chi2_sf_even: k must be even and positive, got {k!r}")
    if x <= 0.0:
        return 1.0
    half = 0.5 * x
    term, total = 1.0, 1.0
    for i in range(1, k // 2):
        term *= half / i
        total += term
    return math.exp(-half) * total


def median(values: np.ndarray) -> float:
    """np.median of a 1-D array, to the same float (the middle value, or the mean of the two
    middle ones; NaN when any value is NaN), without np.median's import of numpy.ma (about
    40 ms of a run's start-up with numpy 2.4, issue 34)."""
    data = np.ravel(np.asarray(values, dtype=float))
    if data.size == 0:
        raise ValueError("median: no values")
    if np.isnan(data).any():
        return math.nan
    ordered = np.sort(data)
    half = data.size // 2
    if data.size % 2:
        return float(ordered[half])
    return float(np.mean(ordered[half - 1 : half + 1]))


def has_duplicates(values: np.ndarray) -> bool:
    """Whether two of `values` are equal (sorted neighbours; np.unique would import numpy.ma,
    about 40 ms of a run's start-up with numpy 2.4, issue 34)."""
    ordered = np.sort(np.ravel(values))
    return bool(np.any(ordered[1:] == ordered[:-1]))


def f_quantiles(d1: int, d2: np.ndarray, p: float) -> np.ndarray:
    """The F(d1, d2) quantiles at `p` (d2 an array): in closed form for d1 = 2 (the CDF is
    1 - (1 + 2x/d2)^(-d2/2)), else from scipy.special (imported here: it costs twice
    `import numpy`, issue 34)."""
    if d1 == 2:
        d2 = np.asarray(d2, dtype=float)
        return 0.5 * d2 * np.expm1(-2.0 / d2 * np.log1p(-p))
    from scipy import special

    return np.asarray(special.fdtri(d1, d2, p), dtype=float)
