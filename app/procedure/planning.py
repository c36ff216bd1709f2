"""A run's plan from what the operator states (issue 26 point 4): lines, sample rate, period,
a per-line amplitude profile clipped by the exciter's stroke, and the stroke check; one
function for `accelcal plan`, `accelcal run` and the GUI's request. Units: Hz, samples, m/s^2,
m peak-to-peak.

Without a period the preset's is kept when every line sits exactly on its bins; otherwise the
shortest period (dsp.lpm.design_grid, a multiple of 50 ms up to `EXACT_MAX_PERIOD_S`) that
puts every line exactly on a bin with q >= 8 non-excited degrees of freedom; failing that (low
frequencies: exact ISO 266 bins can need a 100 s period), lines within `GRID_TOLERANCE` of
their nominal frequency on a non-uniform grid and none outside the nominal span (the lowest
line not below its nominal frequency, the highest not above: a reference calibrated over the
span covers every line), the actual frequencies stated by the plan's warnings and used for
the results.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from app.procedure.capacity import check_capacity
from app.procedure.phase_store import stored_phases
from dsp.multisine import PRESETS, Plan, PlanError, make_plan
from dsp.profiles import AmplitudeProfile, Profile, check_stroke

EXACT_MAX_PERIOD_S = 20.0  # longest period searched for lines exactly on their bins
GRID_TOLERANCE = 0.02  # otherwise lines within 2 % of nominal (ISO 266 rounds by up to 1.6 %)
LONGEST_PERIOD_S = 100.0


@dataclass(frozen=True)
class PlanRequest:
    """What the plan should be (None: the preset's value)."""

    preset: str = "piezo"
    frequencies_hz: tuple[float, ...] | None = None
    sample_rate_hz: float | None = None
    period_samples: int | None = None
    level_ms2: float | None = None
    reference_frequency_hz: float | None = None
    mains_frequency_hz: float = 50.0
    profile: str = Profile.ACCELERATION
    corner_hz: float | None = None
    shift_mains_lines: bool = True  # issue 32: off the mains harmonics unless asked


def _exact(frequencies: Sequence[float], fs: float, period: int) -> bool:
    return all(
        math.isclose(round(f * period / fs) * fs / period, f, rel_tol=1e-9) for f in frequencies
    )


def choose_period(frequencies: Sequence[float], fs: float, preset_period: int) -> int:
    """The period in samples for these lines (module docstring); PlanError when none fits."""
    if _exact(frequencies, fs, preset_period) and min(frequencies) * preset_period / fs >= 1:
        return preset_period
    from dsp import lpm  # the LPM's grid design, for custom lines only (a preset's plan: none)

    try:
        return lpm.design_grid(frequencies, fs, max_period_s=EXACT_MAX_PERIOD_S).period_samples
    except lpm.LpmError:
        pass
    try:  # the end lines never played outside the nominal span: a reference calibrated
        # over it (e.g. from 0.4 Hz) covers every line (issue 32 point 5)
        grid = lpm.design_grid(
            frequencies,
            fs,
            tolerance=GRID_TOLERANCE,
            max_period_s=LONGEST_PERIOD_S,
            within_hz=(min(frequencies), max(frequencies)),
        )
    except lpm.LpmError as exc:
        raise PlanError([f"period: {exc}"]) from None
    return grid.period_samples


def build_plan(
    request: PlanRequest,
    *,
    stroke_peak_to_peak_m: float | None = None,
    phases_rad: Sequence[float] | None = None,
    optimise: bool = True,
    periods: int | None = None,
) -> Plan:
    """The checked plan (PlanError lists what is refused): lines and rate from the request or
    its preset, amplitudes from the profile clipped per line by `stroke_peak_to_peak_m`, and
    the whole plan's predicted travel checked against that stroke before anything moves. A
    plan (or a run of `periods` periods) this machine has not the memory for is refused
    before anything is allocated (app.procedure.capacity)."""
    preset = PRESETS[request.preset]
    freqs = list(request.frequencies_hz or preset.nominal_frequencies_hz)
    fs = request.sample_rate_hz or preset.sample_rate_hz
    if request.period_samples is not None:
        period = request.period_samples
    elif request.frequencies_hz is None and request.sample_rate_hz is None:
        period = preset.period_samples
    else:
        period = choose_period(freqs, fs, preset.period_samples)
    if fs > 0 and period > 0 and freqs:
        top_bin = round(max(freqs) * period / fs)
        check_capacity(period, fs, periods=periods, top_bin=top_bin)
    level = request.level_ms2 if request.level_ms2 is not None else preset.level_ms2
    try:
        kind = Profile(request.profile)
    except ValueError:
        names = ", ".join(p.value for p in Profile)
        raise PlanError([f"profile: unknown {request.profile!r}; choose one of {names}"]) from None
    profile = AmplitudeProfile(level, kind, request.corner_hz, stroke_peak_to_peak_m)
    amplitudes = profile.amplitudes(freqs)
    reference = request.reference_frequency_hz or preset.reference_frequency_hz
    plan = make_plan(
        freqs,
        fs,
        period,
        amplitudes.tolist(),
        reference,
        mains_frequency_hz=request.mains_frequency_hz,
        shift_mains_lines=request.shift_mains_lines,
        phases_rad=phases_rad if phases_rad is not None or optimise else [0.0] * len(freqs),
        optimiser=stored_phases,
    )
    if stroke_peak_to_peak_m is not None:
        check_stroke(plan, stroke_peak_to_peak_m)
    clipped = [f"{f:g} Hz" for f, c in zip(freqs, profile.clipped(freqs), strict=True) if c]
    if clipped:
        note = f"level clipped by the exciter's stroke at {', '.join(clipped)}"
        plan = Plan(
            plan.sample_rate_hz,
            plan.period_samples,
            plan.lines,
            plan.reference_frequency_hz,
            plan.mains_frequency_hz,
            plan.mains_harmonics,
            (*plan.warnings, note),
        )
    return plan
