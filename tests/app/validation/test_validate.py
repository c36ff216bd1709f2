"""`validate(out)`: the 17025 7.11.2 validation cases on the installed code and their report
(issue 27 point 2). Runs a simulated calibration: marked integration."""

from __future__ import annotations

import hashlib
import json
import sys
from pathlib import Path

import pytest
from pypdf import PdfReader

import app.validation.cases as cases
from app.certificate.validated import software_identity
from app.validation import ValidationInputError, validate
from dsp.uncertainty import Budget

pytestmark = pytest.mark.integration


def _text(pdf: Path) -> str:
    return " ".join(" ".join(page.extract_text() for page in PdfReader(str(pdf)).pages).split())


def test_validate_writes_its_report_and_exits_0_when_every_case_passes(tmp_path: Path) -> None:
    out = tmp_path / "validation.pdf"
    assert validate(out) == 0
    record = json.loads(out.with_suffix(".json").read_text())
    assert record["passed"] is True
    groups = {case["group"] for case in record["cases"]}
    assert groups == {cases.KNOWN_ANSWER, cases.PEER, cases.GUM, cases.HOSTILE, cases.COVERAGE}
    assert len(record["cases"]) == 23 and all(case["passed"] for case in record["cases"])
    software = software_identity()
    assert record["software"]["sha256"] == software.sha256
    assert record["report_pdf_sha256"] == hashlib.sha256(out.read_bytes()).hexdigest()
    text = _text(out)
    assert "ISO/IEC 17025:2017 clause 7.11.2" in text
    assert software.sha256 in text and "PASS: every case passed" in text
    assert "coverage factor k at p = 95.45 %, nu = 10" in text and "13.97" in text
    assert "FAIL" not in text


def test_removing_a_budget_term_makes_validation_fail(tmp_path: Path, monkeypatch) -> None:
    at = Budget.at

    def without_the_first_term(self, frequency_hz, quantity):  # the budget loses a term
        return at(self, frequency_hz, quantity)[1:]

    monkeypatch.setattr(Budget, "at", without_the_first_term)
    out = tmp_path / "validation.pdf"
    assert validate(out) == 1
    record = json.loads(out.with_suffix(".json").read_text())
    failed = {case["name"] for case in record["cases"] if not case["passed"]}
    assert "built-in stand budget: u_B at 160 Hz, magnitude" in failed
    assert "built-in stand budget: u_B at 160 Hz, phase" in failed
    assert "FAIL:" in _text(out)


def test_a_case_that_crashes_is_a_failed_case(tmp_path: Path, monkeypatch) -> None:
    def crash() -> list:
        raise RuntimeError("scipy went away")

    monkeypatch.setattr(cases, "peer_h1_scipy", crash)
    monkeypatch.setattr(cases, "known_answer_simulated_run", lambda folder: [])  # time
    out = tmp_path / "validation.pdf"
    assert validate(out) == 1
    record = json.loads(out.with_suffix(".json").read_text())
    (crashed,) = [case for case in record["cases"] if not case["passed"]]
    assert crashed["group"] == cases.PEER and "scipy went away" in crashed["obtained"]


def test_a_wrong_coverage_factor_fails_the_gum_cases(monkeypatch) -> None:
    import dsp.uncertainty

    monkeypatch.setattr(dsp.uncertainty, "coverage_factor", lambda nu, p=0.9545: 2.0)
    results = cases.gum_examples()
    failed = [r.name for r in results if not r.passed]
    assert len(failed) == 8  # every tabulated nu but infinity (t = 2.00)
    assert all(r.passed for r in results if "nu = inf" in r.name)


def test_an_input_that_is_accepted_fails_its_hostile_case(monkeypatch) -> None:
    import dsp.spectral

    monkeypatch.setattr(dsp.spectral, "check_periods", lambda estimator, periods: None)
    (case,) = [r for r in cases.hostile_inputs() if not r.passed]
    assert case.obtained == "accepted" and "periods" in case.expected


@pytest.mark.parametrize(
    ("name", "message"),
    [("report.txt", "the report is a PDF"), ("missing/report.pdf", "no such folder")],
)
def test_a_bad_report_path_is_refused_before_anything_runs(tmp_path, name, message) -> None:
    with pytest.raises(ValidationInputError, match=message):
        validate(tmp_path / name)


def test_an_existing_report_is_never_overwritten(tmp_path: Path) -> None:
    (tmp_path / "r.json").write_text("{}")
    with pytest.raises(ValidationInputError, match="exists; a report is never overwritten"):
        validate(tmp_path / "r.pdf")
    assert (tmp_path / "r.json").read_text() == "{}"


def test_the_software_hash_covers_every_file_but_bytecode(tmp_path: Path, monkeypatch) -> None:
    import app.certificate.validated as report

    package = tmp_path / "validated_pkg"
    (package / "__pycache__").mkdir(parents=True)
    (package / "__init__.py").write_text("x = 1\n")
    (package / "data.toml").write_text("a = 1\n")
    (package / "__pycache__" / "junk.pyc").write_bytes(b"\0")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setattr(report, "PACKAGES", ("validated_pkg",))
    first = software_identity()
    assert first.files == 2
    (package / "__pycache__" / "junk.pyc").write_bytes(b"\1")
    assert software_identity().sha256 == first.sha256
    (package / "data.toml").write_text("a = 2\n")
    assert software_identity().sha256 != first.sha256
    sys.modules.pop("validated_pkg", None)


def _signed(folder: Path, name: str, software: str, when: str, signer, passed: bool = True):
    """A report as `validate --sign` writes it (record embedded, signed with `signer`)."""
    from datetime import datetime

    from app.certificate.validated import Software
    from app.validation.report import write_report

    case = cases.CaseResult("g", "c", "1", "1", "0", passed, "s")
    pdf = folder / f"{name}.pdf"
    env = {"python": "3.11"}
    write_report(pdf, [case], Software("1", software, 1), env, datetime.fromisoformat(when), signer)
    return pdf


def test_the_newest_signed_passed_report_of_the_same_software_is_found(tmp_path, lab_key) -> None:
    """Only signed reports count (issue 33): the newest passed one of this software, by the
    date under its signature; a JSON file beside a PDF is never read."""
    from app.validation import passed_report

    signer, trust = lab_key
    s1, s2 = "1" * 64, "2" * 64
    old = _signed(tmp_path, "a", s1, "2026-01-01T00:00:00+00:00", signer)
    new = _signed(tmp_path, "b", s1, "2026-02-01T00:00:00+00:00", signer)
    _signed(tmp_path, "c", s1, "2026-03-01T00:00:00+00:00", signer, passed=False)
    _signed(tmp_path, "d", s2, "2026-04-01T00:00:00+00:00", signer)
    _signed(tmp_path, "e", s1, "2026-05-01T00:00:00+00:00", None)  # not signed
    (tmp_path / "f.json").write_text("not json")
    assert passed_report(tmp_path, s1, trust) == new
    new.unlink()
    assert passed_report(tmp_path, s1, trust) == old
    assert passed_report(tmp_path, "3" * 64, trust) is None
    assert passed_report(tmp_path, s1, None) is None  # nothing to check the signature against


def test_a_report_whose_pdf_was_replaced_is_not_named(tmp_path: Path, lab_key) -> None:
    """A PDF swapped after the fact (its twin rewritten to match) names nothing."""
    from app.validation import passed_report

    signer, trust = lab_key
    pdf = _signed(tmp_path, "a", "1" * 64, "2026-01-01T00:00:00+00:00", signer)
    assert passed_report(tmp_path, "1" * 64, trust) == pdf
    pdf.write_bytes(b"%PDF-1.4 another report\n%%EOF\n")
    twin = json.loads(pdf.with_suffix(".json").read_text())
    twin["report_pdf_sha256"] = hashlib.sha256(pdf.read_bytes()).hexdigest()
    pdf.with_suffix(".json").write_text(json.dumps(twin))
    assert passed_report(tmp_path, "1" * 64, trust) is None


@pytest.fixture()
def lab_key(tmp_path_factory, monkeypatch):
    """A lab signing key (throwaway CA) and the trust anchors of its CA."""
    from app.certificate.sign import Signer
    from app.certificate.validated_check import trust_from_ca
    from tests.app.certificate.throwaway_ca import PASSWORD, make_ca, make_signer

    folder = tmp_path_factory.mktemp("pki")
    ca = make_ca(folder, "Lab CA")
    monkeypatch.setenv("ACCELCAL_SIGN_PASSWORD", PASSWORD)
    return Signer.load(make_signer(folder, "lab.p12", ca)), trust_from_ca(ca.pem)


def test_the_module_entry_point_refuses_a_bad_path_with_exit_2(tmp_path, capsys) -> None:
    from app.validation.__main__ import main

    assert main(["--out", str(tmp_path / "report.txt")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: --out:") and err.count("\n") == 1
