"""Issue 25 point 2: the blocking-warnings table; each producer's real wording is classified
(texts copied from dsp.calibration, dsp.hum, dsp.multisine, app.procedure.verdict)."""

from __future__ import annotations

from pathlib import Path

import pytest

from app.records.warnings import (
    POLICY,
    SEED_RULE_WARNING,
    Policy,
    RunWarning,
    WarningKind,
    blocking,
    classify,
    incomplete_budget_warning,
    iso_over_warning,
    printed,
    table_markdown,
)
from dsp.annex_a import missing_components
from dsp.uncertainty import Budget

K = WarningKind


@pytest.mark.parametrize(
    ("text", "kind"),
    [
        ("line 160 Hz: low coherence 0.912", K.LOW_COHERENCE),
        ("line 10 Hz: DUT SNR 14.2 dB is below 20 dB", K.LOW_SNR),
        ("line 80 Hz: the DUT adds 2.3 % harmonic distortion (reference 0.1 %)", K.DUT_DISTORTION),
        (
            "nonlinear distortion of the DUT: 0.57 % of the signal (orders 2-3, measured at 23999 "
            "detection bins of this record); the best linear approximation ...",
            K.NONLINEAR_CARRIED,
        ),
        (
            "nonlinear distortion at lines 10 Hz, 12.5 Hz: the order 2-3 model does not explain "
            "the products at the detection bins (orders 4-5 add to it, p = 1e-09); ...",
            K.NONLINEAR_NOT_COVERED,
        ),
        (
            "line 50 Hz: mains hum at 50 Hz: 0.8 % of the line (reference 0.1 %, DUT 0.8 %), "
            "not separable from the line (no drive-off background): estimated from ...",
            K.HUM_NOT_SEPARABLE,
        ),
        (
            "line 50 Hz: mains hum at 50 Hz: 4.93 % of the line (reference 0.1 %, DUT 4.9 %), "
            "measured in 2 drive-off period(s); in the budget as 'mains hum at 50 Hz'",
            K.HUM_MEASURED,
        ),
        ("line 5 Hz: outside the reference certificate's range; extrapolated", K.REFERENCE_REFUSED),
        (
            "line 5 Hz: outside the reference certificate (10-5000 Hz): refused (state a ...)",
            K.REFERENCE_REFUSED,
        ),
        (
            "line 5 Hz: outside the reference certificate (10-5000 Hz): carried with the stated "
            "extrapolation term",
            K.REFERENCE_EXTRAPOLATED,
        ),
        (SEED_RULE_WARNING, K.SEED_RULE),
        ("phase not corrected for skew: the inter-channel delay is unknown", K.SKEW_NOT_CORRECTED),
        ("mounting: coherence 0.950 at 2500 Hz with both channels above 40 dB SNR", K.MOUNTING),
        ("no type B budget: the stated uncertainty is type A only", K.INCOMPLETE_BUDGET),
        ("one period only: no type A uncertainty; acquire at least 2 periods", K.NO_UNCERTAINTY),
        ("line 100 Hz: snapped to 100.5 Hz (bin 201); bin spacing 0.5 Hz", K.PLAN),
        ("something nobody foresaw", K.OTHER),
    ],
)
def test_the_producers_wording_is_classified(text, kind):
    assert classify(text).kind is kind


def test_blocking_and_printed_split_the_warnings_in_order():
    texts = [
        "line 100 Hz: snapped to 100.5 Hz (bin 201); bin spacing 0.5 Hz",
        "line 160 Hz: low coherence 0.912",
        "something nobody foresaw",
        "line 10 Hz: DUT SNR 14.2 dB is below 20 dB",
    ]
    assert [w.text for w in blocking(texts)] == [texts[1], texts[3]]
    assert [w.text for w in printed(texts)] == [texts[0], texts[2]]
    assert blocking([]) == []


def test_typed_warnings_pass_through_and_the_iso_over_one_blocks():
    over = iso_over_warning(2500.0, 0.071, 0.06)
    assert over.text == "line 2500 Hz: U = 7.1 % is over the ISO 16063-21 limit 6 %"
    assert classify(over.text).kind is K.ISO_OVER
    assert blocking([over]) == [over]
    assert printed([RunWarning(K.HUM_MEASURED, "x")]) == [RunWarning(K.HUM_MEASURED, "x")]


def test_an_incomplete_budget_blocks_and_names_the_missing_components():
    w = incomplete_budget_warning(missing_components(Budget()))
    assert blocking([w]) == [w]
    assert "magnitude: temperature (temperature)" in w.text
    assert classify(w.text).kind is K.INCOMPLETE_BUDGET


def test_the_issue_lists_these_as_blocking():
    for kind in (
        K.LOW_COHERENCE,
        K.LOW_SNR,
        K.DUT_DISTORTION,
        K.NONLINEAR_NOT_COVERED,
        K.HUM_NOT_SEPARABLE,
        K.ISO_OVER,
        K.REFERENCE_REFUSED,
        K.SEED_RULE,
        K.SKEW_NOT_CORRECTED,
        K.INCOMPLETE_BUDGET,
    ):
        assert POLICY[kind].policy is Policy.BLOCKS, kind


def test_docs_state_the_same_table():
    doc = (Path(__file__).resolve().parents[3] / "docs" / "validation.md").read_text()
    assert table_markdown() in doc


def test_budget_warning_for_the_shipped_and_an_empty_stand_budget():
    from app.records.warnings import budget_warning
    from app.stand import config

    assert budget_warning(config.load().budget) is None
    w = budget_warning(Budget())
    assert w is not None and w.kind is K.INCOMPLETE_BUDGET and w.policy is Policy.BLOCKS
