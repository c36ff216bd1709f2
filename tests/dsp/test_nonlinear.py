"""dsp.nonlinear through dsp.lpm_record: the DUT's distortion measured at the detection bins of
one record and carried to every line (issue 32 point 4). Known answers on synthetic records:
a static cubic's best linear approximation (BLA) is h (1 + c beta_k) at line k."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

from app.records.warnings import WarningKind, blocking, classify
from dsp import iso266, lpm, nonlinear
from dsp.crestfactor import synthesize
from dsp.lpm_record import hum_bins, record_estimate
from dsp.multisine import make_plan
from dsp.spectral import SpectralAccumulator
from sim.models import DUT_CATALOGUE, MEMS_CUBIC_FRACTION, MEMS_CUBIC_RMS_MS2

FS, N = 2000.0, 4000  # 0.5 Hz bins, one 2 s period
FREQUENCIES = iso266.nominal_frequencies(10.0, 400.0)  # 17 lines on the ISO 266 grid
H = 0.5  # the DUT's linear gain (V/V)


def _plan(seed: int = 3):
    phases = np.random.default_rng(seed).uniform(0, 2 * np.pi, len(FREQUENCIES))
    return make_plan(FREQUENCIES, FS, N, 1.0, 160.0, phases_rad=phases)


def _record(plan, law, noise=1e-5, seed=1):
    """One period: reference u (1 V per line), DUT h law(u), white noise on both."""
    rng = np.random.default_rng(seed)
    u = synthesize(plan.bins, np.ones(len(plan.lines)), plan.phases_rad, N)
    y = H * law(u) + noise * rng.standard_normal(N)
    return (u + noise * rng.standard_normal(N))[None, :], y[None, :]


def _cubic_for(fraction: float) -> float:
    """c of u + c u^3 whose cubic is `fraction` of the signal (sqrt(15) c sigma^2)."""
    sigma2 = len(FREQUENCIES) / 2.0
    return -fraction / (math.sqrt(15.0) * sigma2)


def _bla(plan, c: float) -> np.ndarray:
    power = np.ones(len(plan.lines))
    beta = 0.75 * power + 1.5 * (power.sum() - power)
    return H * (1.0 + c * beta)


def _warnings(record, plan) -> list[str]:
    """What dsp.calibration adds to a run's warnings for this estimate."""
    e = record.estimate
    assert e.nonlinear is not None
    return nonlinear.warnings(e.nonlinear, [ln.label for ln in plan.lines], e.relative_type_a)


def test_a_cubic_is_found_and_the_stated_h_is_the_bla_within_its_type_a():
    plan = _plan()
    c = _cubic_for(0.006)
    ref, dut = _record(plan, lambda u: u + c * u**3)
    record = record_estimate(ref, dut, plan)
    found, e = record.nonlinear, record.estimate
    assert found is not None and found.found and found.adequate
    assert found.fraction == pytest.approx(0.006, rel=0.15)
    assert found.coefficients[1] == pytest.approx(c * len(FREQUENCIES) / 2, rel=0.02)
    error = e.response / _bla(plan, c) - 1.0
    assert np.all(np.abs(error.real) <= 4 * e.relative_type_a)
    assert np.all(np.abs(error.imag) <= 4 * e.phase_type_a_rad)
    # the plain one-period LPM's windows hold the products: its u is 10x larger, and still
    # its error against the BLA is larger than the stated one's u at most lines
    plain = lpm.estimate(ref, dut, plan.bins)
    plain_error = plain.response / _bla(plan, c) - 1.0
    assert np.median(plain.relative_type_a) > 10 * np.median(e.relative_type_a)
    assert np.median(np.abs(plain_error)) > 10 * np.median(np.abs(error))
    # the Bussgang part stays in: removing it too would state h, not the BLA
    assert np.max(np.abs(e.response / H - 1.0)) > 0.003
    texts = _warnings(record, plan)
    assert [classify(w).kind for w in texts] == [WarningKind.NONLINEAR_CARRIED]
    assert re.match(r"nonlinear distortion of the DUT: 0\.[56]\d? % of the signal", texts[0])
    assert e.nonlinear is found


def test_a_linear_dut_is_left_as_the_plain_lpm_states_it():
    plan = _plan()
    ref, dut = _record(plan, lambda u: u)
    record = record_estimate(ref, dut, plan)
    assert record.nonlinear is not None and not record.nonlinear.found
    assert _warnings(record, plan) == []
    plain = lpm.estimate(ref, dut, plan.bins, excluded_bins=hum_bins(plan))  # as a run's LPM
    np.testing.assert_array_equal(record.estimate.response, plain.response)
    np.testing.assert_array_equal(record.estimate.relative_type_a, plain.relative_type_a)


def test_rounding_in_a_noise_free_record_is_never_distortion():
    plan = _plan()
    for seed in range(3):
        ref, dut = _record(_plan(seed), lambda u: u, noise=0.0)
        record = record_estimate(ref, dut, _plan(seed))
        assert record.nonlinear is not None and not record.nonlinear.found
    assert plan.bins.size == len(FREQUENCIES)


def test_distortion_the_model_does_not_explain_blocks_pass_naming_the_lines():
    plan = _plan()
    ref, dut = _record(plan, lambda u: u - 2e-5 * u**5)  # fifth order, 4 %: not in the model
    record = record_estimate(ref, dut, plan)
    found = record.nonlinear
    assert found is not None and found.found and not found.adequate
    blocked = blocking(_warnings(record, plan))
    assert [w.kind for w in blocked] == [WarningKind.NONLINEAR_NOT_COVERED]
    assert blocked[0].text.startswith("nonlinear distortion at lines ")
    assert "Hz" in blocked[0].text


def test_the_periodic_estimator_states_the_bla_where_it_was_blind():
    """Every period repeats the same stochastic part: the between-period type A cannot see it;
    measured at the detection bins of the mean period, it is removed."""
    plan = _plan()
    c = _cubic_for(0.006)
    measured = SpectralAccumulator(N, plan.bins, nonlinear_excluded_bins=())
    plain = SpectralAccumulator(N, plan.bins)
    for seed in range(4):
        ref, dut = _record(plan, lambda u: u + c * u**3, noise=1e-4, seed=seed)
        measured.add_periods(ref, dut)
        plain.add_periods(ref, dut)
    e, p = measured.estimate("periodic"), plain.estimate("periodic")
    assert e.nonlinear is not None and e.nonlinear.found and p.nonlinear is None
    error = e.response / _bla(plan, c) - 1.0
    assert np.all(np.abs(error.real) <= 4 * e.relative_type_a)
    assert np.all(np.abs(error.imag) <= 4 * e.phase_type_a_rad)
    blind = p.response / _bla(plan, c) - 1.0
    assert np.max(np.abs(blind.real) / p.relative_type_a) > 10
    assert np.all(np.asarray(e.dof) >= 6)  # 2 (L - 1), joined by the model's (infinite) dof


def test_detection_bins_are_every_free_bin():
    free = nonlinear.free_bins(12, np.array([2, 5]), excluded=[7])
    assert free.tolist() == [1, 3, 4, 6, 8, 9, 10]


def test_detection_bins_as_a_mask_are_the_bins_the_loop_over_every_bin_gave():
    """free_bins is a boolean mask (issue 34 point 6: the list comprehension over a record's
    bins held the run worker in Python); the same bins as the set rule it replaced, with lines
    at the ends, repeated, beyond the record, and mains bins given as a generator."""

    def by_loop(size: int, lines, excluded) -> list[int]:
        blocked = {int(b) for b in lines} | {int(b) for b in excluded} | {0, size - 1}
        return [b for b in range(1, size - 1) if b not in blocked]

    rng = np.random.default_rng(5)
    for size in (0, 1, 2, 3, 17, 51_201):
        lines = rng.integers(-3, size + 4, 9) if size else np.array([], dtype=np.int64)
        mains = [int(b) for b in rng.integers(0, size + 2, 4)] + [size - 1, 1]
        free = nonlinear.free_bins(size, lines, excluded=(b for b in mains))
        assert free.dtype == np.int64
        assert free.tolist() == by_loop(size, lines, mains), size


def test_the_simulated_mems_cubic_dut_states_its_fraction():
    dut = DUT_CATALOGUE["mems-cubic"]
    assert dut.cubic_fraction(MEMS_CUBIC_RMS_MS2) == pytest.approx(MEMS_CUBIC_FRACTION)
    assert dut.cubic_per_ms2_sq < 0  # compressive
    twice = dut.with_cubic_fraction(0.012, MEMS_CUBIC_RMS_MS2)
    assert twice.cubic_per_ms2_sq == pytest.approx(2 * dut.cubic_per_ms2_sq)
    with pytest.raises(ValueError, match="cubic"):
        dut.with_cubic_fraction(-0.01, 10.0)
