"""ISO 266 preferred frequencies for acoustics/vibration, one-third-octave series (SPEC.md s.3).

The exact (base-ten) mid-band frequencies are f_n = 10^(n/10) Hz; the preferred (nominal)
values are those rounded to the R10 series 1, 1.25, 1.6, 2, 2.5, 3.15, 4, 5, 6.3, 8 per decade.
Band number n = -4 is 0.4 Hz (exact 0.398 Hz; ISO 16063-21 starts there: 0.4, 0.5, 0.63,
0.8 Hz below 1 Hz), n = 0 is 1 Hz, n = 43 is 20 kHz (exact 19 952.6 Hz). The series goes on
past ISO 266's 20 kHz, as resonance searches need (SPEC.md s.3): n = 44, 45, 46 are 25, 31.5 and
40 kHz; a fill ("1000,...,31500") stops at none of them.
"""

from __future__ import annotations

import math

NOMINAL_MANTISSAS: tuple[float, ...] = (1.0, 1.25, 1.6, 2.0, 2.5, 3.15, 4.0, 5.0, 6.3, 8.0)
MIN_BAND = -4  # 0.4 Hz
MAX_BAND = 46  # 40 kHz (ISO 266 ends at 20 kHz; the R10 series continues)


def nominal_frequency(band: int) -> float:
    """Preferred (nominal) frequency of ISO 266 band number `band`, in Hz."""
    if not MIN_BAND <= band <= MAX_BAND:
        raise ValueError(f"ISO 266 band number must be {MIN_BAND}..{MAX_BAND}, got {band}")
    decade, index = divmod(band, 10)
    return round(NOMINAL_MANTISSAS[index] * 10**decade, 6)


def exact_frequency(band: int) -> float:
    """Exact base-ten mid-band frequency 10^(n/10) of band number `band`, in Hz."""
    if not MIN_BAND <= band <= MAX_BAND:
        raise ValueError(f"ISO 266 band number must be {MIN_BAND}..{MAX_BAND}, got {band}")
    return 10.0 ** (band / 10.0)


def band_number(nominal_hz: float) -> int:
    """Band number of a preferred frequency in Hz; ValueError if it is not an ISO 266 value."""
    if not (math.isfinite(nominal_hz) and nominal_hz > 0):
        raise ValueError(f"{nominal_hz!r} Hz is not an ISO 266 preferred frequency")
    band = round(10.0 * math.log10(nominal_hz))
    if MIN_BAND <= band <= MAX_BAND and math.isclose(
        nominal_frequency(band), nominal_hz, rel_tol=1e-9
    ):
        return band
    raise ValueError(f"{nominal_hz:g} Hz is not an ISO 266 preferred frequency (0.4 Hz-40 kHz)")


def is_preferred(frequency_hz: float) -> bool:
    """True when `frequency_hz` is an ISO 266 preferred one-third-octave value."""
    try:
        band_number(frequency_hz)
    except ValueError:
        return False
    return True


def nominal_frequencies(min_hz: float = 1.0, max_hz: float = 20_000.0) -> tuple[float, ...]:
    """Preferred frequencies f with min_hz <= f <= max_hz, ascending, in Hz."""
    if min_hz > max_hz:
        raise ValueError(f"min_hz ({min_hz:g}) must not exceed max_hz ({max_hz:g})")
    values = (nominal_frequency(n) for n in range(MIN_BAND, MAX_BAND + 1))
    return tuple(f for f in values if min_hz * (1 - 1e-12) <= f <= max_hz * (1 + 1e-12))
