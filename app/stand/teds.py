"""Reading and writing the DUT's TEDS on a stand (simulated or NI-DAQmx): the port, the TEDS in
words, a write read back. Writing a run's result to a TEDS (which needs the run's record) is
the use case `app.procedure.teds_write`; it is never implicit: `accelcal teds write` asks
first."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from hardware.interfaces import InputChannel
from hardware.teds import Teds, TedsError, encode

if TYPE_CHECKING:
    from app.stand.config import StandConfig


@dataclass(frozen=True)
class TedsPort:
    """Where the DUT's TEDS is: the simulated stand's memory, or an NI physical channel."""

    description: str
    sim: Any = None  # a sim.stand.SimulatedStand (sim.fixture_stand.FixtureStand: `channel`)
    physical_channel: str | None = None
    channel: InputChannel | None = None  # a several-DUT stand's DUT input ("dut.<position>")

    def read(self) -> tuple[int, ...]:
        if self.sim is not None:
            if self.channel is not None:
                return tuple(self.sim.read_teds_channel(self.channel.name))
            return tuple(self.sim.read_teds())
        if self.channel is not None:  # one channel of the stand's inputs, as a run reads them
            return _channel_bits(self.channel)
        from hardware.nidaq import read_teds_bits

        return read_teds_bits(str(self.physical_channel))

    def write(self, bits: tuple[int, ...]) -> None:
        if self.sim is not None:
            if self.channel is not None:
                self.sim.write_teds_channel(self.channel.name, bits)
                return
            self.sim.write_teds(bits)
            return
        from hardware.nidaq import write_teds_bits

        write_teds_bits(str(self.physical_channel), bits)


def _channel_bits(channel: InputChannel) -> tuple[int, ...]:
    """The TEDS bits of one DUT input through hardware.nidaq.read_teds_channels; TedsError
    with the reason when the channel has none."""
    from hardware.nidaq import read_teds_channels
    from hardware.teds import bits_from_bytes

    found = read_teds_channels([channel])[channel.name]
    if found.data is None:
        raise TedsError(f"TEDS on {channel.name} ({found.physical}): {found.reason}")
    return bits_from_bytes(found.data)


def fixture_channel(config: StandConfig, name: str) -> InputChannel:
    """The fixture's DUT input `name` ("dut.<position>", or an axis "dut.<position>.x") with
    [daq.dut]'s settings; ValueError naming --channel and the stand's DUT channels."""
    fixture = config.fixture
    dut = next((c for c in config.inputs if c.name == "dut"), None)
    if fixture is None or dut is None:
        raise ValueError(
            f"--channel {name}: the stand file {config.source} has no [fixture] table "
            "(its one DUT channel is read without --channel)"
        )
    inputs = {c.name: c for c in fixture.inputs(dut)}
    if name not in inputs:
        raise ValueError(
            f"--channel {name!r}: not a DUT channel of the fixture ({', '.join(inputs)})"
        )
    return inputs[name]


def open_port(
    stand_file: Path | None, dut: str = "piezo", seed: int = 0, channel: str | None = None
) -> TedsPort:
    """The DUT channel's TEDS on the stand a stand file names (the simulated stand without one,
    or when the file says backend "sim"); `channel`: one DUT input of its fixture
    ("dut.<position>"; the simulated fixture: `dut` at every position, each its own TEDS)."""
    from app.stand import config as stand_config

    config = stand_config.load(stand_file)
    if channel is not None and channel != "dut":
        named = fixture_channel(config, channel)
        if config.backend == "sim":
            from app.stand.simulated import open_simulated_fixture

            assert config.fixture is not None
            dut_input = next(c for c in config.inputs if c.name == "dut")
            duts = {c.name: dut for c in config.fixture.inputs(dut_input)}
            sim = open_simulated_fixture(duts, seed)
            return TedsPort(f"simulated stand, {channel} DUT {dut!r}", sim=sim, channel=named)
        return TedsPort(f"{config.device} {channel} {named.physical}", channel=named)
    if config.backend == "sim":
        from app.stand.simulated import open_simulated

        return TedsPort(f"simulated stand, DUT {dut!r}", sim=open_simulated(dut, seed))
    own = next(c for c in config.inputs if c.name == "dut")
    return TedsPort(f"{config.device} {own.physical}", physical_channel=own.physical)


def describe(teds: Teds) -> list[str]:
    """The TEDS in lines for people (units in the text)."""
    lines = [
        f"manufacturer id {teds.basic.manufacturer_id}, model {teds.basic.model_number}, "
        f"version {teds.basic.version_letter}{teds.basic.version_number}, "
        f"serial {teds.basic.serial_number}",
        f"template {teds.template_id}"
        + ("" if teds.selector == 0 else f" (selector {teds.selector})"),
    ]
    a = teds.accelerometer
    if a is None:
        lines.append("(not an accelerometer template: fields not decoded)")
        return lines
    lines += [
        f"sensitivity {a.sensitivity_mv_per_ms2:.5g} mV/(m/s^2) "
        f"({a.sensitivity_v_per_ms2 * 9.80665:.5g} V/g) at {a.reference_frequency_hz:.4g} Hz, "
        f"{a.reference_temperature_c:g} degC",
        f"high-pass {a.high_pass_hz:.3g} Hz, weight {a.weight_g:.3g} g",
        f"calibrated {a.calibration_date} by {a.calibration_initials.strip() or '-'}, "
        f"period {a.calibration_period_days} days",
    ]
    return lines


def sensor_named(teds: Teds) -> str:
    """The sensor a TEDS names, for people: serial, model and manufacturer ids, identity."""
    b = teds.basic
    return (
        f"serial {b.serial_number}, model {b.model_number}, manufacturer {b.manufacturer_id} "
        f"(TEDS identity {b.identity})"
    )


def write_checked(port: TedsPort, teds: Teds) -> None:
    """Write and read back; TedsError when the sensor does not hold what was written."""
    bits = encode(teds)
    port.write(bits)
    back = port.read()
    if tuple(back[: len(bits)]) != bits:
        raise TedsError(f"TEDS on {port.description}: read back differs from what was written")
