"""Known answers for the local polynomial method (dsp.lpm): an LTI pair with known FRFs, a
start-up transient and white noise; expected values computed here from the filters, not by
the estimator."""

import numpy as np
import pytest
import scipy.signal as sg

from dsp import iso266, lpm

FS = 1000.0
N = 2000  # 2 s: the 0.5 Hz grid
FREQS = np.array(iso266.nominal_frequencies(10, 250))
BINS = np.rint(FREQS * N / FS).astype(np.int64)
REF_FILTER = sg.butter(2, [5 / (FS / 2), 300 / (FS / 2)], "band")  # reference chain
DUT_FILTER = sg.cheby1(2, 1, 80 / (FS / 2))  # DUT: a low-pass with ripple


def _truth() -> np.ndarray:
    g_u = sg.freqz(*REF_FILTER, worN=FREQS, fs=FS)[1]
    g_y = sg.freqz(*DUT_FILTER, worN=FREQS, fs=FS)[1]
    return g_y / g_u


def _drive(rng: np.random.Generator, bins: np.ndarray = BINS, n: int = N) -> np.ndarray:
    phases = rng.uniform(0, 2 * np.pi, bins.size)
    t = np.arange(n)
    return np.cos(2 * np.pi * np.outer(bins, t) / n + phases[:, None]).sum(axis=0)


def _record(rng, sigma, *, cubic=0.0, settled=False):
    """First period after the drive starts from rest (transient in it), or a settled one."""
    r = _drive(rng)
    x = np.tile(r, 3) if settled else r
    u = sg.lfilter(*REF_FILTER, x)[-N:]
    v = x + cubic * x**3
    y = sg.lfilter(*DUT_FILTER, v)[-N:]
    return u + sigma * rng.standard_normal(N), y + sigma * rng.standard_normal(N), r


def test_frf_recovered_and_transient_removed_without_noise():
    rng = np.random.default_rng(1)
    u, y, _ = _record(rng, 0.0)
    truth = _truth()
    with_transient = lpm.estimate(u, y, BINS)
    error = np.abs(with_transient.response / truth - 1)
    assert error.max() < 2e-4  # the transient term leaves a polynomial misfit only
    # the same record without the transient term: leakage of the start-up stays in
    without = lpm.estimate(u, y, BINS, settings=lpm.LpmSettings(order=-1, bins=9))
    assert np.abs(without.response / truth - 1).max() > 50 * error.max()
    # and a settled record gives nearly no transient at the lines
    u_s, y_s, _ = _record(rng, 0.0, settled=True)
    settled = lpm.estimate(u_s, y_s, BINS)
    assert np.median(settled.dut_transient_v) < 1e-3 * np.median(with_transient.dut_transient_v)


def test_noise_variance_and_dof_recovered():
    rng = np.random.default_rng(2)
    sigma = 0.01
    u, y, _ = _record(rng, sigma)
    e = lpm.estimate(u, y, BINS)
    expected = np.sqrt(4 * sigma**2 / N)  # |(2/N) DFT of white noise|, rms, per bin
    # 15 lines x 9 complex dof: the pooled estimate is within 15 % (chi2(270) spread 9 %)
    assert np.sqrt(np.mean(e.dut_noise_v**2)) == pytest.approx(expected, rel=0.15)
    assert np.sqrt(np.mean(e.reference_noise_v**2)) == pytest.approx(expected, rel=0.15)
    assert np.all(e.line_dof == 12 - 3)
    np.testing.assert_array_equal(e.dof, 2 * 9)
    assert e.variance_kind == ("total",) * FREQS.size
    assert np.all(np.isnan(e.nonlinear_variance))


@pytest.mark.slow
def test_coverage_with_student_t_at_the_stated_dof():
    from scipy import stats

    rng = np.random.default_rng(3)
    truth = _truth()
    hits = []
    for _ in range(300):
        u, y, _ = _record(rng, 0.02)
        e = lpm.estimate(u, y, BINS)
        k = stats.t.ppf(0.97725, e.dof)
        err = e.response / truth - 1
        hits.append(np.abs(err.real) <= k * e.relative_type_a)
        hits.append(np.abs(err.imag) <= k * e.phase_type_a_rad)
    coverage = np.mean(hits)
    assert 0.93 <= coverage <= 0.975  # 9000 cases: +-0.5 % standard error


def test_usual_settings_leave_too_few_dof_and_are_refused():
    with pytest.raises(lpm.LpmError, match="q = 1"):
        lpm.LpmSettings(order=2, bins=4, min_dof=8).check()
    # a line crowded by its neighbours is refused by name
    u = np.zeros(256)
    with pytest.raises(lpm.LpmError, match="line at bin 10"):
        lpm.estimate(u, u, [10, 12, 14, 16], settings=lpm.LpmSettings(reach=3))


@pytest.mark.slow
def test_neighbouring_lines_share_bins_and_their_errors_correlate():
    """Order 0, 4 bins: line 20 uses 18, 19, 21, 22 and line 23 uses 21, 22, 24, 25, so
    weights 1/4, shared 21 and 22: cov = 2/16 sigma^2, var = (1 + 4/16) sigma^2, rho = 0.1
    for two lines in phase (relative errors e/Y: the correlation of the magnitude errors is
    0.1 cos(phase difference), so the drive is fixed and in phase)."""
    rng = np.random.default_rng(4)
    n = 256
    bins = np.array([20, 23])
    settings = lpm.LpmSettings(order=0, bins=4, min_dof=3)
    errors, stated = [], []
    t = np.arange(n)
    r = np.cos(2 * np.pi * 20 * t / n) + np.cos(2 * np.pi * 23 * t / n)
    for _ in range(3000):
        y = r + 0.05 * rng.standard_normal(n)
        e = lpm.estimate(r, y, bins, settings=settings)
        errors.append(e.response.real - 1)
        stated.append(e.neighbour_correlation[0])
    assert np.median(stated) == pytest.approx(0.1, abs=0.02)
    measured = np.corrcoef(np.array(errors).T)[0, 1]
    assert measured == pytest.approx(0.1, abs=0.04)  # 3000 pairs: standard error 0.018
    # the deviation from line 23 has a smaller u than two independent lines would give
    e = lpm.estimate(r, y, bins, settings=settings)
    independent = np.hypot(*e.relative_type_a)
    assert e.ratio_type_a(0, 1) < independent * 0.97


def test_nonlinear_part_found_with_realisations_and_labelled():
    """Stochastic nonlinear distortion as it appears at the lines: per realisation a random
    complex part xi of the DUT's line, E|xi|^2 = s^2 (relative), nothing at other bins. The
    between-realisation variance holds it, the LPM's noise does not: relation (7)."""
    rng = np.random.default_rng(5)
    linear = [_record(rng, 0.01) for _ in range(2)]
    e = lpm.estimate([r[0] for r in linear], [r[1] for r in linear], BINS)
    assert e.realisations == 2
    assert e.variance_kind.count("noise") >= FREQS.size - 1  # 1 % false alarm per line
    s = 0.01
    g_y = sg.freqz(*DUT_FILTER, worN=FREQS, fs=FS)[1]
    t = np.arange(N)
    refs, duts = [], []
    for _ in range(3):
        u, y, r = _record(rng, 0.01, settled=True)
        phases = np.angle(np.fft.rfft(r)[BINS])
        xi = s * (rng.standard_normal(BINS.size) + 1j * rng.standard_normal(BINS.size))
        xi /= np.sqrt(2)
        line = g_y * xi * np.exp(1j * phases)
        y = y + np.real(line[:, None] * np.exp(2j * np.pi * np.outer(BINS, t) / N)).sum(axis=0)
        refs.append(u)
        duts.append(y)
    e = lpm.estimate(refs, duts, BINS)
    found = np.array([k == "noise+nonlinear" for k in e.variance_kind])
    assert found.sum() >= FREQS.size - 2  # s^2 is 20-200 x the noise variance
    assert np.median(e.noise_variance) < 0.01 * s**2
    # 15 lines x 2 (P - 1) dof: the pooled estimate of s^2 within 30 %
    assert np.mean(e.nonlinear_variance) == pytest.approx(s**2, rel=0.3)
    assert np.all(e.dof[found] == 2 * (3 - 1))
    u_expected = np.sqrt((e.nonlinear_variance + e.noise_variance) / 3 / 2)
    np.testing.assert_allclose(e.relative_type_a[found], u_expected[found], rtol=1e-9)


def test_drive_given_gives_frfs_per_volt_and_refuses_a_fade_inside():
    rng = np.random.default_rng(6)
    u, y, r = _record(rng, 0.0)
    e = lpm.estimate(u, y, BINS, drive_v=r)
    g_u = sg.freqz(*REF_FILTER, worN=FREQS, fs=FS)[1]
    np.testing.assert_allclose(e.reference_per_drive, g_u, rtol=2e-4)
    faded = r * np.linspace(0, 1, N)
    with pytest.raises(lpm.LpmError, match="drive: not periodic"):
        lpm.estimate(u, y, BINS, drive_v=faded)


def test_design_grid_seed_lines_and_a_low_frequency_plan():
    grid = lpm.design_grid(iso266.nominal_frequencies(10, 2500), 6000.0)
    assert grid.period_samples == 12000  # 31.5 and 12.5 Hz need the 0.5 Hz grid
    assert grid.frequencies_hz == grid.nominal_frequencies_hz
    assert min(grid.line_dof) >= 8
    assert grid.describe()[0] == "10 Hz: at 10 Hz (bin 20), q = 9 complex degrees of freedom"
    low = iso266.nominal_frequencies(0.4, 8)
    with pytest.raises(lpm.LpmError, match="no period"):
        lpm.design_grid(low, 200.0, max_period_s=60.0)  # exact 0.63 Hz needs 100 s
    grid = lpm.design_grid(low, 200.0, tolerance=0.03, max_period_s=60.0)
    assert grid.period_s < 60.0
    actual = np.array(grid.frequencies_hz)
    assert np.all(np.abs(actual / np.array(low) - 1) <= 0.03 + 1e-12)
    assert min(grid.line_dof) >= 8


def test_mains_bins_are_excluded_from_windows():
    assert lpm.mains_bins(0.5, 1001, 50.0, 2) == {100, 200}
    assert lpm.mains_bins(0.3, 1001, 50.0, 1) == {166, 167}
    offsets = lpm.window_offsets([98], 1001, lpm.LpmSettings(), excluded_bins={100})
    assert 2 not in offsets[0] and offsets[0].size == 12


@pytest.mark.slow
def test_table_motion_at_the_window_bins_is_not_taken_for_noise():
    """Content common to both channels at every non-excited bin (an exciter's distortion
    products: the drive carries it, both filters see it), 100 x the channel noise, with
    H = DUT/reference sloping: the stated u stays the size of the errors (z = error/u has
    rms sqrt(18/16) = 1.06 for t(18)); taken for noise it would be 2-3 x too large."""
    rng = np.random.default_rng(7)
    others = np.setdiff1d(np.arange(5, 300), BINS)
    t = np.arange(N)
    truth = _truth()
    z = []
    for _ in range(200):
        r = _drive(rng)
        phases = rng.uniform(0, 2 * np.pi, others.size)[:, None]
        motion = 5e-4 * np.cos(2 * np.pi * np.outer(others, t) / N + phases).sum(axis=0)
        x = np.tile(r + motion, 2)
        u = sg.lfilter(*REF_FILTER, x)[-N:] + 1e-4 * rng.standard_normal(N)
        y = sg.lfilter(*DUT_FILTER, x)[-N:] + 1e-4 * rng.standard_normal(N)
        e = lpm.estimate(u, y, BINS)
        err = e.response / truth - 1
        z.append(np.concatenate([err.real / e.relative_type_a, err.imag / e.phase_type_a_rad]))
    rms = float(np.sqrt(np.mean(np.square(z))))
    assert 0.85 <= rms <= 1.2
