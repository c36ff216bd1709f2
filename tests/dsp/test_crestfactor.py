"""dsp.crestfactor: synthesis (seed eq. 13), crest factor, Schroeder and optimised phases."""

from __future__ import annotations

import os
import re
import time

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dsp import crestfactor
from dsp.crestfactor import (
    crest_factor,
    optimise_phases,
    random_phases,
    schroeder_phases,
    synthesize,
)

# Seed piezo plan: fs 6000 Hz, 2 s period (0.5 Hz grid), ISO 266 lines 10 ... 2500 Hz.
# fmt: off
ISO266_10_2500 = np.array([
    10, 12.5, 16, 20, 25, 31.5, 40, 50, 63, 80, 100, 125, 160, 200, 250, 315, 400, 500, 630,
    800, 1000, 1250, 1600, 2000, 2500,
])
# fmt: on
PIEZO_N = 12000
PIEZO_BINS = np.rint(ISO266_10_2500 * PIEZO_N / 6000).astype(int)
PIEZO_AMPS = np.ones(PIEZO_BINS.size)
CPU_LIMIT_S = 4.0 if os.environ.get("CI") else 2.0  # CI machines are noisy


def direct_sum(bins, amplitudes, phases, n):
    """sum_k A_k sin(2 pi m_k i / N + phi_k), with m_k i reduced mod N in exact integers so
    that the reference itself is accurate to ~1e-15 per line."""
    i = np.arange(n)
    arg = 2 * np.pi * (np.outer(bins, i) % n) / n + np.asarray(phases)[:, None]
    return np.sum(np.asarray(amplitudes)[:, None] * np.sin(arg), axis=0)


@pytest.fixture(scope="module")
def piezo_optimised():
    """Optimised piezo phases, the process CPU time the optimisation took and the objective
    evaluations it made (computed once for the module)."""
    with pytest.MonkeyPatch.context() as patch:
        made = _counting_problems(patch)
        t0 = time.process_time()
        phases = optimise_phases(PIEZO_BINS, PIEZO_AMPS, PIEZO_N)
        cpu_s = time.process_time() - t0
    (problem,) = made
    return phases, cpu_s, problem.objective_evaluations


# --- synthesis and crest factor -------------------------------------------------------


def test_synthesize_matches_direct_sum_of_sines():
    rng = np.random.default_rng(1)
    n = 1000
    bins = rng.choice(np.arange(1, 500), size=15, replace=False)
    amplitudes = rng.uniform(0.1, 2.0, bins.size)
    phases = random_phases(bins.size, rng)
    x = synthesize(bins, amplitudes, phases, n)
    assert x.shape == (n,)
    np.testing.assert_allclose(x, direct_sum(bins, amplitudes, phases, n), rtol=0, atol=1e-12)


@settings(max_examples=30, deadline=None)
@given(
    n=st.integers(3, 400),
    data=st.data(),
)
def test_synthesize_matches_direct_sum_property(n, data):
    top = (n - 1) // 2  # largest bin below N/2
    if top < 1:
        return
    bins = data.draw(st.lists(st.integers(1, top), min_size=1, max_size=8, unique=True))
    amps = data.draw(st.lists(st.floats(0.0, 10.0), min_size=len(bins), max_size=len(bins)))
    phases = data.draw(st.lists(st.floats(-7.0, 7.0), min_size=len(bins), max_size=len(bins)))
    x = synthesize(np.array(bins), np.array(amps), np.array(phases), n)
    np.testing.assert_allclose(x, direct_sum(bins, amps, phases, n), rtol=0, atol=1e-11)


def test_crest_factor_of_a_pure_sine_is_sqrt2():
    x = synthesize(np.array([3]), np.array([2.5]), np.array([0.0]), 48)  # sample 4 is the peak
    assert crest_factor(x) == pytest.approx(np.sqrt(2.0), rel=1e-12)


def test_crest_factor_of_a_square_wave_is_one_and_zero_signal_is_refused():
    assert crest_factor(np.array([1.0, -1.0, 1.0, -1.0])) == pytest.approx(1.0)
    with pytest.raises(ValueError, match="zero"):
        crest_factor(np.zeros(8))


@pytest.mark.parametrize(
    ("bins", "n", "named"),
    [
        ([20, 25, 20], 12000, "bin 20"),  # duplicate
        ([0, 25], 12000, "bin 0"),
        ([20, 6000], 12000, "bin 6000"),  # Nyquist bin, m = N/2
        ([20, 7000], 12000, "bin 7000"),
        ([20, -3], 12000, "bin -3"),
        ([20, 12.5], 12000, "bin 12.5"),  # not an integer
    ],
)
def test_invalid_bins_raise_value_error_naming_the_bin(bins, n, named):
    b = np.array(bins)
    ones = np.ones(b.size)
    with pytest.raises(ValueError, match=re.escape(named)):
        synthesize(b, ones, np.zeros(b.size), n)
    with pytest.raises(ValueError, match=re.escape(named)):
        optimise_phases(b, ones, n)


def test_non_positive_amplitude_is_refused_by_bin():
    with pytest.raises(ValueError, match="bin 25"):
        optimise_phases(np.array([20, 25]), np.array([1.0, 0.0]), 12000)


# --- Schroeder and random phases ------------------------------------------------------


def test_schroeder_equal_amplitudes_closed_form():
    # p_l = 1/K: sum_{l<k} (k - l)/K = k (k + 1) / (2 K) for 0-based k
    k = np.arange(25)
    expected = np.mod(-np.pi * k * (k + 1) / 25, 2 * np.pi)
    got = schroeder_phases(np.ones(25))
    np.testing.assert_allclose(np.exp(1j * got), np.exp(1j * expected), atol=1e-12)


def test_schroeder_weights_lines_by_power_share():
    # two lines: phi_2 = phi_1 - 2 pi p_1 with p_1 = 9 / (9 + 1)
    got = schroeder_phases(np.array([3.0, 1.0]))
    np.testing.assert_allclose(np.exp(1j * got), np.exp(1j * np.array([0.0, -2 * np.pi * 0.9])))


def test_random_phases_are_uniform_in_0_2pi_and_reproducible():
    a = random_phases(10_000, np.random.default_rng(5))
    assert a.min() >= 0.0 and a.max() < 2 * np.pi
    assert abs(a.mean() - np.pi) < 0.05
    np.testing.assert_array_equal(a, random_phases(10_000, np.random.default_rng(5)))


def test_schroeder_beats_the_median_of_random_phases_on_the_piezo_plan():
    rng = np.random.default_rng(2024)
    random_cf = [
        crest_factor(synthesize(PIEZO_BINS, PIEZO_AMPS, random_phases(25, rng), PIEZO_N))
        for _ in range(200)
    ]
    schroeder_cf = crest_factor(
        synthesize(PIEZO_BINS, PIEZO_AMPS, schroeder_phases(PIEZO_AMPS), PIEZO_N)
    )
    assert schroeder_cf < np.median(random_cf)


# --- the Lp objective and its gradient ------------------------------------------------


@pytest.mark.parametrize("p", [4.0, 8.0, 16.0, 64.0])
def test_lp_gradient_matches_finite_differences(p):
    rng = np.random.default_rng(7)
    amplitudes = rng.uniform(0.2, 2.0, PIEZO_BINS.size)
    problem = crestfactor._LpProblem(PIEZO_BINS, amplitudes, PIEZO_N, max_evaluations=10**9)
    phases = random_phases(PIEZO_BINS.size, rng)
    _, grad = problem.lp_value_and_grad(phases, p)
    h = 1e-6
    numeric = np.array(
        [
            (
                problem.lp_value_and_grad(phases + h * e, p)[0]
                - problem.lp_value_and_grad(phases - h * e, p)[0]
            )
            / (2 * h)
            for e in np.eye(phases.size)
        ]
    )
    np.testing.assert_allclose(grad, numeric, rtol=0, atol=1e-6 * np.max(np.abs(numeric)))


def test_lp_value_is_the_log_p_mean_of_the_unit_rms_signal():
    rng = np.random.default_rng(8)
    amplitudes = rng.uniform(0.2, 2.0, PIEZO_BINS.size)
    phases = random_phases(PIEZO_BINS.size, rng)
    problem = crestfactor._LpProblem(PIEZO_BINS, amplitudes, PIEZO_N, max_evaluations=10**9)
    x = synthesize(PIEZO_BINS, amplitudes, phases, PIEZO_N)
    x /= np.sqrt(np.mean(x * x))
    for p in (4.0, 10.0):
        value, _ = problem.lp_value_and_grad(phases, p)
        assert value == pytest.approx(np.log(np.mean(np.abs(x) ** p)) / p, abs=1e-12)


def test_frequency_domain_4_norm_equals_the_fft_one_including_aliased_products():
    # N = 200: sums such as 99 + 70 pass N/2, so products of lines alias on the sample grid
    bins = np.array([30, 45, 70, 99])
    rng = np.random.default_rng(9)
    amplitudes = rng.uniform(0.5, 2.0, bins.size)
    problem = crestfactor._LpProblem(bins, amplitudes, 200, max_evaluations=10**9)
    assert problem._use_pairs
    for _ in range(5):
        phases = random_phases(bins.size, rng)
        v_fft, g_fft = problem.lp_value_and_grad(phases, 4.0)
        v_pairs, g_pairs = problem.l4_value_and_grad(phases)
        assert v_pairs == pytest.approx(v_fft, abs=1e-13)
        np.testing.assert_allclose(g_pairs, g_fft, rtol=0, atol=1e-13)


# --- optimisation ---------------------------------------------------------------------


def test_optimised_piezo_plan_meets_crest_factor_and_cpu_time(piezo_optimised):
    phases, cpu_s, _ = piezo_optimised
    assert phases.shape == (25,)
    assert np.all((phases >= 0) & (phases < 2 * np.pi))
    cf = crest_factor(synthesize(PIEZO_BINS, PIEZO_AMPS, phases, PIEZO_N))
    assert cf <= 2.5, cf
    assert cpu_s <= CPU_LIMIT_S, f"optimisation took {cpu_s:.2f} s of CPU"


def test_optimisation_is_deterministic(piezo_optimised):
    phases, _, _ = piezo_optimised
    again = optimise_phases(PIEZO_BINS, PIEZO_AMPS, PIEZO_N, seed=0)
    np.testing.assert_array_equal(again, phases)


def test_unequal_amplitudes_still_improve_on_schroeder():
    amplitudes = 10.0 / ISO266_10_2500  # 1/f
    schroeder_cf = crest_factor(
        synthesize(PIEZO_BINS, amplitudes, schroeder_phases(amplitudes), PIEZO_N)
    )
    phases = optimise_phases(PIEZO_BINS, amplitudes, PIEZO_N, seed=1)
    cf = crest_factor(synthesize(PIEZO_BINS, amplitudes, phases, PIEZO_N))
    assert cf < schroeder_cf - 0.5, (cf, schroeder_cf)


def _counting_problems(monkeypatch) -> list:
    """The _LpProblem instances optimise_phases creates from now on (to read their counts)."""
    made = []

    class Counted(crestfactor._LpProblem):
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            made.append(self)

    monkeypatch.setattr(crestfactor, "_LpProblem", Counted)
    return made


def test_the_seed_plan_stops_on_its_own_counts_well_below_the_evaluation_cap(piezo_optimised):
    evaluations = piezo_optimised[2]
    assert 1000 < evaluations < crestfactor.DEFAULT_MAX_EVALUATIONS / 2


def test_the_evaluation_cap_is_what_stops_a_short_budget_and_the_phases_stay_usable(
    monkeypatch, piezo_optimised
):
    made = _counting_problems(monkeypatch)
    t0 = time.process_time()
    phases = optimise_phases(PIEZO_BINS, PIEZO_AMPS, PIEZO_N, max_evaluations=40)
    assert time.process_time() - t0 < 0.5
    (problem,) = made
    assert problem.objective_evaluations == 40  # stopped by the count, at the count
    again = optimise_phases(PIEZO_BINS, PIEZO_AMPS, PIEZO_N, max_evaluations=40)
    np.testing.assert_array_equal(again, phases)  # a capped run is as reproducible
    assert not np.array_equal(phases, piezo_optimised[0])  # and the cap did change the work
    cf = crest_factor(synthesize(PIEZO_BINS, PIEZO_AMPS, phases, PIEZO_N))
    schroeder_cf = crest_factor(
        synthesize(PIEZO_BINS, PIEZO_AMPS, schroeder_phases(PIEZO_AMPS), PIEZO_N)
    )
    assert cf < schroeder_cf


def test_no_clock_decides_the_phases_even_one_that_jumps(monkeypatch, piezo_optimised):
    """Every clock of the time module jumps by an hour per reading (a loaded machine, a
    suspended VM, a clock step): the phases are bit-identical to an undisturbed call."""
    readings = [0]

    def jumping(*_args: object) -> float:
        readings[0] += 1
        return 3600.0 * readings[0]

    def jumping_ns(*_args: object) -> int:
        return int(jumping() * 1e9)

    for name in ("time", "monotonic", "perf_counter", "process_time", "thread_time"):
        monkeypatch.setattr(time, name, jumping)
        monkeypatch.setattr(time, name + "_ns", jumping_ns)
    phases = optimise_phases(PIEZO_BINS, PIEZO_AMPS, PIEZO_N, seed=0)
    capped = optimise_phases(PIEZO_BINS, PIEZO_AMPS, PIEZO_N, seed=0, max_evaluations=300)
    monkeypatch.undo()
    assert phases.tobytes() == piezo_optimised[0].tobytes()
    unhurried = optimise_phases(PIEZO_BINS, PIEZO_AMPS, PIEZO_N, seed=0, max_evaluations=300)
    assert capped.tobytes() == unhurried.tobytes()
    assert not hasattr(crestfactor, "time")  # the module reads no clock at all


def test_the_same_lines_at_another_level_give_bit_identical_phases(piezo_optimised):
    louder = optimise_phases(PIEZO_BINS, 7.3 * PIEZO_AMPS, PIEZO_N, seed=0)
    assert louder.tobytes() == piezo_optimised[0].tobytes()


@pytest.mark.parametrize("cap", [0, -5, 2.5, True])
def test_an_evaluation_cap_that_is_not_a_positive_count_is_refused(cap):
    with pytest.raises(ValueError, match="max_evaluations"):
        optimise_phases(PIEZO_BINS, PIEZO_AMPS, PIEZO_N, max_evaluations=cap)


def test_a_single_line_needs_no_optimisation():
    phases = optimise_phases(np.array([7]), np.array([1.0]), 100)
    assert phases.shape == (1,)
    assert crest_factor(synthesize(np.array([7]), np.ones(1), phases, 100)) == pytest.approx(
        np.sqrt(2), rel=0.05
    )
