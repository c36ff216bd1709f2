"""The DCC's decisions in machine-readable form (issue 35 point 3), after PTB's DCC good
practice (the GP temperature example: a `basic_conformity` metaData on the result quantity with
its `dcc:conformityXMLList` and the limits as quantities in its data).

- The decision rule: a statement `basic_decisionRule` naming ILAC-G8:09/2019 4.2.2 (guarded
  acceptance) in `dcc:norm`/`dcc:reference`, the rule's sentence (dsp.conformity), the guard
  band as a quantity (w = 1 U, `vib_guardBandFactor`) and the amplitude characteristic's
  tolerance limits (`basic_toleranceLimitLower`/`Upper`, %).
- Each point's conformity: a result `vib_characteristicConformity` listing, for every frequency
  with a statement, the frequency, the deviation from the sensitivity at the reference frequency
  with its U (as printed: app.certificate.printed), and on the deviation a `basic_conformity`
  metaData with one status per point (`conformityXMLList`) and the per-point tolerance limits.
  DCC 3.3.0's statuses: pass and fail as decided; ILAC-G8's "inconclusive" zone as
  conditionalPass (the deviation inside the tolerance, its U interval across the limit) or
  conditionalFail (outside, U across): ILAC-G8:09/2019 4.2.3's words. Points without a statement
  (the reference frequency, 0 by definition; "not stated": no U, or one below the floor) are not
  listed; the declaration names those not stated.
- The software's release in the form DCC's Schematron accepts (`v0.1.2`), the full version in
  its description.
"""

from __future__ import annotations

import math
import re
import xml.etree.ElementTree as ET

from app.certificate.printed import printed_lines
from dsp.calibration import Results
from dsp.conformity import DECISION_RULE, NOT_STATED, Outcome

# the DCC's vocabulary as app.certificate.dcc writes it (which imports this module; the test
# test_dcc_statements checks they are the same)
DCC_NS = "https://ptb.de/dcc"
SI_NS = "https://ptb.de/si"
REF_FREQUENCY = "vib_frequency basic_referenceValue"
UNIT_HZ = r"\hertz"
UNIT_PERCENT = r"\percent"
DECISION_RULE_REF = "basic_decisionRule"
CONFORMITY_REF = "basic_conformity"
LIMIT_LOWER_REF = "basic_toleranceLimitLower"
LIMIT_UPPER_REF = "basic_toleranceLimitUpper"
GUARD_BAND_REF = "vib_guardBandFactor"
CONFORMITY_RESULT_REF = "vib_characteristicConformity"
DEVIATION_REF = "vib_relativeDeviation basic_measuredValue"
DECISION_NORM = "ILAC-G8:09/2019"
DECISION_SECTION = "4.2.2"
UNIT_ONE = r"\one"
# names apart from the frequency response's (readers find that list's quantities by name)
POINT_FREQUENCY_NAME = "Frequency of each conformity statement"
POINT_DEVIATION_NAME = "Deviation from the sensitivity at the reference frequency, per statement"


class DccStatus:
    """DCC 3.3.0's conformity statuses this program writes (dcc:stringConformityStatus)."""

    PASS = "pass"
    FAIL = "fail"
    CONDITIONAL_PASS = "conditionalPass"
    CONDITIONAL_FAIL = "conditionalFail"


def dcc_status(
    outcome: str | None, deviation_percent: float, tolerance_percent: float
) -> str | None:
    """The DCC status of one point's outcome (dsp.conformity.Outcome): pass, fail, or for an
    inconclusive one conditionalPass / conditionalFail by where the deviation lies against the
    tolerance (%); None where there is no statement (no check, or not stated)."""
    if outcome == Outcome.PASS:
        return DccStatus.PASS
    if outcome == Outcome.FAIL:
        return DccStatus.FAIL
    if outcome == Outcome.INCONCLUSIVE and math.isfinite(deviation_percent):
        inside = abs(deviation_percent) <= tolerance_percent
        return DccStatus.CONDITIONAL_PASS if inside else DccStatus.CONDITIONAL_FAIL
    return None


def _tag(
    ns: str, parent: ET.Element, tag: str, text: str | None = None, **attrs: str
) -> ET.Element:
    element = ET.SubElement(parent, f"{{{ns}}}{tag}", attrs)
    if text is not None:
        element.text = text
    return element


def _names() -> tuple[str, str]:
    return DCC_NS, SI_NS


def _text(parent: ET.Element, tag: str, content: str) -> ET.Element:
    dcc, _ = _names()
    element = _tag(dcc, parent, tag)
    _tag(dcc, element, "content", content, lang="en")
    return element


def _quantity(
    parent: ET.Element, ref_type: str, name: str, values: list[str], unit: str, listed: bool = True
) -> ET.Element:
    """A dcc:quantity with a name and an si:realListXMLList (`listed`), else one si:real."""
    dcc, si = _names()
    quantity = _tag(dcc, parent, "quantity", refType=ref_type)
    _text(quantity, "name", name)
    if not listed:
        real = _tag(si, quantity, "real")
        _tag(si, real, "value", values[0])
        _tag(si, real, "unit", unit)
    else:
        real_list = _tag(si, quantity, "realListXMLList")
        _tag(si, real_list, "valueXMLList", " ".join(values))
        _tag(si, real_list, "unitXMLList", unit)
    return quantity


def software_release(software: ET.Element, version: str) -> None:
    """The software's dcc:release as DCC's Schematron wants it (a letter, then up to four
    dot-separated numbers of at most three digits: `v0.1`), then its full version (PEP 440,
    with the commit) in dcc:type and dcc:description."""
    dcc, _ = _names()
    numbers = re.match(r"\d+(?:\.\d+){0,3}", version or "")
    parts = numbers.group(0).split(".") if numbers else ["0"]
    release = "v" + ".".join(str(min(int(p), 999)) for p in parts)
    _tag(dcc, software, "release", release)
    _tag(dcc, software, "type", "application")
    _text(software, "description", f"accelcal {version or 'unknown'} (the full version)")


def decision_rule(statements: ET.Element, results: Results) -> None:
    """The decision rule statement: the rule (ILAC-G8 guarded acceptance, w = U), and the
    amplitude characteristic's tolerance limits when the run had one."""
    dcc, _ = _names()
    statement = _tag(dcc, statements, "statement", refType=DECISION_RULE_REF)
    _text(statement, "name", "Decision rule")
    _tag(dcc, statement, "norm", DECISION_NORM)
    _tag(dcc, statement, "reference", f"{DECISION_SECTION} guarded acceptance, guard band w = U")
    _text(statement, "declaration", f"Decision rule: {DECISION_RULE}.")
    data = _tag(dcc, statement, "data")
    _quantity(data, GUARD_BAND_REF, "Guard band w in units of the expanded uncertainty U",
              ["1"], UNIT_ONE, listed=False)  # fmt: skip
    tolerance = results.tolerance_percent
    if tolerance is not None:
        for ref, sign, word in ((LIMIT_LOWER_REF, "-", "Lower"), (LIMIT_UPPER_REF, "", "Upper")):
            _quantity(data, ref, f"{word} tolerance limit of the deviation from the sensitivity "
                      "at the reference frequency", [f"{sign}{tolerance:g}"], UNIT_PERCENT,
                      listed=False)  # fmt: skip


def characteristic_conformity(results_element: ET.Element, results: Results) -> None:
    """The per-point conformity of the amplitude characteristic (see the module docstring);
    nothing when the run had no tolerance or no point has a statement."""
    tolerance = results.tolerance_percent
    if tolerance is None:
        return
    dcc, si = _names()
    points: list[tuple[str, str, str, str, str]] = []
    left_out: list[str] = []
    for ln, raw in zip(printed_lines(results), results.lines, strict=True):
        found = dcc_status(ln.tolerance_verdict, raw.deviation_percent, tolerance)
        if found is None or ln.deviation_expanded in ("n/a", "n/s"):
            if ln.tolerance_verdict is not None:
                left_out.append(f"{ln.frequency} Hz ({ln.tolerance_verdict or NOT_STATED})")
            continue
        points.append((ln.frequency, ln.deviation, ln.deviation_expanded, ln.k, found))
    if not points:
        return
    p = f"{results.coverage_probability:g}"
    result = _tag(dcc, results_element, "result", refType=CONFORMITY_RESULT_REF)
    _text(result, "name", "Conformity of the amplitude characteristic per frequency")
    data_list = _tag(dcc, _tag(dcc, result, "data"), "list")
    freq, dev, u, k, status = (list(column) for column in zip(*points, strict=True))
    _quantity(data_list, REF_FREQUENCY, POINT_FREQUENCY_NAME, freq, UNIT_HZ)
    deviation = _tag(dcc, data_list, "quantity", refType=DEVIATION_REF)
    _text(deviation, "name", POINT_DEVIATION_NAME)
    real_list = _tag(si, deviation, "realListXMLList")
    _tag(si, real_list, "valueXMLList", " ".join(dev))
    _tag(si, real_list, "unitXMLList", UNIT_PERCENT)
    expanded = _tag(si, _tag(si, real_list, "measurementUncertaintyUnivariateXMLList"),
                    "expandedMUXMLList")  # fmt: skip
    _tag(si, expanded, "valueExpandedMUXMLList", " ".join(u))
    _tag(si, expanded, "coverageFactorXMLList", " ".join(k))
    _tag(si, expanded, "coverageProbabilityXMLList", " ".join([p] * len(points)))
    metadata = _tag(dcc, deviation, "measurementMetaData")
    meta = _tag(dcc, metadata, "metaData", refType=CONFORMITY_REF)
    _text(meta, "name", "Conformity")
    _tag(dcc, meta, "norm", DECISION_NORM)
    declaration = (
        f"Decision rule: {DECISION_RULE} (the statement {DECISION_RULE_REF}); an inconclusive "
        "point is conditionalPass where the deviation lies within the tolerance, "
        "conditionalFail where it lies outside."
    )
    if left_out:
        declaration += " Without a statement: " + ", ".join(left_out) + "."
    _text(meta, "declaration", declaration)
    _tag(dcc, meta, "conformityXMLList", " ".join(status))
    limits = _tag(dcc, meta, "data")
    n = len(points)
    for ref, sign, word in ((LIMIT_LOWER_REF, "-", "Lower"), (LIMIT_UPPER_REF, "", "Upper")):
        _quantity(
            limits, ref, f"{word} tolerance limit", [f"{sign}{tolerance:g}"] * n, UNIT_PERCENT
        )
