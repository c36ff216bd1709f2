"""Amendments and withdrawals stated (issue 35 point 1, ISO/IEC 17025 7.8.8.3): an amendment's
PDF names on page 1 the certificate it replaces and the reason, its DCC fills coreData's
reportAmendedSubstituted and previousReport (read back here by xmlschema against the PTB
schema, not by this program's reader), and `accelcal verify --db` reports what the register
says: in force, replaced (by which) or withdrawn (why), and a file that is not the one issued."""

from __future__ import annotations

import dataclasses
import hashlib
from pathlib import Path
from typing import Any

import pytest
import xmlschema
from pypdf import PdfReader

from app.certificate.issuing import dcc_path
from app.certificate.pdf_marks import read_marks
from app.certificate.readback import PrintedItems, items_from_dcc, items_from_pdf, parse_inert
from app.certificate.register_status import register_findings
from app.cli import main
from app.records.db.engine import open_engine
from app.records.db.lab import Lab as Records
from app.records.run_folder import load_run
from tests.app.certificate.conftest import Lab, Pki
from tests.app.certificate.test_service import own_records

pytestmark = pytest.mark.integration

ROOT = Path(__file__).resolve().parents[3]
REASON = "customer address corrected"
ITEMS = ["--temperature", "23", "--mounting", "stud", "--prepared-by", "A. Tech",
         "--authorised-by", "J. Smith"]  # fmt: skip


def _certify(url: str, run: Path, out: Path, key: Path, *amend: str) -> None:
    argv = ["certificate", str(run), "--db", url, "--out", str(out), "--sign", str(key)]
    assert main([*argv, *ITEMS, *amend]) == 0


def _verify(capsys: pytest.CaptureFixture[str], pdf: Path, url: str, ca: Path) -> tuple[int, str]:
    capsys.readouterr()
    code = main(["verify", str(pdf), "--db", url, "--trust", str(ca)])
    return code, capsys.readouterr().out


def _core(xml: bytes) -> dict[str, Any]:
    """coreData as xmlschema decodes it against the PTB DCC 3.3.0 schema (an independent
    reader: schema-driven, none of app.certificate.readback)."""
    base = ROOT / "app/data/dcc"
    locations = [("https://ptb.de/si", str(base / "SI_Format.xsd")),
                 ("http://www.w3.org/2000/09/xmldsig#", str(base / "xmldsig-core-schema.xsd")),
                 ("http://qudt.org/vocab/", str(base / "quantitykind.xsd"))]  # fmt: skip
    schema = xmlschema.XMLSchema(str(base / "dcc.xsd"), locations=locations, allow="local")
    decoded: Any = schema.to_dict(xml.decode("utf-8"))
    return dict(decoded["dcc:administrativeData"]["dcc:coreData"])


@pytest.fixture()
def amended(lab: Lab, records_runs: tuple[Path, Path], pki: Pki, sign_password: str,
            tmp_path: Path) -> tuple[str, Path, Path]:  # fmt: skip
    """(records URL, the first certificate, its amendment) of one run, in a copy of the
    session's records."""
    url = own_records(lab, tmp_path)
    run = records_runs[0]
    records = Records(open_engine(url))
    first = tmp_path / "first.pdf"
    current = records.issued_for_run(str(load_run(run).run_id))
    if current is not None:  # the session's records already certified it: amend that first
        _certify(url, run, first, pki.key, "--replaces", current.number, "--reason", "renewed")
    else:
        _certify(url, run, first, pki.key)
    second = tmp_path / "second.pdf"
    number = str(items_from_pdf(read_marks(first.read_bytes())).number)
    _certify(url, run, second, pki.key, "--replaces", number, "--reason", f"  {REASON} ")
    return url, first, second


def test_the_amendment_names_what_it_replaces_on_page_1_and_in_its_dcc(
    amended: tuple[str, Path, Path],
) -> None:
    _, first, second = amended
    old = items_from_pdf(read_marks(first.read_bytes()))
    new = items_from_pdf(read_marks(second.read_bytes()))
    assert new.replaces == old.number and new.amendment_reason == REASON
    page_1 = " ".join(PdfReader(second).pages[0].extract_text().split())
    assert f"Replaces certificate {old.number}" in page_1
    assert f"Reason for the amendment {REASON}" in page_1
    assert f"{old.number} is no longer valid" in page_1
    first_dcc = dcc_path(first).read_bytes()
    core = _core(dcc_path(second).read_bytes())
    assert core["dcc:reportAmendedSubstituted"]["dcc:typeOfChange"] == "substituted"
    assert core["dcc:reportAmendedSubstituted"]["dcc:replacedUniqueIdentifier"] == old.number
    previous = core["dcc:previousReport"]
    assert previous["dcc:referralID"] == old.number
    assert previous["dcc:value"] == hashlib.sha256(first_dcc).hexdigest()  # the file issued
    assert previous["dcc:procedure"] == "SHA-256 of its DCC"
    assert previous["dcc:description"]["dcc:content"][0]["$"] == REASON
    assert "dcc:previousReport" not in _core(first_dcc) or old.replaces  # a first issue: none
    # this program's reader agrees with the independent one
    assert items_from_dcc(parse_inert(dcc_path(second).read_bytes())).replaces == old.number


def test_verify_reports_the_register_in_force_replaced_and_withdrawn(
    amended: tuple[str, Path, Path], pki: Pki, capsys: pytest.CaptureFixture[str]
) -> None:
    url, first, second = amended
    new_number = str(items_from_pdf(read_marks(second.read_bytes())).number)
    code, out = _verify(capsys, second, url, pki.ca)
    assert code == 0, out
    assert f"ok   in force in the records' register: certificate {new_number} issued" in out
    code, out = _verify(capsys, first, url, pki.ca)  # intact and signed, but superseded
    assert code == 2
    assert f"is REPLACED by {new_number} ({REASON}): use that one" in out.splitlines()[-1]
    assert main(["register", "withdraw", new_number, "--reason", "wrong sensor", "--db", url]) == 0
    code, out = _verify(capsys, second, url, pki.ca)
    assert code == 2
    assert f"certificate {new_number} is WITHDRAWN: wrong sensor" in out.splitlines()[-1]


def test_the_register_knows_the_file_it_issued(amended: tuple[str, Path, Path]) -> None:
    url, _, second = amended
    data = second.read_bytes()
    printed = items_from_pdf(read_marks(data))
    ok, detail = register_findings(data, printed, url)
    assert ok, detail
    ok, detail = register_findings(data + b"%\n", printed, url)  # one byte appended
    assert not ok and "is not the certificate" in detail
    # what it prints of the amendment must be the register's, item by item
    for forged in (
        dataclasses.replace(printed, replaces="ACC-0000-0001"),
        dataclasses.replace(printed, amendment_reason="typo"),
        PrintedItems(number=printed.number),
    ):
        ok, detail = register_findings(data, forged, url)
        assert not ok and "the register" in detail, forged
    ok, detail = register_findings(data, PrintedItems(number="ACC-9999-9999"), url)
    assert not ok and "has no certificate ACC-9999-9999" in detail


def test_a_dcc_whose_two_amendment_elements_disagree_matches_nothing(
    amended: tuple[str, Path, Path],
) -> None:
    xml = dcc_path(amended[2]).read_bytes()
    replaced = items_from_dcc(parse_inert(xml)).replaces
    forged = xml.replace(
        f"<dcc:replacedUniqueIdentifier>{replaced}<".encode(),
        b"<dcc:replacedUniqueIdentifier>ACC-0000-0001<",
    )
    assert forged != xml
    assert items_from_dcc(parse_inert(forged)).replaces == f"{replaced} | ACC-0000-0001"


def test_a_replaces_without_a_reason_is_refused_before_anything_is_written(
    lab: Lab, records_runs: tuple[Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    url = own_records(lab, tmp_path)
    out = tmp_path / "c.pdf"
    argv = ["certificate", str(records_runs[1]), "--db", url, "--out", str(out), *ITEMS]
    assert main([*argv, "--replaces", "ACC-2026-0001", "--reason", "  "]) == 2
    assert "reason: must not be blank" in capsys.readouterr().err
    assert main([*argv, "--replaces", "NO-SUCH-1", "--reason", "x"]) == 2
    assert "replaces: no certificate 'NO-SUCH-1'" in capsys.readouterr().err
    assert not out.exists() and not dcc_path(out).exists()
