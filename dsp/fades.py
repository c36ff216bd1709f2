"""Fades of the multisine (SPEC.md section 4): a raised-cosine envelope so the output starts and
ends at exactly 0 V, and the table motion the fades cause (issue 34: the preflight's predicted
peaks cover them). Gains are dimensionless; lengths in samples, frequencies in Hz, times in s,
motion in m/s^2, m/s and m.

Lengths (issue 34 point 2): a fade-in of FADE_IN_CYCLES cycles of the lowest line before the
LPM's record (its transient term estimates what the fade leaves in the record), and a fade-out
of FADE_OUT_CYCLES cycles. A raised cosine over T = N cycles of a line of acceleration a at
w leaves the table, moving as a free mass during the fade, a velocity offset of
(a/w) |1 + e^{j 2 pi N}| / (2 |1 - 4 N^2|) (the half-sine spectrum of the envelope's slope):
a third of the line's velocity amplitude for N = 1, zero for N = 1.5, 1/63 for N = 4. So 1.5
cycles bring the lowest line (the largest velocity and displacement) to rest as well as four
did; the higher lines are shorter fades of more cycles. `fade_motion` computes all of it for
a plan's lines.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = [
    "FADE_IN_CYCLES",
    "FADE_OUT_CYCLES",
    "FADE_OUT_MIN_S",
    "FadeMotion",
    "fade_envelope",
    "fade_in_samples",
    "fade_in_seconds",
    "fade_motion",
    "fade_out_envelope",
    "fade_out_samples",
    "fade_out_seconds",
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


FADE_IN_CYCLES = 1.0  # the LPM's fade-in: cycles of the lowest line (at most one period)
FADE_OUT_CYCLES = 1.5  # cycles of the lowest line a fade-out lasts at least (issue 34: was 4)
FADE_OUT_MIN_S = 0.05  # and at least this (s): the exciter's suspension is far faster


def fade_in_seconds(lowest_frequency_hz: float, seconds: float | None = None) -> float:
    """The fade-in before an LPM record (s): `seconds` when given, else FADE_IN_CYCLES cycles
    of the lowest line."""
    if seconds is not None:
        return seconds
    if not lowest_frequency_hz > 0:
        raise ValueError("fade-in: the lowest frequency must be > 0")
    return FADE_IN_CYCLES / lowest_frequency_hz


def fade_in_samples(
    lowest_hz: float, sample_rate_hz: float, period_samples: int, s: float | None
) -> int:
    """Fade-in length in samples: `s` seconds, else FADE_IN_CYCLES of the lowest line; within
    2 .. one period."""
    seconds = fade_in_seconds(lowest_hz, s)
    return int(min(max(2, math.ceil(seconds * sample_rate_hz)), period_samples))


def fade_out_seconds(lowest_frequency_hz: float) -> float:
    """A fade-out's length (s): FADE_OUT_CYCLES cycles of the lowest line, at least
    FADE_OUT_MIN_S."""
    if not lowest_frequency_hz > 0:
        raise ValueError("fade-out: frequency must be > 0")
    return max(FADE_OUT_CYCLES / lowest_frequency_hz, FADE_OUT_MIN_S)


def fade_out_samples(lowest_frequency_hz: float, sample_rate_hz: float) -> int:
    """Length in samples of a fade-out (SPEC s.4, issues 14 and 34): FADE_OUT_CYCLES cycles of
    the lowest line, at least FADE_OUT_MIN_S. 1.5 cycles of a raised cosine leave the lowest
    line no velocity (module docstring); the residual motion of all lines is `fade_motion`'s."""
    if not (lowest_frequency_hz > 0 and sample_rate_hz > 0):
        raise ValueError("fade-out: frequency and sample rate must be > 0")
    return max(2, math.ceil(fade_out_seconds(lowest_frequency_hz) * sample_rate_hz))


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


@dataclass(frozen=True)
class FadeMotion:
    """The table motion during a fade-in from rest and a fade-out to rest (free mass during
    each fade): the largest |acceleration|, |velocity| and |displacement| and the lowest and
    highest displacement reached in either fade, the offsets the fade-in leaves on the steady
    orbit, and the residual velocity and displacement after the fade-out. SI units."""

    acceleration_peak_ms2: float
    velocity_peak_m_per_s: float
    displacement_peak_m: float
    displacement_low_m: float
    displacement_high_m: float
    offset_velocity_m_per_s: float  # after the fade-in: velocity - the steady orbit's
    offset_displacement_m: float
    residual_velocity_m_per_s: float  # after the fade-out
    residual_displacement_m: float


POINTS_PER_CYCLE = 16  # peaks searched on this many points per cycle of the highest line
GRID_SHARE = 0.01  # of those whose velocity amplitude is at least this share of the largest
MAX_POINTS = 50_000  # per fade: beyond, a coarser grid (the motion is the low lines')


def _integrals(omega: np.ndarray, tau: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """int_0^tau e^{j omega s} ds and its integral again, exact, for every omega (columns) at
    every tau (rows); a series where |omega tau| is small (no cancellation)."""
    x = np.outer(tau, omega)
    small = np.abs(omega) * float(tau[-1]) < 1e-4
    safe = np.where(small, 1.0, omega)
    rotor = np.exp(1j * x)
    first = (rotor - 1) / (1j * safe)
    second = -(rotor - 1 - 1j * x) / safe**2
    if np.any(small):
        t = tau[:, None]
        first = np.where(small, t + 0.5j * x * t, first)
        second = np.where(small, t**2 / 2 + 1j * x * t**2 / 6, second)
    return first, second


def fade_motion(
    frequencies_hz: np.ndarray,
    acceleration: np.ndarray,
    fade_in_s: float,
    fade_out_s: float,
) -> FadeMotion:
    """The motion of a table driven with acceleration x(t) = Re sum_k A_k e^{j w_k t}
    (`acceleration`: complex A_k per line, m/s^2; t = 0 at a period boundary) faded in over
    [-fade_in_s, 0] from rest and faded out over [0, fade_out_s] from the steady orbit,
    raised-cosine envelopes (as played). During a fade the table is taken as a free mass (an
    exciter above its suspension resonance: mass-controlled, the case where a short fade
    leaves the most): velocity and displacement are the integrals of the faded acceleration,
    computed exactly (the envelope times a line is three exponentials), their peaks searched
    on a grid of POINTS_PER_CYCLE points per cycle of the highest line that moves (velocity
    amplitude at least GRID_SHARE of the largest line's). What a fade leaves (an
    offset from the steady orbit after the fade-in, a residual motion after the fade-out) the
    suspension returns; its time constant is no stand-file figure, so the offsets are
    reported, and the preflight adds them to the steady orbit's peaks."""
    f = np.asarray(frequencies_hz, float)
    a = np.asarray(acceleration, complex)
    if f.shape != a.shape or f.size == 0 or not np.all(f > 0):
        raise ValueError("fade motion: one complex acceleration per line, frequencies > 0")
    if not (fade_in_s > 0 and fade_out_s > 0):
        raise ValueError("fade motion: fade lengths must be > 0 s")
    w = 2 * np.pi * f
    steady_v = float((a / (1j * w)).sum().real)  # the steady orbit at t = 0
    steady_d = float((-a / w**2).sum().real)
    speed = np.abs(a) / w  # each line's velocity amplitude: the grid follows the lines that move
    grid_hz = float(np.max(f[speed >= GRID_SHARE * speed.max()]))

    def piece(start_s: float, length_s: float, sign: float) -> tuple[np.ndarray, ...]:
        """Acceleration, velocity, displacement over one fade; envelope 0.5 + sign 0.5 cos."""
        n = int(min(MAX_POINTS, max(64, math.ceil(length_s * grid_hz * POINTS_PER_CYCLE))))
        tau = length_s * np.arange(n + 1) / n
        envelope = 0.5 + sign * 0.5 * np.cos(np.pi * tau / length_s)
        acc = np.zeros(n + 1)
        v = np.zeros(n + 1, complex)
        d = np.zeros(n + 1, complex)
        slope = np.pi / length_s
        chunk = max(1, 2_000_000 // (n + 1))  # lines at a time: memory bounded
        for lo in range(0, w.size, chunk):
            omega = w[lo : lo + chunk]
            b = a[lo : lo + chunk] * np.exp(1j * omega * start_s)
            acc += (np.exp(1j * np.outer(tau, omega)) @ b).real
            for weight, shift in ((0.5, 0.0), (0.25 * sign, slope), (0.25 * sign, -slope)):
                first, second = _integrals(omega + shift, tau)
                v += weight * (first @ b)
                d += weight * (second @ b)
        v0, d0 = (0.0, 0.0) if sign < 0 else (steady_v, steady_d)  # in: from rest
        return envelope * acc, v0 + v.real, d0 + v0 * tau + d.real

    acc_in, v_in, d_in = piece(-fade_in_s, fade_in_s, -1.0)
    acc_out, v_out, d_out = piece(0.0, fade_out_s, 1.0)
    both_d = np.concatenate((d_in, d_out))
    return FadeMotion(
        acceleration_peak_ms2=float(max(np.max(np.abs(acc_in)), np.max(np.abs(acc_out)))),
        velocity_peak_m_per_s=float(max(np.max(np.abs(v_in)), np.max(np.abs(v_out)))),
        displacement_peak_m=float(np.max(np.abs(both_d))),
        displacement_low_m=float(np.min(both_d)),
        displacement_high_m=float(np.max(both_d)),
        offset_velocity_m_per_s=float(v_in[-1] - steady_v),
        offset_displacement_m=float(d_in[-1] - steady_d),
        residual_velocity_m_per_s=float(v_out[-1]),
        residual_displacement_m=float(d_out[-1]),
    )
