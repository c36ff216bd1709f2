"""sim.triaxial: the true matrix, the mounting's table motion and the channels' voltages."""

from __future__ import annotations

import math

import numpy as np
import pytest

from dsp.multisine import make_plan
from sim.triaxial import (
    AxisModel,
    Mounting,
    TableTransverse,
    TriaxialSensor,
    channel_phasors,
    example_sensor,
    period_voltages,
)

F = np.array([10.0, 160.0, 2500.0])


def test_the_matrix_has_each_axis_main_response_and_its_tilt_at_its_angle():
    sensor = example_sensor()
    s = sensor.matrix(F)
    assert s.shape == (3, 3, 3)
    x = sensor.x
    np.testing.assert_allclose(np.abs(s[1, 0, 0]), x.sensitivity_mv_per_ms2, rtol=2e-3)
    t_xy, t_xz = s[:, 0, 1] / s[:, 0, 0], s[:, 0, 2] / s[:, 0, 0]
    np.testing.assert_allclose(np.hypot(np.abs(t_xy), np.abs(t_xz))[:2], 0.02, rtol=2e-3)
    np.testing.assert_allclose(np.degrees(np.arctan2(t_xz.real, t_xy.real)), 30.0, rtol=1e-9)
    # the transverse resonance makes the ratio grow and turn towards high frequencies
    assert abs(t_xy[2]) > 1.05 * abs(t_xy[0]) and abs(np.angle(t_xy[2])) > math.radians(1.0)
    # each axis its own phase (delay, high-pass, resonance)
    phases = np.angle([s[2, j, j] for j in range(3)])
    assert len({round(float(p), 4) for p in phases}) == 3
    # y is the next axis of x, z of y, x of z (cyclic): y's 3.5 % at 140 degrees from z to x
    t_yz, t_yx = s[0, 1, 2] / s[0, 1, 1], s[0, 1, 0] / s[0, 1, 1]
    assert math.degrees(math.atan2(t_yx.real, t_yz.real)) == pytest.approx(140.0)


def test_a_mounting_moves_the_table_along_its_axis_and_a_little_across():
    table = TableTransverse(ratio=0.001, rocking_hz=4000.0, rocking_q=8.0)
    m = Mounting(orientation=1, motion_deg=90.0, tilt_rad=0.0)
    a = m.acceleration(F, table)
    np.testing.assert_array_equal(a[:, 1], 1.0)
    np.testing.assert_allclose(a[:, 2], 0.0, atol=1e-18)  # 90 degrees from z: along x
    np.testing.assert_allclose(np.abs(a[0, 0]), 0.001, rtol=1e-4)
    assert np.abs(a[2, 0]) > 1.5 * np.abs(a[0, 0])  # the rocking mode near 4 kHz
    tilted = Mounting(orientation=0, tilt_rad=0.002, tilt_deg=0.0).acceleration(
        F, TableTransverse(ratio=0.0)
    )
    np.testing.assert_allclose(tilted[:, 1], 0.002)
    with pytest.raises(ValueError, match="orientation must be 0, 1 or 2"):
        Mounting.draw(3, np.random.default_rng(0), 0.001)
    drawn = Mounting.draw(2, np.random.default_rng(0), 0.001)
    assert 0.0 <= drawn.tilt_rad <= 0.001


def test_period_voltages_carry_the_matrix_columns_of_the_mounted_axis():
    plan = make_plan([10.0, 160.0, 1000.0], 6000.0, 6000, 5.0, 160.0, phases_rad=[0.1, 1.0, 2.0])
    sensor = TriaxialSensor(
        AxisModel(10.0, transverse=0.03, angle_deg=0.0),
        AxisModel(8.0, transverse=0.0),
        AxisModel(12.0, transverse=0.0),
    )
    volts = period_voltages(sensor, Mounting(orientation=1), plan, TableTransverse(ratio=0.0))
    assert volts.shape == (3, plan.period_samples)
    spectra = np.fft.rfft(volts, axis=1)[:, plan.bins] * 2 / plan.period_samples
    axial = plan.amplitudes_ms2 * np.exp(1j * plan.phases_rad)
    ratio = spectra / (-1j * axial)  # synthesize's sines: sin = the phasor times -i
    s = sensor.matrix(plan.frequencies_hz) * 1e-3  # V per m/s^2
    np.testing.assert_allclose(ratio[1], s[:, 1, 1], rtol=1e-9)  # y along the exciter
    np.testing.assert_allclose(ratio[0], s[:, 0, 1], rtol=1e-9)  # x sees 3 % of it (y: next)
    np.testing.assert_allclose(np.abs(ratio[2]), 0.0, atol=1e-12)
    phasors = channel_phasors(sensor, Mounting(orientation=1), plan.frequencies_hz, axial)
    np.testing.assert_allclose(phasors[1], s[:, 1, 1] * axial, rtol=1e-12)
