"""app.io.reference_dcc on DCCs written by hand to the PTB DCC 3.3.0 schema (tests/data/refdcc):
the shapes calibrating laboratories use read to the same table in the records' units, the
malformed refused naming the element and the reason, the signature verified or refused."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from app.errors import Refusal
from app.io.dcc_signature import SignatureState
from app.io.dsi_units import Kind, parse_unit
from app.io.reference_dcc import ReferenceDccError, parse_reference_dcc, read_reference_dcc

DATA = Path(__file__).parents[2] / "data" / "refdcc"
RESULT = (
    "/dcc:digitalCalibrationCertificate/dcc:measurementResults/dcc:measurementResult/"
    "dcc:results/dcc:result"
)


def test_parallel_lists_in_mv_and_degrees_are_read_with_identity_dates_and_item() -> None:
    dcc = read_reference_dcc(DATA / "lists_mv_degree.xml")
    assert dcc.unique_identifier == "NMI-VIB-2026-0412"
    assert dcc.laboratory == "National Vibration Laboratory (DKD-K-99001)"
    assert (dcc.manufacturer, dcc.model, dcc.serial) == ("Brüel & Kjær", "8305-001", "SIM-0001")
    assert (str(dcc.begin_date), str(dcc.calibration_date), str(dcc.issue_date)) == (
        "2026-03-02",
        "2026-03-04",
        "2026-03-06",
    )
    assert [p.frequency_hz for p in dcc.points] == [10, 80, 160, 1000, 10000]
    assert [p.sensitivity_mv_per_ms2 for p in dcc.points] == [1.0051, 1.0, 0.9998, 1.0004, 1.017]
    assert [p.phase_deg for p in dcc.points] == [-0.1, -0.05, 0.0, 0.1, 0.4]
    assert [p.phase_expanded_uncertainty_deg for p in dcc.points] == [0.2] * 5  # one for all
    assert [p.coverage_factor for p in dcc.points] == [2.0] * 5
    assert dcc.points[1].relative_expanded_uncertainty == pytest.approx(0.004)
    assert dcc.points[4].relative_expanded_uncertainty == pytest.approx(0.012 / 1.017)
    assert dcc.table()[1] == (80.0, 1.0, pytest.approx(0.004), -0.05)
    assert not dcc.charge and dcc.signature.state is SignatureState.UNSIGNED
    assert dcc.signature.line() == "unsigned"
    assert len(dcc.sha256) == 64 and dcc.content == (DATA / "lists_mv_degree.xml").read_bytes()


def test_a_list_per_point_in_pc_per_ms2_radians_and_k_2_2_is_kept_at_k_2() -> None:
    dcc = read_reference_dcc(DATA / "points_pc_radian.xml")
    assert dcc.charge and dcc.sensitivity_unit == r"\pico\coulomb\per\metre\second\tothe{-2}"
    assert [p.frequency_hz for p in dcc.points] == [40, 160, 1000]
    assert [p.sensitivity_mv_per_ms2 for p in dcc.points] == [1.012, 1.01, 1.0105]  # 1 mV/pC
    assert [p.coverage_factor for p in dcc.points] == [2.2] * 3
    # U 0.0055 pC/(m/s^2) at k = 2.2: u = 0.0025, kept as 2u relative
    assert dcc.points[1].relative_expanded_uncertainty == pytest.approx(0.0055 / 2.2 * 2 / 1.01)
    assert dcc.points[2].phase_deg == pytest.approx(math.degrees(0.0035))
    assert dcc.points[0].phase_expanded_uncertainty_deg == pytest.approx(math.degrees(0.0035))
    assert dcc.serial == "2291017" and dcc.model == "4371"


def test_hybrid_lists_in_khz_with_a_coverage_interval_and_a_ratio_beside() -> None:
    dcc = read_reference_dcc(DATA / "hybrid_interval_khz.xml")
    assert [p.frequency_hz for p in dcc.points] == [160, 500, 1000, 2000]
    assert [p.sensitivity_mv_per_ms2 for p in dcc.points] == [10.02, 10.05, 10.11, 10.30]
    assert [p.coverage_factor for p in dcc.points] == [None] * 4  # an interval states no k
    # the interval's half-width: (10.40 - 10.20) / 2 at 2 kHz
    assert dcc.points[3].expanded_uncertainty_mv_per_ms2 == pytest.approx(0.10)
    assert dcc.points[3].relative_expanded_uncertainty == pytest.approx(0.10 / 10.30)
    assert [p.phase_deg for p in dcc.points] == [-0.3, -0.2, -0.5, -1.1]
    assert dcc.points[0].phase_expanded_uncertainty_deg is None
    assert dcc.manufacturer == "Metra Mess- und Frequenztechnik"


@pytest.mark.parametrize(
    ("name", "where", "why"),
    [
        (
            "bad_missing_u.xml",
            f"{RESULT}/dcc:data/dcc:list/dcc:quantity[2]: ",
            "a sensitivity without its expanded uncertainty",
        ),
        (
            "bad_wrong_unit.xml",
            f"{RESULT}/dcc:data/dcc:list/dcc:quantity[2]/si:realListXMLList/si:unitXMLList: ",
            "unit '\\metre\\second\\tothe{-2}' of quantity 'Sensitivity magnitude' is not a "
            "sensitivity",
        ),
        (
            "bad_no_frequency.xml",
            f"{RESULT}: ",
            "a sensitivity table without frequencies",
        ),
        (
            "bad_not_vibration.xml",
            "/dcc:digitalCalibrationCertificate/dcc:administrativeData/dcc:items/dcc:item: ",
            "'Pt100 resistance thermometer' is not a vibration transducer calibration",
        ),
        (
            "bad_schema.xml",
            "/dcc:digitalCalibrationCertificate/dcc:administrativeData/dcc:coreData: ",
            "not valid against the DCC schema 3.3.0: Unexpected child with tag "
            "'dcc:performanceLocation'",
        ),
    ],
)
def test_a_malformed_dcc_is_refused_naming_the_element_and_why(
    name: str, where: str, why: str
) -> None:
    with pytest.raises(ReferenceDccError) as refused:
        read_reference_dcc(DATA / name)
    message = str(refused.value)
    assert isinstance(refused.value, Refusal)
    assert message.startswith(f"--dcc: {DATA / name}: {where}{why}"), message


def _lists() -> str:
    return (DATA / "lists_mv_degree.xml").read_text(encoding="utf-8")


@pytest.mark.parametrize(
    ("old", "new", "why"),
    [
        ("<dcc:", "<x:", "not well-formed XML"),  # an unbound prefix
        (
            'xmlns:dcc="https://ptb.de/dcc"',
            'xmlns:dcc="https://example.org/dcc"',
            "the root is not dcc:digitalCalibrationCertificate",
        ),
        (
            "<si:valueXMLList>10 80 160 1000 10000</si:valueXMLList>",
            "<si:valueXMLList>10 160 80 1000 10000</si:valueXMLList>",
            "frequencies must increase (80 Hz after 160 Hz)",
        ),
        (
            "<si:valueXMLList>10 80 160 1000 10000</si:valueXMLList>",
            "<si:valueXMLList>10 80 160 1000</si:valueXMLList>",
            "4 frequencies but 5 sensitivities",
        ),
        (
            "<si:coverageFactorXMLList>2</si:coverageFactorXMLList>",
            "<si:coverageFactorXMLList>2 2</si:coverageFactorXMLList>",
            "2 values for 5 points",
        ),
        (
            "<si:unitXMLList>\\degree</si:unitXMLList>",
            "<si:unitXMLList>\\volt</si:unitXMLList>",
            "unit '\\volt' of quantity 'Phase' is not an angle",
        ),
        (
            "Complex voltage sensitivity",
            "Complex voltage sensitivity",
            None,  # control: the file as written is accepted
        ),
    ],
)
def test_edits_of_a_good_dcc_are_refused_by_name(old: str, new: str, why: str | None) -> None:
    text = _lists()
    assert old in text
    data = text.replace(old, new, 1).encode("utf-8")
    if why is None:
        assert len(parse_reference_dcc(data, "f").points) == 5
        return
    with pytest.raises(ReferenceDccError, match=r"^f: ") as refused:
        parse_reference_dcc(data, "f")
    assert why in str(refused.value)


def test_a_doctype_with_entities_is_refused_before_anything_is_expanded() -> None:
    bomb = (
        _lists()
        .replace(
            "<dcc:digitalCalibrationCertificate",
            '<!DOCTYPE d [<!ENTITY a "aaaaaaaaaa"><!ENTITY b "&a;&a;&a;&a;&a;&a;&a;&a;&a;&a;">]>\n'
            "<dcc:digitalCalibrationCertificate",
            1,
        )
        .replace("Dr. A. Prüfer", "&b;")
    )
    with pytest.raises(ReferenceDccError) as refused:
        parse_reference_dcc(bomb.encode("utf-8"), "f")
    assert str(refused.value) == "f: a DOCTYPE (DTD) is not allowed in a DCC"


def test_a_dcc_without_any_sensitivity_is_refused_as_having_no_table() -> None:
    text = (
        _lists()
        .replace("\\milli\\volt\\second\\tothe{2}\\metre\\tothe{-1}", "\\percent")
        .replace("Sensitivity magnitude", "Relative deviation")
    )
    with pytest.raises(ReferenceDccError) as refused:
        parse_reference_dcc(text.encode(), "f")
    assert str(refused.value) == (
        "f: /dcc:digitalCalibrationCertificate/dcc:measurementResults: no sensitivity table (no "
        "quantity in V or pC per m/s^2 in any dcc:result)"
    )


# ---- the signature -----------------------------------------------------------------------


def test_a_signed_dcc_is_verified_against_its_embedded_or_the_given_certificate() -> None:
    embedded = read_reference_dcc(DATA / "signed.xml")
    assert embedded.signature.state is SignatureState.VERIFIED
    assert embedded.signature.line() == (
        "signed by DCC signing, National Vibration Laboratory, verified against the "
        "certificate it embeds, not checked against a trust anchor"
    )
    given = read_reference_dcc(DATA / "signed.xml", certificate=DATA / "signer.pem")
    assert given.signature.line() == (
        "signed by DCC signing, National Vibration Laboratory, verified against the given "
        "certificate"
    )
    assert given.table() == read_reference_dcc(DATA / "lists_mv_degree.xml").table()


def test_a_signed_dcc_changed_by_one_digit_or_checked_against_another_key_is_refused() -> None:
    signed = (DATA / "signed.xml").read_bytes()
    assert signed.count(b"1.0004") == 1
    with pytest.raises(ReferenceDccError) as changed:
        parse_reference_dcc(signed.replace(b"1.0004", b"1.0005"), "f")
    assert str(changed.value).startswith(
        "f: /dcc:digitalCalibrationCertificate/ds:Signature: the signature does not verify"
    )
    with pytest.raises(ReferenceDccError) as other:
        read_reference_dcc(DATA / "signed.xml", certificate=DATA / "other.pem")
    assert "ds:Signature: the signature does not verify" in str(other.value)
    with pytest.raises(ReferenceDccError) as unsigned:
        read_reference_dcc(DATA / "lists_mv_degree.xml", certificate=DATA / "signer.pem")
    assert "a signer's certificate was given but the DCC is unsigned" in str(unsigned.value)


def test_a_file_that_is_not_there_is_refused_by_option(tmp_path: Path) -> None:
    with pytest.raises(ReferenceDccError, match=r"^--dcc: "):
        read_reference_dcc(tmp_path / "missing.xml")


# ---- units -------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("text", "kind", "per_mv"),
    [
        (r"\milli\volt\second\tothe{2}\metre\tothe{-1}", Kind.VOLTAGE_SENSITIVITY, 1.0),
        (r"\milli\volt\metre\tothe{-1}\second\tothe{2}", Kind.VOLTAGE_SENSITIVITY, 1.0),
        (r"\volt\per\metre\second\tothe{-2}", Kind.VOLTAGE_SENSITIVITY, 1000.0),
        (r"\pico\coulomb\per\metre\second\tothe{-2}", Kind.CHARGE_SENSITIVITY, 1.0),
        (r"\pico\coulomb\second\tothe{2}\metre\tothe{-1}", Kind.CHARGE_SENSITIVITY, 1.0),
        ("mV/(m/s^2)", Kind.VOLTAGE_SENSITIVITY, 1.0),
        ("mV/(m/s²)", Kind.VOLTAGE_SENSITIVITY, 1.0),
        ("pC/(m/s2)", Kind.CHARGE_SENSITIVITY, 1.0),
        ("mV/g", Kind.VOLTAGE_SENSITIVITY, 1 / 9.80665),
    ],
)
def test_sensitivity_units_in_d_si_and_common_spellings(
    text: str, kind: Kind, per_mv: float
) -> None:
    unit = parse_unit(text)
    assert unit is not None and unit.kind is kind
    assert unit.to_mv_per_ms2(1.0) == pytest.approx(per_mv, rel=1e-12)


@pytest.mark.parametrize(
    ("text", "kind"),
    [
        (r"\hertz", Kind.FREQUENCY),
        (r"\kilo\hertz", Kind.FREQUENCY),
        (r"\degree", Kind.ANGLE),
        (r"\radian", Kind.ANGLE),
        (r"\metre\second\tothe{-2}", Kind.OTHER),  # an acceleration
        (r"\volt\metre\tothe{-1}\second\tothe{-2}", Kind.OTHER),  # V per (m s^2): not one
        (r"\volt\per\metre\per\second\tothe{2}", Kind.OTHER),
        (r"\percent", Kind.OTHER),
    ],
)
def test_other_units_are_told_apart(text: str, kind: Kind) -> None:
    unit = parse_unit(text)
    assert unit is not None and unit.kind is kind


@pytest.mark.parametrize("text", ["", r"\milli", r"\furlong", r"\volt\tothe{x}", "V per g", "mV/s"])
def test_unknown_units_are_none(text: str) -> None:
    assert parse_unit(text) is None
