"""A long record's LPM read a batch of periods at a time (issue 34 point 4): dsp.lpm's
NeighbourAccumulator holds the record's DFT near the period grid exactly, and
dsp.lpm_record.record_estimate_batches gives `record_estimate`'s result from it (every bin held
up to 2 NEIGHBOURHOOD_BINS + 1 periods; beyond, only the nonlinear fit's detection bins are
fewer)."""

from __future__ import annotations

import numpy as np
import pytest

from dsp import iso266, lpm
from dsp.calibration import AnalysisError
from dsp.crestfactor import synthesize
from dsp.lpm_neighbours import NeighbourAccumulator
from dsp.lpm_record import (
    NEIGHBOURHOOD_BINS,
    WHOLE_RECORD_PERIODS,
    record_estimate,
    record_estimate_batches,
)
from dsp.multisine import make_plan

FS, N = 2000.0, 1000  # 2 Hz bins, one 0.5 s period
FREQUENCIES = iso266.nominal_frequencies(10.0, 400.0)


def _plan(seed: int = 3):
    phases = np.random.default_rng(seed).uniform(0, 2 * np.pi, len(FREQUENCIES))
    return make_plan(FREQUENCIES, FS, N, 1.0, 160.0, phases_rad=phases)


def _record(plan, periods, cubic=0.0, noise=1e-5, seed=1):
    """`periods` periods: reference u (1 V per line), DUT 0.5 (u + cubic u^3) with a decaying
    start-up transient, white noise on both; and the drive."""
    rng = np.random.default_rng(seed)
    drive = synthesize(plan.bins, np.ones(len(plan.lines)), plan.phases_rad, N)
    u = np.tile(drive, periods)
    t = np.arange(u.size) / FS
    y = 0.5 * (u + cubic * u**3) + 1e-3 * np.exp(-t / 0.2) + noise * rng.standard_normal(u.size)
    u = u + noise * rng.standard_normal(u.size)
    shape = (periods, N)
    return u.reshape(shape), y.reshape(shape), np.tile(drive, (periods, 1))


def _batches(ref, dut, drive, size=7):
    for a in range(0, ref.shape[0], size):
        yield ref[a : a + size], dut[a : a + size], None if drive is None else drive[a : a + size]


@pytest.mark.parametrize(("periods", "half_width", "n"), [(40, 3, 60), (41, 2, 61), (5, 12, 60)])
def test_the_accumulated_bins_are_the_whole_record_dft(periods, half_width, n):
    rng = np.random.default_rng(periods)
    x = rng.standard_normal((2, periods * n))
    acc = NeighbourAccumulator(periods, n, half_width, 2)
    for a in range(0, periods, 3):  # batches of 3 periods, the last shorter
        acc.add(*(v.reshape(periods, n)[a : a + 3] for v in x))
    for channel in (0, 1):
        held = acc.spectrum(channel)
        full = np.fft.rfft(x[channel]) * (2.0 / (periods * n))
        bins = held.held_bins()
        residues = bins % periods
        expected = np.flatnonzero(
            np.minimum(np.arange(full.size) % periods, periods - np.arange(full.size) % periods)
            <= half_width
        )
        np.testing.assert_array_equal(bins, expected)
        assert np.all(np.minimum(residues, periods - residues) <= half_width)
        assert np.max(np.abs(held[bins] - full[bins])) < 1e-13 * np.max(np.abs(full))
        assert held[int(bins[5])] == pytest.approx(full[bins[5]], abs=1e-13)


def test_a_bin_not_held_and_a_period_too_many_are_refused():
    acc = NeighbourAccumulator(40, 60, 2, 1)
    acc.add(np.ones((40, 60)))
    with pytest.raises(lpm.LpmError, match="periods"):
        acc.add(np.ones((1, 60)))
    held = acc.spectrum()
    with pytest.raises(lpm.LpmError, match="bin 43: not held"):
        held[np.array([40, 43])]
    with pytest.raises(lpm.LpmError, match="bin 1201: not held"):  # beyond Nyquist (1200)
        held[1201]
    with pytest.raises(lpm.LpmError, match="3 of 4 periods"):
        short = NeighbourAccumulator(4, 60, 2, 1)
        short.add(np.ones((3, 60)))
        short.spectrum()


def _relative(a, b):
    return float(np.max(np.abs(np.asarray(a) - np.asarray(b)) / np.abs(np.asarray(b))))


def test_up_to_2w_plus_1_periods_every_bin_is_held_and_the_result_is_the_whole_records():
    """A cubic DUT, found: the fit, its test, the cleaned LPM and the carried result all agree
    with the whole record's to rounding (the type A from bins 1e-5 below the lines: 1e-9)."""
    plan = _plan()
    periods = 2 * NEIGHBOURHOOD_BINS + 1
    assert periods > WHOLE_RECORD_PERIODS
    ref, dut, drive = _record(plan, periods, cubic=-0.002)
    whole = record_estimate(ref, dut, plan, drive_blocks=drive)
    streamed = record_estimate_batches(_batches(ref, dut, drive), periods, plan)
    w, s = whole.nonlinear, streamed.nonlinear
    assert w is not None and s is not None and w.found and s.found
    assert s.tested_bins == w.tested_bins
    assert _relative(s.coefficients, w.coefficients) < 1e-9
    assert s.p_value == pytest.approx(w.p_value, rel=1e-6, abs=1e-300)
    assert s.model_p_value == pytest.approx(w.model_p_value, rel=1e-6)
    assert s.fraction == pytest.approx(w.fraction, rel=1e-12)
    e, f = whole.estimate, streamed.estimate
    assert _relative(f.response, e.response) < 1e-12
    assert _relative(f.relative_type_a, e.relative_type_a) < 1e-9
    assert _relative(f.phase_type_a_rad, e.phase_type_a_rad) < 1e-9
    np.testing.assert_allclose(f.dof, e.dof, rtol=1e-9)
    assert _relative(f.dut_noise_v, e.dut_noise_v) < 1e-9
    assert _relative(streamed.lpm.dut_per_drive, whole.lpm.dut_per_drive) < 1e-12
    np.testing.assert_allclose(f.dut_distortion, e.dut_distortion, rtol=1e-9, atol=1e-15)


def test_a_longer_record_fits_the_distortion_at_the_bins_held_and_states_the_same_bla():
    plan = _plan()
    periods = 60
    ref, dut, drive = _record(plan, periods, cubic=-0.002)
    whole = record_estimate(ref, dut, plan, drive_blocks=drive)
    streamed = record_estimate_batches(_batches(ref, dut, drive, size=16), periods, plan)
    w, s = whole.nonlinear, streamed.nonlinear
    assert w is not None and s is not None and w.found and s.found and s.adequate
    free = (periods * N // 2 + 1) - 2 - len(FREQUENCIES)
    held = (2 * NEIGHBOURHOOD_BINS + 1) * N // 2
    assert w.tested_bins > 0.99 * free and abs(s.tested_bins - held) < 30
    # the products of a periodic excitation land on the grid: theta the same within its u
    assert np.all(np.abs(s.coefficients - w.coefficients) < 3 * np.sqrt(np.diag(w.covariance)))
    e, f = whole.estimate, streamed.estimate
    assert np.all(np.abs(f.response / e.response - 1) < 2 * e.relative_type_a)
    np.testing.assert_allclose(f.relative_type_a, e.relative_type_a, rtol=0.2)


def test_a_linear_long_record_gives_the_whole_records_lpm():
    """No distortion found: the LPM reads the same bins, so the result is the whole record's."""
    plan = _plan()
    ref, dut, drive = _record(plan, 40)
    whole = record_estimate(ref, dut, plan, drive_blocks=drive)
    streamed = record_estimate_batches(_batches(ref, dut, drive), 40, plan)
    assert whole.nonlinear is not None and not whole.nonlinear.found
    assert streamed.nonlinear is not None and not streamed.nonlinear.found
    assert _relative(streamed.estimate.response, whole.estimate.response) < 1e-12
    assert _relative(streamed.estimate.relative_type_a, whole.estimate.relative_type_a) < 1e-9


def test_a_fade_inside_a_long_record_is_refused_as_for_the_whole_record():
    plan = _plan()
    ref, dut, drive = _record(plan, 30)
    drive = drive.copy()
    drive[0] *= np.linspace(0.0, 1.0, N)
    with pytest.raises(AnalysisError, match="drive: not periodic"):
        record_estimate_batches(_batches(ref, dut, drive), 30, plan)
    with pytest.raises(AnalysisError, match="29 of 30 periods"):
        record_estimate_batches(_batches(ref[:29], dut[:29], None), 30, plan)
