"""Three-parameter sine fit at a known frequency (IEEE Std 1057, section 4.1.3.1).

x(i) ~ A cos(w t_i) + B sin(w t_i) + C, least squares. Returned as a peak-scaled complex
amplitude in the convention of dsp.spectral (a line a sin(w t + phi) gives a exp(j(phi - pi/2))),
so stepped-sine blocks feed the same estimators as multisine periods.
"""

from __future__ import annotations

import math
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
