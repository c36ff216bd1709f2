"""The simulated stand: the `hardware.interfaces.Daq` protocol over the physical models.

Deterministic for a seed; block size does not change its output. It draws its systematic
deviations (reference certificate error, gains, mounting) per seed from its own budget
(sim/stand.toml), so the analysis, which sees only the certificate and nominal values, is
tested on its whole uncertainty statement. Faults are injected at chosen simulated times and
surface as the interface's exceptions; power amplifier faults (over-current, over-temperature,
an open over-travel interlock, a lost VISA session) go through the power amplifier's pyvisa-sim
instrument, where the procedure polls them as it would on a real stand, never through the DAQ.
It records its own output (and the peak of every period written to it), so tests can prove
the drive ended at 0 V and never exceeded a limit.
"""

from __future__ import annotations

import math
import time
from collections import deque
from dataclasses import dataclass, field
from typing import Any, NamedTuple

import numpy as np
import pyvisa
import pyvisa.constants
import pyvisa.errors

from dsp import iso266
from dsp.calibration import ReferenceChain
from hardware.errors import (
    AmplifierFaultError,
    DaqTimeoutError,
    DeviceLostError,
    HardwareError,
    OverloadError,
)
from hardware.interfaces import DaqConfig, DaqStatus, checked_output_period
from hardware.visa_amplifiers import BK2525Amplifier, ScpiPowerAmplifier
from sim.budget import Deviations, SimBudget, draw_deviations
from sim.faults import FAULT_KINDS, POWER_AMPLIFIER_FAULT_KINDS, Fault
from sim.lti import MultiZoh, Network, ZohFilter
from sim.models import DUT_CATALOGUE, G_N, SensorModel, StandModel
from sim.visa import (
    SIM_MEASURING_AMPLIFIER,
    SIM_MEASURING_AMPLIFIER_CHANNELS,
    SIM_POWER_AMPLIFIER,
    FailingResource,
    simulated_resource_manager,
)

# Fault, SimBudget and the fault kinds are imported from here too (their homes: sim.faults,
# sim.budget)
__all__ = [
    "FAULT_KINDS",
    "POWER_AMPLIFIER_FAULT_KINDS",
    "Fault",
    "OutputPeriod",
    "OutputRecord",
    "SimBudget",
    "SimulatedStand",
]

_FAULT_ANSWERS = {"amplifier-fault": '2,"Over-temperature"', "over-current": '3,"Over-current"'}


EDGE_S = 0.1  # the output's local level is taken over this long at each end of a period


class OutputPeriod(NamedTuple):
    """One period the simulated DAQ output played (time in s, voltages in V); the RMS over its
    first and last `EDGE_S` shows a step in level at a period boundary."""

    start_s: float
    peak_v: float
    last_v: float
    first_v: float
    head_rms_v: float
    tail_rms_v: float


@dataclass
class OutputRecord:
    """What the simulated DAQ output did, period by period."""

    periods: list[OutputPeriod] = field(default_factory=list)
    written_peaks_v: list[float] = field(default_factory=list)  # each period given, as given
    final_v: float = 0.0
    stopped: bool = False


class SimulatedStand:
    """A DAQ plus exciter, reference and DUT behind the `Daq` protocol."""

    def __init__(
        self,
        dut: str | SensorModel = "piezo",
        *,
        model: StandModel | None = None,
        sim_budget: SimBudget | None = None,
        seed: int = 0,
        paced: bool = False,
        faults: tuple[Fault, ...] = (),
        systematic: bool = True,
    ):
        self.dut = dut = catalogue_sensor(dut)
        self.model = model or StandModel()
        self.sim_budget = sim_budget or SimBudget.load()
        self.seed = seed
        self.paced = paced
        self.faults = tuple(sorted(faults, key=lambda f: f.at_s))
        seeds = np.random.SeedSequence(seed).spawn(8)
        self.deviations = (
            draw_deviations(self.sim_budget, np.random.default_rng(seeds[0]))
            if systematic
            else Deviations()
        )
        self._noise = {
            name: np.random.default_rng(s)
            for name, s in zip(
                ("amp", "ref_sensor", "dut_sensor", "adc_ref", "adc_dut"), seeds[1:6], strict=True
            )
        }
        self._hum_phases = np.random.default_rng(seeds[6]).uniform(0, 2 * np.pi, (2, 8))
        self._hum_table: tuple[np.ndarray, float] | None = None  # (2, k spans + n), fs
        self.output = OutputRecord()
        self._config: DaqConfig | None = None
        self._ranges: dict[str, float] = {}  # per input channel, the range quantised at
        self._buffer: np.ndarray | None = None  # the period playing (regenerated)
        # written, not yet played, in order: (the read from which it may play, period)
        self._pending: deque[tuple[int, np.ndarray]] = deque()
        self._reads = 0
        self._running = False
        self._lost = False
        self._amp_tripped = False
        self._power: Any = None  # the power amplifier's raw pyvisa-sim resource, once opened
        self._power_lost = False  # its VISA session is gone (amplifier-lost)
        self._power_state = False  # its output, as last read
        self._sample_index = 0
        self._wall_start = 0.0
        from sim.teds import TedsMemory, catalogue_teds

        self.dut_teds = TedsMemory(catalogue_teds(dut, serial_number=10_000 + seed % 10_000))

    # --- the DUT's TEDS (IEEE 1451.4) -----------------------------------------------------

    def read_teds(self) -> tuple[int, ...]:
        """The bits of the DUT channel's TEDS."""
        return self.dut_teds.read()

    def write_teds(self, bits: tuple[int, ...]) -> None:
        """Write the DUT channel's TEDS (refused unless it decodes)."""
        self.dut_teds.write(bits)

    # --- what the analysis is told (nominal values and the certificate) ---------------------

    def reference_chain(self, dut_gain: float = 1.0) -> ReferenceChain:
        """The reference certificate (with its drawn error) and nominal gains and skew."""
        freqs = np.array(iso266.nominal_frequencies(0.4, 20000.0))  # ISO 16063-21 from 0.4 Hz
        true = self.model.reference.sensitivity(freqs)
        certificate = np.abs(true) * self.deviations.certificate_factor(freqs)
        phase = np.degrees(np.angle(true)) + self.deviations.reference_phase_deg
        return ReferenceChain(
            tuple(freqs.tolist()),
            tuple(certificate.tolist()),
            tuple(phase.tolist()),
            reference_gain=self.model.reference_gain,
            dut_gain=dut_gain,
            skew_s=self.model.skew_s,
        )

    def truth(self, frequency_hz: np.ndarray, rms_ms2: float = 0.0) -> np.ndarray:
        """The DUT's true complex sensitivity in mV/(m/s^2) (at a total rms excitation)."""
        return self.dut.sensitivity(frequency_hz, rms_ms2)

    def table_response(self, frequency_hz: np.ndarray) -> np.ndarray:
        """Nominal table acceleration (m/s^2) per DAQ output volt for a sampled line (ZOH,
        anti-imaging filter, amplifier gain, exciter); for open-loop pre-equalisation."""
        if self._config is None:
            raise HardwareError("simulated DAQ: configure() first")
        return (
            self._chain.discrete_response("acceleration", frequency_hz, self._config.sample_rate_hz)
            * self.model.amplifier.gain
        )

    def measuring_amplifier(self) -> BK2525Amplifier:
        """The stand's measuring amplifier: the real VISA driver over pyvisa-sim, whose
        resource stops answering (a VISA timeout) once a `visa-timeout` fault's time passes."""
        manager = simulated_resource_manager(fresh=True)
        resource = manager.open_resource(
            SIM_MEASURING_AMPLIFIER, read_termination="\n", write_termination="\n"
        )
        at = next((f.at_s for f in self.faults if f.kind == "visa-timeout"), None)
        return BK2525Amplifier(
            FailingResource(resource, lambda: at is not None and self.sim_time_s >= at),
            channels=SIM_MEASURING_AMPLIFIER_CHANNELS,
        )

    def power_amplifier(self) -> ScpiPowerAmplifier:
        """The stand's power amplifier: the real SCPI driver over pyvisa-sim. From now on the
        exciter moves only while its output is on; its faults (`over-current`,
        `amplifier-fault`, `interlock`, and over-travel) are set in the instrument, where a
        poll finds them, and `amplifier-lost` makes its session fail (connection lost)."""
        manager = simulated_resource_manager(fresh=True)
        self._power = manager.open_resource(
            SIM_POWER_AMPLIFIER, read_termination="\n", write_termination="\n"
        )
        lost = pyvisa.constants.StatusCode.error_connection_lost
        return ScpiPowerAmplifier(FailingResource(self._power, lambda: self._power_lost, lost))

    @property
    def power_output_on(self) -> bool | None:
        """Whether the power amplifier's output is on (None without one), as the instrument
        itself knows it (also after its session was lost)."""
        if self._power is None:
            return None
        try:
            self._power_state = self._power.query("OUTP?").strip() == "ON"
        except (pyvisa.errors.Error, AttributeError):  # closed with the stand: as last seen
            pass
        return self._power_state

    # --- the Daq protocol -------------------------------------------------------------------

    def input_ranges_v(self) -> tuple[float, ...]:
        """The +-ranges (V) the simulated converter offers on every input."""
        return tuple(sorted(self.model.adc.ranges_v))

    @property
    def input_ranges_used_v(self) -> dict[str, float]:
        """Per configured input channel, the +-range (V) the converter quantises at."""
        return dict(self._ranges)

    def configure(self, config: DaqConfig) -> DaqStatus:
        """Build the exact sampled models for this sample rate and channel set; each input's
        range coerced up to an offered one (HardwareError above the largest)."""
        self._set_ranges(config)
        fs = config.sample_rate_hz
        m, d = self.model, self.deviations
        dut_model = self.dut.model()
        exciter = m.exciter.loaded(self.dut.mass_g)
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
            .combine(
                "dut_input",
                {
                    "acceleration": d.dut_motion,
                    "transverse": self.dut.transverse_sensitivity * d.transverse_cos,
                },
            )
            .add("dut", dut_model, "dut_input")
        )
        skew = m.skew_s
        outputs = {
            "acceleration": ("acceleration", 0.0),
            "displacement": ("displacement", 0.0),
            "reference": ("reference", 0.0),
            "dut": ("dut", skew),
        }
        if self.dut.cubic_per_ms2_sq:
            # the cubic of the table motion sampled mid-hold: held over the next sample
            # interval, its ZOH is centred on the instant it was taken (no half-sample lag
            # against the linear path, which is exact), so the DUT's distortion products reach
            # the lines with the DUT's own phase (issue 32 point 4)
            outputs["cubic_input"] = ("acceleration", 0.5 / fs)
        self._chain = MultiZoh(network, outputs, fs)
        self._cubic = ZohFilter(dut_model, fs, skew) if self.dut.cubic_per_ms2_sq else None
        return DaqStatus(actual_sample_rate_hz=fs, skew_s=skew)

    def _set_ranges(self, config: DaqConfig) -> None:
        """Each input's range coerced up to an offered one (HardwareError above the largest);
        `config` from now on."""
        ranges: dict[str, float] = {}
        for channel in config.inputs:
            used = self.model.adc.coerced_range(channel.range_v)
            if used is None:
                raise HardwareError(
                    f"simulated DAQ: {channel.name} channel range +-{channel.range_v:g} V is "
                    f"above the largest it offers (+-{max(self.model.adc.ranges_v):g} V)"
                )
            ranges[channel.name] = used
        self._ranges = ranges
        self._config = config

    def start(self, period_v: np.ndarray) -> None:
        self._require_config()
        if self._lost:
            raise DeviceLostError("simulated DAQ: device lost")
        self._buffer = self._checked(period_v)
        self.output.written_peaks_v.append(float(np.max(np.abs(self._buffer))))
        self._pending.clear()
        self._running = True
        self.output.stopped = False
        # paced: simulated time goes on from where it was (a restart between segments)
        self._wall_start = time.monotonic() - self.sim_time_s

    def write_period(self, period_v: np.ndarray) -> None:
        """Queue one period: it plays after the periods written before it, from a period
        boundary, and repeats until another is written (as on a board with a regenerated
        one-period buffer, every period written plays)."""
        if self._lost:
            raise DeviceLostError("simulated DAQ: device lost")
        period = self._checked(period_v)
        self.output.written_peaks_v.append(float(np.max(np.abs(period))))
        self._pending.append((self._reads + self.model.output_latency_periods, period))

    def read_period(self, timeout_s: float = 10.0) -> np.ndarray:
        """Simulate the next period; (channels, N) volts in the configured input order."""
        config = self._require_config()
        if self._lost:
            raise DeviceLostError("simulated DAQ: device lost")
        if not self._running or self._buffer is None:
            raise HardwareError("simulated DAQ: read before start()")
        n = config.period_samples
        t0 = self._sample_index / config.sample_rate_hz
        period_s = n / config.sample_rate_hz
        fault = next((f for f in self.faults if t0 <= f.at_s < t0 + period_s), None)
        if fault is not None:
            self._inject(fault)
        if self.paced:
            wait = self._wall_start + t0 + period_s - time.monotonic()
            if wait > timeout_s:
                raise DaqTimeoutError(f"simulated DAQ: no period within {timeout_s:g} s")
            if wait > 0:
                time.sleep(wait)
        if self._pending and self._pending[0][0] <= self._reads:
            self._buffer = self._pending.popleft()[1]
        self._reads += 1
        drive = self._buffer
        blocks = self._simulate(drive)
        self._played(drive)
        return np.vstack([blocks[c.name] for c in config.inputs])

    def _played(self, drive: np.ndarray) -> None:
        """Record one period of output and advance the clock."""
        config = self._require_config()
        t0 = self._sample_index / config.sample_rate_hz
        self._sample_index += config.period_samples
        edge = max(1, min(drive.size, round(EDGE_S * config.sample_rate_hz)))
        self.output.periods.append(
            OutputPeriod(
                t0,
                float(np.max(np.abs(drive))),
                float(drive[-1]),
                float(drive[0]),
                float(np.sqrt(np.mean(drive[:edge] ** 2))),
                float(np.sqrt(np.mean(drive[-edge:] ** 2))),
            )
        )
        self.output.final_v = float(drive[-1])

    def stop(self) -> None:
        """Play what is still queued, then 0 V, and stop (as the NI driver's stop does). Safe at
        any time, twice, after an error or a lost device (whose output has reset: nothing more
        plays)."""
        if self._config is not None and self._buffer is not None and not self._lost:
            while self._running and self._pending:
                self._buffer = self._pending.popleft()[1]
                self._played(self._buffer)
            self._buffer = np.zeros_like(self._buffer)
        self._pending.clear()
        self._running = False
        self.output.final_v = 0.0
        self.output.stopped = True

    def close(self) -> None:
        self.stop()

    @property
    def output_v(self) -> float | None:
        """The DAQ output voltage now (0 V when stopped, lost or never started)."""
        return self.output.final_v if self._running else 0.0

    @property
    def sim_time_s(self) -> float:
        if self._config is None:
            return 0.0
        return self._sample_index / self._config.sample_rate_hz

    # --- internals --------------------------------------------------------------------------

    def _require_config(self) -> DaqConfig:
        if self._config is None:
            raise HardwareError("simulated DAQ: configure() first")
        return self._config

    def _checked(self, period_v: np.ndarray) -> np.ndarray:
        return checked_output_period(period_v, self._require_config(), "simulated DAQ")

    def _inject(self, fault: Fault) -> None:
        at = f"at {fault.at_s:g} s"
        if fault.kind == "daq-timeout":
            raise DaqTimeoutError(f"simulated DAQ: read timed out {at}")
        if fault.kind == "device-lost":
            self._lost = True
            self._running = False
            self.output.final_v = 0.0  # a lost device resets its output
            raise DeviceLostError(f"simulated DAQ: device lost {at}")
        if fault.kind in POWER_AMPLIFIER_FAULT_KINDS and self._power is not None:
            if fault.kind == "amplifier-lost":
                self._power_lost = True  # the instrument plays on; its session is gone
                return
            self._amp_tripped = True  # it protects itself: no more output
            if fault.kind == "interlock":
                self._power.write("SIM:INTERLOCK 0")
            else:
                self._power.write(f"SIM:FAULT {_FAULT_ANSWERS[fault.kind]}")
            return
        if fault.kind in POWER_AMPLIFIER_FAULT_KINDS:
            self._amp_tripped = True
            raise AmplifierFaultError(f"simulated power amplifier: fault ({fault.kind}) {at}")
        if fault.kind == "overload":
            raise OverloadError(f"simulated measuring amplifier: overload {at}", channel="dut")
        # visa-timeout surfaces through the simulated measuring amplifier's queries

    def _simulate(self, drive: np.ndarray) -> dict[str, np.ndarray]:
        config = self._require_config()
        m, d = self.model, self.deviations
        n = drive.size
        amp = m.amplifier
        v = self._noise["amp"].standard_normal(n)
        v *= amp.noise_v
        v += drive * amp.gain
        np.clip(v, -amp.output_limit_v, amp.output_limit_v, out=v)
        v_off = self._amp_tripped or self.power_output_on is False
        if v_off:
            v = np.zeros(n)
        u = m.exciter.nonlinearity(v)
        chain = self._chain.process(u)
        displacement = chain["displacement"]
        limit = m.exciter.stroke_peak_to_peak_m / 2
        peak = max(float(displacement.max(initial=0.0)), -float(displacement.min(initial=0.0)))
        if peak > limit and not self._amp_tripped:
            self._amp_tripped = True
            if self._power is not None:  # the over-travel switch opens the interlock
                self._power.write("SIM:INTERLOCK 0")
                return self._simulate(drive)
            raise AmplifierFaultError(
                f"simulated power amplifier: exciter over-travel interlock (displacement "
                f"{1e3 * peak:.2f} mm > {1e3 * limit:g} mm) at "
                f"{self.sim_time_s:g} s; lower the level at low frequencies"
            )
        fs = config.sample_rate_hz
        sensor_noise = math.sqrt(fs / 2) * G_N
        reference = chain["reference"]
        reference *= m.reference_gain * d.reference_gain
        noise = self._noise["ref_sensor"].standard_normal(n)
        noise *= (
            m.reference.noise_g_per_rthz
            * sensor_noise
            * m.reference.sensitivity_mv_per_ms2
            * 1e-3
            * m.reference_gain
        )
        reference += noise
        return self._outputs(chain, reference, drive, v_off)

    def _outputs(
        self, chain: dict[str, np.ndarray], reference: np.ndarray, drive: np.ndarray, v_off: bool
    ) -> dict[str, np.ndarray]:
        """`_simulate`'s end: the DUT's output, hum and converter on both channels (V), each
        quantised at its input's range (the reference's sensor output given)."""
        m, d = self.model, self.deviations
        n = drive.size
        fs = self._require_config().sample_rate_hz
        sensor_noise = math.sqrt(fs / 2) * G_N
        dut = chain["dut"]
        if self._cubic is not None:
            dut += self._cubic.process(self.dut.cubic_per_ms2_sq * chain["cubic_input"] ** 3)
        noise = self._noise["dut_sensor"].standard_normal(n)
        noise *= self.dut.noise_g_per_rthz * sensor_noise * self.dut.sensitivity_mv_per_ms2 * 1e-3
        dut += noise
        hum_reference, hum_dut = self._hum(n, fs)
        if m.driven_hum and not v_off and np.any(drive != 0.0):
            driven_reference, driven_dut = self._driven_hum(n, fs)
            hum_reference = hum_reference + driven_reference
            hum_dut = hum_dut + driven_dut
        adc = m.adc
        reference *= d.daq_gain_reference
        reference += hum_reference
        noise = self._noise["adc_ref"].standard_normal(n)
        noise *= adc.noise_v
        reference += noise
        dut *= d.daq_gain_dut
        dut += hum_dut
        noise = self._noise["adc_dut"].standard_normal(n)
        noise *= adc.noise_v
        dut += noise
        out = {"reference": reference, "dut": dut, "drive": drive.copy()}
        for name in ("reference", "dut", "drive"):
            if name in self._ranges:
                out[name] = m.adc.quantise(out[name], self._ranges[name])
        return out

    def _hum(self, n: int, fs: float) -> tuple[np.ndarray, np.ndarray]:
        """Mains hum (V) on the reference and DUT channels for the next n samples; the DUT
        channel is sampled `skew_s` later. When a whole number of mains cycles spans a whole
        number of samples (50 Hz at 6, 12 or 51.2 kS/s: one cycle), it is cut from a table of
        one such span, computed once; else computed for the block."""
        start = self._sample_index
        span = _hum_span(fs, self.model.mains_hz)
        if span is None:
            return self._hum_block(start, n, fs)
        if (
            self._hum_table is None
            or self._hum_table[1] != fs
            or self._hum_table[0].shape[1] < span + n
        ):
            repeats = -(-(span + n) // span)
            one = np.vstack(self._hum_block(0, span, fs))
            self._hum_table = (np.tile(one, repeats), fs)
        table = self._hum_table[0]
        offset = start % span
        return table[0, offset : offset + n], table[1, offset : offset + n]

    def _driven_hum(self, n: int, fs: float) -> tuple[np.ndarray, np.ndarray]:
        """The model's hum while driven (V) on the reference and DUT channels for the next n
        samples, continuous in phase with the sample index (the DUT channel `skew_s` later)."""
        m = self.model
        time_s = (self._sample_index + np.arange(n)) / fs
        reference, dut = np.zeros(n), np.zeros(n)
        for k, tone in enumerate(m.driven_hum):
            phase = self._hum_phases[0, k % self._hum_phases.shape[1]]
            w = 2 * np.pi * tone.frequency_hz
            if tone.reference_v:
                reference += tone.reference_v * np.sin(w * time_s + phase)
            if tone.dut_v:
                dut += tone.dut_v * np.sin(w * (time_s - m.skew_s) + phase)
        return reference, dut

    def _hum_block(self, start: int, n: int, fs: float) -> tuple[np.ndarray, np.ndarray]:
        """The hum for samples start .. start + n - 1: one complex exponential, harmonics by
        products."""
        m = self.model
        time_s = (start + np.arange(n)) / fs
        base = np.exp(2j * np.pi * m.mains_hz * time_s)
        rotor = np.ones(n, complex)
        reference, dut = np.zeros(n), np.zeros(n)
        for h, amplitude in enumerate(m.adc.hum_v, start=1):
            rotor *= base
            skew = np.exp(2j * np.pi * h * m.mains_hz * m.skew_s)
            reference += amplitude * (rotor * np.exp(1j * self._hum_phases[0, h])).imag
            dut += amplitude * (rotor * (skew * np.exp(1j * self._hum_phases[1, h]))).imag
        return reference, dut


def _hum_span(fs: float, mains_hz: float, max_cycles: int = 50) -> int | None:
    """The fewest samples holding a whole number of mains cycles (at most `max_cycles`), or
    None when there is no such span."""
    if mains_hz <= 0:
        return None
    per_cycle = fs / mains_hz
    for cycles in range(1, max_cycles + 1):
        samples = per_cycle * cycles
        if abs(samples - round(samples)) < 1e-9 * samples and round(samples) >= 1:
            return round(samples)
    return None


def catalogue_sensor(dut: str | SensorModel) -> SensorModel:
    """A catalogue DUT by name, or the sensor given (ValueError naming the catalogue)."""
    if not isinstance(dut, str):
        return dut
    try:
        return DUT_CATALOGUE[dut]
    except KeyError:
        raise ValueError(
            f"dut: unknown {dut!r}; the catalogue has {', '.join(DUT_CATALOGUE)}"
        ) from None
