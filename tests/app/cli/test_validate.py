"""`accelcal validate` (issue 27): the report, exit 0; a failed case exit 1 (removing a budget
term: tests/app/validation/test_validate.py)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from app.cli import main

pytestmark = pytest.mark.integration


def test_validate_writes_the_report_and_exits_0(tmp_path: Path, capsys) -> None:
    out = tmp_path / "report.pdf"
    assert main(["validate", "--out", str(out)]) == 0
    assert out.read_bytes().startswith(b"%PDF")
    assert json.loads(out.with_suffix(".json").read_text())["passed"] is True
    assert f"validation passed: report {out}" in capsys.readouterr().out


def test_validate_exits_1_when_a_case_fails(tmp_path: Path, monkeypatch) -> None:
    from app.validation import cases

    original = cases.run_all

    def one_failed():  # type: ignore[no-untyped-def]
        import dataclasses

        results = original()
        return [dataclasses.replace(results[0], passed=False), *results[1:]]

    monkeypatch.setattr(cases, "run_all", one_failed)
    assert main(["validate", "--out", str(tmp_path / "r.pdf")]) == 1


def test_validate_refuses_a_report_path_that_is_no_pdf(tmp_path: Path, capsys) -> None:
    assert main(["validate", "--out", str(tmp_path / "r.txt")]) == 2
    assert "--out" in capsys.readouterr().err


def test_validate_writes_to_the_labs_validation_folder_by_default(monkeypatch, tmp_path) -> None:
    """Without --out the report goes where the certificate looks for it."""
    from app.cli.validate import default_out

    monkeypatch.setenv("ACCELCAL_VALIDATION_DIR", str(tmp_path / "v"))
    out = default_out()
    assert out.parent == tmp_path / "v" and out.parent.is_dir() and out.suffix == ".pdf"


@pytest.mark.slow  # runs every validation case once (~2 s idle, 3.4 s at load 7)
def test_validate_sign_writes_a_report_a_certificate_accepts(tmp_path: Path, capsys) -> None:
    """`accelcal validate --sign` (issue 33): the one way a report the certificate names is
    made; without --sign the report says it is not signed and proves nothing."""
    from app.certificate.validated import ValidationClaimError, software_identity
    from app.certificate.validated_check import read_report, trust_from_ca
    from tests.app.certificate.throwaway_ca import PASSWORD, make_ca, make_signer

    ca = make_ca(tmp_path, "Lab CA")
    key = make_signer(tmp_path, "lab.p12", ca)
    import os

    os.environ["ACCELCAL_SIGN_PASSWORD"] = PASSWORD
    try:
        assert main(["validate", "--out", str(tmp_path / "r.pdf"), "--sign", str(key)]) == 0
    finally:
        del os.environ["ACCELCAL_SIGN_PASSWORD"]
    assert "validation passed: report" in capsys.readouterr().out
    claim = read_report(tmp_path / "r.pdf", trust_from_ca(ca.pem), software_identity().sha256)
    assert claim.cases == 23 and claim.software_sha256 == software_identity().sha256
    assert main(["validate", "--out", str(tmp_path / "u.pdf")]) == 0
    assert "NOT signed" in capsys.readouterr().out
    with pytest.raises(ValidationClaimError, match="the PDF is not signed"):
        read_report(tmp_path / "u.pdf", trust_from_ca(ca.pem), software_identity().sha256)


def test_validate_refuses_a_key_it_cannot_use_before_running(tmp_path: Path, capsys) -> None:
    assert (
        main(["validate", "--out", str(tmp_path / "r.pdf"), "--sign", str(tmp_path / "no.p12")])
        == 2
    )
    assert "--sign: no such file" in capsys.readouterr().err
    assert not (tmp_path / "r.pdf").exists()
