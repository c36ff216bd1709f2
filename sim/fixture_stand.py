"""The simulated stand with several DUTs on a fixture (issue 36): one reference channel and a
DUT channel per position ("dut.<position>"), one excitation.

Each position's DUT is its own sensor model; the acceleration at a position is the reference
axis's times the fixture's motion ratio there (sim.fixture_rigid.FixtureMotion), and the
fixture's crosstalk mixes the input channels' voltages; both applied per period in the
frequency domain (skipped for the rigid fixture, where they are the identity). The truth of a
DUT is its sensor model's sensitivity: the relative motion is an error of the comparison.

A triaxial DUT (issue 36 point 3) is named per channel "dut.<position>.<axis>" with the model
"triaxial@<o>": sim.triaxial's example sensor mounted with its axis o along the exciter. Each
of its channels j reads S[j, :](f) times the table's acceleration along the sensor's three
axes (sim.triaxial.Mounting: the axial motion, the exciter's own transverse motion and the
mounting's tilt, drawn once per seed), applied per period in the frequency domain. The truth
of channel j in orientation o is S[j, o] (`truth_of`).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from hardware.interfaces import DaqConfig, DaqStatus, is_dut_channel
from sim.fixture_rigid import FixtureMotion, RigidFixture, apply_crosstalk, apply_motion, is_rigid
from sim.lti import Model, MultiZoh, Network, ZohFilter
from sim.models import G_N, SensorModel
from sim.stand import SimulatedStand, catalogue_sensor
from sim.teds import position_teds
from sim.triaxial import (
    AXIS_NAMES,
    MASS_G,
    Mounting,
    TableTransverse,
    TriaxialSensor,
    example_sensor,
)


def channel_delays(config: DaqConfig, interval_s: float) -> dict[str, float]:
    """Each sampled input's delay after the reference (s) on a multiplexed converter: the
    inputs in `config.inputs` order, `interval_s` apart (the stand file's [daq] skew_s, the
    first DUT channel's delay), the reference's 0. The drive read-back is not delayed here
    (the simulator copies it), so it is left out."""
    names = [c.name for c in config.inputs if c.name != "drive"]
    first = names.index("reference")
    return {name: (i - first) * interval_s for i, name in enumerate(names)}


TRIAXIAL_MODEL = "triaxial@"  # "triaxial@x": the example triaxial sensor, its x axis along
TRIAXIAL_MASS_G = MASS_G  # one sensor: each of its three channels counts a third
TILT_MAX_RAD = math.radians(0.05)  # the mounting's misalignment, uniform in a disc
TABLE = TableTransverse(ratio=0.0005, rocking_hz=4000.0, rocking_q=8.0)


@dataclass(frozen=True)
class TriaxialChannel:
    """Channel `axis` (0-2) of `sensor` mounted as `mounting` (its orientation along the
    exciter) on a table moving transversely as `table`."""

    sensor: TriaxialSensor
    axis: int
    mounting: Mounting
    table: TableTransverse

    def response(self, frequency_hz: np.ndarray) -> np.ndarray:
        """The channel's volts per axial m/s^2 at the reference axis (complex)."""
        f = np.asarray(frequency_hz, dtype=float)
        row = self.sensor.matrix(f)[:, self.axis, :]  # mV/(m/s^2) per sensor axis
        acceleration = self.mounting.acceleration(f, self.table)  # per axial m/s^2
        return np.asarray(np.sum(row * acceleration, axis=1) * 1e-3)

    def sensitivity(self, frequency_hz: np.ndarray, rms_ms2: float = 0.0) -> np.ndarray:
        """The truth: S[axis, orientation](f) in mV/(m/s^2), complex (level independent)."""
        f = np.atleast_1d(np.asarray(frequency_hz, dtype=float))
        return np.asarray(self.sensor.matrix(f)[:, self.axis, self.mounting.orientation])


def triaxial_orientation(model: str) -> int | None:
    """The orientation (0-2) a "triaxial@<x|y|z>" model names; None for any other model
    (ValueError for a triaxial model naming no axis)."""
    if not model.startswith(TRIAXIAL_MODEL):
        return None
    axis = model[len(TRIAXIAL_MODEL) :]
    if axis not in AXIS_NAMES:
        raise ValueError(f"simulated triaxial DUT {model!r}: the axis must be x, y or z")
    return AXIS_NAMES.index(axis)


def _stand_in(channel: TriaxialChannel) -> SensorModel:
    """A SensorModel for what the stand needs beyond the response: mass (a third of the
    sensor's), noise (the catalogue piezo's density at this axis's sensitivity)."""
    axis = channel.sensor.axes[channel.axis]
    return dataclasses.replace(
        catalogue_sensor("piezo"),
        name=f"triaxial {AXIS_NAMES[channel.axis]}",
        description=channel.sensor.name,
        sensitivity_mv_per_ms2=axis.sensitivity_mv_per_ms2,
        transverse_sensitivity=0.0,
        mass_g=TRIAXIAL_MASS_G / 3,
    )


class FixtureStand(SimulatedStand):
    """`SimulatedStand` with `duts` (input channel "dut.<position>" -> its sensor, or a
    catalogue name) on `fixture` (rigid by default), the exciter loaded by every DUT and the
    fixture's own `fixture_mass_g` (g). `multiplexed`: the inputs sampled one after another,
    `skew_s` apart (`channel_delays`, an M-series-like board; the app's simulated stand), else
    every DUT channel `skew_s` after the reference. Other arguments as SimulatedStand's; the
    first DUT is `dut` (its TEDS, `truth`)."""

    def __init__(
        self,
        duts: Mapping[str, str | SensorModel],
        *,
        fixture: FixtureMotion | None = None,
        fixture_mass_g: float = 0.0,
        multiplexed: bool = False,
        **kwargs: object,
    ):
        if not duts:
            raise ValueError("simulated fixture stand: needs at least one DUT")
        for name in duts:
            if not is_dut_channel(name) or name == "dut":
                raise ValueError(f"simulated fixture stand: {name!r} is not a 'dut.<position>'")
        seed = kwargs.get("seed", 0)
        mount_rng = np.random.default_rng([int(seed) if isinstance(seed, int) else 0, 363])
        self.triaxial: dict[str, TriaxialChannel] = {}
        mountings: dict[tuple[str, int], Mounting] = {}  # one per position and orientation
        for name, model in duts.items():
            o = triaxial_orientation(model) if isinstance(model, str) else None
            if o is None:
                continue
            parts = name.split(".")
            if len(parts) != 3:
                raise ValueError(f"simulated fixture stand: a triaxial DUT on {name!r}")
            key = (parts[1], o)
            if key not in mountings:
                mountings[key] = Mounting.draw(o, mount_rng, TILT_MAX_RAD)
            axis = AXIS_NAMES.index(parts[2])
            self.triaxial[name] = TriaxialChannel(example_sensor(), axis, mountings[key], TABLE)
        self.duts = {
            name: _stand_in(self.triaxial[name]) if name in self.triaxial else catalogue_sensor(m)
            for name, m in duts.items()
        }
        super().__init__(next(iter(self.duts.values())), **kwargs)  # type: ignore[arg-type]
        self.fixture: FixtureMotion = fixture or RigidFixture()
        self.fixture_mass_g = float(fixture_mass_g)
        mounted = getattr(self.fixture, "mounted", None)
        if mounted is not None:  # this run's mounting of the block (sim.fixture: per seed)
            masses: dict[str, float] = {}  # g per position (a triaxial's three channels add)
            for name, sensor in self.duts.items():
                position = name.split(".")[1]
                masses[position] = masses.get(position, 0.0) + sensor.mass_g
            self.fixture = mounted(self.seed, masses, self.fixture_mass_g)
        self.multiplexed = multiplexed
        # each DUT's own noise streams (sensor, converter), apart from the single-DUT ones
        streams = np.random.SeedSequence([self.seed, 36]).spawn(2 * len(self.duts))
        self._dut_noise = {
            name: (np.random.default_rng(streams[2 * i]), np.random.default_rng(streams[2 * i + 1]))
            for i, name in enumerate(self.duts)
        }
        self._cubics: dict[str, ZohFilter] = {}
        # each position's sensor its own TEDS; the first's is the stand's `dut_teds`
        self.position_teds = position_teds(self.duts, self.seed)
        self.dut_teds = next(iter(self.position_teds.values()))

    def read_teds_channel(self, channel: str) -> tuple[int, ...]:
        """The bits of the TEDS of the sensor on DUT input `channel` (KeyError: no such)."""
        return self.position_teds[channel].read()

    def write_teds_channel(self, channel: str, bits: tuple[int, ...]) -> None:
        """Write the TEDS of the sensor on DUT input `channel` (refused unless it decodes)."""
        self.position_teds[channel].write(bits)

    def truth_of(self, channel: str) -> SensorModel | TriaxialChannel:
        """The sensor on the DUT input `channel` (its truth: `.sensitivity(f, rms)`)."""
        return self.triaxial.get(channel) or self.duts[channel]

    def truth(self, frequency_hz: np.ndarray, rms_ms2: float = 0.0) -> np.ndarray:
        """The first DUT's true complex sensitivity in mV/(m/s^2)."""
        return self.truth_of(next(iter(self.duts))).sensitivity(frequency_hz, rms_ms2)

    def configure(self, config: DaqConfig) -> DaqStatus:
        """One network node per DUT input, each sampled at its own delay (`multiplexed`: the
        n-th input after the reference n x `skew_s` after it); every input's in `skews_s`."""
        self._set_ranges(config)
        fs = config.sample_rate_hz
        m, d = self.model, self.deviations
        mass = sum(s.mass_g for s in self.duts.values()) + self.fixture_mass_g
        exciter = m.exciter.loaded(mass)
        network = (
            Network()
            .add(
                "acceleration",
                m.amplifier.anti_imaging(fs).then(
                    *exciter.acceleration_model().stages, gain=exciter.midband_ms2_per_v
                ),
            )
            .add("displacement", m.exciter.displacement_stage(), "acceleration")
            .add("reference", m.reference.model(), "acceleration")
            .add("transverse", m.exciter.transverse_stage(), "acceleration")
        )
        delays = channel_delays(config, m.skew_s)
        if not self.multiplexed:  # every DUT channel sampled `skew_s` after the reference
            delays = {n: (0.0 if n == "reference" else m.skew_s) for n in delays}
        outputs = {name: (name, 0.0) for name in ("acceleration", "displacement", "reference")}
        self._cubics = {}
        for name, sensor in self.duts.items():
            skew = delays.get(name, m.skew_s)  # its own sampling delay (multiplexed)
            if name in self.triaxial:  # the axial acceleration; its response per period
                network = network.add(name, Model(()), "acceleration")
                outputs[name] = (name, skew)
                continue
            terms = {
                "acceleration": d.dut_motion,
                "transverse": sensor.transverse_sensitivity * d.transverse_cos,
            }
            network = network.combine(f"{name}:input", terms).add(
                name, sensor.model(), f"{name}:input"
            )
            outputs[name] = (name, skew)
            if sensor.cubic_per_ms2_sq:
                self._cubics[name] = ZohFilter(sensor.model(), fs, skew)
        if self._cubics:
            outputs["cubic_input"] = ("acceleration", 0.5 / fs)
        self._chain = MultiZoh(network, outputs, fs)
        self._cubic = None
        first = next((n for n in delays if is_dut_channel(n)), None)
        return DaqStatus(
            actual_sample_rate_hz=fs,
            skew_s=delays[first] if first is not None else m.skew_s,
            skews_s=delays,
        )

    def _outputs(
        self, chain: dict[str, np.ndarray], reference: np.ndarray, drive: np.ndarray, v_off: bool
    ) -> dict[str, np.ndarray]:
        """Each DUT's output at its position, its own noise, the hum and converter of a DUT
        channel; the fixture's crosstalk across the inputs; quantised at each input's range."""
        m, d = self.model, self.deviations
        n = drive.size
        fs = self._require_config().sample_rate_hz
        sensor_noise = math.sqrt(fs / 2) * G_N
        hum_reference, hum_dut = self._hum(n, fs)
        if m.driven_hum and not v_off and np.any(drive != 0.0):
            driven_reference, driven_dut = self._driven_hum(n, fs)
            hum_reference = hum_reference + driven_reference
            hum_dut = hum_dut + driven_dut
        rigid = is_rigid(self.fixture)
        reference *= d.daq_gain_reference
        reference += hum_reference
        reference += self._noise["adc_ref"].standard_normal(n) * m.adc.noise_v
        out = {"reference": reference}
        for name, sensor in self.duts.items():
            x = chain[name]
            cubic = self._cubics.get(name)
            if cubic is not None:
                x += cubic.process(sensor.cubic_per_ms2_sq * chain["cubic_input"] ** 3)
            if name in self.triaxial:
                x = self._triaxial_volts(name, x, fs)
            if not rigid:
                x = apply_motion(x, self.fixture, name.split(".")[1], fs)
            rng_sensor, rng_adc = self._dut_noise[name]
            noise = rng_sensor.standard_normal(n)
            noise *= sensor.noise_g_per_rthz * sensor_noise * sensor.sensitivity_mv_per_ms2 * 1e-3
            x += noise
            x *= d.daq_gain_dut
            x += hum_dut
            x += rng_adc.standard_normal(n) * m.adc.noise_v
            out[name] = x
        if not rigid:
            out = apply_crosstalk(out, self.fixture, fs)
        out["drive"] = drive.copy()
        for name in out:
            if name in self._ranges:
                out[name] = m.adc.quantise(out[name], self._ranges[name])
        return out

    def _triaxial_volts(self, channel: str, block: np.ndarray, fs: float) -> np.ndarray:
        """One period of a triaxial channel's noise-free output (V) from the axial
        acceleration at the reference axis (m/s^2): each DFT bin times its response."""
        spectrum = np.fft.rfft(block)
        frequency = np.fft.rfftfreq(block.size, 1.0 / fs)
        spectrum *= self.triaxial[channel].response(frequency)
        return np.fft.irfft(spectrum, n=block.size)
