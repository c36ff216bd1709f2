"""Mounted-resonance search from a measured frequency response (issue 26 point 4).

A low-level plan of closely spaced lines up to 20 kHz or more gives the DUT/reference response
H(f) per line (complex, V/V, e.g. dsp.lpm.estimate). The mounted resonance is the largest peak
of |H| above the mid band, fitted near the peak by one second-order mode,
H(w) (w0^2 - w^2 + j w w0/Q) = n (Levy's linearised least squares: real unknowns
a = w0^2 and b = w0/Q, complex n, over the lines within the half-power band of the peak and
at least one line each side). Frequencies in Hz.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

MIN_RISE = 1.2  # a peak must stand this far above the mid band (|H| ratio) to count


@dataclass(frozen=True)
class Resonance:
    """Fitted mode: frequency in Hz, quality factor Q, peak |H| over the mid band."""

    frequency_hz: float
    q: float
    peak_ratio: float
    lines_used: int


class ResonanceError(ValueError):
    """Input from which no resonance can be stated; the message names the reason."""


def find_resonance(
    frequencies_hz: Sequence[float] | np.ndarray,
    response: Sequence[complex] | np.ndarray,
    *,
    mid_band_hz: float | None = None,
) -> Resonance:
    """The largest resonance of `response` (complex per line, lines ascending in Hz).

    `mid_band_hz`: |H| is referred to the line nearest it (default: the lowest line).
    ResonanceError when the peak is at the highest line (the resonance lies above the plan:
    extend it), when no line stands `MIN_RISE` above the mid band, or on bad input.
    """
    f = np.asarray(frequencies_hz, dtype=float)
    h = np.asarray(response, dtype=complex)
    if f.ndim != 1 or f.shape != h.shape or f.size < 5:
        raise ResonanceError("response: needs at least 5 lines, one value per frequency")
    if not (np.all(np.isfinite(f)) and np.all(np.isfinite(h)) and np.all(np.diff(f) > 0)):
        raise ResonanceError("response: frequencies must be finite and ascending, values finite")
    magnitude = np.abs(h)
    reference = 0 if mid_band_hz is None else int(np.argmin(np.abs(f - mid_band_hz)))
    mid = magnitude[reference]
    if not mid > 0:
        raise ResonanceError("response: zero at the mid-band line")
    peak = reference + int(np.argmax(magnitude[reference:]))
    ratio = float(magnitude[peak] / mid)
    if ratio < MIN_RISE:
        raise ResonanceError(
            f"response: no resonance up to {f[-1]:g} Hz (peak {ratio:.2f} x the mid band)"
        )
    if peak == f.size - 1:
        raise ResonanceError(
            f"response: still rising at the highest line {f[-1]:g} Hz; the resonance lies "
            "above the plan, extend it"
        )
    half = magnitude[peak] / math.sqrt(2.0)
    lo = peak
    while lo > reference and magnitude[lo - 1] >= half:
        lo -= 1
    hi = peak
    while hi < f.size - 1 and magnitude[hi + 1] >= half:
        hi += 1
    lo, hi = max(lo - 1, 0), min(hi + 1, f.size - 1)
    scale = 2.0 * math.pi * f[peak]
    w = 2.0 * math.pi * f[lo : hi + 1] / scale  # normalised angular frequency
    hh = h[lo : hi + 1]
    jwh = 1j * w * hh
    rows = np.vstack(
        [
            np.column_stack([hh.real, jwh.real, -np.ones(w.size), np.zeros(w.size)]),
            np.column_stack([hh.imag, jwh.imag, np.zeros(w.size), -np.ones(w.size)]),
        ]
    )
    rhs = np.concatenate([(w**2 * hh).real, (w**2 * hh).imag])
    (a, b, _n_re, _n_im), *_ = np.linalg.lstsq(rows, rhs, rcond=None)
    if not (a > 0 and b > 0):
        raise ResonanceError(f"response: the peak near {f[peak]:g} Hz does not fit one mode")
    w0 = math.sqrt(a)
    return Resonance(
        frequency_hz=float(w0 * scale / (2.0 * math.pi)),
        q=float(w0 / b),
        peak_ratio=ratio,
        lines_used=int(w.size),
    )
