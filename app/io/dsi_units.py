"""D-SI unit strings as a calibrating laboratory writes them in a DCC (`\\milli\\volt\\second
\\tothe{2}\\metre\\tothe{-1}`, `\\pico\\coulomb\\per\\metre\\second\\tothe{-2}`) and the few
plain spellings seen in the wild (`mV/(m/s^2)`, `pC/(m/s²)`, `mV/g`), reduced to a factor and
the dimensions in volt, coulomb, metre, second and radian, so that a reference DCC's
sensitivity, frequency and phase are recognised by what they are, not by their spelling.

`\\per` divides by everything after it (`\\volt\\per\\metre\\second\\tothe{-2}` is V/(m s^-2)).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from enum import StrEnum

STANDARD_GRAVITY_MS2 = 9.80665  # 1 g in m/s^2, exact (CGPM 1901)

_PREFIXES = {
    "yotta": 1e24, "zetta": 1e21, "exa": 1e18, "peta": 1e15, "tera": 1e12, "giga": 1e9,
    "mega": 1e6, "kilo": 1e3, "hecto": 1e2, "deca": 1e1, "deci": 1e-1, "centi": 1e-2,
    "milli": 1e-3, "micro": 1e-6, "nano": 1e-9, "pico": 1e-12, "femto": 1e-15,
    "atto": 1e-18,
}  # fmt: skip
# unit -> (factor to base units, dimensions): V, C, m, s, rad
_UNITS: dict[str, tuple[float, dict[str, int]]] = {
    "volt": (1.0, {"V": 1}),
    "coulomb": (1.0, {"C": 1}),
    "metre": (1.0, {"m": 1}),
    "meter": (1.0, {"m": 1}),
    "second": (1.0, {"s": 1}),
    "hertz": (1.0, {"s": -1}),
    "radian": (1.0, {"rad": 1}),
    "degree": (math.pi / 180.0, {"rad": 1}),
    "one": (1.0, {}),
    "percent": (0.01, {}),
}
_TOKEN = re.compile(r"\\([A-Za-z]+)(?:\{([^}]*)\})?")
_PLAIN = re.compile(
    r"^(?P<prefix>[mupnµμ]?)(?P<unit>V|C)\s*/\s*(?P<per>"
    r"\(\s*m\s*/\s*s\s*(?:\^\s*2|²|2)\s*\)|m\s*/\s*s\s*(?:\^\s*2|²|2)|"
    r"\(?\s*m\s*[·*. ]?\s*s\s*(?:\^\s*-\s*2|⁻²|-2)\s*\)?|g)$"
)
_PLAIN_PREFIX = {"": 1.0, "m": 1e-3, "u": 1e-6, "µ": 1e-6, "μ": 1e-6, "n": 1e-9, "p": 1e-12}
SENSITIVITY_VOLTAGE = {"V": 1, "m": -1, "s": 2}
SENSITIVITY_CHARGE = {"C": 1, "m": -1, "s": 2}
FREQUENCY = {"s": -1}
ANGLE = {"rad": 1}


class Kind(StrEnum):
    """What a unit measures, as far as a reference DCC's table is concerned."""

    VOLTAGE_SENSITIVITY = "voltage sensitivity"
    CHARGE_SENSITIVITY = "charge sensitivity"
    FREQUENCY = "frequency"
    ANGLE = "angle"
    OTHER = "other"


@dataclass(frozen=True)
class Unit:
    """A unit as read: its text, the factor to the base units (V, C, m, s, rad) and its kind."""

    text: str
    factor: float
    kind: Kind

    def to_mv_per_ms2(self, value: float) -> float:
        """A sensitivity in this unit in mV/(m/s^2); a charge sensitivity in pC/(m/s^2) taken
        at 1 mV/pC (app.records.db.units: the charge amplifier's gain is the stand's)."""
        scale = 1e-3 if self.kind is Kind.VOLTAGE_SENSITIVITY else 1e-12
        return value * (self.factor / scale)  # 1e-3 / 1e-3 is 1: mV read as written

    def to_degrees(self, value: float) -> float:
        """An angle in this unit in degrees."""
        return math.degrees(value * self.factor)

    def to_hz(self, value: float) -> float:
        """A frequency in this unit in Hz."""
        return value * self.factor


def _kind(dims: dict[str, int]) -> Kind:
    dims = {k: v for k, v in dims.items() if v}
    if dims == SENSITIVITY_VOLTAGE:
        return Kind.VOLTAGE_SENSITIVITY
    if dims == SENSITIVITY_CHARGE:
        return Kind.CHARGE_SENSITIVITY
    if dims == FREQUENCY:
        return Kind.FREQUENCY
    if dims == ANGLE:
        return Kind.ANGLE
    return Kind.OTHER


def parse_unit(text: str) -> Unit | None:
    """The unit `text` (D-SI, or a plain spelling of a sensitivity), None when it is neither
    (an unknown D-SI token, a stray character)."""
    compact = "".join(text.split())
    if not compact:
        return None
    if not compact.startswith("\\"):
        return _plain(text.strip())
    factor, dims = 1.0, dict[str, int]()
    sign, position, pending = 1, 0, None  # pending: the last unit's (factor, dims) for tothe
    prefix = 1.0
    for match in _TOKEN.finditer(compact):
        if match.start() != position:
            return None
        position = match.end()
        name, argument = match.group(1), match.group(2)
        if name == "per":
            sign = -1
        elif name == "tothe":
            if pending is None or argument is None:
                return None
            try:
                power = float(argument)
            except ValueError:
                return None
            if not power.is_integer():
                return None
            unit_factor, unit_dims, unit_sign = pending
            # the unit was counted once already: add the rest of its power
            factor *= unit_factor ** (unit_sign * (power - 1))
            for key, value in unit_dims.items():
                dims[key] = dims.get(key, 0) + unit_sign * value * (int(power) - 1)
            pending = None
        elif name in _PREFIXES:
            prefix *= _PREFIXES[name]
        elif name in _UNITS:
            unit_factor, unit_dims = _UNITS[name]
            unit_factor *= prefix
            prefix = 1.0
            factor *= unit_factor**sign
            for key, value in unit_dims.items():
                dims[key] = dims.get(key, 0) + sign * value
            pending = (unit_factor, unit_dims, sign)
        else:
            return None
    if position != len(compact) or prefix != 1.0:
        return None
    return Unit(text.strip(), factor, _kind(dims))


def _plain(text: str) -> Unit | None:
    match = _PLAIN.match(text)
    if match is None:
        return None
    factor = _PLAIN_PREFIX[match.group("prefix")]
    if match.group("per") == "g":
        factor /= STANDARD_GRAVITY_MS2
    kind = Kind.VOLTAGE_SENSITIVITY if match.group("unit") == "V" else Kind.CHARGE_SENSITIVITY
    return Unit(text, factor, kind)
