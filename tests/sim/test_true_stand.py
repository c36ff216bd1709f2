"""sim/true_stand.py (issue 25 point 6): the true stand's factor, by hand, and its filter."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sim.true_stand import TrueStand

ZERO = TrueStand.draw(0).without(*TrueStand.__dataclass_fields__)


def test_laws_by_hand():
    t = ZERO.__class__(
        **{
            **ZERO.__dict__,
            "transverse": 0.002,
            "antialias_deg_per_khz": 0.04,
            "skew_error_s": 1e-7,
            "mounting": 0.001,
        }
    )
    # 1 kHz: below 2 kHz, constant terms; 8 kHz: (8/2)^1.5 = 8, (8/2)^1.2 = 5.278
    assert t.magnitude_error(np.array([1000.0]))[0] == pytest.approx(0.003)
    assert t.magnitude_error(np.array([8000.0]))[0] == pytest.approx(0.016 + 0.001 * 4**1.2)
    # phase at 5 kHz: 0.04 * 5 + 360 * 5000 * 1e-7 = 0.2 + 0.18 deg
    assert t.phase_error_deg(np.array([5000.0]))[0] == pytest.approx(0.38)


def test_apply_is_the_factor_at_each_line():
    fs, n = 6000.0, 12000
    t = np.arange(3 * n) / fs
    x = np.sin(2 * np.pi * 500.0 * t) + 0.5 * np.sin(2 * np.pi * 2500.0 * t)
    stand = TrueStand.draw(3, scale=5.0)
    y = stand.apply(x, fs)
    spectrum_x, spectrum_y = np.fft.rfft(x), np.fft.rfft(y)
    for f in (500.0, 2500.0):
        m = int(f * 3 * n / fs)
        ratio = spectrum_y[m] / spectrum_x[m]
        assert abs(ratio) == pytest.approx(1 + stand.magnitude_error(np.array([f]))[0], rel=1e-9)
        assert math.degrees(np.angle(ratio)) == pytest.approx(
            stand.phase_error_deg(np.array([f]))[0], abs=1e-9
        )


def test_draws_are_per_seed_and_can_leave_terms_out():
    assert TrueStand.draw(1) == TrueStand.draw(1) != TrueStand.draw(2)
    assert TrueStand.draw(1).without("antialias_deg_per_khz").antialias_deg_per_khz == 0.0
    assert ZERO.factor(np.array([10.0, 5000.0])) == pytest.approx([1.0, 1.0])
