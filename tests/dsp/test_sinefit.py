"""dsp.sinefit: the stepped sine's blocks of whole cycles and its block-compatible grid (issue 32
point 8: the fair stepped sine of docs/benchmarks.md plays these frequencies)."""

from __future__ import annotations

import numpy as np
import pytest

from dsp import iso266
from dsp.sinefit import block_compatible_grid, integer_cycle_block, sine_fit


def test_a_block_holds_whole_cycles_of_the_line_and_of_the_mains():
    assert integer_cycle_block(0.4, 200.0, 0.05, (50.0,)) == 500  # 2.5 s: one cycle
    assert integer_cycle_block(0.63, 200.0, 0.05, (50.0,)) == 20000  # 100 s: 63 cycles
    assert integer_cycle_block(8.0, 200.0, 0.05, (50.0,)) == 100  # 25 samples a cycle, x 4


def test_the_fit_returns_the_peak_scaled_complex_amplitude():
    fs, f, n = 200.0, 0.625, 320
    t = np.arange(n) / fs
    x = 0.3 * np.sin(2 * np.pi * f * t + 0.4) + 0.01
    (value,) = sine_fit(x, f, fs)
    assert value == pytest.approx(0.3 * np.exp(1j * (0.4 - np.pi / 2)), abs=1e-12)


def test_the_low_frequency_grid_trades_nominal_values_for_short_blocks():
    """0.4-8 Hz at 200 S/s: exact 0.63 Hz needs 100 s blocks; within 2 % the grid plays it at
    0.625 Hz (1.6 s, one cycle), never below 0.4 Hz nor above 8 Hz, each block the shortest
    integer_cycle_block gives for the frequency played."""
    nominal = iso266.nominal_frequencies(0.4, 8.0)
    grid = block_compatible_grid(nominal, 200.0, 0.05, within_hz=(0.4, 8.0))
    actual = np.array(grid.frequencies_hz)
    assert np.all(np.abs(actual / np.array(nominal) - 1) <= 0.02 + 1e-12)
    assert actual.min() >= 0.4 and actual.max() <= 8.0
    assert dict(zip(nominal, actual, strict=True))[0.63] == pytest.approx(0.625)
    for f, b, n in zip(actual, grid.bins, grid.block_samples, strict=True):
        assert b * 200.0 / grid.period_samples == pytest.approx(f, rel=1e-12)
        assert n == integer_cycle_block(f, 200.0, 0.05, (50.0,))
    exact = sum(integer_cycle_block(f, 200.0, 0.05, (50.0,)) for f in nominal) / 200.0
    assert sum(grid.block_samples) / 200.0 < 20.0 < 130.0 < exact


def test_lines_stay_off_the_mains_harmonics():
    grid = block_compatible_grid([50.0, 100.0, 160.0], 6000.0, 0.05, max_period_s=4.0)
    for f in grid.frequencies_hz:
        assert min(abs(f - 50.0 * h) for h in range(1, 6)) > 0.1


def test_no_bin_within_the_tolerance_is_refused():
    with pytest.raises(ValueError, match="no period up to 1 s"):
        block_compatible_grid([0.63], 200.0, 0.05, tolerance=0.0, max_period_s=1.0)
