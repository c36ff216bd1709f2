"""The stand file's [[instrument]] entries (app.stand.instruments): each refusal names the
entry and key; an instrument overdue on the run date refuses the run before anything moves,
naming it and its due date (exit 2); the simulated stand lists its own."""

from __future__ import annotations

from datetime import date
from pathlib import Path

import pytest

from app.cli import main
from app.stand import config as stand_config
from app.stand.instruments import (
    InstrumentError,
    InstrumentRole,
    SensorDriver,
    environment_sensor,
    overdue,
    parse_humidity,
    parse_instruments,
)

ROOT = Path(__file__).resolve().parents[3]
SIM_STAND = (ROOT / "sim" / "stand.toml").read_text(encoding="utf-8")
DAQ = {
    "role": "daq",
    "model": "NI PCIe-6351",
    "serial": "1A2B",
    "calibration_due": date(2027, 3, 31),
}


def test_the_simulated_stand_lists_its_daq_amplifier_and_sensor() -> None:
    instruments = stand_config.load(None).instruments
    assert [x.role for x in instruments] == [
        InstrumentRole.DAQ,
        InstrumentRole.MEASURING_AMPLIFIER,
        InstrumentRole.ENVIRONMENT_SENSOR,
    ]
    sensor = environment_sensor(instruments)
    assert sensor is not None and sensor.resource == "ASRL3::INSTR"
    assert sensor.driver is SensorDriver.FLUKE_1620A


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"role": "oscilloscope"}, "instrument[0].role: 'oscilloscope' is not one of"),
        ({"model": " "}, "instrument[0].model: required"),
        ({"serial": None}, "instrument[0].serial: required"),
        ({"calibration_due": "next year"}, "instrument[0].calibration_due: 'next year' is not"),
        ({"colour": "red"}, "instrument[0].colour: unknown key"),
        ({"resource": "ASRL3::INSTR"}, "instrument[0].resource: only an environment sensor"),
    ],
)
def test_a_bad_entry_is_refused_naming_entry_and_key(change: dict, message: str) -> None:
    entry = {k: v for k, v in {**DAQ, **change}.items() if v is not None}
    with pytest.raises(InstrumentError, match=message.replace("[", r"\[").replace("]", r"\]")):
        parse_instruments([entry])


def test_a_missing_due_date_is_refused() -> None:
    entry = {k: v for k, v in DAQ.items() if k != "calibration_due"}
    with pytest.raises(InstrumentError, match=r"instrument\[0\].calibration_due: required"):
        parse_instruments([entry])


def test_a_sensor_needs_a_known_driver_and_only_one_sensor_is_read() -> None:
    sensor = {**DAQ, "role": "environment sensor", "resource": "ASRL3::INSTR"}
    with pytest.raises(InstrumentError, match=r"instrument\[0\].driver: '' is not one of"):
        parse_instruments([sensor])
    sensor["driver"] = "fluke1620a"
    with pytest.raises(InstrumentError, match="more than one environment sensor"):
        parse_instruments([sensor, sensor])
    assert environment_sensor(parse_instruments([sensor])) is not None


def test_overdue_is_strictly_before_the_run_date() -> None:
    (daq,) = parse_instruments([DAQ])
    assert overdue([daq], date(2027, 3, 31)) == []  # due that day: still in calibration
    assert overdue([daq], date(2027, 4, 1)) == [
        "Data acquisition (DAQ) NI PCIe-6351, serial 1A2B was due for calibration on 2027-03-31"
    ]


@pytest.mark.parametrize(
    ("text", "value"), [("45%", 45.0), (" 45 % ", 45.0), ("45,5", 45.5), ("0", 0.0)]
)
def test_humidity_reads_with_or_without_its_percent_sign(text: str, value: float) -> None:
    assert parse_humidity(text) == value


@pytest.mark.parametrize("text", ["101%", "-1", "wet", "nan"])
def test_humidity_outside_0_to_100_or_not_a_number_is_refused_naming_the_option(text: str) -> None:
    with pytest.raises(ValueError, match=r"humidity \(--humidity\)"):
        parse_humidity(text)


def test_a_run_with_an_overdue_instrument_is_refused_before_anything_moves(
    tmp_path: Path, capsys
) -> None:
    stand = tmp_path / "stand.toml"
    stand.write_text(
        SIM_STAND.replace("calibration_due = 2199-12-31\n", "calibration_due = 2020-01-31\n", 1),
        encoding="utf-8",
    )
    out = tmp_path / "runs"
    argv = ["run", "--stand", str(stand), "--dut", "piezo", "--dut-id", "SN-C", "--out", str(out)]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "instrument (" in err and "SIM-DAQ-0001 was due for calibration on 2020-01-31" in err
    assert "Traceback" not in err
    assert not out.exists() or not any(out.iterdir())  # no run folder
