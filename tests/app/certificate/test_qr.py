"""The QR code of the public verification address (issue 27): on page 1 of the certificate
(from `[laboratory] verify_url` of the stand file) and in the DCC; a bad address refused by name."""

from __future__ import annotations

import io
from pathlib import Path

import pytest
from pypdf import PdfReader

from app.certificate import CertificateInfo, build
from app.certificate.qr import verification_code
from app.procedure.run import RunRequest, execute
from app.records.run_folder import MANIFEST_NAME, sha256_of
from app.stand.config import ConfigError, load

pytestmark = pytest.mark.integration

ROOT = Path(__file__).resolve().parents[3]
VERIFY = "https://lab.example/verify"
INFO = CertificateInfo(
    customer="ACME Ltd",
    customer_address="1 Test Street, 00-001 Testtown",
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
