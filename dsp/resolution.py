"""The converter's resolution at a line (issue 32 point 2): the line's amplitude in LSB of the
input range it was measured on, and the budget term for the error the quantiser and the
converter's nonlinearity leave at the line's frequency.

Model. An ADC of `bits` bits over +-R volts has the step q = 2 R / 2^bits (one LSB). Its
transfer error e(x) (quantisation plus nonlinearity) is bounded, |e| <= E. For a sine of
amplitude A the error's component at the sine's own frequency is the first Fourier coefficient
of e(A sin t), at most (4 / pi) E in size: a relative error of at most 4 E / (pi A) on the
amplitude and as many radians on the phase (the error can lie in phase or in quadrature).
E has two parts, in LSB:

- quantisation: 1/2 LSB without noise at the converter's input. Random noise of sigma LSB
  there (dither) makes the deterministic part (what repeats from period to period and so does
  not average down) shrink: the sawtooth's Fourier series sum_k (-1)^k sin(2 pi k x) / (pi k)
  smoothed by a Gaussian, each term times exp(-2 pi^2 k^2 sigma^2), bounded by
  sum_k exp(-2 pi^2 k^2 sigma^2) / (pi k) and never above 1/2. The random part is noise, in
  type A already.
- linearity: the converter's nonlinearity near the codes used, as its data sheet states it
  (`linearity_lsb`, a half-width); dither does not remove it.

The half-width is read as a rectangular distribution (GUM 4.3.7), one per channel, the two
channels independent. Units: volts, LSB, relative (fraction) for magnitude, degrees for phase.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from dsp.uncertainty import Component, Distribution, Quantity

__all__ = [
    "MIN_LINE_LSB",
    "Converter",
    "LineResolution",
    "dithered_quantisation_lsb",
    "line_resolution",
    "resolution_components",
    "resolution_half_width",
]

#: A line below this many LSB (amplitude) on a channel is not stated: the error bound of the
#: model above is then over 6 % (no dither) and the converter's real behaviour at a few codes
#: (missing codes, DNL) is not what a data sheet's linearity describes.
MIN_LINE_LSB = 20.0
RESOLUTION_NAME = "ADC resolution and linearity"
_TERMS = 64  # terms of the smoothed sawtooth's series (exp(-2 pi^2 k^2 s^2) is tiny beyond)


@dataclass(frozen=True)
class Converter:
    """An analog input's converter: `bits` (resolution) and `linearity_lsb` (its nonlinearity
    near the codes a line uses, half-width in LSB, from its data sheet)."""

    bits: int = 16
    linearity_lsb: float = 1.0

    def __post_init__(self) -> None:
        if (
            isinstance(self.bits, bool)
            or not isinstance(self.bits, int)
            or not 8 <= self.bits <= 32
        ):
            raise ValueError(f"converter: bits must be an integer 8..32, got {self.bits!r}")
        lin = self.linearity_lsb
        if isinstance(lin, bool) or not isinstance(lin, int | float) or not 0 <= lin <= 64:
            raise ValueError(f"converter: linearity_lsb must be 0..64 LSB, got {lin!r}")

    def step_v(self, range_v: float) -> float:
        """One LSB (V) on the +-`range_v` range."""
        if not (math.isfinite(range_v) and range_v > 0):
            raise ValueError(f"converter: range must be > 0 V, got {range_v!r}")
        return 2.0 * range_v / 2**self.bits


def dithered_quantisation_lsb(noise_lsb: float) -> float:
    """The bound (LSB) of the quantiser's deterministic error under Gaussian input noise of
    `noise_lsb` LSB rms (module docstring): 1/2 without noise, falling as exp(-2 pi^2 s^2)."""
    s = float(noise_lsb)
    if not s > 0 or not math.isfinite(s):
        return 0.5
    k = np.arange(1, _TERMS + 1)
    series = float(np.sum(np.exp(-2.0 * math.pi**2 * k**2 * s**2) / (math.pi * k)))
    return min(0.5, series)


def resolution_half_width(amplitude_lsb: float, noise_lsb: float, linearity_lsb: float) -> float:
    """Relative half-width of the converter's error at a line of `amplitude_lsb` (module
    docstring): 4 (E_q + E_lin) / (pi A). Infinite for a line of no amplitude."""
    if not amplitude_lsb > 0:
        return math.inf
    bound = dithered_quantisation_lsb(noise_lsb) + float(linearity_lsb)
    return 4.0 * bound / (math.pi * float(amplitude_lsb))


@dataclass(frozen=True)
class LineResolution:
    """One line on one channel: its range (V), amplitude and per-sample noise in LSB, and the
    relative half-width of the converter's error there."""

    frequency_hz: float
    channel: str
    range_v: float
    amplitude_lsb: float
    noise_lsb: float
    half_width: float

    @property
    def too_few_lsb(self) -> bool:
        """Below `MIN_LINE_LSB`: not stated."""
        return not self.amplitude_lsb >= MIN_LINE_LSB

    def warning(self) -> str:
        """The blocking warning for a line too few LSB above the converter's step."""
        return (
            f"line {self.frequency_hz:g} Hz: {self.channel} channel {self.amplitude_lsb:.3g} LSB "
            f"on its +-{self.range_v:g} V range (< {MIN_LINE_LSB:g} LSB): resolution not "
            "stated; raise the level or use a smaller input range"
        )


def line_resolution(
    frequency_hz: float,
    channel: str,
    amplitude_v: float,
    noise_rms_v: float,
    range_v: float,
    converter: Converter,
) -> LineResolution:
    """A line's resolution on one channel: `amplitude_v` (peak, V) and the per-sample random
    noise `noise_rms_v` (V rms at the converter's input) in LSB of the +-`range_v` range."""
    q = converter.step_v(range_v)
    amplitude = abs(float(amplitude_v)) / q
    noise = max(0.0, float(noise_rms_v)) / q if math.isfinite(noise_rms_v) else 0.0
    return LineResolution(
        float(frequency_hz),
        channel,
        float(range_v),
        amplitude,
        noise,
        resolution_half_width(amplitude, noise, converter.linearity_lsb),
    )


def resolution_components(
    per_line: Sequence[tuple[LineResolution, LineResolution]],
) -> tuple[Component, ...]:
    """Per line (reference, DUT): one magnitude and one phase component at the line's frequency
    alone, the two channels' rectangular half-widths combined in quadrature (standard
    uncertainty). Tagged with no Annex A kind: a term the procedure computes from what it
    measured (the stand's own "daq_linearity" component stays what it states). A line too few
    LSB above the step carries its term too (the bound holds there as well; its warning keeps
    it from PASS); a line of no amplitude gets a term of 100 %."""
    out: list[Component] = []
    for ref, dut in per_line:
        u = min(math.hypot(ref.half_width, dut.half_width), 1.0) / math.sqrt(3.0)
        f = ref.frequency_hz
        common = {
            "distribution": Distribution.STANDARD,
            "min_frequency_hz": f,
            "max_frequency_hz": f,
            "note": (
                f"reference {ref.amplitude_lsb:.4g} LSB on +-{ref.range_v:g} V, DUT "
                f"{dut.amplitude_lsb:.4g} LSB on +-{dut.range_v:g} V (dsp.resolution)"
            ),
        }
        out.append(Component(f"{RESOLUTION_NAME} at {f:g} Hz", u, **common))  # type: ignore[arg-type]
        out.append(
            Component(
                f"{RESOLUTION_NAME} (phase) at {f:g} Hz",
                math.degrees(u),
                quantity=Quantity.PHASE,
                **common,  # type: ignore[arg-type]
            )
        )
    return tuple(out)
