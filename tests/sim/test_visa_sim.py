"""The VISA amplifier drivers against the shipped pyvisa-sim definitions (sim/amplifiers.yaml)."""

from __future__ import annotations

import pytest

from hardware.errors import (
    AmplifierFaultError,
    DeviceLostError,
    InstrumentError,
    VisaTimeoutError,
)
from hardware.interfaces import MeasuringAmplifier, PowerAmplifier
from hardware.visa_amplifiers import (
    BK2525_GAINS,
    BK2525_HIGH_PASS_HZ,
    BK2525_LOW_PASS_HZ,
    BK2525Amplifier,
    ScpiPowerAmplifier,
)
from sim.visa import (
    SIM_MEASURING_AMPLIFIER,
    SIM_MEASURING_AMPLIFIER_CHANNELS,
    SIM_POWER_AMPLIFIER,
    simulated_resource_manager,
)


@pytest.fixture
def rm():
    manager = simulated_resource_manager(fresh=True)  # instruments in their default state
    yield manager
    manager.close()


@pytest.fixture
def amp(rm):
    with BK2525Amplifier(
        SIM_MEASURING_AMPLIFIER, rm, channels=SIM_MEASURING_AMPLIFIER_CHANNELS
    ) as driver:
        yield driver


@pytest.fixture
def pa(rm):
    with ScpiPowerAmplifier(SIM_POWER_AMPLIFIER, rm) as driver:
        yield driver


def raw(rm, name: str):
    """The simulated instrument without a driver, for writing what no driver would send."""
    return rm.open_resource(name, read_termination="\n", write_termination="\n", timeout=200)


def test_both_instruments_are_listed_and_identify(rm, amp, pa):
    assert set(rm.list_resources()) == {SIM_MEASURING_AMPLIFIER, SIM_POWER_AMPLIFIER}
    assert isinstance(amp, MeasuringAmplifier)
    assert isinstance(pa, PowerAmplifier)
    assert amp.identify().startswith("Bruel&Kjaer,2525,")
    assert "power amplifier" in pa.identify()


def test_shared_manager_is_reused_and_fresh_one_starts_from_defaults():
    shared = simulated_resource_manager()
    assert simulated_resource_manager() is shared
    amp = BK2525Amplifier(SIM_MEASURING_AMPLIFIER, shared, channels=2)
    amp.configure(1, sensitivity_mv_per_ms2=2.0, gain=50, low_pass_hz=1000)
    other = BK2525Amplifier(SIM_MEASURING_AMPLIFIER, simulated_resource_manager(), channels=2)
    assert other.read_settings(1).gain == 50.0  # same simulated instrument
    fresh_rm = simulated_resource_manager(fresh=True)
    try:
        fresh = BK2525Amplifier(SIM_MEASURING_AMPLIFIER, fresh_rm, channels=2)
        assert fresh.read_settings(1).gain == 1.0
    finally:
        fresh_rm.close()
    amp.configure(1, sensitivity_mv_per_ms2=1.0, gain=1, high_pass_hz=1, low_pass_hz=10000)
    amp.close()
    other.close()


def test_the_definitions_are_parsed_once_and_fresh_instruments_stay_apart(monkeypatch):
    """Issue 31 point 7: one YAML parse per process; two fresh managers (as one simulated run
    opens) still have instruments of their own."""
    import sim.visa

    simulated_resource_manager(fresh=True).close()  # parsed by now, whatever ran before
    parses = []
    real_parse = sim.visa.parse_file  # the parse (libyaml's, issue 34) the cache calls
    monkeypatch.setattr(
        sim.visa, "parse_file", lambda path: parses.append(path) or real_parse(path)
    )
    first_rm, second_rm = (simulated_resource_manager(fresh=True) for _ in range(2))
    try:
        assert parses == []  # neither parsed the file again
        assert first_rm.visalib is not second_rm.visalib
        first = BK2525Amplifier(SIM_MEASURING_AMPLIFIER, first_rm, channels=2)
        second = BK2525Amplifier(SIM_MEASURING_AMPLIFIER, second_rm, channels=2)
        first.configure(1, sensitivity_mv_per_ms2=2.0, gain=50, low_pass_hz=1000)
        assert first.read_settings(1).gain == 50.0
        assert second.read_settings(1).gain == 1.0  # its own instrument, at its default
    finally:
        first_rm.close()
        second_rm.close()
    monkeypatch.setattr(sim.visa, "_parsed", {})  # a process that has not parsed it yet
    simulated_resource_manager(fresh=True).close()
    simulated_resource_manager(fresh=True).close()
    assert len(parses) == 1 and parses[0].endswith("amplifiers.yaml")


def test_defaults_read_back(amp):
    # The defaults of the manual's Recall_Work? example (vol. 2, 5.3): 1E-12 C/(m/s^2) on a
    # charge input, Output_Gain 0 dB, Upper_Frequency_Limit 10000, Lower_Frequency_Limit 1.
    settings = amp.read_settings(1)
    assert settings.measurement_mode == "Acceleration"
    assert (settings.sensitivity_mv_per_ms2, settings.gain) == (1.0, 1.0)
    assert (settings.high_pass_hz, settings.low_pass_hz) == (1.0, 10000.0)
    assert settings.identity == amp.identify()


def test_simulation_speaks_the_manuals_units_and_long_headers(rm, amp):
    amp.configure(1, sensitivity_mv_per_ms2=9.21, gain=20, high_pass_hz=0.1)
    instrument = raw(rm, SIM_MEASURING_AMPLIFIER)
    for query, answer in (
        ("Header?", ":Header Long"),
        (":Channel_1:Input_Type?", ":Channel_1:Input_Type Charge_Single_Ended"),
        (":Channel_1:Transducer_Sensitivity?", ":Channel_1:Transducer_Sensitivity 9.21E-12"),
        (":Channel_1:Output_Gain?", ":Channel_1:Output_Gain 26.0206"),
        (":Channel_1:Upper_Frequency_Limit?", ":Channel_1:Upper_Frequency_Limit OFf"),
        (":Channel_1:Lower_Frequency_Limit?", ":Channel_1:Lower_Frequency_Limit 0.1"),
        ("*IDN?", "ERROR -100 Command error"),  # not in the 2525's command set (Table 9.1)
    ):
        assert instrument.query(query) == answer
    instrument.close()


@pytest.mark.parametrize(
    ("channel", "sensitivity", "gain", "high_pass", "low_pass"),
    [
        (1, 9.21, 20, 0.1, None),
        (2, 35.0, 0.5, None, 3000),
        (2, 0.0123456, 10000, 10, 22400),
    ],
)
def test_configure_then_read_settings_round_trip(
    amp, channel, sensitivity, gain, high_pass, low_pass
):
    other = 3 - channel
    before_other = amp.read_settings(other)
    configured = amp.configure(
        channel,
        sensitivity_mv_per_ms2=sensitivity,
        gain=gain,
        high_pass_hz=high_pass,
        low_pass_hz=low_pass,
    )
    again = amp.read_settings(channel)
    assert configured == again
    assert again.channel == channel
    assert again.sensitivity_mv_per_ms2 == pytest.approx(sensitivity, rel=1e-6)
    assert again.gain == gain
    assert again.output_mv_per_ms2 == pytest.approx(sensitivity * gain, rel=1e-6)
    assert again.high_pass_hz == high_pass
    assert again.low_pass_hz == low_pass
    assert amp.read_settings(other) == before_other  # the other channel is untouched


def test_every_gain_and_filter_of_the_driver_is_accepted_by_the_simulation(amp):
    for gain in BK2525_GAINS:
        assert amp.configure(1, sensitivity_mv_per_ms2=1.0, gain=gain).gain == gain
    for high_pass in BK2525_HIGH_PASS_HZ:
        for low_pass in BK2525_LOW_PASS_HZ:
            settings = amp.configure(
                2,
                sensitivity_mv_per_ms2=1.0,
                gain=1,
                high_pass_hz=high_pass,
                low_pass_hz=low_pass,
            )
            assert (settings.high_pass_hz, settings.low_pass_hz) == (high_pass, low_pass)


@pytest.mark.parametrize(
    "change",
    [
        {"gain": 3},
        {"gain": 1e5},
        {"sensitivity_mv_per_ms2": 0.0},
        {"high_pass_hz": 5},
        {"low_pass_hz": 20000},
    ],
)
def test_driver_refuses_out_of_range_and_the_instrument_keeps_its_settings(amp, change):
    before = amp.read_settings(1)
    kwargs = {"sensitivity_mv_per_ms2": 5.0, "gain": 10, "high_pass_hz": 10, **change}
    with pytest.raises(InstrumentError, match="refused: allowed"):
        amp.configure(1, **kwargs)
    assert amp.read_settings(1) == before


@pytest.mark.parametrize(
    ("command", "answer", "query", "unchanged"),
    [
        (":Channel_1:Output_Gain 3", "ERROR -224 Illegal parameter value", "Output_Gain?", "0"),
        (":Channel_1:Output_Gain 81", "ERROR -224 Illegal parameter value", "Output_Gain?", "0"),
        (
            ":Channel_2:Transducer_Sensitivity 0",
            "ERROR -222 Data out of range",
            "Transducer_Sensitivity?",
            "1E-12",
        ),
        (
            ":Channel_1:Lower_Frequency_Limit 5",
            "ERROR -224 Illegal parameter value",
            "Lower_Frequency_Limit?",
            "1",
        ),
        (
            ":Channel_1:Upper_Frequency_Limit 2000",
            "ERROR -224 Illegal parameter value",
            "Upper_Frequency_Limit?",
            "10000",
        ),
        (
            ":Channel_1:Measurement_Mode Charge",
            "ERROR -224 Illegal parameter value",
            "Measurement_Mode?",
            "Acceleration",
        ),
        (":Channel_1:High_Pass_Filter 1", "ERROR -100 Command error", "Output_Gain?", "0"),
        (":Channel_1:No_Such_Thing 1", "ERROR -100 Command error", "Output_Gain?", "0"),
    ],
)
def test_simulated_measuring_amplifier_answers_errors_to_raw_bad_writes(
    rm, command, answer, query, unchanged
):
    instrument = raw(rm, SIM_MEASURING_AMPLIFIER)
    instrument.write(command)
    assert instrument.read() == answer
    channel = command.split(":")[1]
    assert instrument.query(f":{channel}:{query}") == f":{channel}:{query[:-1]} {unchanged}"
    instrument.close()


def test_simulated_measuring_amplifier_accepts_the_manuals_single_setting_writes(rm, amp):
    instrument = raw(rm, SIM_MEASURING_AMPLIFIER)
    instrument.write(":Channel_2:Output_Gain 46.0206")  # 200 V/V
    instrument.write(":Channel_2:Transducer_Sensitivity 1.03E-11")  # 10.3 pC/(m/s^2)
    instrument.write(":Channel_2:Upper_Frequency_Limit 3000")
    settings = amp.read_settings(2)
    assert (settings.gain, settings.sensitivity_mv_per_ms2, settings.low_pass_hz) == (
        200.0,
        10.3,
        3000.0,
    )
    instrument.close()


def test_an_error_answer_reaches_the_driver_as_an_instrument_error(rm, amp):
    instrument = raw(rm, SIM_MEASURING_AMPLIFIER)
    instrument.write(":Channel_1:Output_Gain 3")  # its error answer waits in the output queue
    with pytest.raises(InstrumentError, match="'ERROR -224 Illegal parameter value'"):
        amp.overloaded(1)
    instrument.close()


def test_overload_and_recall_work(rm, amp):
    assert amp.overloaded(1) is False
    assert amp.overloaded(2) is False
    instrument = raw(rm, SIM_MEASURING_AMPLIFIER)
    instrument.write("SIM:Channel_2:Overload 1")
    assert amp.overloaded(1) is False
    assert amp.overloaded(2) is True
    instrument.close()
    work = amp.recall_work()
    # The manual's example (vol. 2, 5.3), up to Additional_Filter, once per channel.
    assert work.startswith(
        ":Channel_1:Measurement_Mode Acceleration;Transducer_Sensitivity 1E-12;"
        "Input_Type Charge_Single_Ended;Input_Gain -20;Fine_Gain 0;Output_Gain 0;"
        "Upper_Frequency_Limit 10000;Lower_Frequency_Limit 1;Additional_Filter None;"
    )
    assert ":Channel_2:Measurement_Mode Acceleration;" in work


def test_wrong_instrument_at_the_address_is_an_instrument_error(rm):
    with BK2525Amplifier(SIM_POWER_AMPLIFIER, rm) as wrong:
        with pytest.raises(InstrumentError, match="Command error"):
            wrong.overloaded(1)


def test_power_amplifier_on_off(pa):
    pa.set_output_enabled(True)
    pa.set_output_enabled(True)
    pa.set_output_enabled(False)
    pa.set_output_enabled(False)


def test_power_amplifier_state_is_what_was_set(rm, pa):
    instrument = raw(rm, SIM_POWER_AMPLIFIER)
    pa.set_output_enabled(True)
    assert instrument.query("OUTP?") == "ON"
    pa.set_output_enabled(False)
    assert instrument.query("OUTP?") == "OFF"
    instrument.close()


def test_power_amplifier_gain(rm, pa):
    assert pa.gain() == 0.0
    for gain in (0.25, 1.0, 0.0, 0.123457):
        pa.set_gain(gain)
        assert pa.gain() == gain
    with pytest.raises(InstrumentError, match=r"gain 1\.5 refused: allowed 0 to 1"):
        pa.set_gain(1.5)
    assert pa.gain() == 0.123457
    instrument = raw(rm, SIM_POWER_AMPLIFIER)
    instrument.write("GAIN 1.5")
    assert instrument.read() == '-222,"Data out of range"'
    instrument.write("OUTP MAYBE")
    assert instrument.read() == '-224,"Illegal parameter value"'
    assert pa.gain() == 0.123457
    instrument.close()


def test_power_amplifier_fault_blocks_enable(rm, pa):
    assert pa.fault() is None
    instrument = raw(rm, SIM_POWER_AMPLIFIER)
    instrument.write('SIM:FAULT 12,"Over temperature"')
    assert pa.fault() == "Over temperature (fault code 12)"
    with pytest.raises(AmplifierFaultError, match="Over temperature"):
        pa.set_output_enabled(True)
    assert instrument.query("OUTP?") == "OFF"
    pa.set_output_enabled(False)  # always allowed
    instrument.close()


def test_power_amplifier_open_interlock_blocks_enable(rm, pa):
    assert pa.interlock_closed() is True
    instrument = raw(rm, SIM_POWER_AMPLIFIER)
    instrument.write("SIM:INTERLOCK 0")
    assert pa.interlock_closed() is False
    with pytest.raises(AmplifierFaultError, match="interlock open"):
        pa.set_output_enabled(True)
    assert instrument.query("OUTP?") == "OFF"
    instrument.write("SIM:INTERLOCK 1")
    pa.set_output_enabled(True)
    assert instrument.query("OUTP?") == "ON"
    pa.set_output_enabled(False)
    instrument.close()


def test_real_pyvisa_timeout_is_a_visa_timeout_error(rm):
    instrument = raw(rm, SIM_POWER_AMPLIFIER)
    instrument.timeout = 30
    pa = ScpiPowerAmplifier(instrument)
    with pytest.raises(VisaTimeoutError, match=r"'\*RST'"):
        pa._query("*RST")  # the simulated instrument never answers *RST
    pa.close()


def test_closed_session_is_device_lost(rm):
    instrument = raw(rm, SIM_POWER_AMPLIFIER)
    pa = ScpiPowerAmplifier(instrument)
    assert pa.interlock_closed() is True
    instrument.close()  # as if the driver's session were closed behind its back
    with pytest.raises(DeviceLostError, match="power amplifier at ASRL1::INSTR"):
        pa.set_output_enabled(False)


class _Wire:
    """A pyvisa-sim resource that logs every message as the bytes put on the wire."""

    def __init__(self, resource):
        self._resource = resource
        self.exchange: list[tuple[str, bytes]] = []

    @property
    def timeout(self):
        return self._resource.timeout

    def _bytes(self, text: str, termination: str) -> bytes:
        return (text + termination).encode("ascii")

    def write(self, message: str):
        self.exchange.append(("->", self._bytes(message, self._resource.write_termination)))
        return self._resource.write(message)

    def query(self, message: str) -> str:
        self.exchange.append(("->", self._bytes(message, self._resource.write_termination)))
        answer = self._resource.query(message)
        self.exchange.append(("<-", self._bytes(answer, self._resource.read_termination)))
        return answer

    def read(self) -> str:
        answer = self._resource.read()
        self.exchange.append(("<-", self._bytes(answer, self._resource.read_termination)))
        return answer

    def close(self) -> None:
        self._resource.close()


def test_power_amplifier_run_exchange_is_byte_exact(rm):
    """What a run sends: enable (interlock, fault, on, confirm), one poll per period (fault,
    interlock), a fault found by the poll, disable (off, confirm)."""
    wire = _Wire(raw(rm, SIM_POWER_AMPLIFIER))
    pa = ScpiPowerAmplifier(wire)
    pa.set_output_enabled(True)
    assert pa.fault() is None and pa.interlock_closed()
    raw(rm, SIM_POWER_AMPLIFIER).write('SIM:FAULT 3,"Over-current"')
    assert pa.fault() == "Over-current (fault code 3)"
    pa.set_output_enabled(False)
    assert wire.exchange == [
        ("->", b"INT?\n"),
        ("<-", b"1\n"),
        ("->", b"STAT:FAULT?\n"),
        ("<-", b'0,"No fault"\n'),
        ("->", b"OUTP ON\n"),
        ("->", b"OUTP?\n"),
        ("<-", b"ON\n"),
        ("->", b"STAT:FAULT?\n"),
        ("<-", b'0,"No fault"\n'),
        ("->", b"INT?\n"),
        ("<-", b"1\n"),
        ("->", b"STAT:FAULT?\n"),
        ("<-", b'3,"Over-current"\n'),
        ("->", b"OUTP OFF\n"),
        ("->", b"OUTP?\n"),
        ("<-", b"OFF\n"),
    ]


def test_measuring_amplifier_run_exchange_is_byte_exact(rm):
    """What a run sends the 2525 (manual vol. 2 sections as the driver cites them): Header Long
    (4.3.2), Input_Type? (5.3: charge -> C per m/s^2), one message per setting with SI
    sensitivity and dB gain (5.3), Identify? (Table 9.1), the read-back with long headers,
    then one overload poll per period (not a command of the pages read: see the driver)."""
    wire = _Wire(raw(rm, SIM_MEASURING_AMPLIFIER))
    amp = BK2525Amplifier(wire, channels=2)
    settings = amp.configure(1, sensitivity_mv_per_ms2=1.0, gain=10.0)
    assert (settings.sensitivity_mv_per_ms2, settings.gain) == (1.0, 10.0)
    assert amp.overloaded(1) is False
    assert wire.exchange == [
        ("->", b"Header Long\n"),
        ("->", b":Channel_1:Input_Type?\n"),
        ("<-", b":Channel_1:Input_Type Charge_Single_Ended\n"),
        ("->", b":Channel_1:Measurement_Mode Acceleration\n"),
        ("->", b":Channel_1:Transducer_Sensitivity 1E-12\n"),
        ("->", b":Channel_1:Output_Gain 20\n"),
        ("->", b":Channel_1:Upper_Frequency_Limit OFf\n"),
        ("->", b":Channel_1:Lower_Frequency_Limit OFf\n"),
        ("->", b"Identify?\n"),
        ("<-", b":Identify Bruel&Kjaer,2525,SIM-2525-0001,pyvisa-sim 1.0\n"),
        ("->", b":Channel_1:Measurement_Mode?\n"),
        ("<-", b":Channel_1:Measurement_Mode Acceleration\n"),
        ("->", b":Channel_1:Transducer_Sensitivity?\n"),
        ("<-", b":Channel_1:Transducer_Sensitivity 1E-12\n"),
        ("->", b":Channel_1:Output_Gain?\n"),
        ("<-", b":Channel_1:Output_Gain 20\n"),
        ("->", b":Channel_1:Upper_Frequency_Limit?\n"),
        ("<-", b":Channel_1:Upper_Frequency_Limit OFf\n"),
        ("->", b":Channel_1:Lower_Frequency_Limit?\n"),
        ("<-", b":Channel_1:Lower_Frequency_Limit OFf\n"),
        ("->", b":Channel_1:Overload?\n"),
        ("<-", b":Channel_1:Overload 0\n"),
    ]


def test_the_definitions_read_by_libyaml_are_pyvisa_sims() -> None:
    """sim.visa.parse_file (libyaml's C BaseLoader) gives the dict pyvisa-sim's own parser
    gives, and refuses a file without a spec version as it does."""
    import importlib.resources

    from pyvisa_sim import parser

    from sim import visa

    definitions = importlib.resources.files("sim") / visa.SIM_DEFINITIONS
    with importlib.resources.as_file(definitions) as path:
        assert visa.parse_file(str(path)) == parser.parse_file(str(path))


def test_definitions_without_a_spec_version_are_refused(tmp_path) -> None:  # type: ignore[no-untyped-def]
    from sim import visa

    bad = tmp_path / "bad.yaml"
    bad.write_text("devices: {}\n", encoding="utf-8")
    with pytest.raises(ValueError, match="spec version"):
        visa.parse_file(str(bad))
    newer = tmp_path / "newer.yaml"
    newer.write_text('spec: "99.0"\n', encoding="utf-8")
    with pytest.raises(ValueError, match="newer"):
        visa.parse_file(str(newer))
