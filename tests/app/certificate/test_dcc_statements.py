"""Each point's conformity in the DCC (issue 35 point 3): the run's outcomes as DCC 3.3.0's
statuses, fail and inconclusive points included (the session's run passes everywhere)."""

from __future__ import annotations

import dataclasses
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from app.certificate import dcc
from app.certificate import dcc_statements as decisions
from app.certificate.dcc import DCC_NS, SI_NS
from app.certificate.load import load_stored_run

NS = {"dcc": DCC_NS, "si": SI_NS}


def test_the_vocabulary_is_the_dcc_writers() -> None:
    for name in ("DCC_NS", "SI_NS", "REF_FREQUENCY", "UNIT_HZ", "UNIT_PERCENT"):
        assert getattr(decisions, name) == getattr(dcc, name), name


@pytest.mark.parametrize(
    ("outcome", "deviation", "status"),
    [
        ("pass", 1.0, "pass"),
        ("fail", 7.0, "fail"),
        ("inconclusive", 4.9, "conditionalPass"),
        ("inconclusive", -5.0, "conditionalPass"),  # on the limit: inside
        ("inconclusive", 5.1, "conditionalFail"),
        ("inconclusive", -5.2, "conditionalFail"),
        ("not stated", 1.0, None),
        (None, 0.0, None),  # the reference line: no check
    ],
)
def test_each_outcome_as_a_dcc_status(outcome: str | None, deviation: float, status: str) -> None:
    assert decisions.dcc_status(outcome, deviation, 5.0) == status


def test_the_per_point_list_carries_fail_and_inconclusive_and_leaves_out_not_stated(
    complete_run: Path,
) -> None:
    results = load_stored_run(complete_run).results
    assert results.tolerance_percent == 5.0
    lines = list(results.lines)
    changes = {2: ("fail", 7.5), 3: ("inconclusive", 4.8), 4: ("inconclusive", -5.3),
               5: ("not stated", 0.5)}  # fmt: skip
    for index, (verdict, deviation) in changes.items():
        lines[index] = dataclasses.replace(
            lines[index], tolerance_verdict=verdict, deviation_percent=deviation
        )
    results = dataclasses.replace(results, lines=tuple(lines))
    parent = ET.Element(f"{{{DCC_NS}}}results")
    decisions.characteristic_conformity(parent, results)
    meta = parent.find(".//dcc:metaData[@refType='basic_conformity']", NS)
    assert meta is not None
    statuses = str(meta.findtext("dcc:conformityXMLList", namespaces=NS)).split()
    checked = [i for i, ln in enumerate(lines) if ln.tolerance_verdict not in (None, "not stated")]
    assert len(statuses) == len(checked)  # the reference line and the one not stated left out
    by_line = dict(zip(checked, statuses, strict=True))
    assert (by_line[2], by_line[3], by_line[4]) == ("fail", "conditionalPass", "conditionalFail")
    assert all(by_line[i] == "pass" for i in checked if i not in changes)
    frequencies = parent.findtext(".//dcc:list/dcc:quantity/si:realListXMLList/si:valueXMLList",
                                  namespaces=NS)  # fmt: skip
    assert frequencies is not None and len(frequencies.split()) == len(checked)
    declaration = str(meta.findtext("dcc:declaration/dcc:content", namespaces=NS))
    assert f"{lines[5].frequency_hz:g} Hz (not stated)" in declaration
    for ref, value in (("basic_toleranceLimitLower", "-5"), ("basic_toleranceLimitUpper", "5")):
        limits = meta.findtext(f".//dcc:quantity[@refType='{ref}']//si:valueXMLList", namespaces=NS)
        assert limits is not None and limits.split() == [value] * len(checked)


def test_no_tolerance_no_per_point_list(complete_run: Path) -> None:
    results = dataclasses.replace(load_stored_run(complete_run).results, tolerance_percent=None)
    parent = ET.Element(f"{{{DCC_NS}}}results")
    decisions.characteristic_conformity(parent, results)
    assert len(parent) == 0
    statements = ET.Element(f"{{{DCC_NS}}}statements")
    decisions.decision_rule(statements, results)
    refs = [q.get("refType") for q in statements.iter(f"{{{DCC_NS}}}quantity")]
    assert refs == ["vib_guardBandFactor"]  # the rule stands; no limits without a tolerance


@pytest.mark.parametrize(
    ("version", "release"),
    [
        ("0.1.dev782+gaf3946fc7", "v0.1"),
        ("1.2.3", "v1.2.3"),
        ("", "v0"),
        ("2026.11.27", "v999.11.27"),
    ],
)
def test_the_release_as_the_schematron_wants_it(version: str, release: str) -> None:
    software = ET.Element(f"{{{DCC_NS}}}software")
    decisions.software_release(software, version)
    assert software.findtext("dcc:release", namespaces=NS) == release
    assert version in str(software.findtext("dcc:description/dcc:content", namespaces=NS))
