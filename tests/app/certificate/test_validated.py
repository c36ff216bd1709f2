"""The software validation report a certificate names (issue 27; issue 33 point 4): only a
report made by `accelcal validate --sign`, signed with the lab's key, for this very software,
every case passed, not dated in the future. The issue's attacks run again: a fake PDF with a
JSON twin saying "all cases passed" (dated 2099, naming the installed software's hash), the
report re-signed with another key, a lab-signed report of another software; each refused by
`certificate` and by `verify --validation-report`, naming what it found."""

from __future__ import annotations

import dataclasses
import hashlib
import json
import re
from datetime import UTC, datetime, timedelta
from pathlib import Path

import pytest
from pypdf import PdfReader

from app.certificate import CertificateInfo, build
from app.certificate.sign import Signer
from app.certificate.validated import (
    REPORT_ATTACHMENT,
    Software,
    ValidationClaimError,
    software_identity,
)
from app.certificate.validated_check import (
    folder_claim,
    read_report,
    trust_from_ca,
    trust_from_signer,
    verify_report,
)
from app.cli import main
from app.validation.cases import CaseResult
from app.validation.report import write_report
from tests.app.certificate.conftest import copy_run
from tests.app.certificate.throwaway_ca import PASSWORD, make_ca, make_signer

pytestmark = pytest.mark.integration

INFO = CertificateInfo(
    customer="ACME Ltd",
    customer_address="1 Test Street, 00-001 Testtown",
    authorised_by="J. Smith",
    temperature_c=23.0,
    mounting="stud-mounted back-to-back, 2 N m",
)
CASES = [
    CaseResult("known answer", f"case {i}", "1.000", "1.000", "0.001", True, "ISO 16063-21")
    for i in range(3)
]


@pytest.fixture()
def key(pki, monkeypatch) -> Signer:
    """The lab's signing key (the session's throwaway lab CA issued it)."""
    monkeypatch.setenv("ACCELCAL_SIGN_PASSWORD", PASSWORD)
    return Signer.load(pki.key)


def _report(
    folder: Path,
    signer: Signer | None,
    *,
    software: Software | None = None,
    when: datetime | None = None,
    cases: list[CaseResult] = CASES,
    name: str = "validation-20261125T000000Z.pdf",
) -> Path:
    """A report as `accelcal validate` writes it (write_report: record embedded, signed)."""
    folder.mkdir(parents=True, exist_ok=True)
    out = folder / name
    write_report(
        out,
        cases,
        software or software_identity(),
        {"python": "3.11"},
        when or datetime.now(UTC) - timedelta(hours=1),
        signer,
    )
    return out


def _forged_twin_report(folder: Path, when: str = "2099-01-01T00:00:00+00:00") -> Path:
    """The issue's attack: a fake PDF and a JSON twin saying every case passed, dated 2099,
    naming the installed software's hash and the PDF's SHA-256."""
    folder.mkdir(parents=True, exist_ok=True)
    pdf = folder / "validation-20990101T000000Z.pdf"
    pdf.write_bytes(b"%PDF-1.4 validation report\n%%EOF\n")
    twin = {
        "date_utc": when,
        "software": {"sha256": software_identity().sha256, "version": "9.9"},
        "passed": True,
        "cases": [{"name": "everything", "passed": True}],
        "report_pdf_sha256": hashlib.sha256(pdf.read_bytes()).hexdigest(),
    }
    pdf.with_suffix(".json").write_text(json.dumps(twin))
    return pdf


def _dcc(pdf: Path) -> str:
    return PdfReader(pdf).attachments["certificate.xml"][0].decode("utf-8")


def _text(pdf: Path) -> str:
    return " ".join(" ".join(p.extract_text() for p in PdfReader(pdf).pages).split())


def _certify(run: Path, out: Path, *extra: str) -> int:
    return main(["certificate", str(run), "--customer", "ACME Ltd",
                 "--customer-address", "1 Test Street, 00-001 Testtown", "--authorised-by",
                 "J. Smith", "--temperature", "23", "--mounting", "stud, 2 N m", "--dut-model",
                 "PCB 352C33", "--dut-type", "piezoelectric accelerometer", "--out", str(out),
                 *extra])  # fmt: skip


# --- the report proves itself ------------------------------------------------------------------


def test_a_signed_report_of_this_software_is_accepted_and_its_record_is_inside(
    key, pki, tmp_path
) -> None:
    report = _report(tmp_path, key)
    claim = read_report(report, trust_from_ca(pki.ca), software_identity().sha256)
    assert claim.cases == 3 and claim.signer.endswith("Vibration Calibration Laboratory")
    assert claim.report_sha256 == hashlib.sha256(report.read_bytes()).hexdigest()
    record = json.loads(PdfReader(report).attachments[REPORT_ATTACHMENT][0])
    assert [c["name"] for c in record["cases"]] == ["case 0", "case 1", "case 2"]
    assert record["software"]["sha256"] == software_identity().sha256
    # the lab's own key is trusted as itself too (certificate --sign without --trust)
    assert read_report(report, trust_from_signer(key), software_identity().sha256) == claim


@pytest.mark.parametrize(
    ("attack", "found"),
    [
        ("forged twin, 2099", "signature: the PDF is not signed"),
        ("unsigned report of validate", "signature: the PDF is not signed"),
        ("re-signed with another CA's key", "not trusted"),
        ("self-signed key of the lab's name", "not trusted"),
        ("signed, another software", "validates software " + "0" * 64),
        ("signed, dated in the future", "in the future"),
        ("signed, a case failed", "not every case passed (1 of 3 failed: case 1)"),
        ("signed, a byte changed after signing", "do not match"),
        ("signed, another report's record appended", "a revision added after signing"),
    ],
)
def test_each_forged_report_is_refused_naming_what_was_found(
    attack, found, key, pki, tmp_path
) -> None:
    sha = software_identity().sha256
    if attack == "forged twin, 2099":
        report = _forged_twin_report(tmp_path)
    elif attack == "unsigned report of validate":
        report = _report(tmp_path, None)
    elif attack in ("re-signed with another CA's key", "self-signed key of the lab's name"):
        other = make_ca(tmp_path, "Other CA") if "CA" in attack else None
        p12 = make_signer(tmp_path, "other.p12", other)
        report = _report(tmp_path / "r", Signer.load(p12, PASSWORD))
    elif attack == "signed, another software":
        report = _report(tmp_path, key, software=Software("9.9", "0" * 64, 1))
    elif attack == "signed, dated in the future":
        report = _report(tmp_path, key, when=datetime(2099, 1, 1, tzinfo=UTC))
    elif attack == "signed, a case failed":
        failed = [CASES[0], dataclasses.replace(CASES[1], passed=False), CASES[2]]
        report = _report(tmp_path, key, cases=failed)
    elif attack == "signed, a byte changed after signing":
        report = _report(tmp_path, key)
        data = bytearray(report.read_bytes())
        at = data.index(b"case 1")
        data[at : at + 6] = b"case 7"
        report.write_bytes(bytes(data))
    else:  # an incremental update after the signature carrying another record
        from pypdf import PdfWriter

        report = _report(tmp_path, key)
        signed = report.read_bytes()
        writer = PdfWriter(str(report), incremental=True)
        writer.add_attachment(REPORT_ATTACHMENT, b'{"passed": true}')
        writer.write(report)
        assert report.read_bytes().startswith(signed)  # the signed bytes kept, one update after
    with pytest.raises(ValidationClaimError) as refused:
        read_report(report, trust_from_ca(pki.ca), sha)
    assert report.name in str(refused.value) and found in str(refused.value)


def test_without_a_lab_key_or_ca_no_report_is_accepted(key, tmp_path) -> None:
    report = _report(tmp_path, key)
    with pytest.raises(ValidationClaimError, match="no lab key or CA to check it against"):
        read_report(report, None, software_identity().sha256)
    found = folder_claim(tmp_path, None, software_identity().sha256)
    assert found.claim is None and "--sign" in found.summary()


def test_the_newest_report_that_proves_itself_is_named(key, pki, tmp_path) -> None:
    sha = software_identity().sha256
    now = datetime.now(UTC)
    _report(tmp_path, key, when=now - timedelta(days=2), name="a.pdf")
    _report(tmp_path, key, when=now - timedelta(days=1), name="b.pdf")
    _report(tmp_path, key, when=datetime(2099, 1, 1, tzinfo=UTC), name="c.pdf")
    _forged_twin_report(tmp_path)
    found = folder_claim(tmp_path, trust_from_ca(pki.ca), sha)
    assert found.claim is not None and found.claim.report == "b.pdf"
    refused = " | ".join(found.refused)
    assert "c.pdf: dated 2099-01-01" in refused
    assert "validation-20990101T000000Z.pdf: signature: the PDF is not signed" in refused


# --- certificate ------------------------------------------------------------------------------


@pytest.mark.slow  # a signed certificate issued and verified twice in full (~4 s idle)
def test_certificate_names_the_signed_report_and_verify_proves_it(
    complete_run, key, pki, sign_password, tmp_path, monkeypatch, capsys
) -> None:
    folder = tmp_path / "validation"
    monkeypatch.setenv("ACCELCAL_VALIDATION_DIR", str(folder))
    report = _report(folder, key)
    digest = hashlib.sha256(report.read_bytes()).hexdigest()
    run = copy_run(complete_run, tmp_path / "runs")
    pdf = tmp_path / "c.pdf"
    assert _certify(run, pdf, "--sign", str(pki.key)) == 0
    out = capsys.readouterr().out
    assert f"software validation: report {report.name}" in out and "named" in out
    assert digest in _text(pdf).replace(" ", "") and digest in _dcc(pdf)
    named = re.findall(  # issue 35: named by refType for a machine, not only in words
        r'<dcc:statement refType="vib_softwareValidation">.*?<dcc:declaration>\s*'
        r'<dcc:content lang="en">([^<]*)<',
        _dcc(pdf),
        re.S,
    )
    assert len(named) == 1 and digest in named[0], named
    assert main(["verify", str(pdf), "--trust", str(pki.ca),
                 "--validation-report", str(report)]) == 0  # fmt: skip
    out = capsys.readouterr().out
    assert "certificate verified" in out
    assert "validation report: ok" in out and "3 cases passed" in out
    # the holder of the report can check the claim; another file is not the one named
    verify_report(digest, report)
    other = tmp_path / "other.pdf"
    other.write_bytes(b"%PDF-1.4 not the report")
    assert main(["verify", str(pdf), "--trust", str(pki.ca),
                 "--validation-report", str(other)]) == 2  # fmt: skip
    assert "the certificate names" in capsys.readouterr().out


@pytest.mark.slow  # a certificate issued per attack (~2 s idle, 4-5 s on the loaded machine)
@pytest.mark.parametrize("attack", ["forged twin, 2099", "another key", "another software"])
def test_certificate_names_no_forged_report_and_says_what_it_found(
    attack, complete_run, key, pki, sign_password, tmp_path, monkeypatch, capsys
) -> None:
    folder = tmp_path / "validation"
    monkeypatch.setenv("ACCELCAL_VALIDATION_DIR", str(folder))
    if attack == "forged twin, 2099":
        report, found = _forged_twin_report(folder), "signature: the PDF is not signed"
    elif attack == "another key":
        other = Signer.load(make_signer(tmp_path, "o.p12", make_ca(tmp_path, "Other CA")))
        report, found = _report(folder, other), "Other CA) is not trusted by the lab's key or CA"
    else:
        report = _report(folder, key, software=Software("9.9", "1" * 64, 1))
        found = f"validates software {'1' * 64}, not this software"
    run = copy_run(complete_run, tmp_path / "runs")
    pdf = tmp_path / "c.pdf"
    assert _certify(run, pdf, "--sign", str(pki.key), "--trust", str(pki.ca)) == 0
    out = capsys.readouterr().out
    assert f"software validation: no report named ({report.name}:" in out and found in out
    assert "Software validation" not in _text(pdf) and "Software validation" not in _dcc(pdf)


def test_certificate_without_the_labs_key_names_no_report(
    complete_run, key, tmp_path, monkeypatch, capsys
) -> None:
    folder = tmp_path / "validation"
    monkeypatch.setenv("ACCELCAL_VALIDATION_DIR", str(folder))
    _report(folder, key)
    run = copy_run(complete_run, tmp_path / "runs")
    assert _certify(run, tmp_path / "c.pdf") == 0
    assert "no lab key to check a report's signature against" in capsys.readouterr().out
    assert "Software validation" not in _text(tmp_path / "c.pdf")


# --- verify: a certificate made to name a forged report ----------------------------------------


@pytest.mark.slow  # a certificate built and verified per attack (~2 s idle, 4-6 s loaded)
@pytest.mark.parametrize("attack", ["forged twin, 2099", "another key", "another software"])
def test_verify_refuses_a_forged_report_a_certificate_names(
    attack, complete_run, key, pki, tmp_path, capsys
) -> None:
    """The attacker builds a certificate whose statement names his report (its SHA-256 and the
    software it claims): `verify --validation-report` proves the report itself and refuses."""
    from app.certificate.validated import ValidationClaim

    software = software_identity().sha256
    if attack == "forged twin, 2099":
        report, found = _forged_twin_report(tmp_path), "the PDF is not signed"
    elif attack == "another key":
        other = Signer.load(make_signer(tmp_path, "o.p12", make_ca(tmp_path, "Other CA")))
        report, found = _report(tmp_path / "r", other), "Other CA) is not trusted by the lab"
    else:  # a genuine lab report of other software, named as if of this one
        report = _report(tmp_path, key, software=Software("9.9", "2" * 64, 1))
        found = f"validates software {'2' * 64}, not this software ({software})"
    claim = ValidationClaim(
        report.name, "2026-11-25", hashlib.sha256(report.read_bytes()).hexdigest(), "9.9",
        software, 23, "Vibration Calibration Laboratory",
    )  # fmt: skip
    run = copy_run(complete_run, tmp_path / "runs")
    pdf = build(run, dataclasses.replace(INFO, validation=claim), tmp_path / "c.pdf")
    code = main(["verify", str(pdf), "--trust", str(pki.ca), "--validation-report", str(report)])
    out = capsys.readouterr().out
    assert code == 2
    (line,) = [x for x in out.splitlines() if x.startswith("validation report:")]
    assert line.startswith(f"validation report: FAIL: --validation-report: {report.name}: ")
    assert found in line


def test_verify_without_trust_does_not_prove_the_report(
    complete_run, key, pki, tmp_path, capsys
) -> None:
    from app.certificate.validated import ValidationClaim

    report = _report(tmp_path, key)
    claim = read_report(report, trust_from_ca(pki.ca), software_identity().sha256)
    run = copy_run(complete_run, tmp_path / "runs")
    pdf = build(run, dataclasses.replace(INFO, validation=claim), tmp_path / "c.pdf")
    assert isinstance(claim, ValidationClaim)
    assert main(["verify", str(pdf), "--validation-report", str(report)]) == 2
    assert "no lab key or CA to check it against" in capsys.readouterr().out
