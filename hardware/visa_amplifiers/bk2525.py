"""Driver of the Brüel & Kjær 2525 measuring (conditioning) amplifier, implementing
`hardware.interfaces.MeasuringAmplifier`, per its User Manual Vol. 2 (sections cited beside
each command; what the readable pages did not settle is marked MANUAL UNREAD).

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
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import pyvisa

from hardware.errors import InstrumentError
from hardware.interfaces import ConditioningSettings
from hardware.visa_amplifiers.instrument import DEFAULT_TIMEOUT_MS, VisaInstrument
from hardware.visa_amplifiers.settings import (
    InRange,
    OneOf,
    Setting,
    VisaResourceLike,
    _as_real,
    _same_choice,
    one_word_of,
    parse_bool,
    parse_filter_hz,
    parse_float,
    parse_text,
)

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


class BK2525Amplifier(VisaInstrument):
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
        wanted_gain = float(_GAIN_CHOICES.canonical(gain))
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
