"""Input ranges from the predicted peaks, and the converter's resolution at every line (issue 32
point 2). One module for the preflight (what the ranges will be, each line's predicted LSB),
the run (the ranges the DAQ is configured with: per run, per line in stepped sine) and the
budget (each line's measured amplitude in LSB as a term, dsp.resolution).

A channel's range is the smallest the stand's DAQ offers (`Stand.input_ranges_v`, or the stand
file's `daq.input_ranges_v` before a stand is opened) that holds the predicted peak times a
headroom, and never above the channel's `range_v` (the largest the stand file lets it use; the
preflight refuses a peak too close to that). Before anything is measured the reference
channel's peak is predicted from its certificate, the DUT's from its nominal sensitivity;
without a nominal, or without a list of ranges, a channel keeps its `range_v`. A multisine
runs on its predicted ranges; when identification (a fixed drive voltage, whatever the level)
or its first level step overloads one, it is identified again on the `range_v`s
(app.procedure.procedure). A stepped-sine line's first measurement is on the `range_v`s only
for the first line (identification); a line is re-ranged down once from its measured amplitude
when it is under `RE_RANGE_BELOW_LSB`, the next line predicted from the DUT/reference ratio it
measured, and a line whose first level step overloads is measured again on the `range_v`s.
Units: V, Hz, m/s^2.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

import numpy as np

from dsp.multisine import Plan
from dsp.resolution import Converter, LineResolution, line_resolution, resolution_components
from dsp.uncertainty import Budget
from hardware.interfaces import InputChannel, choose_range, is_dut_channel

if TYPE_CHECKING:
    from app.stand.config import StandConfig
    from dsp.calibration import ReferenceChain

Floats = Sequence[float] | np.ndarray  # per line

#: A peak predicted before it was measured: the DUT's nominal stands in for its unknown
#: response (a resonance near the top line, a loose mount), and a stepped-sine line's first
#: level step starts from a response extrapolated within a factor of two (app.procedure.stepped).
PREDICTED_HEADROOM = 2.5
#: A stepped-sine line is measured again on a smaller range only when it is under this many
#: LSB on its own (its resolution term then over 0.06 %; above, a second measurement buys little).
RE_RANGE_BELOW_LSB = 2000.0


@dataclass(frozen=True)
class RangePlan:
    """Per line: the +-range (V) of the reference and DUT channels and the predicted amplitude
    (V) there, and whether the ranges change per line (stepped sine) or hold for the run."""

    frequencies_hz: tuple[float, ...]
    reference_v: tuple[float, ...]
    dut_v: tuple[float, ...]
    reference_amplitude_v: tuple[float, ...]
    dut_amplitude_v: tuple[float, ...] | None  # None: no nominal, not predicted
    per_line: bool
    chosen: bool  # picked among offered ranges (False: the stand file's range_v as they stand)
    # the offered ranges each channel may use (up to its range_v), V
    allowed_v: dict[str, tuple[float, ...]] = field(default_factory=dict)
    top_v: dict[str, float] = field(default_factory=dict)  # each channel's range_v
    bits: int = 16  # the converter's

    def _pick(self, name: str, peak_v: float, headroom: float) -> float | None:
        allowed = self.allowed_v.get(name, ())
        if not allowed or not (math.isfinite(peak_v) and peak_v > 0):
            return None
        return choose_range(peak_v, allowed, headroom) or max(allowed)

    def from_ratio(self, k: int, dut_per_reference: float) -> dict[str, float]:
        """Line k's ranges with the DUT's predicted from the DUT/reference amplitude ratio the
        last line measured (V/V) when its nominal did not predict it."""
        out = self.ranges_at(k)
        if self.dut_amplitude_v is None:
            dut = self._pick(
                "dut", self.reference_amplitude_v[k] * dut_per_reference, PREDICTED_HEADROOM
            )
            if dut is not None:
                out["dut"] = dut
        return out

    def re_ranged(
        self, amplitudes_v: dict[str, float], current_v: dict[str, float]
    ) -> dict[str, float] | None:
        """Smaller ranges for a line whose measured amplitudes (V peak) are under
        `RE_RANGE_BELOW_LSB` on their range and fit a smaller one with the predicted headroom
        (the next line's level step may overshoot as this one's could); never up (a peak too
        close to its range overloads and stops the run). None when nothing changes."""
        out = dict(current_v)
        for name, amplitude in amplitudes_v.items():
            lsb = 2.0 * current_v[name] / 2**self.bits
            if not amplitude < RE_RANGE_BELOW_LSB * lsb:
                continue
            smaller = self._pick(name, amplitude, PREDICTED_HEADROOM)
            if smaller is not None and smaller < current_v[name]:
                out[name] = smaller
        return out if out != current_v else None

    def ranges_at(self, k: int) -> dict[str, float]:
        """The reference and DUT ranges (V) for line k."""
        return {"reference": self.reference_v[k], "dut": self.dut_v[k]}

    @property
    def run_ranges(self) -> dict[str, float]:
        """The ranges (V) of the run's multi-line segments (the background; every line in a
        multisine): the largest over the lines."""
        return {"reference": max(self.reference_v), "dut": max(self.dut_v)}

    def predicted(self, converter: Converter) -> list[tuple[LineResolution, LineResolution]]:
        """Each line's predicted resolution (no dither credit); the DUT's from its nominal
        (an upper bound on its amplitude below its high-pass or above its low-pass)."""
        out = []
        for k, f in enumerate(self.frequencies_hz):
            dut_amplitude = math.nan if self.dut_amplitude_v is None else self.dut_amplitude_v[k]
            out.append(
                (
                    line_resolution(
                        f,
                        "reference",
                        self.reference_amplitude_v[k],
                        0.0,
                        self.reference_v[k],
                        converter,
                    ),
                    line_resolution(
                        f,
                        "DUT",
                        dut_amplitude if math.isfinite(dut_amplitude) else 0.0,
                        0.0,
                        self.dut_v[k],
                        converter,
                    ),
                )
            )
        return out

    def warnings(self, converter: Converter) -> list[str]:
        """One line per line predicted too few LSB above the converter's step."""
        return [
            f"predicted: {side.warning()}" for side in self._known(converter) if side.too_few_lsb
        ]

    def _known(self, converter: Converter) -> list[LineResolution]:
        """The predicted line resolutions whose amplitude is known (the reference's needs its
        certificate, the DUT's its nominal)."""
        sides = [side for pair in self.predicted(converter) for side in pair]
        return [s for s in sides if s.amplitude_lsb > 0 and math.isfinite(s.amplitude_lsb)]

    def summary(self, converter: Converter) -> str:
        """One line for run.log, the preflight and the preview: the ranges and the fewest LSB."""
        how = "chosen from the predicted peaks" if self.chosen else "as the stand file sets them"

        def ranges(values: Floats) -> str:
            distinct = sorted(set(values))
            if len(distinct) == 1:
                return f"+-{distinct[0]:g} V"
            parts = []
            for r in distinct:
                at = [f for f, v in zip(self.frequencies_hz, values, strict=True) if v == r]
                parts.append(f"+-{r:g} V ({at[0]:g}-{at[-1]:g} Hz)")
            return ", ".join(parts)

        text = f"input ranges {how}: reference {ranges(self.reference_v)}, DUT {ranges(self.dut_v)}"
        fewest = []
        for name in ("reference", "DUT"):
            sides = [s for s in self._known(converter) if s.channel == name]
            if sides:
                low = min(sides, key=lambda s: s.amplitude_lsb)
                fewest.append(f"{name} {low.amplitude_lsb:.3g} at {low.frequency_hz:g} Hz")
        if fewest:
            text += f"; fewest LSB per line: {', '.join(fewest)}"
        return text


def plan_ranges(
    plan: Plan,
    config: StandConfig,
    chain: ReferenceChain | None,
    nominal_mv_per_ms2: float | None,
    offered_v: tuple[float, ...],
    *,
    per_line: bool,
    level_scale: float = 1.0,
) -> RangePlan:
    """The ranges of a run of `plan` (module docstring): one per channel from the whole plan's
    predicted peak, or (`per_line`, stepped sine) one per line from that line's amplitude."""
    limits: dict[str, float] = ranges_by_name(config.inputs)
    freqs = np.asarray(plan.frequencies_hz, float)
    amplitudes = np.asarray(plan.amplitudes_ms2, float) * level_scale
    if chain is not None:
        ref_s, _ = chain.sensitivity_at(freqs)
        ref_per_ms2 = np.abs(ref_s) * 1e-3 * chain.reference_gain
        dut_gain = chain.dut_gain
    else:  # a window before its stand is opened: the reference's nominal 1:1 is not known
        ref_per_ms2 = None
        dut_gain = config.dut_gain
    dut_per_ms2 = None if nominal_mv_per_ms2 is None else nominal_mv_per_ms2 * 1e-3 * dut_gain
    if per_line:
        ref_peaks = None if ref_per_ms2 is None else amplitudes * ref_per_ms2
        dut_peaks = None if dut_per_ms2 is None else amplitudes * dut_per_ms2
    else:
        peak = plan.predicted_peaks().acceleration_ms2 * level_scale
        ref_peaks = None if ref_per_ms2 is None else np.full(freqs.size, peak * ref_per_ms2.max())
        dut_peaks = None if dut_per_ms2 is None else np.full(freqs.size, peak * dut_per_ms2)
    offered = tuple(r for r in offered_v if r > 0)

    allowed = {
        name: tuple(r for r in offered if r <= limits[name] * (1 + 1e-9)) or (limits[name],)
        for name in ("reference", "dut")
    }

    def pick(peaks: np.ndarray | None, name: str, headroom: float) -> tuple[float, ...]:
        top = limits[name]
        if peaks is None or not offered:
            return (top,) * freqs.size
        return tuple((choose_range(float(p), allowed[name], headroom) or top) for p in peaks)

    ref_amplitude = (
        amplitudes * ref_per_ms2 if ref_per_ms2 is not None else np.full(freqs.size, math.nan)
    )
    return RangePlan(
        tuple(freqs.tolist()),
        pick(ref_peaks, "reference", PREDICTED_HEADROOM),
        pick(dut_peaks, "dut", PREDICTED_HEADROOM),
        tuple(ref_amplitude.tolist()),
        None if dut_per_ms2 is None else tuple((amplitudes * dut_per_ms2).tolist()),
        per_line,
        bool(offered),
        allowed if offered else {},
        dict(limits),
        config.converter.bits,
    )


def member_ranges(
    ranges: RangePlan,
    plan: Plan,
    nominals_mv_per_ms2: Mapping[str, float | None],
    dut_gain: float,
    *,
    level_scale: float = 1.0,
) -> dict[str, float]:
    """Each DUT channel's +-range (V) of a run of several DUTs (issue 36), by channel name
    ("dut.<position>" -> its DUT's nominal sensitivity, mV/(m/s^2); None: not known): picked
    as the run's own DUT channel's is (`plan_ranges`, a multisine's whole-plan peak), from its
    own predicted peak among the ranges the DUT inputs may use. A DUT without a nominal, or a
    run whose ranges are not chosen (no offered ranges), takes the run's DUT range."""
    run_dut = ranges.run_ranges["dut"]
    allowed = ranges.allowed_v.get("dut", ())
    peak_ms2 = plan.predicted_peaks().acceleration_ms2 * level_scale
    out: dict[str, float] = {}
    for channel, nominal in nominals_mv_per_ms2.items():
        if nominal is None or not ranges.chosen or not allowed or not nominal > 0:
            out[channel] = run_dut
            continue
        peak_v = peak_ms2 * nominal * 1e-3 * dut_gain
        out[channel] = choose_range(peak_v, allowed, PREDICTED_HEADROOM) or max(allowed)
    return out


def ranges_by_name(inputs: Sequence[InputChannel]) -> dict[str, float]:
    """Each input's +-range (V) by name; with several DUTs (issue 36: "dut.<position>"
    inputs, no "dut") also "dut": the first DUT input's, the one the run's own phases read."""
    ranges = {c.name: c.range_v for c in inputs}
    if "dut" not in ranges:
        first = next((name for name in ranges if is_dut_channel(name)), None)
        if first is not None:
            ranges["dut"] = ranges[first]
    return ranges


def with_ranges(
    inputs: Sequence[InputChannel], ranges: dict[str, float]
) -> tuple[InputChannel, ...]:
    """The input channels with the named channels' +-range (V) replaced."""
    return tuple(replace(c, range_v=ranges[c.name]) if c.name in ranges else c for c in inputs)


def per_sample_noise_v(noise_per_period_v: float, samples: int, step_v: float) -> float:
    """The random noise at the converter's input (V rms per sample) from a line's per-period
    noise (peak-scaled DFT, V: its complex standard deviation is 2 sigma / sqrt(N) for white
    noise), less the quantisation noise q^2/12 it may hold (so dither is never overstated)."""
    if not (math.isfinite(noise_per_period_v) and noise_per_period_v > 0):
        return 0.0
    sigma2 = (noise_per_period_v * math.sqrt(samples) / 2.0) ** 2 - step_v**2 / 12.0
    return math.sqrt(sigma2) if sigma2 > 0 else 0.0


def measured_resolution(
    frequencies_hz: Floats,
    amplitudes_v: tuple[Floats, Floats],
    noise_per_period_v: tuple[Floats, Floats],
    samples: Sequence[int],
    ranges_v: tuple[Floats, Floats],
    converter: Converter,
) -> list[tuple[LineResolution, LineResolution]]:
    """Per line (reference, DUT): its measured amplitude (V peak) and noise (per period, V)
    over `samples` per period, on the range (V) it was measured on, in LSB."""
    out = []
    for k, f in enumerate(frequencies_hz):
        pair = []
        for side, name in ((0, "reference"), (1, "DUT")):
            range_v = float(ranges_v[side][k])
            step = converter.step_v(range_v)
            noise = per_sample_noise_v(float(noise_per_period_v[side][k]), samples[k], step)
            pair.append(
                line_resolution(f, name, float(amplitudes_v[side][k]), noise, range_v, converter)
            )
        out.append((pair[0], pair[1]))
    return out


def with_resolution(
    budget: Budget, lines: Sequence[tuple[LineResolution, LineResolution]]
) -> tuple[Budget, list[str]]:
    """The budget with each line's resolution term (dsp.resolution), and the blocking warning
    of every line too few LSB above the converter's step."""
    warnings = [side.warning() for pair in lines for side in pair if side.too_few_lsb]
    return Budget((*budget.components, *resolution_components(lines))), warnings


def run_resolution(
    plan: Plan,
    amplitudes_v: tuple[Floats, Floats],
    noise_per_period_v: np.ndarray,
    ranges_v: dict[str, float],
    converter: Converter,
) -> list[tuple[LineResolution, LineResolution]]:
    """Every line of a multi-line run (multisine, LPM) on the run's ranges: its amplitude
    (V peak, reference and DUT) and the background's per-period noise (rows reference, DUT)."""
    count = len(plan.lines)
    return measured_resolution(
        plan.frequencies_hz,
        amplitudes_v,
        (noise_per_period_v[0], noise_per_period_v[1]),
        [plan.period_samples] * count,
        ([ranges_v["reference"]] * count, [ranges_v["dut"]] * count),
        converter,
    )
