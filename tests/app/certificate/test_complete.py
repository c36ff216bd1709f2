"""A complete certificate (issue 35 point 2; app.certificate.complete, pdf_complete,
dcc_complete, remembered): the customer's address or a stated reason, the specification behind
the statement of conformity, the instruments used with their calibration due dates, the
humidity typed or read at run start, the mounting remembered per model and template. Each
checked in the PDF's text (pypdf) and in the DCC as xmlschema decodes it against the PTB schema
(an independent reader), refusals by exit 2 naming the field."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path
from typing import Any

import pytest
import xmlschema
from pypdf import PdfReader

from app.certificate.complete import (
    TYPED,
    stored_environment,
    tolerances_checked,
    with_environment,
    with_specification,
)
from app.certificate.info import CertificateError, CertificateInfo, missing_items
from app.certificate.load import load_stored_run
from app.certificate.remembered import RememberedConditions
from app.cli import main
from app.records.run_record import DutIdentity
from tests.app.certificate.conftest import copy_run

ROOT = Path(__file__).resolve().parents[3]
ITEMS = ["--customer", "ACME Ltd", "--authorised-by", "J. Smith", "--temperature", "23",
         "--mounting", "stud"]  # fmt: skip
SENSOR_READ = "read from Thermo-hygrometer simulated Fluke 1620A DewK, serial SIM-1620-0001"


def _text(pdf: Path) -> str:
    return " ".join(" ".join(p.extract_text() for p in PdfReader(pdf).pages).split())


def _dcc(pdf: Path) -> dict[str, Any]:
    """The DCC beside `pdf` as xmlschema decodes it against the PTB DCC 3.3.0 schema."""
    base = ROOT / "app/data/dcc"
    locations = [("https://ptb.de/si", str(base / "SI_Format.xsd")),
                 ("http://www.w3.org/2000/09/xmldsig#", str(base / "xmldsig-core-schema.xsd")),
                 ("http://qudt.org/vocab/", str(base / "quantitykind.xsd"))]  # fmt: skip
    schema = xmlschema.XMLSchema(str(base / "dcc.xsd"), locations=locations, allow="local")
    decoded: Any = schema.to_dict(pdf.with_suffix(".xml").read_text(encoding="utf-8"))
    return dict(decoded)


def _content(text_type: Any) -> str:
    content = text_type["dcc:content"]
    first = content[0] if isinstance(content, list) else content
    return str(first["$"] if isinstance(first, dict) else first)


def _ref(element: dict[str, Any]) -> str:
    """An element's refType as text (a list type in the schema, decoded as a list)."""
    ref = element.get("@refType", "")
    return " ".join(ref) if isinstance(ref, list) else str(ref)


def _issue(run: Path, out: Path, *extra: str) -> int:
    return main(["certificate", str(run), "--out", str(out), *ITEMS, *extra])


def test_an_empty_address_is_refused_naming_the_field_and_nothing_is_written(
    complete_run: Path, tmp_path: Path, capsys
) -> None:
    run = copy_run(complete_run, tmp_path / "runs")
    capsys.readouterr()
    assert _issue(run, tmp_path / "c.pdf") == 2
    err = capsys.readouterr().err
    assert "customer_address (--customer-address): required" in err
    assert "--address-not-stated" in err and "Traceback" not in err
    assert _issue(run, tmp_path / "c.pdf", "--customer-address", "  ") == 2  # blanks: empty
    assert not (tmp_path / "c.pdf").exists() and not (tmp_path / "c.xml").exists()
    both = ("--customer-address", "1 Road", "--address-not-stated", "walk-in")
    assert _issue(run, tmp_path / "c.pdf", *both) == 2
    assert "give one" in capsys.readouterr().err


def test_not_stated_with_a_reason_is_printed_and_carried_in_the_dcc(
    complete_run: Path, tmp_path: Path
) -> None:
    run = copy_run(complete_run, tmp_path / "runs")
    pdf = tmp_path / "c.pdf"
    assert _issue(run, pdf, "--address-not-stated", "walk-in customer, paid cash") == 0
    assert "ACME Ltd, Address not stated: walk-in customer, paid cash" in _text(pdf)
    customer = _dcc(pdf)["dcc:administrativeData"]["dcc:customer"]
    further = customer["dcc:location"]["dcc:further"]
    further = further[0] if isinstance(further, list) else further
    assert _content(further) == "Address not stated: walk-in customer, paid cash"


def test_the_specification_is_named_beside_the_conformity_statement_and_in_the_dcc(
    complete_run: Path, tmp_path: Path
) -> None:
    run = copy_run(complete_run, tmp_path / "runs")
    pdf = tmp_path / "c.pdf"
    spec = ("--spec-kind", "customer", "--spec-id", "ACME purchase spec AS-12 rev. C")
    assert _issue(run, pdf, "--customer-address", "1 Road, Town", *spec) == 0
    text = _text(pdf)
    conformity = text.index("Statement of conformity")
    named = text.index("Specification: customer requirement, ACME purchase spec AS-12 rev. C;")
    assert conformity < named < text.index("Prepared by")
    # the tolerances the verdict checked, as the run's reasons state them
    assert "tolerances: sensitivity at 160 Hz ±5 %; amplitude characteristic ±5 %" in text
    statements = _dcc(pdf)["dcc:administrativeData"]["dcc:statements"]["dcc:statement"]
    refs = [_ref(s) for s in statements]
    at = refs.index("vib_conformitySpecification")
    assert "basic_conformity" in refs[at - 1]  # right after the statement of conformity
    assert statements[at]["dcc:reference"] == ["ACME purchase spec AS-12 rev. C"]
    assert "tolerances: sensitivity at 160 Hz ±5 %" in _content(statements[at]["dcc:declaration"])


def test_a_standard_is_named_as_a_norm(complete_run: Path, tmp_path: Path) -> None:
    run = copy_run(complete_run, tmp_path / "runs")
    pdf = tmp_path / "c.pdf"
    spec = ("--spec-kind", "standard", "--spec-id", "ISO 5347-0:1987", "--spec-tolerances", "±5 %")
    assert _issue(run, pdf, "--customer-address", "1 Road", *spec) == 0
    assert "Specification: standard, ISO 5347-0:1987; tolerances: ±5 %." in _text(pdf)
    statements = _dcc(pdf)["dcc:administrativeData"]["dcc:statements"]["dcc:statement"]
    named = next(s for s in statements if _ref(s) == "vib_conformitySpecification")
    assert named["dcc:norm"] == ["ISO 5347-0:1987"] and "dcc:reference" not in named


def test_a_kind_without_its_document_is_refused(complete_run: Path, tmp_path: Path, capsys) -> None:
    run = copy_run(complete_run, tmp_path / "runs")
    capsys.readouterr()
    assert (
        _issue(run, tmp_path / "c.pdf", "--customer-address", "1 Road", "--spec-kind", "customer")
        == 2
    )
    assert "specification (--spec-kind, --spec-id)" in capsys.readouterr().err


def test_no_conformity_statement_against_tolerances_without_a_named_specification(
    complete_run: Path,
) -> None:
    stored = load_stored_run(complete_run)
    checked = tolerances_checked(stored.results)
    assert checked.startswith("sensitivity at 160 Hz ±5 %")
    unknown = dataclasses.replace(stored.record, dut=DutIdentity(id="SN-42"))  # no catalogue
    with pytest.raises(CertificateError, match=r"specification \(--spec-kind, --spec-id\)"):
        with_specification(CertificateInfo(), unknown, stored.results)
    # the catalogue DUT's data sheet is its default, with the tolerances checked
    info = with_specification(CertificateInfo(), stored.record, stored.results)
    assert info.specification is not None and info.specification.tolerances == checked
    assert "data sheet of the simulated 'piezo' model" in info.specification.identity
    # no tolerance checked: nothing to name, nothing refused
    plain = dataclasses.replace(stored.results, verdict_reasons=(), tolerance_percent=None)
    assert with_specification(CertificateInfo(), unknown, plain).specification is None


def test_the_instruments_are_listed_with_their_due_dates_in_the_pdf_and_the_dcc(
    complete_run: Path, tmp_path: Path
) -> None:
    run = copy_run(complete_run, tmp_path / "runs")
    pdf = tmp_path / "c.pdf"
    assert _issue(run, pdf, "--customer-address", "1 Road") == 0
    text = _text(pdf)
    listed = text[text.index("Instruments used") :]
    for serial in ("SIM-DAQ-0001", "SIM-2525-000", "SIM-1620-000"):  # wrapped in the table
        assert serial in listed
    assert listed.count("2199-12-31") == 3
    equipment = _dcc(pdf)["dcc:measurementResults"]["dcc:measurementResult"][0][
        "dcc:measuringEquipments"
    ]["dcc:measuringEquipment"]
    found = {}
    for item in equipment[1:]:  # after the reference standard (basic_normalUsed)
        ids = item["dcc:identifications"]["dcc:identification"]
        values = {_content(i["dcc:name"]): i["dcc:value"] for i in ids}
        found[values["Serial number"]] = (
            _ref(item),
            item["dcc:model"],
            values["Calibration due date"],
        )
    assert found["SIM-DAQ-0001"] == (
        "vib_measuringInstrument",
        "simulated M-series-like multiplexed DAQ",
        "2199-12-31",
    )
    assert set(found) == {"SIM-DAQ-0001", "SIM-2525-0001", "SIM-1620-0001"}


def test_the_humidity_read_at_run_start_is_stored_printed_and_in_the_dcc(
    complete_run: Path, tmp_path: Path
) -> None:
    stored = json.loads((complete_run / "config.json").read_text(encoding="utf-8"))
    assert stored["environment"]["humidity_percent"] == 45.3  # sim/environment.yaml's reading
    run = copy_run(complete_run, tmp_path / "runs")
    pdf = tmp_path / "c.pdf"
    assert _issue(run, pdf, "--customer-address", "1 Road") == 0
    text = _text(pdf)
    assert f"Relative humidity 45.3 % ({SENSOR_READ} at run start)" in text
    assert f"Ambient temperature 23.0 °C ({TYPED})" in text  # typed wins over the reading
    conditions = _dcc(pdf)["dcc:measurementResults"]["dcc:measurementResult"][0][
        "dcc:influenceConditions"
    ]["dcc:influenceCondition"]
    refs = [_ref(c) for c in conditions]
    humidity = conditions[refs.index("basic_humidityRelative")]
    assert refs.index("basic_humidityRelative") == refs.index("basic_temperature") + 1
    real = humidity["dcc:data"]["dcc:quantity"][0]["si:real"]
    assert (real["si:value"], real["si:unit"]) == (45.3, r"\percent")
    assert SENSOR_READ in _content(humidity["dcc:description"])


def test_a_typed_humidity_wins_and_says_so(complete_run: Path, tmp_path: Path, capsys) -> None:
    run = copy_run(complete_run, tmp_path / "runs")
    pdf = tmp_path / "c.pdf"
    assert _issue(run, pdf, "--customer-address", "1 Road", "--humidity", "50%") == 0
    assert f"Relative humidity 50.0 % ({TYPED})" in _text(pdf)
    capsys.readouterr()
    assert (
        _issue(run, tmp_path / "d.pdf", "--customer-address", "1 Road", "--humidity", "120%") == 2
    )
    assert "humidity (--humidity): '120%' is not in [0, 100] %" in capsys.readouterr().err


def test_without_a_reading_the_temperature_and_humidity_come_from_the_run_where_not_typed(
    complete_run: Path,
) -> None:
    start = load_stored_run(complete_run).start
    reading = stored_environment(start)
    assert reading is not None and reading.temperature_c == 23.1
    info = with_environment(CertificateInfo(), start)
    assert (info.temperature_c, info.humidity_percent) == (23.1, 45.3)
    assert info.temperature_source.startswith(SENSOR_READ)
    typed = with_environment(CertificateInfo(temperature_c=21.0), start)
    assert (typed.temperature_c, typed.temperature_source) == (21.0, TYPED)
    assert typed.humidity_percent == 45.3
    empty = dataclasses.replace(start, extra={})  # a run that read no sensor
    assert with_environment(CertificateInfo(), empty).humidity_percent is None
    assert "temperature_c (--temperature)" in missing_items(
        with_environment(CertificateInfo(), empty)
    )


def test_the_mounting_is_remembered_per_model_and_offered_with_a_note(
    complete_run: Path, tmp_path: Path, capsys
) -> None:
    first = copy_run(complete_run, tmp_path / "a")
    second = copy_run(complete_run, tmp_path / "b")
    argv = ["certificate", "--customer", "ACME Ltd", "--customer-address", "1 Road",
            "--authorised-by", "J. Smith", "--temperature", "23"]  # fmt: skip
    capsys.readouterr()
    assert main([*argv, str(first), "--mounting", "stud M5, 2 N m, silicone grease"]) == 0
    assert "(from model" not in capsys.readouterr().out  # typed: nothing offered
    assert main([*argv, str(second)]) == 0  # no --mounting: offered, not refused
    out = capsys.readouterr().out
    assert "mounting: 'stud M5, 2 N m, silicone grease' (from model simulated piezo" in out
    assert "Mounting stud M5, 2 N m, silicone grease" in _text(second / "certificate.pdf")


def test_a_template_is_offered_before_its_model_and_models_do_not_mix(tmp_path: Path) -> None:
    store = RememberedConditions(tmp_path / "conditions.json")
    assert store.offered("PCB 352C33") is None
    store.remember("PCB 352C33", "stud")
    store.remember("PCB 352C33", "adhesive", template="low level")
    assert store.offered("PCB 352C33").mounting == "adhesive"  # the last for the model
    offered = store.offered("PCB 352C33", "low level")
    assert offered is not None and offered.source == "template low level of model PCB 352C33"
    store.remember("PCB 352C33", "magnet")
    assert store.offered("PCB 352C33", "low level").mounting == "adhesive"
    assert (
        store.offered("PCB 352C33", "other").note() == "mounting: 'magnet' (from model PCB 352C33)"
    )
    assert store.offered("Kistler 8704") is None
    (tmp_path / "conditions.json").write_text("{not json", encoding="utf-8")
    assert store.offered("PCB 352C33") is None  # a damaged file offers nothing


def test_a_records_customer_without_an_address_is_refused_unless_a_reason_is_given() -> None:
    from types import SimpleNamespace

    from app.certificate.register_issue import _identity

    model = SimpleNamespace(maker="PCB", model="352C33", unit="mV/g")
    owner = SimpleNamespace(name="ACME Ltd", address="")
    sensor = SimpleNamespace(serial="SN-7", owner=owner, model=model)
    with pytest.raises(CertificateError, match="records hold no address for customer 'ACME Ltd'"):
        _identity(CertificateInfo(), sensor, "SN-7", "A. Tech")
    info = _identity(CertificateInfo(address_not_stated="walk-in"), sensor, "SN-7", "A. Tech")
    assert info.specification is not None  # the sensor model's data sheet, by default
    assert info.specification.identity.startswith("PCB 352C33 data sheet")
    owner.address = "1 Road, Town"
    assert (
        _identity(CertificateInfo(), sensor, "SN-7", "A. Tech").customer_address == "1 Road, Town"
    )


def test_with_records_the_reference_standard_is_listed_with_its_records_due_date(
    tmp_path: Path,
) -> None:
    """A records database of its own (the session's runs keep their one certificate each)."""
    from datetime import UTC, datetime, timedelta

    url = f"sqlite:///{tmp_path / 'records.sqlite'}"
    today = datetime.now(UTC).date()
    due = (today + timedelta(days=300)).isoformat()
    for argv in (
        ["db", "upgrade"],
        ["customers", "add", "ACME Ltd", "--address", "1 Road, Town"],
        ["models", "add", "PCB", "352C33", "--nominal", "100", "--unit", "mV/g", "--tolerance",
         "5", "--fmin", "1", "--fmax", "10000"],
        ["sensors", "add", "SN-7", "--model", "352C33", "--owner", "ACME Ltd"],
        ["refs", "add", "REF-8305-SIM", "--model", "B&K 8305", "--serial", "SIM-0001",
         "--certificate", "PTB-1", "--calibrated", str(today - timedelta(days=30)), "--due",
         due, "--table", str(ROOT / "examples/ref-table.csv")],
        ["run", "--sim", "--periods", "3", "--sensor", "SN-7", "--out", str(tmp_path / "runs")],
    ):  # fmt: skip
        assert main([*argv, "--db", url]) == 0, argv
    (run,) = (tmp_path / "runs").iterdir()
    pdf = tmp_path / "c.pdf"
    argv = ["certificate", str(run), "--db", url, "--out", str(pdf), "--prepared-by", "A. Tech",
            "--authorised-by", "J. Smith", "--temperature", "23", "--mounting", "stud"]  # fmt: skip
    assert main(argv) == 0
    listed = _text(pdf)[_text(pdf).index("Instruments used") :]
    assert f"SIM-0001 {due} records" in listed
    # and the sensor model's data sheet names the specification (tolerance ±5 % on record)
    assert "Specification: manufacturer's data sheet, PCB 352C33 data sheet" in _text(pdf)
    normal = _dcc(pdf)["dcc:measurementResults"]["dcc:measurementResult"][0][
        "dcc:measuringEquipments"
    ]["dcc:measuringEquipment"][0]
    ids = normal["dcc:identifications"]["dcc:identification"]
    assert {_content(i["dcc:name"]): i["dcc:value"] for i in ids}["Calibration due date"] == due
