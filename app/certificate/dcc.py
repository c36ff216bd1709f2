"""The Digital Calibration Certificate (PTB DCC 3.3.0 with D-SI 2.2.1 lists) of a stored run.

Built from the same stored run and certificate items as the PDF, with every number printed by
the same function (app.certificate.printed), so the XML, the PDF and the run agree to the last
printed digit; its sentences are app.certificate.text's. Validated offline against the schema
set shipped in app/data/dcc (PTB, LGPL-3; see its LICENSES) before it is written: an invalid
DCC is never written.

Layout: administrative data (software, core data with the
certificate number and dates, the item with maker, model and serial, laboratory, responsible
person, customer, the decision-rule statement with the verdict), one measurement result (method
ISO 16063-21 comparison with the multisine plan, the reference standard with its certificate,
the conditions) whose data is a list of parallel D-SI lists: frequency, sensitivity magnitude
and phase, each with expanded uncertainty, coverage factor and coverage probability per point,
and the deviation from the sensitivity at the reference frequency (%) with its U
(dsp.characteristic); then the result at the reference frequency on its own, marked
(REF_RESULT), so a reader finds the certified sensitivity without matching names.

refType attributes name what each element is, so a reader need not match English names: PTB's
good-practice names where one exists (basic_measuredValue, basic_referenceValue,
basic_conformity, basic_normalUsed, basic_temperature, basic_serialNumber, as in PTB's GP
examples), and this program's `vib_` names for the vibration quantities without one. The XML
is indented (two spaces) for a human reader; readers compare values, not layout.
"""

from __future__ import annotations

import functools
import xml.etree.ElementTree as ET
from collections.abc import Callable
from importlib import resources
from typing import Any

import app.certificate.reference_dcc as reference_dcc
import app.certificate.text as text
from app.certificate.info import CertificateInfo
from app.certificate.load import StoredRun
from app.certificate.printed import PrintedLine, printed_lines
from app.errors import Refusal
from app.records.run_record import RunRecord
from dsp.calibration import Results

DCC_NS = "https://ptb.de/dcc"
SI_NS = "https://ptb.de/si"
XSI_NS = "http://www.w3.org/2001/XMLSchema-instance"
DS_NS = "http://www.w3.org/2000/09/xmldsig#"
QUDT_NS = "http://qudt.org/vocab/"
SCHEMA_VERSION = "3.3.0"
UNIT_SENSITIVITY = r"\milli\volt\second\tothe{2}\metre\tothe{-1}"
UNIT_HZ = r"\hertz"
UNIT_DEGREE = r"\degree"
UNIT_CELSIUS = r"\degreecelsius"
UNIT_ACCELERATION = r"\metre\second\tothe{-2}"
UNIT_PERCENT = r"\percent"
DEVIATION_NAME = "Deviation from the sensitivity at the reference frequency"
PHASE_NAME = "Phase shift (DUT relative to the acceleration)"
RUN_ID_NAME = "Calibration run"  # the run certified, an identification of the core data
SEAL_NAME = "Run seal (SHA-256)"  # its seal's hash (app.records.seal)
# refTypes (see the module docstring): PTB good-practice basic_ names, vib_ ones of this program
REF_FREQUENCY = "vib_frequency basic_referenceValue"
REF_MAGNITUDE = "vib_sensitivityMagnitude basic_measuredValue"
REF_PHASE = "vib_sensitivityPhase basic_measuredValue"
REF_DEVIATION = "vib_relativeDeviation"
REF_RESPONSE = "vib_frequencyResponse"
REF_RESULT = "vib_referenceFrequencyResult"  # the result at the reference frequency
CHAIN_HEAD_NAME = "Records chain head (SHA-256)"  # the records' chain head its seal names
REF_RUN_ID = "vib_runIdentifier"  # issue 35: the run, its seal and the software validation
REF_SEAL = "vib_runSeal"  # named by refType, for a machine
REF_CHAIN_HEAD = "vib_recordsChainHead"
REF_VALIDATION = "vib_softwareValidation"

Extension = Callable[[ET.Element, ET.Element, CertificateInfo], None]

ET.register_namespace("dcc", DCC_NS)
ET.register_namespace("si", SI_NS)
ET.register_namespace("xsi", XSI_NS)


class DccError(Refusal):
    """A DCC that cannot be made or does not validate; the message says which item."""


class DccNotApplicable(DccError):
    """The stand file lacks what a DCC needs but a PDF does not (the laboratory's country)."""


def _d(parent: ET.Element, tag: str, text: str | None = None, **attrs: str) -> ET.Element:
    element = ET.SubElement(parent, f"{{{DCC_NS}}}{tag}", attrs)
    if text is not None:
        element.text = text
    return element


def _s(parent: ET.Element, tag: str, text: str | None = None) -> ET.Element:
    element = ET.SubElement(parent, f"{{{SI_NS}}}{tag}")
    if text is not None:
        element.text = text
    return element


def _text(parent: ET.Element, tag: str, content: str) -> ET.Element:
    """A dcc textType element: <tag><dcc:content lang="en">content</dcc:content></tag>."""
    element = _d(parent, tag)
    _d(element, "content", content, lang="en")
    return element


def _real(
    parent: ET.Element,
    value: str,
    unit: str,
    ref_type: str | None = None,
    name: str | None = None,
    uncertainty: tuple[str, str, str] | None = None,
) -> None:
    """A dcc:quantity holding one si:real (value, unit), with its name, refType and expanded
    uncertainty (U, k, coverage probability) when given."""
    quantity = _d(parent, "quantity", **({"refType": ref_type} if ref_type else {}))
    if name is not None:
        _text(quantity, "name", name)
    real = _s(quantity, "real")
    _s(real, "value", value)
    _s(real, "unit", unit)
    if uncertainty is not None:
        expanded = _s(_s(real, "measurementUncertaintyUnivariate"), "expandedMU")
        for tag, text_value in zip(
            ("valueExpandedMU", "coverageFactor", "coverageProbability"), uncertainty, strict=True
        ):
            _s(expanded, tag, text_value)


def _list_quantity(
    parent: ET.Element,
    name: str,
    values: list[str],
    unit: str,
    uncertainty: tuple[list[str], list[str], list[str]] | None = None,
    ref_type: str | None = None,
) -> None:
    quantity = _d(parent, "quantity", **({"refType": ref_type} if ref_type else {}))
    _text(quantity, "name", name)
    real_list = _s(quantity, "realListXMLList")
    _s(real_list, "valueXMLList", " ".join(values))
    _s(real_list, "unitXMLList", unit)
    if uncertainty is not None:
        expanded_values, factors, probabilities = uncertainty
        mu = _s(real_list, "measurementUncertaintyUnivariateXMLList")
        expanded = _s(mu, "expandedMUXMLList")
        _s(expanded, "valueExpandedMUXMLList", " ".join(expanded_values))
        _s(expanded, "coverageFactorXMLList", " ".join(factors))
        _s(expanded, "coverageProbabilityXMLList", " ".join(probabilities))


def line_values(lines: tuple[PrintedLine, ...]) -> dict[str, list[str]]:
    """The printed strings of the DCC's lists, keyed as `accelcal verify` reads them back
    (app.certificate.readback.items_from_dcc): f, s, u, k (and ph, u_ph, dev, u_dev)."""
    return {
        "f": [ln.frequency for ln in lines],
        "s": [ln.sensitivity for ln in lines],
        "u": [ln.expanded for ln in lines],
        "k": [ln.k for ln in lines],
        "ph": [ln.phase for ln in lines],
        "u_ph": [ln.phase_expanded for ln in lines],
        "dev": [ln.deviation for ln in lines],
        "u_dev": [ln.deviation_expanded for ln in lines],
    }


def build(run: StoredRun, info: CertificateInfo, extend: Extension | None = None) -> bytes:
    """The DCC XML of a stored complete run with its (checked, numbered) certificate items;
    `extend(administrativeData, measurementResult, info)` adds to it before it is validated."""
    record, results = run.record, run.results
    start = run.start
    if start.stand is None:  # a folder without config.json: the record's stand
        lab, reference = dict(record.stand.laboratory), dict(record.stand.reference)
    else:
        lab, reference = start.laboratory, start.reference
    if record.stand.reference:  # the reference as the run used it (its certificate from the
        reference = dict(record.stand.reference)  # records when they held it), not the file's
    country = str(lab.get("country") or "")
    if len(country) != 2 or not country.isalpha() or not country.isupper():
        raise DccNotApplicable(
            "laboratory.country (stand file): the DCC needs the laboratory's ISO 3166-1 "
            f"two-letter country code, got {country!r}"
        )
    started = record.started_utc[:10]
    finished = (record.finished_utc or started)[:10]
    root = ET.Element(
        f"{{{DCC_NS}}}digitalCalibrationCertificate",
        {
            "schemaVersion": SCHEMA_VERSION,
            f"{{{XSI_NS}}}schemaLocation": f"{DCC_NS} https://ptb.de/dcc/v3.3.0/dcc.xsd",
        },
    )
    admin = _d(root, "administrativeData")
    software = _d(_d(admin, "dccSoftware"), "software")
    _text(software, "name", "accelcal")
    from app.certificate import dcc_statements as decisions  # issue 35: machine-readable

    decisions.software_release(software, record.software_version)
    core = _d(admin, "coreData")
    _d(core, "countryCodeISO3166_1", country)
    _d(core, "usedLangCodeISO639_1", "en")
    _d(core, "mandatoryLangCodeISO639_1", "en")
    _d(core, "uniqueIdentifier", str(info.certificate_number))
    _run_identifications(core, run)
    _d(core, "beginPerformanceDate", started)
    _d(core, "endPerformanceDate", finished)
    _d(core, "performanceLocation", "laboratory")
    _d(core, "issueDate", str(info.issue_date))
    _amendment(core, info)
    item = _d(_d(admin, "items"), "item")
    _text(item, "name", str(info.dut_type or "accelerometer"))
    model = str(info.dut_model or "")
    if model:
        _d(item, "model", model)
    identification = _d(_d(item, "identifications"), "identification", refType="basic_serialNumber")
    _d(identification, "issuer", "manufacturer")
    _d(identification, "value", str(info.dut_serial))
    _text(identification, "name", "Serial number")
    contact = _d(_d(admin, "calibrationLaboratory"), "contact")
    _text(contact, "name", str(lab.get("name") or "calibration laboratory"))
    location = _d(contact, "location")
    _text(location, "further", str(lab.get("address") or lab.get("name") or "laboratory"))
    person = _d(_d(admin, "respPersons"), "respPerson")
    _text(_d(person, "person"), "name", str(info.authorised_by))
    if info.authorised_function:  # the function apart from the name (issue 33)
        _d(person, "role", info.authorised_function)
    _d(person, "mainSigner", "true")
    customer = _d(admin, "customer")
    _text(customer, "name", str(info.customer))
    _text(_d(customer, "location"), "further", info.customer_address or text.ADDRESS_NOT_STATED)
    _statements(admin, results, record)
    decisions.decision_rule(_statements_of(admin), results)
    duty_statements(admin, run, info)

    result_set = _d(_d(root, "measurementResults"), "measurementResult")
    _text(result_set, "name", "Comparison calibration per ISO 16063-21 (multisine)")
    method = _d(_d(result_set, "usedMethods"), "usedMethod")
    _text(method, "name", text.dcc_method_text(record, results))
    _d(method, "norm", "ISO 16063-21:2003")
    equipment = _d(
        _d(result_set, "measuringEquipments"), "measuringEquipment", refType="basic_normalUsed"
    )
    _text(equipment, "name", f"Reference standard {reference.get('id', '')}".strip())
    _d(equipment, "model", str(reference.get("model") or "reference accelerometer"))
    ids = _d(equipment, "identifications")
    for issuer, label, value in (
        ("manufacturer", "Serial number", reference.get("serial")),
        ("calibrationLaboratory", "Calibration certificate", reference.get("certificate_number")),
    ):
        if value:
            ident = _d(ids, "identification")
            _d(ident, "issuer", issuer)
            _d(ident, "value", str(value))
            _text(ident, "name", label)
    reference_dcc.dcc_identifications(ids, reference)  # issue 35 point 4
    conditions = _d(result_set, "influenceConditions")
    temperature = _d(conditions, "influenceCondition", refType="basic_temperature")
    _text(temperature, "name", "Ambient temperature")
    _real(_d(temperature, "data"), f"{float(info.temperature_c or 0.0):.1f}", UNIT_CELSIUS)
    level = _d(conditions, "influenceCondition")
    _text(level, "name", "Excitation level, peak per frequency")
    _real(_d(level, "data"), f"{record.level_ms2 or 0:g}", UNIT_ACCELERATION)
    mounting = _d(conditions, "influenceCondition")
    _text(mounting, "name", "Mounting")
    _text(_d(mounting, "data"), "text", str(info.mounting))

    values = line_values(printed_lines(results))
    n = len(values["f"])
    probability = [f"{results.coverage_probability:g}"] * n
    results_element = _d(result_set, "results")
    result = _d(results_element, "result", refType=REF_RESPONSE)
    _text(result, "name", "Frequency response of the voltage sensitivity")
    data_list = _d(_d(result, "data"), "list")
    _list_quantity(data_list, "Excitation frequency", values["f"], UNIT_HZ, ref_type=REF_FREQUENCY)
    _list_quantity(
        data_list,
        "Sensitivity magnitude",
        values["s"],
        UNIT_SENSITIVITY,
        (values["u"], values["k"], probability),
        REF_MAGNITUDE,
    )
    if results.phase_corrected_for_skew:
        _list_quantity(
            data_list,
            PHASE_NAME,
            values["ph"],
            UNIT_DEGREE,
            (values["u_ph"], values["k"], probability),
            REF_PHASE,
        )
    if all(u != "n/a" for u in values["u_dev"]):
        _list_quantity(
            data_list,
            DEVIATION_NAME,
            values["dev"],
            UNIT_PERCENT,
            (values["u_dev"], values["k"], probability),
            REF_DEVIATION,
        )
    _reference_result(results_element, results)
    decisions.characteristic_conformity(results_element, results)
    if extend is not None:  # the issuing service's additions (app.certificate.dcc_complete)
        extend(admin, result_set, info)
    ET.indent(root, space="  ")
    xml = ET.tostring(root, encoding="utf-8", xml_declaration=True)
    problem = validation_error(xml)
    if problem is not None:
        raise DccError(f"the DCC does not validate against DCC {SCHEMA_VERSION}: {problem}")
    return xml


AMENDMENT_REFERRAL = "Calibration certificate replaced by this one"


def _amendment(core: ET.Element, info: CertificateInfo) -> None:
    """An amendment's coreData (ISO/IEC 17025 7.8.8.3): reportAmendedSubstituted (this DCC
    substitutes the one named in full) and previousReport (its number, the SHA-256 of its
    DCC, else of its PDF, as the register holds it, and the reason as its description)."""
    a = info.amendment
    if a is None:
        return
    changed = _d(core, "reportAmendedSubstituted")
    _d(changed, "typeOfChange", "substituted")
    _d(changed, "replacedUniqueIdentifier", a.replaces)
    previous = _d(core, "previousReport")
    _text(previous, "referral", AMENDMENT_REFERRAL)
    _d(previous, "referralID", a.replaces)
    _d(previous, "procedure", "SHA-256 of its DCC" if a.of_dcc else "SHA-256 of its PDF")
    _d(previous, "value", a.sha256 or "unknown (issued before the register kept hashes)")
    _text(previous, "description", a.reason)


def _reference_result(parent: ET.Element, results: Results) -> None:
    """The result at the reference frequency, marked REF_RESULT: its frequency, sensitivity
    and (when stated) phase with their U, printed as in the list (app.certificate.printed)."""
    f_ref = results.reference.frequency_hz
    line = next(ln for ln in printed_lines(results) if ln.nominal_frequency_hz == f_ref)
    p = f"{results.coverage_probability:g}"
    result = _d(parent, "result", refType=REF_RESULT)
    _text(result, "name", "Sensitivity at the reference frequency")
    data = _d(result, "data")
    _real(data, line.frequency, UNIT_HZ, REF_FREQUENCY, "Reference frequency")
    _real(
        data,
        line.sensitivity,
        UNIT_SENSITIVITY,
        REF_MAGNITUDE,
        "Sensitivity magnitude",
        (line.expanded, line.k, p),
    )
    if results.phase_corrected_for_skew:
        _real(
            data, line.phase, UNIT_DEGREE, REF_PHASE, PHASE_NAME, (line.phase_expanded, line.k, p)
        )


def _run_identifications(core: ET.Element, run: StoredRun) -> None:
    """The run certified and its seal's hash (app.records.seal), as `verify --run` reads them
    (app.certificate.readback); no seal entry for a run made before seals."""
    from app.records.seal import SealError, named_chain_head, named_seal

    try:
        seal, head = named_seal(run.path), named_chain_head(run.path)
    except SealError as exc:
        raise DccError(str(exc)) from None
    ids = _d(core, "identifications")
    for label, value, ref_type in (
        (RUN_ID_NAME, run.record.run_id, REF_RUN_ID),
        (SEAL_NAME, seal, REF_SEAL),
        (CHAIN_HEAD_NAME, head, REF_CHAIN_HEAD),
    ):
        if value:
            ident = _d(ids, "identification", refType=ref_type)
            _d(ident, "issuer", "calibrationLaboratory")
            _d(ident, "value", str(value))
            _text(ident, "name", label)


def _statements(admin: ET.Element, results: Results, record: RunRecord) -> None:
    statements = _d(admin, "statements")
    statement = _d(statements, "statement", refType="basic_conformity")
    _text(statement, "name", "Statement of conformity")
    verdict = results.verdict
    _text(statement, "declaration", text.dcc_declaration(verdict, results.verdict_reasons))
    conformity = text.dcc_conformity(verdict)
    if conformity is not None:
        _d(statement, "conformity", conformity)
    cmc = _d(statements, "statement")
    _text(cmc, "name", CMC_NAME)
    _text(cmc, "declaration", text.cmc_statement(results))
    _override_statements(statements, record)


CMC_NAME = "Calibration and measurement capability"


def _statements_of(admin: ET.Element) -> ET.Element:
    """The administrative data's dcc:statements (written by `_statements`)."""
    statements = admin.find(f"{{{DCC_NS}}}statements")
    assert statements is not None  # _statements wrote it
    return statements


def _override_statements(statements: ET.Element, record: RunRecord) -> None:
    """One statement per check the run went past with a stated reason (results.json's
    overrides): what, why, who and when, as the PDF's "Overrides" section prints them."""
    for override in record.overrides:
        statement = _d(statements, "statement")
        _text(statement, "name", f"Override: {override.kind}")
        _text(statement, "declaration", override.line())


@functools.cache
def _schema() -> Any:
    import xmlschema

    base = resources.files("app").joinpath("data", "dcc")
    locations = [
        (SI_NS, str(base.joinpath("SI_Format.xsd"))),
        (DS_NS, str(base.joinpath("xmldsig-core-schema.xsd"))),
        (QUDT_NS, str(base.joinpath("quantitykind.xsd"))),
    ]
    return xmlschema.XMLSchema(str(base.joinpath("dcc.xsd")), locations=locations, allow="local")


def validation_error(xml: bytes) -> str | None:
    """The first schema error of a DCC (where and why), or None when it is valid. Offline."""
    error = next(iter(_schema().iter_errors(xml.decode("utf-8"))), None)
    if error is None:
        return None
    return f"{error.path}: {error.reason or error.message}"


# ---- issue 27: the verification address and the software validation statement -----------


def duty_statements(admin: ET.Element, run: StoredRun, info: CertificateInfo) -> None:
    """After the statement of conformity: the public verification address (when the stand
    file has a verify_url) and the software validation report (`info.validation`: a report the
    issuing service accepted), each a statement named as the PDF names it."""
    from app.certificate.qr import verification_address
    from app.certificate.validated import STATEMENT_NAME

    statements = admin.find(f"{{{DCC_NS}}}statements")
    if statements is None:
        return
    address = verification_address(run, str(info.certificate_number))
    if address is not None:
        statement = _d(statements, "statement")
        _text(statement, "name", VERIFY_NAME)
        _text(statement, "declaration", address)
    claim = info.validation
    if claim is not None:
        statement = _d(statements, "statement", refType=REF_VALIDATION)
        _text(statement, "name", STATEMENT_NAME)
        _text(statement, "declaration", claim.line())
    from app.certificate.complete import fixture_position_text

    fixture = fixture_position_text(run.start)  # issue 36: a DUT of a several-DUT run
    if fixture is not None:
        statement = _d(statements, "statement", refType=REF_FIXTURE)
        _text(statement, "name", FIXTURE_NAME)
        _text(statement, "declaration", fixture)


VERIFY_NAME = "Verification address"
FIXTURE_NAME = "Mounting position on the fixture"
REF_FIXTURE = "vib_fixturePosition"
