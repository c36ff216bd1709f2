"""VISA drivers for the stand's amplifiers (spec section 14).

- `BK2525Amplifier`: the Brüel & Kjær 2525 measuring (conditioning) amplifier, implementing
  `hardware.interfaces.MeasuringAmplifier`, per its User Manual Vol. 2 (sections cited in the
  code beside each command; what the readable pages did not settle is marked MANUAL UNREAD).
- `ScpiPowerAmplifier`: a remotely controlled power amplifier with a small generic SCPI command
  set, implementing `hardware.interfaces.PowerAmplifier`.

Every instrument setting is declared once, as a `Setting`: a human-readable name, the
set-command template, the query command, a parser for the answer and a validator (a range or a
list of allowed values). A value the validator refuses raises `InstrumentError` naming the
setting and what is allowed, before anything is written to the instrument. VISA failures are
translated into the stand's error types: a timeout becomes `VisaTimeoutError`; a lost
connection, a resource that is not found or a closed/invalid session becomes `DeviceLostError`;
an answer that cannot be parsed becomes `InstrumentError` quoting the answer.

B&K 2525 command set as the driver uses it (manual vol. 2 sections in brackets):

    Header Long                               answers with long header, full names  [4.3.2]
    Identify?                                 identity (no *IDN? on the 2525)  [9.2, 5.3.4]
    :Channel_<n>:Input_Type?                  Charge_... -> C, else V per m/s^2  [5.3, 9.3]
    :Channel_<n>:Measurement_Mode Acceleration                                    [5.3, 9.3]
    :Channel_<n>:Transducer_Sensitivity <x>   SI: C/(m/s^2) or V/(m/s^2), "1E-12" [5.3, 9.3]
    :Channel_<n>:Output_Gain <dB>             dB ("Output_Gain 0")        [5.3; vol. 1, 6.4]
    :Channel_<n>:Upper_Frequency_Limit <Hz>   low-pass corner                     [5.3, 9.3]
    :Channel_<n>:Lower_Frequency_Limit <Hz>   high-pass corner                    [5.3, 9.3]
    :Channel_<n>:Overload?                    NOT in the pages read (see _BK_OVERLOAD)
    Recall_Work?                              the whole set-up, long form     [5.3, Fig 5.16]

Each setting is its own message (every query is the command with "?", 4.1.4); answers carry
the echoed long header (`:Channel_1:Output_Gain 20`), which the driver strips; a header-off
answer (value only) is accepted too. Callers keep pC/(m/s^2) or mV/(m/s^2) and V/V gains: the
driver converts to the wire's SI units and dB and back.

Power amplifier command set (SCPI style):

    OUTP ON|OFF, OUTP?      output relay; the answer may be ON/OFF or 1/0
    GAIN <x>, GAIN?         gain as a fraction of full gain, 0..1 (linear, not dB)
    STAT:FAULT?             <code>,"<text>"; code 0 means no fault
    INT?                    interlock: 1 closed (safe to drive), 0 open
    *IDN?                   identity

Termination is '\\n' both ways. A driver owns the resource it was given or opened: `close()`
closes it (once; further calls do nothing). A resource manager passed in, or created here, is
never closed by the driver, since pyvisa shares one manager between all resources of a library.
After a timeout the instrument's late answer may still be in its output queue; close and reopen
the driver before using it again.
"""

from __future__ import annotations

import math
import numbers
import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, ClassVar, Generic, Protocol, TypeVar

import pyvisa
from pyvisa import constants
from pyvisa import errors as visa_errors

from hardware.errors import (
    AmplifierFaultError,
    DeviceLostError,
    HardwareError,
    InstrumentError,
    VisaTimeoutError,
)
from hardware.interfaces import ConditioningSettings

__all__ = [
    "BK2525_GAINS",
    "BK2525_HIGH_PASS_HZ",
    "BK2525_LOW_PASS_HZ",
    "BK2525_MODES",
    "BK2525_SENSITIVITY_RANGE",
    "BK2525Amplifier",
    "InRange",
    "OneOf",
    "ScpiPowerAmplifier",
    "Setting",
    "VisaResourceLike",
    "parse_bool",
    "parse_fault",
    "parse_filter_hz",
    "parse_float",
    "parse_text",
    "translate_visa_error",
]

T = TypeVar("T")

TERMINATION = "\n"
DEFAULT_TIMEOUT_MS = 2000


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
class OneOf:
    """One of a fixed set of values; `choices` maps each allowed value to its wire text.

    Numbers match within a relative 1e-9 (so 0.1 + 0.2 - 0.2 still counts as 0.1), strings
    case-insensitively, None only None (None stands for "off").
    """

    choices: Mapping[object, str]
    unit: str = ""

    def to_wire(self, value: object) -> str:
        for choice, wire in self.choices.items():
            if _same_choice(choice, value):
                return wire
        raise ValueError(f"{value!r} is not one of the allowed values")

    def canonical(self, value: object) -> object:
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


def _open_resource(
    name: str, resource_manager: pyvisa.ResourceManager | None, timeout_ms: int, label: str
) -> VisaResourceLike:
    if resource_manager is None:
        try:
            resource_manager = pyvisa.ResourceManager()
        except (OSError, ValueError) as exc:
            raise HardwareError(
                f"{label}: no VISA library found ({exc}); install NI-VISA or pyvisa-py"
            ) from exc
    try:
        resource = resource_manager.open_resource(
            name,
            read_termination=TERMINATION,
            write_termination=TERMINATION,
            timeout=timeout_ms,
        )
    except (visa_errors.VisaIOError, visa_errors.InvalidSession) as exc:
        raise translate_visa_error(exc, label, "open") from exc
    if not isinstance(resource, pyvisa.resources.MessageBasedResource):
        resource.close()
        raise InstrumentError(f"{label}: {name} is not a message-based instrument")
    return resource  # type: ignore[return-value]


class _VisaInstrument:
    """Open/close, error translation and the set/query helpers shared by both drivers."""

    kind: ClassVar[str] = "VISA instrument"

    def __init__(
        self,
        resource: str | VisaResourceLike,
        resource_manager: pyvisa.ResourceManager | None = None,
        *,
        timeout_ms: int = DEFAULT_TIMEOUT_MS,
    ) -> None:
        self._identity: str | None = None
        self._resource: VisaResourceLike | None = None
        if isinstance(resource, str):
            self.resource_name = resource
            self.label = f"{self.kind} at {resource}"
            self._resource = _open_resource(resource, resource_manager, timeout_ms, self.label)
        else:
            self.resource_name = str(getattr(resource, "resource_name", "") or "")
            where = self.resource_name or type(resource).__name__
            self.label = f"{self.kind} at {where}"
            self._resource = resource

    # --- low level

    def _require_open(self, command: str) -> VisaResourceLike:
        if self._resource is None:
            raise DeviceLostError(f"{self.label}: closed, cannot send {command!r}")
        return self._resource

    def _write(self, command: str) -> None:
        resource = self._require_open(command)
        try:
            resource.write(command)
        except (visa_errors.VisaIOError, visa_errors.InvalidSession) as exc:
            raise translate_visa_error(exc, self.label, command) from exc

    def _query(self, command: str) -> str:
        """The answer to `command`, termination and surrounding blanks removed."""
        resource = self._require_open(command)
        try:
            answer = resource.query(command)
        except (visa_errors.VisaIOError, visa_errors.InvalidSession) as exc:
            raise translate_visa_error(exc, self.label, command) from exc
        except UnicodeDecodeError as exc:
            raise InstrumentError(
                f"{self.label}: answer to {command!r} is not text: {exc.object!r}"
            ) from exc
        return str(answer).strip()

    def _clean_answer(self, answer: str) -> str:
        """The value part of an answer to a setting's query (drivers strip echoed headers)."""
        return answer

    # --- declarative settings

    def _set(self, setting: Setting[Any], value: object, **path: object) -> None:
        self._write(setting.command(value, self.label, **path))

    def _set_many(self, items: Sequence[tuple[Setting[Any], object]], **path: object) -> str:
        """Validate every (setting, value) first, then send them as ONE ';'-joined message."""
        commands = [setting.command(value, self.label, **path) for setting, value in items]
        message = ";".join(commands)
        self._write(message)
        return message

    def _get(self, setting: Setting[T], **path: object) -> T:
        answer = self._clean_answer(self._query(setting.query_command(**path)))
        return setting.parse_answer(answer, self.label, **path)

    # --- common API

    def identify(self) -> str:
        """The instrument's `*IDN?` answer (also kept for the run record)."""
        self._identity = self._get(_IDENTITY)
        return self._identity

    @property
    def closed(self) -> bool:
        return self._resource is None

    def close(self) -> None:
        """Close the resource; calling it again does nothing."""
        resource, self._resource = self._resource, None
        if resource is None:
            return
        try:
            resource.close()
        except (visa_errors.VisaIOError, visa_errors.InvalidSession) as exc:
            raise translate_visa_error(exc, self.label, "close") from exc

    def __enter__(self):
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    def __repr__(self) -> str:
        state = "closed" if self.closed else "open"
        return f"<{type(self).__name__} {self.label} ({state})>"


_IDENTITY: Setting[str] = Setting("identity", query="*IDN?", parse=parse_text)


# --------------------------------------------------------------------------------------------
# B&K 2525 measuring amplifier
#
# Sources: Brüel & Kjær, Measuring Amplifier Type 2525, User Manual Vol. 2 (BE1394-11), cited
# below as "manual vol. 2, <section>", and Vol. 1 (BE1406-12) as "manual vol. 1, <section>".
# Read: 4.1.4 (mnemonics, a command becomes a query by appending "?"), 4.1.5 (NL is the only
# program message terminator), 4.3.2 (Header OFf|Short|Long, default Long, the three answer
# forms), 5.3 / Fig. 5.16 (Recall_Work? and its long example, which names the channel
# settings and their wire units), 5.3.3 (Status_Byte?), 7.1 (Measurement_Data), 9.1 and the
# first page of Table 9.1 (channel-independent commands). NOT readable in the copy available:
# Table 9.2 (channel-dependent commands: the allowed values, units and mnemonics of every
# Channel_1 setting), 5.3.2 (Measurement_Status register bits, where overloads are reported),
# 5.3.4 (Identify? answer format). What those sections would settle is marked
# "MANUAL UNREAD" below instead of being guessed.
# --------------------------------------------------------------------------------------------


def _one_two_five(lowest_exp: int, highest: float) -> tuple[float, ...]:
    values: list[float] = []
    exp = lowest_exp
    while True:
        for mantissa in (1, 2, 5):
            x = float(f"{mantissa}e{exp}")
            if x > highest * (1 + 1e-12):
                return tuple(values)
            values.append(x)
        exp += 1


#: Output gains the driver accepts, V/V, 0.1 to 10000 in 1-2-5 steps. On the wire the 2525
#: takes Output_Gain in dB (manual vol. 2, 5.3: "Input_Gain -20;Fine_Gain 0;Output_Gain 0";
#: manual vol. 1, 6.4: "Output Gain to 0dB"); the driver converts. MANUAL UNREAD (Table 9.2):
#: which dB values the 2525 accepts; a value it refuses is caught by the read-back in
#: `configure`, never used silently.
BK2525_GAINS: tuple[float, ...] = _one_two_five(-1, 10000.0)
#: Lower_Frequency_Limit (high-pass) corners in Hz (None = OFf). MANUAL UNREAD (Table 9.2):
#: only 1 Hz is confirmed (the 5.3 example); the list and OFf are the driver's earlier choice.
BK2525_HIGH_PASS_HZ: tuple[float | None, ...] = (None, 0.1, 1.0, 10.0)
#: Upper_Frequency_Limit (low-pass) corners in Hz (None = OFf). MANUAL UNREAD (Table 9.2):
#: only 10000 Hz is confirmed (the 5.3 example); the list and OFf are the driver's choice.
BK2525_LOW_PASS_HZ: tuple[float | None, ...] = (None, 1000.0, 3000.0, 10000.0, 22400.0)
#: Measurement modes. Acceleration is the manual's (vol. 2, 5.3 example) and the only one the
#: driver sets; MANUAL UNREAD (Table 9.2): the others' names.
BK2525_MODES: tuple[str, ...] = ("Acceleration", "Velocity", "Displacement")
#: Transducer sensitivity range the driver accepts, in the callers' unit: pC/(m/s^2) on a
#: charge input, mV/(m/s^2) on a voltage input. On the wire it is in SI units, C/(m/s^2) or
#: V/(m/s^2) (manual vol. 2, 5.3: "Transducer_Sensitivity 1E-12" = 1 pC/(m/s^2)).
#: MANUAL UNREAD (Table 9.2): the 2525's own range.
BK2525_SENSITIVITY_RANGE = (0.001, 10000.0)
#: Callers' unit -> SI: pC -> C (charge inputs), mV -> V (voltage inputs).
PICO = 1e-12
MILLI = 1e-3
#: Input_Type answers starting with this are charge inputs (manual vol. 2, 5.3 example:
#: "Input_Type Charge_Single_Ended"). MANUAL UNREAD (Table 9.2): the other input types'
#: names; every other answer is taken as a voltage input (the 2525's non-charge input is the
#: DeltaTron voltage input, manual vol. 1, 4.2.4: "100pC (100mV for DeltaTron)").
CHARGE_INPUT_PREFIX = "charge"


def _db_text(gain: float) -> str:
    """Output_Gain wire text in dB for a V/V gain (6 significant digits, "-0" as "0")."""
    db = 20.0 * math.log10(gain)
    text = f"{db:.6g}"
    return "0" if text == "-0" else text


def _gain_from_db(text: str) -> float:
    """A V/V gain from an Output_Gain answer in dB, snapped to BK2525_GAINS within the
    answer's rounding (relative 1e-4), else the raw value (which read-back then refuses)."""
    gain = 10.0 ** (parse_float(text) / 20.0)
    for choice in BK2525_GAINS:
        if math.isclose(gain, choice, rel_tol=1e-4):
            return choice
    return gain


@dataclass(frozen=True)
class _Nr3:
    """An SI number sent in NR3 form as the manual prints it ("1E-12"; vol. 2, 5.3)."""

    minimum: float
    maximum: float
    unit: str

    def to_wire(self, value: object) -> str:
        x = _as_real(value)
        if not self.minimum <= x <= self.maximum:
            raise ValueError(f"{x:g} is out of range")
        # NR3 with the mantissa's trailing zeros dropped: 1e-12 -> "1E-12" as in 5.3.
        mantissa, exponent = f"{x:.5E}".split("E")
        mantissa = mantissa.rstrip("0").rstrip(".")
        return f"{mantissa}E{int(exponent)}"

    def describe(self) -> str:
        return f"{self.minimum:G} to {self.maximum:G} {self.unit}"


def _wire_choices(values: Sequence[float | None]) -> dict[object, str]:
    # "OFf": the manual's spelling of the Off character data (vol. 2, 4.3.2, Table 9.1).
    return {v: ("OFf" if v is None else f"{v:g}") for v in values}


# MANUAL UNREAD: the 2525 also has Input_Gain and Fine_Gain (vol. 2, 5.3 example: "Input_Gain
# -20;Fine_Gain 0"), and vol. 1, 6.4 makes the gain the operator needs out of Input and Output
# Gain together; how the three combine with the transducer sensitivity into the output scaling
# is in unread pages (Table 9.2, chapter 6). The driver neither sets nor reads Input_Gain and
# Fine_Gain, and reports Output_Gain alone as `gain`, as it did before: check on a real 2525
# that Input_Gain and Fine_Gain leave the output scaling the stand file assumes.
_GAIN_CHOICES = OneOf({g: _db_text(g) for g in BK2525_GAINS}, unit="V/V")
_SENSITIVITY_RANGE = InRange(*BK2525_SENSITIVITY_RANGE, unit="pC/(m/s^2) or mV/(m/s^2)")

# Header Long: answers carry the long header and full character data (manual vol. 2, 4.3.2);
# Short and OFf return character data as mnemonics, whose letters are in the unread Table 9.2.
_BK_HEADER_LONG = "Header Long"  # manual vol. 2, 4.3.2 (Fig. 4.9), Table 9.1
# Channel-dependent settings: ":Channel_<n>:<Par_Header> <value>", query with "?" (manual
# vol. 2, 4.1.4 rule 9; 5.3 Fig. 5.16; 9.1/9.3). The 2525 has Channel_1 only (5.3).
_BK_MODE: Setting[str] = Setting(
    "measurement mode",
    query=":Channel_{channel}:Measurement_Mode?",  # manual vol. 2, 5.3 example; 9.3
    parse=one_word_of(BK2525_MODES),
    set_command=":Channel_{channel}:Measurement_Mode {value}",
    validator=OneOf({m: m for m in BK2525_MODES}),
)
_BK_INPUT_TYPE: Setting[str] = Setting(
    "input type",
    query=":Channel_{channel}:Input_Type?",  # manual vol. 2, 5.3 example; 9.3 (read only here)
    parse=parse_text,
)
_BK_SENSITIVITY: Setting[float] = Setting(
    "transducer sensitivity",
    query=":Channel_{channel}:Transducer_Sensitivity?",  # manual vol. 2, 5.3 example; 9.3
    parse=parse_float,
    set_command=":Channel_{channel}:Transducer_Sensitivity {value}",
    # SI units (manual vol. 2, 5.3: "Transducer_Sensitivity 1E-12"): the range is the
    # callers' 0.001..10000 pC or mV per m/s^2 in C or V; MANUAL UNREAD (Table 9.2): the 2525's.
    validator=_Nr3(0.001 * PICO, 10000 * MILLI, unit="C/(m/s^2) or V/(m/s^2)"),
)
_BK_GAIN: Setting[float] = Setting(
    "output gain",
    query=":Channel_{channel}:Output_Gain?",  # manual vol. 2, 5.3 example; 9.3; dB
    parse=_gain_from_db,
    set_command=":Channel_{channel}:Output_Gain {value}",
    validator=_GAIN_CHOICES,
)
_BK_HIGH_PASS: Setting[float | None] = Setting(
    "lower frequency limit (high-pass)",
    query=":Channel_{channel}:Lower_Frequency_Limit?",  # manual vol. 2, 5.3 example; 9.3; Hz
    parse=parse_filter_hz,
    set_command=":Channel_{channel}:Lower_Frequency_Limit {value}",
    validator=OneOf(_wire_choices(BK2525_HIGH_PASS_HZ), unit="Hz"),
)
_BK_LOW_PASS: Setting[float | None] = Setting(
    "upper frequency limit (low-pass)",
    query=":Channel_{channel}:Upper_Frequency_Limit?",  # manual vol. 2, 5.3 example; 9.3; Hz
    parse=parse_filter_hz,
    set_command=":Channel_{channel}:Upper_Frequency_Limit {value}",
    validator=OneOf(_wire_choices(BK2525_LOW_PASS_HZ), unit="Hz"),
)
# MANUAL UNREAD: the 2525 reports overloads in its Measurement_Status register (vol. 2, 5.3.2;
# also "Status 1" of every Measurement_Data answer, 7.1) and on its screen (vol. 1, 6.4:
# SIG/DET/CM OVL), but 5.3.2's bit assignment and Table 9.2 could not be read. This query is
# the driver's earlier one, kept so that `overloaded` works with the simulation; it is not a
# command found in the manual. Check it against Table 9.2 / 5.3.2 before trusting it.
_BK_OVERLOAD: Setting[bool] = Setting(
    "overload", query=":Channel_{channel}:Overload?", parse=parse_bool
)
# Recall_Work?: the whole set-up in the form used to set it (manual vol. 2, 5.3, Fig. 5.16),
# provided Header is not OFf.
_BK_RECALL_WORK: Setting[str] = Setting("working set-up", query="Recall_Work?", parse=parse_text)
# Identify? (manual vol. 2, Table 9.1 -> 5.3.4); the 2525's command set (9.1: "all the IEEE
# commands/queries used by the 2525") has no *IDN?. MANUAL UNREAD (5.3.4): the answer's
# format; it is kept as text, with an echoed header removed.
_BK_IDENTITY: Setting[str] = Setting("identity", query="Identify?", parse=parse_text)

#: Relative tolerance when checking a read-back transducer sensitivity (instrument rounding).
SENSITIVITY_READBACK_RTOL = 1e-3


class BK2525Amplifier(_VisaInstrument):
    """A B&K 2525 measuring amplifier with `channels` channels (numbered from 1).

    `resource` is a VISA resource string (opened with `resource_manager`, or the default
    pyvisa manager) or an already open message-based resource. The real 2525 has one channel
    (manual vol. 2, 5.3: "for the 2525 always Channel_1"); family members and the shipped
    simulation (`sim.visa`) have two: pass `channels=2`.

    The first exchange of a session sets `Header Long` (manual vol. 2, 4.3.2), so that answers
    carry full character data. `configure` validates every value first (nothing is sent if
    one is refused), reads the channel's Input_Type (charge or voltage: the SI unit of the
    transducer sensitivity), writes each setting as its own message, reads them back and
    raises `InstrumentError` if the amplifier did not take them. Callers keep pC/(m/s^2) or
    mV/(m/s^2) and V/V; the driver converts to and from the wire's C or V per m/s^2 and dB.
    Output scaling = transducer sensitivity x output gain.
    """

    kind = "measuring amplifier"

    def __init__(
        self,
        resource: str | VisaResourceLike,
        resource_manager: pyvisa.ResourceManager | None = None,
        *,
        channels: int = 1,
        timeout_ms: int = DEFAULT_TIMEOUT_MS,
    ) -> None:
        if isinstance(channels, bool) or not isinstance(channels, int) or channels < 1:
            raise ValueError(
                f"measuring amplifier: channels must be an integer >= 1, not {channels!r}"
            )
        self.channels = channels
        self._header_set = False
        super().__init__(resource, resource_manager, timeout_ms=timeout_ms)

    def _ensure_header(self) -> None:
        if not self._header_set:
            super()._write(_BK_HEADER_LONG)
            self._header_set = True

    def _write(self, command: str) -> None:
        self._ensure_header()
        super()._write(command)

    def _query(self, command: str) -> str:
        self._ensure_header()
        return super()._query(command)

    def _clean_answer(self, answer: str) -> str:
        # Long (or short) header echoed before the value: ":Channel_1:Output_Gain 20" or
        # ":Identify ..." (manual vol. 2, 4.3.2); with Header OFf only the value comes.
        if answer.startswith(":"):
            parts = answer.split(None, 1)
            return parts[1].strip() if len(parts) == 2 else ""
        return answer

    def identify(self) -> str:
        """The amplifier's `Identify?` answer (manual vol. 2, Table 9.1, 5.3.4)."""
        self._identity = self._get(_BK_IDENTITY)
        return self._identity

    def _check_channel(self, channel: object) -> int:
        if (
            isinstance(channel, bool)
            or not isinstance(channel, numbers.Integral)
            or not 1 <= int(channel) <= self.channels
        ):
            raise InstrumentError(
                f"{self.label}: channel {channel!r} refused: allowed 1 to {self.channels}"
            )
        return int(channel)

    def _si_factor(self, channel: int) -> float:
        """C or V per caller unit: PICO on a charge input, MILLI on a voltage input."""
        input_type = self._get(_BK_INPUT_TYPE, channel=channel)
        return PICO if input_type.casefold().startswith(CHARGE_INPUT_PREFIX) else MILLI

    def configure(
        self,
        channel: int,
        *,
        sensitivity_mv_per_ms2: float,
        gain: float,
        high_pass_hz: float | None = None,
        low_pass_hz: float | None = None,
    ) -> ConditioningSettings:
        ch = self._check_channel(channel)
        # Validate everything in the callers' units before anything is sent.
        try:
            sent_sensitivity = float(_SENSITIVITY_RANGE.to_wire(sensitivity_mv_per_ms2))
        except (TypeError, ValueError):
            raise InstrumentError(
                f"{self.label}: transducer sensitivity {sensitivity_mv_per_ms2!r} refused: "
                f"allowed {_SENSITIVITY_RANGE.describe()}"
            ) from None
        others: list[tuple[Setting[Any], object]] = [
            (_BK_GAIN, gain),
            (_BK_LOW_PASS, low_pass_hz),
            (_BK_HIGH_PASS, high_pass_hz),
        ]
        for setting, value in others:
            setting.wire_value(value, self.label)
        factor = self._si_factor(ch)
        # One message per setting, each with its full header: the form every manual example
        # shows for a single setting (vol. 2, 4.3.2, 5.3). The 2525 also takes several in one
        # message with the header path kept after ';' (5.3, Fig. 5.16), but pyvisa-sim cannot
        # follow that path, and a ';:Channel_1:' restart is not shown in the pages read.
        items: list[tuple[Setting[Any], object]] = [
            (_BK_MODE, "Acceleration"),
            (_BK_SENSITIVITY, sent_sensitivity * factor),
            *others,
        ]
        commands = [setting.command(value, self.label, channel=ch) for setting, value in items]
        for command in commands:
            self._write(command)
        settings = self._read(ch, factor)
        mismatches = []
        if settings.measurement_mode != "Acceleration":
            mismatches.append(f"measurement mode reads {settings.measurement_mode}")
        if not math.isclose(
            settings.sensitivity_mv_per_ms2, sent_sensitivity, rel_tol=SENSITIVITY_READBACK_RTOL
        ):
            mismatches.append(
                f"transducer sensitivity reads {settings.sensitivity_mv_per_ms2:g}, "
                f"sent {sent_sensitivity:g}"
            )
        wanted_gain = float(_GAIN_CHOICES.canonical(gain))  # type: ignore[arg-type]
        if not math.isclose(settings.gain, wanted_gain, rel_tol=1e-6):
            mismatches.append(f"output gain reads {settings.gain:g}, sent {wanted_gain:g}")
        for name, got, wanted in (
            ("lower frequency limit", settings.high_pass_hz, high_pass_hz),
            ("upper frequency limit", settings.low_pass_hz, low_pass_hz),
        ):
            if not _same_choice(got, wanted):
                mismatches.append(f"{name} reads {_hz(got)}, sent {_hz(wanted)}")
        if mismatches:
            raise InstrumentError(
                f"{self.label}: channel {ch} did not take its settings: " + "; ".join(mismatches)
            )
        return settings

    def read_settings(self, channel: int) -> ConditioningSettings:
        ch = self._check_channel(channel)
        return self._read(ch, self._si_factor(ch))

    def _read(self, ch: int, factor: float) -> ConditioningSettings:
        identity = self._identity if self._identity is not None else self.identify()
        mode = self._get(_BK_MODE, channel=ch)
        # SI answer back to the callers' unit, to 12 digits (1.03E-11 / 1e-12 -> 10.3).
        sensitivity = float(f"{self._get(_BK_SENSITIVITY, channel=ch) / factor:.12g}")
        gain = self._get(_BK_GAIN, channel=ch)
        low_pass = self._get(_BK_LOW_PASS, channel=ch)  # Recall_Work? order (5.3): Upper,
        high_pass = self._get(_BK_HIGH_PASS, channel=ch)  # then Lower_Frequency_Limit
        return ConditioningSettings(
            channel=ch,
            measurement_mode=mode,
            sensitivity_mv_per_ms2=sensitivity,
            gain=gain,
            output_mv_per_ms2=sensitivity * gain,
            high_pass_hz=high_pass,
            low_pass_hz=low_pass,
            identity=identity,
        )

    def overloaded(self, channel: int) -> bool:
        """Overload on `channel`. MANUAL UNREAD: see `_BK_OVERLOAD`."""
        return self._get(_BK_OVERLOAD, channel=self._check_channel(channel))

    def recall_work(self) -> str:
        """The amplifier's whole working set-up as it reports it (raw text, for the run record;
        manual vol. 2, 5.3, Fig. 5.16: long form, since the driver sets Header Long)."""
        answer = self._query(_BK_RECALL_WORK.query_command())  # raw: keep its headers
        return _BK_RECALL_WORK.parse_answer(answer, self.label)


def _hz(value: float | None) -> str:
    return "off" if value is None else f"{value:g} Hz"


# --------------------------------------------------------------------------------------------
# SCPI power amplifier
# --------------------------------------------------------------------------------------------

_PA_OUTPUT: Setting[bool] = Setting(
    "output",
    query="OUTP?",
    parse=parse_bool,
    set_command="OUTP {value}",
    validator=OneOf({True: "ON", False: "OFF"}),
)
_PA_GAIN: Setting[float] = Setting(
    "gain",
    query="GAIN?",
    parse=parse_float,
    set_command="GAIN {value}",
    validator=InRange(0.0, 1.0, unit="(fraction of full gain)"),
)
_PA_FAULT: Setting[str | None] = Setting("fault status", query="STAT:FAULT?", parse=parse_fault)
_PA_INTERLOCK: Setting[bool] = Setting("interlock", query="INT?", parse=parse_bool)


class ScpiPowerAmplifier(_VisaInstrument):
    """A remotely controlled power amplifier with a generic SCPI command set.

    Gain is linear, 0..1 of full gain. `set_output_enabled(True)` refuses (AmplifierFaultError)
    while the interlock is open or a fault is reported; both directions read the output state
    back and raise if it did not change. `set_output_enabled(False)` needs no earlier call and
    may be called on any error path; it raises if it cannot confirm the output is off.
    """

    kind = "power amplifier"

    def set_output_enabled(self, enabled: bool) -> None:
        on = bool(enabled)
        if on:
            if not self.interlock_closed():
                raise AmplifierFaultError(
                    f"{self.label}: interlock open, output not enabled; close the exciter's "
                    "interlock (cover, over-travel switch) and try again"
                )
            fault = self.fault()
            if fault is not None:
                raise AmplifierFaultError(
                    f"{self.label}: reports a fault, output not enabled: {fault}; "
                    "clear the fault on the amplifier and try again"
                )
        self._set(_PA_OUTPUT, on)
        state = self._get(_PA_OUTPUT)
        if state != on:
            raise AmplifierFaultError(
                f"{self.label}: output still {'ON' if state else 'OFF'} after switching it "
                f"{'ON' if on else 'OFF'}; "
                + ("switch the amplifier off by hand" if not on else "check the amplifier")
            )

    def set_gain(self, gain: float) -> None:
        wire = _PA_GAIN.wire_value(gain, self.label)
        self._set(_PA_GAIN, gain)
        got = self.gain()
        if not math.isclose(got, float(wire), rel_tol=1e-6, abs_tol=1e-9):
            raise InstrumentError(f"{self.label}: gain reads {got:g} after setting {wire}")

    def gain(self) -> float:
        return self._get(_PA_GAIN)

    def fault(self) -> str | None:
        return self._get(_PA_FAULT)

    def interlock_closed(self) -> bool:
        return self._get(_PA_INTERLOCK)
