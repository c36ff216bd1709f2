"""Results object: reference chain, gains, skew, budget, verdicts, serialisation.

SPEC.md sections 2, 7 and 8.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from app.procedure.analysis import analyze
from dsp.calibration import AnalysisError, ReferenceChain, Results
from dsp.multisine import make_plan
from dsp.uncertainty import Budget, Component, Distribution, Quantity
from tests.synthetic import lowpass_response, make_recording

FREQS = [10.0, 20.0, 40.0, 80.0, 160.0, 315.0, 630.0, 1250.0, 2500.0]


@pytest.fixture(scope="module")
def plan():
    return make_plan(FREQS, 6000, 12000, 5.0, 160.0)


def test_sensitivity_scales_with_reference_chain_and_gains(plan):
    dut = lowpass_response(35.0, 200.0)
    rec = make_recording(plan, dut, periods=4, reference_sensitivity_mv_per_ms2=1.5, dut_gain=10)
    results = analyze(rec).results
    truth = dut(plan.frequencies_hz)
    got = np.array([ln.sensitivity_mv_per_ms2 for ln in results.lines])
    np.testing.assert_allclose(got, np.abs(truth), rtol=1e-9)
    phases = np.array([ln.phase_deg for ln in results.lines])
    np.testing.assert_allclose(phases, np.degrees(np.angle(truth)), atol=1e-6)
    ref = results.reference
    assert ref.frequency_hz == 160.0
    assert ref.sensitivity_mv_per_ms2 == pytest.approx(abs(dut(np.array([160.0]))[0]), rel=1e-9)
    assert ref.sensitivity_db == pytest.approx(20 * math.log10(ref.sensitivity_mv_per_ms2))
    assert results.lines[4].deviation_percent == pytest.approx(0.0, abs=1e-9)


def test_inter_channel_skew_is_removed_from_the_phase(plan):
    dut = lowpass_response(10.0, 20000.0)
    rec = make_recording(plan, dut, periods=2, skew_s=10e-6)
    results = analyze(rec).results
    phases = np.array([ln.phase_deg for ln in results.lines])
    np.testing.assert_allclose(phases, np.degrees(np.angle(dut(plan.frequencies_hz))), atol=1e-6)
    skewed = ReferenceChain.flat(1.0)  # analysed without the skew: 2500 Hz off by 9 degrees
    raw = analyze(rec.__class__(**{**rec.__dict__, "chain": skewed})).results
    assert raw.lines[-1].phase_deg - results.lines[-1].phase_deg == pytest.approx(9.0, abs=1e-6)


def test_reference_certificate_is_interpolated_in_magnitude_and_phase():
    chain = ReferenceChain((10.0, 1000.0), (1.0, 1.2), (0.0, -2.0))
    magnitude, phase = chain.sensitivity_at(np.array([100.0, 5.0, 5000.0]))
    np.testing.assert_allclose(magnitude, [1.1, 1.0, 1.2])
    np.testing.assert_allclose(phase, [-1.0, 0.0, -2.0])
    assert not chain.covers(5000.0)
    with pytest.raises(ValueError, match="increasing"):
        ReferenceChain((100.0, 10.0), (1.0, 1.0), (0.0, 0.0))
    with pytest.raises(ValueError, match="dut_gain"):
        ReferenceChain.flat(1.0, dut_gain=0.0)
    with pytest.raises(ValueError, match="unknown field"):
        ReferenceChain.from_dict({"gain": 1})


def test_budget_enters_uncertainty_and_iso_verdicts(plan):
    budget = Budget(
        (
            Component("reference calibration", 0.01, Distribution.NORMAL, coverage_factor=2),
            Component("high band", 0.05, Distribution.RECTANGULAR, min_frequency_hz=2000),
            Component("phase", 0.5, Distribution.RECTANGULAR, quantity=Quantity.PHASE),
        )
    )
    rec = make_recording(plan, lowpass_response(), periods=8, dut_noise_v=1e-4, budget=budget)
    results = analyze(rec, tolerance_percent=5.0).results
    low, high = results.lines[0], results.lines[-1]
    assert low.relative_type_b == pytest.approx(0.005)
    assert high.relative_type_b == pytest.approx(math.hypot(0.005, 0.05 / math.sqrt(3)))
    assert low.relative_expanded_uncertainty == pytest.approx(
        low.coverage_factor * math.hypot(low.relative_type_a, 0.005)
    )
    assert low.iso_verdict == "within" and high.iso_limit == 0.06 and high.iso_verdict == "within"
    assert low.phase_expanded_uncertainty_deg >= 0.5 / math.sqrt(3) * 1.9
    # a 35 mV low-pass at 200 Hz deviates hugely at 2500 Hz: a clear fail at +-5 %
    assert high.tolerance_verdict == "fail"
    # the reference line (160 Hz): deviation 0 by definition, with U 0: no statement (issue 32)
    ref = results.lines[4]
    assert ref.nominal_frequency_hz == 160.0 and ref.tolerance_verdict is None
    assert ref.deviation_percent == 0.0 and ref.deviation_expanded_percent == 0.0


def test_results_serialise_to_json_and_csv_and_back(plan):
    rec = make_recording(plan, lowpass_response(), periods=3, dut_noise_v=1e-4, seed=2)
    results = analyze(rec).results
    data = json.loads(json.dumps(results.to_dict()))
    for key in (
        "frequency_hz",
        "sensitivity_mv_per_ms2",
        "expanded_uncertainty_mv_per_ms2",
        "coverage_factor",
    ):
        assert key in data["reference"]
    for key in (
        "frequency_hz",
        "nominal_frequency_hz",
        "sensitivity_mv_per_ms2",
        "phase_deg",
        "relative_expanded_uncertainty",
        "coherence",
    ):
        assert key in data["lines"][0]
    assert Results.from_dict(data) == results
    csv_text = results.to_csv().splitlines()
    assert csv_text[0].startswith("nominal_frequency_hz,frequency_hz,sensitivity_mv_per_ms2")
    assert len(csv_text) == 1 + len(FREQS)


def test_one_period_states_no_type_a(plan):
    results = analyze(make_recording(plan, lowpass_response(), periods=1)).results
    assert math.isnan(results.reference.expanded_uncertainty_mv_per_ms2)
    assert any("one period only" in w for w in results.warnings)
    assert any("no type B budget" in w for w in results.warnings)
    assert Results.from_dict(json.loads(json.dumps(results.to_dict()))).periods == 1


def test_dead_dut_channel_is_an_analysis_error(plan):
    rec = make_recording(plan, lambda f: 0 * f + 1e-9, periods=2, dut_noise_v=1e-3)
    with pytest.raises(AnalysisError, match="DUT channel: no signal at most lines"):
        analyze(rec)


@pytest.mark.parametrize(("periods", "k", "p"), [(4, 3.182, 0.95), (12, 2.0, 0.9545)])
def test_the_seed_rule_states_the_probability_its_k_gives(plan, periods, k, p):
    """L < 10: t at 95 % with L - 1 dof; L >= 10: k = 2, which is 95.45 % of a normal
    distribution, not the 95 % the seed prints (SPEC.md section 7)."""
    rec = make_recording(plan, lowpass_response(), periods=periods, dut_noise_v=1e-4)
    results = analyze(rec, rule="seed").results
    assert results.reference.coverage_factor == pytest.approx(k, abs=5e-4)
    assert results.reference.coverage_probability == p
    assert results.coverage_probability == p
