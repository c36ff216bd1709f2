"""Physical models of the simulated stand (SPEC.md section 13); parameters in SI units.

Signal chain, all at the DAQ sample rate and exact at the sample instants (sim.lti):

    drive (DAQ AO, V, zero-order hold)
      -> power amplifier: anti-imaging input filter, gain, noise, output clipping
      -> exciter nonlinearity (Hammerstein: compression and 2nd harmonic growing with level)
      -> voltage-driven moving-coil exciter: damped suspension resonance, flat mid band,
         L/R roll-off, axial resonance; transverse rocking; stroke (over-travel) limit
      -> table acceleration a(t) -> reference accelerometer (+ conditioning amplifier)
                                 -> DUT (its own dynamics, transverse sensitivity, noise,
                                    nonlinearity)
      -> ADC per channel: gain error, white noise, mains hum (and, when asked for, hum only
         while driven: DrivenHum), 16-bit quantisation, clipping;
         the DUT channel sampled `skew_s` after the reference channel (multiplexed board).
"""

from __future__ import annotations

import dataclasses
import functools
import math
from dataclasses import dataclass, field

import numpy as np

from sim.lti import Model, Stage, highpass1, highpass2, lowpass1, resonance

G_N = 9.80665  # standard gravity, m/s^2, for noise densities given in g/sqrt(Hz)


def zpk_stages(
    zeros: np.ndarray, poles: np.ndarray, gain: float
) -> tuple[tuple[Stage, ...], float]:
    """Analog zeros/poles/gain as second-order stages (conjugate pairs matched in order of
    frequency) and the overall gain."""
    upper_poles = sorted((p for p in poles if p.imag > 1e-9 * abs(p)), key=abs)
    real_poles = [p.real for p in poles if abs(p.imag) <= 1e-9 * abs(p)]
    upper_zeros = sorted((z for z in zeros if z.imag > 1e-9 * abs(z)), key=abs)
    stages: list[Stage] = []
    for i, p in enumerate(upper_poles):
        den = np.array([1.0, -2.0 * p.real, abs(p) ** 2])
        if i < len(upper_zeros):
            z = upper_zeros[i]
            num = np.array([1.0, -2.0 * z.real, abs(z) ** 2])
        else:
            num = np.array([1.0])
        stages.append((num, den))
    for p in real_poles:
        stages.append((np.array([1.0]), np.array([1.0, -p])))
    return tuple(stages), float(gain)


# scipy.signal.ellipap(order, ripple_db, stop_db): the normalised analog prototype (zeros,
# poles, gain) of the anti-imaging filters the simulated stands use, as scipy 1.17 computes
# it. `elliptic_lowpass` scales it as scipy.signal.ellip(..., analog=True) does, to the same
# floats (tests/sim/test_lti_exact.py compares them with scipy.signal.ellip bit for bit); other
# designs call scipy.signal.ellip.
_ELLIPTIC_PROTOTYPES: dict[
    tuple[int, float, float], tuple[tuple[complex, ...], tuple[complex, ...], float]
] = {
    (10, 0.1, 80.0): (
        (
            complex(0.0, 5.539084211061333),
            complex(0.0, 2.033785641736452),
            complex(0.0, 1.4342331580389418),
            complex(0.0, 1.2386772932204764),
            complex(0.0, 1.172783001758194),
            complex(0.0, -5.539084211061333),
            complex(0.0, -2.033785641736452),
            complex(0.0, -1.4342331580389418),
            complex(0.0, -1.2386772932204764),
            complex(0.0, -1.172783001758194),
        ),
        (
            complex(-0.3475104744787929, -0.23347790258524243),
            complex(-0.25099633595873666, -0.618903261262954),
            complex(-0.1424633818455124, -0.8510695133670702),
            complex(-0.06671804143483319, -0.9656315956148926),
            complex(-0.019026412380692685, -1.0106542110185628),
            complex(-0.3475104744787929, 0.23347790258524243),
            complex(-0.25099633595873666, 0.618903261262954),
            complex(-0.1424633818455124, 0.8510695133670702),
            complex(-0.06671804143483319, 0.9656315956148926),
            complex(-0.019026412380692685, 1.0106542110185628),
        ),
        9.999999999999916e-05,
    ),
}


def elliptic_zpk(
    order: int, edge_hz: float, ripple_db: float, stop_db: float
) -> tuple[np.ndarray, np.ndarray, float]:
    """Zeros, poles (rad/s) and gain of an analog elliptic low-pass: what
    scipy.signal.ellip(order, ripple_db, stop_db, 2 pi edge_hz, analog=True, output="zpk")
    returns, from the tabulated prototype when there is one (scipy.signal not imported: about
    1.5 s of a run's start-up), else from scipy.signal."""
    prototype = _ELLIPTIC_PROTOTYPES.get((order, float(ripple_db), float(stop_db)))
    wn = 2 * np.pi * edge_hz
    if prototype is None:
        import scipy.signal

        z, p, k = scipy.signal.ellip(order, ripple_db, stop_db, wn, analog=True, output="zpk")
        return z, p, float(k)
    zeros, poles, k_proto = prototype
    # scipy.signal.lp2lp_zpk, as iirfilter calls it for an analog low-pass
    wo = float(np.asarray(wn, dtype=np.float64))
    z_proto = np.array(zeros, dtype=complex)
    p_proto = np.array(poles, dtype=complex)
    degree = p_proto.shape[0] - z_proto.shape[0]
    return wo * z_proto, wo * p_proto, k_proto * wo**degree


def elliptic_lowpass(order: int, edge_hz: float, ripple_db: float, stop_db: float) -> Model:
    """Analog elliptic (Cauer) low-pass: passband to `edge_hz` within `ripple_db`, at least
    `stop_db` down in the stopband."""
    z, p, k = elliptic_zpk(order, edge_hz, ripple_db, stop_db)
    stages, gain = zpk_stages(z, p, k)
    return Model(stages, gain)


@dataclass(frozen=True)
class PowerAmplifierModel:
    """Gain (V/V), output limit (V peak), output noise (V rms per sample), and an input
    anti-imaging (reconstruction) filter: elliptic, passband to `anti_imaging_edge` x fs,
    `anti_imaging_stop_db` down from fs - 0.45 fs. With AO and AI on one clock, the zero-order
    hold's images at fs - f would otherwise move the table and alias back onto the lines; on a
    multiplexed board the DUT channel samples them `skew` later than the reference, so the skew
    correction, right at f, is wrong for them (about 1.5 % at 2.5 kHz with a Butterworth)."""

    gain: float = 20.0
    output_limit_v: float = 60.0
    noise_v: float = 50e-6
    anti_imaging_order: int = 10
    anti_imaging_edge: float = 0.45
    anti_imaging_ripple_db: float = 0.1
    anti_imaging_stop_db: float = 80.0

    def anti_imaging(self, sample_rate_hz: float) -> Model:
        if self.anti_imaging_order == 0:
            return Model(())
        return elliptic_lowpass(
            self.anti_imaging_order,
            self.anti_imaging_edge * sample_rate_hz,
            self.anti_imaging_ripple_db,
            self.anti_imaging_stop_db,
        )


@dataclass(frozen=True)
class ExciterModel:
    """Voltage-driven moving-coil exciter: table acceleration per amplifier volt.

    a/V = K s^2/(s^2 + w_s/Q_s s + w_s^2) * 1/(1 + s/w_e) * w_a^2/(s^2 + w_a/Q_a s + w_a^2):
    suspension resonance (voltage drive: rising 40 dB/decade below it), flat mid band of
    `midband_ms2_per_v`, electrical L/R corner, axial resonance. The nonlinearity acts on the
    amplifier voltage v (Hammerstein): v + c2 v^2/V0 - c3 v^3/V0^2 with V0 = 10 V.
    """

    name: str = "small exciter (4809-like)"
    midband_ms2_per_v: float = 100.0
    suspension_hz: float = 150.0
    suspension_q: float = 1.5
    electrical_corner_hz: float = 6000.0
    axial_resonance_hz: float = 16000.0
    axial_q: float = 25.0
    stroke_peak_to_peak_m: float = 8e-3
    quadratic: float = 0.004
    cubic: float = 0.003
    transverse_ratio: float = 0.01
    rocking_hz: float = 1800.0
    rocking_q: float = 8.0
    moving_mass_g: float = 100.0  # armature, table and reference standard
    rated_load_g: float = 10.0  # the DUT mass the figures above hold for
    # poles (Hz) of the slightly leaky double integrator giving the table displacement
    displacement_leak_hz: tuple[float, float] = (0.2, 0.3)

    def loaded(self, dut_mass_g: float) -> ExciterModel:
        """The exciter carrying a DUT of `dut_mass_g` (g) instead of its rated load: a force
        per volt acting on the whole moving mass M, so the mid-band acceleration per volt
        scales as 1/M, the suspension resonance sqrt(k/M) as 1/sqrt(M) and its Q
        (sqrt(k M)/c) as sqrt(M)."""
        if dut_mass_g == self.rated_load_g:
            return self
        if not (math.isfinite(dut_mass_g) and dut_mass_g >= 0):
            raise ValueError(f"DUT mass: must be >= 0 g, got {dut_mass_g:g}")
        ratio = (self.moving_mass_g + self.rated_load_g) / (self.moving_mass_g + dut_mass_g)
        return dataclasses.replace(
            self,
            midband_ms2_per_v=self.midband_ms2_per_v * ratio,
            suspension_hz=self.suspension_hz * math.sqrt(ratio),
            suspension_q=self.suspension_q / math.sqrt(ratio),
            rated_load_g=dut_mass_g,
        )

    def acceleration_model(self) -> Model:
        return Model(
            (
                highpass2(self.suspension_hz, self.suspension_q),
                lowpass1(self.electrical_corner_hz),
                resonance(self.axial_resonance_hz, self.axial_q),
            ),
            self.midband_ms2_per_v,
        )

    def transverse_stage(self) -> Model:
        """Transverse per axial table acceleration (small, with a rocking mode)."""
        return Model((resonance(self.rocking_hz, self.rocking_q),), self.transverse_ratio)

    def displacement_stage(self) -> Model:
        """Table displacement (m) per m/s^2 of table acceleration: a double integrator made
        slightly leaky (poles at `displacement_leak_hz`, 0.2 and 0.3 Hz for the small exciter,
        far below any line) so that it has no defective pole; within 0.1 % of 1/(j w)^2 from
        about 50 times the higher pole up (10 Hz for the small exciter)."""
        a, b = self.displacement_leak_hz
        return Model((lowpass1(a), lowpass1(b)), 1.0 / ((2 * np.pi) ** 2 * a * b))

    def nonlinearity(self, v: np.ndarray) -> np.ndarray:
        """v + c2 v^2/V0 - c3 v^3/V0^2 (V0 = 10 V), in Horner form."""
        out = v * (-self.cubic / 100.0)
        out += self.quadratic / 10.0
        out *= v
        out += 1.0
        out *= v
        return out


#: The simulated stand's exciters by name (SPEC.md s.13; issue 26: ISO 16063-21 from 0.4 Hz).
EXCITER_CATALOGUE: dict[str, ExciterModel] = {
    "small": ExciterModel(),
    "long-stroke": ExciterModel(
        name="long-stroke exciter (APS 129-like), 150 mm stroke, 0.4-200 Hz",
        midband_ms2_per_v=5.0,
        suspension_hz=1.0,
        suspension_q=0.7,
        electrical_corner_hz=250.0,
        axial_resonance_hz=900.0,
        axial_q=10.0,
        stroke_peak_to_peak_m=0.15,
        quadratic=0.002,
        cubic=0.002,
        transverse_ratio=0.005,
        rocking_hz=60.0,
        rocking_q=5.0,
        moving_mass_g=1500.0,
        displacement_leak_hz=(0.004, 0.006),  # within 0.1 % of 1/(j w)^2 from 0.3 Hz
    ),
}


CUBIC_RMS_FACTOR = math.sqrt(15.0)  # sqrt(E x^6)/sigma^3 of a Gaussian x


@dataclass(frozen=True)
class SensorModel:
    """An accelerometer with its conditioning, output in V per m/s^2 of table acceleration.

    `sensitivity_mv_per_ms2` mid band; a first-order high-pass (IEPE/charge discharge time
    constant), a resonance (mounted), an optional second-order low-pass (capacitive sensor
    bandwidth), an optional mount resonance (loose mount), transverse sensitivity (fraction),
    noise density in g/sqrt(Hz), a cubic nonlinearity coefficient per (m/s^2)^2.
    """

    name: str
    description: str
    kind: str
    sensitivity_mv_per_ms2: float
    highpass_hz: float | None = None
    resonance_hz: float | None = None
    resonance_q: float = 30.0
    lowpass_hz: float | None = None
    lowpass_q: float = 0.707
    mount_resonance_hz: float | None = None
    mount_q: float = 10.0
    transverse_sensitivity: float = 0.01
    noise_g_per_rthz: float = 0.0
    cubic_per_ms2_sq: float = 0.0
    dead: bool = False
    mass_g: float = 10.0  # what it adds to the exciter's moving mass

    def model(self) -> Model:
        """Linear output (V) per m/s^2."""
        stages: list[Stage] = []
        if self.highpass_hz:
            stages.append(highpass1(self.highpass_hz))
        if self.resonance_hz:
            stages.append(resonance(self.resonance_hz, self.resonance_q))
        if self.lowpass_hz:
            stages.append(resonance(self.lowpass_hz, self.lowpass_q))
        if self.mount_resonance_hz:
            stages.append(resonance(self.mount_resonance_hz, self.mount_q))
        gain = 0.0 if self.dead else self.sensitivity_mv_per_ms2 * 1e-3
        return Model(tuple(stages), gain)

    def cubic_fraction(self, rms_ms2: float) -> float:
        """The cubic term's rms over the linear term's rms (a ratio) for a Gaussian-like
        excitation (a many-line random-phase multisine) of rms `rms_ms2` m/s^2:
        |c3| sqrt(E a^6)/sqrt(E a^2) = sqrt(15) |c3| rms^2."""
        return CUBIC_RMS_FACTOR * abs(self.cubic_per_ms2_sq) * rms_ms2**2

    def with_cubic_fraction(self, fraction: float, rms_ms2: float) -> SensorModel:
        """This sensor with a compressive cubic of `fraction` (ratio, e.g. 0.006 for 0.6 %) of
        the signal at an excitation of rms `rms_ms2` m/s^2 (see `cubic_fraction`)."""
        if not (math.isfinite(fraction) and fraction >= 0 and rms_ms2 > 0):
            raise ValueError(f"cubic: fraction >= 0 and rms > 0 m/s^2, got {fraction}, {rms_ms2}")
        cubic = -fraction / (CUBIC_RMS_FACTOR * rms_ms2**2)
        return dataclasses.replace(self, cubic_per_ms2_sq=cubic)

    def sensitivity(self, frequency_hz: np.ndarray, rms_ms2: float = 0.0) -> np.ndarray:
        """True complex sensitivity in mV/(m/s^2) at frequencies, at an excitation with total
        rms acceleration `rms_ms2`: the cubic term's Bussgang gain 1 + 3 c3 rms^2."""
        compression = 1.0 + 3.0 * self.cubic_per_ms2_sq * rms_ms2**2
        return 1e3 * self.model().response(frequency_hz) * compression


@dataclass(frozen=True)
class AdcModel:
    """One analog input: white noise (V rms), hum at the mains frequency and harmonics
    (V peak each), 16-bit quantisation of its +-range, clipping at the range; the +-ranges it
    offers (a requested range is coerced up to one of them)."""

    noise_v: float = 20e-6
    hum_v: tuple[float, ...] = (40e-6, 12e-6, 8e-6, 5e-6, 3e-6)
    bits: int = 16
    ranges_v: tuple[float, ...] = (0.1, 0.2, 0.5, 1.0, 2.0, 5.0, 10.0)  # M-series-like, +-V
    # differential nonlinearity: each code transition moved by a fixed amount, uniform within
    # +-dnl_lsb (drawn once, the same converter for every seed: a property of the board)
    dnl_lsb: float = 0.25

    def coerced_range(self, range_v: float) -> float | None:
        """The range the converter uses for a requested +-`range_v` (V): the smallest offered
        one that holds it, as DAQmx coerces; None above the largest."""
        return next((r for r in sorted(self.ranges_v) if range_v <= r * (1 + 1e-9)), None)

    def quantise(self, x: np.ndarray, range_v: float) -> np.ndarray:
        """Round to the ADC step (2 range / 2^bits), the transition between codes c and c + 1
        at c + 1/2 - d[c] (the converter's DNL pattern), and clip to the code range."""
        step = 2.0 * range_v / 2**self.bits
        codes = x / step
        floor = np.floor(codes)
        codes -= floor
        if self.dnl_lsb:
            codes += _transition_offsets(self.bits, self.dnl_lsb)[
                floor.astype(np.int64) & (2**self.bits - 1)
            ]
        codes = floor + (codes >= 0.5)
        np.clip(codes, -(2 ** (self.bits - 1)), 2 ** (self.bits - 1) - 1, out=codes)
        codes *= step
        return codes


@functools.lru_cache(maxsize=4)
def _transition_offsets(bits: int, dnl_lsb: float) -> np.ndarray:
    """The fixed DNL pattern of a simulated converter: per code (mod 2^bits), how far (LSB) its
    upper transition moves down, uniform within +-dnl_lsb."""
    return np.random.default_rng(1451).uniform(-dnl_lsb, dnl_lsb, 2**bits)


REFERENCE = SensorModel(
    name="reference",
    description="back-to-back reference standard (8305-like) with its conditioning amplifier",
    kind="reference",
    sensitivity_mv_per_ms2=1.0,
    highpass_hz=0.1,
    resonance_hz=30000.0,
    resonance_q=40.0,
    transverse_sensitivity=0.0,
    noise_g_per_rthz=2e-7,
)

MEMS_CUBIC_FRACTION = 0.006  # the "mems-cubic" DUT's cubic: 0.6 % of the signal ...
MEMS_CUBIC_RMS_MS2 = math.sqrt(27 * 5.0**2 / 2)  # ... at the capacitive plan's rms, m/s^2

DUT_CATALOGUE: dict[str, SensorModel] = {
    "piezo": SensorModel(
        name="piezo",
        description="IEPE piezoelectric accelerometer (338B35-like), ~10 mV/(m/s^2), "
        "0.5 Hz high-pass, resonance 25 kHz",
        kind="piezoelectric",
        sensitivity_mv_per_ms2=10.2,
        highpass_hz=0.5,
        resonance_hz=25000.0,
        resonance_q=35.0,
        transverse_sensitivity=0.02,
        noise_g_per_rthz=1e-6,
    ),
    "capacitive": SensorModel(
        name="capacitive",
        description="capacitive MEMS accelerometer (ADXL202-based), ~35 mV/(m/s^2), "
        "2nd-order low-pass at 200 Hz, 200 ug/sqrt(Hz), slight nonlinearity",
        kind="capacitive",
        sensitivity_mv_per_ms2=35.0,
        lowpass_hz=200.0,
        lowpass_q=0.707,
        transverse_sensitivity=0.01,
        noise_g_per_rthz=200e-6,
        cubic_per_ms2_sq=-1e-6,
    ),
    # issue 32 point 4: a DUT with a stated nonlinearity, for tests and bench/nonlinear_coverage
    "mems-cubic": SensorModel(
        name="mems-cubic",
        description="capacitive MEMS accelerometer as 'capacitive' with a compressive cubic of "
        f"{100 * MEMS_CUBIC_FRACTION:g} % of the signal at {MEMS_CUBIC_RMS_MS2:g} m/s^2 rms (the "
        "capacitive plan's 27 lines at 5 m/s^2)",
        kind="capacitive",
        sensitivity_mv_per_ms2=35.0,
        lowpass_hz=200.0,
        lowpass_q=0.707,
        transverse_sensitivity=0.01,
        noise_g_per_rthz=200e-6,
        cubic_per_ms2_sq=-MEMS_CUBIC_FRACTION / (CUBIC_RMS_FACTOR * MEMS_CUBIC_RMS_MS2**2),
    ),
    "loose": SensorModel(
        name="loose",
        description="faulty: piezoelectric accelerometer on a loose mount (resonance 1.2 kHz)",
        kind="piezoelectric",
        sensitivity_mv_per_ms2=10.2,
        highpass_hz=0.5,
        resonance_hz=25000.0,
        mount_resonance_hz=1200.0,
        mount_q=6.0,
        transverse_sensitivity=0.05,
        noise_g_per_rthz=1e-6,
    ),
    "dead": SensorModel(
        name="dead",
        description="faulty: dead channel (broken cable): noise only",
        kind="piezoelectric",
        sensitivity_mv_per_ms2=10.2,
        dead=True,
    ),
}

#: The plan preset (dsp.multisine.PRESETS) a catalogue DUT is calibrated with by default:
#: the one place CLI, GUI and `simulate` look it up.
PLAN_PRESET_BY_DUT: dict[str, str] = {"capacitive": "capacitive", "mems-cubic": "capacitive"}
DEFAULT_PLAN_PRESET = "piezo"  # every other catalogue DUT


def plan_preset_for(dut: str) -> str:
    """The default plan preset for the catalogue DUT `dut`."""
    return PLAN_PRESET_BY_DUT.get(dut, DEFAULT_PLAN_PRESET)


_VOLT_UNITS = {"v": 1.0, "mv": 1e-3, "uv": 1e-6}


@dataclass(frozen=True)
class DrivenHum:
    """A hum tone present only while the exciter is driven (a power-amplifier ground loop:
    its return current through the DUT's cable shield): `dut_v` and `reference_v` (V peak) at
    `frequency_hz` on those ADC channels, whenever the drive is not at 0 V. The drive-off
    background cannot see it (issue 32 point 3)."""

    frequency_hz: float
    dut_v: float
    reference_v: float = 0.0

    def __post_init__(self) -> None:
        if not (math.isfinite(self.frequency_hz) and self.frequency_hz > 0):
            raise ValueError(f"hum: frequency must be > 0 Hz, got {self.frequency_hz!r}")
        for name, value in (("DUT", self.dut_v), ("reference", self.reference_v)):
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f"hum: {name} amplitude must be >= 0 V, got {value!r}")

    @classmethod
    def parse(cls, text: str) -> DrivenHum:
        """'1mV@50.3Hz' (DUT channel) or '1mV/0.2mV@50.3Hz' (DUT/reference): V, mV or uV
        peak at Hz; ValueError naming --sim-hum."""

        def volts(part: str) -> float:
            word = part.strip().lower().replace("µ", "u")
            for unit in sorted(_VOLT_UNITS, key=len, reverse=True):
                if word.endswith(unit):
                    return float(word[: -len(unit)]) * _VOLT_UNITS[unit]
            return float(word)

        amplitudes, at, frequency = text.partition("@")
        try:
            if not at:
                raise ValueError("no @")
            dut, _, reference = amplitudes.partition("/")
            hz = frequency.strip().lower().removesuffix("hz")
            return cls(float(hz), volts(dut), volts(reference) if reference else 0.0)
        except ValueError as exc:
            raise ValueError(
                f"--sim-hum {text!r}: expected AMPLITUDE@FREQUENCY, e.g. 1mV@50.3Hz or "
                f"1mV/0.2mV@100Hz (DUT/reference, V peak) ({exc})"
            ) from None


@dataclass(frozen=True)
class StandModel:
    """Everything physical about a simulated stand (nominal values; systematic deviations are
    drawn per seed from the budget by sim.budget)."""

    exciter: ExciterModel = field(default_factory=ExciterModel)
    amplifier: PowerAmplifierModel = field(default_factory=PowerAmplifierModel)
    reference: SensorModel = REFERENCE
    reference_gain: float = 10.0
    adc: AdcModel = field(default_factory=AdcModel)
    skew_s: float = 4e-6
    mains_hz: float = 50.0
    # a period written to the output plays this many periods later than the next one read
    # (a real board's buffer and FIFO latency; 0: in lockstep)
    output_latency_periods: int = 0
    driven_hum: tuple[DrivenHum, ...] = ()  # hum only while driven (none on the shipped stand)
