"""The simulated stand with several DUTs on a fixture (issue 36): one reference channel and a
DUT channel per position ("dut.<position>"), one excitation.

Each position's DUT is its own sensor model; the acceleration at a position is the reference
axis's times the fixture's motion ratio there (sim.fixture_rigid.FixtureMotion), and the
fixture's crosstalk mixes the input channels' voltages; both applied per period in the
frequency domain (skipped for the rigid fixture, where they are the identity). The truth of a
DUT is its sensor model's sensitivity: the relative motion is an error of the comparison.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from hardware.interfaces import DaqConfig, DaqStatus, is_dut_channel
from sim.fixture_rigid import FixtureMotion, RigidFixture, apply_crosstalk, apply_motion, is_rigid
from sim.lti import MultiZoh, Network, ZohFilter
from sim.models import G_N, SensorModel
from sim.stand import SimulatedStand, catalogue_sensor


class FixtureStand(SimulatedStand):
    """`SimulatedStand` with `duts` (input channel "dut.<position>" -> its sensor, or a
    catalogue name) on `fixture` (rigid by default), the exciter loaded by every DUT and the
    fixture's own `fixture_mass_g` (g). Other arguments as SimulatedStand's; the first DUT is
    `dut` (its TEDS, `truth`)."""

    def __init__(
        self,
        duts: Mapping[str, str | SensorModel],
        *,
        fixture: FixtureMotion | None = None,
        fixture_mass_g: float = 0.0,
        **kwargs: object,
    ):
        if not duts:
            raise ValueError("simulated fixture stand: needs at least one DUT")
        for name in duts:
            if not is_dut_channel(name) or name == "dut":
                raise ValueError(f"simulated fixture stand: {name!r} is not a 'dut.<position>'")
        self.duts = {name: catalogue_sensor(model) for name, model in duts.items()}
        super().__init__(next(iter(self.duts.values())), **kwargs)  # type: ignore[arg-type]
        self.fixture: FixtureMotion = fixture or RigidFixture()
        self.fixture_mass_g = float(fixture_mass_g)
        mounted = getattr(self.fixture, "mounted", None)
        if mounted is not None:  # this run's mounting of the block (sim.fixture: per seed)
            masses = {name.split(".")[1]: s.mass_g for name, s in self.duts.items()}
            self.fixture = mounted(self.seed, masses, self.fixture_mass_g)
        # each DUT's own noise streams (sensor, converter), apart from the single-DUT ones
        streams = np.random.SeedSequence([self.seed, 36]).spawn(2 * len(self.duts))
        self._dut_noise = {
            name: (np.random.default_rng(streams[2 * i]), np.random.default_rng(streams[2 * i + 1]))
            for i, name in enumerate(self.duts)
        }
        self._cubics: dict[str, ZohFilter] = {}

    def truth_of(self, channel: str) -> SensorModel:
        """The sensor on the DUT input `channel` (its truth: `.sensitivity(f, rms)`)."""
        return self.duts[channel]

    def configure(self, config: DaqConfig) -> DaqStatus:
        """One network node per DUT input; every DUT channel sampled `skew_s` after the
        reference (simultaneous DUT channels)."""
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
        skew = m.skew_s
        outputs = {name: (name, 0.0) for name in ("acceleration", "displacement", "reference")}
        self._cubics = {}
        for name, sensor in self.duts.items():
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
        skews = {c.name: (skew if is_dut_channel(c.name) else 0.0) for c in config.inputs}
        return DaqStatus(actual_sample_rate_hz=fs, skew_s=skew, skews_s=skews)

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
