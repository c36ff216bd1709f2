"""Fades of the multisine (SPEC.md section 4): a raised-cosine envelope over whole periods so
the output starts and ends at exactly 0 V, and a fade-out a few cycles of the lowest line long.
Gains are dimensionless; lengths in samples, frequencies in Hz, times in s."""

from __future__ import annotations

import math

import numpy as np

__all__ = [
    "FADE_OUT_CYCLES",
    "FADE_OUT_MIN_S",
    "fade_envelope",
    "fade_out_envelope",
    "fade_out_samples",
]


def fade_envelope(period_samples: int, periods: int, direction: str) -> np.ndarray:
    """Raised-cosine gain over whole periods (SPEC s.4): 'in' rises 0 -> 1, 'out' falls 1 -> 0.

    The fade-out's last sample is exactly 0.0, so the output ends at exactly 0 V.
    """
    if periods < 1 or period_samples < 2:
        raise ValueError("fade: needs at least one period of at least 2 samples")
    n = period_samples * periods
    ramp = 0.5 * (1.0 - np.cos(np.pi * np.arange(n) / (n - 1)))
    if direction == "in":
        return ramp
    if direction == "out":
        return ramp[::-1].copy()
    raise ValueError(f"fade: direction must be 'in' or 'out', got {direction!r}")


FADE_OUT_CYCLES = 4  # cycles of the lowest line a fade-out lasts at least
FADE_OUT_MIN_S = 0.05  # and at least this (s): the exciter's suspension is far faster


def fade_out_samples(lowest_frequency_hz: float, sample_rate_hz: float) -> int:
    """Length in samples of a fade-out (SPEC s.4, issue 14): FADE_OUT_CYCLES cycles of the
    lowest line, at least FADE_OUT_MIN_S. A raised cosine over four cycles puts its spectral
    splatter within about a quarter of the lowest line's frequency around each line, and the
    table's velocity and displacement return to rest with it (its integrals are smooth)."""
    if not (lowest_frequency_hz > 0 and sample_rate_hz > 0):
        raise ValueError("fade-out: frequency and sample rate must be > 0")
    seconds = max(FADE_OUT_CYCLES / lowest_frequency_hz, FADE_OUT_MIN_S)
    return max(2, math.ceil(seconds * sample_rate_hz))


def fade_out_envelope(period_samples: int, ramp_samples: int) -> np.ndarray:
    """A raised-cosine fall from 1 to exactly 0 over `ramp_samples`, then zeros, padded to whole
    periods of `period_samples`: the output ends at exactly 0 V at a period boundary, and the
    shaker stops after `ramp_samples`, not after whole periods."""
    if period_samples < 2 or ramp_samples < 2:
        raise ValueError("fade-out: needs periods and a ramp of at least 2 samples")
    periods = math.ceil(ramp_samples / period_samples)
    envelope = np.zeros(periods * period_samples)
    envelope[:ramp_samples] = fade_envelope(ramp_samples, 1, "out")
    return envelope
