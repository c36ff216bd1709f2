"""Issue 32 points 1 and 7 at the dsp level, known answers by hand: the CMC bands, the plausible
minimum per Annex A kind, the floor below which no conformity is stated, and a stated U never
below the CMC."""

from __future__ import annotations

import dataclasses
import math

import pytest

from app.procedure.analysis import analyze
from dsp import conformity
from dsp.annex_a import (
    ANNEX_A,
    PLAUSIBLE_MINIMUM,
    ComponentKind,
    implausible_components,
    missing_components,
    plausible_floor,
)
from dsp.cmc import Cmc, CmcBand
from dsp.conformity import Outcome
from dsp.multisine import make_plan
from dsp.uncertainty import Budget, Component, Distribution, Quantity
from tests.synthetic import lowpass_response, make_recording

FREQS = [10.0, 20.0, 40.0, 80.0, 160.0, 315.0, 630.0, 1250.0]
CMC = Cmc(
    (
        CmcBand(5.0, 100.0, 1.0, 1.0),
        CmcBand(100.0, 1000.0, 0.5, 0.4),  # shares 100 Hz with the first: the larger there
    )
)


def _gamed(value: float) -> Budget:
    """Every Annex A (kind, quantity) tagged, each component `value` (rectangular)."""
    return Budget(
        tuple(
            Component(f"{r.kind.value} ({r.quantity})", value, quantity=r.quantity, kind=r.kind)
            for r in ANNEX_A
        )
    )


def _plausible() -> Budget:
    """Each Annex A (kind, quantity) at 1.5 times its plausible minimum (standard)."""
    return Budget(
        tuple(
            Component(
                f"{r.kind.value} ({r.quantity})",
                1.5 * PLAUSIBLE_MINIMUM[r.kind],
                Distribution.STANDARD,
                quantity=r.quantity,
                kind=r.kind,
            )
            for r in ANNEX_A
        )
    )


def test_the_plausible_floor_by_hand():
    magnitude = 2 * math.sqrt(5e-4**2 + 7 * 1e-5**2 + 2 * 1e-6**2)
    phase = 2 * math.sqrt(0.02**2 + 2e-8**2 + 2 * 1e-3**2)
    assert plausible_floor("magnitude") == pytest.approx(magnitude, rel=1e-12)
    assert plausible_floor("phase") == pytest.approx(phase, rel=1e-12)
    assert plausible_floor("magnitude") == pytest.approx(0.0010014, rel=1e-4)
    with pytest.raises(ValueError, match="quantity must be"):
        plausible_floor("gain")


def test_a_budget_complete_by_tag_with_nominal_values_states_nothing_and_names_each():
    gamed = _gamed(1e-9)
    assert len(missing_components(gamed)) == len(ANNEX_A)  # none counts
    refused = implausible_components(gamed)
    assert len(refused) == len(ANNEX_A)
    assert refused[0] == (
        "'reference_calibration (magnitude)' (reference_calibration): standard uncertainty "
        "5.77e-10 (relative) is below the plausible minimum 0.0005 for its kind"
    )
    assert "degrees is below the plausible minimum 0.02" in refused[10]  # reference_phase
    assert missing_components(_plausible()) == [] and implausible_components(_plausible()) == []


def test_exactly_the_minimum_is_plausible_and_other_has_none():
    at = Component("ref", 2 * 5e-4, Distribution.NORMAL, kind="reference_calibration")
    below = dataclasses.replace(at, value=2 * 5e-4 * 0.999)
    assert implausible_components(Budget((at,))) == []
    assert len(implausible_components(Budget((below,)))) == 1
    assert implausible_components(Budget((Component("x", 0.0, kind="other"),))) == []
    assert implausible_components(Budget((Component("hum", 0.0),))) == []  # measured: no kind


def test_cmc_bands_known_answers_and_refusals():
    assert CMC.at(50.0) == CmcBand(5.0, 100.0, 1.0, 1.0)
    assert CMC.at(100.0).magnitude_percent == 1.0  # the shared edge: the larger
    assert CMC.at(1000.0).phase_deg == 0.4 and CMC.at(1000.1) is None and CMC.at(4.9) is None
    assert Cmc.from_list(CMC.to_list()) == CMC
    assert CMC.text() == "5-100 Hz: 1 %, 1°; 100-1000 Hz: 0.5 %, 0.4°"
    with pytest.raises(ValueError, match="overlap"):
        Cmc((CmcBand(5.0, 200.0, 1.0, 1.0), CmcBand(100.0, 1000.0, 0.5, 0.4)))
    no_phase = {k: v for k, v in CMC.bands[1].to_dict().items() if k != "phase_deg"}
    with pytest.raises(ValueError, match=r"cmc entry 2 of 2: missing key 'phase_deg'"):
        Cmc.from_list([CMC.bands[0].to_dict(), no_phase])
    with pytest.raises(ValueError, match=r"cmc entry 1 of 1: unknown key 'magnitude'"):
        Cmc.from_list([{**CMC.bands[0].to_dict(), "magnitude": 1.0}])
    with pytest.raises(ValueError, match=r"magnitude_percent must be finite and > 0"):
        CmcBand(5.0, 100.0, 0.0, 1.0)
    with pytest.raises(ValueError, match=r"min_frequency_hz must be below"):
        CmcBand(100.0, 5.0, 1.0, 1.0)


def test_decide_states_nothing_below_the_floor():
    assert conformity.decide(0.0, 0.05, 1.0, floor=0.1) == Outcome.NOT_STATED
    assert conformity.decide(0.0, 0.1, 1.0, floor=0.1) == Outcome.PASS  # at the floor: stated
    assert conformity.decide(0.0, 1e-16, 1.0) == Outcome.PASS  # no floor given: only U > 0
    assert conformity.decide(0.0, 1e-16, 1.0, 100 * plausible_floor("magnitude")) == (
        Outcome.NOT_STATED
    )
    assert conformity.decide(3.0, 0.5, 1.0, floor=math.nan) == Outcome.FAIL  # NaN: no floor


@pytest.fixture(scope="module")
def recording():
    plan = make_plan(FREQS, 6000, 12000, 5.0, 160.0)
    return make_recording(plan, lowpass_response(35.0, 5000.0), periods=6, dut_noise_v=1e-5)


def test_a_plausible_but_tiny_budget_states_the_cmc(recording):
    rec = dataclasses.replace(recording, budget=_plausible(), cmc=CMC)
    results = analyze(rec, tolerance_percent=5.0).results
    for ln in results.lines[:-1]:  # 10-630 Hz: inside the scope
        band = CMC.at(ln.nominal_frequency_hz)
        assert 100 * ln.relative_expanded_uncertainty == pytest.approx(band.magnitude_percent)
        assert ln.expanded_uncertainty_mv_per_ms2 == pytest.approx(
            band.magnitude_percent / 100 * ln.sensitivity_mv_per_ms2
        )
        assert ln.phase_expanded_uncertainty_deg == pytest.approx(band.phase_deg)
        assert ln.magnitude_floor_percent == band.magnitude_percent
        if ln.nominal_frequency_hz == 160.0:
            assert ln.deviation_expanded_percent == 0.0 and ln.tolerance_verdict is None
            assert ln.cmc_bounds == "U, phase U"
        else:
            least = band.magnitude_percent * (1 + ln.deviation_percent / 100)
            assert ln.deviation_expanded_percent == pytest.approx(least)
            assert ln.cmc_bounds == "U, phase U, U of the deviation"
            assert ln.tolerance_verdict == "pass"
    outside = results.lines[-1]  # 1250 Hz: no CMC there, its U the budget's (above the floor)
    assert outside.cmc_bounds == "" and 100 * outside.relative_expanded_uncertainty < 0.5
    assert outside.magnitude_floor_percent == pytest.approx(100 * plausible_floor("magnitude"))
    assert outside.relative_expanded_uncertainty > plausible_floor("magnitude")
    assert "no CMC at 1250 Hz: outside the laboratory's scope" in " ".join(results.warnings)
    assert results.verdict != "PASS"
    assert results.cmc == tuple(CMC.to_list())


def test_without_a_cmc_type_a_only_is_no_conformity_statement(recording):
    """The issue's case: no budget, quiet periods: U of a few 1e-4 % is rounding-level; no line
    is ISO "within" or tolerance "pass", and the run is blocked by the missing CMC too."""
    results = analyze(recording, tolerance_percent=5.0).results
    assert all(
        ln.relative_expanded_uncertainty < plausible_floor("magnitude") for ln in results.lines
    )
    assert {ln.iso_verdict for ln in results.lines} == {"not stated"}
    assert {ln.tolerance_verdict for ln in results.lines} == {"not stated", None}
    assert any(w.startswith("no CMC: results for review only") for w in results.warnings)
    assert results.cmc == () and results.verdict == "INDETERMINATE"


def test_a_component_of_several_kinds_or_implausible_is_blocking_in_a_stored_budget(recording):
    two = Component("DAQ", 0.0015, kind=[ComponentKind.DAQ_GAIN, ComponentKind.DAQ_LINEARITY])
    budget = Budget((*_plausible().components, two))
    rec = dataclasses.replace(recording, budget=budget, cmc=CMC)
    results = analyze(rec, tolerance_percent=5.0).results
    (text,) = [w for w in results.warnings if w.startswith("implausible budget")]
    assert "'DAQ' is tagged with several kinds (daq_gain, daq_linearity)" in text
    assert results.verdict != "PASS"
    assert any("(implausible budget)" in r for r in results.verdict_reasons)


def test_a_u_above_the_cmc_is_kept_and_only_what_it_bounds_is_named(recording):
    budget = Budget(
        (
            *_plausible().components,
            Component("phase of the conditioning", 2.0, quantity=Quantity.PHASE, kind="other"),
        )
    )
    rec = dataclasses.replace(recording, budget=budget, cmc=CMC)
    ln = analyze(rec).results.lines[1]  # 20 Hz: CMC 1 %, 1 degree
    u_b = budget.type_b(ln.frequency_hz, Quantity.PHASE)[0]  # about 2 / sqrt(3) degrees
    assert ln.phase_expanded_uncertainty_deg == pytest.approx(2 * u_b, rel=0.01)
    assert ln.phase_expanded_uncertainty_deg > 1.0
    assert ln.cmc_bounds == "U, U of the deviation"  # the phase U is its own, above the CMC
