"""Issue 32 point 5, the range edges at the dsp level: a line outside the reference's
calibrated range is not stated (no number with U in the results, JSON, CSV or the
characteristic), stored results that only warned read back the same way, the tolerance grid
keeps its end lines inside the nominal span, and a budget term can grow below f0."""

from __future__ import annotations

import csv
import dataclasses
import io
import json
import math

import numpy as np
import pytest

from app.procedure.analysis import analyze
from dsp import lpm
from dsp.calibration import AnalysisError, ReferenceChain, Results
from dsp.characteristic import characteristic
from dsp.conformity import NOT_STATED
from dsp.multisine import make_plan
from dsp.uncertainty import Component, Law
from tests.synthetic import lowpass_response, make_recording

FREQS = [10.0, 20.0, 40.0, 80.0, 160.0, 315.0, 630.0, 1250.0, 2500.0]
VALUES = (
    "sensitivity_mv_per_ms2",
    "deviation_percent",
    "phase_deg",
    "relative_expanded_uncertainty",
    "expanded_uncertainty_mv_per_ms2",
    "phase_expanded_uncertainty_deg",
    "deviation_expanded_percent",
    "coverage_factor",
)


@pytest.fixture(scope="module")
def edged() -> Results:
    """Four periods of a synthetic DUT analysed against a reference calibrated 20-1250 Hz
    only: 10 and 2500 Hz lie outside its range, with no extrapolation term."""
    plan = make_plan(FREQS, 6000, 12000, 5.0, 160.0)
    recording = make_recording(plan, lowpass_response(10.0, 2000.0), periods=4, dut_noise_v=1e-5)
    chain = ReferenceChain((20.0, 160.0, 1250.0), (1.0, 1.0, 1.0), (0.0, 0.0, 0.0))
    return analyze(dataclasses.replace(recording, chain=chain), tolerance_percent=50.0).results


def test_a_line_outside_the_reference_range_states_no_number_with_u(edged):
    outside = [ln for ln in edged.lines if ln.nominal_frequency_hz in (10.0, 2500.0)]
    inside = [ln for ln in edged.lines if ln.nominal_frequency_hz not in (10.0, 2500.0)]
    for ln in outside:
        assert not ln.stated and "outside the reference's calibrated range (20-1250 Hz)" in (
            ln.not_stated
        )
        assert all(math.isnan(getattr(ln, name)) for name in VALUES)
        assert ln.iso_verdict == NOT_STATED and ln.tolerance_verdict == NOT_STATED
        assert ln.frequency_hz == ln.nominal_frequency_hz  # where it was, not what it is
    for ln in inside:
        assert ln.stated and all(math.isfinite(getattr(ln, name)) for name in VALUES[:5])
    assert any("10 Hz: outside the reference certificate" in w for w in edged.warnings)


def test_json_csv_and_the_characteristic_carry_no_value_for_it(edged):
    data = json.loads(json.dumps(edged.to_dict()))
    first = data["lines"][0]
    assert all(first[name] is None for name in VALUES)
    assert first["not_stated"].startswith("outside the reference's calibrated range")
    rows = list(csv.DictReader(io.StringIO(edged.to_csv())))
    assert all(rows[0][name] == "" for name in VALUES) and rows[0]["not_stated"]
    assert rows[1]["sensitivity_mv_per_ms2"] != ""
    c = characteristic(edged)
    assert c.frequency_hz.tolist() == FREQS[1:-1]  # the charts draw stated lines only
    assert Results.from_dict(data).to_dict() == edged.to_dict()


def test_results_stored_with_numbers_and_a_refused_warning_read_back_not_stated(edged):
    """Results written before issue 32 kept the numbers of a line they warned "refused"."""
    data = edged.to_dict()
    data["lines"][0].update(sensitivity_mv_per_ms2=9.9, relative_expanded_uncertainty=0.01)
    del data["lines"][0]["not_stated"]
    back = Results.from_dict(data).lines[0]
    assert not back.stated and math.isnan(back.sensitivity_mv_per_ms2)
    assert "(20-1250 Hz)" in back.not_stated
    data["warnings"] = []  # no refusal stored: the numbers stand as stored
    assert Results.from_dict(data).lines[0].sensitivity_mv_per_ms2 == 9.9


def test_a_reference_frequency_outside_the_range_is_refused():
    plan = make_plan(FREQS, 6000, 12000, 5.0, 2500.0)
    recording = make_recording(plan, lowpass_response(10.0, 20000.0), periods=2)
    chain = ReferenceChain((20.0, 1250.0), (1.0, 1.0), (0.0, 0.0))
    with pytest.raises(AnalysisError, match=r"reference frequency 2500 Hz .*outside"):
        analyze(dataclasses.replace(recording, chain=chain))


def test_the_tolerance_grid_keeps_its_end_lines_inside_the_nominal_span():
    nominal = [0.4, 0.5, 0.63, 0.8, 1.0, 1.25, 1.6, 2.0, 2.5, 3.15, 4.0, 5.0, 6.3, 8.0]
    free = lpm.design_grid(nominal, 200.0, tolerance=0.02)
    assert free.frequencies_hz[0] < 0.4  # nearest bins: 0.3966 Hz, below a reference from 0.4 Hz
    held = lpm.design_grid(nominal, 200.0, tolerance=0.02, within_hz=(0.4, 8.0))
    assert 0.4 <= held.frequencies_hz[0] and held.frequencies_hz[-1] <= 8.0
    assert np.all(np.abs(np.array(held.frequencies_hz) / nominal - 1) <= 0.02)
    with pytest.raises(lpm.LpmError, match=r"inside 0\.41-8 Hz"):
        lpm.design_grid(nominal, 200.0, tolerance=0.02, max_period_s=30, within_hz=(0.41, 8))


def test_a_power_below_term_grows_below_f0_only():
    c = Component("low", 0.001, law="power-below", law_frequency_hz=2.0, law_exponent=1.0)
    assert c.law is Law.POWER_BELOW
    assert c.scale_at(0.4) == pytest.approx(5.0)
    assert c.scale_at(2.0) == 1.0 and c.scale_at(100.0) == 1.0
    assert Component.from_dict(c.to_dict()).scale_at(1.0) == pytest.approx(2.0)
