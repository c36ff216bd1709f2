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
