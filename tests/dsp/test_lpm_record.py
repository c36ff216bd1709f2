"""dsp.lpm_record: the LPM on a run's record as a spectral.Estimate (issue 26 point 3)."""

from __future__ import annotations

import numpy as np
import pytest

from dsp.calibration import AnalysisError
from dsp.crestfactor import synthesize
from dsp.lpm_record import harmonic_distortion, record_estimate
from dsp.multisine import make_plan

FS, N = 1000.0, 1000  # 1 Hz bins
LINES = (10.0, 20.0, 40.0, 80.0, 160.0)


def _plan():
    return make_plan(LINES, FS, N, 1.0, 160.0, phases_rad=[0.1, 0.7, 1.3, 2.1, 2.9])


def _record(plan, periods, h=0.5, noise=1e-5, seed=1, transient=0.0):
    rng = np.random.default_rng(seed)
    drive = synthesize(plan.bins, np.ones(len(LINES)), plan.phases_rad, N)
    u = np.tile(drive, periods)
    t = np.arange(u.size) / FS
    start_up = transient * np.exp(-t / 0.3)  # the DUT's own high-pass settling
    y = h * u + start_up + noise * rng.standard_normal(u.size)
    u = u + noise * rng.standard_normal(u.size)
    return u.reshape(periods, N), y.reshape(periods, N), np.tile(drive, (periods, 1))


def test_one_period_gives_the_ratio_type_a_and_student_dof():
    plan = _plan()
    ref, dut, drive = _record(plan, 1)
    e = record_estimate(ref, dut, plan, drive_blocks=drive).estimate
    assert e.estimator == "lpm" and e.periods == 1
    np.testing.assert_allclose(np.abs(e.response), 0.5, rtol=1e-4)  # transient removed
    # noise 1e-5 per sample: per bin sqrt(2/N) 1e-5 = 4.5e-7 V on 1 V lines, both channels
    expected = np.sqrt((2 / N) * 1e-10 * (1 / 0.25 + 1)) / np.sqrt(2)
    assert np.all(e.relative_type_a < 3 * expected) and np.all(e.relative_type_a > expected / 3)
    assert np.all(np.asarray(e.dof) >= 16)  # q >= 8 complex: 2 q real degrees of freedom
    assert np.all(np.isnan(e.coherence))


def test_the_transient_term_removes_a_start_up_the_plain_ratio_keeps():
    plan = _plan()
    ref, dut, drive = _record(plan, 1, transient=0.05)
    e = record_estimate(ref, dut, plan, drive_blocks=drive).estimate
    error = np.max(np.abs(e.response / 0.5 - 1))
    assert error < 5 * np.max(e.relative_type_a)
    # without the transient term the start-up would bias H by far more than the type A
    naive = np.fft.rfft(dut[0])[plan.bins] / np.fft.rfft(ref[0])[plan.bins]
    assert np.max(np.abs(np.abs(naive) - 0.5)) > 10 * np.max(np.abs(np.abs(e.response) - 0.5))


def test_more_periods_lower_the_type_a():
    plan = _plan()
    one = record_estimate(*_record(plan, 1)[:2], plan).estimate
    four = record_estimate(*_record(plan, 4)[:2], plan).estimate
    ratio = np.median(four.relative_type_a / one.relative_type_a)
    assert 0.3 < ratio < 0.75  # 1/sqrt(4) = 0.5 within the scatter of 18-dof estimates


def test_a_fade_inside_the_record_is_refused():
    plan = _plan()
    ref, dut, drive = _record(plan, 1)
    drive = drive * np.linspace(0, 1, N)  # a fade-in inside the analysed record
    with pytest.raises(AnalysisError, match="not periodic over the record"):
        record_estimate(ref, dut, plan, drive_blocks=drive)


def test_harmonic_distortion_finds_a_3_percent_second_harmonic_and_nothing_else():
    n = 4000
    rng = np.random.default_rng(3)
    t = np.arange(n)
    x = np.sin(2 * np.pi * 100 * t / n) + 0.03 * np.sin(2 * np.pi * 200 * t / n)
    x = x + 1e-4 * rng.standard_normal(n)
    spectrum = np.fft.rfft(x) * 2 / n
    d = harmonic_distortion(spectrum, np.array([100, 130]))
    assert d[0] == pytest.approx(0.03, rel=0.01)
    assert d[1] == 0.0  # 260, 390, 520, 650: noise only, below the threshold
