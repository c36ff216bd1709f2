"""The digital calibration certificate: valid against DCC 3.3.0 offline, the same numbers as the
PDF and the run to the last printed digit, attached to the PDF, never written invalid."""

from __future__ import annotations

import json
import shutil
import stat
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest
from pypdf import PdfReader

from app.certificate import CertificateError, CertificateInfo, dcc, issue
from app.cli import main

NS = {"dcc": dcc.DCC_NS, "si": dcc.SI_NS}
INFO = CertificateInfo(
    customer="Jürgen Weiß GmbH",
    customer_address="1 Test Street, 00-001 Testtown",
    authorised_by="J. Smith",
    temperature_c=23.0,
    mounting="stud, 2 N m",
)


@pytest.fixture(scope="module")
def run_folder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("runs")
    argv = ["run", "--sim", "--dut", "piezo", "--dut-id", "SN-42", "--periods", "3"]
    assert main([*argv, "--seed", "3", "--out", str(out)]) == 0
    (folder,) = out.iterdir()
    return folder


def _lists(xml: bytes) -> dict[str, tuple[list[str], list[str], list[str], list[str]]]:
    """Each D-SI list of the result by its name: values, U values, k, p."""
    root = ET.fromstring(xml)
    out = {}
    for quantity in root.iterfind(".//dcc:result/dcc:data/dcc:list/dcc:quantity", NS):
        name = quantity.findtext("dcc:name/dcc:content", namespaces=NS)
        values = quantity.findtext("si:realListXMLList/si:valueXMLList", namespaces=NS).split()
        mu = quantity.find(".//si:expandedMUXMLList", NS)
        u, k, p = (
            ([], [], [])
            if mu is None
            else (
                mu.findtext(f"si:{tag}", namespaces=NS).split()
                for tag in (
                    "valueExpandedMUXMLList",
                    "coverageFactorXMLList",
                    "coverageProbabilityXMLList",
                )
            )
        )
        out[name] = (values, list(u), list(k), list(p))
    return out


def test_the_dcc_is_valid_attached_and_says_what_the_pdf_and_the_run_say(
    run_folder: Path, tmp_path: Path
) -> None:
    pdf = tmp_path / "cert.pdf"
    issued = issue(run_folder, INFO, pdf)
    xml = (tmp_path / "cert.xml").read_bytes()
    assert dcc.validation_error(xml) is None
    assert not (tmp_path / "cert.xml").stat().st_mode & stat.S_IWUSR  # read-only
    reader = PdfReader(pdf)
    assert reader.attachments["certificate.xml"] == [xml]
    root = ET.fromstring(xml)
    assert root.findtext(".//dcc:uniqueIdentifier", namespaces=NS) == issued.number
    assert root.findtext(".//dcc:item//dcc:value", namespaces=NS) == "SN-42"
    assert root.findtext(".//dcc:customer/dcc:name/dcc:content", namespaces=NS) == INFO.customer
    record = json.loads((run_folder / "results.json").read_text())
    lines = record["results"]["lines"]
    lists = _lists(xml)
    freq = lists["Excitation frequency"][0]
    sens, u_sens, k, p = lists["Sensitivity magnitude"]
    assert freq == [f"{ln['frequency_hz']:g}" for ln in lines]
    assert len(sens) == len(u_sens) == len(k) == len(p) == len(lines) == 25
    assert set(p) == {"0.9545"}
    page_text = " ".join(" ".join(page.extract_text() for page in reader.pages).split())
    for ln, s, u, kk in zip(lines, sens, u_sens, k, strict=True):
        # the run's value within half a unit of the last printed digit, U to 2 significant digits
        decimals = len(u.split(".")[1]) if "." in u else 0
        assert abs(float(s) - ln["sensitivity_mv_per_ms2"]) <= 0.5 * 10**-decimals
        assert abs(float(u) - ln["expanded_uncertainty_mv_per_ms2"]) <= 0.5 * 10**-decimals
        assert len(u.replace(".", "").lstrip("0")) == 2
        assert kk == f"{ln['coverage_factor']:.2f}"
        assert f"{s} {u}" in page_text  # the PDF's table row prints the same two strings
    phase = lists["Phase shift (DUT relative to the acceleration)"]
    assert len(phase[0]) == 25 and len(phase[1]) == 25
    conformity = root.findtext(".//dcc:statement/dcc:conformity", namespaces=NS)
    assert conformity == {"PASS": "pass", "FAIL": "fail"}.get(record["verdict"])


def test_an_invalid_dcc_is_never_written(
    run_folder: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(dcc, "SCHEMA_VERSION", "3.3")  # the schema fixes its version
    out = tmp_path / "bad.pdf"
    with pytest.raises(CertificateError, match=r"does not validate against DCC .*schemaVersion"):
        issue(run_folder, INFO, out)
    assert not out.exists() and not (tmp_path / "bad.xml").exists()


def test_a_stand_without_the_laboratory_country_gets_the_pdf_alone(
    run_folder: Path, tmp_path: Path
) -> None:
    copy = tmp_path / run_folder.name
    shutil.copytree(run_folder, copy)
    for path in [copy, *copy.iterdir()]:
        path.chmod(0o755 if path.is_dir() else 0o644)
    for name in ("config.json", "results.json"):
        data = json.loads((copy / name).read_text())
        data["stand"]["laboratory"].pop("country")
        (copy / name).write_text(json.dumps(data))
    from app.records.run_folder import write_manifest

    (copy / "manifest.json").unlink()
    write_manifest(copy)
    (copy / "seal.json").unlink()  # its hashes name the old files: as a run made before seals
    out = tmp_path / "no-country.pdf"
    issue(copy, INFO, out)
    assert out.exists() and not (tmp_path / "no-country.xml").exists()
    assert "certificate.xml" not in PdfReader(out).attachments


def test_reftypes_indentation_address_and_the_marked_reference_result(
    run_folder: Path, tmp_path: Path
) -> None:
    """A reader finds each quantity by its refType (PTB good-practice names, vib_ ones of
    this program), the result at the reference frequency marked and equal to its list entry,
    the customer's address (never the name) in the address, one element a line (issue 27)."""
    info = CertificateInfo(**{**INFO.__dict__, "customer_address": "Hauptstraße 1, Berlin"})
    issue(run_folder, info, tmp_path / "cert.pdf")
    xml = (tmp_path / "cert.xml").read_bytes()
    assert dcc.validation_error(xml) is None
    text = xml.decode("utf-8")
    assert text.count("\n") > 200 and "\n      <dcc:coreData>" not in text  # two-space levels
    assert "\n    <dcc:coreData>" in text
    root = ET.fromstring(xml)
    address = root.findtext(".//dcc:customer/dcc:location/dcc:further/dcc:content", namespaces=NS)
    assert address == "Hauptstraße 1, Berlin"
    kinds = {
        q.get("refType") for q in root.iterfind(".//dcc:result/dcc:data/dcc:list/dcc:quantity", NS)
    }
    assert kinds == {
        dcc.REF_FREQUENCY,
        dcc.REF_MAGNITUDE,
        dcc.REF_PHASE,
        dcc.REF_DEVIATION,
    }
    assert "basic_measuredValue" in dcc.REF_MAGNITUDE.split()
    assert root.find(".//dcc:statement[@refType='basic_conformity']", NS) is not None
    assert root.find(".//dcc:identification[@refType='basic_serialNumber']", NS) is not None
    marked = root.findall(f".//dcc:result[@refType='{dcc.REF_RESULT}']", NS)
    assert len(marked) == 1
    quantities = marked[0].findall("dcc:data/dcc:quantity", NS)
    values = {q.get("refType"): q.findtext("si:real/si:value", namespaces=NS) for q in quantities}
    record = json.loads((run_folder / "results.json").read_text())
    f_ref = record["results"]["reference"]["frequency_hz"]
    assert values[dcc.REF_FREQUENCY] == f"{f_ref:g}"
    lists = _lists(xml)
    k = lists["Excitation frequency"][0].index(f"{f_ref:g}")
    sens, u_sens, cover, _ = lists["Sensitivity magnitude"]
    assert values[dcc.REF_MAGNITUDE] == sens[k]
    magnitude = next(q for q in quantities if q.get("refType") == dcc.REF_MAGNITUDE)
    assert magnitude.findtext(".//si:valueExpandedMU", namespaces=NS) == u_sens[k]
    assert magnitude.findtext(".//si:coverageFactor", namespaces=NS) == cover[k]


def test_no_address_is_said_so_not_filled_with_the_name(run_folder: Path, tmp_path: Path) -> None:
    # issue 35: no address only with the reason, which is stated
    info = CertificateInfo(
        **{**INFO.__dict__, "customer_address": "", "address_not_stated": "walk-in customer"}
    )
    issue(run_folder, info, tmp_path / "cert.pdf")
    root = ET.fromstring((tmp_path / "cert.xml").read_bytes())
    address = root.findtext(".//dcc:customer/dcc:location/dcc:further/dcc:content", namespaces=NS)
    assert address == "Address not stated: walk-in customer" and address != INFO.customer
