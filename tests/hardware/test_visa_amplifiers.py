"""Exact protocol exchange of the VISA amplifier drivers against a scripted fake resource."""

from __future__ import annotations

import math

import pytest
from pyvisa import constants
from pyvisa import errors as visa_errors

from hardware.errors import (
    AmplifierFaultError,
    DeviceLostError,
    HardwareError,
    InstrumentError,
    VisaTimeoutError,
)
from hardware.interfaces import ConditioningSettings, MeasuringAmplifier, PowerAmplifier
from hardware.visa_amplifiers import (
    BK2525_GAINS,
    BK2525Amplifier,
    InRange,
    OneOf,
    ScpiPowerAmplifier,
    Setting,
    parse_float,
)

IDN_BK = "Bruel&Kjaer,2525,1234567,1.0"
IDN_PA = "ACME,PA-100,42,2.1"

READ = object()  # script key for a bare read()


class ScriptedResource:
    """A pyvisa resource stand-in playing an exact script of (command, answer) pairs.

    answer None: the command must be written; a str: the command must be queried and gets
    that answer; an exception: raised by whichever call sends the command.
    """

    def __init__(self, pairs, resource_name: str = "FAKE::1::INSTR"):
        self.script = list(pairs)
        self.sent: list[str] = []
        self.resource_name = resource_name
        self.timeout = 2000
        self.close_calls = 0

    def _next(self, kind: str, command) -> object:
        assert self.script, f"unexpected {kind} {command!r}; sent so far: {self.sent}"
        expected, answer = self.script.pop(0)
        assert command == expected, f"{kind} {command!r}, expected {expected!r}"
        self.sent.append(command)
        if isinstance(answer, BaseException):
            raise answer
        return answer

    def write(self, message: str) -> int:
        answer = self._next("write", message)
        assert answer is None, f"{message!r} written, but the script answers it: a query"
        return len(message) + 1

    def query(self, message: str) -> str:
        answer = self._next("query", message)
        assert isinstance(answer, str), f"{message!r} queried, but the script expects a write"
        return answer + "\n"

    def read(self) -> str:
        answer = self._next("read", READ)
        assert isinstance(answer, str)
        return answer + "\n"

    def close(self) -> None:
        self.close_calls += 1

    def assert_done(self) -> None:
        assert not self.script, f"never sent: {self.script}"


@pytest.fixture
def scripted():
    """Factory of scripted resources; at teardown every script must be used up."""
    made: list[ScriptedResource] = []

    def make(*pairs, resource_name: str = "FAKE::1::INSTR") -> ScriptedResource:
        resource = ScriptedResource(pairs, resource_name)
        made.append(resource)
        return resource

    yield make
    for resource in made:
        resource.assert_done()


def timeout_error() -> visa_errors.VisaIOError:
    return visa_errors.VisaIOError(constants.StatusCode.error_timeout)


# --- the fake itself must be able to fail ------------------------------------------------------


def test_scripted_resource_refuses_wrong_extra_and_kind():
    fake = ScriptedResource([("A?", "1"), ("B 1", None)])
    with pytest.raises(AssertionError, match="expected 'A\\?'"):
        fake.query("X?")
    fake = ScriptedResource([("A?", "1")])
    with pytest.raises(AssertionError, match="written, but the script answers it"):
        fake.write("A?")
    fake = ScriptedResource([])
    with pytest.raises(AssertionError, match="unexpected query"):
        fake.query("A?")
    fake = ScriptedResource([("A?", "1")])
    with pytest.raises(AssertionError, match="never sent"):
        fake.assert_done()


# --- declarative settings ----------------------------------------------------------------------


def test_setting_builds_commands_and_refuses_before_formatting():
    level = Setting(
        "level",
        query=":Ch_{channel}:Level?",
        parse=parse_float,
        set_command=":Ch_{channel}:Level {value}",
        validator=InRange(0.0, 5.0, unit="V"),
    )
    assert level.command(2.5, channel=3) == ":Ch_3:Level 2.5"
    assert level.query_command(channel=3) == ":Ch_3:Level?"
    assert level.parse_answer(" 1.25 ") == 1.25
    with pytest.raises(InstrumentError, match=r"^dev: level 7 refused: allowed 0 to 5 V$"):
        level.command(7, "dev", channel=1)
    with pytest.raises(InstrumentError, match=r"cannot read level: answer 'x' to ':Ch_1:Level\?'"):
        level.parse_answer("x", channel=1)
    read_only = Setting("status", query="STAT?", parse=parse_float)
    with pytest.raises(InstrumentError, match="status is read-only"):
        read_only.command(1)


def test_one_of_matches_numbers_strings_none_and_bools_strictly():
    choices = OneOf({None: "Off", 0.1: "0.1", 1.0: "1"}, unit="Hz")
    assert choices.to_wire(0.1 + 0.2 - 0.2) == "0.1"
    assert choices.to_wire(None) == "Off"
    assert choices.to_wire(1) == "1"
    assert choices.describe() == "one of off, 0.1, 1 Hz"
    for bad in (True, "1", 0.0, 0.11):
        with pytest.raises(ValueError):
            choices.to_wire(bad)
    onoff = OneOf({True: "ON", False: "OFF"})
    assert onoff.to_wire(False) == "OFF"
    with pytest.raises(ValueError):
        onoff.to_wire(0)
    modes = OneOf({"Acceleration": "Acceleration"})
    assert modes.to_wire("acceleration") == "Acceleration"


def test_gain_list_is_one_two_five_from_0_1_to_10000():
    assert BK2525_GAINS[0] == 0.1
    assert BK2525_GAINS[-1] == 10000.0
    assert len(BK2525_GAINS) == 16
    assert BK2525_GAINS[:6] == (0.1, 0.2, 0.5, 1.0, 2.0, 5.0)


# --- measuring amplifier -------------------------------------------------------------------------
# The exchanges follow the 2525 User Manual Vol. 2 (sections as hardware/visa_amplifiers.py
# cites them): Header Long first (4.3.2), Identify? (Table 9.1), one message per setting with
# its ":Channel_<n>:" header, Transducer_Sensitivity in C or V per m/s^2 (5.3: "1E-12"),
# Output_Gain in dB (5.3: "Output_Gain 0"), Upper_/Lower_Frequency_Limit (5.3).

HDR = ("Header Long", None)
CHARGE = "Charge_Single_Ended"  # the 5.3 example's input type
# Not a name from the manual (Table 9.2 unread): any Input_Type not starting with "Charge" is
# taken as a voltage input, so any such word exercises that path.
VOLTAGE = "Deltatron"


def input_type(channel: int, answer: str = CHARGE, header: bool = True):
    text = f":Channel_{channel}:Input_Type {answer}" if header else answer
    return (f":Channel_{channel}:Input_Type?", text)


def writes(channel: int, sensitivity: str, gain_db: str, upper: str, lower: str):
    """The writes configure sends, one message per setting, in Recall_Work? order (5.3)."""
    prefix = f":Channel_{channel}:"
    return [
        (prefix + "Measurement_Mode Acceleration", None),
        (prefix + f"Transducer_Sensitivity {sensitivity}", None),
        (prefix + f"Output_Gain {gain_db}", None),
        (prefix + f"Upper_Frequency_Limit {upper}", None),
        (prefix + f"Lower_Frequency_Limit {lower}", None),
    ]


def readback(channel: int, mode, sens, gain, upper, lower, idn: str | None = IDN_BK):
    """The queries read_settings sends after Input_Type?, answered with a long header (the
    2525's default and what the driver sets, 4.3.2) unless an answer starts with '='."""
    prefix = f":Channel_{channel}:"
    pairs = [("Identify?", f":Identify {idn}")] if idn is not None else []
    for name, answer in (
        ("Measurement_Mode", mode),
        ("Transducer_Sensitivity", sens),
        ("Output_Gain", gain),
        ("Upper_Frequency_Limit", upper),
        ("Lower_Frequency_Limit", lower),
    ):
        text = answer[1:] if answer.startswith("=") else f"{prefix}{name} {answer}"
        pairs.append((f"{prefix}{name}?", text))
    return pairs


def test_drivers_satisfy_the_protocols(scripted):
    assert isinstance(BK2525Amplifier(scripted()), MeasuringAmplifier)
    assert isinstance(ScpiPowerAmplifier(scripted()), PowerAmplifier)


def test_configure_charge_input_sends_si_units_and_db_then_reads_back(scripted):
    fake = scripted(
        HDR,
        input_type(1),
        *writes(1, "9.21E-12", "26.0206", "OFf", "0.1"),
        *readback(1, "Acceleration", "9.21E-12", "26.0206", "OFf", "0.1"),
    )
    amp = BK2525Amplifier(fake)
    settings = amp.configure(
        1, sensitivity_mv_per_ms2=9.21, gain=20, high_pass_hz=0.1, low_pass_hz=None
    )
    assert settings == ConditioningSettings(
        channel=1,
        measurement_mode="Acceleration",
        sensitivity_mv_per_ms2=9.21,  # pC/(m/s^2), from 9.21E-12 C/(m/s^2)
        gain=20.0,  # V/V, from 26.0206 dB
        output_mv_per_ms2=pytest.approx(184.2),
        high_pass_hz=0.1,
        low_pass_hz=None,
        identity=IDN_BK,
    )


def test_configure_voltage_input_second_channel_sends_volts(scripted):
    fake = scripted(
        HDR,
        input_type(2, VOLTAGE),
        *writes(2, "3.16228E-4", "80", "22400", "10"),
        *readback(2, "Acceleration", "3.16228E-4", "80", "22400", "10"),
    )
    amp = BK2525Amplifier(fake, channels=2)
    settings = amp.configure(
        2, sensitivity_mv_per_ms2=math.sqrt(0.1), gain=1e4, high_pass_hz=10, low_pass_hz=22400
    )
    assert settings.channel == 2
    assert settings.sensitivity_mv_per_ms2 == 0.316228  # mV/(m/s^2), from V/(m/s^2)
    assert settings.gain == 10000.0
    assert settings.high_pass_hz == 10.0
    assert settings.low_pass_hz == 22400.0


@pytest.mark.parametrize(
    ("gain", "db"),
    [(0.1, "-20"), (0.2, "-13.9794"), (0.5, "-6.0206"), (1, "0"), (2, "6.0206"), (10, "20")],
)
def test_output_gain_goes_out_in_db_and_comes_back_in_v_per_v(scripted, gain, db):
    fake = scripted(
        HDR,
        input_type(1),
        *writes(1, "1E-12", db, "OFf", "1"),
        *readback(1, "Acceleration", "1E-12", db, "OFf", "1"),
    )
    settings = BK2525Amplifier(fake).configure(
        1, sensitivity_mv_per_ms2=1, gain=gain, high_pass_hz=1
    )
    assert settings.gain == gain


def test_read_settings_parses_long_and_header_off_answers(scripted):
    fake = scripted(
        HDR,
        input_type(1, header=False),
        *readback(1, "=ACCELERATION", "1.250E-12", "=33.9794", "1000", "=OFf"),
    )
    settings = BK2525Amplifier(fake).read_settings(1)
    assert settings.measurement_mode == "Acceleration"
    assert settings.sensitivity_mv_per_ms2 == 1.25
    assert settings.gain == 50.0
    assert settings.output_mv_per_ms2 == 62.5
    assert settings.high_pass_hz is None
    assert settings.low_pass_hz == 1000.0
    assert settings.identity == IDN_BK


def test_header_long_is_sent_once_and_identity_asked_once(scripted):
    fake = scripted(
        HDR,
        ("Identify?", f":Identify {IDN_BK}"),
        input_type(1),
        *readback(1, "Velocity", "1E-12", "0", "OFf", "1", idn=None),
        input_type(1),
        *readback(1, "Velocity", "1E-12", "0", "OFf", "1", idn=None),
    )
    amp = BK2525Amplifier(fake)
    assert amp.identify() == IDN_BK
    assert amp.read_settings(1).measurement_mode == "Velocity"
    assert amp.read_settings(1).gain == 1.0


@pytest.mark.parametrize(
    ("answer", "expected"),
    [("0", False), ("1", True), (":Channel_1:Overload ON", True), ("OFf", False)],
)
def test_overload_query(scripted, answer, expected):
    fake = scripted(HDR, (":Channel_1:Overload?", answer))
    assert BK2525Amplifier(fake).overloaded(1) is expected


def test_recall_work_returns_the_raw_long_text(scripted):
    # The manual's own example (vol. 2, 5.3), cut after Additional_Filter.
    text = (
        ":Channel_1:Measurement_Mode Acceleration;Transducer_Sensitivity 1E-12;"
        "Input_Type Charge_Single_Ended;Input_Gain -20;Fine_Gain 0;Output_Gain 0;"
        "Upper_Frequency_Limit 10000;Lower_Frequency_Limit 1;Additional_Filter None"
    )
    fake = scripted(HDR, ("Recall_Work?", text))
    assert BK2525Amplifier(fake).recall_work() == text


@pytest.mark.parametrize(
    ("position", "answer"),
    [
        (1, "Charge"),  # unknown mode
        (2, "abc"),  # sensitivity not a number
        (3, ""),  # empty gain
        (3, "nan"),
        (4, "-5"),  # negative filter corner
        (5, "ERROR -222 Data out of range"),
    ],
)
def test_malformed_answer_is_an_instrument_error_quoting_it(scripted, position, answer):
    answers = ["=Acceleration", "=1E-12", "=0", "=OFf", "=1"]
    answers[position - 1] = "=" + answer
    pairs = readback(1, *answers)[: position + 1]  # the driver stops at the bad answer
    fake = scripted(HDR, input_type(1), *pairs)
    with pytest.raises(InstrumentError, match=f"answer {answer!r}") as info:
        BK2525Amplifier(fake).read_settings(1)
    assert "measuring amplifier at FAKE::1::INSTR" in str(info.value)


def test_malformed_overload_answer(scripted):
    fake = scripted(HDR, (":Channel_1:Overload?", "maybe"))
    with pytest.raises(InstrumentError, match=r"overload: answer 'maybe'"):
        BK2525Amplifier(fake).overloaded(1)


GOOD = {"sensitivity_mv_per_ms2": 1.0, "gain": 1.0, "high_pass_hz": 1.0, "low_pass_hz": None}


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"gain": 3}, r"output gain 3 refused: allowed one of 0\.1, 0\.2, 0\.5, 1, .* 10000 V/V"),
        ({"gain": 0.05}, "output gain 0.05 refused"),
        ({"gain": 20000}, "output gain 20000 refused"),
        ({"gain": float("nan")}, "output gain nan refused"),
        ({"gain": "20"}, "output gain '20' refused"),
        ({"gain": True}, "output gain True refused"),
        (
            {"sensitivity_mv_per_ms2": 0.0},
            r"transducer sensitivity 0\.0 refused: allowed 0\.001 to 10000 pC/\(m/s\^2\) or mV",
        ),
        ({"sensitivity_mv_per_ms2": 1e5}, "transducer sensitivity 100000.0 refused"),
        ({"sensitivity_mv_per_ms2": float("inf")}, "transducer sensitivity inf refused"),
        (
            {"high_pass_hz": 5},
            r"lower frequency limit \(high-pass\) 5 refused: allowed one of off, 0\.1, 1, 10 Hz",
        ),
        (
            {"low_pass_hz": 2000},
            r"upper frequency limit \(low-pass\) 2000 refused: allowed one of off, 1000, 3000",
        ),
    ],
)
def test_out_of_range_setting_refused_with_nothing_sent(scripted, change, message):
    fake = scripted()  # an empty script: any write or query fails the test
    with pytest.raises(InstrumentError, match=message):
        BK2525Amplifier(fake).configure(1, **{**GOOD, **change})
    assert fake.sent == []


@pytest.mark.parametrize("channel", [0, 2, True, 1.0])
def test_bad_channel_refused_with_nothing_sent(scripted, channel):
    fake = scripted()
    amp = BK2525Amplifier(fake)  # one channel, like a real 2525
    with pytest.raises(InstrumentError, match=r"channel .* refused: allowed 1 to 1"):
        amp.configure(channel, **GOOD)
    with pytest.raises(InstrumentError, match="channel"):
        amp.overloaded(channel)


def test_configure_raises_when_the_amplifier_does_not_take_a_setting(scripted):
    fake = scripted(
        HDR,
        input_type(1),
        *writes(1, "1E-12", "26.0206", "OFf", "1"),
        *readback(1, "Acceleration", "1E-12", "20", "22400", "1"),
    )
    with pytest.raises(
        InstrumentError, match=r"output gain reads 10, sent 20.*upper frequency limit reads 22400"
    ):
        BK2525Amplifier(fake).configure(1, **{**GOOD, "gain": 20})


def test_configure_reports_a_gain_off_the_list_as_read(scripted):
    fake = scripted(
        HDR,
        input_type(1),
        *writes(1, "1E-12", "6.0206", "OFf", "1"),
        *readback(1, "Acceleration", "1E-12", "6", "OFf", "1"),  # 6 dB, not 6.0206
    )
    with pytest.raises(InstrumentError, match=r"output gain reads 1\.99526, sent 2$"):
        BK2525Amplifier(fake).configure(1, **{**GOOD, "gain": 2})


def test_configure_tolerates_instrument_rounding_of_the_sensitivity(scripted):
    fake = scripted(
        HDR,
        input_type(1),
        *writes(1, "9.21234E-12", "0", "OFf", "1"),
        *readback(1, "Acceleration", "9.212E-12", "0", "OFf", "1"),
    )
    settings = BK2525Amplifier(fake).configure(1, **{**GOOD, "sensitivity_mv_per_ms2": 9.21234})
    assert settings.sensitivity_mv_per_ms2 == 9.212  # what the amplifier holds is reported


def test_query_timeout_becomes_visa_timeout_error(scripted):
    fake = scripted(HDR, (":Channel_1:Overload?", timeout_error()))
    with pytest.raises(VisaTimeoutError, match=r"no answer to ':Channel_1:Overload\?'") as info:
        BK2525Amplifier(fake).overloaded(1)
    assert isinstance(info.value.__cause__, visa_errors.VisaIOError)


def test_write_timeout_becomes_visa_timeout_error(scripted):
    fake = scripted(
        HDR,
        input_type(1),
        (":Channel_1:Measurement_Mode Acceleration", timeout_error()),
    )
    with pytest.raises(VisaTimeoutError):
        BK2525Amplifier(fake).configure(1, **GOOD)


@pytest.mark.parametrize(
    "error",
    [
        visa_errors.VisaIOError(constants.StatusCode.error_connection_lost),
        visa_errors.VisaIOError(constants.StatusCode.error_resource_not_found),
        visa_errors.VisaIOError(constants.StatusCode.error_invalid_object),
        visa_errors.InvalidSession(),
    ],
    ids=["conn-lost", "rsrc-nfound", "invalid-session", "closed-session"],
)
def test_lost_connection_becomes_device_lost_error(scripted, error):
    fake = scripted(HDR, ("Identify?", error))
    with pytest.raises(DeviceLostError, match=r"measuring amplifier at FAKE::1::INSTR"):
        BK2525Amplifier(fake).identify()


def test_lost_connection_on_the_header_command_is_device_lost(scripted):
    fake = scripted(("Header Long", visa_errors.InvalidSession()))
    with pytest.raises(DeviceLostError, match=r"while sending 'Header Long'"):
        BK2525Amplifier(fake).identify()


def test_other_visa_error_is_a_plain_hardware_error(scripted):
    fake = scripted(HDR, ("Identify?", visa_errors.VisaIOError(constants.StatusCode.error_io)))
    with pytest.raises(HardwareError, match="VISA error") as info:
        BK2525Amplifier(fake).identify()
    assert type(info.value) is HardwareError


def test_close_is_idempotent_and_later_use_is_refused(scripted):
    fake = scripted()
    amp = BK2525Amplifier(fake)
    amp.close()
    amp.close()
    assert fake.close_calls == 1
    assert amp.closed
    with pytest.raises(DeviceLostError, match="closed"):
        amp.identify()


def test_context_manager_closes(scripted):
    fake = scripted(HDR, ("Identify?", f":Identify {IDN_BK}"))
    with BK2525Amplifier(fake) as amp:
        assert amp.identify() == IDN_BK
    assert fake.close_calls == 1


class _RefusingManager:
    def __init__(self, error: Exception):
        self.error = error
        self.calls: list[tuple[str, dict]] = []

    def open_resource(self, name: str, **kwargs):
        self.calls.append((name, kwargs))
        raise self.error


def test_opening_a_missing_resource_is_device_lost():
    rm = _RefusingManager(visa_errors.VisaIOError(constants.StatusCode.error_resource_not_found))
    with pytest.raises(DeviceLostError, match=r"measuring amplifier at GPIB0::99::INSTR"):
        BK2525Amplifier("GPIB0::99::INSTR", rm, timeout_ms=1500)  # type: ignore[arg-type]
    assert rm.calls == [
        (
            "GPIB0::99::INSTR",
            {"read_termination": "\n", "write_termination": "\n", "timeout": 1500},
        )
    ]


# --- power amplifier ------------------------------------------------------------------------------


def test_enable_checks_interlock_and_fault_then_switches_and_confirms(scripted):
    fake = scripted(
        ("INT?", "1"),
        ("STAT:FAULT?", '0,"No error"'),
        ("OUTP ON", None),
        ("OUTP?", "1"),
    )
    ScpiPowerAmplifier(fake).set_output_enabled(True)


def test_disable_switches_and_confirms_without_other_queries(scripted):
    fake = scripted(("OUTP OFF", None), ("OUTP?", "OFF"))
    ScpiPowerAmplifier(fake).set_output_enabled(False)


def test_enable_refused_while_interlock_open(scripted):
    fake = scripted(("INT?", "0"))
    with pytest.raises(AmplifierFaultError, match="interlock open"):
        ScpiPowerAmplifier(fake).set_output_enabled(True)


def test_enable_refused_while_fault_reported(scripted):
    fake = scripted(("INT?", "1"), ("STAT:FAULT?", '12,"Over temperature"'))
    with pytest.raises(AmplifierFaultError, match=r"Over temperature \(fault code 12\)"):
        ScpiPowerAmplifier(fake).set_output_enabled(True)


def test_disable_not_confirmed_raises(scripted):
    fake = scripted(("OUTP OFF", None), ("OUTP?", "1"))
    with pytest.raises(AmplifierFaultError, match="output still ON after switching it OFF"):
        ScpiPowerAmplifier(fake).set_output_enabled(False)


@pytest.mark.parametrize(
    ("pairs", "error"),
    [
        ([("OUTP OFF", timeout_error())], VisaTimeoutError),
        ([("OUTP OFF", None), ("OUTP?", timeout_error())], VisaTimeoutError),
        (
            [("OUTP OFF", visa_errors.VisaIOError(constants.StatusCode.error_connection_lost))],
            DeviceLostError,
        ),
        ([("OUTP OFF", None), ("OUTP?", "garbage")], InstrumentError),
    ],
)
def test_disable_failure_is_raised_not_swallowed(scripted, pairs, error):
    fake = scripted(*pairs)
    with pytest.raises(error):
        ScpiPowerAmplifier(fake).set_output_enabled(False)


def test_disable_after_close_raises(scripted):
    amp = ScpiPowerAmplifier(scripted())
    amp.close()
    with pytest.raises(DeviceLostError):
        amp.set_output_enabled(False)


def test_set_gain_writes_and_confirms(scripted):
    fake = scripted(("GAIN 0.25", None), ("GAIN?", "2.500000E-01"), ("GAIN?", "0.25"))
    amp = ScpiPowerAmplifier(fake)
    amp.set_gain(0.25)
    assert amp.gain() == 0.25


def test_set_gain_not_taken_raises(scripted):
    fake = scripted(("GAIN 0.5", None), ("GAIN?", "0.3"))
    with pytest.raises(InstrumentError, match=r"gain reads 0\.3 after setting 0\.5"):
        ScpiPowerAmplifier(fake).set_gain(0.5)


@pytest.mark.parametrize("gain", [1.5, -0.1, float("nan"), None])
def test_power_gain_out_of_range_refused_with_nothing_sent(scripted, gain):
    fake = scripted()
    with pytest.raises(InstrumentError, match=r"gain .* refused: allowed 0 to 1"):
        ScpiPowerAmplifier(fake).set_gain(gain)  # type: ignore[arg-type]
    assert fake.sent == []


@pytest.mark.parametrize(
    ("answer", "expected"),
    [
        ('0,"No error"', None),
        ("+0", None),
        ('12,"Over temperature"', "Over temperature (fault code 12)"),
        ("-3,Clipping", "Clipping (fault code -3)"),
        ("7", "fault code 7"),
    ],
)
def test_fault_query(scripted, answer, expected):
    fake = scripted(("STAT:FAULT?", answer))
    assert ScpiPowerAmplifier(fake).fault() == expected


def test_malformed_fault_answer(scripted):
    fake = scripted(("STAT:FAULT?", "Over temperature"))
    with pytest.raises(InstrumentError, match="'Over temperature'"):
        ScpiPowerAmplifier(fake).fault()


@pytest.mark.parametrize(("answer", "expected"), [("1", True), ("0", False), ("ON", True)])
def test_interlock_query(scripted, answer, expected):
    fake = scripted(("INT?", answer))
    assert ScpiPowerAmplifier(fake).interlock_closed() is expected


def test_power_amplifier_identify_and_timeout(scripted):
    fake = scripted(("*IDN?", IDN_PA), ("INT?", timeout_error()))
    amp = ScpiPowerAmplifier(fake)
    assert amp.identify() == IDN_PA
    with pytest.raises(VisaTimeoutError, match=r"power amplifier at FAKE::1::INSTR"):
        amp.interlock_closed()
