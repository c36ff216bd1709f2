"""TEDS on a stand (app.stand.teds): the simulated DUT's memory read, a TEDS file decoded,
NI-DAQmx's calls with the exact bytes. Writing a run's result: tests/app/procedure/
test_teds_write.py."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace
from typing import ClassVar

import pytest

from app.cli import main
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
        self.configured = False

    def configure_teds(self, file_path: object = None) -> None:
        """DAQmx scans the sensor now mounted; until then the channel has no TEDS to give."""
        self.configured = True

    @property
    def teds_bit_stream(self) -> bytes:
        return FakeChannel.stream if self.configured else b""

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
