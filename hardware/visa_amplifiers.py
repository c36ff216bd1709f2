"""VISA drivers for the stand's amplifiers (spec section 14).

- `BK2525Amplifier`: a measuring (conditioning) amplifier in the Brüel & Kjær 2525 command
  style, implementing `hardware.interfaces.MeasuringAmplifier`.
- `ScpiPowerAmplifier`: a remotely controlled power amplifier with a small generic SCPI command
  set, implementing `hardware.interfaces.PowerAmplifier`.

Every instrument setting is declared once, as a `Setting`: a human-readable name, the
set-command template, the query command, a parser for the answer and a validator (a range or a
list of allowed values). A value the validator refuses raises `InstrumentError` naming the
setting and what is allowed, before anything is written to the instrument. VISA failures are
translated into the stand's error types: a timeout becomes `VisaTimeoutError`; a lost
connection, a resource that is not found or a closed/invalid session becomes `DeviceLostError`;
an answer that cannot be parsed becomes `InstrumentError` quoting the answer.

Measuring amplifier command set (one channel-prefixed header per setting; several settings of
one channel are sent as ONE message joined by ';', each fully qualified with its leading ':',
which the 2525 accepts as well as the short form that omits the repeated header path; the
fully qualified form is the one the shipped pyvisa-sim definition can follow, because
pyvisa-sim keeps no header path between the parts of a compound message):

    :Channel_<n>:Measurement_Mode Acceleration|Velocity|Displacement    (query: ...?)
    :Channel_<n>:Transducer_Sensitivity <x>   x in 0.001..10000, pC or mV per m/s^2
    :Channel_<n>:Output_Gain <g>              g in 0.1..10000 V/V in 1-2-5 steps
    :Channel_<n>:High_Pass_Filter Off|0.1|1|10                       (Hz)
    :Channel_<n>:Low_Pass_Filter Off|1000|3000|10000|22400           (Hz)
    :Channel_<n>:Overload?                    0|1 (or ON/OFF)
    Recall_Work?                              the whole working set-up as one line
    *IDN?                                     identity

Answers may carry the echoed header (`:Channel_1:Output_Gain 20`, the 2525's default long
header) or not (`20`, header off); both are accepted.

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
# B&K 2525-style measuring amplifier
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


#: Output gains (V/V), 0.1 to 10000 in 1-2-5 steps.
BK2525_GAINS: tuple[float, ...] = _one_two_five(-1, 10000.0)
#: High-pass corners in Hz (None = off).
BK2525_HIGH_PASS_HZ: tuple[float | None, ...] = (None, 0.1, 1.0, 10.0)
#: Low-pass corners in Hz (None = off).
BK2525_LOW_PASS_HZ: tuple[float | None, ...] = (None, 1000.0, 3000.0, 10000.0, 22400.0)
#: Measurement modes.
BK2525_MODES: tuple[str, ...] = ("Acceleration", "Velocity", "Displacement")
#: Transducer sensitivity range, pC or mV per m/s^2.
BK2525_SENSITIVITY_RANGE = (0.001, 10000.0)


def _wire_choices(values: Sequence[float | None]) -> dict[object, str]:
    return {v: ("Off" if v is None else f"{v:g}") for v in values}


_GAIN_CHOICES = OneOf(_wire_choices(BK2525_GAINS), unit="V/V")

_BK_MODE: Setting[str] = Setting(
    "measurement mode",
    query=":Channel_{channel}:Measurement_Mode?",
    parse=one_word_of(BK2525_MODES),
    set_command=":Channel_{channel}:Measurement_Mode {value}",
    validator=OneOf({m: m for m in BK2525_MODES}),
)
_BK_SENSITIVITY: Setting[float] = Setting(
    "transducer sensitivity",
    query=":Channel_{channel}:Transducer_Sensitivity?",
    parse=parse_float,
    set_command=":Channel_{channel}:Transducer_Sensitivity {value}",
    validator=InRange(*BK2525_SENSITIVITY_RANGE, unit="pC/(m/s^2) or mV/(m/s^2)"),
)
_BK_GAIN: Setting[float] = Setting(
    "output gain",
    query=":Channel_{channel}:Output_Gain?",
    parse=parse_float,
    set_command=":Channel_{channel}:Output_Gain {value}",
    validator=_GAIN_CHOICES,
)
_BK_HIGH_PASS: Setting[float | None] = Setting(
    "high-pass filter",
    query=":Channel_{channel}:High_Pass_Filter?",
    parse=parse_filter_hz,
    set_command=":Channel_{channel}:High_Pass_Filter {value}",
    validator=OneOf(_wire_choices(BK2525_HIGH_PASS_HZ), unit="Hz"),
)
_BK_LOW_PASS: Setting[float | None] = Setting(
    "low-pass filter",
    query=":Channel_{channel}:Low_Pass_Filter?",
    parse=parse_filter_hz,
    set_command=":Channel_{channel}:Low_Pass_Filter {value}",
    validator=OneOf(_wire_choices(BK2525_LOW_PASS_HZ), unit="Hz"),
)
_BK_OVERLOAD: Setting[bool] = Setting(
    "overload", query=":Channel_{channel}:Overload?", parse=parse_bool
)
_BK_RECALL_WORK: Setting[str] = Setting("working set-up", query="Recall_Work?", parse=parse_text)

#: Relative tolerance when checking a read-back transducer sensitivity (instrument rounding).
SENSITIVITY_READBACK_RTOL = 1e-3


class BK2525Amplifier(_VisaInstrument):
    """A B&K 2525-style measuring amplifier with `channels` channels (numbered from 1).

    `resource` is a VISA resource string (opened with `resource_manager`, or the default
    pyvisa manager) or an already open message-based resource. The real 2525 has one channel;
    family members and the shipped simulation (`sim.visa`) have two: pass `channels=2`.

    `configure` validates every value first (nothing is sent if one is refused), writes the
    channel's settings in one message, reads them back and raises `InstrumentError` if the
    amplifier did not take them. Output scaling = transducer sensitivity x output gain.
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
        super().__init__(resource, resource_manager, timeout_ms=timeout_ms)

    def _clean_answer(self, answer: str) -> str:
        # Long or short header echoed before the value (":Channel_1:Output_Gain 20").
        if answer.startswith(":"):
            parts = answer.split(None, 1)
            return parts[1].strip() if len(parts) == 2 else ""
        return answer

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
        items: list[tuple[Setting[Any], object]] = [
            (_BK_MODE, "Acceleration"),
            (_BK_SENSITIVITY, sensitivity_mv_per_ms2),
            (_BK_GAIN, gain),
            (_BK_HIGH_PASS, high_pass_hz),
            (_BK_LOW_PASS, low_pass_hz),
        ]
        self._set_many(items, channel=ch)
        settings = self.read_settings(ch)
        sent_sensitivity = float(_BK_SENSITIVITY.wire_value(sensitivity_mv_per_ms2))
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
            ("high-pass filter", settings.high_pass_hz, high_pass_hz),
            ("low-pass filter", settings.low_pass_hz, low_pass_hz),
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
        identity = self._identity if self._identity is not None else self.identify()
        mode = self._get(_BK_MODE, channel=ch)
        sensitivity = self._get(_BK_SENSITIVITY, channel=ch)
        gain = self._get(_BK_GAIN, channel=ch)
        high_pass = self._get(_BK_HIGH_PASS, channel=ch)
        low_pass = self._get(_BK_LOW_PASS, channel=ch)
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
        return self._get(_BK_OVERLOAD, channel=self._check_channel(channel))

    def recall_work(self) -> str:
        """The amplifier's whole working set-up as it reports it (raw text, for the run record)."""
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
