"""app.procedure.ranging: the input ranges a run picks, per run and per line, and what the
preflight and the warnings policy make of a line too few LSB above the converter's step."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from app.procedure.preflight import check_preflight
from app.procedure.ranging import (
    PREDICTED_HEADROOM,
    per_sample_noise_v,
    plan_ranges,
    with_ranges,
)
from app.records.warnings import WarningKind, blocking, classify
from app.stand import config as stand_config
from dsp.calibration import ReferenceChain
from dsp.multisine import make_plan
from dsp.resolution import Converter
from hardware.interfaces import choose_range

CONFIG = stand_config.load()
OFFERED = CONFIG.input_ranges_v
# the simulated reference: 1 mV/(m/s^2) flat, conditioning gain 10
CHAIN = ReferenceChain((0.4, 20000.0), (1.0, 1.0), (0.0, 0.0), reference_gain=10.0)


def _plan(freqs=(0.5, 2.0, 8.0), amplitudes=(0.02, 0.3, 5.0)):
    return make_plan(list(freqs), 1000.0, 40000, list(amplitudes), 8.0, optimiser=None)


def test_the_shipped_stand_states_the_ranges_its_converter_offers():
    assert OFFERED == (0.1, 0.2, 0.5, 1.0, 2.0, 5.0, 10.0)
    assert CONFIG.converter == Converter(16, 0.5)


def test_choose_range_is_the_smallest_that_holds_the_peak_with_headroom():
    assert choose_range(0.039, OFFERED, 2.5) == 0.1
    assert choose_range(0.041, OFFERED, 2.5) == 0.2
    assert choose_range(3.0, OFFERED, 1.5) == 5.0
    assert choose_range(9.0, OFFERED, 1.5) is None


def test_stepped_sine_picks_per_line_and_keeps_under_each_channels_range_v():
    plan = _plan()
    ranges = plan_ranges(plan, CONFIG, CHAIN, 10.2, OFFERED, per_line=True)
    amplitudes = plan.amplitudes_ms2
    # reference: 10 mV/(m/s^2) at the DAQ; DUT: its nominal 10.2 mV/(m/s^2)
    assert ranges.reference_amplitude_v == pytest.approx(tuple(amplitudes * 10e-3))
    assert ranges.dut_v == (0.1, 0.1, choose_range(5.0 * 10.2e-3, OFFERED, PREDICTED_HEADROOM))
    assert ranges.dut_v[2] == 0.2
    assert ranges.ranges_at(2) == {"reference": ranges.reference_v[2], "dut": 0.2}
    assert ranges.run_ranges["dut"] == 0.2  # the background's: the largest of the lines
    # a level far above: the largest range the stand file allows, never above it
    loud = plan_ranges(plan, CONFIG, CHAIN, 10.2, OFFERED, per_line=True, level_scale=300)
    assert max(loud.dut_v) == 5.0 and max(loud.reference_v) == 1.0


def test_a_multisine_picks_one_range_per_channel_from_the_whole_plans_peak():
    plan = _plan()
    ranges = plan_ranges(plan, CONFIG, CHAIN, 10.2, OFFERED, per_line=False)
    peak = plan.predicted_peaks().acceleration_ms2
    assert len(set(ranges.dut_v)) == 1 and len(set(ranges.reference_v)) == 1
    assert ranges.dut_v[0] == choose_range(peak * 10.2e-3, OFFERED, PREDICTED_HEADROOM)


def test_without_a_nominal_or_a_list_the_channels_keep_their_range_v():
    plan = _plan()
    unknown = plan_ranges(plan, CONFIG, CHAIN, None, OFFERED, per_line=True)
    assert unknown.dut_v == (5.0,) * 3 and unknown.chosen and unknown.dut_amplitude_v is None
    fixed = plan_ranges(plan, CONFIG, CHAIN, 10.2, (), per_line=True)
    assert fixed.dut_v == (5.0,) * 3 and fixed.reference_v == (1.0,) * 3 and not fixed.chosen


def test_a_line_is_re_ranged_down_from_its_measured_amplitude_and_the_next_predicted():
    plan = _plan()
    ranges = plan_ranges(plan, CONFIG, CHAIN, None, OFFERED, per_line=True)
    current = ranges.ranges_at(0)
    assert current["dut"] == 5.0
    smaller = ranges.re_ranged({"reference": 200e-6, "dut": 144e-6}, current)
    assert smaller == {"reference": current["reference"], "dut": 0.1}
    assert ranges.re_ranged({"reference": 200e-6, "dut": 144e-6}, smaller) is None
    # never up: a line measured larger than its range holds is not re-ranged here
    assert ranges.re_ranged({"reference": 1e-4, "dut": 0.09}, {**current, "dut": 0.1}) is None
    # nor when it is over 2000 LSB where it is (a second measurement buys little)
    loud = {"reference": 0.3, "dut": 0.5}
    assert ranges.re_ranged(loud, {"reference": 1.0, "dut": 5.0}) is None
    # the next line's DUT range from the ratio the last line measured (V/V)
    ratio = 0.7  # the piezo's high-pass below 1 Hz
    k = 2
    expected = choose_range(ranges.reference_amplitude_v[k] * ratio, OFFERED, PREDICTED_HEADROOM)
    assert ranges.from_ratio(k, ratio)["dut"] == expected
    known = plan_ranges(plan, CONFIG, CHAIN, 10.2, OFFERED, per_line=True)
    assert known.from_ratio(k, 100.0) == known.ranges_at(k)  # the nominal's prediction stands


def test_the_preflight_report_shows_the_ranges_and_the_lines_too_few_lsb():
    plan = _plan(amplitudes=(0.0005, 0.3, 5.0))
    report = check_preflight(plan, CONFIG, CHAIN, 10.2, offered_v=OFFERED, per_line=True)
    assert report.ok
    text = report.ranges_text()
    assert text.startswith("input ranges chosen from the predicted peaks: reference")
    assert "fewest LSB per line: reference" in text and "DUT" in text
    assert text in report.summary()
    (ref_warning, dut_warning) = report.resolution_warnings
    assert ref_warning.startswith("predicted: line 0.5 Hz: reference channel")
    assert "DUT channel" in dut_warning
    # before a stand is opened (no chain): the reference is not predicted, nothing invented
    preview = check_preflight(plan, CONFIG, None, None, per_line=True)
    assert "fewest LSB" not in preview.ranges_text()
    assert preview.resolution_warnings == ()


def test_a_line_too_few_lsb_blocks_pass_and_the_prediction_is_only_logged():
    text = (
        "line 0.5 Hz: DUT channel 9.24 LSB on its +-0.1 V range (< 20 LSB): resolution not "
        "stated; raise the level or use a smaller input range"
    )
    assert classify(text).kind is WarningKind.ADC_RESOLUTION
    assert [w.kind for w in blocking([text])] == [WarningKind.ADC_RESOLUTION]


def test_per_sample_noise_from_a_lines_per_period_noise_less_the_quantisation():
    rng = np.random.default_rng(3)
    n, sigma = 4000, 1e-4
    carrier = np.exp(-2j * np.pi * 7 * np.arange(n) / n)
    spectra = [2 / n * np.sum(sigma * rng.standard_normal(n) * carrier) for _ in range(400)]
    noise_per_period = np.sqrt(np.var(spectra))
    assert per_sample_noise_v(float(noise_per_period), n, 0.0) == pytest.approx(sigma, rel=0.1)
    step = 1e-4
    assert per_sample_noise_v(float(noise_per_period), n, step) < sigma
    assert per_sample_noise_v(0.99 * step / np.sqrt(12) * 2 / np.sqrt(n), n, step) == 0.0
    assert per_sample_noise_v(float("nan"), n, step) == 0.0


def test_with_ranges_replaces_only_the_named_channels():
    inputs = with_ranges(CONFIG.inputs, {"dut": 0.1})
    by_name = {c.name: c for c in inputs}
    assert by_name["dut"].range_v == 0.1
    assert by_name["dut"] == dataclasses.replace(
        next(c for c in CONFIG.inputs if c.name == "dut"), range_v=0.1
    )
    assert by_name["reference"].range_v == 1.0
