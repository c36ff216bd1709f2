"""The TEDS memory of the simulated stand's DUT (IEEE 1451.4, Template 25), so reading a
sensor's identity and nominal sensitivity, and writing a new calibration, are tested without
hardware. The memory holds bits, exactly as a sensor's EEPROM; writes are counted. On a
fixture of several DUTs (issue 36) every position's sensor has its own memory
(`position_teds`), each with its own serial number."""

from __future__ import annotations

from collections.abc import Mapping
from datetime import date

from hardware.teds import (
    AccelerometerTeds,
    BasicTeds,
    Teds,
    TedsError,
    decode,
    encode,
)
from sim.models import DUT_CATALOGUE, SensorModel

SIM_MANUFACTURER_ID = 43  # an arbitrary id for the simulator's sensors
END_SELECTOR = (1, 1)
REFERENCE_160_HZ_CODE = 178  # 0.35 * 1.035^178 = 159.75 Hz, the code nearest 160 Hz
REFERENCE_23_C_CODE = 16  # 15 + 0.5 * 16 = 23 degC


def catalogue_teds(sensor: SensorModel, serial_number: int) -> tuple[int, ...]:
    """The bits a catalogue DUT's TEDS holds: its identity and nominal sensitivity (the
    manufacturer's calibration, dated 2025-01-15)."""
    model_number = list(DUT_CATALOGUE).index(sensor.name) + 1 if sensor.name in DUT_CATALOGUE else 0
    template = AccelerometerTeds(
        sensitivity_code=0,
        high_pass_code=0,
        direction=3,
        weight_code=10,
        polarity=0,
        transfer_function=None,
        reference_frequency_code=REFERENCE_160_HZ_CODE,
        reference_temperature_code=REFERENCE_23_C_CODE,
        calibration_date_code=0,
        calibration_initials_codes=(0, 0, 0),
        calibration_period_days=365,
        measurement_location_id=0,
    ).with_sensitivity(sensor.sensitivity_mv_per_ms2, date(2025, 1, 15), "MFR")
    basic = BasicTeds(SIM_MANUFACTURER_ID, model_number, 1, 1, serial_number)
    return encode(Teds(basic, 0, 25, template, END_SELECTOR))


class TedsMemory:
    """A sensor's TEDS memory: read gives the bits, write replaces them (a decodable TEDS only)."""

    def __init__(self, bits: tuple[int, ...]) -> None:
        self._bits = tuple(bits)
        self.writes = 0

    def read(self) -> tuple[int, ...]:
        return self._bits

    def write(self, bits: tuple[int, ...]) -> None:
        try:
            decode(bits)
        except TedsError as exc:
            raise TedsError(f"TEDS write refused: {exc}") from None
        self._bits = tuple(bits)
        self.writes += 1


def position_serial(seed: int, index: int) -> int:
    """The TEDS serial number of the simulated sensor at the fixture's `index`-th DUT channel
    (0: the first, the same number a single-DUT stand's sensor has for `seed`)."""
    return 10_000 + seed % 10_000 + 100_000 * index


def position_teds(sensors: Mapping[str, SensorModel], seed: int) -> dict[str, TedsMemory]:
    """Every DUT channel's TEDS memory ("dut.<position>" -> its sensor's catalogue TEDS, a
    serial number of its own: `position_serial`), in the channels' order."""
    return {
        channel: TedsMemory(catalogue_teds(sensor, position_serial(seed, index)))
        for index, (channel, sensor) in enumerate(sensors.items())
    }
