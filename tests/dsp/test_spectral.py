"""Known-answer, equivalence and Monte Carlo tests of the estimators (SPEC.md s.6)."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.signal
import scipy.stats
from hypothesis import given, settings
from hypothesis import strategies as st

from dsp.spectral import (
    ESTIMATORS,
    RECORD_ESTIMATORS,
    SpectralAccumulator,
    dft_at,
    period_spectrum,
    periods_agree,
)

STREAMING = tuple(e for e in ESTIMATORS if e not in RECORD_ESTIMATORS)  # lpm: dsp.lpm_record
N = 1200  # 0.5 Hz grid at 600 Hz: small and fast
FS = 600.0
BINS = np.array([20, 25, 32, 40, 50, 63, 80, 100, 126, 160, 200])  # 10..100 Hz


def lowpass(f: np.ndarray) -> np.ndarray:
    """35 mV/(m/s^2) second-order low-pass at 200 Hz (Q 0.707), as a ratio to a 1 mV ref."""
    s = 1j * f / 200.0
    return 35.0 / (1 + s / 0.707 + s**2)


def periods_of(response: np.ndarray, bins=BINS, n=N, periods=1, seed=0):
    rng = np.random.default_rng(seed)
    i = np.arange(n)
    phases = rng.uniform(0, 2 * np.pi, bins.size)
    amps = rng.uniform(0.5, 1.5, bins.size)
    u = sum(
        a * np.sin(2 * np.pi * m * i / n + p) for a, m, p in zip(amps, bins, phases, strict=True)
    )
    y = sum(
        a * abs(h) * np.sin(2 * np.pi * m * i / n + p + np.angle(h))
        for a, m, p, h in zip(amps, bins, phases, response, strict=True)
    )
    return np.tile(u, (periods, 1)), np.tile(y, (periods, 1)), amps


@pytest.mark.parametrize("estimator", STREAMING)
def test_noiseless_known_response_recovered(estimator):
    truth = lowpass(BINS * FS / N)
    u, y, _ = periods_of(truth, periods=3)
    acc = SpectralAccumulator(N, BINS)
    acc.add_periods(u, y)
    est = acc.estimate(estimator)
    np.testing.assert_allclose(np.abs(est.response), np.abs(truth), rtol=1e-9)
    phase_error = np.degrees(np.angle(est.response / truth))
    assert np.max(np.abs(phase_error)) < 1e-6
    np.testing.assert_allclose(est.coherence, 1.0, atol=1e-9)


def test_period_spectrum_scaling_is_peak_amplitude():
    i = np.arange(N)
    x = 2.5 * np.sin(2 * np.pi * 40 * i / N + 0.3)
    spectrum = period_spectrum(x)
    assert abs(spectrum[40]) == pytest.approx(2.5, rel=1e-12)
    assert np.angle(spectrum[40]) == pytest.approx(0.3 - np.pi / 2, abs=1e-12)
    assert abs(dft_at(x, [40 * FS / N], FS)) == pytest.approx(2.5, rel=1e-12)


def test_h1_equals_scipy_csd_over_welch():
    rng = np.random.default_rng(3)
    truth = lowpass(BINS * FS / N)
    u, y, _ = periods_of(truth, periods=6)
    u = u + 0.05 * rng.standard_normal(u.shape)
    y = y + 0.05 * rng.standard_normal(y.shape)
    acc = SpectralAccumulator(N, BINS)
    acc.add_periods(u, y)
    ours = acc.estimate("h1").response
    kw = dict(fs=FS, window="boxcar", nperseg=N, noverlap=0, detrend=False)
    _, p_uy = scipy.signal.csd(u.ravel(), y.ravel(), **kw)
    _, p_uu = scipy.signal.welch(u.ravel(), **kw)
    _, p_yy = scipy.signal.welch(y.ravel(), **kw)
    reference = p_uy[BINS] / p_uu[BINS]
    np.testing.assert_allclose(ours, reference, rtol=1e-12, atol=0)
    coherence = np.abs(p_uy[BINS]) ** 2 / (p_uu[BINS] * p_yy[BINS])
    np.testing.assert_allclose(acc.estimate("h1").coherence, coherence, rtol=1e-10)


def monte_carlo(estimator: str, runs: int, periods: int, snr_db: float, seed: int = 11):
    """Relative magnitude errors and stated type A over runs with noise on both channels."""
    truth = lowpass(BINS * FS / N)
    u0, y0, amps = periods_of(truth)
    # per-period SNR at a line: (A^2) / (4 sigma^2 / N) for a peak-scaled DFT
    sigma_u = amps.min() * np.sqrt(N / 4) * 10 ** (-snr_db / 20)
    sigma_y = sigma_u * np.abs(truth).min()
    rng = np.random.default_rng(seed)
    errors, stated = [], []
    for _ in range(runs):
        acc = SpectralAccumulator(N, BINS, track_floor=False)
        u = u0 + sigma_u * rng.standard_normal((periods, N))
        y = y0 + sigma_y * rng.standard_normal((periods, N))
        acc.add_periods(u, y)
        est = acc.estimate(estimator)
        errors.append(np.abs(est.response) / np.abs(truth) - 1)
        stated.append(est.relative_type_a)
    return np.array(errors), np.array(stated)


@pytest.mark.slow  # Monte Carlo
def test_type_a_matches_monte_carlo_spread():
    """Stated type A (rms over runs) within 15 % of the Monte Carlo std, time-domain noise."""
    for estimator in ("periodic", "seed"):
        errors, stated = monte_carlo(estimator, runs=1500, periods=8, snr_db=20)
        spread = errors.std(axis=0, ddof=1)
        ratio = np.sqrt((stated**2).mean(axis=0)) / spread
        assert np.all(np.abs(ratio - 1) < 0.15), (estimator, ratio)


def line_spectra_monte_carlo(estimator: str, runs: int, periods: int, snr_db: float):
    """Relative |H| errors of `runs` independent calibrations of one line at `snr_db` per
    period on both channels; the DFT of white noise at a bin is circular complex Gaussian,
    so each accumulator column is an independent run (vectorised)."""
    rng = np.random.default_rng(7)
    truth = 0.035 * np.exp(-0.7j)
    u_true, y_true = 1.0 * np.exp(0.3j), truth * np.exp(0.3j)
    sigma = 10 ** (-snr_db / 20) / np.sqrt(2)  # per real/imag part: E|n|^2 = A^2 / SNR

    def noise():
        return sigma * (
            rng.standard_normal((periods, runs)) + 1j * rng.standard_normal((periods, runs))
        )

    acc = SpectralAccumulator(periods, np.arange(1, runs + 1), track_floor=False)
    acc.add_line_spectra(u_true + noise(), y_true * (1 + noise()))
    return np.abs(acc.estimate(estimator).response) / abs(truth) - 1


@pytest.mark.slow  # Monte Carlo
def test_periodic_is_unbiased_and_seed_is_biased_at_20_db():
    periodic = line_spectra_monte_carlo("periodic", runs=200_000, periods=16, snr_db=20)
    seed = line_spectra_monte_carlo("seed", runs=200_000, periods=16, snr_db=20)
    standard_error = periodic.std() / np.sqrt(periodic.size)
    assert standard_error < 1e-4
    assert abs(periodic.mean()) < 5e-4, periodic.mean()  # SPEC s.12: bias < 0.05 %
    # the seed's mean of per-period ratios is biased by about var/4 = 1/(2 SNR) = 0.5 %
    assert seed.mean() == pytest.approx(0.005, rel=0.2)
    assert seed.mean() > 10 * abs(periodic.mean())


def test_order_and_batching_do_not_change_the_estimate():
    rng = np.random.default_rng(5)
    truth = lowpass(BINS * FS / N)
    u, y, _ = periods_of(truth, periods=7)
    u = u + 0.1 * rng.standard_normal(u.shape)
    y = y + 0.1 * rng.standard_normal(y.shape)
    one = SpectralAccumulator(N, BINS)
    for k in range(7):
        one.add_period(u[k], y[k])
    batch = SpectralAccumulator(N, BINS)
    batch.add_periods(u[:3], y[:3])
    batch.add_periods(u[3:], y[3:])
    for name in STREAMING:
        a, b = one.estimate(name), batch.estimate(name)
        np.testing.assert_allclose(a.response, b.response, rtol=1e-12)
        np.testing.assert_allclose(a.relative_type_a, b.relative_type_a, rtol=1e-9)
        np.testing.assert_allclose(a.dut_noise_v, b.dut_noise_v, rtol=1e-9)


@settings(max_examples=30, deadline=None)
@given(order=st.permutations(list(range(6))), seed=st.integers(0, 2**16))
def test_any_order_of_periods_gives_the_same_answer(order, seed):
    rng = np.random.default_rng(seed)
    truth = lowpass(BINS * FS / N)
    u, y, _ = periods_of(truth, periods=6, seed=seed)
    u = u + 0.2 * rng.standard_normal(u.shape)
    y = y + 0.2 * rng.standard_normal(y.shape)
    forward = SpectralAccumulator(N, BINS)
    forward.add_periods(u, y)
    shuffled = SpectralAccumulator(N, BINS)
    for k in order:
        shuffled.add_period(u[k], y[k])
    for name in STREAMING:
        a, b = forward.estimate(name), shuffled.estimate(name)
        np.testing.assert_allclose(a.response, b.response, rtol=1e-10)
        np.testing.assert_allclose(a.relative_type_a, b.relative_type_a, rtol=1e-7)
        np.testing.assert_allclose(a.coherence, b.coherence, rtol=1e-10)


def test_noise_floor_snr_and_distortion():
    i = np.arange(N)
    rng = np.random.default_rng(2)
    periods, sigma = 16, 0.01
    u = np.sin(2 * np.pi * 40 * i / N)
    # DUT: the line plus 3 % second harmonic (bin 80 is not a line here)
    y = 0.5 * np.sin(2 * np.pi * 40 * i / N) + 0.015 * np.sin(2 * np.pi * 80 * i / N)
    acc = SpectralAccumulator(N, [40, 100])
    acc.add_periods(
        np.tile(u + 0.2 * np.sin(2 * np.pi * 100 * i / N), (periods, 1))
        + sigma * rng.standard_normal((periods, N)),
        np.tile(y + 0.1 * np.sin(2 * np.pi * 100 * i / N), (periods, 1))
        + sigma * rng.standard_normal((periods, N)),
    )
    est = acc.estimate()
    expected_noise = sigma * np.sqrt(4 / N)  # peak-scaled DFT noise per period
    np.testing.assert_allclose(est.dut_noise_v, expected_noise, rtol=0.15)
    assert est.dut_snr_db[0] == pytest.approx(20 * np.log10(0.5 / expected_noise), abs=1.5)
    assert est.dut_distortion[0] == pytest.approx(0.03, rel=0.05)
    assert est.reference_distortion[0] < 0.003


def test_one_period_gives_nan_type_a_and_errors_on_bad_shapes():
    truth = lowpass(BINS * FS / N)
    u, y, _ = periods_of(truth)
    acc = SpectralAccumulator(N, BINS)
    with pytest.raises(ValueError, match="no period"):
        acc.estimate()
    acc.add_periods(u, y)
    est = acc.estimate()
    assert np.all(np.isnan(est.relative_type_a)) and np.isnan(est.dof)
    with pytest.raises(ValueError, match="1200 samples"):
        acc.add_period(u[0, :-1], y[0, :-1])
    with pytest.raises(ValueError, match="unknown"):
        acc.estimate("welch")


@pytest.mark.slow  # Monte Carlo
@pytest.mark.parametrize("estimator", ["periodic", "seed"])
def test_type_a_degrees_of_freedom_give_nominal_t_coverage(estimator):
    """With 4 periods, the t interval at the stated dof covers the truth 95.45 % of the time
    (complex estimators: 2 (L - 1) dof from circular noise; L - 1 would give about 98 %)."""
    periods, runs = 4, 200_000
    rng = np.random.default_rng(3)
    sigma = 0.05
    shape = (2, periods, runs)
    noise = sigma * (rng.standard_normal(shape) + 1j * rng.standard_normal(shape))
    acc = SpectralAccumulator(periods, np.arange(1, runs + 1), track_floor=False)
    acc.add_line_spectra(1.0 + 0.1 * noise[0], 0.5 * (1.0 + noise[1]))
    est = acc.estimate(estimator)
    k = scipy.stats.t.ppf((1 + 0.9545) / 2, est.dof)
    covered = np.abs(np.abs(est.response) / 0.5 - 1) <= k * est.relative_type_a
    assert covered.mean() == pytest.approx(0.9545, abs=0.003)


def test_periods_agree_checks_every_channel_against_level_or_noise():
    previous = np.array([[1.0 + 0j, 0.5j], [0.2 + 0j, 0.1 + 0j]])  # (channel, line), volts
    noise = np.full((2, 2), 1e-4)
    assert periods_agree(previous, previous * (1 + 1e-3), noise, 0.002)
    dut_moved = previous.copy()
    dut_moved[1, 1] *= 1.01  # only the DUT channel, one line: 1 % > 0.2 % and > 6 sigma
    assert not periods_agree(previous, dut_moved, noise, 0.002)
    weak = np.array([[1e-4 + 0j], [1e-4 + 0j]])  # lines in the noise: 6 sigma decides
    assert periods_agree(weak, weak + 5e-4, np.full((2, 1), 1e-4), 0.002)
    assert not periods_agree(weak, weak + 7e-4, np.full((2, 1), 1e-4), 0.002)


def test_noise_only_periods_agree_with_the_floor_estimated_from_neighbour_bins():
    """The settle test's noise scale from one background period's non-excited bins is
    within 5 % on average, so two later noise-only periods agree (a 6 sigma test) in 200 of
    200 trials."""
    rng = np.random.default_rng(4)
    n, bins = 4000, np.arange(20, 1800, 70)
    sigma_v = 1e-3
    background = SpectralAccumulator(n, bins)
    background.add_period(rng.normal(0, sigma_v, n), rng.normal(0, sigma_v, n))
    noise = background.estimate().reference_noise_v
    expected = 2 * sigma_v / np.sqrt(n)  # std of one period's peak-scaled complex bin
    assert np.all(np.abs(noise / expected - 1) < 0.5)
    assert abs(np.mean(noise) / expected - 1) < 0.05
    for _ in range(200):
        a, b = period_spectrum(rng.normal(0, sigma_v, (2, n)))[:, bins]
        assert periods_agree(a, b, noise, 0.002)


def test_the_accumulator_refuses_the_record_estimator():
    acc = SpectralAccumulator(N, BINS)
    acc.add_period(np.ones(N), np.ones(N))
    with pytest.raises(ValueError, match="lpm analyses one record"):
        acc.estimate("lpm")
