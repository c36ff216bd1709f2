"""sim/true_stand.py (issue 32 point 6): the true stand's factors by hand, its filter, and the
partial correlation of its certificate errors across frequency."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from sim.true_stand import TABLE, Term, TrueStand

ZERO = TrueStand.draw(0).without(*Term)


def _only(*terms: Term, **values: float) -> TrueStand:
    """A draw with the given deviations set and every other term left out."""
    stand = dataclasses.replace(TrueStand.draw(0), **values)
    return stand.without(*(t for t in Term if t not in terms))


def test_every_term_left_out_is_the_identity():
    assert ZERO.factor(np.array([0.5, 10.0, 5000.0, 40_000.0])) == pytest.approx([1, 1, 1, 1])


def test_transverse_motion_follows_the_rocking_mode():
    stand = _only(Term.TRANSVERSE, transverse_ratio=0.05, transverse_projection=0.04)
    f = np.array([10.0, TABLE.rocking_hz])
    # far below the rocking mode: 1 + 0.04 * 0.05; at it: 1 + 0.002 * Q / j (Q = 8)
    assert stand.factor(f)[0] == pytest.approx(1.002, abs=1e-6)
    assert stand.factor(f)[1] == pytest.approx(1.0 - 0.002j * TABLE.rocking_q, rel=1e-12)


def test_skew_antialias_and_bending_by_hand():
    skew = _only(Term.SKEW, skew_error_s=5e-8)
    # 360 * 4000 Hz * 50 ns = 0.072 deg, the DUT sampled later reads a lagging phase
    assert skew.phase_error_deg(np.array([4000.0]))[0] == pytest.approx(-0.072)
    bending = _only(Term.MOUNTING, mounting_torque=0.0, plate_bending=0.02)
    # 0.02 * (6 kHz / 12 kHz)^2 = 0.5 %
    assert bending.magnitude_error(np.array([6000.0]))[0] == pytest.approx(0.005)
    filters = _only(Term.ANTIALIAS, antialias_corner_difference=0.01)
    f, fc = 1000.0, TABLE.antialias_corner_hz

    # a 2-pole Butterworth's phase -atan2(sqrt2 f/fc, 1 - (f/fc)^2): the corner 1 % higher
    # lags less
    def phase(corner: float) -> float:
        return -math.degrees(math.atan2(math.sqrt(2) * f / corner, 1 - (f / corner) ** 2))

    expected = phase(fc * 1.01) - phase(fc)
    assert filters.phase_error_deg(np.array([f]))[0] == pytest.approx(expected, rel=1e-9)
    assert expected == pytest.approx(0.0321, abs=2e-4)


def test_certificate_errors_are_only_partly_correlated_across_frequency():
    f = np.array([100.0, 200.0, 1600.0])
    errors = np.array(
        [
            TrueStand.draw(s)
            .without(*(t for t in Term if t is not Term.REFERENCE_CERTIFICATE))
            .magnitude_error(f)
            for s in range(3000)
        ]
    )
    local = errors  # the whole certificate error: common and local parts
    total_sd = local.std(axis=0)
    expected_sd = math.hypot(TABLE.certificate_common, TABLE.certificate_local)
    assert total_sd == pytest.approx([expected_sd] * 3, rel=0.06)
    # one octave apart: common^2 + local^2 e^-1 over the total; four octaves: e^-4
    c, loc = TABLE.certificate_common**2, TABLE.certificate_local**2
    rho_1 = np.corrcoef(local[:, 0], local[:, 1])[0, 1]
    rho_4 = np.corrcoef(local[:, 0], local[:, 2])[0, 1]
    assert rho_1 == pytest.approx((c + loc * math.exp(-1)) / (c + loc), abs=0.04)
    assert rho_4 == pytest.approx((c + loc * math.exp(-4)) / (c + loc), abs=0.04)
    assert rho_4 < rho_1 < 0.95


def test_apply_is_the_factor_at_each_line():
    fs, n = 6000.0, 12000
    t = np.arange(3 * n) / fs
    x = np.sin(2 * np.pi * 500.0 * t) + 0.5 * np.sin(2 * np.pi * 2500.0 * t)
    stand = TrueStand.draw(3)
    y = stand.apply(x, fs)
    spectrum_x, spectrum_y = np.fft.rfft(x), np.fft.rfft(y)
    for f in (500.0, 2500.0):
        m = int(f * 3 * n / fs)
        ratio = spectrum_y[m] / spectrum_x[m]
        assert ratio == pytest.approx(stand.factor(np.array([f]))[0], rel=1e-9)


def test_draws_are_per_seed_and_can_leave_terms_out():
    assert TrueStand.draw(1) == TrueStand.draw(1) != TrueStand.draw(2)
    one = TrueStand.draw(1)
    f = np.array([10.0, 3000.0])
    without = one.without(Term.TRANSVERSE)
    assert Term.TRANSVERSE not in without.term_factors(f)
    ratio = one.factor(f) / without.factor(f)
    assert ratio == pytest.approx(one.term_factors(f)[Term.TRANSVERSE], rel=1e-12)
