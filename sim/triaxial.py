"""A simulated triaxial accelerometer (issue 36 point 3): its true 3 x 3 sensitivity matrix
S(f) in mV/(m/s^2), and the three channels' voltages (V) when it is mounted in orientation o
on an exciter (the exciter's axis along the sensor's axis o).

Each axis j has its own dynamics (mid-band sensitivity, a first-order high-pass, a mounted
resonance, a conditioning delay: its own phase) and a sensing direction tilted from its
nominal axis by `transverse` (a fraction: the transverse sensitivity ratio) at `angle_deg` in
the plane normal to j, measured from axis k towards axis l with (j, k, l) cyclic (x: y -> z,
y: z -> x, z: x -> y), so S[j, k] = S[j, j] t cos(angle) and S[j, l] = S[j, j] t sin(angle),
times an optional transverse resonance of the sensor (its rocking mode) that makes the ratio
complex towards high frequencies. Truth for tests: `TriaxialSensor.matrix`.

Mounted, the table does not move along the axis o alone: the exciter's own transverse motion
(a rocking mode: a complex ratio to the axial acceleration, in a direction of the table's
plane fixed by the mounting) and the mounting's misalignment (a small tilt, frequency
independent) add acceleration along the sensor's other two axes. The analysis knows neither;
it states a bound for them (dsp.triaxial's `table_transverse`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from dsp.crestfactor import synthesize
from dsp.multisine import Plan
from sim.lti import Model, Stage, highpass1, resonance

AXIS_NAMES = ("x", "y", "z")


@dataclass(frozen=True)
class AxisModel:
    """One sensing axis: mid-band sensitivity (mV/(m/s^2)), high-pass corner (Hz, None:
    DC-coupled), mounted resonance (Hz) and Q, conditioning delay (s), the transverse
    sensitivity ratio (fraction) and its direction (degrees, from the next axis towards the
    one after), the sensor's transverse (rocking) resonance (Hz, None: none) and Q."""

    sensitivity_mv_per_ms2: float
    highpass_hz: float | None = 0.5
    resonance_hz: float = 25000.0
    resonance_q: float = 30.0
    delay_s: float = 0.0
    transverse: float = 0.02
    angle_deg: float = 0.0
    transverse_resonance_hz: float | None = None
    transverse_q: float = 20.0

    def main(self, frequency_hz: np.ndarray) -> np.ndarray:
        """S[j, j](f) in mV/(m/s^2), complex."""
        f = np.asarray(frequency_hz, dtype=float)
        stages: list[Stage] = [resonance(self.resonance_hz, self.resonance_q)]
        if self.highpass_hz:
            stages.append(highpass1(self.highpass_hz))
        h = Model(tuple(stages), self.sensitivity_mv_per_ms2).response(f)
        return h * np.exp(-2j * np.pi * f * self.delay_s)

    def cross(self, frequency_hz: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """S[j, k](f) and S[j, l](f) (mV/(m/s^2)) of the next axis k and the one after, l."""
        base = self.main(frequency_hz) * self.transverse
        if self.transverse_resonance_hz:
            rocking = Model((resonance(self.transverse_resonance_hz, self.transverse_q),))
            base = base * rocking.response(np.asarray(frequency_hz, dtype=float))
        a = math.radians(self.angle_deg)
        return base * math.cos(a), base * math.sin(a)


@dataclass(frozen=True)
class TriaxialSensor:
    """Three axes x, y, z (AxisModel each)."""

    x: AxisModel
    y: AxisModel
    z: AxisModel
    name: str = "simulated triaxial IEPE sensor"

    @property
    def axes(self) -> tuple[AxisModel, AxisModel, AxisModel]:
        return (self.x, self.y, self.z)

    def matrix(self, frequency_hz: np.ndarray) -> np.ndarray:
        """The true S(f): shape (F, 3, 3) complex, mV/(m/s^2); S[:, j, o] is channel j's
        output per m/s^2 along axis o."""
        f = np.atleast_1d(np.asarray(frequency_hz, dtype=float))
        out = np.zeros((f.size, 3, 3), dtype=complex)
        for j, axis in enumerate(self.axes):
            out[:, j, j] = axis.main(f)
            s_k, s_l = axis.cross(f)
            out[:, j, (j + 1) % 3] = s_k
            out[:, j, (j + 2) % 3] = s_l
        return out


MASS_G = 15.0  # the example sensor's mass, g (on the exciter: each channel counts a third)


def example_sensor() -> TriaxialSensor:
    """A triaxial sensor like a small IEPE cube: about 10 mV/(m/s^2), resonances 22-30 kHz,
    transverse 1-4 % at various angles, each axis with its own phase."""
    return TriaxialSensor(
        x=AxisModel(10.2, 0.5, 28000.0, 30.0, 2e-6, 0.02, 30.0, 9000.0, 15.0),
        y=AxisModel(9.7, 0.7, 25000.0, 25.0, 4e-6, 0.035, 140.0, 8000.0, 12.0),
        z=AxisModel(10.6, 0.4, 22000.0, 35.0, 1e-6, 0.012, -70.0, 11000.0, 20.0),
    )


@dataclass(frozen=True)
class TableTransverse:
    """The exciter's own transverse motion per axial acceleration: `ratio` (fraction) at low
    frequency, rising through a rocking mode at `rocking_hz` with `rocking_q`."""

    ratio: float = 0.0005
    rocking_hz: float = 4000.0
    rocking_q: float = 8.0

    def ratio_at(self, frequency_hz: np.ndarray) -> np.ndarray:
        """Complex transverse/axial acceleration ratio at frequencies (Hz)."""
        f = np.asarray(frequency_hz, dtype=float)
        return self.ratio * Model((resonance(self.rocking_hz, self.rocking_q),)).response(f)


@dataclass(frozen=True)
class Mounting:
    """How the sensor sits in one orientation: `orientation` (0, 1, 2 for x, y, z: the
    sensor's axis along the exciter's), the direction of the table's transverse motion in
    the sensor's transverse plane (degrees from the next axis towards the one after), and
    the tilt (rad) with its direction (degrees, likewise)."""

    orientation: int
    motion_deg: float = 0.0
    tilt_rad: float = 0.0
    tilt_deg: float = 0.0

    @classmethod
    def draw(cls, orientation: int, rng: np.random.Generator, tilt_max_rad: float) -> Mounting:
        """A mounting with a random motion direction and a tilt uniform in a disc of radius
        `tilt_max_rad`."""
        if orientation not in (0, 1, 2):
            raise ValueError(f"mounting: orientation must be 0, 1 or 2, got {orientation!r}")
        return cls(
            orientation,
            float(rng.uniform(0.0, 360.0)),
            float(tilt_max_rad * math.sqrt(rng.uniform())),
            float(rng.uniform(0.0, 360.0)),
        )

    def acceleration(self, frequency_hz: np.ndarray, table: TableTransverse) -> np.ndarray:
        """Table acceleration along the sensor's x, y, z per axial m/s^2: (F, 3) complex."""
        f = np.atleast_1d(np.asarray(frequency_hz, dtype=float))
        o = self.orientation
        k, k2 = (o + 1) % 3, (o + 2) % 3
        out = np.zeros((f.size, 3), dtype=complex)
        out[:, o] = 1.0
        eps = table.ratio_at(f)
        m, t = math.radians(self.motion_deg), math.radians(self.tilt_deg)
        out[:, k] = eps * math.cos(m) + self.tilt_rad * math.cos(t)
        out[:, k2] = eps * math.sin(m) + self.tilt_rad * math.sin(t)
        return out


def channel_phasors(
    sensor: TriaxialSensor,
    mounting: Mounting,
    frequency_hz: np.ndarray,
    axial_ms2: np.ndarray,
    table: TableTransverse | None = None,
) -> np.ndarray:
    """The three channels' voltage phasors (V peak, complex, shape (3, F)) for the complex
    axial acceleration `axial_ms2` (m/s^2 peak per frequency)."""
    f = np.atleast_1d(np.asarray(frequency_hz, dtype=float))
    acc = mounting.acceleration(f, table or TableTransverse()) * np.asarray(axial_ms2)[:, None]
    volts = np.einsum("fjo,fo->jf", sensor.matrix(f), acc) * 1e-3
    return np.asarray(volts)


def period_voltages(
    sensor: TriaxialSensor,
    mounting: Mounting,
    plan: Plan,
    table: TableTransverse | None = None,
) -> np.ndarray:
    """One period of the three channels (V, shape (3, plan.period_samples)) for the plan's
    axial multisine (its lines' amplitudes in m/s^2 peak and phases)."""
    axial = plan.amplitudes_ms2 * np.exp(1j * plan.phases_rad)
    phasors = channel_phasors(sensor, mounting, plan.frequencies_hz, axial, table)
    return np.stack(
        [synthesize(plan.bins, np.abs(p), np.angle(p), plan.period_samples) for p in phasors]
    )
