"""Reading and writing the DUT's TEDS on a stand (simulated or NI-DAQmx): the port, the TEDS in
words, a write read back. Writing a run's result to a TEDS (which needs the run's record) is
the use case `app.procedure.teds_write`; it is never implicit: `accelcal teds write` asks
first."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from hardware.teds import Teds, TedsError, encode


@dataclass(frozen=True)
class TedsPort:
    """Where the DUT's TEDS is: the simulated stand's memory, or an NI physical channel."""

    description: str
    sim: Any = None  # a sim.stand.SimulatedStand
    physical_channel: str | None = None

    def read(self) -> tuple[int, ...]:
        if self.sim is not None:
            return tuple(self.sim.read_teds())
        from hardware.nidaq import read_teds_bits

        return read_teds_bits(str(self.physical_channel))

    def write(self, bits: tuple[int, ...]) -> None:
        if self.sim is not None:
            self.sim.write_teds(bits)
            return
        from hardware.nidaq import write_teds_bits

        write_teds_bits(str(self.physical_channel), bits)


def open_port(stand_file: Path | None, dut: str = "piezo", seed: int = 0) -> TedsPort:
    """The DUT channel's TEDS on the stand a stand file names (the simulated stand without one,
    or when the file says backend "sim")."""
    from app.stand import config as stand_config

    config = stand_config.load(stand_file)
    if config.backend == "sim":
        from app.stand.simulated import open_simulated

        return TedsPort(f"simulated stand, DUT {dut!r}", sim=open_simulated(dut, seed))
    channel = next(c for c in config.inputs if c.name == "dut")
    return TedsPort(f"{config.device} {channel.physical}", physical_channel=channel.physical)


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
