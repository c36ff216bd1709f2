"""The software validation report of this software named on the certificate by the SHA-256 of
its PDF (issue 27): PDF line, DCC statement, checkable by `accelcal verify`."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import pytest
from pypdf import PdfReader

from app.certificate import CertificateInfo, build
from app.certificate.validated import (
    ValidationClaimError,
    software_identity,
    verify_report,
)

pytestmark = pytest.mark.integration

INFO = CertificateInfo(
    customer="ACME Ltd",
    authorised_by="J. Smith",
    temperature_c=23.0,
    mounting="stud-mounted back-to-back, 2 N m",
)


def _dcc(pdf: Path) -> str:
    return PdfReader(pdf).attachments["certificate.xml"][0].decode("utf-8")


def _validation_report(folder: Path, software_sha: str, passed: bool = True) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    pdf = folder / "validation-20261125T000000Z.pdf"
    pdf.write_bytes(b"%PDF-1.4 validation report")
    twin = {
        "date_utc": "2026-11-25T00:00:00+00:00",
        "software": {"sha256": software_sha, "version": "9.9"},
        "passed": passed,
        "cases": [{"passed": passed}],
        "report_pdf_sha256": hashlib.sha256(pdf.read_bytes()).hexdigest(),
    }
    pdf.with_suffix(".json").write_text(json.dumps(twin))
    return pdf


def test_the_certificate_names_the_passed_validation_report_by_its_hash(
    complete_run, tmp_path, monkeypatch
) -> None:
    import shutil

    folder = tmp_path / "validation"
    monkeypatch.setenv("ACCELCAL_VALIDATION_DIR", str(folder))
    report = _validation_report(folder, software_identity().sha256)
    digest = hashlib.sha256(report.read_bytes()).hexdigest()
    run = tmp_path / "runs" / complete_run.name
    shutil.copytree(complete_run, run, ignore=shutil.ignore_patterns("certificate*"))
    pdf = build(run, INFO, tmp_path / "c.pdf")
    text = " ".join(" ".join(p.extract_text() for p in PdfReader(pdf).pages).split())
    assert "Software validation" in text and report.name in text
    assert digest in text.replace(" ", "")
    assert digest in _dcc(pdf) and "Software validation" in _dcc(pdf)
    verify_report(digest, report)  # the holder of the report can check the claim
    report.write_bytes(b"%PDF-1.4 another report")
    with pytest.raises(ValidationClaimError, match="--validation-report"):
        verify_report(digest, report)


def test_a_report_of_other_software_or_failed_is_not_named(complete_run, tmp_path, monkeypatch):
    import shutil

    run = tmp_path / "runs" / complete_run.name
    shutil.copytree(complete_run, run, ignore=shutil.ignore_patterns("certificate*"))
    monkeypatch.setenv("ACCELCAL_VALIDATION_DIR", str(tmp_path / "a"))
    _validation_report(tmp_path / "a", "0" * 64)
    monkeypatch.setenv("ACCELCAL_VALIDATION_DIR", str(tmp_path / "b"))
    _validation_report(tmp_path / "b", software_identity().sha256, passed=False)
    for folder in ("a", "b"):
        monkeypatch.setenv("ACCELCAL_VALIDATION_DIR", str(tmp_path / folder))
        pdf = build(run, INFO, tmp_path / f"c-{folder}.pdf")
        text = " ".join(p.extract_text() for p in PdfReader(pdf).pages)
        assert "Software validation" not in text and "Software validation" not in _dcc(pdf)


def test_verify_recomputes_the_named_validation_report(complete_run, tmp_path, monkeypatch, capsys):
    import shutil

    from app.cli import main

    folder = tmp_path / "validation"
    monkeypatch.setenv("ACCELCAL_VALIDATION_DIR", str(folder))
    report = _validation_report(folder, software_identity().sha256)
    run = tmp_path / "runs" / complete_run.name
    shutil.copytree(complete_run, run, ignore=shutil.ignore_patterns("certificate*"))
    pdf = build(run, INFO, tmp_path / "c.pdf")
    main(["verify", str(pdf), "--validation-report", str(report)])
    assert "validation report: ok" in capsys.readouterr().out
    other = tmp_path / "other.pdf"
    other.write_bytes(b"%PDF-1.4 not the report")
    assert main(["verify", str(pdf), "--validation-report", str(other)]) == 2
    assert "the certificate names" in capsys.readouterr().err
