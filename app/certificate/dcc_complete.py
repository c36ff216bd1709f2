"""The DCC's parts of a complete certificate (issue 35 point 2; app.certificate.complete), kept
apart from app.certificate.dcc so that changes there stay small: the customer's address or why
it is not stated, the specification behind the statement of conformity (a statement naming its
kind, document and tolerances), the instruments used (dcc:measuringEquipment with model,
serial and calibration due date) and the relative humidity (dcc:influenceCondition), with
where the temperature and humidity come from."""

from __future__ import annotations

import xml.etree.ElementTree as ET

from app.certificate.complete import customer_address_text
from app.certificate.dcc import DCC_NS, UNIT_PERCENT, _d, _real, _text
from app.certificate.info import CertificateInfo, SpecKind

SPECIFICATION_NAME = "Specification of the statement of conformity"
REF_SPECIFICATION = "vib_conformitySpecification"
REF_HUMIDITY = "basic_humidityRelative"
REF_INSTRUMENT = "vib_measuringInstrument"
DUE_NAME = "Calibration due date"


def _find(parent: ET.Element, path: str) -> ET.Element | None:
    return parent.find(path, {"dcc": DCC_NS})


def complete_dcc(admin: ET.Element, result_set: ET.Element, info: CertificateInfo) -> None:
    """Add the complete certificate's items to the DCC being built (before validation)."""
    further = _find(admin, "dcc:customer/dcc:location/dcc:further/dcc:content")
    if further is not None:
        further.text = customer_address_text(info)
    specification_statement(admin, info)
    equipment = _find(result_set, "dcc:measuringEquipments")
    if equipment is not None:
        instruments(equipment, info)
    conditions = _find(result_set, "dcc:influenceConditions")
    if conditions is not None:
        humidity(conditions, info)


def specification_statement(admin: ET.Element, info: CertificateInfo) -> None:
    """A statement after the statement of conformity naming its specification: the kind in
    words, the document (dcc:norm for a standard, else dcc:reference) and the tolerances."""
    spec = info.specification
    statements = _find(admin, "dcc:statements")
    if spec is None or statements is None:
        return
    statement = _d(statements, "statement", refType=REF_SPECIFICATION)
    _text(statement, "name", SPECIFICATION_NAME)
    _d(statement, "norm" if spec.kind == SpecKind.STANDARD else "reference", spec.identity)
    _text(statement, "declaration", spec.line())
    # placed right after the statement of conformity (basic_conformity)
    children = list(statements)
    first = next(
        (i for i, s in enumerate(children) if "basic_conformity" in s.get("refType", "")), None
    )
    if first is not None:
        statements.remove(statement)
        statements.insert(first + 1, statement)


def instruments(equipment: ET.Element, info: CertificateInfo) -> None:
    """One dcc:measuringEquipment per instrument listed (the reference standard's own entry,
    basic_normalUsed, gets its calibration due date), each with model, serial and due date."""
    for x in info.instruments:
        if x.kind == "Reference standard":
            normal = _find(equipment, "dcc:measuringEquipment")
            if normal is not None and x.calibration_due:
                _due(normal, x.calibration_due)
            continue
        item = _d(equipment, "measuringEquipment", refType=REF_INSTRUMENT)
        _text(item, "name", x.kind)
        _d(item, "model", x.model)
        ids = _d(item, "identifications")
        ident = _d(ids, "identification")
        _d(ident, "issuer", "manufacturer")
        _d(ident, "value", x.serial)
        _text(ident, "name", "Serial number")
        if x.calibration_due:
            _due(item, x.calibration_due)


def _due(item: ET.Element, due: str) -> None:
    """The calibration due date as an identification of the calibrating laboratory's."""
    ids = _find(item, "dcc:identifications")
    if ids is None:
        ids = _d(item, "identifications")
    ident = _d(ids, "identification")
    _d(ident, "issuer", "calibrationLaboratory")
    _d(ident, "value", due)
    _text(ident, "name", DUE_NAME)


def humidity(conditions: ET.Element, info: CertificateInfo) -> None:
    """The relative humidity (%) after the temperature, each with where it comes from."""
    temperature = _find(conditions, "dcc:influenceCondition[@refType='basic_temperature']")
    if temperature is not None and info.temperature_source:
        _described(temperature, info.temperature_source)
    if info.humidity_percent is None:
        return
    condition = _d(conditions, "influenceCondition", refType=REF_HUMIDITY)
    _text(condition, "name", "Relative humidity")
    if info.humidity_source:
        _described(condition, info.humidity_source)
    _real(_d(condition, "data"), f"{float(info.humidity_percent):.1f}", UNIT_PERCENT)
    conditions.remove(condition)  # next to the temperature
    children = list(conditions)
    at = children.index(temperature) + 1 if temperature is not None else 0
    conditions.insert(at, condition)


def _described(condition: ET.Element, source: str) -> None:
    """A dcc:description (after the name) saying where the value comes from."""
    description = ET.Element(f"{{{DCC_NS}}}description")
    content = ET.SubElement(description, f"{{{DCC_NS}}}content", {"lang": "en"})
    content.text = source
    condition.insert(1, description)
