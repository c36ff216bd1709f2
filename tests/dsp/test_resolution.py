"""dsp.resolution: the converter's error at a line, its bound, dither, and the budget terms."""

from __future__ import annotations

import math

import numpy as np
import pytest

from dsp.resolution import (
    MIN_LINE_LSB,
    RESOLUTION_NAME,
    Converter,
    dithered_quantisation_lsb,
    line_resolution,
    resolution_components,
    resolution_half_width,
)
from dsp.uncertainty import Budget, Quantity


def _fundamental_error(amplitude_lsb: float, offset_lsb: float, phase: float, noise: float = 0.0):
    """Relative error of the fundamental of a quantised sine (ideal rounding), N samples of one
    cycle, noise (LSB rms) averaged over 64 periods."""
    n = 4096
    t = np.arange(n) / n
    x = amplitude_lsb * np.sin(2 * np.pi * t + phase) + offset_lsb
    rng = np.random.default_rng(0)
    periods = 64 if noise else 1
    total = np.zeros(n)
    for _ in range(periods):
        total += np.round(x + noise * rng.standard_normal(n))
    q = total / periods
    basis = np.exp(-1j * (2 * np.pi * t + phase))
    measured = 2 * np.mean(q * basis)
    return abs(measured / (-1j * amplitude_lsb) - 1)


def test_the_step_and_the_half_width_known_answers():
    assert Converter(16).step_v(0.1) == pytest.approx(0.2 / 65536)
    assert Converter(24).step_v(10.0) == pytest.approx(20 / 2**24)
    # no noise: E = 1/2 + linearity; 4 E / (pi A)
    assert resolution_half_width(10.0, 0.0, 0.5) == pytest.approx(4 * 1.0 / (math.pi * 10))
    assert resolution_half_width(100.0, 0.0, 0.0) == pytest.approx(2 / (math.pi * 100))
    assert resolution_half_width(0.0, 0.0, 0.5) == math.inf


def test_dither_shrinks_the_quantisers_deterministic_part_as_a_gaussian_does():
    assert dithered_quantisation_lsb(0.0) == 0.5
    assert dithered_quantisation_lsb(float("nan")) == 0.5
    values = [dithered_quantisation_lsb(s) for s in (0.05, 0.1, 0.2, 0.3, 0.5)]
    assert values == sorted(values, reverse=True) and values[0] <= 0.5
    # one term dominates from 0.3 LSB on: exp(-2 pi^2 s^2) / pi
    assert dithered_quantisation_lsb(0.3) == pytest.approx(
        math.exp(-2 * math.pi**2 * 0.09) / math.pi, rel=5e-3
    )
    assert dithered_quantisation_lsb(0.5) < 3e-3


@pytest.mark.parametrize("amplitude", [0.94, 3.3, 12.6, 47.0])
def test_the_bound_holds_for_an_undithered_quantiser_at_any_offset_and_phase(amplitude):
    bound = resolution_half_width(amplitude, 0.0, 0.0)
    worst = max(
        _fundamental_error(amplitude, offset, phase)
        for offset in np.linspace(-0.5, 0.5, 7)
        for phase in (0.0, 0.3, 1.1)
    )
    assert worst <= bound
    assert worst > bound / 40  # the bound is not absurdly loose at a few LSB


def test_noise_at_the_input_averages_the_quantisation_error_down():
    amplitude = 3.3
    undithered = max(_fundamental_error(amplitude, o, 0.2) for o in np.linspace(-0.5, 0.5, 7))
    dithered = max(_fundamental_error(amplitude, o, 0.2, noise=0.5) for o in (-0.3, 0.0, 0.4))
    assert dithered < undithered / 5
    assert dithered <= resolution_half_width(amplitude, 0.5, 0.0) + 3 * 0.5 / (
        amplitude * math.sqrt(64 * 4096 / 2)
    )  # what is left is the noise itself, in type A


def test_a_line_in_lsb_and_its_warning():
    converter = Converter(16, 0.5)
    line = line_resolution(0.5, "DUT", 144e-6, 0.0, 5.0, converter)
    assert line.amplitude_lsb == pytest.approx(144e-6 / (10 / 65536))  # 0.94 LSB: issue 32
    assert line.too_few_lsb
    assert "line 0.5 Hz: DUT channel 0.944 LSB on its +-5 V range (< 20 LSB)" in line.warning()
    small = line_resolution(0.5, "DUT", 144e-6, 20e-6, 0.1, converter)
    assert small.amplitude_lsb == pytest.approx(47.2, abs=0.1) and not small.too_few_lsb
    assert small.noise_lsb == pytest.approx(20e-6 / (0.2 / 65536))
    assert small.half_width == pytest.approx(resolution_half_width(47.19, 6.55, 0.5), rel=1e-3)
    assert line_resolution(
        1.0, "DUT", MIN_LINE_LSB * 10 / 65536, 0.0, 5.0, converter
    ).amplitude_lsb == (pytest.approx(MIN_LINE_LSB))


def test_converter_fields_are_checked():
    with pytest.raises(ValueError, match="bits"):
        Converter(4)
    with pytest.raises(ValueError, match="linearity_lsb"):
        Converter(16, -1.0)
    with pytest.raises(ValueError, match="range"):
        Converter().step_v(0.0)


def test_the_budget_terms_apply_at_their_line_only_and_combine_both_channels():
    converter = Converter(16, 0.5)
    ref = line_resolution(0.8, "reference", 100e-6, 0.0, 0.1, converter)
    dut = line_resolution(0.8, "DUT", 300e-6, 0.0, 0.1, converter)
    high_ref = line_resolution(8.0, "reference", 10e-3, 0.0, 0.1, converter)
    high_dut = line_resolution(8.0, "DUT", 10e-3, 0.0, 0.1, converter)
    budget = Budget(resolution_components([(ref, dut), (high_ref, high_dut)]))
    u = math.hypot(ref.half_width, dut.half_width) / math.sqrt(3)
    (magnitude,) = budget.at(0.8, Quantity.MAGNITUDE)
    (phase,) = budget.at(0.8, Quantity.PHASE)
    assert magnitude.name == f"{RESOLUTION_NAME} at 0.8 Hz"
    assert magnitude.standard_uncertainty == pytest.approx(u)
    assert phase.standard_uncertainty == pytest.approx(math.degrees(u))
    assert magnitude.kind == ()  # measured by the procedure: no Annex A kind
    assert budget.at(1.0, Quantity.MAGNITUDE) == ()
    (at_8,) = budget.at(8.0, Quantity.MAGNITUDE)
    assert at_8.standard_uncertainty < magnitude.standard_uncertainty / 20
    # no amplitude at all: capped at a 100 % half-width, never infinite
    none = line_resolution(2.0, "DUT", 0.0, 0.0, 5.0, converter)
    (capped, _) = resolution_components([(high_ref, none)])
    assert capped.standard_uncertainty == pytest.approx(1 / math.sqrt(3))
