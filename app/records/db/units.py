"""Sensitivity units of accelerometer models and their exact conversions.

Everything is stored in the unit the sensor model states and converted here when compared with
a result, which is always in mV/(m/s^2). 1 g = 9.80665 m/s^2 exactly (CGPM 1901, ISO 80000-3).
A charge sensitivity in pC/(m/s^2) becomes mV/(m/s^2) only through the charge amplifier's
gain in mV/pC, so it converts 1:1 at a stated 1 mV/pC and is flagged as charge.
"""

from __future__ import annotations

STANDARD_GRAVITY_MS2 = 9.80665

# unit -> factor to mV/(m/s^2) (charge units at a unit charge-amplifier gain of 1 mV/pC)
SENSITIVITY_UNITS: dict[str, float] = {
    "mV/(m/s^2)": 1.0,
    "pC/(m/s^2)": 1.0,
    "mV/g": 1.0 / STANDARD_GRAVITY_MS2,
}
CHARGE_UNITS = frozenset({"pC/(m/s^2)"})


def check_unit(unit: str, field: str = "unit") -> str:
    """`unit` if it is one we know; ValueError naming the field and the known units."""
    if unit not in SENSITIVITY_UNITS:
        known = ", ".join(SENSITIVITY_UNITS)
        raise ValueError(f"{field}: unknown unit {unit!r} (known: {known})")
    return unit


def to_mv_per_ms2(value: float, unit: str) -> float:
    """A sensitivity in `unit` expressed in mV/(m/s^2) (charge units at 1 mV/pC)."""
    return value * SENSITIVITY_UNITS[check_unit(unit)]


def from_mv_per_ms2(value: float, unit: str) -> float:
    """A sensitivity in mV/(m/s^2) expressed in `unit` (charge units at 1 mV/pC)."""
    return value / SENSITIVITY_UNITS[check_unit(unit)]
