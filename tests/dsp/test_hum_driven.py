"""Hum while driven (issue 32 point 3): tones at the non-excited bins beside the lines located
and carried (dsp.tones, dsp.hum.DrivenHum), known answers on synthetic periods."""

from __future__ import annotations

import math

import numpy as np
import pytest

from app.records.warnings import Policy, WarningKind, classify
from dsp.hum import NEGLIGIBLE_HUM, DrivenHum, driven_hum, driven_hum_of_periods, merged
from dsp.multisine import make_plan
from dsp.spectral import period_spectrum, periods_agree
from dsp.tones import ON_LINE_BINS, find_tones, line_leak
from dsp.uncertainty import Budget, Component

FS, N = 6000.0, 12000  # 0.5 Hz bins
T = np.arange(N) / FS
LINE_BINS = np.array([80, 101, 126, 320])  # 40, 50.5 (moved off 50 Hz), 63, 160 Hz


def tone(f_hz: float, amplitude: float, phase: float = 0.3) -> np.ndarray:
    return amplitude * np.sin(2 * np.pi * f_hz * T + phase)


def lines_signal(scale: float = 1.0) -> np.ndarray:
    return sum(scale * np.sin(2 * np.pi * m * FS / N * T + m) for m in LINE_BINS)


@pytest.mark.parametrize("f_hum", [50.3, 50.7, 49.8, 63.2])
def test_a_tone_off_its_bin_is_located_and_its_leak_onto_each_line_known(f_hum):
    """The tone's content at each line bin, C / (nu - m), against the DFT of the tone alone;
    a second tone exactly on the 50 Hz bin (the ADC's hum) beside it changes nothing."""
    rng = np.random.default_rng(3)
    hum = tone(f_hum, 0.01) + tone(50.0, 0.02, 2.0)
    spectrum = period_spectrum(lines_signal() + hum + rng.normal(0, 1e-4, N))
    leak = line_leak(spectrum, LINE_BINS)
    truth = np.abs(period_spectrum(hum))[LINE_BINS]
    np.testing.assert_allclose(leak.leak_v, truth, rtol=0.06, atol=2e-5)
    k = int(np.argmin(np.abs(LINE_BINS - f_hum / 0.5)))
    assert abs(leak.tone_bin[k] * 0.5 - f_hum) < 0.01
    assert leak.separable.all()


def test_a_tone_on_a_bin_leaks_nothing_and_noise_alone_finds_no_tone():
    rng = np.random.default_rng(4)
    on_bin = period_spectrum(lines_signal() + tone(50.0, 0.05) + rng.normal(0, 1e-4, N))
    assert np.all(line_leak(on_bin, LINE_BINS).leak_v < 1e-5)
    for seed in range(5):
        noise = period_spectrum(lines_signal() + np.random.default_rng(seed).normal(0, 1e-3, N))
        assert [t for t in find_tones(noise, LINE_BINS) if t.c != 0] == []


def test_noise_beside_a_tone_on_its_bin_invents_no_tone_next_to_a_line():
    """The shipped stand's case: the ADC's 50 Hz hum on its free bin beside the 50.5 Hz line,
    noise around it. Fitting the neighbours' noise found a "tone" 0.13 bin from the line,
    "not separable", which blocked an ordinary run; the flanks must now hold 16 noise powers."""
    for seed in range(40):
        rng = np.random.default_rng(seed)
        x = lines_signal() + tone(50.0, 3e-3, seed) + rng.normal(0, 1e-4, N)
        leak = line_leak(period_spectrum(x), LINE_BINS)
        assert leak.separable.all(), seed
        assert np.all(leak.leak_v < 9e-6), seed  # noise-level: 1.8e-6 V per bin


def test_a_tone_within_a_fifth_of_a_bin_of_a_line_is_not_separable():
    spectrum = period_spectrum(lines_signal() + tone(50.45, 0.01))  # 0.1 bin from 50.5 Hz
    leak = line_leak(spectrum, LINE_BINS)
    assert leak.separable.tolist() == [True, False, True, True]
    assert abs(leak.tone_bin[1] - 100.9) < ON_LINE_BINS


def plan():
    return make_plan([40.0, 50.0, 63.0, 160.0], FS, N, 5.0, 160.0, phases_rad=[0.0] * 4)


def periods(dut_extra: np.ndarray, motion: np.ndarray | None = None, count: int = 4):
    """(reference, DUT) periods: the plan's lines, the DUT twice the reference, `motion` on
    the table (both channels), `dut_extra` on the DUT channel only; a tone continues across
    periods, so stack one long record."""
    t = np.arange(count * N) / FS
    table = sum(np.sin(2 * np.pi * ln.frequency_hz * t + 1.0) for ln in plan().lines)
    if motion is not None:
        table = table + motion(t)
    reference = 0.01 * table
    dut = 0.02 * table + dut_extra(t)
    return reference.reshape(count, N), dut.reshape(count, N)


def test_table_motion_off_the_bins_cancels_in_the_ratio_and_is_not_taken_for_hum():
    """Non-periodic table motion is on both channels in H: only hum on one channel counts."""
    p = plan()
    motion = periods(lambda t: 0 * t, motion=lambda t: 0.05 * np.sin(2 * np.pi * 50.3 * t))
    assert not driven_hum_of_periods(p, motion).affected.any()
    hum = periods(lambda t: 2e-4 * np.sin(2 * np.pi * 50.3 * t))  # 1 % of the 50.5 Hz line
    found = driven_hum_of_periods(p, hum)
    y = period_spectrum(hum[1].mean(axis=0))
    hum_alone = y - period_spectrum(periods(lambda t: 0 * t)[1].mean(axis=0))
    expected = np.abs(hum_alone[p.bins]) / np.abs(y[p.bins])  # after averaging 4 periods
    np.testing.assert_allclose(found.relative, expected, rtol=0.05, atol=2e-6)
    assert found.affected.tolist() == (expected >= NEGLIGIBLE_HUM).tolist()
    assert found.affected[1] and not found.affected[3]  # 50.5 Hz reached, 160 Hz not
    assert found.separable.all() and abs(found.tone_hz[1] - 50.3) < 0.01


def test_driven_hum_components_warnings_and_their_policy():
    p = plan()
    found = driven_hum_of_periods(p, periods(lambda t: 2e-4 * np.sin(2 * np.pi * 50.3 * t)))
    names = [c.name for c in found.components()]
    assert "hum while driven at 50 Hz" in names and "hum while driven (phase) at 50 Hz" in names
    magnitude = next(c for c in found.components() if c.name == "hum while driven at 50 Hz")
    assert magnitude.value == pytest.approx(found.relative[1])
    assert magnitude.min_frequency_hz <= 50.5 <= magnitude.max_frequency_hz
    assert magnitude.max_frequency_hz - magnitude.min_frequency_hz == pytest.approx(0.5)
    text = next(w for w in found.warnings() if w.startswith("line 50 Hz:"))
    tone_hz = float(text.split("driven at ")[1].split(" Hz")[0])
    assert abs(tone_hz - 50.3) < 0.01 and classify(text).kind == WarningKind.HUM_MEASURED
    assert classify(text).policy == Policy.PRINTED
    close = driven_hum_of_periods(p, periods(lambda t: 2e-4 * np.sin(2 * np.pi * 50.45 * t)))
    blocked = next(w for w in close.warnings() if w.startswith("line 50 Hz:"))
    assert classify(blocked).kind == WarningKind.HUM_NOT_SEPARABLE
    assert classify(blocked).policy == Policy.BLOCKS


def test_a_line_kept_on_a_mains_harmonic_carries_its_departure_from_its_neighbours():
    """Exact bins: hum while driven on the 50 Hz line's own bin cannot be told from it; the
    line's departure from a smooth response through its neighbours bounds it."""
    p = make_plan(
        [31.5, 40.0, 50.0, 63.0, 80.0, 160.0],
        FS,
        N,
        5.0,
        160.0,
        shift_mains_lines=False,
        phases_rad=[0.0] * 6,
    )
    t = np.arange(N) / FS
    table = sum(np.sin(2 * np.pi * ln.frequency_hz * t + 1.0) for ln in p.lines)
    hum = 4e-4 * np.sin(2 * np.pi * 50.0 * t)  # 2 % of the DUT's 50 Hz line
    u, y = period_spectrum(0.01 * table), period_spectrum(0.02 * table + hum)
    found = driven_hum(p, u, y)
    assert found.affected.tolist() == [False, False, True, False, False, False]
    assert 0.02 <= found.relative[2] <= 0.03
    assert "kept on a mains harmonic" in found.warnings()[0]
    clean = driven_hum(p, u, period_spectrum(0.02 * table))
    assert clean.relative[2] < 1e-6


def test_a_stored_hum_term_is_replaced_only_by_a_larger_one():
    stored = Budget((Component("hum while driven at 50 Hz", 0.001), Component("other", 0.002)))
    larger = merged(stored, [Component("hum while driven at 50 Hz", 0.053)])
    assert [(c.name, c.value) for c in larger.components] == [
        ("other", 0.002),
        ("hum while driven at 50 Hz", 0.053),
    ]
    smaller = merged(stored, [Component("hum while driven at 50 Hz", 0.0001)])
    assert smaller.components == stored.components


def test_the_settle_test_allows_a_tone_beside_a_line_but_not_a_transient():
    """Two periods of a line with a 50.3 Hz tone beside it differ by the tone's turn; the
    tone's measured change at the line is allowed on top, a change of the line itself is not."""
    p = plan()
    _, dut = periods(lambda t: 2e-4 * np.sin(2 * np.pi * 50.3 * t), count=2)
    spectra = [period_spectrum(dut[i]) for i in (0, 1)]
    noise = np.full(4, 1e-7)
    lines = [s[p.bins] for s in spectra]
    assert not periods_agree(lines[0], lines[1], noise, 0.002)
    leak = line_leak(spectra[1] - spectra[0], p.bins)
    allowed = np.where(leak.separable, leak.leak_v, 0.0)
    assert periods_agree(lines[0], lines[1], noise, 0.002, interference=allowed)
    moved = lines[1] * np.array([1.0, 1.05, 1.0, 1.0])  # the line itself changed by 5 %
    assert not periods_agree(lines[0], moved, noise, 0.002, interference=allowed)


def test_driven_hum_object_is_plain_data():
    hum = DrivenHum(
        np.array([50.0]),
        np.array([50.5]),
        np.array([math.nan]),
        np.array([0.0]),
        np.array([True]),
        0.5,
    )
    assert not hum.affected.any() and hum.components() == [] and hum.warnings() == []
