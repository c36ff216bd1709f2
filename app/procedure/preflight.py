"""Preflight: the one check made before anything moves, for the CLI, the GUI and the run.

The plan's predicted peaks (stroke, velocity, acceleration) against the stand's limits and the
channels' predicted peaks against their ranges: refused, never clipped. The input ranges the run
will use (app.procedure.ranging: per run, per line in stepped sine) and each line's predicted
resolution in LSB are part of the report, so the preview shows them before anything moves.
Before every drive is played at level (issue 25 point 7), the peaks the drive itself will give
through the stand's response (the latest measured one) are checked against the same limits:
`check_drive`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from app.procedure.errors import PreflightError
from app.procedure.ranging import RangePlan, plan_ranges, ranges_by_name
from dsp.crestfactor import peak_grid_samples, synthesize
from dsp.fades import fade_in_seconds, fade_motion, fade_out_seconds
from dsp.multisine import Plan, PredictedPeaks
from dsp.resolution import Converter

if TYPE_CHECKING:
    from app.stand.config import Limits, StandConfig
    from dsp.calibration import ReferenceChain

OVERLOAD_FRACTION = 0.995  # SPEC s.11: a sample within 0.5 % of a channel's range
RANGE_MARGIN = 1.2  # predicted channel peaks stay this far below the overload limit


@dataclass(frozen=True)
class PreflightReport:
    """What preflight found: the predicted peaks (at the level checked), the crest factor and
    the problems (empty: the plan may run)."""

    peaks: PredictedPeaks
    crest_factor: float
    problems: tuple[str, ...]
    ranges: RangePlan | None = None
    converter: Converter = field(default_factory=Converter)
    fade_in_s: float | None = None  # a multisine's fade-in (s) the peaks cover (`fade_in_for`)

    @property
    def ok(self) -> bool:
        return not self.problems

    @property
    def resolution_warnings(self) -> tuple[str, ...]:
        """The lines predicted too few LSB above the converter's step (not stated unless the
        measured amplitude turns out larger)."""
        return () if self.ranges is None else tuple(self.ranges.warnings(self.converter))

    def ranges_text(self) -> str:
        """The input ranges and the fewest LSB per channel, one line ("" without ranges)."""
        return "" if self.ranges is None else self.ranges.summary(self.converter)

    def raise_if_refused(self) -> None:
        """PreflightError naming every problem, if any."""
        if self.problems:
            raise PreflightError("; ".join(self.problems))

    def summary(self) -> str:
        """One line for run.log."""
        p = self.peaks
        text = (
            f"preflight: peaks {p.acceleration_ms2:.1f} m/s^2, "
            f"{1e3 * p.velocity_m_per_s:.1f} mm/s, "
            f"{1e3 * p.displacement_peak_to_peak_m:.3f} mm p-p; crest factor "
            f"{self.crest_factor:.2f}"
        )
        return f"{text}; {self.ranges_text()}" if self.ranges is not None else text


def check_preflight(
    plan: Plan,
    config: StandConfig,
    chain: ReferenceChain | None,
    nominal_mv_per_ms2: float | None = None,
    *,
    level_scale: float = 1.0,
    offered_v: tuple[float, ...] | None = None,
    per_line: bool = False,
    fade_in_s: float | None = None,
    fade_out_s: float | None = None,
) -> PreflightReport:
    """Check `plan` (its amplitudes times `level_scale`) on the stand of `config` with the
    reference `chain` and, when known, the DUT's nominal sensitivity (mV/(m/s^2)). Without a
    chain (a window before its stand is opened) the reference channel is not checked here;
    the run's own preflight checks it before anything moves. The ranges are picked among
    `offered_v` (V; None: the stand file's `daq.input_ranges_v`), per line when `per_line`
    (stepped sine, whose motion is then one line's at a time: `largest_line_peaks`). A
    multisine's peaks cover its fades (`motion_peaks`: `fade_in_s`, None: the LPM's as
    `fade_in_for` picks it; `fade_out_s`, None: dsp.fades' default)."""
    limits = config.limits
    ranges = ranges_by_name(config.inputs)
    picked_fade_in_s = None
    if per_line:
        raw = largest_line_peaks(plan)
        peaks = PredictedPeaks(
            acceleration_ms2=raw.acceleration_ms2 * level_scale,
            velocity_m_per_s=raw.velocity_m_per_s * level_scale,
            displacement_m=raw.displacement_m * level_scale,
            displacement_peak_to_peak_m=raw.displacement_peak_to_peak_m * level_scale,
        )
    else:  # the multisine's own orbit and its fades (issue 34)
        target = level_scale * plan.amplitudes_ms2 * np.exp(1j * (plan.phases_rad - np.pi / 2))
        if fade_in_s is None and fade_out_s is None:  # the peaks the fade-in was picked by
            picked_fade_in_s, peaks = fade_in_and_peaks(plan, target, limits)
        else:
            picked_fade_in_s = fade_in_for(plan, target, limits, fade_in_s)
            peaks = motion_peaks(plan, target, fade_in_s=picked_fade_in_s, fade_out_s=fade_out_s)
    problems = limit_problems(peaks, limits)
    if chain is not None:
        ref_s, _ = chain.sensitivity_at(plan.frequencies_hz)
        ref_peak = peaks.acceleration_ms2 * float(ref_s.max()) * 1e-3 * chain.reference_gain
        if ref_peak > OVERLOAD_FRACTION * ranges["reference"] / RANGE_MARGIN:
            problems.append(
                f"reference channel: predicted peak {ref_peak:.3g} V is too close to its "
                f"+-{ranges['reference']:g} V range (raise the range or lower the level)"
            )
    dut_gain = chain.dut_gain if chain is not None else config.dut_gain
    if nominal_mv_per_ms2 is not None:  # the DUT's own response is unknown: its nominal stands in
        dut_peak = peaks.acceleration_ms2 * nominal_mv_per_ms2 * 1e-3 * dut_gain
        if dut_peak > OVERLOAD_FRACTION * ranges["dut"] / RANGE_MARGIN:
            problems.append(
                f"DUT channel: predicted peak {dut_peak:.3g} V (nominal {nominal_mv_per_ms2:g} "
                f"mV/(m/s^2)) is too close to its +-{ranges['dut']:g} V range "
                "(raise the range or lower the level)"
            )
    problems += reference_line_problems(plan, chain)
    range_plan = plan_ranges(
        plan,
        config,
        chain,
        nominal_mv_per_ms2,
        config.input_ranges_v if offered_v is None else offered_v,
        per_line=per_line,
        level_scale=level_scale,
    )
    return PreflightReport(
        peaks,
        plan.crest_factor(),
        tuple(problems),
        range_plan,
        config.converter,
        fade_in_s=picked_fade_in_s,
    )


def largest_line_peaks(plan: Plan) -> PredictedPeaks:
    """The largest peaks of the plan's lines played one at a time (stepped sine): a sine of
    peak a (m/s^2) at f has velocity a / (2 pi f) and displacement a / (2 pi f)^2 (peak)."""
    a = plan.amplitudes_ms2
    w = 2 * np.pi * plan.frequencies_hz
    displacement = float(np.max(a / w**2))
    return PredictedPeaks(float(np.max(a)), float(np.max(a / w)), displacement, 2 * displacement)


def reference_line_problems(plan: Plan, chain: ReferenceChain | None) -> list[str]:
    """The plan's reference line outside the reference's calibrated range (issue 32 point 5:
    no line could then be stated): refused before anything moves, not after the run."""
    if chain is None or len(chain.frequencies_hz) < 2:
        return []
    f = float(plan.frequencies_hz[plan.reference_index])
    lo, hi = chain.frequencies_hz[0], chain.frequencies_hz[-1]
    if lo <= f <= hi:
        return []
    return [
        f"reference frequency {plan.reference_frequency_hz:g} Hz (played at {f:g} Hz): outside "
        f"the reference's calibrated range ({lo:g}-{hi:g} Hz), so no line could be stated; "
        "choose a reference frequency inside it"
    ]


def limit_problems(peaks: PredictedPeaks, limits: Limits) -> list[str]:
    """The stand's motion limits that `peaks` exceed, one message each (SI units)."""
    problems = []
    if peaks.displacement_peak_to_peak_m > limits.displacement_peak_to_peak_m:
        problems.append(
            f"displacement {1e3 * peaks.displacement_peak_to_peak_m:.2f} mm p-p exceeds the "
            f"exciter's {1e3 * limits.displacement_peak_to_peak_m:g} mm (lower the level at "
            "low frequencies)"
        )
    if peaks.velocity_m_per_s > limits.velocity_peak_m_per_s:
        problems.append(
            f"velocity {peaks.velocity_m_per_s:.3g} m/s exceeds "
            f"{limits.velocity_peak_m_per_s:g} m/s"
        )
    if peaks.acceleration_ms2 > limits.acceleration_peak_ms2:
        problems.append(
            f"acceleration {peaks.acceleration_ms2:.1f} m/s^2 exceeds "
            f"{limits.acceleration_peak_ms2:g} m/s^2"
        )
    return problems


def motion_peaks(
    plan: Plan,
    acceleration: np.ndarray,
    *,
    fade_in_s: float | None = None,
    fade_out_s: float | None = None,
    fades: bool = True,
) -> PredictedPeaks:
    """Peaks of the table motion for the acceleration per line (complex m/s^2, phasor
    convention of the procedure: x(t) = Re sum X_k e^{j w_k t}): the steady orbit (velocity
    A_k/(j w_k), displacement -A_k/w_k^2, synthesised on an oversampled grid as
    Plan.predicted_peaks) and its fades (issue 34): a fade-in from rest and a fade-out to rest
    (dsp.fades.fade_motion, free mass during a fade; `fade_in_s`/`fade_out_s`, None: the
    defaults), the offsets the fade-in leaves added to the steady orbit's peaks, the residual
    velocity after the fade-out counted. The drive's peak is not raised by a fade (its
    envelope is at most 1)."""
    acceleration = np.asarray(acceleration, complex)
    if acceleration.shape != (len(plan.bins),) or not np.all(np.isfinite(acceleration)):
        raise PreflightError("predicted motion: the drive or the response is not finite")
    omega = 2 * np.pi * np.asarray(plan.frequencies_hz, float)
    n = peak_grid_samples(plan.period_samples, plan.bins)

    def wave(phasors: np.ndarray) -> np.ndarray:
        return synthesize(plan.bins, np.abs(phasors), np.angle(phasors) + np.pi / 2, n)

    displacement = wave(-acceleration / omega**2)
    steady_v = float(np.max(np.abs(wave(acceleration / (1j * omega)))))
    steady_a = float(np.max(np.abs(wave(acceleration))))
    if not fades:  # the steady orbit alone (Plan.predicted_peaks' figures)
        return PredictedPeaks(
            steady_a, steady_v, float(np.max(np.abs(displacement))), float(np.ptp(displacement))
        )
    lowest = float(np.min(plan.frequencies_hz))
    motion = fade_motion(
        plan.frequencies_hz,
        acceleration,
        fade_in_seconds(lowest, fade_in_s),
        fade_out_s if fade_out_s is not None else fade_out_seconds(lowest),
    )
    offset = motion.offset_displacement_m
    high = max(float(np.max(displacement)) + max(offset, 0.0), motion.displacement_high_m)
    low = min(float(np.min(displacement)) + min(offset, 0.0), motion.displacement_low_m)
    return PredictedPeaks(
        acceleration_ms2=max(steady_a, motion.acceleration_peak_ms2),
        velocity_m_per_s=max(
            steady_v + abs(motion.offset_velocity_m_per_s),
            motion.velocity_peak_m_per_s,
            abs(motion.residual_velocity_m_per_s),
        ),
        displacement_m=max(high, -low),
        displacement_peak_to_peak_m=high - low,
    )


def predict_drive_peaks(
    plan: Plan,
    drive_lines_v: np.ndarray,
    response: np.ndarray,
    *,
    fade_in_s: float | None = None,
    fades: bool = True,
) -> PredictedPeaks:
    """Peaks of the table motion the drive (complex volts per line) will give through
    `response` ((m/s^2)/V per line): acceleration A_k = R_k D_k, its steady orbit and (with
    `fades`) its fades (`motion_peaks`)."""
    acceleration = np.asarray(response, complex) * np.asarray(drive_lines_v, complex)
    if acceleration.shape != (len(plan.bins),) or not np.all(np.isfinite(acceleration)):
        raise PreflightError("predicted motion: the drive or the response is not finite")
    return motion_peaks(plan, acceleration, fade_in_s=fade_in_s, fades=fades)


FADE_IN_STEPS = (1.0, 1.5, 2.0, 3.0, 4.0, 6.0, 8.0)  # cycles of the lowest line tried, in turn


def fade_in_for(
    plan: Plan, acceleration: np.ndarray, limits: Limits, given_s: float | None = None
) -> float:
    """The LPM's fade-in (s) for the acceleration per line (complex m/s^2): `given_s` when
    given; else the shortest of FADE_IN_STEPS cycles of the lowest line (at most a period)
    whose motion, its fades included (`motion_peaks`), stays within `limits`: a short fade-in
    leaves the table an offset from its orbit (dsp.fades), so a level near the stroke gets a
    longer one instead of a refusal. When none does, the longest (the refusal then names the
    orbit's own excess)."""
    return fade_in_and_peaks(plan, acceleration, limits, given_s)[0]


def fade_in_and_peaks(
    plan: Plan, acceleration: np.ndarray, limits: Limits, given_s: float | None = None
) -> tuple[float, PredictedPeaks]:
    """`fade_in_for`'s fade-in (s) and the motion's peaks with it (`motion_peaks`, the default
    fade-out): the peaks it judged the fade-in by, not computed again by its callers."""
    if given_s is not None:
        return given_s, motion_peaks(plan, acceleration, fade_in_s=given_s)
    lowest = float(np.min(plan.frequencies_hz))
    seconds = fade_in_seconds(lowest)
    peaks = None
    for cycles in FADE_IN_STEPS:
        seconds = min(cycles / lowest, plan.period_s)
        peaks = motion_peaks(plan, acceleration, fade_in_s=seconds)
        if not limit_problems(peaks, limits):
            break
        if seconds >= plan.period_s:
            break
    assert peaks is not None  # FADE_IN_STEPS is not empty
    return seconds, peaks


def check_drive(
    plan: Plan, drive_lines_v: np.ndarray, response: np.ndarray, limits: Limits, what: str
) -> PredictedPeaks:
    """PreflightError (exit 2) naming the predicted displacement when the drive about to be
    played (`what` says which) would take the table past a limit through `response` (its
    fades included, the fade-in as `fade_in_for` picks it); else the predicted peaks.
    Nothing has been played with this drive when it refuses."""
    acceleration = np.asarray(response, complex) * np.asarray(drive_lines_v, complex)
    if acceleration.shape != (len(plan.bins),) or not np.all(np.isfinite(acceleration)):
        raise PreflightError("predicted motion: the drive or the response is not finite")
    _, peaks = fade_in_and_peaks(plan, acceleration, limits)  # the peaks it picked it by
    problems = limit_problems(peaks, limits)
    if problems:
        raise PreflightError(
            f"{what}: refused before it is played: predicted displacement "
            f"{1e3 * peaks.displacement_peak_to_peak_m:.2f} mm p-p, velocity "
            f"{peaks.velocity_m_per_s:.3g} m/s, acceleration {peaks.acceleration_ms2:.1f} m/s^2: "
            + "; ".join(problems)
        )
    return peaks
