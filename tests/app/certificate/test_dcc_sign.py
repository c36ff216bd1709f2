"""The DCC's own signature (issue 35 point 3): the lab's key signs the DCC (enveloped XAdES
baseline B) before it goes into the PDF; signxml verifies it on its own with the lab's
certificate and its CA, and refuses it when one value changes; a signature by another key is
refused; `accelcal verify` checks it beside the PDF's PAdES (and a DCC given alone) and says
which signature failed; a lab without a key issues an unsigned DCC, reported as the PDF's."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from cryptography.hazmat.primitives.serialization import Encoding, pkcs12
from lxml import etree
from signxml import SignatureConfiguration, XMLVerifier
from signxml.exceptions import InvalidCertificate, InvalidDigest, InvalidSignature
from signxml.xades import XAdESVerifier

from app.certificate import dcc_sign, issuing
from app.certificate.sign import Signer
from app.cli import main
from tests.app.certificate.conftest import Pki, copy_run
from tests.app.certificate.throwaway_ca import PASSWORD, make_ca, make_signer

pytestmark = pytest.mark.integration
ITEMS = ("--customer", "ACME Ltd", "--customer-address", "1 Test Street, 00-001 Testtown",
         "--authorised-by", "J. Smith", "--prepared-by", "A. Tech", "--temperature", "23",
         "--mounting", "stud, 2 N m")  # fmt: skip
DS = "{http://www.w3.org/2000/09/xmldsig#}"
# the references XAdES baseline B signs: the document (URI=""), the SignedProperties, the
# signer's certificate in KeyInfo
SIGNED = SignatureConfiguration(expect_references=3, location="./")


def xml_verify(xml: bytes, **kwargs: str) -> object:
    """signxml's own XMLVerifier (not this program's code) on `xml`; the first reference's
    signed element."""
    results = XMLVerifier().verify(xml, expect_config=SIGNED, **kwargs)
    assert isinstance(results, list)
    return results[0].signed_xml


def lab_certificate(pki: Pki) -> str:
    """The lab signer's certificate (PEM), out of its PKCS#12 file."""
    _, cert, _ = pkcs12.load_key_and_certificates(pki.key.read_bytes(), PASSWORD.encode())
    assert cert is not None
    return cert.public_bytes(Encoding.PEM).decode("ascii")


@pytest.fixture(scope="module")
def other_key(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """Another CA's certificate (PEM) and a key it issued, under the lab's own name."""
    folder = tmp_path_factory.mktemp("other-pki")
    ca = make_ca(folder, "Other CA")
    return ca.pem, make_signer(folder, "other.p12", ca)


@pytest.fixture()
def signed(complete_run: Path, pki: Pki, sign_password: str, tmp_path: Path) -> tuple[Path, Path]:
    """A certificate issued with the lab's key: (its PDF, its run)."""
    run = copy_run(complete_run, tmp_path / "runs")
    pdf = tmp_path / "signed.pdf"
    assert main(["certificate", str(run), *ITEMS, "--sign", str(pki.key), "--out", str(pdf)]) == 0
    return pdf, run


def verify_lines(capsys: pytest.CaptureFixture[str], *argv: str | Path) -> list[str]:
    capsys.readouterr()
    code = main(["verify", *map(str, argv)])
    lines = capsys.readouterr().out.strip().splitlines()
    assert code == (0 if lines[-1] == "certificate verified" else 2), lines
    return lines


def change_one_value(xml: bytes) -> bytes:
    """The DCC with the first sensitivity's last digit changed (still well-formed, still valid)."""
    quantity = re.search(rb"vib_sensitivityMagnitude[^>]*>.*?<si:valueXMLList>(\S+)", xml, re.S)
    assert quantity is not None
    value = quantity.group(1)
    changed = value[:-1] + (b"1" if value[-1:] != b"1" else b"2")
    return xml[: quantity.start(1)] + changed + xml[quantity.end(1) :]


def test_signxml_verifies_the_dcc_on_its_own_and_refuses_a_changed_value(
    signed: tuple[Path, Path], pki: Pki
) -> None:
    pdf, _ = signed
    xml = pdf.with_suffix(".xml").read_bytes()
    root = etree.fromstring(xml)
    assert root[-1].tag == f"{DS}Signature"  # enveloped: the root's last child
    document = xml_verify(xml, x509_cert=lab_certificate(pki))
    assert etree.QName(document).localname == "digitalCalibrationCertificate"
    xml_verify(xml, ca_pem_file=str(pki.ca))  # the chain to the lab's CA
    xades = XAdESVerifier().verify(xml, x509_cert=lab_certificate(pki))  # baseline B props
    assert any(r.signed_xml is not None and "SignedProperties" in r.signed_xml.tag for r in xades)
    with pytest.raises(InvalidDigest):
        xml_verify(change_one_value(xml), x509_cert=lab_certificate(pki))


def test_a_signature_by_another_key_is_refused(
    signed: tuple[Path, Path], pki: Pki, other_key: tuple[Path, Path], tmp_path: Path, capsys
) -> None:
    """The DCC re-signed by another key (another CA's, under the lab's name): signxml refuses
    it against the lab's certificate and CA, and so does `accelcal verify --trust`."""
    pdf, run = signed
    xml = pdf.with_suffix(".xml").read_bytes()
    root = etree.fromstring(xml)
    root.remove(root[-1])
    resigned = dcc_sign.sign_dcc(etree.tostring(root), Signer.load(other_key[1], PASSWORD))
    with pytest.raises(InvalidSignature):
        xml_verify(resigned, x509_cert=lab_certificate(pki))
    with pytest.raises(InvalidCertificate):
        xml_verify(resigned, ca_pem_file=str(pki.ca))
    alone = tmp_path / "resigned.xml"
    alone.write_bytes(resigned)
    lines = verify_lines(capsys, alone, "--run", run, "--trust", pki.ca)
    assert lines[0].startswith(f"FAIL {dcc_sign.CHECK}: intact, but ") and "not trusted" in lines[0]
    assert "ok   DCC numbers equal the run's results" in lines


def test_verify_checks_both_signatures_and_names_the_one_that_failed(
    signed: tuple[Path, Path], pki: Pki, other_key: tuple[Path, Path], sign_password: str,
    tmp_path: Path, capsys, monkeypatch: pytest.MonkeyPatch,
) -> None:  # fmt: skip
    pdf, run = signed
    lines = verify_lines(capsys, pdf, "--run", run, "--trust", pki.ca)
    assert lines[-1] == "certificate verified"
    assert any(ln.startswith(f"ok   {dcc_sign.CHECK}: intact, signed by ") for ln in lines), lines
    lines = verify_lines(capsys, pdf.with_suffix(".xml"), "--run", run, "--trust", pki.ca)
    assert lines[-1] == "certificate verified", lines  # the DCC alone
    changed = tmp_path / "changed.xml"
    changed.write_bytes(change_one_value(pdf.with_suffix(".xml").read_bytes()))
    lines = verify_lines(capsys, changed, "--trust", pki.ca)
    assert lines[-1].startswith(f"certificate NOT verified: {dcc_sign.CHECK}: the signature does")
    # a PDF signed by the lab whose DCC another key signed: the PAdES holds, the DCC's fails
    other = Signer.load(other_key[1], PASSWORD)
    monkeypatch.setattr(issuing, "_signed_dcc", lambda xml, signer: dcc_sign.sign_dcc(xml, other))
    mixed = tmp_path / "mixed.pdf"
    argv = ["certificate", str(run), *ITEMS, "--sign", str(pki.key), "--out", str(mixed)]
    assert main(argv) == 0
    lines = verify_lines(capsys, mixed, "--run", run, "--trust", pki.ca)
    failed = [ln for ln in lines[:-1] if not ln.startswith("ok   ")]
    assert len(failed) == 1 and failed[0].startswith(f"FAIL {dcc_sign.CHECK}: signed by "), lines
    assert "not by the PDF's signer" in failed[0]
    assert "ok   signature intact, covering the whole file" in lines


def test_a_lab_without_a_key_issues_an_unsigned_dcc(
    complete_run: Path, tmp_path: Path, capsys
) -> None:
    run = copy_run(complete_run, tmp_path / "runs")
    assert main(["certificate", str(run), *ITEMS]) == 0
    xml = (run / "certificate.xml").read_bytes()
    assert etree.fromstring(xml).find(f"{DS}Signature") is None
    status = dcc_sign.check_dcc_signature(xml)
    assert not status.signed and status.detail == dcc_sign.UNSIGNED_DETAIL
    lines = verify_lines(capsys, run / "certificate.xml", "--run", run)
    assert lines[0] == f"FAIL {dcc_sign.CHECK}: {dcc_sign.UNSIGNED_DETAIL}"
    assert [ln for ln in lines[:-1] if not ln.startswith("ok   ")] == [lines[0]]


def test_a_dcc_with_a_second_or_misplaced_signature_is_refused(
    signed: tuple[Path, Path],
) -> None:
    """A signature moved under another element, or a second one added, does not prove the
    DCC (an enveloped signature is the root's child, one only)."""
    pdf, _ = signed
    xml = pdf.with_suffix(".xml").read_bytes()
    root = etree.fromstring(xml)
    signature = root[-1]
    twice = etree.fromstring(xml)
    twice.append(etree.fromstring(etree.tostring(signature)))
    assert not dcc_sign.check_dcc_signature(etree.tostring(twice)).intact
    moved = etree.fromstring(xml)
    moved.remove(moved[-1])
    moved[0].append(etree.fromstring(etree.tostring(signature)))
    status = dcc_sign.check_dcc_signature(etree.tostring(moved))
    assert status.signed and not status.intact


def test_a_signed_pdf_issued_before_dccs_were_signed_still_verifies(
    complete_run: Path, pki: Pki, sign_password: str, tmp_path: Path, capsys,
    monkeypatch: pytest.MonkeyPatch,
) -> None:  # fmt: skip
    """Its DCC is unsigned but inside the PDF's PAdES signature: verified, and the report says
    that the DCC alone proves nothing."""
    from app.certificate.verify import COVERED_BY_PDF

    run = copy_run(complete_run, tmp_path / "runs")
    monkeypatch.setattr(issuing, "_signed_dcc", lambda xml, signer: xml)  # as before issue 35
    pdf = tmp_path / "old.pdf"
    assert main(["certificate", str(run), *ITEMS, "--sign", str(pki.key), "--out", str(pdf)]) == 0
    lines = verify_lines(capsys, pdf, "--run", run, "--trust", pki.ca)
    assert lines[-1] == "certificate verified", lines
    assert f"ok   {dcc_sign.CHECK}: {COVERED_BY_PDF}" in lines
    lines = verify_lines(capsys, pdf.with_suffix(".xml"), "--run", run, "--trust", pki.ca)
    assert lines[0] == f"FAIL {dcc_sign.CHECK}: {dcc_sign.UNSIGNED_DETAIL}"
