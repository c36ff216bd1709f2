"""Frequency plan and multisine excitation (SPEC.md sections 3 and 4; seed eq. 13).

A plan puts every line exactly on a DFT bin of the period, f_k = m_k fs / N_p, and is checked
before anything moves: errors (a line at or above 0.45 fs, two lines on one bin, the reference
frequency missing, ...) refuse the plan; warnings (harmonics or aliases of a line landing on
another line, a line on a low mains harmonic, a line snapped off its nominal value) are kept
with it. Every message names the line.

Amplitudes are target peak table accelerations in m/s^2 per line; phases in rad minimise the
crest factor of the acceleration waveform (dsp.crestfactor).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from dsp import crestfactor, iso266
from dsp.crestfactor import peak_grid_samples
from dsp.errors import InputRefused
from dsp.fades import FADE_OUT_CYCLES as FADE_OUT_CYCLES  # re-exported for its callers
from dsp.fades import FADE_OUT_MIN_S as FADE_OUT_MIN_S
from dsp.fades import fade_envelope as fade_envelope
from dsp.fades import fade_out_envelope as fade_out_envelope
from dsp.fades import fade_out_samples as fade_out_samples
from dsp.mains import mains_harmonic_of_bin, mains_shifted_bins

MAX_FREQUENCY_FRACTION = 0.45  # of fs: multiplexed boards have no anti-alias filter (SPEC s.3)
HARMONICS_CHECKED = (2, 3, 4, 5)  # SPEC s.3: 2nd..5th harmonic of a line
PEAK_OVERSAMPLING = 8  # predicted peaks are taken on an 8x oversampled waveform


PLAN_FORMAT_VERSION = 1


class PhaseOptimiser(Protocol):
    """Where a plan's crest-factor phases come from: `dsp.crestfactor.optimise_phases` or
    anything returning exactly what it returns for the same arguments (e.g. a store of its
    results, app.procedure.phases). Bins, amplitudes (any unit), period in samples; rad."""

    def __call__(
        self, bins: np.ndarray, amplitudes: np.ndarray, period_samples: int, *, seed: int = 0
    ) -> np.ndarray: ...


class PlanError(InputRefused):
    """A plan that must not be run; `problems` lists every reason, each naming its line/field."""

    def __init__(self, problems: Sequence[str]):
        self.problems = tuple(problems)
        super().__init__("; ".join(self.problems))


@dataclass(frozen=True)
class Line:
    """One excited frequency: nominal (ISO 266) and actual bin frequency in Hz, target peak
    table acceleration in m/s^2 and the phase of its sine in rad."""

    nominal_frequency_hz: float
    frequency_hz: float
    bin: int
    amplitude_ms2: float
    phase_rad: float

    @property
    def label(self) -> str:
        """How messages name the line, e.g. '12.5 Hz'."""
        return f"{self.nominal_frequency_hz:g} Hz"


@dataclass(frozen=True)
class PlanCheck:
    """Result of checking plan inputs: errors refuse the plan, warnings are shown with it."""

    errors: tuple[str, ...] = ()
    warnings: tuple[str, ...] = ()

    @property
    def ok(self) -> bool:
        return not self.errors


@dataclass(frozen=True)
class PredictedPeaks:
    """Predicted peaks of the table motion for one period (continuous-time, oversampled)."""

    acceleration_ms2: float
    velocity_m_per_s: float
    displacement_m: float
    displacement_peak_to_peak_m: float


@dataclass(frozen=True)
class Plan:
    """Sample rate (Hz), period length (samples) and lines of a multisine calibration."""

    sample_rate_hz: float
    period_samples: int
    lines: tuple[Line, ...]
    reference_frequency_hz: float
    mains_frequency_hz: float = 50.0
    mains_harmonics: int = 5
    warnings: tuple[str, ...] = field(default=(), compare=False)

    @property
    def period_s(self) -> float:
        return self.period_samples / self.sample_rate_hz

    @property
    def resolution_hz(self) -> float:
        """Bin spacing fs / N_p in Hz."""
        return self.sample_rate_hz / self.period_samples

    @property
    def bins(self) -> np.ndarray:
        return np.array([line.bin for line in self.lines], dtype=np.int64)

    @property
    def frequencies_hz(self) -> np.ndarray:
        return np.array([line.frequency_hz for line in self.lines])

    @property
    def nominal_frequencies_hz(self) -> np.ndarray:
        return np.array([line.nominal_frequency_hz for line in self.lines])

    @property
    def amplitudes_ms2(self) -> np.ndarray:
        return np.array([line.amplitude_ms2 for line in self.lines])

    @property
    def phases_rad(self) -> np.ndarray:
        return np.array([line.phase_rad for line in self.lines])

    @property
    def reference_index(self) -> int:
        """Index of the line at the reference frequency."""
        return _reference_index(self.nominal_frequencies_hz, self.reference_frequency_hz)

    def acceleration_period(self) -> np.ndarray:
        """One period of the target table acceleration in m/s^2 (seed eq. 13)."""
        return crestfactor.synthesize(
            self.bins, self.amplitudes_ms2, self.phases_rad, self.period_samples
        )

    def crest_factor(self) -> float:
        """Crest factor max|x|/rms of the period's samples x(i) (seed eq. 13; SPEC s.4)."""
        return crestfactor.crest_factor(self.acceleration_period())

    def continuous_crest_factor(self) -> float:
        """Crest factor of the continuous-time acceleration (8x oversampled): peaks between
        samples included, so it is >= `crest_factor()`."""
        return self._oversampled_figures[1]

    def predicted_peaks(self) -> PredictedPeaks:
        """Peak acceleration, velocity and displacement of the table (SPEC s.4).

        Integrated per line, v_k = A_k/w_k and d_k = A_k/w_k^2, then synthesised on an
        oversampled grid so that peaks between samples are not missed.
        """
        return self._oversampled_figures[0]

    @functools.cached_property
    def _oversampled_figures(self) -> tuple[PredictedPeaks, float]:
        """`predicted_peaks` and `continuous_crest_factor`, synthesised once per plan (a plan
        is immutable; `accelcal plan` asked for them three times: issue 34 point 3)."""
        acceleration = self._oversampled(0)
        displacement = self._oversampled(2)
        peaks = PredictedPeaks(
            acceleration_ms2=float(np.max(np.abs(acceleration))),
            velocity_m_per_s=float(np.max(np.abs(self._oversampled(1)))),
            displacement_m=float(np.max(np.abs(displacement))),
            displacement_peak_to_peak_m=float(np.ptp(displacement)),
        )
        return peaks, crestfactor.crest_factor(acceleration)

    def _oversampled(self, integrations: int) -> np.ndarray:
        omega = 2 * np.pi * self.frequencies_hz
        amplitudes = self.amplitudes_ms2 / omega**integrations
        phases = self.phases_rad - integrations * np.pi / 2
        return crestfactor.synthesize(
            self.bins, amplitudes, phases, peak_grid_samples(self.period_samples, self.bins)
        )

    def with_amplitudes(self, amplitudes_ms2: Sequence[float] | float) -> Plan:
        """The same plan with new per-line target amplitudes (phases kept)."""
        values = np.broadcast_to(np.asarray(amplitudes_ms2, dtype=float), (len(self.lines),))
        lines = tuple(
            Line(ln.nominal_frequency_hz, ln.frequency_hz, ln.bin, float(a), ln.phase_rad)
            for ln, a in zip(self.lines, values, strict=True)
        )
        return Plan(
            self.sample_rate_hz,
            self.period_samples,
            lines,
            self.reference_frequency_hz,
            self.mains_frequency_hz,
            self.mains_harmonics,
            self.warnings,
        )

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description (all numbers in the units their names carry)."""
        return {
            "format_version": PLAN_FORMAT_VERSION,
            "sample_rate_hz": self.sample_rate_hz,
            "period_samples": self.period_samples,
            "reference_frequency_hz": self.reference_frequency_hz,
            "mains_frequency_hz": self.mains_frequency_hz,
            "mains_harmonics": self.mains_harmonics,
            "lines": [
                {
                    "nominal_frequency_hz": ln.nominal_frequency_hz,
                    "frequency_hz": ln.frequency_hz,
                    "bin": ln.bin,
                    "amplitude_ms2": ln.amplitude_ms2,
                    "phase_rad": ln.phase_rad,
                }
                for ln in self.lines
            ],
            "warnings": list(self.warnings),
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> Plan:
        """Rebuild a stored plan; PlanError naming the field when something is missing/wrong."""
        try:
            lines = tuple(
                Line(
                    float(item["nominal_frequency_hz"]),
                    float(item["frequency_hz"]),
                    int(item["bin"]),
                    float(item["amplitude_ms2"]),
                    float(item["phase_rad"]),
                )
                for item in data["lines"]
            )
            plan = cls(
                sample_rate_hz=float(data["sample_rate_hz"]),
                period_samples=int(data["period_samples"]),
                lines=lines,
                reference_frequency_hz=float(data["reference_frequency_hz"]),
                mains_frequency_hz=float(data.get("mains_frequency_hz", 50.0)),
                mains_harmonics=int(data.get("mains_harmonics", 5)),
            )
        except KeyError as exc:
            raise PlanError([f"plan: missing field {exc.args[0]!r}"]) from None
        except (TypeError, ValueError) as exc:
            raise PlanError([f"plan: malformed field ({exc})"]) from None
        check = check_lines(
            plan.nominal_frequencies_hz,
            plan.sample_rate_hz,
            plan.period_samples,
            plan.reference_frequency_hz,
            mains_frequency_hz=plan.mains_frequency_hz,
            mains_harmonics=plan.mains_harmonics,
            bins=plan.bins,
        )
        if check.errors:
            raise PlanError(check.errors)
        for ln in lines:
            expected = ln.bin * plan.resolution_hz
            if not math.isclose(ln.frequency_hz, expected, rel_tol=1e-9):
                raise PlanError(
                    [f"plan: line {ln.label}: frequency {ln.frequency_hz} Hz is not bin {ln.bin}"]
                )
        return Plan(**{**plan.__dict__, "warnings": check.warnings})


def snap_to_bin(frequency_hz: float, sample_rate_hz: float, period_samples: int) -> int:
    """Nearest DFT bin m of the period for a frequency in Hz (f = m fs / N_p)."""
    return round(frequency_hz * period_samples / sample_rate_hz)


def _reference_index(nominal_hz: np.ndarray, reference_frequency_hz: float) -> int:
    hits = np.flatnonzero(np.isclose(nominal_hz, reference_frequency_hz, rtol=1e-9))
    if hits.size == 0:
        raise PlanError([f"reference frequency {reference_frequency_hz:g} Hz is not a line"])
    return int(hits[0])


def _folded_bin(bin_index: int, period_samples: int) -> int:
    """Bin where content at `bin_index` appears after sampling (aliasing about fs)."""
    folded = bin_index % period_samples
    return period_samples - folded if folded > period_samples // 2 else folded


def _ordinal(n: int) -> str:
    return {1: "1st", 2: "2nd", 3: "3rd"}.get(n, f"{n}th")


def _exact_period_hint(frequency_hz: float) -> str:
    """How long a period puts `frequency_hz` exactly on a bin: the shortest multiple of 10 ms
    (up to 100 s) holding a whole number of its cycles (ISO 266 from 10 Hz: 2 s; 1.6 Hz:
    10 s; 0.63 Hz: 100 s)."""
    for hundredths in range(1, 10_001):
        cycles = frequency_hz * hundredths / 100.0
        if abs(cycles - round(cycles)) < 1e-9 * max(cycles, 1.0) and round(cycles) >= 1:
            return f"a period of a multiple of {hundredths / 100:g} s puts it exactly on a bin"
    return "no period up to 100 s puts it exactly on a bin"


def check_lines(
    nominal_frequencies_hz: Sequence[float] | np.ndarray,
    sample_rate_hz: float,
    period_samples: int,
    reference_frequency_hz: float,
    *,
    mains_frequency_hz: float = 50.0,
    mains_harmonics: int = 5,
    bins: Sequence[int] | np.ndarray | None = None,
) -> PlanCheck:
    """Check plan inputs before anything moves (SPEC s.3); every message names its line.

    `bins` overrides the nearest-bin snapping (for stored plans or shifted lines).
    """
    errors: list[str] = []
    warnings: list[str] = []
    if not (math.isfinite(sample_rate_hz) and sample_rate_hz > 0):
        errors.append(f"sample rate: must be a positive number of Hz, got {sample_rate_hz!r}")
    if int(period_samples) != period_samples or period_samples < 4:
        errors.append(f"period: must be an integer >= 4 samples, got {period_samples!r}")
    if mains_frequency_hz <= 0 or mains_harmonics < 0:
        errors.append("mains: frequency must be > 0 Hz and harmonics >= 0")
    nominal = [float(f) for f in nominal_frequencies_hz]
    if not nominal:
        errors.append("lines: the plan has no lines")
    if errors:
        return PlanCheck(tuple(errors), ())

    resolution = sample_rate_hz / period_samples
    labels = [f"{f:g} Hz" for f in nominal]
    snapped = [
        snap_to_bin(f, sample_rate_hz, period_samples) if math.isfinite(f) and f > 0 else 0
        for f in nominal
    ]
    bins = snapped if bins is None else [int(b) for b in bins]
    shifted = {  # bin -> the mains harmonic its line was moved off (mains_shifted_bins)
        m: h
        for s, m in zip(snapped, bins, strict=True)
        if abs(m - s) == 1
        and (h := mains_harmonic_of_bin(s, resolution, mains_frequency_hz, mains_harmonics))
    }

    for label, f, m in zip(labels, nominal, bins, strict=True):
        if not (math.isfinite(f) and f > 0):
            errors.append(f"line {label}: frequency must be a positive number of Hz")
        elif m <= 0:
            errors.append(
                f"line {label}: below the bin spacing {resolution:g} Hz (lands on DC); "
                "use a longer period"
            )
        elif m * resolution >= MAX_FREQUENCY_FRACTION * sample_rate_hz:
            errors.append(
                f"line {label}: at or above 0.45 fs = {MAX_FREQUENCY_FRACTION * sample_rate_hz:g}"
                " Hz (no anti-alias filter on multiplexed boards); raise the sample rate"
            )
        elif m in shifted:
            h = shifted[m]
            warnings.append(
                f"line {label}: moved one bin off the {_ordinal(h)} mains harmonic "
                f"({h * mains_frequency_hz:g} Hz) to {m * resolution:g} Hz (bin {m}), the "
                "frequency its result is stated at (hum at the mains harmonic then falls on a "
                "free bin, where it is measured; --exact-mains-bins keeps the exact bin)"
            )
        elif not math.isclose(m * resolution, f, rel_tol=1e-9, abs_tol=1e-9):
            warnings.append(
                f"line {label}: snapped to {m * resolution:g} Hz (bin {m}); "
                f"bin spacing {resolution:g} Hz ({_exact_period_hint(f)})"
            )

    owner: dict[int, str] = {}
    for label, m in zip(labels, bins, strict=True):
        if m in owner:
            errors.append(f"line {label}: on the same bin ({m}) as line {owner[m]}")
        else:
            owner[m] = label

    if not any(math.isclose(f, reference_frequency_hz, rel_tol=1e-9) for f in nominal):
        errors.append(
            f"reference frequency {reference_frequency_hz:g} Hz: not among the lines; add it"
        )
    if errors:
        return PlanCheck(tuple(errors), tuple(warnings))

    for label, m in zip(labels, bins, strict=True):
        for harmonic in HARMONICS_CHECKED:
            folded = _folded_bin(harmonic * m, period_samples)
            aliased = harmonic * m > period_samples // 2
            if folded in owner and folded != m:
                how = "alias about fs" if aliased else "harmonic"
                warnings.append(
                    f"line {owner[folded]}: the {_ordinal(harmonic)} {how} of line {label} "
                    "lands on its bin (distortion adds to it)"
                )
    for label, m in zip(labels, bins, strict=True):
        for harmonic in range(1, mains_harmonics + 1):
            mains_bin = harmonic * mains_frequency_hz / resolution
            if abs(mains_bin - m) < 0.5:
                warnings.append(
                    f"line {label}: on the {_ordinal(harmonic)} mains harmonic "
                    f"({harmonic * mains_frequency_hz:g} Hz); a periodic average does not "
                    "remove hum; the default plan moves it one bin (kept here by "
                    "--exact-mains-bins)"
                )
    return PlanCheck(tuple(errors), tuple(warnings))


def check_played_lines(
    nominal_frequencies_hz: Sequence[float] | np.ndarray,
    sample_rate_hz: float,
    period_samples: int,
    reference_frequency_hz: float,
    *,
    mains_frequency_hz: float = 50.0,
    mains_harmonics: int = 5,
    shift_mains_lines: bool = True,
) -> tuple[PlanCheck, list[int]]:
    """`check_lines` on the lines as they will be played, and their bins: snapped to the
    nearest bin, then (`shift_mains_lines`, the default) moved one bin off the mains
    harmonics (`mains_shifted_bins`). No bins when the nominal lines already fail."""
    check = functools.partial(
        check_lines,
        nominal_frequencies_hz,
        sample_rate_hz,
        period_samples,
        reference_frequency_hz,
        mains_frequency_hz=mains_frequency_hz,
        mains_harmonics=mains_harmonics,
    )
    first = check()
    if first.errors:
        return first, []
    bins = [snap_to_bin(float(f), sample_rate_hz, period_samples) for f in nominal_frequencies_hz]
    if not shift_mains_lines:
        return first, bins
    resolution = sample_rate_hz / period_samples
    bins = mains_shifted_bins(bins, resolution, mains_frequency_hz, mains_harmonics)
    return check(bins=bins), bins


def make_plan(
    nominal_frequencies_hz: Sequence[float] | np.ndarray,
    sample_rate_hz: float,
    period_samples: int,
    amplitude_ms2: float | Sequence[float],
    reference_frequency_hz: float,
    *,
    mains_frequency_hz: float = 50.0,
    mains_harmonics: int = 5,
    shift_mains_lines: bool = True,
    phases_rad: Sequence[float] | None = None,
    seed: int = 0,
    optimiser: PhaseOptimiser | None = None,
) -> Plan:
    """Build a checked plan; PlanError lists every failing line.

    Amplitudes are target peak table accelerations (m/s^2), one value for all lines or one per
    line. Without `phases_rad`, phases minimise the crest factor: `optimiser` (default
    dsp.crestfactor.optimise_phases; they depend only on the lines, the amplitudes' ratios,
    the period and `seed`). `shift_mains_lines` (the default, issue 32) moves a line sitting on
    a mains harmonic by one bin (`mains_shifted_bins`; a plan warning states where); False
    keeps the exact bins (the line then carries the hum it cannot separate).
    """
    nominal = [float(f) for f in nominal_frequencies_hz]
    amplitudes = np.asarray(amplitude_ms2, dtype=float)
    if amplitudes.ndim == 0:
        amplitudes = np.full(len(nominal), float(amplitudes))
    problems = []
    if amplitudes.shape != (len(nominal),):
        problems.append(
            f"amplitudes: {amplitudes.size} values for {len(nominal)} lines; "
            "give one or one per line"
        )
    elif not np.all(np.isfinite(amplitudes) & (amplitudes > 0)):
        bad = [f"{f:g} Hz" for f, a in zip(nominal, amplitudes, strict=True) if not a > 0]
        problems.append(f"amplitude: must be > 0 m/s^2 (lines {', '.join(bad)})")
    if phases_rad is not None and len(phases_rad) != len(nominal):
        problems.append(f"phases: {len(phases_rad)} values for {len(nominal)} lines")
    if problems:
        raise PlanError(problems)

    check, bins = check_played_lines(
        nominal,
        sample_rate_hz,
        period_samples,
        reference_frequency_hz,
        mains_frequency_hz=mains_frequency_hz,
        mains_harmonics=mains_harmonics,
        shift_mains_lines=shift_mains_lines,
    )
    if check.errors:
        raise PlanError(check.errors)
    resolution = sample_rate_hz / period_samples

    if phases_rad is None:
        optimise = crestfactor.optimise_phases if optimiser is None else optimiser
        phases = optimise(np.asarray(bins), amplitudes, int(period_samples), seed=seed)
    else:
        phases = np.asarray(phases_rad, dtype=float)
    lines = tuple(
        Line(f, m * resolution, m, float(a), float(p) % (2 * np.pi))
        for f, m, a, p in zip(nominal, bins, amplitudes, phases, strict=True)
    )
    return Plan(
        float(sample_rate_hz),
        int(period_samples),
        lines,
        float(reference_frequency_hz),
        float(mains_frequency_hz),
        int(mains_harmonics),
        check.warnings,
    )


@dataclass(frozen=True)
class Preset:
    """A named plan: ISO 266 lines between two frequencies at a sample rate and period."""

    name: str
    description: str
    min_frequency_hz: float
    max_frequency_hz: float
    sample_rate_hz: float
    period_samples: int
    reference_frequency_hz: float = 160.0
    level_ms2: float = 5.0

    @property
    def nominal_frequencies_hz(self) -> tuple[float, ...]:
        return iso266.nominal_frequencies(self.min_frequency_hz, self.max_frequency_hz)


PRESETS: dict[str, Preset] = {
    "piezo": Preset(
        "piezo",
        "piezoelectric DUT, seed plan: ISO 266 10-2500 Hz (25 lines), fs 6 kHz, 2 s period",
        10.0,
        2500.0,
        6000.0,
        12000,
    ),
    "capacitive": Preset(
        "capacitive",
        "capacitive DUT, seed plan: ISO 266 10-4000 Hz (27 lines), fs 12 kHz, 2 s period",
        10.0,
        4000.0,
        12000.0,
        24000,
    ),
}


def preset_plan(
    name: str,
    *,
    level_ms2: float | None = None,
    reference_frequency_hz: float | None = None,
    mains_frequency_hz: float = 50.0,
    shift_mains_lines: bool = True,
    optimiser: PhaseOptimiser | None = None,
) -> Plan:
    """The plan of a named preset (`piezo`, `capacitive`) at a per-line level in m/s^2 peak;
    lines off the mains harmonics unless `shift_mains_lines` is False, phases from
    `optimiser` as for `make_plan`."""
    try:
        preset = PRESETS[name]
    except KeyError:
        raise PlanError(
            [f"preset: unknown {name!r}; choose one of {', '.join(sorted(PRESETS))}"]
        ) from None
    return make_plan(
        preset.nominal_frequencies_hz,
        preset.sample_rate_hz,
        preset.period_samples,
        preset.level_ms2 if level_ms2 is None else level_ms2,
        preset.reference_frequency_hz if reference_frequency_hz is None else reference_frequency_hz,
        mains_frequency_hz=mains_frequency_hz,
        shift_mains_lines=shift_mains_lines,
        optimiser=optimiser,
    )
