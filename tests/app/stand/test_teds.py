"""TEDS on a stand: the simulated DUT's memory read and written, NI-DAQmx's calls with the exact
bytes, and writing only after a confirmation."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace
from typing import ClassVar

import pytest

from app.cli import main
from app.records.run_folder import load_run
from app.stand import teds as teds_io
from hardware.nidaq import read_teds_bits, write_teds_bits
from hardware.teds import bitstream_bytes, decode, read_ted_file
from sim.models import DUT_CATALOGUE

VOLTAGE_TED = Path(__file__).resolve().parents[2] / "data" / "teds" / "Voltage.ted"


def test_the_simulated_dut_carries_its_nominal_sensitivity_in_teds() -> None:
    port = teds_io.open_port(None, "capacitive", seed=7)
    teds = decode(port.read())
    assert teds.basic.serial_number == 10_007 and teds.template_id == 25
    nominal = DUT_CATALOGUE["capacitive"].sensitivity_mv_per_ms2
    # coded to half a ConRelRes step: (1.0003 ** 0.5 - 1) = 0.015 %
    assert teds.accelerometer.sensitivity_mv_per_ms2 == pytest.approx(nominal, rel=1.5e-4)


def test_a_complete_run_is_written_to_the_teds_and_read_back(complete_run: Path) -> None:
    record = load_run(complete_run)
    port = teds_io.open_port(None, "piezo", seed=5)
    new = teds_io.calibrated_teds(port.read(), record, "js")
    teds_io.write_checked(port, new)
    assert port.sim.dut_teds.writes == 1
    back = decode(port.read()).accelerometer
    expected = record.results["reference"]["sensitivity_mv_per_ms2"]
    assert back.sensitivity_mv_per_ms2 == pytest.approx(expected, rel=1.5e-4)
    assert str(back.calibration_date) == record.finished_utc[:10]
    assert back.calibration_initials == "JS "


def test_writing_needs_a_confirmation(
    complete_run: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    # the simulated piezo's TEDS names serial 10000, the run's DUT is SN-42 (issue 24 point 6)
    assert main(["teds", "write", str(complete_run), "--yes"]) == 2
    captured = capsys.readouterr()
    assert "sensor on simulated" in captured.out and "serial 10000" in captured.out
    assert "the run's DUT is SN-42" in captured.err and "--yes-different-sensor" in captured.err
    other = ["teds", "write", str(complete_run), "--yes-different-sensor", "re-labelled"]
    monkeypatch.setattr("sys.stdin.isatty", lambda: False)
    assert main(other) == 2
    assert "--yes: writing a TEDS needs a confirmation" in capsys.readouterr().err
    monkeypatch.setattr("sys.stdin.isatty", lambda: True)
    monkeypatch.setattr("builtins.input", lambda prompt: "n")
    assert main(other) == 0
    captured = capsys.readouterr()
    assert "TEDS not written" in captured.out and "OVERRIDE" not in captured.err
    assert main([*other, "--yes"]) == 0
    captured = capsys.readouterr()
    assert "TEDS written and read back" in captured.out
    assert "OVERRIDE" in captured.err and "override: re-labelled" in captured.err


def test_the_teds_must_name_the_runs_sensor(complete_run: Path) -> None:
    import dataclasses

    from app.records.run_record import DutIdentity

    record = load_run(complete_run)
    teds = decode(teds_io.open_port(None, "piezo", seed=5).read())  # serial 10005
    assert "the run's DUT is SN-42" in teds_io.identity_mismatch(teds, record)
    for serial in ("10005", "SN-10005", f"TEDS-{teds.basic.identity.replace('/', '-')}"):
        same = dataclasses.replace(record, dut=DutIdentity(id=serial))
        assert teds_io.identity_mismatch(teds, same) is None, serial
    assert teds_io.identity_mismatch(teds, record, teds.basic.identity) is None
    other = teds.basic.identity.rsplit("/", 1)[0] + "/10006"
    assert "TEDS identity " + other in teds_io.identity_mismatch(teds, record, other)
    assert teds_io.identity_mismatch(teds, dataclasses.replace(record, dut=None)) is not None


def test_decode_prints_the_nidaqmx_sensitivity(capsys: pytest.CaptureFixture[str]) -> None:
    ted = VOLTAGE_TED.parent / "Accelerometer.ted"
    assert main(["teds", "decode", str(ted)]) == 0
    assert "(49.033 V/g)" in capsys.readouterr().out


class FakeChannel:
    """nidaqmx.system.PhysicalChannel as far as TEDS goes; records what is written."""

    written: ClassVar[list[tuple[str, list[int], object]]] = []
    stream = b""

    def __init__(self, name: str) -> None:
        self.name = name

    @property
    def teds_bit_stream(self) -> bytes:
        return FakeChannel.stream

    def write_to_teds_from_array(self, bit_stream: list[int], basic_teds_options: object) -> None:
        FakeChannel.written.append((self.name, bit_stream, basic_teds_options))


def test_nidaqmx_is_asked_for_the_exact_bytes() -> None:
    ni = SimpleNamespace(
        system=SimpleNamespace(PhysicalChannel=FakeChannel),
        constants=SimpleNamespace(WriteBasicTEDSOptions=SimpleNamespace(DO_NOT_WRITE="dnw")),
    )
    bits = read_ted_file(VOLTAGE_TED)
    FakeChannel.stream = bitstream_bytes(bits)
    read = read_teds_bits("Dev1/ai1", ni=ni)
    assert read[: len(bits)] == bits and set(read[len(bits) :]) <= {0}
    write_teds_bits("Dev1/ai1", bits, ni=ni)
    name, stream, option = FakeChannel.written[-1]
    assert (name, option) == ("Dev1/ai1", "dnw")
    assert stream[:7] == [17, 64, 0, 32, 4, 57, 48]  # nidaqmx-python's own expectation
