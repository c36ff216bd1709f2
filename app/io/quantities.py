"""Quantities as people write them: a number with its unit (`0.5g`, `100 mV/g`, `2 min`,
`0.2%`), converted to the unit the program works in, through the pint units library.

Every option and field that holds a quantity reads it here, so the command line and the GUI
accept the same strings and refuse them with the same reason:

    acceleration  m/s^2         bare number = m/s^2; g, gn = standard gravity 9.80665 m/s^2
    sensitivity   mV/(m/s^2)    bare number = mV/(m/s^2); mV/g, V/g, mV/gn; a charge unit
                                (pC/(m/s^2)) is refused: it needs the amplifier's gain
    time          s             bare number = s; ms, min, h
    frequency     Hz            bare number = Hz; kHz
    mass          g             bare number = g (gram here); kg, mg
    percent       %             bare number = percent, `0.2%` the same; a fraction is never
                                implied (0.2 is 0.2 %, not 20 %)

A bare number, or one in the working unit as shown above (`0.2%`, `160 Hz`), never imports
pint (building its registry costs more than a run's start-up budget, issue 34): the library is
imported, and its registry built, the first time another unit has to be read. An error names
the option or field and the reason (`QuantityError`, a refusal: exit 2 on the command line).
"""

from __future__ import annotations

import math
import re
import threading
from dataclasses import dataclass
from typing import TYPE_CHECKING

from app.errors import Refusal

if TYPE_CHECKING:
    import pint

STANDARD_GRAVITY_MS2 = 9.80665  # 1 g, exactly (CGPM 1901, ISO 80000-3)

MAX_TEXT = 64  # characters: longer is not a quantity anyone types
# `g` alone is standard gravity for accelerations and sensitivities (pint's `g` is the gram)
_GRAVITY = re.compile(r"(?<![A-Za-z_])(?:g|gn|G)(?![A-Za-z_0-9])")


class QuantityError(Refusal):
    """A quantity that cannot be read or is out of range; names the option or field."""

    def __init__(self, option: str, reason: str) -> None:
        super().__init__(f"{option}: {reason}" if option else reason)
        self.option, self.reason = option, reason


@dataclass(frozen=True)
class Dimension:
    """What a quantity is: `noun` for messages ("an acceleration"), `unit` the pint
    expression of the unit values are returned in, `shown` that unit as printed, `accepted`
    the units to suggest, `gravity`: a lone `g` is standard gravity (not the gram)."""

    noun: str
    unit: str
    shown: str
    accepted: str
    gravity: bool = False


ACCELERATION = Dimension("an acceleration", "m/s**2", "m/s^2", "m/s^2 or g", gravity=True)
SENSITIVITY = Dimension(
    "a voltage sensitivity", "mV/(m/s**2)", "mV/(m/s^2)", "mV/(m/s^2) or mV/g", gravity=True
)
TIME = Dimension("a time", "s", "s", "s, min or h")
FREQUENCY = Dimension("a frequency", "Hz", "Hz", "Hz or kHz")
MASS = Dimension("a mass", "g", "g", "g or kg")
PERCENT = Dimension("a percentage", "percent", "%", "e.g. 0.2 or 0.2%")

# what a wrongly dimensioned unit is, for the message: (name, a unit of that class), first
# match wins
_CLASSES: tuple[tuple[str, str], ...] = (
    ("a charge sensitivity (it needs the charge amplifier's gain)", "pC/(m/s**2)"),
    ("a voltage sensitivity", "mV/(m/s**2)"),
    ("an acceleration", "m/s**2"),
    ("a rate of change of acceleration", "m/s**3"),
    ("a velocity", "m/s"),
    ("a length", "m"),
    ("a time", "s"),
    ("a frequency", "Hz"),
    ("a mass", "g"),
    ("a voltage", "V"),
    ("a charge", "pC"),
    ("a ratio", "percent"),
)
# a number, then its unit (nothing else: no arithmetic, which pint would otherwise evaluate)
_NUMBER_UNIT = re.compile(r"^([+-]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][+-]?\d+)?)\s*(.*)$")
_LOCK = threading.Lock()


def registry() -> pint.UnitRegistry:
    """The one unit registry, built on first use (pint is imported only here; thread-safe:
    a GUI field and a worker may read a unit at once)."""
    global _REGISTRY
    with _LOCK:
        if _REGISTRY is None:
            import pint

            _REGISTRY = pint.UnitRegistry()
        return _REGISTRY


_REGISTRY: pint.UnitRegistry | None = None


def _unit_class(unit: pint.Unit) -> str:
    ureg = registry()
    for name, example in _CLASSES:
        if unit.dimensionality == ureg.parse_units(example).dimensionality:
            return name
    return f"of dimension {unit.dimensionality}"


def to_unit(text: str, option: str, dimension: Dimension) -> float:
    """`text` in `dimension`'s unit: a bare number is taken in that unit, else a number then
    its unit, read by pint and converted. QuantityError naming `option` when it is not a
    finite quantity of that dimension."""
    plain = text.strip()
    if not plain:
        raise QuantityError(option, f"empty; give {dimension.noun} ({dimension.accepted})")
    if len(plain) > MAX_TEXT:
        raise QuantityError(option, f"{plain[:20]!r}...: too long for a quantity")
    try:
        value = float(plain)
    except ValueError:
        value = _with_unit(plain, option, dimension)
    if not math.isfinite(value):
        raise QuantityError(option, f"must be a finite number, got {plain!r}")
    return value


def _unit(text: str, option: str, dimension: Dimension, whole: str) -> pint.Unit:
    """The unit `text` names, in `dimension` (QuantityError naming the unit's class if not)."""
    ureg = registry()
    import pint

    expression = text.replace("²", "^2").replace("³", "^3")
    if dimension.gravity:
        expression = _GRAVITY.sub("g_n", expression)
    not_one = f"{whole!r} is not {dimension.noun} ({dimension.accepted})"
    try:
        unit = ureg.parse_units(expression)
    except pint.UndefinedUnitError as exc:
        names = ", ".join(repr(n) for n in exc.unit_names) or repr(text)
        raise QuantityError(option, f"{not_one}: unknown unit {names}") from None
    except Exception:  # pint's parser: any malformed unit text
        raise QuantityError(option, f"{not_one}: {text!r} cannot be read as a unit") from None
    wanted = ureg.parse_units(dimension.unit)
    if unit.dimensionality != wanted.dimensionality or unit == ureg.dimensionless:
        raise QuantityError(option, f"{not_one}: {text} is {_unit_class(unit)}")
    return unit


def _with_unit(text: str, option: str, dimension: Dimension) -> float:
    """A number followed by its unit, in `dimension`'s unit."""
    match = _NUMBER_UNIT.match(text)
    if match is None or not match.group(2):
        nothing = QuantityError(
            option, f"{text!r} is not a number nor {dimension.noun} ({dimension.accepted})"
        )
        if any(c.isdigit() for c in text):
            raise nothing
        try:
            _unit(text, option, dimension, text)  # a unit alone: its class when wrong ('g/s')
        except QuantityError as exc:
            unreadable = "unknown unit" in exc.reason or "cannot be read" in exc.reason
            raise (nothing if unreadable else exc) from None
        raise QuantityError(
            option, f"{text!r}: a number is missing ({dimension.noun}: {dimension.accepted})"
        )
    number, unit_text = float(match.group(1)), match.group(2)
    if unit_text.strip() == dimension.shown and math.isfinite(number):
        return number  # the working unit itself (`0.2%`, `160 Hz`): pint would return it as is
    unit = _unit(unit_text, option, dimension, text)
    if not math.isfinite(number):
        raise QuantityError(option, f"must be a finite number, got {text!r}")
    ureg = registry()
    return float(ureg.Quantity(number, unit).to(dimension.unit).magnitude)


@dataclass(frozen=True)
class Quantity:
    """An option's or field's quantity: its dimension and range (in the dimension's unit;
    closed unless `open_low` / `open_high`)."""

    dimension: Dimension
    low: float
    high: float
    open_low: bool = False
    open_high: bool = False
    shown: str = ""  # the range as printed, when not in the dimension's unit: "(0, 24 h]"

    def describe(self) -> str:
        """The range as printed in --help and tool tips, e.g. '(0, 1000] m/s^2'."""
        if self.shown:
            return self.shown
        left, right = "(" if self.open_low else "[", ")" if self.open_high else "]"
        return f"{left}{self.low:g}, {self.high:g}{right} {self.dimension.shown}"

    def parse(self, text: str, option: str) -> float:
        """`text` in the dimension's unit, within the range; QuantityError naming `option`."""
        return self.check(to_unit(text, option, self.dimension), option, text)

    def check(self, value: float, option: str, text: str | None = None) -> float:
        """`value` (in the dimension's unit) if it is finite and within the range, else
        QuantityError naming `option` (`text`: as typed, for the message)."""
        if not math.isfinite(value):
            raise QuantityError(option, f"must be a finite number, got {value!r}")
        if text is None:
            text = f"{value:g}"
        too_low = value <= self.low if self.open_low else value < self.low
        too_high = value >= self.high if self.open_high else value > self.high
        if too_low or too_high:
            shown = text.strip()
            typed = _NUMBER_UNIT.match(shown)
            if typed is not None and typed.group(2) and float(typed.group(1)) != value:
                shown += f" = {value:g} {self.dimension.shown}"
            raise QuantityError(option, f"must be in {self.describe()}, got {shown}")
        return value


#: How every percent option and field reads a number (stated in each one's --help).
PERCENT_RULE = "in percent: 5 and 5% both mean 5 % (a bare number is percent, never a fraction)"

# The quantities of the run's options and the GUI's fields (one definition for both faces).
LEVEL = Quantity(ACCELERATION, 0.0, 1000.0, open_low=True)  # peak per line
NOMINAL_SENSITIVITY = Quantity(SENSITIVITY, 0.0, 1e6, open_low=True)
TOLERANCE = Quantity(PERCENT, 0.0, 100.0, open_low=True)  # the DUT's, of its characteristic
TARGET_UA = Quantity(PERCENT, 0.0, 100.0, open_low=True)  # relative type A target
# the bound on the acquisition time
MAX_TIME = Quantity(TIME, 0.0, 24 * 3600.0, open_low=True, shown="(0, 24 h]")
FADE_IN = Quantity(TIME, 0.001, 60.0)
STEPPED_BLOCK = Quantity(TIME, 0.01, 10.0)  # the stepped sine's shortest block per sine fit
DUT_MASS = Quantity(MASS, 0.0, 100_000.0)
SAMPLE_RATE = Quantity(FREQUENCY, 1.0, 1e7)
LINE_FREQUENCY = Quantity(FREQUENCY, 0.0, 1e6, open_low=True)  # a reference or corner
MAINS = Quantity(FREQUENCY, 1.0, 1000.0)
SKEW = Quantity(TIME, -1e-3, 1e-3)  # inter-channel delay


def parse_level(text: str, option: str) -> float:
    """A peak acceleration per line in m/s^2: '5', '5 m/s^2', '0.5g' (= 4.903325)."""
    return LEVEL.parse(text, option)


def parse_sensitivity(text: str, option: str) -> float:
    """A voltage sensitivity in mV/(m/s^2): '10.2', '100mV/g' (= 10.197), '0.1 V/g'."""
    return NOMINAL_SENSITIVITY.parse(text, option)


def parse_percent(text: str, option: str) -> float:
    """A relative quantity in percent, (0, 100]: '0.2' and '0.2%' are both 0.2 %."""
    return TARGET_UA.parse(text, option)


def parse_tolerance(text: str, option: str) -> float:
    """A tolerance in percent, (0, 100]: '5' and '5%' are both 5 %."""
    return TOLERANCE.parse(text, option)


def parse_seconds(text: str, option: str) -> float:
    """A time bound in s, (0, 24 h]: '45', '30s', '2 min', '1.5h'."""
    return MAX_TIME.parse(text, option)


def parse_mass(text: str, option: str) -> float:
    """A DUT mass in g (the gram here), [0, 100 kg]: '25', '25 g', '0.1 kg'."""
    return DUT_MASS.parse(text, option)


def parse_frequency(text: str, option: str) -> float:
    """A frequency in Hz, (0, 1 MHz]: '160', '1.6 kHz'."""
    return LINE_FREQUENCY.parse(text, option)
