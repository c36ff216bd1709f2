"""Fade lengths and the table motion they leave (issue 34 point 2: dsp.fades)."""

import numpy as np
import pytest

from dsp.fades import (
    FADE_IN_CYCLES,
    FADE_OUT_CYCLES,
    fade_in_samples,
    fade_motion,
    fade_out_samples,
)


def _offset_bound(n_cycles: float, w: float) -> float:
    """|velocity left| of a unit line after a raised cosine of n cycles (free mass): the
    half-sine spectrum of the envelope's slope, (1/w) |1 + e^{j 2 pi n}| / (2 |1 - 4 n^2|)."""
    return abs(1 + np.exp(2j * np.pi * n_cycles)) / (2 * abs(1 - 4 * n_cycles**2)) / w


def test_the_fades_are_one_cycle_in_and_one_and_a_half_out_of_the_lowest_line():
    assert (FADE_IN_CYCLES, FADE_OUT_CYCLES) == (1.0, 1.5)
    assert fade_in_samples(10.0, 6000.0, 12000, None) == 600  # 0.1 s before the record
    assert fade_out_samples(10.0, 6000.0) == 900  # 0.15 s (was 0.4 s: four cycles)
    assert fade_out_samples(0.40632054176072235, 200.0) == 739  # 0.4-8 Hz: 3.69 s (was 9.8 s)


@pytest.mark.parametrize("cycles", [1.0, 1.5, 2.0, 4.0])
def test_a_lines_velocity_offset_is_the_envelopes_spectrum_at_the_line(cycles):
    """Worst phase of one 10 Hz line: the fade-in's offset from the steady orbit and the
    fade-out's residual velocity equal the closed form (zero at 1.5 cycles, 1/3 at one)."""
    w = 2 * np.pi * 10.0
    length = cycles / 10.0
    worst_in = worst_out = 0.0
    for theta in np.linspace(0, np.pi, 181):
        m = fade_motion(np.array([10.0]), np.array([np.exp(1j * theta)]), length, length)
        worst_in = max(worst_in, abs(m.offset_velocity_m_per_s))
        worst_out = max(worst_out, abs(m.residual_velocity_m_per_s))
    bound = _offset_bound(cycles, w)
    assert worst_in == pytest.approx(bound, rel=1e-3, abs=1e-12)
    assert worst_out == pytest.approx(bound, rel=1e-3, abs=1e-12)
    if cycles == 1.0:
        assert worst_in == pytest.approx(1 / (3 * w), rel=1e-3)


def test_the_seed_plans_fade_out_leaves_little_velocity_and_a_shorter_one_would_not():
    from app.procedure.phase_store import stored_phases
    from dsp.multisine import preset_plan

    plan = preset_plan("piezo", optimiser=stored_phases)
    a = plan.amplitudes_ms2 * np.exp(1j * (plan.phases_rad - np.pi / 2))
    steady_v = plan.predicted_peaks().velocity_m_per_s  # 0.27 m/s
    now = fade_motion(plan.frequencies_hz, a, 0.1, 0.15)
    one_cycle = fade_motion(plan.frequencies_hz, a, 0.1, 0.1)
    assert abs(now.residual_velocity_m_per_s) < 0.01 * steady_v
    assert abs(one_cycle.residual_velocity_m_per_s) > 5 * abs(now.residual_velocity_m_per_s)
    # the fades stay inside the steady orbit's peaks; what they leave is under 2 mm
    assert now.velocity_peak_m_per_s < steady_v
    assert abs(now.residual_displacement_m) < 2e-3 and abs(now.offset_displacement_m) < 2e-3


def test_the_motion_is_integrated_exactly_not_on_the_grid():
    """A slow line on a fast one: the grid follows the fast line, the end values are exact
    whatever the grid (two grids agree to 1e-9)."""
    f = np.array([0.5, 400.0])
    a = np.array([0.3 + 0.1j, 1.0])
    coarse = fade_motion(f, a, 2.0, 3.0)
    fine = fade_motion(np.append(f, 4000.0), np.append(a, 1e-12), 2.0, 3.0)  # a finer grid
    assert coarse.residual_displacement_m == pytest.approx(fine.residual_displacement_m, rel=1e-9)
    assert coarse.offset_velocity_m_per_s == pytest.approx(fine.offset_velocity_m_per_s, rel=1e-9)


def test_fade_motion_refuses_what_it_cannot_integrate():
    with pytest.raises(ValueError, match="one complex acceleration per line"):
        fade_motion(np.array([10.0, 20.0]), np.array([1.0]), 0.1, 0.1)
    with pytest.raises(ValueError, match="fade lengths"):
        fade_motion(np.array([10.0]), np.array([1.0]), 0.0, 0.1)
