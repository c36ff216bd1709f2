"""Issue 25 points 1 and 3: the Annex A table, per-line laws, the skew's phase term, the
reference's calibrated range; expected values by hand."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from app.stand import config
from dsp.annex_a import ANNEX_A, ComponentKind, implausible_components, missing_components
from dsp.budget_terms import reference_range, skew_phase_component
from dsp.uncertainty import Budget, Component, Law, Quantity, combine

ROOT = Path(__file__).resolve().parents[2]


def test_an_empty_budget_misses_every_annex_a_component():
    missing = missing_components(Budget())
    assert len(missing) == len(ANNEX_A) == 14
    assert "magnitude: temperature (temperature)" in missing
    assert "phase: channel skew (sampling delay) uncertainty (skew)" in missing


def test_untagged_terms_do_not_count_and_a_magnitude_term_says_nothing_of_phase():
    budget = Budget(
        (
            Component("mains hum at 50 Hz", 0.05),  # measured term: no kind
            Component("temperature", 0.001, kind="temperature"),
        )
    )
    missing = missing_components(budget)
    assert "magnitude: temperature (temperature)" not in missing
    assert len(missing) == 13
    phase_only = Budget((Component("amp", 0.1, quantity=Quantity.PHASE, kind="amplifier_gain"),))
    assert "magnitude: conditioning amplifier gains (amplifier_gain)" in missing_components(
        phase_only
    )


def test_a_component_tagged_with_several_kinds_states_none_of_them_and_is_named():
    """Issue 32 point 1 (it reversed issue 25's rule): one value cannot stand for several
    independent effects; a stored one still reads back (old records), but counts for none."""
    c = Component("DAQ", 0.0015, kind=["daq_gain", "daq_linearity"])
    assert c.kind == (ComponentKind.DAQ_GAIN, ComponentKind.DAQ_LINEARITY)
    missing = missing_components(Budget((c,)))
    assert "magnitude: DAQ gain (daq_gain)" in missing
    assert "magnitude: DAQ linearity (daq_linearity)" in missing
    assert implausible_components(Budget((c,))) == [
        "'DAQ' is tagged with several kinds (daq_gain, daq_linearity): one component per kind"
    ]
    assert Component.from_dict(c.to_dict()) == c


def test_an_unknown_kind_is_refused_naming_the_field():
    with pytest.raises(ValueError, match=r"component 'x': kind must be one of .*got 'tempreture'"):
        Component("x", 0.1, kind="tempreture")


def test_old_records_keep_their_keys():
    assert set(Component("x", 0.1).to_dict()) == {
        "name",
        "value",
        "distribution",
        "coverage_factor",
        "dof",
        "quantity",
        "min_frequency_hz",
        "max_frequency_hz",
        "note",
    }


@pytest.mark.parametrize(
    ("law", "f", "factor"),
    [
        (Law.POWER_ABOVE, 1000.0, 1.0),  # below f0: the stated value
        (Law.POWER_ABOVE, 2000.0, 1.0),
        (Law.POWER_ABOVE, 5000.0, 6.25),  # (5/2)^2
        (Law.POWER, 1000.0, 0.25),  # (1/2)^2 below f0 too
        (Law.POWER, 8000.0, 16.0),
    ],
)
def test_frequency_laws(law, f, factor):
    c = Component("t", 0.003, law=law, law_frequency_hz=2000.0, law_exponent=2.0)
    assert c.standard_uncertainty_at(f) == pytest.approx(0.003 / math.sqrt(3) * factor)
    assert Component.from_dict(c.to_dict()) == c


def test_combine_uses_the_law_at_the_line():
    c = Component("t", 0.003, law="power-above", law_frequency_hz=2000.0, law_exponent=1.0)
    at_4k = combine(0.0, math.inf, Budget((c,)), 4000.0)
    assert at_4k.type_b == pytest.approx(0.006 / math.sqrt(3))
    assert combine(0.0, math.inf, Budget((c,)), 100.0).type_b == pytest.approx(0.003 / math.sqrt(3))


def test_a_law_needs_its_frequency_and_a_constant_has_none():
    with pytest.raises(ValueError, match="law 'power' needs law_frequency_hz"):
        Component("t", 0.1, law="power", law_exponent=1.0)
    with pytest.raises(ValueError, match="law_frequency_hz/law_exponent need law"):
        Component("t", 0.1, law_frequency_hz=100.0)
    with pytest.raises(ValueError, match="law_exponent must be between 0 and 4"):
        Component("t", 0.1, law="power", law_frequency_hz=1.0, law_exponent=9.0)


def test_skew_phase_term_is_360_f_tau_degrees():
    c = skew_phase_component(1e-7)  # rectangular half-width 0.1 us
    # at 5 kHz: 360 * 5000 * 1e-7 = 0.18 deg half-width, u = 0.18 / sqrt 3
    assert c.standard_uncertainty_at(5000.0) == pytest.approx(0.18 / math.sqrt(3))
    assert c.standard_uncertainty_at(10.0) == pytest.approx(0.00036 / math.sqrt(3))
    assert c.quantity is Quantity.PHASE and c.kind == (ComponentKind.SKEW,)
    with pytest.raises(ValueError, match="between 0 and 1 ms"):
        skew_phase_component(-1e-9)


def test_lines_outside_the_reference_certificate_are_refused_by_default():
    r = reference_range([5.0, 10.0, 5000.0, 8000.0], [10.0, 20.0, 5000.0], Budget())
    assert r.refused == (True, False, False, True)
    assert r.inside == (False, True, True, False)
    assert "refused" in r.messages([5.0, 10.0, 5000.0, 8000.0], 10.0, 5000.0)[0]


def test_a_stated_extrapolation_term_carries_the_line_where_it_applies():
    kind = "reference_extrapolation"
    budget = Budget(
        (
            Component("extra mag", 0.01, kind=kind, max_frequency_hz=10.0),
            Component("extra phase", 1.0, kind=kind, quantity="phase", max_frequency_hz=10.0),
        )
    )
    r = reference_range([5.0, 8000.0], [10.0, 5000.0], budget)
    assert r.extrapolated == (True, False)
    assert r.refused == (False, True)
    magnitude_only = Budget(budget.components[:1])
    assert reference_range([5.0], [10.0, 5000.0], magnitude_only).refused == (True,)


@pytest.mark.parametrize("path", [None, ROOT / "examples" / "stand-pxi6251.toml"])
def test_the_shipped_stand_files_state_a_full_budget(path):
    stand = config.load(path)
    assert stand.missing_components() == []
    skew = [c for c in stand.budget.components if ComponentKind.SKEW in c.kind]
    assert len(skew) == 1


def test_a_stand_file_without_components_is_missing_all_of_them():
    text = (ROOT / "sim" / "stand.toml").read_text()
    head = text.split("[[component]]")[0]
    head = head.replace("skew_tolerance_s = 1e-7", "")
    stand = config.parse(head, "bare.toml")
    assert len(stand.missing_components()) == len(ANNEX_A)


def test_a_stand_file_without_components_but_its_skew_tolerance_misses_13():
    """docs/validation.md (issue 32 point 8): the shipped stand file without its components
    still states the skew entry through daq.skew_tolerance_s: 13 of the 14 missing."""
    text = (ROOT / "sim" / "stand.toml").read_text()
    assert "skew_tolerance_s = 1e-7" in text
    stand = config.parse(text.split("[[component]]")[0], "bare.toml")
    missing = stand.missing_components()
    assert len(missing) == len(ANNEX_A) - 1 == 13
    assert not any("(skew)" in m for m in missing)


def test_a_bad_skew_tolerance_names_the_field():
    text = (
        (ROOT / "sim" / "stand.toml")
        .read_text()
        .replace("skew_tolerance_s = 1e-7", "skew_tolerance_s = 0.5")
    )
    with pytest.raises(config.ConfigError, match=r"daq\.skew_tolerance_s: must be between"):
        config.parse(text, "bad.toml")
