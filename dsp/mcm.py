"""JCGM 101:2008 Monte Carlo propagation of one line's budget, and the clause 8 validation
of its GUM interval (issue 25 point 5; SPEC.md section 7).

The measurement model of a line is the GUM's additive one (dsp.uncertainty.combine): the
error of the relative magnitude (fraction) or of the phase (degrees) is the sum of type A and
every applying type B component, unit sensitivity coefficients. Each input gets the PDF
JCGM 101 6.4 assigns it:

- type A from L periods: scaled and shifted t with nu_A dof, scale u_A (6.4.9);
- rectangular, triangular, U-shaped (arcsine) on [-a, a] (6.4.2, 6.4.5, 6.4.6);
- normal with u = U/k, or a standard uncertainty u (6.4.7); a type B with finite dof is a
  scaled t with those dof, like type A;
- each component scaled by its frequency law at the line (dsp.uncertainty.Component).

The coverage interval is the probabilistically symmetric one (7.7.1) and the shortest one
(7.7.2). Clause 8: the GUM interval y +- U_p is validated when both its end points lie within
delta of the Monte Carlo interval's, delta half a unit in the last of the `digits` significant
digits of u(y) (8.2). The Monte Carlo end points are themselves estimates: their standard
deviation over repeated runs (the order statistic's, sqrt(p(1-p)/M)/g with g the density at the
end point, read off the sorted draws) is the resolution of the check. A difference within delta
plus three times that resolution cannot be told from noise: "validated within the Monte Carlo's
resolution" (the GUM interval stands), never "NOT validated" on noise alone. Pure numpy, no I/O.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from dsp.uncertainty import Budget, Combined, Component, Distribution, Quantity, combine

__all__ = [
    "McmLine",
    "endpoint_resolution",
    "numerical_tolerance",
    "propagate",
    "validate_line",
    "validate_lines",
]

DEFAULT_TRIALS = 1_000_000  # JCGM 101 7.2.2: 10^6 for a 95 % interval
_CHUNK = 200_000  # draws summed per block (bounded memory)
# a clause 8 difference beyond delta but within this many standard deviations of the Monte Carlo
# end points is noise (both end points of one run beyond it by chance: ~3e-4)
RESOLUTION_FACTOR = 3.0


def numerical_tolerance(standard_uncertainty: float, digits: int = 2) -> float:
    """delta = 1/2 10^l with u(y) written as c 10^l, c an integer of `digits` digits
    (JCGM 101 7.9.2); in the unit of u."""
    if not (math.isfinite(standard_uncertainty) and standard_uncertainty > 0):
        raise ValueError(
            f"numerical tolerance: u must be finite and > 0, got {standard_uncertainty}"
        )
    if digits < 1:
        raise ValueError(f"numerical tolerance: digits must be >= 1, got {digits}")
    exponent = math.floor(math.log10(standard_uncertainty)) - (digits - 1)
    return 0.5 * 10.0**exponent


def _draw(
    rng: np.random.Generator, distribution: Distribution, u: float, a: float, dof: float, n: int
) -> np.ndarray:
    """n draws of one input's error: u is its standard uncertainty, a its half-width."""
    if math.isfinite(dof) and distribution in (Distribution.NORMAL, Distribution.STANDARD):
        return u * rng.standard_t(dof, n)
    match distribution:
        case Distribution.RECTANGULAR:
            return rng.uniform(-a, a, n)
        case Distribution.TRIANGULAR:
            return rng.triangular(-a, 0.0, a, n)
        case Distribution.U_SHAPED:
            return a * np.sin(rng.uniform(0.0, 2.0 * math.pi, n))
        case _:
            return rng.normal(0.0, u, n)


def _inputs(
    type_a: float, type_a_dof: float, budget: Budget, frequency_hz: float, quantity: Quantity
) -> list[tuple[Distribution, float, float, float]]:
    """(distribution, u, half-width, dof) of every input at the line; type A first."""
    out = [(Distribution.STANDARD, type_a, math.nan, type_a_dof)]
    for c in budget.at(frequency_hz, quantity):
        out.append(_input(c, frequency_hz))
    return out


def _input(c: Component, frequency_hz: float) -> tuple[Distribution, float, float, float]:
    scale = c.scale_at(frequency_hz)
    return (c.distribution, c.standard_uncertainty * scale, c.value * scale, c.dof)


def propagate(
    type_a: float,
    type_a_dof: float,
    budget: Budget,
    frequency_hz: float,
    quantity: Quantity = Quantity.MAGNITUDE,
    *,
    trials: int = DEFAULT_TRIALS,
    seed: int = 0,
) -> np.ndarray:
    """`trials` draws of the line's error (relative or degrees), sorted (JCGM 101 7.5)."""
    if not (math.isfinite(type_a) and type_a >= 0):
        raise ValueError(f"mcm: type_a must be finite and >= 0, got {type_a!r}")
    if not type_a_dof > 0:
        raise ValueError(f"mcm: type_a_dof must be > 0 (inf allowed), got {type_a_dof!r}")
    if not 1000 <= trials <= 20_000_000:
        raise ValueError(f"mcm: trials must be between 1000 and 2e7, got {trials}")
    rng = np.random.default_rng(seed)
    inputs = _inputs(type_a, type_a_dof, budget, frequency_hz, quantity)
    out = np.empty(trials)
    for start in range(0, trials, _CHUNK):
        n = min(_CHUNK, trials - start)
        block = np.zeros(n)
        for distribution, u, a, dof in inputs:
            if u > 0:
                block += _draw(rng, distribution, u, a, dof, n)
        out[start : start + n] = block
    out.sort()
    return out


def _symmetric(sorted_draws: np.ndarray, p: float) -> tuple[float, float]:
    """Probabilistically symmetric 100p % interval (JCGM 101 7.7.1)."""
    m = sorted_draws.size
    q = int(p * m + 0.5)
    r = (m - q) // 2
    return float(sorted_draws[max(r - 1, 0)]), float(sorted_draws[min(r + q - 1, m - 1)])


def endpoint_resolution(sorted_draws: np.ndarray, p: float) -> float:
    """The standard deviation of the symmetric interval's end points over repeated Monte Carlo
    runs of as many trials (the larger of the two): sqrt(q(1-q)/M) / g(x_q) for q = (1-p)/2 and
    1-q, the density g estimated by the spacing of the sorted draws about the end point
    (h = sqrt(M) order statistics each side). In the draws' unit."""
    m = sorted_draws.size
    q = 0.5 * (1.0 - p)
    h = max(int(math.sqrt(m)), 1)
    worst = 0.0
    for tail in (q, 1.0 - q):
        r = min(max(int(tail * m), h), m - 1 - h)
        spacing = float(sorted_draws[r + h] - sorted_draws[r - h])  # ~ 2h / (M g)
        worst = max(worst, math.sqrt(tail * (1.0 - tail) / m) * spacing * m / (2 * h))
    return worst


def _shortest(sorted_draws: np.ndarray, p: float) -> tuple[float, float]:
    """Shortest 100p % interval (JCGM 101 7.7.2)."""
    m = sorted_draws.size
    q = int(p * m + 0.5)
    widths = sorted_draws[q:] - sorted_draws[: m - q]
    r = int(np.argmin(widths))
    return float(sorted_draws[r]), float(sorted_draws[r + q])


@dataclass(frozen=True)
class McmLine:
    """One line's Monte Carlo result and the clause 8 check of its GUM interval; all values
    in the quantity's unit (relative for magnitude, degrees for phase), about the estimate 0."""

    frequency_hz: float
    quantity: str
    trials: int
    probability: float
    mean: float
    standard: float  # u(y) of the draws
    low: float  # probabilistically symmetric interval
    high: float
    shortest_low: float
    shortest_high: float
    gum_low: float  # -U_p
    gum_high: float  # +U_p
    tolerance: float  # delta (JCGM 101 8.2)
    d_low: float
    d_high: float
    validated: bool  # within delta, or within delta + 3 x the Monte Carlo's own resolution
    resolution: float = 0.0  # standard deviation of the Monte Carlo end points (same unit)
    within_resolution: bool = False  # validated only allowing for that resolution

    @property
    def half_width(self) -> float:
        """Half the symmetric interval's width, the Monte Carlo counterpart of U."""
        return 0.5 * (self.high - self.low)

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe dict (stored per line)."""
        return asdict(self)

    def summary(self) -> str:
        """One line: both intervals and the verdict, in % (magnitude) or degrees (phase)."""
        scale, unit = (100.0, " %") if self.quantity == Quantity.MAGNITUDE.value else (1.0, " deg")
        if self.within_resolution:
            verdict = (
                "validated within the Monte Carlo's resolution "
                f"(end points +-{scale * self.resolution:.2g}{unit})"
            )
        elif self.validated:
            verdict = "validated"
        else:
            verdict = "NOT validated: the MCM interval is stated"
        return (
            f"{self.frequency_hz:g} Hz {self.quantity}: GUM +-{scale * self.gum_high:.4g}{unit}, "
            f"MCM [{scale * self.low:.4g}, {scale * self.high:.4g}]{unit} "
            f"(delta {scale * self.tolerance:.2g}{unit}): {verdict} (JCGM 101 clause 8)"
        )


def validate_line(
    type_a: float,
    type_a_dof: float,
    budget: Budget,
    frequency_hz: float,
    gum: Combined,
    quantity: Quantity = Quantity.MAGNITUDE,
    *,
    trials: int = DEFAULT_TRIALS,
    seed: int = 0,
    digits: int = 2,
) -> McmLine:
    """Propagate the line's budget and check the GUM statement `gum` (same inputs, from
    dsp.uncertainty.combine) against it at gum.coverage_probability (JCGM 101 8.2)."""
    if not (math.isfinite(gum.expanded) and gum.expanded > 0):
        raise ValueError("mcm: the GUM statement has no finite expanded uncertainty")
    p = gum.coverage_probability
    draws = propagate(type_a, type_a_dof, budget, frequency_hz, quantity, trials=trials, seed=seed)
    low, high = _symmetric(draws, p)
    s_low, s_high = _shortest(draws, p)
    delta = numerical_tolerance(gum.standard, digits)
    d_low = abs(-gum.expanded - low)
    d_high = abs(gum.expanded - high)
    resolution = endpoint_resolution(draws, p)
    strict = d_low <= delta and d_high <= delta
    loose = max(d_low, d_high) <= delta + RESOLUTION_FACTOR * resolution
    return McmLine(
        frequency_hz=float(frequency_hz),
        quantity=Quantity(quantity).value,
        trials=trials,
        probability=p,
        mean=float(draws.mean()),
        standard=float(draws.std(ddof=1)),
        low=low,
        high=high,
        shortest_low=s_low,
        shortest_high=s_high,
        gum_low=-gum.expanded,
        gum_high=gum.expanded,
        tolerance=delta,
        d_low=d_low,
        d_high=d_high,
        validated=bool(strict or loose),
        resolution=resolution,
        within_resolution=bool(loose and not strict),
    )


def validate_lines(
    frequencies_hz: Sequence[float],
    type_a: Sequence[float],
    type_a_dof: Sequence[float] | float,
    budget: Budget,
    quantity: Quantity = Quantity.MAGNITUDE,
    *,
    probability: float = 0.9545,
    trials: int = DEFAULT_TRIALS,
    seed: int = 0,
) -> list[McmLine]:
    """`validate_line` at every line (type A relative or in degrees, per line; dof per line
    or one for all), each against the GUM statement dsp.uncertainty.combine gives; lines
    whose type A is not finite are skipped (no GUM statement to check). For the run record:
    one McmLine per line, stored with its `to_dict`."""
    dofs = np.broadcast_to(np.asarray(type_a_dof, dtype=float), (len(frequencies_hz),))
    out = []
    for k, (f, u_a, dof) in enumerate(zip(frequencies_hz, type_a, dofs, strict=True)):
        if not math.isfinite(u_a):
            continue
        gum = combine(float(u_a), float(dof), budget, float(f), quantity, probability=probability)
        out.append(
            validate_line(
                float(u_a),
                float(dof),
                budget,
                float(f),
                gum,
                quantity,
                trials=trials,
                seed=seed + k,
            )
        )
    return out
