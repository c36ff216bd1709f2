"""Issue 27 on the certificate: the QR code of the public verification address on page 1 (from
`[laboratory] verify_url` of the stand file) and in the DCC, and the software validation report
of this software named by the SHA-256 of its PDF (PDF line, DCC statement, checkable)."""

from __future__ import annotations

import hashlib
import io
import json
from pathlib import Path

import pytest
from pypdf import PdfReader

from app.certificate import CertificateInfo, build
from app.certificate.qr import verification_code
from app.certificate.validated import (
    ValidationClaimError,
    software_identity,
    verify_report,
)
from app.procedure.run import RunRequest, execute
from app.records.run_folder import MANIFEST_NAME, sha256_of
from app.stand.config import ConfigError, load

pytestmark = pytest.mark.integration

ROOT = Path(__file__).resolve().parents[2]
VERIFY = "https://lab.example/verify"
INFO = CertificateInfo(
    customer="ACME Ltd",
    authorised_by="J. Smith",
    temperature_c=23.0,
    mounting="stud-mounted back-to-back, 2 N m",
)


def _stand(folder: Path, verify_line: str) -> Path:
    text = (ROOT / "sim" / "stand.toml").read_text(encoding="utf-8")
    text = text.replace("[laboratory]\n", f"[laboratory]\n{verify_line}\n", 1)
    path = folder / "stand.toml"
    path.write_text(text, encoding="utf-8")
    return path


@pytest.fixture(scope="module")
def qr_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    base = tmp_path_factory.mktemp("qr")
    stand = _stand(base, f'verify_url = "{VERIFY}/"')
    finished = execute(
        RunRequest(dut="piezo", dut_id="SN-QR", periods=4, out=base / "runs", stand_file=stand)
    )
    return base / "runs" / str(finished.record.run_id)


def _page_text(pdf: Path, page: int) -> str:
    return " ".join(PdfReader(pdf).pages[page].extract_text().split())


def _dcc(pdf: Path) -> str:
    return PdfReader(pdf).attachments["certificate.xml"][0].decode("utf-8")


def test_page_one_carries_the_qr_code_of_the_verification_address(qr_run, tmp_path) -> None:
    import zxingcpp
    from PIL import Image

    pdf = build(qr_run, INFO, tmp_path / "c.pdf")
    number = f"AC-{qr_run.name}"
    code = verification_code(number, sha256_of(qr_run / MANIFEST_NAME))
    expected = f"{VERIFY}/{number}?code={code}"
    images = PdfReader(pdf).pages[0].images
    decoded = [
        r.text
        for image in images
        for r in zxingcpp.read_barcodes(Image.open(io.BytesIO(image.data)))
    ]
    assert decoded == [expected]  # exactly one QR code on page 1, the certificate's address
    assert expected in _page_text(pdf, 0).replace(" ", "") or expected in _page_text(pdf, 0)
    assert f'<dcc:content lang="en">{expected}</dcc:content>' in _dcc(pdf)


def test_no_verify_url_no_qr_code(complete_run, tmp_path) -> None:
    import shutil

    run = tmp_path / "runs" / complete_run.name
    shutil.copytree(complete_run, run, ignore=shutil.ignore_patterns("certificate*"))
    pdf = build(run, INFO, tmp_path / "c.pdf")
    assert len(PdfReader(pdf).pages[0].images) == 0
    assert "Verification address" not in _dcc(pdf)


@pytest.mark.parametrize(
    "line",
    [
        'verify_url = "ftp://lab.example/v"',
        'verify_url = "https://lab.example/v?x=1"',
        "verify_url = 3",
    ],
)
def test_a_bad_verify_url_is_refused_naming_the_field(tmp_path: Path, line: str) -> None:
    with pytest.raises(ConfigError, match=r"laboratory\.verify_url"):
        load(_stand(tmp_path, line))


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
