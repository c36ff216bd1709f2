"""The preflight (app.procedure.preflight): the peaks predicted from the drive about to be played
(issue 25 point 7) and the one check of a plan against the stand's limits."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from app.procedure import check_preflight
from app.procedure.errors import PreflightError
from app.procedure.phase_store import stored_phases
from app.procedure.preflight import check_drive, predict_drive_peaks
from app.stand import config as stand_config
from app.stand.config import Limits
from app.stand.open import open_stand
from dsp.multisine import make_plan, preset_plan

LIMITS = Limits(8e-3, 0.5, 300.0, 5.0)
CONFIG = stand_config.load()


def target(plan):
    return plan.amplitudes_ms2 * np.exp(1j * (plan.phases_rad - np.pi / 2))


def test_the_drive_through_its_own_response_gives_the_plans_peaks():
    plan = preset_plan("piezo", optimiser=stored_phases)
    response = np.linspace(2.0, 40.0, len(plan.lines)) * np.exp(1j * 0.3)  # (m/s^2)/V
    peaks = predict_drive_peaks(plan, target(plan) / response, response, fades=False)
    expected = plan.predicted_peaks()
    assert peaks.displacement_peak_to_peak_m == pytest.approx(expected.displacement_peak_to_peak_m)
    assert peaks.velocity_m_per_s == pytest.approx(expected.velocity_m_per_s)
    assert peaks.acceleration_ms2 == pytest.approx(expected.acceleration_ms2)
    # issue 34: with its fades (the default) the motion is larger, never smaller
    faded = predict_drive_peaks(plan, target(plan) / response, response)
    assert faded.displacement_peak_to_peak_m > expected.displacement_peak_to_peak_m
    assert faded.acceleration_ms2 == pytest.approx(expected.acceleration_ms2)


def test_one_line_by_hand():
    """One 10 Hz line: 1 V through 5 (m/s^2)/V is 5 m/s^2 peak, 5/(2 pi 10) = 79.6 mm/s,
    displacement 5/(2 pi 10)^2 = 1.2665 mm peak, 2.533 mm p-p."""
    plan = make_plan([10.0], 1000.0, 1000, 5.0, 10.0)
    peaks = predict_drive_peaks(plan, np.array([1.0 + 0j]), np.array([5.0 + 0j]), fades=False)
    w = 2 * np.pi * 10.0
    assert peaks.acceleration_ms2 == pytest.approx(5.0, rel=1e-4)
    assert peaks.velocity_m_per_s == pytest.approx(5.0 / w, rel=1e-4)
    assert peaks.displacement_peak_to_peak_m == pytest.approx(2 * 5.0 / w**2, rel=1e-4)


def test_a_drive_past_the_stroke_is_refused_naming_the_predicted_displacement():
    plan = make_plan([10.0], 1000.0, 1000, 5.0, 10.0)
    # 20 m/s^2 at 10 Hz: an orbit of 10.13 mm p-p > 8 mm, and since issue 34 the offset its
    # fade-in leaves (the longest tried, 8 cycles: 0.43 mm) counted: 10.56 mm
    drive = np.array([4.0 + 0j])
    with pytest.raises(PreflightError, match=r"predicted displacement 10\.56 mm p-p"):
        check_drive(plan, drive, np.array([5.0 + 0j]), LIMITS, "step 1")
    assert check_drive(
        plan, drive / 2, np.array([5.0 + 0j]), LIMITS, "step 1"
    ).acceleration_ms2 == (pytest.approx(10.0, rel=1e-4))


def test_preflight_reports_peaks_and_scales_with_the_level():
    stand = open_stand(CONFIG, dut="piezo")
    try:
        plan = preset_plan("piezo", level_ms2=1.0, optimiser=stored_phases)
        ok = check_preflight(plan, stand.config, stand.chain)
        assert ok.ok and ok.summary().startswith("preflight: peaks")
        at_50 = check_preflight(plan, stand.config, stand.chain, level_scale=50.0)
        assert at_50.peaks.acceleration_ms2 == pytest.approx(50 * ok.peaks.acceleration_ms2)
        assert any("exceeds the exciter's 8 mm" in p for p in at_50.problems)
        with pytest.raises(PreflightError, match="displacement"):
            at_50.raise_if_refused()
    finally:
        stand.close()


def test_a_reference_frequency_outside_the_reference_range_is_refused_before_the_run():
    """Issue 32 point 5: no line of such a run could be stated; refused naming the range."""
    from dsp.calibration import ReferenceChain

    chain = ReferenceChain((10.0, 160.0, 5000.0), (1.0, 1.0, 1.0), (0.0, 0.0, 0.0))
    freqs = [10.0, 160.0, 1000.0, 8000.0]
    phases = [0.0] * 4
    inside = make_plan(freqs, 51200, 51200, 1.0, 160.0, phases_rad=phases)
    assert check_preflight(inside, CONFIG, chain).problems == ()
    outside = make_plan(freqs, 51200, 51200, 1.0, 8000.0, phases_rad=phases)
    (problem,) = check_preflight(outside, CONFIG, chain).problems
    assert problem.startswith("reference frequency 8000 Hz (played at 8000 Hz): outside the ")
    assert "calibrated range (10-5000 Hz)" in problem


def test_a_stepped_sine_is_checked_one_line_at_a_time():
    """Issue 32 point 8: a stepped sine plays one line at a time, so its motion is one line's,
    not the sum the multisine plays: 0.5 and 1 Hz at 1.2 m/s^2 in phase sum to 0.57 m/s, over
    the 0.5 m/s velocity limit; each alone (0.382 m/s at 0.5 Hz) is within it."""
    plan = make_plan([0.5, 1.0], 200.0, 400, 1.2, 1.0, phases_rad=[0.0, 0.0])
    config = dataclasses.replace(CONFIG, limits=Limits(1.0, 0.5, 300.0, 5.0))
    summed = check_preflight(plan, config, None)
    assert any(p.startswith("velocity") for p in summed.problems)
    alone = check_preflight(plan, config, None, per_line=True)
    assert alone.problems == ()
    assert alone.peaks.velocity_m_per_s == pytest.approx(1.2 / (2 * np.pi * 0.5))
    assert alone.peaks.displacement_peak_to_peak_m == pytest.approx(2.4 / (2 * np.pi * 0.5) ** 2)
