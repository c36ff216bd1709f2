"""Amplitude profiles and the stroke check (dsp.profiles); expected values by hand."""

import math

import numpy as np
import pytest

from dsp import iso266
from dsp.multisine import PlanError, make_plan
from dsp.profiles import AmplitudeProfile, Profile, check_stroke, line_displacement_pp_m

FREQS = np.array([0.4, 1.0, 2.0, 10.0, 100.0])


def test_constant_acceleration_velocity_and_displacement_below_the_corner():
    np.testing.assert_allclose(AmplitudeProfile(5.0).amplitudes(FREQS), 5.0)
    velocity = AmplitudeProfile(5.0, Profile.VELOCITY, corner_hz=10.0)
    np.testing.assert_allclose(velocity.amplitudes(FREQS), [0.2, 0.5, 1.0, 5.0, 5.0])
    displacement = AmplitudeProfile(5.0, Profile.DISPLACEMENT, corner_hz=10.0)
    np.testing.assert_allclose(displacement.amplitudes(FREQS), [0.008, 0.05, 0.2, 5.0, 5.0])
    # constant displacement really is: A / w^2 equal below the corner (5 / (20 pi)^2 m)
    d = line_displacement_pp_m(FREQS[:4], displacement.amplitudes(FREQS)[:4])
    np.testing.assert_allclose(d, 2 * 5 / (2 * math.pi * 10) ** 2)


def test_stroke_clip_per_line():
    """150 mm stroke, half of it per line: at 0.4 Hz A <= 0.5 * 0.075 * (0.8 pi)^2."""
    profile = AmplitudeProfile(5.0, stroke_peak_to_peak_m=0.15)
    limit = 0.5 * 0.075 * (2 * math.pi * 0.4) ** 2
    assert limit == pytest.approx(0.236871, rel=1e-5)
    amps = profile.amplitudes(FREQS)
    assert amps[0] == pytest.approx(limit)
    assert amps[3] == 5.0
    np.testing.assert_array_equal(profile.clipped(FREQS), [True, True, False, False, False])
    assert line_displacement_pp_m([0.4], [amps[0]])[0] == pytest.approx(0.075)


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"level_ms2": 0.0}, "level"),
        ({"level_ms2": float("nan")}, "level"),
        ({"level_ms2": 5.0, "kind": Profile.VELOCITY}, "corner"),
        ({"level_ms2": 5.0, "kind": "jerk"}, "profile"),
        ({"level_ms2": 5.0, "stroke_peak_to_peak_m": -1.0}, "stroke"),
        ({"level_ms2": 5.0, "stroke_share": 0.0}, "stroke share"),
    ],
)
def test_bad_profiles_are_refused_by_field(kwargs, field):
    with pytest.raises(PlanError, match=f"^{field}:"):
        AmplitudeProfile(**kwargs)


def test_a_plan_over_the_stroke_is_refused_naming_the_line():
    """5 m/s^2 at 0.4 Hz alone: 2 * 5 / (0.8 pi)^2 = 1.583 m peak-to-peak."""
    low = iso266.nominal_frequencies(0.4, 8)
    plan = make_plan(low, 200.0, 4000, 5.0, 8.0)  # 20 s: 0.05 Hz bins
    with pytest.raises(PlanError, match=r"line 0\.4 Hz: .* beyond the exciter's 8 mm stroke") as e:
        check_stroke(plan, 8e-3)
    assert "alone needs 1583 mm" in str(e.value)
    # with a displacement profile below 8 Hz the same lines fit a 150 mm stroke
    amps = AmplitudeProfile(5.0, Profile.DISPLACEMENT, corner_hz=8.0).amplitudes(
        plan.frequencies_hz
    )
    travel = check_stroke(plan.with_amplitudes(amps), 0.15)
    one_line = 2 * 5 / (2 * math.pi * 8) ** 2  # each line alone: 3.96 mm
    assert one_line < travel < len(low) * one_line
