"""The Fluke 1620A "DewK" thermo-hygrometer driver (hardware.environment): the exact bytes it
sends and how it reads the answers (scripted resource), and the same driver against the
simulated instrument of sim/environment.yaml through pyvisa-sim."""

from __future__ import annotations

import pytest

from hardware.environment import EnvironmentReading, Fluke1620A
from hardware.errors import InstrumentError, VisaTimeoutError
from sim.visa import SIM_ENVIRONMENT_DEFINITIONS, SIM_ENVIRONMENT_SENSOR, simulated_resource_manager
from tests.hardware.test_visa_amplifiers import ScriptedResource, scripted, timeout_error

__all__ = ["scripted"]  # the fixture, shared with the amplifier tests

IDN = "HART,1620,A1B234,1.10"


def _read_script(unit: str, answer: str) -> list[tuple[str, str | None]]:
    return [
        ("*IDN?", IDN),
        ("FORM:TDST:STAT 0", None),
        ("UNIT:TEMP?", unit),
        ("MEAS? 1", answer),
    ]


def test_read_sends_identity_timestamp_off_unit_then_measure_in_this_order(scripted) -> None:
    resource: ScriptedResource = scripted(*_read_script("C", "23.100,45.30"))
    reading = Fluke1620A(resource).read(1)
    assert reading == EnvironmentReading(23.1, 45.3, IDN)
    assert resource.sent == ["*IDN?", "FORM:TDST:STAT 0", "UNIT:TEMP?", "MEAS? 1"]


def test_the_identity_is_asked_once_over_two_readings(scripted) -> None:
    script = _read_script("C", "23.100,45.30")
    resource = scripted(*script, *script[1:3], ("MEAS? 2", "22.000,50.00"))
    device = Fluke1620A(resource)
    device.read(1)
    assert device.read(2) == EnvironmentReading(22.0, 50.0, IDN)


def test_a_fahrenheit_display_is_converted_to_celsius(scripted) -> None:
    reading = Fluke1620A(scripted(*_read_script("F", "73.580,45.30"))).read()
    assert reading.temperature_c == pytest.approx(23.1, abs=1e-9)
    assert reading.humidity_percent == 45.3


@pytest.mark.parametrize(
    ("answer", "words"),
    [
        ("23.1", "not '<temperature>,<humidity>'"),  # one value
        ("1,1,23.1,C,45.3,%", "not '<temperature>,<humidity>'"),  # the time-stamped form
        ("abc,45.3", "not '<temperature>,<humidity>'"),
        ("23.1,101.0", "humidity"),  # above 100 %
        ("23.1,-0.5", "humidity"),
        ("200.0,45.0", "temperature"),  # outside what the probe reports
        ("nan,45.0", "temperature"),
    ],
)
def test_an_unusable_answer_is_refused_quoting_it(scripted, answer: str, words: str) -> None:
    with pytest.raises(InstrumentError, match=words) as caught:
        Fluke1620A(scripted(*_read_script("C", answer))).read()
    assert repr(answer) in str(caught.value)


def test_an_unknown_unit_is_refused(scripted) -> None:
    resource = scripted(("*IDN?", IDN), ("FORM:TDST:STAT 0", None), ("UNIT:TEMP?", "K"))
    with pytest.raises(InstrumentError, match="temperature unit"):
        Fluke1620A(resource).read()


@pytest.mark.parametrize("channel", [0, 3, True])
def test_a_channel_other_than_1_or_2_is_refused_with_nothing_sent(scripted, channel) -> None:
    resource = scripted()
    with pytest.raises(InstrumentError, match="channel"):
        Fluke1620A(resource).read(channel)
    assert resource.sent == []


def test_a_timeout_is_a_visa_timeout_error(scripted) -> None:
    resource = scripted(("*IDN?", timeout_error()))
    with pytest.raises(VisaTimeoutError):
        Fluke1620A(resource).read()


def test_the_simulated_instrument_answers_as_the_real_one_is_read() -> None:
    manager = simulated_resource_manager(fresh=True, definitions_name=SIM_ENVIRONMENT_DEFINITIONS)
    with Fluke1620A(SIM_ENVIRONMENT_SENSOR, manager) as device:
        assert device.read(1) == EnvironmentReading(23.1, 45.3, "HART,1620,SIM-1620-0001,1.10")
        device._write("SIM:MEAS 1,21.500,38.20")  # the simulator's own command: a new reading
        device._write("SIM:UNIT:TEMP F")
        reading = device.read(1)
    assert reading.temperature_c == pytest.approx((21.5 - 32) * 5 / 9)  # read as F
    assert reading.humidity_percent == 38.2
