"""Three-parameter sine fit at a known frequency (IEEE Std 1057, section 4.1.3.1).

x(i) ~ A cos(w t_i) + B sin(w t_i) + C, least squares. Returned as a peak-scaled complex
amplitude in the convention of dsp.spectral (a line a sin(w t + phi) gives a exp(j(phi - pi/2))),
so stepped-sine blocks feed the same estimators as multisine periods.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from fractions import Fraction

import numpy as np


def sine_fit(blocks: np.ndarray, frequency_hz: float, sample_rate_hz: float) -> np.ndarray:
    """Complex amplitude (V) of the sine at `frequency_hz` in each row of `blocks`."""
    blocks = np.atleast_2d(np.asarray(blocks, dtype=float))
    n = blocks.shape[-1]
    t = np.arange(n) / sample_rate_hz
    w = 2 * np.pi * frequency_hz
    design = np.column_stack([np.cos(w * t), np.sin(w * t), np.ones(n)])
    coefficients, *_ = np.linalg.lstsq(design, blocks.T, rcond=None)
    a, b = coefficients[0], coefficients[1]
    # a cos + b sin = Re((a - j b) e^{j w t}): the complex amplitude is a - j b
    return a - 1j * b


def integer_cycle_block(
    frequency_hz: float,
    sample_rate_hz: float,
    minimum_s: float,
    also_hz: tuple[float, ...] = (),
) -> int:
    """Shortest block (samples) of at least `minimum_s` holding a whole number of cycles of
    `frequency_hz` and of every frequency in `also_hz` (e.g. the mains, so that hum does not
    leak into the fit). Frequencies must be rational multiples of the sample rate."""
    fs = Fraction(sample_rate_hz).limit_denominator(10**7)
    samples = 1
    for f in (frequency_hz, *also_hz):
        ratio = Fraction(f).limit_denominator(10**7) / fs
        samples = math.lcm(samples, ratio.denominator)  # denominator samples hold whole cycles
    needed = math.ceil(minimum_s * sample_rate_hz / samples)
    return samples * max(needed, 1)


@dataclass(frozen=True)
class SteppedGrid:
    """A stepped sine's lines on one period's bins (Hz, samples): per line the actual
    frequency and the shortest block of whole cycles of it and of the mains."""

    sample_rate_hz: float
    period_samples: int
    nominal_frequencies_hz: tuple[float, ...]
    bins: tuple[int, ...]
    frequencies_hz: tuple[float, ...]
    block_samples: tuple[int, ...]


def block_compatible_grid(
    nominal_frequencies_hz: Sequence[float],
    sample_rate_hz: float,
    minimum_block_s: float,
    *,
    mains_hz: float = 50.0,
    mains_harmonics: int = 5,
    tolerance: float = 0.02,
    within_hz: tuple[float, float] | None = None,
    max_period_s: float = 100.0,
    step_s: float = 0.05,
) -> SteppedGrid:
    """The stepped sine's own best frequencies (issue 32 point 8): per line the bin within
    `tolerance` (relative) of its nominal frequency, inside `within_hz` (lo, hi) and off the
    first `mains_harmonics` mains harmonics, whose block (integer_cycle_block: whole cycles of
    the line and of the mains, at least `minimum_block_s`) is shortest, nearest the nominal
    frequency among equals; on the period (a multiple of `step_s` up to `max_period_s`) whose
    blocks sum shortest, the shortest such period. ValueError when no period gives every
    line a bin."""
    nominal = np.asarray([float(f) for f in nominal_frequencies_hz])
    if nominal.size == 0 or not np.all(np.isfinite(nominal) & (nominal > 0)):
        raise ValueError("frequencies: need at least one, each > 0 Hz")
    if not (sample_rate_hz > 0 and minimum_block_s > 0 and step_s > 0 and tolerance >= 0):
        raise ValueError("grid: sample rate, minimum block and step must be > 0, tolerance >= 0")
    fs = Fraction(sample_rate_hz).limit_denominator(10**7)
    mains = Fraction(mains_hz).limit_denominator(10**7)
    mains_samples = (mains / fs).denominator  # samples holding whole mains cycles
    low = nominal * (1 - tolerance)
    high = nominal * (1 + tolerance)
    if within_hz is not None:
        low = np.maximum(low, within_hz[0])
        high = np.minimum(high, within_hz[1])
    harmonics = [mains * h for h in range(1, mains_harmonics + 1)]
    best: tuple[tuple[int, float, int], SteppedGrid] | None = None
    for j in range(1, math.floor(max_period_s / step_s + 1e-9) + 1):
        n = round(j * step_s * sample_rate_hz)
        chosen = _cheapest_bins(
            nominal, low, high, n, fs, harmonics, mains_samples, minimum_block_s
        )
        if chosen is None:
            continue
        bins, blocks = chosen
        actual = [float(b * fs / n) for b in bins]
        cost = (sum(blocks), float(np.sum(np.abs(np.array(actual) / nominal - 1))), n)
        if best is None or cost < best[0]:
            best = (
                cost,
                SteppedGrid(
                    float(sample_rate_hz),
                    n,
                    tuple(nominal.tolist()),
                    tuple(bins),
                    tuple(actual),
                    tuple(blocks),
                ),
            )
    if best is None:
        raise ValueError(
            f"grid: no period up to {max_period_s:g} s puts every line within "
            f"{100 * tolerance:g} % of nominal off the mains harmonics"
        )
    return best[1]


def _cheapest_bins(
    nominal: np.ndarray,
    low: np.ndarray,
    high: np.ndarray,
    n: int,
    fs: Fraction,
    harmonics: list[Fraction],
    mains_samples: int,
    minimum_block_s: float,
) -> tuple[list[int], list[int]] | None:
    """Per line on a period of `n` samples: the bin with the shortest block (nearest nominal
    among equals) and that block; None when a line has no bin in its window."""
    resolution = float(fs) / n
    minimum = float(minimum_block_s * fs)
    on_mains = [
        int(b) for b in (h * n / fs for h in harmonics) if b.denominator == 1
    ]  # the bins exactly on a mains harmonic
    bins, blocks = [], []
    for f0, lo, hi in zip(nominal, low, high, strict=True):
        candidates = np.arange(
            max(1, math.ceil(lo / resolution - 1e-9)), math.floor(hi / resolution + 1e-9) + 1
        )
        candidates = candidates[~np.isin(candidates, on_mains)]
        if candidates.size == 0:
            return None
        cycles = n // np.gcd(candidates, n)  # samples holding whole cycles of the line
        group = np.lcm(cycles, mains_samples)
        block = group * np.maximum(np.ceil(minimum / group - 1e-9), 1).astype(np.int64)
        order = np.lexsort((np.abs(candidates * resolution - f0), block))
        bins.append(int(candidates[order[0]]))
        blocks.append(int(block[order[0]]))
    return bins, blocks
