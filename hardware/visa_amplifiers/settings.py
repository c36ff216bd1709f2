"""The declarative setting mechanism shared by the VISA drivers: a `Setting` names an
instrument setting once (set command, query, answer parser, validator: a range or allowed
values), answer parsers, and the translation of VISA failures into the stand's error types (a
timeout: VisaTimeoutError; a lost or closed session, a resource not found: DeviceLostError;
anything else: HardwareError).
"""

from __future__ import annotations

import math
import numbers
import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Generic, Protocol, TypeVar

from pyvisa import constants
from pyvisa import errors as visa_errors

from hardware.errors import DeviceLostError, HardwareError, InstrumentError, VisaTimeoutError

T = TypeVar("T")
C = TypeVar("C")  # the type of a OneOf's choices (float, str, bool, float | None)


class VisaResourceLike(Protocol):
    """What the drivers use of a pyvisa message-based resource (tests pass their own)."""

    timeout: Any

    def write(self, message: str) -> Any: ...

    def query(self, message: str) -> str: ...

    def read(self) -> str: ...

    def close(self) -> None: ...


# --------------------------------------------------------------------------------------------
# The declarative setting mechanism
# --------------------------------------------------------------------------------------------


def _as_real(value: object) -> float:
    """A finite real number, or ValueError (bools and strings are refused, not coerced)."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise ValueError(f"{value!r} is not a number")
    x = float(value)
    if not math.isfinite(x):
        raise ValueError(f"{value!r} is not finite")
    return x


def _format_number(x: float) -> str:
    return f"{x:.6g}"


class Validator(Protocol):
    """Turns an allowed value into the text sent to the instrument; refuses others."""

    def to_wire(self, value: object) -> str:
        """The text to send for `value`; ValueError if `value` is not allowed."""
        ...

    def describe(self) -> str:
        """What is allowed, for error messages."""
        ...


@dataclass(frozen=True)
class InRange:
    """A real number in [minimum, maximum], sent with `digits` significant digits."""

    minimum: float
    maximum: float
    unit: str = ""
    digits: int = 6

    def to_wire(self, value: object) -> str:
        x = _as_real(value)
        if not self.minimum <= x <= self.maximum:
            raise ValueError(f"{x:g} is out of range")
        return f"{x:.{self.digits}g}"

    def describe(self) -> str:
        text = f"{_format_number(self.minimum)} to {_format_number(self.maximum)}"
        return f"{text} {self.unit}".rstrip()


def _same_choice(choice: object, value: object) -> bool:
    if choice is None or value is None:
        return choice is value
    if isinstance(choice, bool) or isinstance(value, bool):
        return isinstance(choice, bool) and isinstance(value, bool) and choice == value
    if isinstance(choice, str):
        return isinstance(value, str) and choice.casefold() == value.strip().casefold()
    try:
        return math.isclose(_as_real(value), _as_real(choice), rel_tol=1e-9, abs_tol=0.0)
    except ValueError:
        return False


@dataclass(frozen=True)
class OneOf(Generic[C]):
    """One of a fixed set of values; `choices` maps each allowed value to its wire text.

    Numbers match within a relative 1e-9 (so 0.1 + 0.2 - 0.2 still counts as 0.1), strings
    case-insensitively, None only None (None stands for "off").
    """

    choices: Mapping[C, str]
    unit: str = ""

    def to_wire(self, value: object) -> str:
        for choice, wire in self.choices.items():
            if _same_choice(choice, value):
                return wire
        raise ValueError(f"{value!r} is not one of the allowed values")

    def canonical(self, value: object) -> C:
        """The declared choice equal to `value` (e.g. the exact float of the list)."""
        for choice in self.choices:
            if _same_choice(choice, value):
                return choice
        raise ValueError(f"{value!r} is not one of the allowed values")

    def describe(self) -> str:
        names = ["off" if c is None else _describe_choice(c) for c in self.choices]
        return f"one of {', '.join(names)} {self.unit}".rstrip()


def _describe_choice(choice: object) -> str:
    if isinstance(choice, bool) or not isinstance(choice, numbers.Real):
        return str(choice)
    return _format_number(float(choice))


@dataclass(frozen=True)
class Setting(Generic[T]):
    """One instrument setting or reading, declared once.

    `set_command` and `query` are `str.format` templates: `{value}` is the validated wire text,
    other fields (e.g. `{channel}`) are the path given to `command`/`query_command`.
    A setting without `set_command` is read-only. `parse` turns the answer text (already
    stripped of termination and echoed header) into the Python value; it raises ValueError on
    anything it does not recognise.
    """

    name: str
    query: str
    parse: Callable[[str], T]
    set_command: str | None = None
    validator: Validator | None = None

    def allowed(self) -> str:
        return self.validator.describe() if self.validator is not None else "read-only"

    def wire_value(self, value: object, device: str = "") -> str:
        """Validated wire text for `value`, or InstrumentError naming the setting."""
        if self.set_command is None or self.validator is None:
            raise InstrumentError(f"{_prefix(device)}{self.name} is read-only")
        try:
            return self.validator.to_wire(value)
        except (TypeError, ValueError):
            raise InstrumentError(
                f"{_prefix(device)}{self.name} {value!r} refused: allowed {self.allowed()}"
            ) from None

    def command(self, value: object, device: str = "", **path: object) -> str:
        """The complete set command for `value` (validated first, nothing is sent here)."""
        wire = self.wire_value(value, device)
        assert self.set_command is not None
        return self.set_command.format(value=wire, **path)

    def query_command(self, **path: object) -> str:
        return self.query.format(**path)

    def parse_answer(self, answer: str, device: str = "", **path: object) -> T:
        """The parsed answer, or InstrumentError quoting it."""
        try:
            return self.parse(answer)
        except (TypeError, ValueError):
            raise InstrumentError(
                f"{_prefix(device)}cannot read {self.name}: answer {answer!r} to "
                f"{self.query_command(**path)!r} is not understood"
            ) from None


def _prefix(device: str) -> str:
    return f"{device}: " if device else ""


# --- answer parsers --------------------------------------------------------------------------

_OFF_WORDS = frozenset({"off", "of", "none"})
_TRUE_WORDS = frozenset({"1", "on", "true", "yes"})
_FALSE_WORDS = frozenset({"0", "off", "of", "false", "no"})


def parse_float(text: str) -> float:
    """A finite decimal number ('inf', 'nan' and empty answers are refused)."""
    x = float(text.strip())
    if not math.isfinite(x):
        raise ValueError(text)
    return x


def parse_bool(text: str) -> bool:
    """1/0, ON/OFF (also the 2525 mnemonic OF), TRUE/FALSE."""
    word = text.strip().casefold()
    if word in _TRUE_WORDS:
        return True
    if word in _FALSE_WORDS:
        return False
    raise ValueError(text)


def parse_filter_hz(text: str) -> float | None:
    """A filter corner in Hz, or None for Off."""
    word = text.strip()
    if word.casefold() in _OFF_WORDS:
        return None
    x = parse_float(word)
    if x <= 0:
        raise ValueError(text)
    return x


def parse_text(text: str) -> str:
    """Any non-empty printable text (tabs allowed)."""
    value = text.strip()
    if not value or not value.replace("\t", " ").isprintable():
        raise ValueError(text)
    return value


def one_word_of(words: Sequence[str]) -> Callable[[str], str]:
    """A parser accepting one of `words` (case-insensitive) and returning its declared form."""
    by_key = {w.casefold(): w for w in words}

    def parse(text: str) -> str:
        word = by_key.get(text.strip().casefold())
        if word is None:
            raise ValueError(text)
        return word

    return parse


_FAULT_ANSWER = re.compile(r'^\s*([+-]?\d+)\s*(?:,\s*"?(.*?)"?)?\s*$')


def parse_fault(text: str) -> str | None:
    """SCPI-style `<code>,"<text>"`: None for code 0, else the text with its code."""
    match = _FAULT_ANSWER.match(text)
    if match is None:
        raise ValueError(text)
    code = int(match.group(1))
    message = (match.group(2) or "").strip()
    if code == 0:
        return None
    return f"{message} (fault code {code})" if message else f"fault code {code}"


# --------------------------------------------------------------------------------------------
# VISA error translation and the common instrument base
# --------------------------------------------------------------------------------------------

_LOST_CODES = frozenset(
    {
        constants.StatusCode.error_connection_lost,
        constants.StatusCode.error_resource_not_found,
        constants.StatusCode.error_invalid_object,  # also VI_ERROR_INV_SESSION
        constants.StatusCode.error_no_listeners,
    }
)


def translate_visa_error(exc: Exception, device: str, command: str) -> HardwareError:
    """The stand's error for a pyvisa exception raised while sending `command` to `device`."""
    if isinstance(exc, visa_errors.InvalidSession):
        return DeviceLostError(
            f"{device}: the VISA session is closed or invalid (while sending {command!r}); "
            "reconnect the instrument and open it again"
        )
    code = getattr(exc, "error_code", None)
    if code == constants.StatusCode.error_timeout:
        return VisaTimeoutError(
            f"{device}: no answer to {command!r} within the timeout; check that it is "
            "powered, connected and at this address"
        )
    if code in _LOST_CODES:
        return DeviceLostError(
            f"{device}: connection lost (while sending {command!r}: {exc}); check cable and "
            "power, then open it again"
        )
    return HardwareError(f"{device}: VISA error while sending {command!r}: {exc}")
