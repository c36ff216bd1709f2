"""Open the stand a configuration names: the simulated stand or real hardware, never a silent
fallback from one to the other."""

from __future__ import annotations

import dataclasses
import logging
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from app.stand.config import ConfigError, StandConfig
from dsp.calibration import ReferenceChain
from dsp.uncertainty import Budget
from hardware.interfaces import Daq, MeasuringAmplifier, OffersInputRanges, PowerAmplifier
from sim.models import DUT_CATALOGUE, EXCITER_CATALOGUE, DrivenHum, StandModel
from sim.stand import POWER_AMPLIFIER_FAULT_KINDS, Fault, SimBudget, SimulatedStand

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class Stand:
    """What the procedure drives and what the analysis may know about it; frozen: what the
    run knows of the stand is set when it is opened (`open_stand`), never changed after."""

    config: StandConfig
    daq: Daq
    chain: ReferenceChain
    budget: Budget
    measuring_amplifier: MeasuringAmplifier | None = None
    power_amplifier: PowerAmplifier | None = None
    truth: Callable[[np.ndarray, float], np.ndarray] | None = field(default=None, repr=False)
    description: str = ""
    # what else than the stand file makes this stand what it is: the simulated stand's seed
    realisation: str = ""
    # the +-ranges (V) its inputs may use (`offered_ranges`); () : the stand file's range_v only
    input_ranges_v: tuple[float, ...] = ()

    def close(self) -> None:
        """Stop the drive and release every device (safe to call twice)."""
        try:
            self.daq.stop()
        finally:
            if self.power_amplifier is not None:  # the drive is at 0 V: output off too
                try:
                    self.power_amplifier.set_output_enabled(False)
                except Exception as exc:
                    log.error("power amplifier: output could not be switched off: %s", exc)
            for device in (self.measuring_amplifier, self.power_amplifier):
                if device is not None:
                    device.close()
            self.daq.close()


def open_stand(
    config: StandConfig,
    *,
    dut: str = "piezo",
    seed: int = 0,
    paced: bool = False,
    faults: tuple[Fault, ...] = (),
    systematic: bool = True,
    model: StandModel | None = None,
    dut_mass_g: float | None = None,
    exciter: str | None = None,
    chain: ReferenceChain | None = None,
    budget: Budget | None = None,
    driven_hum: tuple[DrivenHum, ...] = (),
    duts: Mapping[str, str] | None = None,
) -> Stand:
    """The stand of `config`; the simulated one needs a catalogue DUT (`dut`), carrying
    `dut_mass_g` (g) instead of its catalogue mass when given, and `exciter` (a name of
    the simulated exciter catalogue) instead of the default one. `chain` and `budget`: the
    reference chain and type B budget the analysis uses when the run takes them from
    elsewhere than the stand (the records' certificate table); the stand is not changed
    after it is opened. `driven_hum`: hum the simulated stand adds only while it is driven
    (issue 32 point 3). `duts`: several DUTs on the stand file's fixture (input channel
    "dut.<position>" -> catalogue DUT; the simulated stand: sim.fixture_stand, the fixture's
    motion from sim.fixture_rigid.fixture_motion)."""
    if config.backend == "sim":
        # without a power amplifier only the legacy `amplifier-fault` (raised by the DAQ) works
        kinds = {f.kind for f in faults} & (set(POWER_AMPLIFIER_FAULT_KINDS) - {"amplifier-fault"})
        needs_power = sorted(kinds)
        if needs_power and not config.power_amplifier:
            raise ConfigError(
                f"--fault {', '.join(needs_power)}: the stand has no power amplifier "
                f"(amplifiers.power in {config.source})"
            )
        if model is None:
            model = StandModel(reference_gain=config.reference.gain, skew_s=config.skew_s)
        if exciter is not None:  # one of the catalogue's exciters (issue 26: long-stroke)
            model = dataclasses.replace(model, exciter=EXCITER_CATALOGUE[exciter])
        if driven_hum:
            model = dataclasses.replace(model, driven_hum=tuple(driven_hum))
        sensor = DUT_CATALOGUE.get(dut)
        if sensor is not None and dut_mass_g is not None:
            sensor = dataclasses.replace(sensor, mass_g=dut_mass_g)
        common: dict[str, Any] = dict(
            model=model,
            sim_budget=SimBudget(config.budget, config.simulation),
            seed=seed,
            paced=paced,
            faults=faults,
            systematic=systematic,
        )
        sim: SimulatedStand
        if duts:
            from sim.fixture_rigid import fixture_motion
            from sim.fixture_stand import FixtureStand

            fixture_g = 1000 * config.fixture.mass_kg if config.fixture is not None else 0.0
            sim = FixtureStand(
                duts,
                fixture=fixture_motion(config.raw),
                fixture_mass_g=fixture_g,
                multiplexed=True,  # each DUT channel its own delay, as on the real board
                **common,
            )
        else:
            sim = SimulatedStand(sensor if sensor is not None else dut, **common)
        return Stand(
            input_ranges_v=offered_ranges(config, sim),
            config=config,
            daq=sim,
            chain=chain if chain is not None else sim.reference_chain(dut_gain=config.dut_gain),
            budget=budget if budget is not None else config.budget,
            measuring_amplifier=sim.measuring_amplifier() if config.measuring_amplifier else None,
            power_amplifier=sim.power_amplifier() if config.power_amplifier else None,
            truth=sim.truth,
            description=(
                f"simulated stand, DUTs {', '.join(f'{k[4:]}={v}' for k, v in duts.items())}, "
                f"seed {seed}"
                if duts
                else f"simulated stand, DUT {dut!r}, seed {seed}"
            ),
            realisation=f"simulated, seed {seed}, {'drawn' if systematic else 'nominal'} values",
        )
    if faults:
        raise ConfigError("--fault: faults can only be injected into the simulated stand")
    if driven_hum:
        raise ConfigError("--sim-hum: hum can only be added to the simulated stand")
    from hardware.discovery import list_ni_devices
    from hardware.errors import DaqNotFoundError
    from hardware.nidaq import NiDaq  # real hardware: errors say what is missing, no fallback
    from hardware.visa_amplifiers import BK2525Amplifier, ScpiPowerAmplifier

    devices = [d["name"] for d in list_ni_devices()]  # "NI-DAQmx is not installed: ..." first
    if config.device not in devices:
        raise DaqNotFoundError(
            f"{config.source}: daq.device {config.device!r} not found; NI-DAQmx sees "
            f"{', '.join(devices) or 'no device'}"
        )
    daq = NiDaq(config.device)
    measuring = power = None
    try:
        if config.measuring_amplifier:
            measuring = BK2525Amplifier(config.measuring_amplifier)
        if config.power_amplifier:
            power = ScpiPowerAmplifier(config.power_amplifier)
        offered = offered_ranges(config, daq)
    except BaseException:
        for device in (measuring, power):
            if device is not None:
                device.close()
        daq.close()
        raise
    return Stand(
        config=config,
        daq=daq,
        chain=chain if chain is not None else config.reference_chain(),
        budget=budget if budget is not None else config.budget,
        measuring_amplifier=measuring,
        power_amplifier=power,
        description=f"NI-DAQmx device {config.device}",
        input_ranges_v=offered,
    )


def offered_ranges(config: StandConfig, daq: Daq) -> tuple[float, ...]:
    """The +-ranges (V) a run may pick from: the stand file's `daq.input_ranges_v`, each one
    offered by the device (ConfigError naming one it does not offer), else the device's own
    list; () when neither says (the channels' range_v are used as they stand)."""
    device: tuple[float, ...] = ()
    if isinstance(daq, OffersInputRanges):
        device = daq.input_ranges_v()
    if not config.input_ranges_v:
        return device
    if device:
        missing = [
            r for r in config.input_ranges_v if not any(abs(r - d) <= 1e-9 * d for d in device)
        ]
        if missing:
            raise ConfigError(
                f"{config.source}: daq.input_ranges_v: +-{missing[0]:g} V is not a range the "
                f"device offers ({', '.join(f'{d:g}' for d in device)} V)"
            )
    return config.input_ranges_v


def read_environment(config: StandConfig, now_utc: str) -> dict[str, object] | None:
    """The ambient temperature (deg C) and relative humidity (%) read from the environment
    sensor the stand file names ([[instrument]] with a resource), as config.json stores it
    (app.certificate.complete.EnvironmentRecord); None when the stand names none or the
    sensor cannot be read (logged: the certificate then asks for typed values)."""
    from app.stand.instruments import environment_sensor
    from hardware.errors import HardwareError

    sensor = environment_sensor(config.instruments)
    if sensor is None:
        return None
    from hardware.environment import Fluke1620A

    manager = None
    if config.backend == "sim":  # the simulated stand's sensor, sim/environment.yaml
        from sim.visa import SIM_ENVIRONMENT_DEFINITIONS, simulated_resource_manager

        manager = simulated_resource_manager(definitions_name=SIM_ENVIRONMENT_DEFINITIONS)
    try:
        with Fluke1620A(sensor.resource, manager) as device:
            reading = device.read(1)
    except HardwareError as exc:
        log.warning("environment sensor %s not read: %s", sensor.label, exc)
        return None
    return {
        "temperature_c": round(reading.temperature_c, 3),
        "humidity_percent": round(reading.humidity_percent, 2),
        "sensor": sensor.label,
        "read_utc": now_utc,
    }
