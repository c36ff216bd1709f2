"""Per-line amplitude profiles and the stroke check of a plan (issue 26 point 4).

A profile gives each line its target peak table acceleration in m/s^2: constant acceleration,
or below a corner frequency constant velocity (A ~ f) or constant displacement (A ~ f^2),
then clipped so that no single line uses more than `stroke_share` of the exciter's stroke
(a line's displacement is A / w^2 peak, 2 A / w^2 peak-to-peak). `check_stroke` refuses a
plan whose predicted table travel (all lines together, dsp.multisine.Plan.predicted_peaks)
exceeds the stroke, before anything moves. Units: Hz, m/s^2, m.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from enum import StrEnum

import numpy as np

from dsp.multisine import Plan, PlanError


class Profile(StrEnum):
    """What is held constant below the corner frequency (above it: acceleration)."""

    ACCELERATION = "acceleration"
    VELOCITY = "velocity"
    DISPLACEMENT = "displacement"


def line_displacement_pp_m(
    frequencies_hz: Sequence[float] | np.ndarray, amplitudes_ms2: Sequence[float] | np.ndarray
) -> np.ndarray:
    """Peak-to-peak table displacement in m of each line alone: 2 A / (2 pi f)^2."""
    f = np.asarray(frequencies_hz, dtype=float)
    return 2.0 * np.asarray(amplitudes_ms2, dtype=float) / (2.0 * np.pi * f) ** 2


@dataclass(frozen=True)
class AmplitudeProfile:
    """`level_ms2` peak acceleration at and above `corner_hz` (every line for ACCELERATION);
    below it constant velocity or displacement; with `stroke_peak_to_peak_m`, each line is
    clipped to `stroke_share` of the stroke."""

    level_ms2: float
    kind: Profile = Profile.ACCELERATION
    corner_hz: float | None = None
    stroke_peak_to_peak_m: float | None = None
    stroke_share: float = 0.5

    def __post_init__(self) -> None:
        if not (math.isfinite(self.level_ms2) and self.level_ms2 > 0):
            raise PlanError([f"level: must be a number > 0 m/s^2, got {self.level_ms2!r}"])
        try:
            Profile(self.kind)
        except ValueError:
            names = ", ".join(p.value for p in Profile)
            raise PlanError([f"profile: unknown {self.kind!r}; choose one of {names}"]) from None
        if self.kind != Profile.ACCELERATION and not (
            self.corner_hz is not None and math.isfinite(self.corner_hz) and self.corner_hz > 0
        ):
            raise PlanError([f"corner: a {self.kind} profile needs a corner frequency > 0 Hz"])
        stroke = self.stroke_peak_to_peak_m
        if stroke is not None and not (math.isfinite(stroke) and stroke > 0):
            raise PlanError([f"stroke: must be > 0 m peak-to-peak, got {stroke!r}"])
        if not 0 < self.stroke_share <= 1:
            raise PlanError([f"stroke share: must be in (0, 1], got {self.stroke_share!r}"])

    def unclipped(self, frequencies_hz: Sequence[float] | np.ndarray) -> np.ndarray:
        """Peak acceleration in m/s^2 per line before the stroke clip."""
        f = np.asarray(frequencies_hz, dtype=float)
        if np.any(~np.isfinite(f) | (f <= 0)):
            raise PlanError(["frequencies: each must be a number > 0 Hz"])
        if self.kind == Profile.ACCELERATION or self.corner_hz is None:
            return np.full(f.shape, float(self.level_ms2))
        power = 1.0 if self.kind == Profile.VELOCITY else 2.0
        return self.level_ms2 * np.minimum(f / self.corner_hz, 1.0) ** power

    def limit_ms2(self, frequencies_hz: Sequence[float] | np.ndarray) -> np.ndarray:
        """Largest peak acceleration per line within its share of the stroke (inf without)."""
        f = np.asarray(frequencies_hz, dtype=float)
        if self.stroke_peak_to_peak_m is None:
            return np.full(f.shape, np.inf)
        return self.stroke_share * self.stroke_peak_to_peak_m / 2.0 * (2.0 * np.pi * f) ** 2

    def amplitudes(self, frequencies_hz: Sequence[float] | np.ndarray) -> np.ndarray:
        """Target peak acceleration in m/s^2 per line (profile, then the stroke clip)."""
        return np.minimum(self.unclipped(frequencies_hz), self.limit_ms2(frequencies_hz))

    def clipped(self, frequencies_hz: Sequence[float] | np.ndarray) -> np.ndarray:
        """Which lines the stroke clip lowered (bool per line)."""
        return self.unclipped(frequencies_hz) > self.limit_ms2(frequencies_hz)


def check_stroke(plan: Plan, stroke_peak_to_peak_m: float) -> float:
    """The plan's predicted peak-to-peak table displacement in m, or PlanError naming the
    line that needs the most travel and the prediction when it exceeds the stroke."""
    predicted = plan.predicted_peaks().displacement_peak_to_peak_m
    if predicted <= stroke_peak_to_peak_m:
        return predicted
    per_line = line_displacement_pp_m(plan.frequencies_hz, plan.amplitudes_ms2)
    worst = int(np.argmax(per_line))
    line = plan.lines[worst]
    raise PlanError(
        [
            f"line {line.label}: the plan predicts {1e3 * predicted:.0f} mm peak-to-peak of "
            f"table travel, beyond the exciter's {1e3 * stroke_peak_to_peak_m:g} mm stroke "
            f"({line.amplitude_ms2:g} m/s^2 at {line.label} alone needs "
            f"{1e3 * per_line[worst]:.0f} mm); lower its level or use a velocity or "
            "displacement profile below a corner frequency"
        ]
    )
